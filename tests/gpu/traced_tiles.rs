//! Long traced passes are cut into tiles (`traced.tile_rays`) so no dispatch runs for seconds;
//! the cut must not change a bit of the image. Hard and soft lights, tiles forced down to a few
//! workgroups, with validation and synchronization validation.

use crate::common;

use std::path::Path;

use umbra::config::{DebugView, ShadowChoice};
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;
use umbra::shadows::traced::params::MIN_TILE_RAYS;

const W: u32 = 200;
const H: u32 = 150;

fn visibility(r: &mut Renderer, light: u32, choice: ShadowChoice) -> Vec<f32> {
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear).all_lights(4, choice);
    s.debug_view = Some(DebugView::Visibility(light));
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
    pixels
}

#[test]
fn tiny_tiles_give_the_same_bits() {
    let ctx = common::gpu();
    let sphere_light =
        "[[lights]]\ntype = \"point\"\nposition = [1.5, 3.0, 1.0]\nintensity = [10.0, 10.0, 10.0]\nradius = 0.4\n";
    let text = common::scene(&[&common::BOX[..], &[sphere_light]].concat());
    let scene = Scene::parse(&text, "tiles.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
    for (what, choice) in [("hard", ShadowChoice::hard()), ("soft, 64 spp", ShadowChoice::soft(64))] {
        let rays = if choice.traced.soft == Some(true) { choice.traced.spp } else { 1 };
        let whole_tiles = choice.traced.tiles(W, H, rays);
        let mut tiny = choice;
        tiny.traced.tile_rays = MIN_TILE_RAYS;
        let tiles = tiny.traced.tiles(W, H, rays);
        assert_eq!(whole_tiles.len(), 1, "{what}: one dispatch by default");
        assert!(tiles.len() >= 2, "{what}: {} tiles", tiles.len());
        // The tiles cover the image exactly once.
        let mut covered = vec![0u8; (W * H) as usize];
        for [x, y, w, h] in &tiles {
            for py in *y..y + h {
                for px in *x..x + w {
                    covered[(py * W + px) as usize] += 1;
                }
            }
        }
        assert!(covered.iter().all(|&c| c == 1), "{what}: tiles overlap or leave gaps");
        for light in 0..4 {
            let whole = visibility(&mut r, light, choice);
            let tiled = visibility(&mut r, light, tiny);
            let differ = whole.iter().zip(&tiled).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
            let shadowed = whole.chunks_exact(4).filter(|p| p[0] < 1.0).count();
            let penumbra = whole.chunks_exact(4).filter(|p| p[0] > 0.0 && p[0] < 1.0).count();
            println!(
                "{what}, light {light}: {} tiles, {shadowed} pixels not fully lit ({penumbra} in penumbra), {differ} values differ",
                tiles.len()
            );
            if what != "hard" && light == 3 {
                assert!(penumbra > 100, "the sphere light's soft shadow has a penumbra");
            }
            assert!(shadowed > 100, "{what}, light {light}: the view shows shadow");
            assert_eq!(differ, 0, "{what}, light {light}: tiling changed the image");
        }
    }
    common::assert_clean(&ctx);
}
