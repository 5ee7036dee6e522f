//! Frame-graph plans of layered images, checked on the CPU: techniques that write different
//! layers of the visibility target run with no barrier between them, a read of every layer
//! waits for each writer, each layer range keeps its own layout, and culling follows layers.

use ash::vk;
use umbra::graph::{Access, Barrier, CompiledGraph, ImageDesc, Layers, RenderGraph};

fn visibility(layers: u32) -> ImageDesc {
    ImageDesc::array(vk::Format::R8_UNORM, 64, 32, layers)
}

fn out_desc() -> ImageDesc {
    ImageDesc::new(vk::Format::R16G16B16A16_SFLOAT, 64, 32)
}

fn noop(_: &mut umbra::graph::PassContext) -> umbra::vk::GpuResult<()> {
    Ok(())
}

fn on<'p>(plan: &'p CompiledGraph, pass: &str, resource: &str) -> Vec<&'p Barrier> {
    plan.barriers_before(pass).iter().filter(|b| plan.resources[b.resource].name == resource).collect()
}

/// A shadow-map resolve writes layer 0, a trace writes layers 1 and 2, compose reads them all.
#[test]
fn techniques_writing_disjoint_layers_need_no_barrier_between_them() {
    let mut g = RenderGraph::new();
    let mut vis = g.create_image("visibility", visibility(3));
    let mut out = g.create_image("radiance", out_desc());
    let mut p = g.add_pass("shadow map resolve");
    p.write_layer(&mut vis, 0, Access::ComputeShaderWrite);
    p.render(noop);
    let mut p = g.add_pass("shadow trace");
    p.write_layer(&mut vis, 1, Access::ComputeShaderWrite);
    p.write_layer(&mut vis, 2, Access::ComputeShaderWrite);
    p.render(noop);
    let mut p = g.add_pass("compose");
    p.read(&vis, Access::ComputeShaderReadSampledImage);
    p.write(&mut out, Access::ComputeShaderWrite);
    p.render(noop);
    g.export(out, Access::TransferRead);
    let plan = CompiledGraph::compile(&g);
    assert_eq!(plan.live_pass_names(), vec!["shadow map resolve", "shadow trace", "compose"], "{plan}");

    // The first writer brings every layer out of UNDEFINED (each layer's first use is a write in
    // GENERAL), so the second writer has nothing to wait for.
    let first = on(&plan, "shadow map resolve", "visibility");
    assert_eq!(first.len(), 1, "{plan}");
    assert_eq!(first[0].layers, Layers::all(3));
    assert_eq!(first[0].layouts, Some((vk::ImageLayout::UNDEFINED, vk::ImageLayout::GENERAL)));
    assert_eq!(first[0].src_stage, vk::PipelineStageFlags2::NONE, "a fresh image waits for nothing");
    assert!(plan.barriers_before("shadow trace").is_empty(), "disjoint layers need no barrier:\n{plan}");

    // Compose's read of all layers waits for both writers: one barrier, since all three layers
    // were last written by compute shaders in GENERAL.
    let read = on(&plan, "compose", "visibility");
    assert_eq!(read.len(), 1, "{plan}");
    assert_eq!(read[0].layers, Layers::all(3));
    assert_eq!(read[0].after, vec![Access::ComputeShaderWrite]);
    assert_eq!(read[0].src_access, vk::AccessFlags2::SHADER_STORAGE_WRITE);
    assert_eq!(read[0].layouts, Some((vk::ImageLayout::GENERAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)));
}

/// An image that lives outside the graph, already in GENERAL: writes of disjoint layers get no
/// barrier between them, and a pass that reads and rewrites a layer another pass wrote waits for
/// that layer alone.
#[test]
fn an_imported_array_orders_only_the_layers_two_passes_share() {
    let mut g = RenderGraph::new();
    let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED;
    let mut vis = g.import_image(
        "visibility",
        visibility(4),
        (vk::Image::null(), vk::ImageView::null(), usage),
        Access::ComputeShaderWrite,
    );
    for (name, layer) in [("a", 0), ("b", 1)] {
        let mut p = g.add_pass(name);
        p.write_layer(&mut vis, layer, Access::ComputeShaderWrite);
        p.render(noop);
    }
    // Reads what b wrote and writes it again (as accumulation does).
    let mut p = g.add_pass("c");
    p.read_layer(&vis, 1, Access::ComputeShaderReadStorageImage);
    p.write_layer(&mut vis, 1, Access::ComputeShaderWrite);
    p.render(noop);
    g.export(vis, Access::ComputeShaderReadSampledImage);
    let plan = CompiledGraph::compile(&g);
    // The import's last write (the previous frame's) covers every layer, so each pass waits for
    // it on its own layer only.
    for (pass, layer) in [("a", 0), ("b", 1)] {
        let b = on(&plan, pass, "visibility");
        assert_eq!(b.len(), 1, "{plan}");
        assert_eq!(b[0].layers, Layers::one(layer), "{plan}");
    }
    let waw = on(&plan, "c", "visibility");
    assert_eq!(waw.len(), 1, "{plan}");
    assert_eq!(waw[0].layers, Layers::one(1), "c waits for b's write of layer 1, not a's of layer 0");
    assert_eq!(waw[0].after, vec![Access::ComputeShaderWrite]);
    assert_eq!(waw[0].before, vec![Access::ComputeShaderReadStorageImage, Access::ComputeShaderWrite]);
    assert_eq!(waw[0].layouts, Some((vk::ImageLayout::GENERAL, vk::ImageLayout::GENERAL)));
}

