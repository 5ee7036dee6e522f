//! The shadow terminator: on a smooth-shaded low-polygon mesh, a hard shadow's edge on the object
//! itself used to be a staircase of facets, because a ray leaving a flat facet near the lit/unlit
//! boundary (where the shading normal still faces the light) runs into the neighbouring facets.
//! The geometry pass now stores, per pixel, Hanika's offset ("Hacking the shadow terminator",
//! Ray Tracing Gems II, ch. 4) from the triangle's vertex normals and the geometric normal, and
//! the traced pass starts its rays there; the CPU twin (`shading::Surfaces`) does the same.
//!
//! A 32-segment sphere lit from the side by a hard directional light, with nothing else in the
//! scene: every pixel whose shading normal faces the light must be lit. The CPU twin traced
//! without the offset shows the staircase the fix removes (measured at 160x160: 180 of the 7975
//! such pixels self-shadowed, 2.3 %, with the ray pushed along the geometric normal or, as before
//! the fix, along the shading normal; the GPU rendered the same 180 before the fix); a
//! 256-segment sphere has none either way.

use crate::common;

use std::path::Path;

use glam::{Vec3, Vec4};
use umbra::config::{DebugView, ShadowChoice};
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowBackend};
use umbra::scene::bvh::{offset_ray_origin, ShadowBvh};
use umbra::scene::Scene;
use umbra::shading::{
    f16_round, flat_shaded, oct_decode, oct_encode, surface_quantised, terminator_offset, triangle_barycentrics,
    Surfaces,
};

const W: u32 = 160;
const H: u32 = 160;
/// The direction the light travels: from the right, a little from above and in front, so the
/// terminator crosses the sphere's facets obliquely.
const LIGHT_TRAVELS: Vec3 = Vec3::new(-1.0, -0.35, -0.2);
/// `ShadowBvh::ray_near_edge` tolerance, as in render_accuracy.rs.
const EDGE_EPS: f64 = 1e-6;

