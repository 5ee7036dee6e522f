//! Samplers are shared: pipeline layouts made from different shaders name one sampler per
//! description, made once on the device.

use crate::common;

use umbra::vk::SamplerDesc;

#[test]
fn pipeline_layouts_share_one_sampler_per_description() {
    let ctx = common::gpu();
    let trace = umbra::shadows::traced::pipeline(&ctx, Default::default(), false).unwrap();
    let again = umbra::shadows::traced::pipeline(&ctx, Default::default(), false).unwrap();
    let resolve = umbra::shadows::map::resolve_pipeline(&ctx).unwrap();
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
