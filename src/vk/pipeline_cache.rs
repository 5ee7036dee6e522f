//! Pipelines made once and kept. A pass asks for its pipeline by key while it declares itself;
//! the first ask makes it, later asks (this frame's other lights, later frames) get the same one.
//! Nothing else owns a pipeline, so no frame prepares pipelines ahead of its graph and no pass
//! keeps a holder of its own.
//!
//! A key is the pipeline's name and its variant bits. The name stands for the shader and its
//! layout (one name, one set of bindings); the bits for everything that makes one variant differ
//! from another (specialisation constants, soft or hard, alpha-masked). One cache belongs to one
//! renderer, and so to one scene: a variant made with the scene's own material set layout lives
//! exactly as long as that layout.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use super::{ComputePipeline, DescriptorKind, GpuContext, GpuResult, GraphicsPipeline};

/// Where a pass gets its pipelines while it declares itself: the device, to make one, and the
/// renderer's cache, to keep it.
#[derive(Clone, Copy)]
pub struct PipelineSource<'a> {
    pub ctx: &'a Arc<GpuContext>,
    pub cache: &'a PipelineCache,
}

impl<'a> PipelineSource<'a> {
    /// The compute pipeline `key` names, made by `make` the first time with `layout`: the set
    /// layout of the pass that asks (`crate::graph::layout_of` of its bindings). A pass that
    /// binds otherwise than the pipeline was made for is a bug, caught here.
    pub fn compute(
        self,
        key: PipelineKey,
        layout: &[(u32, DescriptorKind)],
        make: impl FnOnce(&Arc<GpuContext>, &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline>,
    ) -> GpuResult<&'a ComputePipeline> {
        let p = self.cache.compute(key, || make(self.ctx, layout))?;
        same_layout(key, &p.layout.bindings, layout);
        Ok(p)
    }

    /// The compute pipeline of a shader with one build: `name`'s, from `spirv`, with `layout`,
    /// `push_bytes` of push constants and workgroups of `local_size`.
    pub fn single(
        self,
        name: &'static str,
        spirv: &'static [u8],
        layout: &[(u32, DescriptorKind)],
        push_bytes: u32,
        local_size: [u32; 2],
    ) -> GpuResult<&'a ComputePipeline> {
        self.compute(PipelineKey::new(name, 0), layout, |ctx, layout| {
            ComputePipeline::new(ctx, name, spirv, layout, push_bytes, local_size)
        })
    }

    /// The graphics pipeline `key` names, made by `make` the first time with `layout`, as
    /// `compute`.
    pub fn graphics(
        self,
        key: PipelineKey,
        layout: &[(u32, DescriptorKind)],
        make: impl FnOnce(&Arc<GpuContext>, &[(u32, DescriptorKind)]) -> GpuResult<GraphicsPipeline>,
    ) -> GpuResult<&'a GraphicsPipeline> {
        let p = self.cache.graphics(key, || make(self.ctx, layout))?;
        same_layout(key, &p.layout.bindings, layout);
        Ok(p)
    }
}

fn same_layout(key: PipelineKey, made: &[(u32, DescriptorKind)], asked: &[(u32, DescriptorKind)]) {
    assert!(
        made.len() == asked.len() && made.iter().zip(asked).all(|(a, b)| a == b),
        "pipeline {key:?} was made with bindings {made:?}, a pass binds {asked:?}"
    );
}

/// Which pipeline: its name (the shader and its layout) and its variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PipelineKey {
    pub name: &'static str,
    pub variant: u32,
}

impl PipelineKey {
    pub const fn new(name: &'static str, variant: u32) -> PipelineKey {
        PipelineKey { name, variant }
    }
}

enum Entry {
    Compute(ComputePipeline),
    Graphics(GraphicsPipeline),
}

/// Pipelines by key, each made the first time it is asked for and kept until the cache drops
/// (before the device: the owner's field order sees to it).
#[derive(Default)]
pub struct PipelineCache {
    // Boxed, and never removed or replaced while the cache lives: a reference to an entry's
    // pipeline stays valid as long as the cache is borrowed.
    entries: Mutex<HashMap<PipelineKey, Box<Entry>>>,
}

impl PipelineCache {
    /// The compute pipeline `key` names, made by `make` if it was not.
    pub fn compute(
        &self,
        key: PipelineKey,
        make: impl FnOnce() -> GpuResult<ComputePipeline>,
    ) -> GpuResult<&ComputePipeline> {
        match self.get_or_make(key, || make().map(Entry::Compute))? {
            Entry::Compute(p) => Ok(p),
            Entry::Graphics(_) => panic!("pipeline {key:?} was made as a graphics pipeline"),
        }
    }

    /// The graphics pipeline `key` names, made by `make` if it was not.
    pub fn graphics(
        &self,
        key: PipelineKey,
        make: impl FnOnce() -> GpuResult<GraphicsPipeline>,
    ) -> GpuResult<&GraphicsPipeline> {
        match self.get_or_make(key, || make().map(Entry::Graphics))? {
            Entry::Graphics(p) => Ok(p),
            Entry::Compute(_) => panic!("pipeline {key:?} was made as a compute pipeline"),
        }
    }

    /// How many pipelines the cache holds.
    pub fn len(&self) -> usize {
        self.lock().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether `key`'s pipeline has been made.
    pub fn contains(&self, key: PipelineKey) -> bool {
        self.lock().contains_key(&key)
    }

    /// The keys of the pipelines made so far, sorted.
    pub fn keys(&self) -> Vec<PipelineKey> {
        let mut keys: Vec<PipelineKey> = self.lock().keys().copied().collect();
        keys.sort_by_key(|k| (k.name, k.variant));
        keys
    }

    /// The pipeline's handle (`vk::Pipeline`) `key` names, if made: for tests that check two
    /// asks got one pipeline.
    pub fn handle(&self, key: PipelineKey) -> Option<ash::vk::Pipeline> {
        self.lock().get(&key).map(|e| match &**e {
            Entry::Compute(p) => p.pipeline,
            Entry::Graphics(p) => p.pipeline,
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<PipelineKey, Box<Entry>>> {
        // A panic while the lock was held cannot leave the map half-changed (one insert).
        self.entries.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn get_or_make(&self, key: PipelineKey, make: impl FnOnce() -> GpuResult<Entry>) -> GpuResult<&Entry> {
        if let Some(entry) = self.lock().get(&key) {
            let entry: *const Entry = &**entry;
            // SAFETY: the entry is boxed and stays in the map, unmoved and unchanged, until the
            // cache drops; the reference borrows the cache.
            return Ok(unsafe { &*entry });
        }
        // Made without the lock held: making takes a while, and a maker may ask for another key.
        let made = Box::new(make()?);
        let mut entries = self.lock();
        // Another thread may have made it meanwhile: keep theirs (ours drops here).
        let entry: *const Entry = &**entries.entry(key).or_insert(made);
        // SAFETY: as above.
        Ok(unsafe { &*entry })
    }
}
