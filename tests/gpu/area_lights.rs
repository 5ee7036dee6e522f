//! Sphere and disk lights shaded as the area lights they are (issue 11): a point or spot light
//! with a `radius` and a sun with an `angular_diameter_deg` fill a cap of directions, which
//! compose shades by LTC over a solid-angle-matched polygon (`shading::shade_cap`,
//! `lighting::ltc::cap_polygon`). Checked against numerical integration of umbra's own BRDF over
//! the cap, against the hard light from afar, and GPU against the CPU twin.

use crate::common;

use std::path::Path;

use glam::{DVec3, Vec3, Vec4};
use umbra::config::DebugView;
use umbra::lighting::ltc;
use umbra::renderer::{OutputKind, RenderSettings, Renderer};
use umbra::scene::{Light, Material, Scene};
use umbra::shading::{brdf_times_cos, gpu_lights, light_cap, shade_cap, shade_point, Cap};

/// A cap of half-angle `half_deg` around the unit direction at `tilt_deg` from +z (toward +x,
/// and a little +y so the cap is off the plane of incidence), radiance (1, 2, 3).
fn cap(half_deg: f32, tilt_deg: f32) -> Cap {
    let t = tilt_deg.to_radians();
    let axis = Vec3::new(t.sin(), 0.15 * t.sin(), t.cos()).normalize();
    let one_minus_cos = 1.0 - f64::from(half_deg).to_radians().cos();
    Cap { axis, one_minus_cos: one_minus_cos as f32, radiance: Vec3::new(1.0, 2.0, 3.0) }
}

/// sum over the cap of f(v, l) (n.l)+ L dw at the origin (normal +z), by the midpoint rule in
/// (cos theta, phi) around the cap's axis: `k` x 4`k` cells of equal solid angle.
fn numerical(v: Vec3, material: &Material, cap: &Cap, k: usize) -> DVec3 {
    let axis = cap.axis.as_dvec3();
    let (t, b) = umbra::shading::orthonormal_basis(cap.axis);
    let (t, b) = (t.as_dvec3(), b.as_dvec3());
    let one_minus_cos = f64::from(cap.one_minus_cos);
    let cell = 2.0 * std::f64::consts::PI * one_minus_cos / (4 * k * k) as f64;
    let mut sum = DVec3::ZERO;
    for i in 0..k {
        let e = (i as f64 + 0.5) / k as f64 * one_minus_cos;
        let (c, s) = (1.0 - e, (e * (2.0 - e)).max(0.0).sqrt());
        for j in 0..4 * k {
            let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / (4 * k) as f64;
            let l = axis * c + (t * phi.cos() + b * phi.sin()) * s;
            let f = brdf_times_cos(Vec3::Z, v, l.as_vec3(), material.base_color, material.roughness, material.metallic);
            sum += f.as_dvec3() * cell;
        }
    }
    sum * cap.radiance.as_dvec3()
}

/// The largest relative error over RGB of `shade_cap` against `numerical` (`k` rings) for a
/// view `view_deg` from the normal (+z) toward +x.
fn shading_error(view_deg: f32, material: &Material, c: &Cap, k: usize) -> f64 {
    let t = view_deg.to_radians();
    let v = Vec3::new(t.sin(), 0.0, t.cos());
    let ltc = shade_cap(Vec3::Z, v, material, c).as_dvec3();
    let num = numerical(v, material, c, k);
    ((ltc - num).abs() / num).max_element()
}

/// The cosine's integral over `c` over pi (the Lambert share of a unit-radiance cap), by
/// `numerical` with a white Lambert-only BRDF: umbra's white dielectric minus its black twin.
fn lambert_share(c: &Cap, k: usize) -> f64 {
    let unit = Cap { radiance: Vec3::ONE, ..*c };
    let white = Material { base_color: Vec3::ONE, roughness: 1.0, metallic: 0.0 };
    let black = Material { base_color: Vec3::ZERO, ..white };
    (numerical(Vec3::Z, &white, &unit, k) - numerical(Vec3::Z, &black, &unit, k)).x
}

#[test]
fn the_cap_polygon_has_the_caps_cosine_integral() {
    // Lambert is the cosine itself: the polygon's horizon-clipped form factor against the cap's.
    let mut worst = 0.0f64;
    for half_deg in [0.03f32, 2.0, 10.0, 30.0, 60.0, 85.0] {
        for tilt_deg in [0.0f32, 30.0, 60.0, 85.0, 100.0, 120.0] {
            let c = cap(half_deg, tilt_deg);
            let (centre, offsets) = ltc::cap_polygon(c.axis, c.one_minus_cos);
            let polygon = f64::from(ltc::cap_form_factor(glam::Mat3::IDENTITY, centre, &offsets).z.abs());
            let exact = lambert_share(&c, 200);
            if exact < 1e-4 * (1.0 - f64::from(half_deg).to_radians().cos()) {
                assert!(
                    polygon <= 2e-4 * (1.0 - f64::from(half_deg).to_radians().cos()),
                    "cap {half_deg} deg at {tilt_deg} deg: polygon {polygon}, cap {exact}"
                );
                continue;
            }
            let error = (polygon - exact).abs() / exact;
            println!(
                "cap {half_deg:>2} deg at {tilt_deg:>3} deg: polygon {polygon:.6} numerical {exact:.6} error {:.4} %",
                100.0 * error
            );
            worst = worst.max(error);
        }
    }
    // Matching solid angle leaves 0.02 % above the horizon, down to a cap of 0.03 degrees;
    // where the horizon cuts a cap, the octagon's great-circle sides cross it a little
    // differently from the circle: 0.2 %.
    assert!(worst < 0.003, "the cap polygon's cosine integral is off by {:.3} %", 100.0 * worst);
}