fn sphere(segments: u32) -> Scene {
    let d = LIGHT_TRAVELS;
    let text = format!(
        r#"
[camera]
eye = [0.0, 0.0, 3.2]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0

[[lights]]
type = "directional"
direction = [{}, {}, {}]
irradiance = [2.0, 2.0, 2.0]

[[objects]]
shape = "sphere"
radius = 1.0
segments = {segments}
"#,
        d.x, d.y, d.z
    );
    Scene::parse(&text, "terminator.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

fn frame(r: &mut Renderer, backend: ShadowBackend, view: DebugView) -> Vec<Vec4> {
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.debug_view = Some(view);
    s.shadows = vec![ShadowChoice::hard()];
    s.shadow_backend = backend;
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
    pixels.chunks_exact(4).map(Vec4::from_slice).collect()
}

/// One render's G-buffer and the first light's visibility.
struct Views {
    covered: Vec<bool>,
    position: Vec<Vec3>,
    normal: Vec<Vec3>,
    visibility: Vec<f32>,
}

fn render(scene: &Scene, backend: ShadowBackend) -> Views {
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let visibility = frame(&mut r, backend, DebugView::Visibility(0)).iter().map(|v| v.x).collect();
    let position = frame(&mut r, backend, DebugView::Position).iter().map(|p| p.truncate()).collect();
    let normal = frame(&mut r, backend, DebugView::Normal).iter().map(|n| n.truncate()).collect();
    let covered = frame(&mut r, backend, DebugView::Depth).iter().map(|d| d.x > 0.0).collect();
    drop(r);
    common::assert_clean(&ctx);
    Views { covered, position, normal, visibility }
}

/// Toward the light.
fn to_light() -> Vec3 {
    -LIGHT_TRAVELS.normalize()
}

/// Pixels of the sphere whose shading normal faces the light: all of them should be lit.
fn facing(v: &Views) -> Vec<usize> {
    (0..v.covered.len()).filter(|&i| v.covered[i] && v.normal[i].dot(to_light()) > 0.0).collect()
}

/// How many of `pixels` a CPU-traced ray from `origin(i)` finds shadowed.
fn cpu_shadowed(scene: &Scene, pixels: &[usize], origin: impl Fn(usize) -> Vec3) -> usize {
    let bvh = ShadowBvh::build(scene);
    pixels.iter().filter(|&&i| bvh.occluded_obvhs(origin(i), to_light(), 1e30)).count()
}

/// The GPU's self-shadowed count on `scene`, and the CPU twin's without the terminator offset
/// (pushed along the geometric normal, then along the shading normal as before the fix), with
/// every pixel checked against the CPU twin with the offset.
fn self_shadowed(scene: &Scene, backend: ShadowBackend) -> (usize, usize, usize, usize) {
    let v = render(scene, backend);
    let lit = facing(&v);
    let surfaces = Surfaces::new(scene);
    let eye = scene.camera.eye.as_vec3();
    let at = |i: usize| surfaces.at(v.position[i], eye, 1e-4).expect("a triangle under the pixel");
    let gpu = lit.iter().filter(|&&i| v.visibility[i] == 0.0).count();
    let geometric_only = cpu_shadowed(scene, &lit, |i| offset_ray_origin(v.position[i], at(i).geometric_normal));
    let shading_only = cpu_shadowed(scene, &lit, |i| offset_ray_origin(v.position[i], v.normal[i]));
    // The twin, pixel by pixel: the same rays find the same answers (but where a ray grazes an
    // edge, where rounding may decide either way).
    let bvh = ShadowBvh::build(scene);
    let mut differ = Vec::new();
    for &i in &lit {
        let origin = at(i).ray_origin(v.position[i]);
        let cpu = if bvh.occluded_obvhs(origin, to_light(), 1e30) { 0.0 } else { 1.0 };
        if cpu != v.visibility[i] && !bvh.ray_near_edge(origin, to_light(), 1e30, EDGE_EPS) {
            differ.push(format!("pixel {i}: gpu {} cpu {cpu}, p {}", v.visibility[i], v.position[i]));
        }
    }
    assert!(differ.is_empty(), "{} pixels differ from the CPU twin:\n{}", differ.len(), differ.join("\n"));
    (lit.len(), gpu, geometric_only, shading_only)
}

#[test]
fn a_32_segment_sphere_lit_from_the_side_has_no_self_shadowed_pixels() {
    let (lit, gpu, geometric_only, shading_only) = self_shadowed(&sphere(32), ShadowBackend::Compute);
    println!(
        "32 segments: {lit} pixels face the light; self-shadowed: {gpu} (GPU, terminator offset), without \
         the offset {geometric_only} ({:.2} %, pushed along the geometric normal) and {shading_only} ({:.2} %, \
         along the shading normal)",
        100.0 * geometric_only as f64 / lit as f64,
        100.0 * shading_only as f64 / lit as f64
    );
    assert!(lit > 5000, "{lit} pixels face the light");
    // The scene shows the staircase without the fix: this test would catch losing it.
    assert!(geometric_only > lit / 200 && shading_only > lit / 200, "{geometric_only}, {shading_only} of {lit}");
    assert_eq!(gpu, 0, "{gpu} of {lit} pixels facing the light are self-shadowed");
}

#[test]
fn a_256_segment_sphere_has_none_either() {
    let (lit, gpu, geometric_only, shading_only) = self_shadowed(&sphere(256), ShadowBackend::Compute);
    println!("256 segments: {lit} pixels face the light; self-shadowed {gpu}, without the offset {geometric_only} / {shading_only}");
    assert!(lit > 5000, "{lit} pixels face the light");
    assert_eq!((gpu, geometric_only, shading_only), (0, 0, 0));
}

#[test]
fn the_ray_query_backend_starts_its_rays_at_the_same_points() {
    let ctx = common::gpu();
    let ray_query = ctx.capabilities.ray_query;
    drop(ctx);
    if !ray_query {
        println!("no ray query on this device: nothing to compare");
        return;
    }
    let (lit, gpu, _, _) = self_shadowed(&sphere(32), ShadowBackend::RayQuery);
    println!("32 segments, ray query: {lit} pixels face the light; self-shadowed {gpu}");
    assert_eq!(gpu, 0, "{gpu} of {lit} pixels facing the light are self-shadowed");
}

/// The geometry pass's surface channel on the GPU agrees with its CPU twin where it matters
/// most: the terminator offset never moves a point inward, and lifts the sphere's facets
/// toward the sphere.
#[test]
fn the_terminator_offset_lifts_facets_toward_the_smooth_surface() {
    // A facet of a unit sphere: corners on it, radial normals.
    let corner =
        [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.9, 0.43589, 0.0), Vec3::new(0.9, 0.0, 0.43589)].map(|c| c.normalize());
    let normal = corner;
    let (e1, e2) = (corner[1] - corner[0], corner[2] - corner[0]);
    let face = e1.cross(e2).normalize();
    for b in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.5, 0.5, 0.0), Vec3::splat(1.0 / 3.0), Vec3::new(0.2, 0.3, 0.5)] {
        let p = b.x * corner[0] + b.y * corner[1] + b.z * corner[2];
        let bary = triangle_barycentrics(p, corner[0], e1, e2);
        assert!((bary - b).abs().max_element() < 1e-6, "{bary} for {b}");
        let offset = terminator_offset(p, corner, normal, bary);
        let lifted = p + offset;
        assert!(offset.dot(face) >= 0.0, "outward only");
        // Out of the facet, which lies inside the sphere, by no more than the farthest tangent
        // plane above the point (on a facet this coarse, 25 degrees, the blend bulges past the
        // sphere a little, as Phong tessellation does).
        let highest = corner.iter().zip(&normal).map(|(c, n)| (*c - p).dot(*n)).fold(0.0, f32::max);
        assert!(lifted.length() >= p.length() && offset.length() <= highest + 1e-6, "{b}: {offset}, {highest}");
        if b.max_element() == 1.0 {
            assert!(offset.length() < 1e-6, "a corner stays put: {offset}");
        } else {
            assert!(offset.length() > 1e-3, "{b}: {offset}");
        }
    }
    // Flat shading (every vertex normal the face's) and a concave corner move nothing.
    let p = (corner[0] + corner[1] + corner[2]) / 3.0;
    let bary = Vec3::splat(1.0 / 3.0);
    assert!(terminator_offset(p, corner, [face; 3], bary).length() < 1e-6);
    assert!(
        terminator_offset(p, corner, normal.map(|n| (2.0 * face.dot(n) * face - n).normalize()), bary).length() < 1e-6
    );
}

