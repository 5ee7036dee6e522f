//! Samplers are shared: pipeline layouts made from different shaders name one sampler per
//! description, made once on the device.

use crate::common;

use umbra::vk::SamplerDesc;

#[test]
fn pipeline_layouts_share_one_sampler_per_description() {
    use umbra::vk::bindings::*;
    use umbra::vk::{spirv, ComputePipeline, DescriptorKind::*};
    let ctx = common::gpu();
    let tonemap = [(DISPLAY_INPUT, SampledImage), (DISPLAY_OUTPUT, StorageImage)];
    let trace = ComputePipeline::new(&ctx, "tonemap", spirv::TONEMAP_COMP, &tonemap, 32, [8, 8]).unwrap();
    let again = ComputePipeline::new(&ctx, "tonemap", spirv::TONEMAP_COMP, &tonemap, 32, [8, 8]).unwrap();
    let ao_view = [(AO_OUTPUT, SampledImage), (AO_VIEW_OUTPUT, StorageImage)];
    let resolve = ComputePipeline::new(&ctx, "ao view", spirv::LIGHTING_AO_VIEW_COMP, &ao_view, 16, [8, 8]).unwrap();
    drop(resolve);
    assert_eq!(trace.layout.sampler, again.layout.sampler, "two layouts, one sampler");
    assert_eq!(ctx.samplers.len(), 1, "three layouts with sampled images made one sampler");
    let asked = ctx.samplers.get(&ctx.device, SamplerDesc::NEAREST_CLAMP).unwrap();
    assert_eq!(asked, trace.layout.sampler);
    let linear = SamplerDesc { filter: ash::vk::Filter::LINEAR, ..SamplerDesc::NEAREST_CLAMP };
    assert_ne!(ctx.samplers.get(&ctx.device, linear).unwrap(), asked, "another description, another sampler");
    assert_eq!(ctx.samplers.len(), 2);
    // A dropped layout leaves the shared sampler alive for the others.
    drop(again);
    assert_eq!(ctx.samplers.len(), 2);
    drop(trace);
    common::assert_clean(&ctx);
}
