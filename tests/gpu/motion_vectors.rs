//! The G-buffer's motion channel (`--debug-view motion`) against its CPU twin
//! (`CameraMatrices::motion`) on the same pixels: each pixel's position now (the position
//! view) and where that point was in the previous frame (moved back by the object's motion,
//! seen by the previous frame's camera), for object motion, camera motion, a moving scene's
//! first frame (measured over 1 / FIRST_FRAME_FPS before it) and a still view (exactly zero).
//! Validation and synchronization validation on.

use crate::common;

use glam::{Vec2, Vec3, Vec4};
use umbra::config::DebugView;
use umbra::gpu::CameraMatrices;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, FIRST_FRAME_FPS};
use umbra::scene::Camera;

const W: u32 = 160;
const H: u32 = 120;

/// A floor and a box sliding along +x at 1 m/s (x = 0 at t = 0 to x = 2 at t = 2), under a sun.
fn sliding_box() -> umbra::scene::Scene {
    let dir = common::scratch_dir("motion-vectors");
    let moving = "[[objects]]\nshape = \"cube\"\nsize = 0.5\n\
                  keys = [{ time = 0.0, translate = [0.0, 0.5, 0.0] }, { time = 2.0, translate = [2.0, 0.5, 0.0] }]\n";
    let text = common::scene(&[common::CAMERA, common::SUN, common::FLOOR, moving]);
    common::parse_scene_in(&dir, &text).expect("the sliding box parses")
}

pub(crate) fn floats(r: &mut Renderer, view: DebugView, time: Option<f64>, camera: Option<Camera>) -> Vec<Vec4> {
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.debug_view = Some(view);
    s.time = time;
    s.camera = camera;
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
    pixels.chunks_exact(4).map(Vec4::from_slice).collect()
}

/// The camera matrices `r`'s frames see `camera` (world frame) with.
pub(crate) fn matrices(r: &Renderer, camera: &Camera) -> CameraMatrices {
    CameraMatrices::new(&r.gpu_scene.to_local(camera), r.gpu_scene.bounds, W, H)
}

/// Compares the motion channel `gpu` with the twin on every drawn pixel of `position` (world
/// positions): `before(p)` is where the point at local `p` was in the previous frame. Returns
/// how many pixels moved by more than a tenth of a pixel.
pub(crate) fn check(
    r: &Renderer,
    gpu: &[Vec4],
    position: &[Vec4],
    now: &CameraMatrices,
    previous: &CameraMatrices,
    before: impl Fn(Vec3) -> Vec3,
) -> usize {
    let origin = r.gpu_scene.origin.as_vec3();
    let (mut drawn, mut moved, mut worst) = (0, 0, 0.0f32);
    for (i, (m, p)) in gpu.iter().zip(position).enumerate() {
        if p.truncate() == origin {
            continue; // background: the position view's zero, moved to the world frame
        }
        let local = p.truncate() - origin;
        let want = now.motion(previous, local, before(local), W, H).expect("in front of both cameras");
        let got = Vec2::new(m.x, m.y);
        let off = (got - want).length();
        // f16 keeps 11 bits: a thousandth of the motion, beside the twins' f32 rounding.
        assert!(off <= 0.02 + 2e-3 * want.length(), "pixel {i} at {local}: motion {got}, twin {want}");
        worst = worst.max(off);
        drawn += 1;
        moved += usize::from(want.length() > 0.1);
    }
    assert!(drawn > W as usize * H as usize / 2, "{drawn} drawn pixels");
    println!("{drawn} drawn pixels, {moved} moved; worst difference {worst:.4} px");
    moved
}