#[test]
fn the_surface_channel_encoding() {
    // f16 rounding, ties to even, with subnormals stored as 0.
    assert_eq!(f16_round(1.0 + 1.0 / 2048.0), 1.0);
    assert_eq!(f16_round(1.0 + 3.0 / 2048.0), 1.0 + 2.0 / 1024.0);
    assert_eq!(f16_round(-0.003), -0.0030002594);
    assert_eq!(f16_round(6.0e-5), 0.0);
    assert_eq!(f16_round(6.2e-5), 6.198883e-5);
    assert_eq!(f16_round(1e6), f32::INFINITY);
    // Octahedral normals, 8 bits a coordinate over 254 steps: axes exact, everything within a
    // degree (measured 0.92; the G-buffer uses it only to push rays 0.1 mm off the surface).
    for axis in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
        assert_eq!(surface_quantised(Vec3::ZERO, axis).geometric_normal, axis, "{axis}");
    }
    let mut worst = 0.0f32;
    let n = 200;
    for i in 0..n {
        for j in 0..2 * n {
            let theta = std::f32::consts::PI * (i as f32 + 0.5) / n as f32;
            let phi = std::f32::consts::PI * j as f32 / n as f32;
            let v = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            assert!((oct_decode(oct_encode(v)) - v).length() < 1e-5, "{v}");
            let q = surface_quantised(Vec3::ZERO, v).geometric_normal;
            worst = worst.max(q.dot(v).min(1.0).acos().to_degrees());
        }
    }
    println!("octahedral 8-bit geometric normal: worst error {worst:.3} degrees");
    assert!(worst < 1.0, "{worst} degrees");
}

