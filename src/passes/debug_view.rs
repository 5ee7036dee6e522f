//! Debug-view pass: writes one G-buffer channel, or one light's visibility, instead of
//! the shaded image. Only the passes that view needs survive culling.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec4};

use super::{GBuffer, RADIANCE_FORMAT, ROWS};
use crate::graph::{layout_of, Access, Bound, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey, PipelineSource};

pub use crate::config::DebugView;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    eye: Vec4,
    origin: Vec4,
    params: UVec4,
}

/// Which of the views' pipelines: a G-buffer channel (`debug_view.comp`), a light's
/// visibility, or the geometric normal decoded from the integer surface channel.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Channel = 0,
    Visibility = 1,
    GeometricNormal = 2,
}

fn pipeline(ctx: &Arc<GpuContext>, kind: Kind, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    let push = std::mem::size_of::<Push>() as u32;
    let (name, spirv) = match kind {
        Kind::Channel => ("debug view", spirv::DEBUG_VIEW_COMP),
        Kind::Visibility => ("debug visibility", spirv::DEBUG_VISIBILITY_COMP),
        Kind::GeometricNormal => ("debug geometric normal", spirv::DEBUG_GEOMETRIC_NORMAL_COMP),
    };
    ComputePipeline::new(ctx, name, spirv, layout, push, ROWS)
}

pub struct DebugInputs<'h> {
    pub view: DebugView,
    /// The visibility target and the layer of the light the view shows.
    pub visibility: Option<(&'h Handle<ImageKind>, u32)>,
    /// Scene-local eye.
    pub eye: glam::Vec3,
    /// World position of the scene-local origin: the position view reports world positions.
    pub origin: glam::Vec3,
    /// Distance shown as white in the display-referred depth view.
    pub far: f32,
    /// Map values into 0..=1 for an 8-bit file (else raw values for EXR).
    pub display: bool,
}

/// The view's number in shaders/include/debug_view_body.glsl.
fn shader_view(view: DebugView) -> u32 {
    match view {
        DebugView::Albedo => 0,
        DebugView::Normal => 1,
        DebugView::Depth => 2,
        DebugView::Position => 3,
        DebugView::Visibility(_) => 4,
        // Its input is the G-buffer's motion channel.
        DebugView::Motion => 6,
        // Its own shader (debug_geometric_normal.comp), which reads no view number.
        DebugView::GeometricNormal => 5,
        // Written by the technique itself (`shadows::add`), never by this pass.
        DebugView::ShadowMap { .. }
        | DebugView::Cascades(_)
        | DebugView::Stencil(_)
        | DebugView::Hybrid(_)
        | DebugView::Denoise(_)
        | DebugView::AmbientOcclusion
        | DebugView::DenoiseOcclusion => {
            unreachable!("a technique's own view")
        }
    }
}

pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    gbuffer: &GBuffer,
    inputs: DebugInputs<'_>,
    extent: vk::Extent2D,
) -> GpuResult<Handle<ImageKind>> {
    let mut out = graph.create_image("debug view", ImageDesc::new(RADIANCE_FORMAT, extent.width, extent.height));
    let source = match inputs.view {
        DebugView::Normal => &gbuffer.normal,
        DebugView::GeometricNormal => &gbuffer.surface,
        DebugView::Motion => gbuffer.motion.as_ref().expect("a frame with the motion view draws the motion channel"),
        _ => &gbuffer.position,
    };
    let mut pass = graph.add_pass("debug view");
    let mut bound = vec![
        (DISPLAY_INPUT, Bound::Image(pass.read(source, Access::ComputeShaderReadSampledImage))),
        (DISPLAY_OUTPUT, Bound::Image(pass.write(&mut out, Access::ComputeShaderWrite))),
    ];
    let kind = match inputs.visibility.filter(|_| matches!(inputs.view, DebugView::Visibility(_))) {
        Some((v, l)) => {
            // The light's layer alone: other lights' shadow passes are culled.
            let layer = pass.read_layer(v, l, Access::ComputeShaderReadSampledImage);
            bound.push((DISPLAY_VISIBILITY, Bound::Image(layer)));
            Kind::Visibility
        }
        None if inputs.view == DebugView::GeometricNormal => Kind::GeometricNormal,
        None => Kind::Channel,
    };
    if inputs.view != DebugView::GeometricNormal {
        // debug_view_body.glsl's views also read the material channel (the albedo view).
        let material = pass.read(&gbuffer.material, Access::ComputeShaderReadSampledImage);
        bound.push((DISPLAY_MATERIAL, Bound::Image(material)));
    }
    let key = PipelineKey::new("debug view", kind as u32);
    let pipeline = pipelines.compute(key, &layout_of(&bound), |ctx, layout| pipeline(ctx, kind, layout))?;
    let push = Push {
        eye: inputs.eye.extend(1.0 / inputs.far.max(1e-6)),
        origin: inputs.origin.extend(0.0),
        params: UVec4::new(extent.width, extent.height, shader_view(inputs.view), inputs.display as u32),
    };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(out)
}