#[test]
fn the_caps_diffuse_share_is_exact() {
    // ltc::cap_diffuse (Snyder's closed form) against numerical integration of the cosine.
    let mut worst = 0.0f64;
    for half_deg in [0.03f32, 2.0, 10.0, 30.0, 60.0, 85.0, 90.0] {
        for tilt_deg in [0.0f32, 30.0, 60.0, 85.0, 90.0, 100.0, 120.0, 150.0] {
            let c = Cap { radiance: Vec3::ONE, ..cap(half_deg, tilt_deg) };
            let sin2 = c.one_minus_cos * (2.0 - c.one_minus_cos);
            let closed = f64::from(ltc::cap_diffuse(c.axis.z, sin2));
            let exact = lambert_share(&c, 300);
            // Relative, with a floor of 1 % of the cap's face-on value (f32 at the horizon).
            let error = (closed - exact).abs() / exact.max(1e-2 * f64::from(sin2));
            worst = worst.max(error);
        }
    }
    println!("closed-form diffuse share: worst error {:.4} %", 100.0 * worst);
    // Below 0.05 % everywhere but a 0.03 degree cap straddling the horizon, where the value is
    // 1e-8 and f32 leaves 0.4 % of the floor.
    assert!(worst < 5e-3, "the closed form is off by {:.3} %", 100.0 * worst);
}

#[test]
fn sphere_and_disk_lights_match_numerical_integration() {
    // Where the fitted LTC table holds (tests/cpu/ltc.rs: up to 45 degrees for roughness 0.2..0.7),
    // with caps from a small sun (2 degrees) to a large sphere close by (40 degrees).
    let mut worst = 0.0f64;
    for roughness in [0.2f32, 0.4, 0.7] {
        for view_deg in [0.0f32, 20.0, 45.0] {
            for metallic in [0.0f32, 1.0] {
                for half_deg in [2.0f32, 10.0, 40.0] {
                    let material = Material { base_color: Vec3::new(0.9, 0.6, 0.3), roughness, metallic };
                    let t = view_deg.to_radians();
                    // The light around the mirror direction, where the lobe is.
                    let c = Cap { axis: Vec3::new(-t.sin(), 0.1, t.cos()).normalize(), ..cap(half_deg, 0.0) };
                    let error = shading_error(view_deg, &material, &c, 300);
                    println!(
                        "roughness {roughness} metallic {metallic} view {view_deg:>2} cap {half_deg:>2}: error {:.2} %",
                        100.0 * error
                    );
                    worst = worst.max(error);
                }
            }
        }
    }
    assert!(worst < 0.03, "sphere/disk shading off by {:.2} %", 100.0 * worst);
}