/// The `geometric-normal` view shows what rays are pushed along: on the 32-segment sphere, a
/// unit face normal per facet (so far fewer distinct values than the smooth shading normal
/// takes), never more than a facet's angle from the shading normal, and zero on background.
#[test]
fn the_geometric_normal_view_shows_the_facets_the_shading_normal_smooths() {
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), sphere(32)).expect("renderer");
    let backend = ShadowBackend::Compute;
    let geometric = frame(&mut r, backend, DebugView::GeometricNormal);
    let shading = frame(&mut r, backend, DebugView::Normal);
    let covered: Vec<bool> = frame(&mut r, backend, DebugView::Depth).iter().map(|d| d.x > 0.0).collect();
    drop(r);
    common::assert_clean(&ctx);
    let key = |n: Vec3| (n * 100.0).round().as_ivec3().to_array();
    let (mut faces, mut smooth) = (std::collections::HashSet::new(), std::collections::HashSet::new());
    for i in 0..covered.len() {
        let (g, n) = (geometric[i].truncate(), shading[i].truncate());
        if !covered[i] {
            assert_eq!(g, Vec3::ZERO, "pixel {i}: background");
            continue;
        }
        assert!((g.length() - 1.0).abs() < 1e-3, "pixel {i}: {g} is not unit");
        // A 32-segment sphere's facets span 11.25 degrees: the shading normal stays within one.
        assert!(g.dot(n) > 11.25f32.to_radians().cos(), "pixel {i}: {g} against {n}");
        faces.insert(key(g));
        smooth.insert(key(n));
    }
    println!("{} distinct geometric normals, {} shading normals", faces.len(), smooth.len());
    assert!(faces.len() * 4 < smooth.len(), "{} facets against {} smooth normals", faces.len(), smooth.len());
}

/// The meshes of `scene` as the renderer uploads them (f32, the scene-local frame), flat or not.
fn flat_meshes(scene: &Scene) -> Vec<bool> {
    let (local, _) = scene.local_frame();
    local
        .meshes
        .iter()
        .map(|m| {
            let positions: Vec<Vec3> = m.positions.iter().map(|p| p.as_vec3()).collect();
            flat_shaded(&positions, &m.normals, &m.indices)
        })
        .collect()
}

