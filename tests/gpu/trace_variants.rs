//! The traced pass runs hard and soft lights in their own pipeline variants (trace_body.glsl's
//! TRACE_SOFT), and makes only the variants a frame's lights take.

use crate::common;

use glam::{DVec3, Vec3};
use umbra::config::ShadowChoice;
use umbra::scene::Light;
use umbra::shadows::traced::{self, Rays};
use umbra::shadows::Served;

fn served(light: u32) -> Served {
    Served { light, layer: light, choice: ShadowChoice::default(), unshadowed: false }
}

#[test]
fn hard_and_soft_lights_take_their_own_variant_made_only_when_needed() {
    let ctx = common::gpu();
    let point = |radius| Light::Point { position: DVec3::new(0.0, 2.0, 0.0), intensity: Vec3::ONE, radius };
    // Light 0 is a point (hard), light 1 a sphere (soft by default: it has a size).
    let lights = [point(0.0), point(0.1)];
    assert_eq!(traced::rays(&served(0), &lights[0]), Rays::Hard);
    assert!(matches!(traced::rays(&served(1), &lights[1]), Rays::Soft(_)));

    let pipelines = traced::Pipelines::default();
    let hard_only = pipelines.prepare(&ctx, false, false, &[served(0)], &lights).unwrap();
    assert!(hard_only.hard.is_some() && hard_only.soft.is_none(), "no soft light, no soft variant");
    let soft_only = pipelines.prepare(&ctx, false, false, &[served(1)], &lights).unwrap();
    assert!(soft_only.hard.is_none() && soft_only.soft.is_some(), "no hard light, no hard variant");

    let both = pipelines.prepare(&ctx, false, false, &[served(0), served(1)], &lights).unwrap();
    let (hard, soft) = (both.get(Rays::Hard), both.get(Rays::Soft(4)));
    assert_eq!((hard.name, soft.name), ("shadow trace", "shadow trace (soft)"));
    assert_ne!(hard.pipeline, soft.pipeline);
    // Made once: the frame after reuses them, and a light with its rays off takes the hard one.
    assert_eq!(hard.pipeline, hard_only.hard.unwrap().pipeline);
    assert_eq!(soft.pipeline, soft_only.soft.unwrap().pipeline);
    assert_eq!(both.get(Rays::None).pipeline, hard.pipeline);
    drop(pipelines);
    common::assert_clean(&ctx);
}