#[test]
fn object_motion_matches_the_twin_from_the_first_frame_on_and_a_still_frame_has_none() {
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), sliding_box()).expect("renderer");
    assert!(r.is_moving());
    let camera = r.scene().camera;
    let cam = matrices(&r, &camera);
    // The first frame: the box's motion over the 1/30 s before it.
    let motion = floats(&mut r, DebugView::Motion, Some(1.5), None);
    let position = floats(&mut r, DebugView::Position, Some(1.5), None);
    // On the box: inside its bounds at 1.5 s (a millimetre more), where the floor is not.
    let bounds = r.gpu_scene.draws[r.gpu_scene.moving[0].draw].bounds;
    let on_box = |p: Vec3| p.cmpge(bounds.min - 1e-3).all() && p.cmple(bounds.max + 1e-3).all();
    let step = (1.0 / FIRST_FRAME_FPS) as f32;
    let moved = check(&r, &motion, &position, &cam, &cam, |p| if on_box(p) { p - Vec3::X * step } else { p });
    assert!(moved > 100, "the box moves half a pixel in 1/30 s: {moved} pixels moved");
    // A frame at 1.0 s, then one at 1.5 s: half a metre.
    floats(&mut r, DebugView::Depth, Some(1.0), None);
    let motion = floats(&mut r, DebugView::Motion, Some(1.5), None);
    let moved = check(&r, &motion, &position, &cam, &cam, |p| if on_box(p) { p - Vec3::X * 0.5 } else { p });
    let on_box_pixels = position.iter().filter(|p| on_box(p.truncate() - r.gpu_scene.origin.as_vec3())).count();
    assert!(on_box_pixels > 150 && moved == on_box_pixels, "{moved} of the box's {on_box_pixels} pixels moved");
    // The same instant again (paused): nothing moved since the frame before.
    let still = floats(&mut r, DebugView::Motion, Some(1.5), None);
    assert!(still.iter().all(|m| m.x == 0.0 && m.y == 0.0), "a still frame has no motion");
    drop(r);
    common::assert_clean(&ctx);
}

/// `scene`'s motion channel after a camera move against the twin; its first frame still.
fn camera_motion(ctx: &std::sync::Arc<umbra::vk::GpuContext>, scene: umbra::scene::Scene, min_moved: usize) {
    let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
    // A static scene's first frame: no frame before it, so no motion.
    let first = floats(&mut r, DebugView::Motion, None, None);
    assert!(first.iter().all(|m| m.x == 0.0 && m.y == 0.0), "a first frame has no motion");
    let a = r.scene().camera;
    let b = Camera {
        eye: a.eye + glam::DVec3::new(0.4, 0.15, -0.3),
        target: a.target + glam::DVec3::new(0.1, 0.0, 0.0),
        ..a
    };
    floats(&mut r, DebugView::Depth, None, Some(a));
    let motion = floats(&mut r, DebugView::Motion, None, Some(b));
    let position = floats(&mut r, DebugView::Position, None, Some(b));
    let moved = check(&r, &motion, &position, &matrices(&r, &b), &matrices(&r, &a), |p| p);
    assert!(moved > min_moved, "a moving camera moves most pixels: {moved}");
}

#[test]
fn camera_motion_matches_the_twin_and_a_static_scene_starts_still() {
    let ctx = common::gpu();
    let dir = common::scratch_dir("motion-vectors-camera");
    let text = common::scene(&common::BOX);
    camera_motion(&ctx, common::parse_scene_in(&dir, &text).expect("box scene"), W as usize * H as usize / 2);
    // A textured scene draws with the textured variants (material and emission attachments
    // before the motion channel).
    let quad = crate::textures::textured_quad(
        serde_json::json!({ "pbrMetallicRoughness": {} }),
        &[("baseColorTexture", crate::textures::png(4, 4, [200, 180, 160, 255]))],
    );
    quad.write_glb(&dir.join("quad.glb"));
    let text = common::scene(&[common::CAMERA, common::SUN, "[[objects]]\nmesh = \"quad.glb\"\nscale = 3.0\n"]);
    let scene = common::parse_scene_in(&dir, &text).expect("textured quad");
    assert!(scene.meshes.iter().any(|m| m.surface.is_some()), "textured");
    camera_motion(&ctx, scene, 1000);
    common::assert_clean(&ctx);
}
