//! Every shadow technique with every debug view on the test scenes: each frame either renders
//! with no NaN or is refused in one line (a technique's view of a light it does not serve), and
//! no frame makes a validation message. Small frames: this is about coverage, not accuracy.

use crate::common;

use std::path::Path;

use umbra::config::{DebugView, ShadowChoice, ShadowMethod};
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;

/// A box and a sphere on a floor that casts nothing (so volumes qualify), under a spot, a sun
/// (with a size: soft traced, PCSS maps) and a point light.
const SCENE: &str = r#"
[camera]
eye = [0.0, 3.0, 5.0]
target = [0.0, 0.4, 0.0]
vfov_deg = 45.0
[[lights]]
type = "spot"
position = [1.5, 4.0, 1.0]
direction = [-0.35, -1.0, -0.25]
intensity = [30.0, 30.0, 30.0]
inner_deg = 35.0
outer_deg = 45.0
[[lights]]
type = "directional"
direction = [0.5, -1.0, 0.3]
irradiance = [2.0, 2.0, 2.0]
angular_diameter_deg = 2.0
[[lights]]
type = "point"
position = [-1.5, 2.5, 1.5]
intensity = [20.0, 20.0, 20.0]
radius = 0.1
[[objects]]
shape = "plane"
size = 10.0
cast_shadows = false
[[objects]]
shape = "cube"
size = 1.0
translate = [0.0, 0.5, 0.0]
[[objects]]
shape = "sphere"
radius = 0.4
segments = 24
translate = [1.3, 0.4, 0.5]
"#;

#[test]
fn every_technique_with_every_view_is_clean() {
    let ctx = common::gpu();
    let mut rendered = 0;
    for (name, text) in [("matrix", SCENE.to_string()), ("default", String::new())] {
        let scene = match text.is_empty() {
            true => Scene::default_scene(),
            false => Scene::parse(&text, "matrix.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}")),
        };
        let lights = scene.lights.len() as u32;
        let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
        let mut views = vec![
            None,
            Some(DebugView::Albedo),
            Some(DebugView::GeometricNormal),
            Some(DebugView::Depth),
            Some(DebugView::Motion),
        ];
        for l in 0..lights {
            views.extend([
                Some(DebugView::Visibility(l)),
                Some(DebugView::ShadowMap { light: l, layer: 0 }),
                Some(DebugView::Cascades(l)),
                Some(DebugView::Stencil(l)),
                Some(DebugView::Hybrid(l)),
            ]);
        }
        for method in ShadowMethod::ALL {
            for view in &views {
                for output in [OutputKind::Display, OutputKind::SceneLinear] {
                    let mut s = RenderSettings::new(64, 48, output);
                    s.shadows = vec![ShadowChoice { method, ..ShadowChoice::soft(2) }; lights as usize];
                    s.debug_view = *view;
                    if let Err(why) = r.check_debug_view(&s) {
                        let err = r.render(&s).err().unwrap_or_else(|| panic!("{name} {method} {view:?}: rendered"));
                        assert!(err.to_string().contains(&why) && !why.contains('\n'), "{err} / {why}");
                        continue;
                    }
                    match r.render(&s).unwrap_or_else(|e| panic!("{name} {method} {view:?}: {e}")) {
                        Frame::Rgba32F { pixels, .. } => {
                            assert!(pixels.iter().all(|v| v.is_finite()), "{name} {method} {view:?}: NaN")
                        }
                        Frame::Rgba8 { .. } => {}
                    }
                    rendered += 1;
                }
            }
        }
        drop(r);
    }
    println!("{rendered} frames rendered");
    assert!(rendered > 100);
    common::assert_clean(&ctx);
}

/// Techniques write their lights' layers side by side with no barrier between them (each binds
/// its own layer): a frame mixing three techniques shows each light's visibility exactly as a
/// frame where that light's technique serves every light, and makes no validation message.
#[test]
fn mixed_techniques_write_their_layers_as_they_do_alone() {
    let ctx = common::gpu();
    let scene = Scene::parse(SCENE, "matrix.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
    let mut visibility = |methods: [ShadowMethod; 3], light: u32| -> Vec<f32> {
        let mut s = RenderSettings::new(64, 48, OutputKind::SceneLinear);
        s.shadows = methods.iter().map(|&method| ShadowChoice { method, ..ShadowChoice::hard() }).collect();
        s.debug_view = Some(DebugView::Visibility(light));
        match r.render(&s).unwrap_or_else(|e| panic!("{methods:?} light {light}: {e}")) {
            Frame::Rgba32F { pixels, .. } => pixels,
            Frame::Rgba8 { .. } => unreachable!("scene-linear output"),
        }
    };
    use ShadowMethod::{Hybrid, Map, Traced, Volumes};
    for mixed in [[Map, Volumes, Traced], [Hybrid, Map, Volumes], [Traced, Hybrid, Map]] {
        for (light, method) in mixed.into_iter().enumerate() {
            let light = light as u32;
            let together = visibility(mixed, light);
            let shadowed = together.chunks(4).filter(|p| p[0] < 0.5).count();
            assert!(shadowed > 0, "light {light} casts some shadow in the frame");
            let alone = visibility([method; 3], light);
            assert_eq!(together, alone, "{mixed:?}: light {light}'s layer differs beside other techniques");
        }
    }
    drop(r);
    common::assert_clean(&ctx);
}
