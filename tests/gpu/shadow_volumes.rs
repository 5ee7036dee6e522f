//! The `volumes` technique (stencil shadow volumes) against `traced`: a box over a floor that
//! casts nothing, under a spot, a directional and a point light, pixel by pixel away from
//! shadow edges; the camera inside the box's shadow, where z-fail stays right and z-pass goes
//! wrong; open and non-manifold casters, which send the light to `traced` with a message naming
//! the mesh; and the plan (depth copied, stencil written, then read). All with validation and
//! synchronization validation, at 160x120 at most.

use crate::common;

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use umbra::config::DebugView;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice, ShadowMethod};
use umbra::scene::{Mesh, Scene};
use umbra::shadows::volumes::VolumeParams;
use umbra::vk::GpuContext;

const W: u32 = 160;
const H: u32 = 120;

/// A box on a floor that casts no shadow (the built-in plane is open, so a casting floor would
/// refuse volumes), lit by a spot, a sun and a bulb, all hard.
const BOX_SCENE: &str = r#"
[camera]
eye = [0.0, 3.0, 4.5]
target = [0.0, 0.2, -0.3]
vfov_deg = 50.0

[[lights]]
type = "spot"
position = [1.6, 3.0, 1.2]
direction = [-0.45, -1.0, -0.4]
intensity = [30.0, 30.0, 30.0]
inner_deg = 40.0
outer_deg = 55.0

[[lights]]
type = "directional"
direction = [0.6, -0.8, 0.5]
irradiance = [1.0, 1.0, 1.0]

[[lights]]
type = "point"
position = [-1.8, 2.2, 1.0]
intensity = [20.0, 20.0, 20.0]

[[objects]]
shape = "plane"
size = 10.0
cast_shadows = false

[[objects]]
shape = "cube"
size = 1.2
translate = [0.0, 0.6, 0.0]
"#;

/// A box held up high under a bulb straight above it; the camera sits in its shadow, under it,
/// looking down and out at the floor: shadowed floor near, lit floor beyond.
const INSIDE_SCENE: &str = r#"
[camera]
eye = [0.15, 1.0, 0.1]
target = [2.0, 0.0, 0.6]
vfov_deg = 70.0

[[lights]]
type = "point"
position = [0.0, 7.0, 0.0]
intensity = [60.0, 60.0, 60.0]

[[objects]]
shape = "plane"
size = 12.0
cast_shadows = false

[[objects]]
shape = "cube"
size = 1.4
translate = [0.0, 2.4, 0.0]
"#;