/// Layers written in different ways keep different layouts until a read brings each over.
#[test]
fn each_layer_range_keeps_its_own_layout() {
    let mut g = RenderGraph::new();
    let mut vis = g.create_image("visibility", visibility(3));
    let mut out = g.create_image("radiance", out_desc());
    let mut p = g.add_pass("resolve");
    p.write_layer(&mut vis, 0, Access::ComputeShaderWrite);
    p.render(noop);
    let mut p = g.add_pass("clear");
    p.write_layer(&mut vis, 2, Access::TransferWrite);
    p.render(noop);
    let mut p = g.add_pass("view layer 0");
    p.read_layer(&vis, 0, Access::ComputeShaderReadSampledImage);
    p.write(&mut out, Access::ComputeShaderWrite);
    p.render(noop);
    let mut p = g.add_pass("compose");
    p.read(&vis, Access::ComputeShaderReadSampledImage);
    p.read(&out, Access::ComputeShaderReadStorageImage);
    p.write(&mut out, Access::ComputeShaderWrite);
    p.render(noop);
    g.export(out, Access::TransferRead);
    let plan = CompiledGraph::compile(&g);

    let clear = on(&plan, "clear", "visibility");
    assert_eq!(clear.len(), 1, "{plan}");
    assert_eq!(clear[0].layers, Layers::one(2));
    assert_eq!(clear[0].layouts, Some((vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL)));

    let view = on(&plan, "view layer 0", "visibility");
    assert_eq!(view.len(), 1, "{plan}");
    assert_eq!(view[0].layers, Layers::one(0));
    assert_eq!(view[0].layouts, Some((vk::ImageLayout::GENERAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)));

    // Layer 0 is already readable (read after read); layer 1 was never written, layer 2 waits
    // for the transfer: one barrier per range, each from its own layout.
    let compose = on(&plan, "compose", "visibility");
    let ranges: Vec<_> = compose.iter().map(|b| (b.layers, b.layouts.unwrap().0, b.after.clone())).collect();
    assert_eq!(
        ranges,
        vec![
            (Layers::one(1), vk::ImageLayout::UNDEFINED, vec![]),
            (Layers::one(2), vk::ImageLayout::TRANSFER_DST_OPTIMAL, vec![Access::TransferWrite]),
        ],
        "{plan}"
    );
    assert!(compose.iter().all(|b| b.layouts.unwrap().1 == vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL));
}

/// A cube shadow map drawn face by face as a depth attachment, then sampled whole by the resolve.
#[test]
fn a_shadow_map_written_as_depth_attachment_is_then_sampled() {
    let mut g = RenderGraph::new();
    let mut map = g.create_image("shadow map", ImageDesc::array(vk::Format::D32_SFLOAT, 256, 256, 6));
    let mut vis = g.create_image("visibility", visibility(2));
    for face in 0..6 {
        let mut p = g.add_pass("shadow map face");
        p.write_layer(&mut map, face, Access::DepthAttachmentWrite);
        p.render(noop);
    }
    let mut p = g.add_pass("shadow map resolve");
    p.read(&map, Access::ComputeShaderReadSampledImage);
    p.write_layer(&mut vis, 1, Access::ComputeShaderWrite);
    p.render(noop);
    g.export(vis, Access::ComputeShaderReadSampledImage);
    let plan = CompiledGraph::compile(&g);
    assert_eq!(plan.live_pass_names().len(), 7, "every face is read by the resolve:\n{plan}");

    let first = &plan.passes[0].barriers;
    assert_eq!(first.len(), 1, "{plan}");
    assert_eq!(first[0].layers, Layers::all(6), "the first face's barrier readies all six");
    assert_eq!(first[0].layouts, Some((vk::ImageLayout::UNDEFINED, vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)));
    assert!(plan.passes[1..6].iter().all(|p| p.barriers.is_empty()), "faces are disjoint:\n{plan}");

    let sampled = on(&plan, "shadow map resolve", "shadow map");
    assert_eq!(sampled.len(), 1, "{plan}");
    let b = sampled[0];
    assert_eq!(b.layers, Layers::all(6));
    assert_eq!(b.layouts, Some((vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)));
    assert_eq!(
        b.src_stage,
        vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS
    );
    assert_eq!(
        b.src_access,
        vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_READ | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE
    );
    assert_eq!(b.dst_stage, vk::PipelineStageFlags2::COMPUTE_SHADER);
    assert_eq!(b.dst_access, vk::AccessFlags2::SHADER_SAMPLED_READ);
    assert!(plan.resources[0]
        .image_usage
        .contains(vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT | vk::ImageUsageFlags::SAMPLED));
}

