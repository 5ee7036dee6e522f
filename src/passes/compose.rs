//! Compose pass: for every light, Lambert plus GGX specular times irradiance and visibility,
//! summed into scene-referred radiance (W/(m^2 sr)). Visibility comes from the visibility
//! target, whatever technique wrote a light's layer; the light table says which layer is whose.
//! Where no light has a layer, a variant that reads no visibility runs instead, so no shadow
//! pass or target is needed; likewise for the environment, AO, emission and area lights
//! (`Variant`). Where nothing shades the frame after compose and it is shown, compose also
//! tone-maps and writes the display image itself (`Variant::display`): no tone-map pass, and no
//! radiance image written only to be read back once. Likewise it folds an accumulated frame into
//! the still view's history (`Variant::history`), in place of the accumulate pass.

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, UVec4, Vec4};

use super::{GBuffer, DISPLAY_FORMAT, RADIANCE_FORMAT, ROWS};
use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey, PipelineSource};

use super::accumulate::History;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    eye: Vec4,
    background: Vec4,
    dims: UVec4,
    environment: Vec4,
    clip_to_eye: Mat4,
}

/// What a compose variant reads beside the G-buffer and the lights; each flag is a `#define`
/// of shaders/compose.comp (build.rs compiles every subset), so a frame runs no code and binds
/// nothing for what it lacks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Variant {
    /// The visibility target and the light table (some light has a layer).
    pub shadowed: bool,
    /// A constant environment: the split-sum table.
    pub environment: bool,
    /// Ambient occlusion scaling the environment (only with `environment`).
    pub occluded: bool,
    /// The G-buffer's emission and material occlusion.
    pub emissive: bool,
    /// Lights with a size, shaded as sphere and disk lights: the LTC and split-sum tables.
    pub area_lights: bool,
    /// The environment is a map (`crate::lighting::envmap`, only with `environment`): its SH
    /// irradiance, prefiltered layers and the map itself for the background.
    pub environment_map: bool,
    /// Tone-mapped 8-bit display values instead of radiance, as the tone-map pass would make
    /// them: for display output with no rect lights after compose.
    pub display: bool,
    /// Folds the frame into a still view's accumulation history (the accumulate pass's work,
    /// where no rect lights shade the frame after compose); with `display`, shows the mean.
    pub history: bool,
}

impl Variant {
    /// Index into `spirv::COMPOSE_COMP` and the pipeline cache: the flags in the order of
    /// compose.comp's `// variants:` line.
    pub fn index(self) -> usize {
        [
            self.shadowed,
            self.environment,
            self.occluded,
            self.emissive,
            self.area_lights,
            self.environment_map,
            self.display,
            self.history,
        ]
        .iter()
        .enumerate()
        .map(|(i, &on)| usize::from(on) << i)
        .sum()
    }

    /// The variant of `index` (`index`'s inverse).
    fn from_index(index: usize) -> Variant {
        let on = |bit: usize| index & (1 << bit) != 0;
        Variant {
            shadowed: on(0),
            environment: on(1),
            occluded: on(2),
            emissive: on(3),
            area_lights: on(4),
            environment_map: on(5),
            display: on(6),
            history: on(7),
        }
    }

    /// Whether a frame can ask for this variant: ambient occlusion and an environment map only
    /// come with an environment (compose.comp's `// variant-requires:` line, which build.rs
    /// follows: it compiles no other).
    pub fn can_occur(self) -> bool {
        self.environment || !(self.occluded || self.environment_map)
    }

    fn name(self) -> String {
        let parts = [
            (!self.shadowed, "unshadowed"),
            (self.environment && !self.environment_map, "environment"),
            (self.environment_map, "environment map"),
            (self.occluded, "AO"),
            (self.emissive, "emissive"),
            (self.area_lights, "area lights"),
            (self.display, "tone-mapped"),
            (self.history, "accumulated"),
        ];
        let on: Vec<&str> = parts.iter().filter(|(on, _)| *on).map(|(_, name)| *name).collect();
        if on.is_empty() {
            "compose".to_owned()
        } else {
            format!("compose ({})", on.join(", "))
        }
    }
}

/// Number of compose variants (`Variant::index` is below it).
pub const VARIANTS: usize = spirv::COMPOSE_COMP.len();