/// A flat-shaded mesh (every corner has its face's normal) needs no terminator offset: the
/// geometry pass skips reading its triangles. Planes, cubes and OBJ meshes without normals are
/// flat; a sphere is not, nor is a cube with one normal tilted by 1e-4 or turned inside out.
#[test]
fn flat_shaded_meshes_are_told_from_smooth_ones() {
    let scene = Scene::parse(
        &common::scene(&[
            "[camera]\neye = [0.0, 1.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0",
            "[[objects]]\nshape = \"plane\"\nsize = 4.0\nsegments = 3",
            "[[objects]]\nshape = \"cube\"\nsize = 1.0\nrotate_deg = [10.0, 33.0, 5.0]\ntranslate = [0.3, 0.5, -0.2]",
            "[[objects]]\nshape = \"sphere\"\nradius = 0.5\nsegments = 16",
        ]),
        "flat.toml",
        Path::new("."),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(flat_meshes(&scene), [true, true, false]);
    let cube = &scene.meshes[1];
    let positions: Vec<Vec3> = cube.positions.iter().map(|p| p.as_vec3()).collect();
    let mut tilted = cube.normals.clone();
    tilted[5] = (tilted[5] + Vec3::new(1e-4, 0.0, 0.0)).normalize();
    assert!(!flat_shaded(&positions, &tilted, &cube.indices));
    let inside_out: Vec<Vec3> = cube.normals.iter().map(|n| -*n).collect();
    assert!(!flat_shaded(&positions, &inside_out, &cube.indices));
    // Within the tolerance (normals written with six decimals) it is still flat.
    let mut rounded = cube.normals.clone();
    for n in &mut rounded {
        *n = (*n * 1e6).round() / 1e6;
    }
    assert!(flat_shaded(&positions, &rounded, &cube.indices));
    // A degenerate triangle rasterises nothing and does not count.
    let mut indices = cube.indices.clone();
    indices.extend_from_slice(&[0, 0, 1]);
    assert!(flat_shaded(&positions, &cube.normals, &indices));
}

/// On a scene of flat and smooth meshes lit by a hard light, the G-buffer's geometric normal and
/// the traced visibility agree with the CPU twin at every covered pixel (the twin reads the
/// triangle under each pixel whatever its mesh; a flat mesh's geometric normal is its face's).
#[test]
fn flat_and_smooth_draws_match_the_twin() {
    let d = LIGHT_TRAVELS;
    let scene = Scene::parse(
        &format!(
            "[camera]\neye = [2.0, 2.5, 3.5]\ntarget = [0.0, 0.4, 0.0]\nvfov_deg = 45.0\n\
             [[lights]]\ntype = \"directional\"\ndirection = [{}, {}, {}]\nirradiance = [2.0, 2.0, 2.0]\n\
             [[objects]]\nshape = \"plane\"\nsize = 4.0\nsegments = 5\n\
             [[objects]]\nshape = \"cube\"\nsize = 0.6\nrotate_deg = [0.0, 30.0, 0.0]\ntranslate = [-0.6, 0.3, 0.2]\n\
             [[objects]]\nshape = \"sphere\"\nradius = 0.45\nsegments = 12\ntranslate = [0.5, 0.45, -0.1]\n",
            d.x,
            d.y - 1.0,
            d.z
        ),
        "flat-and-smooth.toml",
        Path::new("."),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(flat_meshes(&scene), [true, true, false]);
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let backend = ShadowBackend::Compute;
    let geometric = frame(&mut r, backend, DebugView::GeometricNormal);
    let position = frame(&mut r, backend, DebugView::Position);
    let visibility = frame(&mut r, backend, DebugView::Visibility(0));
    let normal = frame(&mut r, backend, DebugView::Normal);
    let covered: Vec<bool> = frame(&mut r, backend, DebugView::Depth).iter().map(|d| d.x > 0.0).collect();
    drop(r);
    common::assert_clean(&ctx);
    let surfaces = Surfaces::new(&scene);
    let eye = scene.camera.eye.as_vec3();
    let bvh = ShadowBvh::build(&scene);
    let travels = Vec3::new(d.x, d.y - 1.0, d.z).normalize();
    let (mut checked, mut shadowed, mut differ) = (0, 0, Vec::new());
    for i in (0..covered.len()).filter(|&i| covered[i]) {
        let p = position[i].truncate();
        // Pixels on an edge between meshes may take either triangle.
        let Some(twin) = surfaces.at(p, eye, 1e-4) else { continue };
        let g = geometric[i].truncate();
        assert!(
            g.dot(twin.geometric_normal) > 0.9999,
            "pixel {i}: geometric normal {g}, twin {}",
            twin.geometric_normal
        );
        checked += 1;
        // A pixel facing away from the light is unlit without a ray.
        if normal[i].truncate().dot(-travels) <= 0.0 {
            continue;
        }
        let origin = twin.ray_origin(p);
        let cpu = if bvh.occluded_obvhs(origin, -travels, 1e30) { 0.0 } else { 1.0 };
        if visibility[i].x != cpu && !bvh.ray_near_edge(origin, -travels, 1e30, EDGE_EPS) {
            differ.push(format!("pixel {i} at {p}: gpu {} cpu {cpu}", visibility[i].x));
        }
        shadowed += (cpu == 0.0) as usize;
    }
    println!("{checked} pixels checked, {shadowed} shadowed");
    assert!(differ.is_empty(), "{} pixels differ from the twin:\n{}", differ.len(), differ.join("\n"));
    assert!(checked > W as usize * H as usize / 2 && shadowed > 300, "{checked} pixels, {shadowed} shadowed");
}