/// A pass survives culling exactly when a layer it wrote is read before being overwritten.
#[test]
fn culling_follows_the_layers_each_pass_wrote() {
    let mut g = RenderGraph::new();
    let mut vis = g.create_image("visibility", visibility(2));
    let mut out = g.create_image("radiance", out_desc());
    let mut p = g.add_pass("writes layer 0");
    p.write_layer(&mut vis, 0, Access::ComputeShaderWrite);
    p.render(noop);
    let mut p = g.add_pass("writes layer 1, overwritten");
    p.write_layer(&mut vis, 1, Access::ComputeShaderWrite);
    p.render(noop);
    let mut p = g.add_pass("writes layer 1");
    p.write_layer(&mut vis, 1, Access::ComputeShaderWrite);
    p.render(noop);
    // The handle has moved on twice since layer 0 was written; reading every layer must still
    // keep the writer of layer 0.
    let mut p = g.add_pass("compose");
    p.read(&vis, Access::ComputeShaderReadSampledImage);
    p.write(&mut out, Access::ComputeShaderWrite);
    p.render(noop);
    g.export(out, Access::TransferRead);
    let plan = CompiledGraph::compile(&g);
    assert_eq!(plan.live_pass_names(), vec!["writes layer 0", "writes layer 1", "compose"], "{plan}");

    // A reader of layer 1 alone keeps only layer 1's last writer.
    let mut g = RenderGraph::new();
    let mut vis = g.create_image("visibility", visibility(2));
    let mut out = g.create_image("radiance", out_desc());
    for (name, layer) in [("writes layer 0", 0), ("writes layer 1", 1)] {
        let mut p = g.add_pass(name);
        p.write_layer(&mut vis, layer, Access::ComputeShaderWrite);
        p.render(noop);
    }
    let mut p = g.add_pass("view layer 1");
    p.read_layer(&vis, 1, Access::ComputeShaderReadSampledImage);
    p.write(&mut out, Access::ComputeShaderWrite);
    p.render(noop);
    g.export(out, Access::TransferRead);
    let plan = CompiledGraph::compile(&g);
    assert_eq!(plan.live_pass_names(), vec!["writes layer 1", "view layer 1"], "{plan}");
}

#[test]
fn a_layered_plan_prints_its_layer_ranges() {
    let mut g = RenderGraph::new();
    let mut vis = g.create_image("visibility", visibility(3));
    let mut out = g.create_image("radiance", out_desc());
    let mut p = g.add_pass("clear");
    p.write_layer(&mut vis, 2, Access::TransferWrite);
    p.render(noop);
    let mut p = g.add_pass("resolve");
    p.write_layer(&mut vis, 0, Access::ComputeShaderWrite);
    p.render(noop);
    let mut p = g.add_pass("trace");
    p.write_layer(&mut vis, 1, Access::ComputeShaderWrite);
    p.render(noop);
    let mut p = g.add_pass("compose");
    p.read(&vis, Access::ComputeShaderReadSampledImage);
    p.write(&mut out, Access::ComputeShaderWrite);
    p.render(noop);
    g.export(out, Access::TransferRead);
    let text = CompiledGraph::compile(&g).to_string();
    let expected = "\
frame graph plan:
  resource 0 visibility: image R8_UNORM 64x32x3 layers usage TRANSFER_DST | SAMPLED | STORAGE, transient slot 0, passes 0..=3
  resource 1 radiance: image R16G16B16A16_SFLOAT 64x32 usage TRANSFER_SRC | STORAGE, transient slot 1, passes 3..=4
  pass 0 clear
    barrier visibility layer 2: [] -> [TransferWrite] [UNDEFINED -> TRANSFER_DST_OPTIMAL]
  pass 1 resolve
    barrier visibility layers 0..=1: [] -> [ComputeShaderWrite] [UNDEFINED -> GENERAL]
  pass 2 trace
  pass 3 compose
    barrier visibility layers 0..=1: [ComputeShaderWrite] -> [ComputeShaderReadSampledImage] [GENERAL -> SHADER_READ_ONLY_OPTIMAL]
    barrier visibility layer 2: [TransferWrite] -> [ComputeShaderReadSampledImage] [TRANSFER_DST_OPTIMAL -> SHADER_READ_ONLY_OPTIMAL]
    barrier radiance: [] -> [ComputeShaderWrite] [UNDEFINED -> GENERAL]
  export: barrier radiance: [ComputeShaderWrite] -> [TransferRead] [GENERAL -> TRANSFER_SRC_OPTIMAL]
";
    assert_eq!(text, expected, "\n{text}");
}

#[test]
#[should_panic(expected = "has no layer 3")]
fn a_layer_past_the_image_is_refused() {
    let mut g = RenderGraph::new();
    let mut vis = g.create_image("visibility", visibility(3));
    let mut p = g.add_pass("p");
    p.write_layer(&mut vis, 3, Access::ComputeShaderWrite);
}