/// One compose variant, with the set layout of the pass that asks for it.
fn pipeline(ctx: &Arc<GpuContext>, variant: Variant, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    // A variant no frame asks for was not compiled (`Variant::can_occur`).
    assert!(variant.can_occur(), "{} cannot occur: ambient occlusion or a map without an environment", variant.name());
    let spv = spirv::COMPOSE_COMP[variant.index()];
    // Pipelines keep a 'static name: every variant's, made once per process.
    static NAMES: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
    let names = NAMES.get_or_init(|| (0..VARIANTS).map(|i| Variant::from_index(i).name()).collect());
    let name: &'static str = &names[variant.index()];
    ComputePipeline::new(ctx, name, spv, layout, std::mem::size_of::<Push>() as u32, ROWS)
}

/// The environment's part of compose's inputs.
pub struct EnvironmentInputs<'h> {
    /// Radiance from every direction, W/(m^2 sr).
    pub radiance: glam::Vec3,
    /// Ambient occlusion (1 open, 0 enclosed), scaling the environment term.
    pub occlusion: Option<&'h Handle<ImageKind>>,
    /// With an environment map, its data on the device (`radiance` then scales it).
    pub map: Option<MapInputs<'h>>,
}

/// An environment map's part of compose's inputs (`crate::lighting::envmap`).
pub struct MapInputs<'h> {
    pub sh: &'h Handle<BufferKind>,
    pub prefiltered: &'h Handle<ImageKind>,
    pub source: &'h Handle<ImageKind>,
    pub layers: u32,
    /// The inverse of the eye-relative view-projection: background pixels' view directions.
    pub clip_to_eye: Mat4,
}

pub struct ComposeInputs<'h, 'a> {
    /// The variant this frame runs; the inputs below must be those its flags name.
    pub variant: Variant,
    pub lights: &'h Handle<BufferKind>,
    pub light_count: u32,
    /// The visibility target and the light table (each light's layer), where any light has
    /// a layer.
    pub visibility: Option<(&'h Handle<ImageKind>, &'h Handle<BufferKind>)>,
    pub eye: glam::Vec3,
    pub background: glam::Vec3,
    /// The scene gave `background` (else a map variant shows the map there).
    pub background_given: bool,
    pub environment: Option<EnvironmentInputs<'h>>,
    /// The split-sum table (with an environment or area lights).
    pub brdf_table: Option<&'h Handle<BufferKind>>,
    /// The LTC table (with area lights).
    pub ltc_table: Option<&'h Handle<BufferKind>>,
    /// Exposure in stops, for a variant that writes display values (`Variant::display`).
    pub exposure_ev: Option<f32>,
    /// The accumulation history to fold the frame into (`Variant::history`).
    pub history: Option<&'h History<'a>>,
}

pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    gbuffer: &GBuffer,
    inputs: ComposeInputs<'_, 'a>,
    extent: vk::Extent2D,
) -> GpuResult<Composed> {
    let variant = inputs.variant;
    let occlusion = inputs.environment.as_ref().and_then(|e| e.occlusion);
    let map = inputs.environment.as_ref().and_then(|e| e.map.as_ref());
    assert_eq!(
        variant,
        Variant {
            shadowed: inputs.visibility.is_some(),
            environment: inputs.environment.is_some(),
            occluded: occlusion.is_some(),
            emissive: gbuffer.emission.is_some(),
            area_lights: inputs.ltc_table.is_some(),
            environment_map: map.is_some(),
            display: inputs.exposure_ev.is_some(),
            history: inputs.history.is_some(),
        },
        "compose's inputs are those of its variant"
    );
    let mut output = match (variant.display, variant.history) {
        (true, _) => Some(graph.create_image("display", ImageDesc::new(DISPLAY_FORMAT, extent.width, extent.height))),
        (false, false) => {
            Some(graph.create_image("radiance", ImageDesc::new(RADIANCE_FORMAT, extent.width, extent.height)))
        }
        // The history is the result.
        (false, true) => None,
    };
    let mut mean = inputs.history.map(|h| h.import(graph));
    let mut pass = graph.add_pass("compose");
    let sampled = Access::ComputeShaderReadSampledImage;
    let buffer = Access::ComputeShaderReadStorageBuffer;
    let mut bound = vec![
        (COMPOSE_POSITION, Bound::Image(pass.read(&gbuffer.position, sampled))),
        (COMPOSE_NORMAL, Bound::Image(pass.read(&gbuffer.normal, sampled))),
        (COMPOSE_MATERIAL, Bound::Image(pass.read(&gbuffer.material, sampled))),
        (COMPOSE_LIGHTS, Bound::Buffer(pass.read(inputs.lights, buffer))),
    ];
    if let Some(output) = &mut output {
        bound.push((COMPOSE_RADIANCE, Bound::Image(pass.write(output, Access::ComputeShaderWrite))));
    }
    let frames = inputs.history.map_or(0, |h| h.frames);
    if let Some(mean) = &mut mean {
        if frames > 0 {
            pass.read(mean, Access::ComputeShaderReadStorageImage);
        }
        bound.push((COMPOSE_HISTORY, Bound::Image(pass.write(mean, Access::ComputeShaderWrite))));
    }
    if let Some((v, table)) = inputs.visibility {
        bound.push((COMPOSE_VISIBILITY, Bound::Image(pass.read(v, sampled))));
        bound.push((COMPOSE_LIGHT_LAYERS, Bound::Buffer(pass.read(table, buffer))));
    }
    if let Some(emission) = &gbuffer.emission {
        bound.push((COMPOSE_EMISSION, Bound::Image(pass.read(emission, sampled))));
    }
    if variant.environment || variant.area_lights {
        let table = inputs.brdf_table.expect("the split-sum table comes with an environment or area lights");
        bound.push((COMPOSE_BRDF_TABLE, Bound::Buffer(pass.read(table, buffer))));
    }
    if let Some(ao) = occlusion {
        bound.push((COMPOSE_AMBIENT_OCCLUSION, Bound::Image(pass.read(ao, sampled))));
    }
    if let Some(ltc) = inputs.ltc_table {
        bound.push((COMPOSE_LTC_TABLE, Bound::Buffer(pass.read(ltc, buffer))));
    }
    let (mut layers, mut clip_to_eye) = (0, Mat4::IDENTITY);
    if let Some(map) = map {
        bound.push((COMPOSE_ENV_SH, Bound::Buffer(pass.read(map.sh, buffer))));
        bound.push((COMPOSE_ENV_PREFILTERED, Bound::Filtered(pass.read(map.prefiltered, sampled))));
        bound.push((COMPOSE_ENV_MAP, Bound::Filtered(pass.read(map.source, sampled))));
        layers = map.layers;
        clip_to_eye = map.clip_to_eye;
    }
    let environment = inputs.environment.as_ref().map_or(glam::Vec3::ZERO, |e| e.radiance);
    let push = Push {
        eye: inputs.eye.extend(inputs.exposure_ev.unwrap_or(0.0)),
        background: inputs.background.extend(if inputs.background_given { 1.0 } else { 0.0 }),
        dims: UVec4::new(extent.width, extent.height, inputs.light_count, layers),
        environment: environment.extend(f32::from_bits(frames)),
        clip_to_eye,
    };
    let key = PipelineKey::new("compose", variant.index() as u32);
    let pipeline = pipelines.compute(key, &layout_of(&bound), |ctx, layout| pipeline(ctx, variant, layout))?;
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(match output {
        Some(image) => Composed { image, history: mean },
        None => Composed { image: mean.expect("a variant without an output image writes the history"), history: None },
    })
}

/// What compose wrote: the frame's image (radiance, display values, or with a history and no
/// display the history itself) and, beside display values, the history.
pub struct Composed {
    pub image: Handle<ImageKind>,
    pub history: Option<Handle<ImageKind>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_variant_index_names_its_own_flags() {
        for i in 0..VARIANTS {
            assert_eq!(Variant::from_index(i).index(), i);
        }
        assert_eq!(VARIANTS, 256, "eight flags in compose.comp's variants line");
    }

    /// build.rs compiles exactly the variants that can occur: those whose ambient occlusion and
    /// environment map come with an environment, as the renderer builds them.
    #[test]
    fn exactly_the_variants_that_can_occur_are_compiled() {
        let mut compiled = 0;
        for i in 0..VARIANTS {
            let v = Variant::from_index(i);
            let can_occur = v.can_occur();
            assert_eq!(!spirv::COMPOSE_COMP[i].is_empty(), can_occur, "{}", v.name());
            compiled += usize::from(can_occur);
        }
        assert_eq!(compiled, 160);
    }
}