fn load(text: &str) -> Scene {
    Scene::parse(text, "volumes.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

fn setup(scene: Scene) -> (Arc<GpuContext>, Renderer) {
    let ctx = common::gpu();
    assert!(ctx.capabilities.geometry_shader, "lavapipe offers geometry shaders");
    let r = Renderer::new(ctx.clone(), scene).expect("renderer");
    (ctx, r)
}

fn choice(method: ShadowMethod, zpass: bool) -> ShadowChoice {
    ShadowChoice { method, volumes: VolumeParams { zpass }, ..ShadowChoice::hard() }
}

fn settings(lights: usize, light: u32, choice: ShadowChoice) -> RenderSettings {
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.debug_view = Some(DebugView::Visibility(light));
    s.shadows = vec![choice; lights];
    s
}

/// Light `light`'s visibility, every light on `choice`.
fn visibility(r: &mut Renderer, lights: usize, light: u32, choice: ShadowChoice) -> Vec<f32> {
    let Frame::Rgba32F { pixels, .. } = r.render(&settings(lights, light, choice)).expect("render") else {
        panic!("float frame")
    };
    pixels.chunks_exact(4).map(|p| p[0]).collect()
}

struct Comparison {
    compared: usize,
    /// Lit in traced, shadowed here.
    false_shadow: usize,
    /// Shadowed in traced, lit here.
    leak: usize,
}

impl Comparison {
    fn disagree(&self) -> usize {
        self.false_shadow + self.leak
    }

    fn share(&self) -> f64 {
        self.disagree() as f64 / self.compared as f64
    }
}

fn compare(traced: &[f32], other: &[f32]) -> Comparison {
    let pixels = common::away_from_edges(traced, W, H, 3);
    let false_shadow = pixels.iter().filter(|&&i| traced[i] == 1.0 && other[i] < 0.5).count();
    let leak = pixels.iter().filter(|&&i| traced[i] == 0.0 && other[i] >= 0.5).count();
    Comparison { compared: pixels.len(), false_shadow, leak }
}

#[test]
fn volumes_agree_with_traced_for_spot_directional_and_point_lights() {
    let (ctx, mut r) = setup(load(BOX_SCENE));
    for (light, kind) in ["spot", "directional", "point"].iter().enumerate() {
        let traced = visibility(&mut r, 3, light as u32, choice(ShadowMethod::Traced, false));
        let volumes = visibility(&mut r, 3, light as u32, choice(ShadowMethod::Volumes, false));
        let plan = r.last_plan().expect("plan").to_string();
        let detail = format!("shadow volumes (light {light}, z-fail, 1 casters, 12 triangles)");
        assert!(plan.contains(&detail), "{plan}");
        assert!(!plan.contains("shadow trace"), "no light is traced:\n{plan}");
        let c = compare(&traced, &volumes);
        // Cast shadow: where the light reaches (its layer with shadows off) but traced says 0.
        let reach = visibility(&mut r, 3, light as u32, choice(ShadowMethod::None, false));
        let cast = (0..traced.len()).filter(|&i| reach[i] == 1.0 && traced[i] == 0.0).count();
        let cast_agree =
            (0..traced.len()).filter(|&i| reach[i] == 1.0 && traced[i] == 0.0 && volumes[i] == 0.0).count();
        let anywhere = (0..traced.len()).filter(|&i| (traced[i] < 0.5) != (volumes[i] < 0.5)).count();
        println!(
            "{kind} light: volumes vs traced: {} of {} pixels away from edges disagree ({:.3} %: {} false shadow, {} \
             leak), {anywhere} of {} anywhere; {cast} pixels of cast shadow in traced, {cast_agree} of them shadowed \
             by volumes",
            c.disagree(),
            c.compared,
            100.0 * c.share(),
            c.false_shadow,
            c.leak,
            traced.len()
        );
        assert!(cast > 300 && c.compared > (W * H) as usize / 2, "{kind}: the view must show a cast shadow");
        assert!(c.disagree() * 1000 <= c.compared, "{kind}: {} of {} disagree (over 0.1 %)", c.disagree(), c.compared);
        assert!(volumes.iter().all(|v| *v == 0.0 || *v == 1.0), "hard: 0 or 1");
    }
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn with_the_camera_inside_a_volume_z_fail_stays_right_and_z_pass_goes_wrong() {
    let (ctx, mut r) = setup(load(INSIDE_SCENE));
    let traced = visibility(&mut r, 1, 0, choice(ShadowMethod::Traced, false));
    let zfail = compare(&traced, &visibility(&mut r, 1, 0, choice(ShadowMethod::Volumes, false)));
    let zpass = compare(&traced, &visibility(&mut r, 1, 0, choice(ShadowMethod::Volumes, true)));
    assert!(r.last_plan().expect("plan").to_string().contains("shadow volumes (light 0, z-pass, 1 casters"));
    let shadowed = traced.iter().filter(|&&v| v == 0.0).count();
    let lit = traced.iter().filter(|&&v| v == 1.0).count();
    println!(
        "camera inside the shadow ({shadowed} shadowed, {lit} lit pixels in traced): z-fail disagrees on {} of {} \
         pixels away from edges ({:.3} %), z-pass on {} ({:.1} %: {} false shadow, {} leak)",
        zfail.disagree(),
        zfail.compared,
        100.0 * zfail.share(),
        zpass.disagree(),
        100.0 * zpass.share(),
        zpass.false_shadow,
        zpass.leak
    );
    assert!(shadowed > 2000 && lit > 2000, "the view must show shadowed and lit floor");
    assert!(zfail.disagree() * 1000 <= zfail.compared, "z-fail: {} of {}", zfail.disagree(), zfail.compared);
    // Inside the volume every count is off by one: z-pass swaps light and shadow.
    assert!(zpass.share() > 0.5, "z-pass should be wrong on most pixels, is on {:.1} %", 100.0 * zpass.share());
    drop(r);
    common::assert_clean(&ctx);
}

/// Three triangles on one edge (a fin on a fin): closed nowhere, and not a 2-manifold.
fn fins() -> Mesh {
    let positions = [
        Vec3::new(-0.5, 1.0, 0.0),
        Vec3::new(0.5, 1.0, 0.0),
        Vec3::new(0.0, 1.8, 0.0),
        Vec3::new(0.0, 1.5, 0.6),
        Vec3::new(0.0, 1.5, -0.6),
    ];
    Mesh {
        name: "fins".into(),
        motion: None,
        deform: None,
        object: "objects[9]".into(),
        normals: vec![Vec3::Z; positions.len()],
        positions: positions.iter().map(|p| p.as_dvec3()).collect(),
        indices: vec![0, 1, 2, 1, 0, 3, 1, 0, 4],
        material: Default::default(),
        cast_shadows: true,
        instance: None,
        surface: None,
        double_sided: false,
    }
}

#[test]
fn open_and_non_manifold_casters_fall_back_to_traced_naming_the_mesh() {
    let log = common::captured_log();
    let ctx = common::gpu();
    let casting_floor = load(&BOX_SCENE.replace("cast_shadows = false", "cast_shadows = true"));
    let mut with_fins = load(BOX_SCENE);
    with_fins.meshes.push(fins());
    for (scene, mesh, why) in
        [(casting_floor, "plane", "it is open: edge ("), (with_fins, "fins", "it is not a 2-manifold: edge (")]
    {
        let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
        let s = settings(3, 0, choice(ShadowMethod::Volumes, false));
        let plan = r.plan(&s).expect("plan");
        let passes = plan.live_pass_names();
        assert!(passes.contains(&"shadow trace"), "{mesh}: traced instead:\n{plan}");
        assert!(!passes.iter().any(|p| p.starts_with("shadow volumes")), "{mesh}: no volume pass:\n{plan}");
        // The notice, once per light: which light, which mesh, which edge. The log is the test
        // process's: a line is this scene's where it names this plan's reason (its edge).
        let reasons = r.shadow_plan(&s).expect("plan").fallbacks;
        r.render(&s).expect("render");
        let lines = log.lock().unwrap().clone();
        let notice = |light: usize| {
            let head = format!("light {light}: mesh \"{mesh}\" cannot cast shadow volumes: {why}");
            let (_, _, reason) = reasons.iter().find(|(l, ..)| *l == light).expect("a fallback per light");
            let line = format!("light {light}: {reason}; its shadows are traced instead");
            assert!(line.starts_with(&head), "{line}");
            lines.iter().filter(|l| **l == line).count()
        };
        println!("{mesh}: {}", lines.iter().find(|l| l.contains(mesh)).expect("a notice"));
        assert_eq!([notice(0), notice(1), notice(2)], [1, 1, 1], "{mesh}:\n{}", lines.join("\n"));
        log.lock().unwrap().clear();
    }
    common::assert_clean(&ctx);
}

#[test]
fn the_plan_copies_depth_then_writes_and_reads_the_stencil_per_light() {
    let (ctx, mut r) = setup(load(BOX_SCENE));
    // Lights 0 and 2 on volumes (z-fail and z-pass), light 1 traced; the view shows light 2.
    let mut s = settings(3, 2, choice(ShadowMethod::Volumes, false));
    s.shadows[1] = choice(ShadowMethod::Traced, false);
    s.shadows[2] = choice(ShadowMethod::Volumes, true);
    // The view reads light 2's layer alone: light 0's volume passes and the trace are culled.
    let viewed = r.plan(&s).expect("plan");
    let resolves = viewed.live_pass_names().iter().filter(|p| **p == "shadow volumes resolve").count();
    assert_eq!(resolves, 1, "{viewed}");
    assert!(!viewed.live_pass_names().contains(&"shadow trace"), "{viewed}");
    // The shaded frame reads every light's layer.
    let plan = r.plan(&RenderSettings { debug_view: None, ..s.clone() }).expect("plan");
    println!("{plan}");
    let passes = plan.live_pass_names();
    let at = |name: &str, nth: usize| {
        passes
            .iter()
            .enumerate()
            .filter(|(_, p)| **p == name)
            .nth(nth)
            .map(|(i, _)| i)
            .unwrap_or_else(|| panic!("no pass {name} #{nth} in {passes:?}"))
    };
    let geometry = at("geometry", 0);
    let depth = at("shadow volumes depth", 0);
    let (volumes0, resolve0) = (at("shadow volumes", 0), at("shadow volumes resolve", 0));
    let (volumes2, resolve2) = (at("shadow volumes", 1), at("shadow volumes resolve", 1));
    assert!(geometry < depth && depth < volumes0 && volumes0 < resolve0 && resolve0 < volumes2 && volumes2 < resolve2);
    assert_eq!(passes.iter().filter(|p| p.starts_with("shadow volumes depth")).count(), 1, "one depth copy");
    assert!(passes.contains(&"shadow trace"), "light 1 is traced");
    let text = plan.to_string();
    assert!(text.contains("shadow volumes (light 0, z-fail, 1 casters, 12 triangles)"), "{text}");
    assert!(text.contains("shadow volumes (light 2, z-pass, 1 casters, 12 triangles)"), "{text}");
    let barrier_on = |pass_index: usize| -> Vec<String> {
        let pass = plan.passes.iter().filter(|p| !p.culled).nth(pass_index).expect("live pass");
        pass.barriers
            .iter()
            .map(|b| plan.describe_barrier(b))
            .filter(|b| b.starts_with("barrier volume depth-stencil:"))
            .collect()
    };
    // The depth copy, tested by the volumes; the stencil written, then sampled; the next
    // light's stencil written after that read.
    assert_eq!(
        barrier_on(volumes0),
        ["barrier volume depth-stencil: [DepthStencilAttachmentWrite] -> [DepthTestRead, DepthReadStencilWrite] \
          [DEPTH_STENCIL_ATTACHMENT_OPTIMAL -> DEPTH_READ_ONLY_STENCIL_ATTACHMENT_OPTIMAL]"]
    );
    assert_eq!(
        barrier_on(resolve0),
        ["barrier volume depth-stencil: [DepthReadStencilWrite] -> [ComputeShaderReadStencil] \
          [DEPTH_READ_ONLY_STENCIL_ATTACHMENT_OPTIMAL -> DEPTH_STENCIL_READ_ONLY_OPTIMAL]"]
    );
    assert_eq!(
        barrier_on(volumes2),
        ["barrier volume depth-stencil: [ComputeShaderReadStencil] -> [DepthTestRead, DepthReadStencilWrite] \
          [DEPTH_STENCIL_READ_ONLY_OPTIMAL -> DEPTH_READ_ONLY_STENCIL_ATTACHMENT_OPTIMAL]"]
    );
    // And the frame runs clean.
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
    assert!(pixels.chunks_exact(4).any(|p| p[0] == 0.0) && pixels.chunks_exact(4).any(|p| p[0] == 1.0));
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn the_stencil_view_shows_counts_where_traced_shows_shadow() {
    let (ctx, mut r) = setup(load(BOX_SCENE));
    let traced = visibility(&mut r, 3, 1, choice(ShadowMethod::Traced, false));
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.shadows = vec![choice(ShadowMethod::Volumes, false); 3];
    s.debug_view = Some(DebugView::Stencil(1));
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("stencil view") else { panic!("float frame") };
    let counted: Vec<bool> = pixels.chunks_exact(4).map(|p| p[0] + p[1] + p[2] > 0.0).collect();
    // Every pixel traced sees in the sun's cast shadow on the floor has a count; lit ones none.
    let lit_with_count = (0..traced.len()).filter(|&i| traced[i] == 1.0 && counted[i]).count();
    let counted_total = counted.iter().filter(|&&c| c).count();
    println!("stencil view: {counted_total} pixels with a count; {lit_with_count} of them lit in traced");
    assert!(counted_total > 500 && lit_with_count == 0, "{counted_total} counted, {lit_with_count} lit");
    // A light that is not on volumes has no stencil to show.
    s.shadows[1] = ShadowChoice::hard();
    let err = r.render(&s).err().expect("refused").to_string();
    assert!(err.contains("light 1 does not use shadow volumes"), "{err}");
    drop(r);
    common::assert_clean(&ctx);
}