#[test]
fn sphere_and_disk_lights_at_grazing_views() {
    // Past 50 degrees of view `ltc::lobe_over_polygon` integrates the lobe over the cap's octagon
    // numerically (the fitted LTC alone missed by up to 71 % here: roughness 0.7, 85 degrees, a
    // 2-degree cap). Caps of 2-25 degrees on the mirror direction, lifted clear of the horizon,
    // and turned 60 degrees aside from it (the lobe's tail). Asserted for roughness 0.35 and up:
    // 2 % up to 70 degrees, 5 % beyond (the rect's bounds, tests/cpu/ltc.rs). Printed for 0.2, which
    // misses at 80-85 degrees (up to 24 % for a 25-degree cap on the mirror direction).
    let mut failures = Vec::new();
    for roughness in [0.2f32, 0.35, 0.5, 0.7, 1.0] {
        for view_deg in [60.0f32, 70.0, 80.0, 85.0] {
            for half_deg in [2.0f32, 10.0, 25.0] {
                for aside_deg in [0.0f32, 60.0] {
                    let mut e = 0.0f64;
                    for metallic in [0.0f32, 1.0] {
                        let material = Material { base_color: Vec3::new(0.9, 0.6, 0.3), roughness, metallic };
                        let (elevation, turn) =
                            ((90.0 - view_deg).max(half_deg + 10.0).to_radians(), aside_deg.to_radians());
                        let axis =
                            Vec3::new(-elevation.cos() * turn.cos(), elevation.cos() * turn.sin(), elevation.sin());
                        let c = Cap { axis, ..cap(half_deg, 0.0) };
                        let k = if roughness < 0.3 { 1000 } else { 300 };
                        e = e.max(shading_error(view_deg, &material, &c, k));
                    }
                    println!(
                        "roughness {roughness:<4} view {view_deg:>2} cap {half_deg:>2} aside {aside_deg:>2}: error {:.2} %",
                        100.0 * e
                    );
                    let bound = if view_deg <= 70.0 { 0.02 } else { 0.05 };
                    if roughness >= 0.35 && e > bound {
                        failures.push(format!(
                            "roughness {roughness} view {view_deg} cap {half_deg} aside {aside_deg}: {:.2} %",
                            100.0 * e
                        ));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn a_large_sphere_close_to_a_floor_lights_it_as_a_sphere_does() {
    // A sphere of radius 1 whose centre is 1.5 m above the floor: from points under it the
    // sphere fills a cap of 42 degrees, and from 2 m aside the horizon cuts it. A point light
    // of the same intensity overshoots under it and misses light at the side.
    let material = Material { base_color: Vec3::splat(0.8), roughness: 0.6, metallic: 0.0 };
    let sphere = Light::Point { position: glam::DVec3::new(0.0, 1.5, 0.0), intensity: Vec3::splat(10.0), radius: 1.0 };
    let light = gpu_lights(&[sphere])[0];
    let mut worst = 0.0f64;
    for x in [0.0f32, 0.5, 1.0, 2.0, 3.0] {
        let p = Vec3::new(x, 0.0, 0.0);
        let v = Vec3::new(-0.2, 0.8, 0.3).normalize();
        let c = light_cap(&light, p).expect("a sphere light has a cap");
        // In the floor's frame (normal +y): rotate so that the floor normal is +z.
        let to_z = |d: Vec3| Vec3::new(d.x, -d.z, d.y);
        let local = Cap { axis: to_z(c.axis), ..c };
        let num = numerical(to_z(v), &material, &local, 400);
        let shaded = shade_point(p, Vec3::Y, v, &material, &[light], |_| 1.0).as_dvec3();
        let error = ((shaded - num).abs() / num).max_element();
        println!("x = {x}: shaded {:.5} numerical {:.5} error {:.3} %", shaded.x, num.x, 100.0 * error);
        worst = worst.max(error);
    }
    assert!(worst < 0.01, "the sphere light is off by {:.2} %", 100.0 * worst);
}

#[test]
fn from_afar_a_sphere_or_disk_light_shades_as_its_point() {
    // Intensity keeps its meaning: W/sr from afar (sphere), W/m^2 on a surface facing it (disk),
    // so scenes that exist render the same from far away.
    let material = Material { base_color: Vec3::new(0.7, 0.5, 0.3), roughness: 0.5, metallic: 0.3 };
    let p = Vec3::new(0.3, 0.0, -0.2);
    let v = Vec3::new(0.1, 1.0, 0.4).normalize();
    let position = glam::DVec3::new(30.0, 40.0, 10.0);
    let intensity = Vec3::new(400.0, 300.0, 200.0);
    let pairs = [
        (Light::Point { position, intensity, radius: 0.0 }, Light::Point { position, intensity, radius: 0.05 }),
        (
            Light::Directional {
                direction: Vec3::new(-0.3, -1.0, 0.2),
                irradiance: intensity,
                angular_diameter_deg: 0.0,
            },
            Light::Directional {
                direction: Vec3::new(-0.3, -1.0, 0.2),
                irradiance: intensity,
                angular_diameter_deg: 0.53,
            },
        ),
        (
            Light::Spot {
                position,
                direction: -position.as_vec3(),
                intensity,
                inner_deg: 20.0,
                outer_deg: 30.0,
                radius: 0.0,
            },
            Light::Spot {
                position,
                direction: -position.as_vec3(),
                intensity,
                inner_deg: 20.0,
                outer_deg: 30.0,
                radius: 0.05,
            },
        ),
    ];
    for (hard, sized) in pairs {
        let lights = gpu_lights(&[hard, sized]);
        let point = shade_point(p, Vec3::Y, v, &material, &lights[..1], |_| 1.0);
        let area = shade_point(p, Vec3::Y, v, &material, &lights[1..], |_| 1.0);
        let error = ((area - point).abs() / point).max_element();
        println!("{sized:?}: point {point} area {area} error {:.3} %", 100.0 * error);
        assert!(point.min_element() > 0.0, "{point}");
        // The LTC corrected by the true lobe at the light's direction (ltc::lobe_integral) is
        // the point light's value for a light this small: measured 0.001 %.
        assert!(error < 1e-4, "{sized:?}: {point} as a point, {area} as an area light");
    }
}

const W: u32 = 96;
const H: u32 = 72;

/// A floor and a sphere under a large, low sphere light and a sun with a wide disk.
fn scene(material: &str) -> String {
    format!(
        "background = [0, 0, 0]\n\
         [camera]\neye = [0.0, 2.2, 5.0]\ntarget = [0.0, 0.5, 0.0]\nvfov_deg = 55.0\n\
         [[lights]]\ntype = \"point\"\nposition = [1.2, 1.3, -0.5]\nintensity = [6.0, 5.0, 4.0]\nradius = 0.8\n\
         [[lights]]\ntype = \"directional\"\ndirection = [0.4, -0.5, -0.6]\nirradiance = [1.0, 1.2, 1.5]\n\
         angular_diameter_deg = 20.0\n\
         [[objects]]\nshape = \"plane\"\nsize = 8.0\nmaterial = {material}\n\
         [[objects]]\nshape = \"sphere\"\nradius = 0.5\nsegments = 96\ntranslate = [-0.6, 0.5, 0.3]\n\
         material = {material}\n"
    )
}

/// A scene-linear frame with every light unshadowed.
fn render(renderer: &mut Renderer, view: Option<DebugView>) -> Vec<Vec4> {
    use umbra::config::{ShadowChoice, ShadowMethod};
    let mut settings =
        RenderSettings::new(W, H, OutputKind::SceneLinear).all_lights(2, ShadowChoice::of(ShadowMethod::None));
    settings.debug_view = view;
    common::floats(renderer.render(&settings).expect("render"))
}

/// A scene file's inline material table.
fn material_text(base: Vec3, roughness: f32, metallic: f32) -> String {
    format!("{{ base_color = [{}, {}, {}], roughness = {roughness}, metallic = {metallic} }}", base.x, base.y, base.z)
}

#[test]
fn gpu_sphere_and_disk_shading_matches_the_cpu_twin() {
    let ctx = common::gpu();
    let materials = [(Vec3::new(0.75, 0.5, 0.25), 0.5f32, 0.0f32), (Vec3::new(1.0, 0.75, 0.5), 0.25, 1.0)];
    for (base, roughness, metallic) in materials {
        let text = material_text(base, roughness, metallic);
        let scene = Scene::parse(&scene(&text), "area.toml", Path::new(".")).unwrap();
        let eye = scene.camera.eye.as_vec3();
        let lights = gpu_lights(&scene.lights);
        let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
        let plan = renderer.plan(&RenderSettings::new(W, H, OutputKind::SceneLinear));
        let plan = plan.expect("plan").to_string();
        assert!(plan.contains("LTC table") && plan.contains("area lights"), "{plan}");
        let radiance = render(&mut renderer, None);
        let position = render(&mut renderer, Some(DebugView::Position));
        let normal = render(&mut renderer, Some(DebugView::Normal));
        let depth = render(&mut renderer, Some(DebugView::Depth));
        let material = Material { base_color: base, roughness, metallic };
        let (mut lit, mut worst, mut dim) = (0, 0.0f32, 0);
        let brightest = radiance.iter().map(|r| r.truncate().max_element()).fold(0.0f32, f32::max);
        for i in 0..radiance.len() {
            let got = radiance[i].truncate();
            if depth[i].x <= 0.0 {
                assert_eq!(got, Vec3::ZERO, "pixel {i}: background");
                continue;
            }
            let p = position[i].truncate();
            let n = normal[i].truncate().normalize();
            let twin = shade_point(p, n, (eye - p).normalize(), &material, &lights, |_| 1.0);
            // The G-buffer's position and normal, read back, are the twin's inputs: both sides
            // shade the same point to float rounding, within 0.2 % of the pixel; or within 0.01 %
            // of the brightest pixel, for a few pixels seen at grazing views where the lobe is
            // integrated numerically (`ltc::lobe_over_polygon`) and the two sides' f32 differ by
            // up to 0.7 % of the pixel: a lobe's dim tail, where the light is a sliver near the
            // fitted cosine's horizon (there an f64 twin of the same quadrature agreed with the
            // CPU to 0.01 %), or the sphere's rim seen at 87 degrees. 20 of 3,822 pixels for the
            // rough metal, none for the dielectric.
            let bound = twin * 2e-3 + Vec3::splat(1e-5);
            let close = (got - twin).abs().cmple(bound).all();
            assert!(
                close || (got - twin).abs().cmple(twin * 2e-3 + Vec3::splat(1e-4 * brightest)).all(),
                "pixel {i}: GPU {got} CPU {twin}"
            );
            dim += !close as usize;
            if twin.max_element() > 1e-2 {
                worst = worst.max((got - twin).abs().max_element() / twin.max_element());
            }
            lit += (twin.max_element() > 1e-3) as usize;
        }
        println!(
            "{material:?}: {lit} lit pixels, GPU within {worst:.1e} of the CPU twin ({dim} dim pixels within \
             1e-4 of the brightest, {brightest:.3})"
        );
        assert!(lit > 2000, "{lit}");
    }
    common::assert_clean(&ctx);
}

#[test]
fn gpu_small_caps_by_cubature_match_the_cpu_twin() {
    // The scene of gpu_sphere_and_disk_shading_matches_the_cpu_twin with a 5 cm bulb and a
    // 2 degree sun: caps a twentieth to a tenth of a rough lobe's width, which shading takes by
    // the 4-point cubature (`lighting::cap_cubature`), and for the smoother metal partly by the
    // blend with the LTC and partly by the LTC. Same bound as that test; measured within 0.87 of
    // it (the dielectric, at a pixel of the sphere's terminator a thousandth of the brightest,
    // whose cap the horizon cuts) and 0.77 (the metal).
    use umbra::lighting::cap_cubature;
    let ctx = common::gpu();
    let materials = [(Vec3::new(0.75, 0.5, 0.25), 0.6f32, 0.0f32), (Vec3::new(1.0, 0.75, 0.5), 0.35, 1.0)];
    for (base, roughness, metallic) in materials {
        let text = material_text(base, roughness, metallic);
        let text = scene(&text)
            .replace("radius = 0.8", "radius = 0.05")
            .replace("angular_diameter_deg = 20.0", "angular_diameter_deg = 2.0");
        let scene = Scene::parse(&text, "small.toml", Path::new(".")).unwrap();
        let eye = scene.camera.eye.as_vec3();
        let lights = gpu_lights(&scene.lights);
        let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
        let [radiance, position, normal, depth] =
            [None, Some(DebugView::Position), Some(DebugView::Normal), Some(DebugView::Depth)]
                .map(|view| render(&mut renderer, view));
        let material = Material { base_color: base, roughness, metallic };
        let brightest = radiance.iter().map(|r| r.truncate().max_element()).fold(0.0f32, f32::max);
        // Pixels lit through the cubature alone, the blend and the LTC alone (a light each).
        let (mut paths, mut worst) = ([0usize; 3], 0.0f32);
        for i in (0..radiance.len()).filter(|&i| depth[i].x > 0.0) {
            let (got, p) = (radiance[i].truncate(), position[i].truncate());
            let n = normal[i].truncate().normalize();
            let twin = shade_point(p, n, (eye - p).normalize(), &material, &lights, |_| 1.0);
            let e = ((got - twin).abs() / (twin * 2e-3 + Vec3::splat(1e-4 * brightest))).max_element();
            assert!(e <= 1.0, "pixel {i}: GPU {got} CPU {twin}");
            worst = worst.max(e);
            for light in &lights {
                if let Some(cap) = umbra::shading::shaded_cap(light, p).filter(|c| n.dot(c.axis) > 0.0) {
                    let w = cap_cubature::weight(cap.one_minus_cos, roughness);
                    let path = if w >= 1.0 { 0 } else { 1 + usize::from(w == 0.0) };
                    paths[path] += 1;
                }
            }
        }
        println!(
            "{material:?}: light-pixels by cubature, blend, LTC: {paths:?}; GPU within {worst:.2} of the twin's bound"
        );
        if metallic > 0.0 {
            assert!(paths.iter().all(|&p| p > 500), "{paths:?}");
        } else {
            assert!(paths[0] > 5000, "{paths:?}");
        }
    }
    common::assert_clean(&ctx);
}

#[test]
fn a_scene_of_hard_lights_pays_nothing_for_area_shading() {
    let ctx = common::gpu();
    let hard = scene("{ roughness = 0.5 }").replace("radius = 0.8\n", "").replace("angular_diameter_deg = 20.0\n", "");
    let scene = Scene::parse(&hard, "area.toml", Path::new(".")).unwrap();
    let renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    let settings = RenderSettings::new(W, H, OutputKind::SceneLinear);
    let plan = renderer.plan(&settings).expect("plan").to_string();
    assert!(!plan.contains("LTC") && !plan.contains("area lights"), "{plan}");
    drop(renderer);
    common::assert_clean(&ctx);
}

/// Sphere radii (m) and sun angular diameters (degrees) from ordinary to absurdly small, all
/// legal: below `shading::CAP_MIN_ONE_MINUS_COS` (3e-4 rad) shading takes the hard light, above
/// it the LTC. Before, f32 cancellation made a 1e-5 m sphere up to 3.6 times its hard light and
/// a 1e-7 m one 882 times, and a size whose square underflows NaN (radiance inf times a zero
/// form factor).
const TINY_RADII: [f32; 8] = [1e-2, 3e-3, 1e-3, 1e-5, 1e-7, 1e-10, 1e-20, 1e-40];
const TINY_SUNS_DEG: [f32; 6] = [0.2, 0.05, 1e-3, 1e-9, 1e-18, 1e-30];

/// The lights of `tiny_lights_shade_as_their_hard_light`: a point light 2.6 m from the origin
/// and a sun, of the given radius and angular diameter (0: hard).
fn tiny_lights(radius: f32, sun_deg: f32) -> [Light; 2] {
    [
        Light::Point { position: glam::DVec3::new(0.8, 2.2, 1.2), intensity: Vec3::new(6.0, 5.0, 4.0), radius },
        Light::Directional {
            direction: Vec3::new(0.4, -1.0, -0.3),
            irradiance: Vec3::new(1.0, 1.2, 1.5),
            angular_diameter_deg: sun_deg,
        },
    ]
}

#[test]
fn tiny_lights_shade_as_their_hard_light() {
    // CPU: each light alone at points of a floor seen from above, for a rough dielectric and
    // a smooth-ish metal, against the hard light of the same intensity.
    let materials = [
        Material { base_color: Vec3::new(0.7, 0.5, 0.3), roughness: 0.5, metallic: 0.0 },
        Material { base_color: Vec3::new(0.9, 0.8, 0.6), roughness: 0.2, metallic: 1.0 },
    ];
    let hard = gpu_lights(&tiny_lights(0.0, 0.0));
    let (mut worst_ltc, mut worst_ltc_metal, mut worst_hard, mut cases) = (0.0f32, 0.0f32, 0.0f32, 0);
    for k in 0..TINY_RADII.len().max(TINY_SUNS_DEG.len()) {
        let radius = TINY_RADII[k.min(TINY_RADII.len() - 1)];
        let sun = TINY_SUNS_DEG[k.min(TINY_SUNS_DEG.len() - 1)];
        let sized = gpu_lights(&tiny_lights(radius, sun));
        for material in &materials {
            for (x, z) in [(0.0f32, 0.0f32), (0.5, -0.3), (-0.7, 0.4), (1.0, 1.0), (-1.5, -1.2)] {
                let p = Vec3::new(x, 0.0, z);
                let v = (Vec3::new(0.3, 2.0, 2.5) - p).normalize();
                for i in 0..2 {
                    let point = shade_point(p, Vec3::Y, v, material, &hard[i..=i], |_| 1.0);
                    let area = shade_point(p, Vec3::Y, v, material, &sized[i..=i], |_| 1.0);
                    assert!(area.is_finite(), "light {i}, radius {radius}, sun {sun} deg at {p}: {area}");
                    let error = ((area - point).abs() / point).max_element();
                    if umbra::shading::shaded_cap(&sized[i], p).is_some() {
                        let worst = if material.metallic > 0.0 { &mut worst_ltc_metal } else { &mut worst_ltc };
                        *worst = worst.max(error);
                    } else {
                        worst_hard = worst_hard.max(error);
                    }
                    cases += 1;
                }
            }
        }
    }
    println!(
        "tiny lights on the CPU: {cases} cases; the hard light's value to {worst_hard:.1e} below the threshold, \
         {worst_ltc:.1e} (dielectric) and {worst_ltc_metal:.1e} (metal) above it (by LTC)"
    );
    assert_eq!(worst_hard, 0.0, "below the threshold shading is the hard light's");
    // LTC over a cap of 1e-3 to 6e-3 rad: the cap's own difference from the point and f32
    // both below 1e-3 for the rough dielectric; the metal (roughness 0.2) sees these lights in
    // its lobe's tail, where the fitted LTC itself is a few % off whatever the light's size
    // (7 % measured; the same at 1e-2 rad).
    assert!(worst_ltc < 1e-3, "{worst_ltc}");
    assert!(worst_ltc_metal < 0.1, "{worst_ltc_metal}");
    // Radius 3e-3 m at 2.6 m (1.15e-3 rad) and the 0.2 degree sun go through the LTC, radius
    // 1e-3 m and the 0.05 degree sun (4.4e-4 rad) not.
    let shaded = |radius, sun| {
        let lights = gpu_lights(&tiny_lights(radius, sun));
        lights.iter().map(|l| umbra::shading::shaded_cap(l, Vec3::ZERO).is_some()).collect::<Vec<_>>()
    };
    assert_eq!(shaded(3e-3, 0.2), [true, true]);
    assert_eq!(shaded(1e-3, 0.05), [false, false]);

    // GPU: a floor and a sphere lit by both lights, every tiny size against the hard frame.
    let ctx = common::gpu();
    let renderer_for = |radius: f32, sun: f32| {
        let mut text = "background = [0, 0, 0]\n[camera]\neye = [0.0, 2.2, 5.0]\ntarget = [0.0, 0.5, 0.0]\n\
                        vfov_deg = 55.0\n"
            .to_owned();
        for light in tiny_lights(radius, sun) {
            text += &match light {
                Light::Point { position, intensity, radius } => format!(
                    "[[lights]]\ntype = \"point\"\nposition = [{}, {}, {}]\nintensity = [{}, {}, {}]\nradius = {radius:e}\n",
                    position.x, position.y, position.z, intensity.x, intensity.y, intensity.z
                ),
                Light::Directional { direction, irradiance, angular_diameter_deg } => format!(
                    "[[lights]]\ntype = \"directional\"\ndirection = [{}, {}, {}]\nirradiance = [{}, {}, {}]\n\
                     angular_diameter_deg = {angular_diameter_deg:e}\n",
                    direction.x, direction.y, direction.z, irradiance.x, irradiance.y, irradiance.z
                ),
                _ => unreachable!(),
            };
        }
        text += "[[objects]]\nshape = \"plane\"\nsize = 8.0\nmaterial = { base_color = [0.7, 0.5, 0.3], roughness = 0.5 }\n\
                 [[objects]]\nshape = \"sphere\"\nradius = 0.5\nsegments = 96\ntranslate = [-0.6, 0.5, 0.3]\n\
                 material = { base_color = [0.9, 0.8, 0.6], roughness = 0.2, metallic = 1.0 }\n";
        let scene = Scene::parse(&text, "tiny.toml", Path::new(".")).unwrap();
        Renderer::new(ctx.clone(), scene).expect("renderer")
    };
    // The views come from the hard frame's renderer (the geometry is the same in every frame).
    let (reference, position, normal, depth) = {
        let mut renderer = renderer_for(0.0, 0.0);
        let views = [None, Some(DebugView::Position), Some(DebugView::Normal), Some(DebugView::Depth)];
        let [r, p, n, d] = views.map(|view| render(&mut renderer, view));
        (r, p, n, d)
    };
    let eye = Vec3::new(0.0, 2.2, 5.0);
    let brightest = reference.iter().map(|r| r.truncate().max_element()).fold(0.0f32, f32::max);
    let lit = reference.iter().filter(|r| r.truncate().max_element() > 1e-3).count();
    assert!(lit > 2000, "{lit}");
    let material = |p: Vec3| {
        if p.y > 1e-3 {
            Material { base_color: Vec3::new(0.9, 0.8, 0.6), roughness: 0.2, metallic: 1.0 }
        } else {
            Material { base_color: Vec3::new(0.7, 0.5, 0.3), roughness: 0.5, metallic: 0.0 }
        }
    };
    for (k, radius) in TINY_RADII.iter().enumerate() {
        let sun = TINY_SUNS_DEG[k.min(TINY_SUNS_DEG.len() - 1)];
        let lights = gpu_lights(&tiny_lights(*radius, sun));
        let sized = render(&mut renderer_for(*radius, sun), None);
        let non_finite = sized.iter().filter(|p| !p.truncate().is_finite()).count();
        let (mut worst_twin, mut worst_hard, mut by_ltc) = (0.0f32, 0.0f32, 0);
        for i in (0..sized.len()).filter(|&i| depth[i].x > 0.0) {
            let (got, hard) = (sized[i].truncate(), reference[i].truncate());
            let p = position[i].truncate();
            let twin =
                shade_point(p, normal[i].truncate().normalize(), (eye - p).normalize(), &material(p), &lights, |_| 1.0);
            // As gpu_sphere_and_disk_shading_matches_the_cpu_twin: 0.2 % of the pixel, or
            // 1e-4 of the brightest for a lobe's dim tail.
            let e = ((got - twin).abs() / (twin * 2e-3 + Vec3::splat(1e-4 * brightest))).max_element();
            worst_twin = worst_twin.max(e);
            if lights.iter().any(|l| umbra::shading::shaded_cap(l, p).is_some()) {
                by_ltc += 1;
            } else {
                worst_hard =
                    worst_hard.max(((got - hard).abs() / hard.max(Vec3::splat(1e-3 * brightest))).max_element());
            }
        }
        println!(
            "GPU, radius {radius:e} m, sun {sun:e} deg: {non_finite} non-finite pixels; {by_ltc} pixels by LTC; \
             the others within {worst_hard:.1e} of the hard lights' frame; all within {worst_twin:.2} of the twin's bound"
        );
        assert_eq!(non_finite, 0, "radius {radius}, sun {sun}");
        assert!(worst_twin <= 1.0, "radius {radius}, sun {sun}: {worst_twin}");
        assert!(worst_hard < 1e-5, "radius {radius}, sun {sun}: {worst_hard}");
        // The 1e-2 m sphere and the 0.2 degree sun everywhere, the 3e-3 m sphere where it is
        // 1e-3 rad or more, go through the LTC; smaller sizes never.
        assert_eq!(by_ltc > 0, k < 2, "radius {radius}: {by_ltc}");
    }
    common::assert_clean(&ctx);
}

/// A smooth lobe's specular tail from a small sun: roughness 0.05, a 0.53 degree sun from the
/// mirror direction to 10 degrees off it, against numerical integration of the cap.
fn smooth_lobe_tail_errors() -> Vec<(f32, f32, f32, f64)> {
    let mut errors = Vec::new();
    for view_deg in [30.0f32, 45.0, 55.0] {
        for metallic in [1.0f32, 0.0] {
            for off_deg in [0.0f32, 1.0, 2.0, 3.0, 5.0, 7.5, 10.0] {
                let material = Material { base_color: Vec3::new(0.9, 0.6, 0.3), roughness: 0.05, metallic };
                let (t, o) = (view_deg.to_radians(), off_deg.to_radians());
                // The mirror direction turned by off_deg, half toward the normal, half sideways.
                let mirror = Vec3::new(-t.sin(), 0.0, t.cos());
                let axis = (mirror * o.cos()
                    + Vec3::new(t.cos(), 0.0, t.sin()).normalize() * (o.sin() * 0.6)
                    + Vec3::Y * (o.sin() * 0.8))
                    .normalize();
                let c = Cap { axis, ..cap(0.265, 0.0) };
                errors.push((view_deg, metallic, off_deg, shading_error(view_deg, &material, &c, 60)));
            }
        }
    }
    errors
}

#[test]
fn a_smooth_lobes_tail_from_a_small_sun() {
    // The ratio correction (ltc::lobe_integral) used to fade out by the fitted cosine's z at
    // the light, which a smooth lobe's matrix (entries ~240-480) sends to 0.04-0.10 for a light
    // 2-10 degrees off the mirror: the tail got 45-55 % less than the integral (the metal; the
    // dielectric's Lambert hid most of it). Fading on n.l alone it is within 0.6 %.
    let (mut worst_tail, mut worst_mirror) = (0.0f64, 0.0f64);
    for (view, metallic, off, error) in smooth_lobe_tail_errors() {
        println!(
            "roughness 0.05 metallic {metallic} view {view} sun {off:>4} deg off the mirror: error {:.2} %",
            100.0 * error
        );
        if off == 0.0 {
            worst_mirror = worst_mirror.max(error);
        } else {
            worst_tail = worst_tail.max(error);
        }
    }
    println!("worst: {:.2} % in the tail, {:.2} % on the mirror", 100.0 * worst_tail, 100.0 * worst_mirror);
    assert!(worst_tail < 0.01, "{worst_tail}");
    // On the mirror direction the sun covers much of this lobe and the plain LTC (the fitted
    // lobe's shape) takes over: 10 % measured, as before this change.
    assert!(worst_mirror < 0.11, "{worst_mirror}");
}

/// A point on or inside a sphere light sees the hemisphere around the direction to its centre
/// (`shading::light_cap`). Its polygon lay on a great circle through the point, where the
/// horizon clip divided by almost nothing: a 0.5 m bulb 0.3 m above a floor gave radiance up to
/// 5.6e7 where about 5 is right, and a 100 m sphere around the scene white speckles where
/// 1e-4 is. Now: the CPU twin within 1 % of numerical integration under the bulb (a view 25
/// degrees from the normal), and on the GPU every pixel finite and within the twin's bound.
#[test]
fn points_inside_a_sphere_light_see_the_hemisphere_toward_its_centre() {
    use umbra::config::{ShadowChoice, ShadowMethod};
    let material = Material { base_color: Vec3::splat(0.8), roughness: 0.5, metallic: 0.0 };
    let bulb = Light::Point { position: glam::DVec3::new(0.0, 0.3, 0.0), intensity: Vec3::splat(5.0), radius: 0.5 };
    let light = gpu_lights(&[bulb])[0];
    let v = Vec3::new(-0.2, 0.8, 0.3).normalize();
    let to_z = |d: Vec3| Vec3::new(d.x, -d.z, d.y);
    for x in [0.0f32, 0.2, 0.39, 0.4001, 0.45] {
        let p = Vec3::new(x, 0.0, 0.0);
        let c = light_cap(&light, p).expect("a sphere light has a cap");
        let num = numerical(to_z(v), &material, &Cap { axis: to_z(c.axis), ..c }, 400);
        let shaded = shade_point(p, Vec3::Y, v, &material, &[light], |_| 1.0).as_dvec3();
        let error = ((shaded - num).abs() / num).max_element();
        println!(
            "x = {x}: 1 - cos {:.4}, shaded {:.4} numerical {:.4} ({:.2} %)",
            c.one_minus_cos,
            shaded.x,
            num.x,
            100.0 * error
        );
        assert!(error < 0.01, "x = {x}: shaded {shaded} numerical {num}");
    }

    let ctx = common::gpu();
    let bulb_scene = "[camera]\neye = [0.0, 2.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 50.0\n\
        [[lights]]\ntype = \"point\"\nposition = [0.0, 0.3, 0.0]\nintensity = [5.0, 5.0, 5.0]\nradius = 0.5\n\
        [[objects]]\nshape = \"plane\"\nsize = 6.0\n\
        material = { base_color = [0.8, 0.8, 0.8], roughness = 0.5, metallic = 0.0 }\n";
    for (name, text) in
        [("bulb", bulb_scene.to_string()), ("enclosing sphere", bulb_scene.replace("radius = 0.5", "radius = 100.0"))]
    {
        let scene = Scene::parse(&text, "inside.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
        let eye = scene.camera.eye.as_vec3();
        let lights = gpu_lights(&scene.lights);
        let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
        let frame = |r: &mut Renderer, view| {
            let mut s =
                RenderSettings::new(W, H, OutputKind::SceneLinear).all_lights(1, ShadowChoice::of(ShadowMethod::None));
            s.debug_view = view;
            common::floats(r.render(&s).expect("render"))
        };
        let radiance = frame(&mut r, None);
        let position = frame(&mut r, Some(DebugView::Position));
        let depth = frame(&mut r, Some(DebugView::Depth));
        let (mut twins, mut worst, mut inside) = (Vec::new(), 0.0f32, 0);
        for i in (0..radiance.len()).filter(|&i| depth[i].x > 0.0) {
            let p = position[i].truncate();
            inside +=
                usize::from((p - Vec4::from_array(lights[0].position_kind).truncate()).length() < lights[0].size[0]);
            let twin = shade_point(p, Vec3::Y, (eye - p).normalize(), &material, &lights, |_| 1.0);
            twins.push((i, twin));
        }
        let brightest = twins.iter().map(|t| t.1.max_element()).fold(0.0f32, f32::max);
        for &(i, twin) in &twins {
            let got = radiance[i].truncate();
            assert!(got.is_finite(), "{name}: pixel {i} is {got}");
            worst = worst.max(((got - twin).abs() / (twin * 2e-3 + Vec3::splat(1e-4 * brightest))).max_element());
        }
        let got_max = radiance.iter().map(|p| p.truncate().max_element()).fold(0.0f32, f32::max);
        println!("{name}: {inside} pixels inside the sphere; brightest {got_max:.4e} (twin {brightest:.4e}); GPU within {worst:.2} of the twin's bound");
        assert!(inside > 100, "{name}: the view must hold points inside the light ({inside})");
        assert!(worst <= 1.0, "{name}: GPU off the twin by {worst} of the bound");
    }
    common::assert_clean(&ctx);
}
