//! The traced pass runs hard and soft lights in their own pipeline variants (trace_body.glsl's
//! TRACE_SOFT), and a frame makes only the variants its lights take, once: the renderer's
//! pipeline cache holds what frames asked for.

use crate::common;

use glam::{DVec3, Vec3};
use umbra::config::{OutputKind, RenderSettings, ShadowChoice, ShadowMethod};
use umbra::renderer::Renderer;
use umbra::scene::Light;
use umbra::shadows::traced::{self, Rays};
use umbra::shadows::Served;
use umbra::vk::PipelineKey;

fn served(light: u32) -> Served {
    Served { light, layer: light, choice: ShadowChoice::default(), unshadowed: false }
}

/// The trace over the compute BVH, hard and soft, in the cache's keys: the key's bits are the
/// walk's build (`gpu::WalkBuild::bits`, three bits: the compute builds 0..=3, ray query 4, 5),
/// then soft.
const HARD: PipelineKey = PipelineKey::new("shadow trace", 0);
const SOFT: PipelineKey = PipelineKey::new("shadow trace", 1 << 3);

#[test]
fn hard_and_soft_lights_take_their_own_variant_made_only_when_needed() {
    let point = |radius| Light::Point { position: DVec3::new(0.0, 2.0, 0.0), intensity: Vec3::ONE, radius };
    // Light 0 is a point (hard), light 1 a sphere (soft by default: it has a size).
    let lights = [point(0.0), point(0.1)];
    assert_eq!(traced::rays(&served(0), &lights[0]), Rays::Hard);
    assert!(matches!(traced::rays(&served(1), &lights[1]), Rays::Soft(_)));

    let ctx = common::gpu();
    let dir = common::scratch_dir("trace-variants");
    let text = common::scene(&[
        common::CAMERA,
        "[[lights]]\ntype = \"point\"\nposition = [1.2, 3.0, 1.5]\nintensity = [30.0, 30.0, 30.0]\n",
        "[[lights]]\ntype = \"point\"\nposition = [-1.2, 3.0, 1.5]\nintensity = [30.0, 30.0, 30.0]\nradius = 0.2\n",
        common::FLOOR,
        common::CUBE,
    ]);
    let scene = common::parse_scene_in(&dir, &text).unwrap();
    let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
    let frame = |renderer: &mut Renderer, shadows: [ShadowMethod; 2]| {
        let mut settings = RenderSettings::new(32, 24, OutputKind::SceneLinear);
        settings.shadows = shadows.iter().map(|&m| ShadowChoice::of(m)).collect();
        renderer.render(&settings).unwrap();
    };
    frame(&mut renderer, [ShadowMethod::Traced, ShadowMethod::None]);
    let cache = renderer.pipeline_cache();
    assert!(cache.contains(HARD) && !cache.contains(SOFT), "no soft light, no soft variant: {:?}", cache.keys());
    let hard = cache.handle(HARD);

    frame(&mut renderer, [ShadowMethod::None, ShadowMethod::Traced]);
    let cache = renderer.pipeline_cache();
    assert!(cache.contains(SOFT), "the soft light's variant: {:?}", cache.keys());
    assert_ne!(cache.handle(HARD), cache.handle(SOFT));

    // Made once: the frames after reuse them.
    let made = cache.len();
    frame(&mut renderer, [ShadowMethod::Traced, ShadowMethod::Traced]);
    frame(&mut renderer, [ShadowMethod::Traced, ShadowMethod::Traced]);
    let cache = renderer.pipeline_cache();
    assert_eq!(cache.len(), made, "no pipeline made twice: {:?}", cache.keys());
    assert_eq!(cache.handle(HARD), hard);
    drop(renderer);
    common::assert_clean(&ctx);
}
