//! The transient cache reuses what a frame needs again and frees what no frame has needed for a
//! while, so rendering at many sizes (a window being resized) does not pile up images.

use crate::common;

use umbra::graph::{CompiledGraph, RenderGraph, TransientCache};
use umbra::renderer::{OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::scene::Scene;

#[test]
fn transients_are_reused_at_one_size_and_freed_after_a_size_is_left() {
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), Scene::default_scene()).unwrap();
    // Hard shadows: soft ones would add the accumulation history, which is not transient.
    let settings = |w, h| RenderSettings::new(w, h, OutputKind::Display).all_lights(3, ShadowChoice::hard());
    r.render(&settings(64, 48)).unwrap();
    let per_frame = r.transient_count();
    assert!(per_frame >= 5, "G-buffer, visibility, radiance, display: {per_frame}");
    for _ in 0..3 {
        r.render(&settings(64, 48)).unwrap();
    }
    assert_eq!(r.transient_count(), per_frame, "the same frame again allocates nothing new");
    for i in 0..24 {
        r.render(&settings(40 + i, 30 + i)).unwrap();
    }
    // Only sizes used within the last 8 frames may still hold images.
    assert!(r.transient_count() <= 8 * per_frame, "{} held after 24 sizes", r.transient_count());
    assert!(r.transient_count() >= per_frame);
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn a_frame_that_binds_more_sets_than_a_pool_holds_takes_more_pools_and_keeps_them() {
    // 200 dispatches, a descriptor set each: more than one pool's 64 sets. A discrete GPU's
    // driver refuses a pool's 65th set (64 shadowed lights at 1080p did); lavapipe does not, so
    // the pools move on by count, on every driver alike.
    let ctx = common::gpu();
    let pipelines = umbra::vk::PipelineCache::default();
    let source = umbra::vk::PipelineSource { ctx: &ctx, cache: &pipelines };
    let mut cache = TransientCache::new(&ctx).unwrap();
    for _ in 0..2 {
        let mut g = RenderGraph::new();
        for _ in 0..200 {
            let out = umbra::diagnostics::busy::add(&mut g, source, 1).unwrap();
            g.export(out, umbra::graph::Access::ComputeShaderReadStorageBuffer);
        }
        let plan = CompiledGraph::compile(&g);
        ctx.submit_and_wait(|cmd| cache.execute(g, &plan, cmd, false)).unwrap();
        // The second frame reuses the first's pools.
        assert_eq!(cache.descriptor_pool_count(), 4, "200 sets of 64 a pool");
    }
    drop(cache);
    drop(pipelines);
    common::assert_clean(&ctx);
}
