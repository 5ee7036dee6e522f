//! The frame graph. Passes declare what they read and write through typed, versioned handles;
//! `compile` derives culling, lifetimes, usage flags, transient allocation and one batched
//! barrier per pass; `execute` records it. Passes never write a barrier themselves. Accesses
//! name the image layers they touch (`read_layers`, `write_layers`; `read` and `write` take every
//! layer), and compile tracks state per layer range.

mod access;
mod compile;
mod execute;
mod layers;

use std::marker::PhantomData;

use ash::vk;

pub use access::{Access, AccessInfo, Applies};
pub use compile::{Barrier, CompiledGraph, CompiledPass, ResourcePlan, Storage};
pub use compile::{ResourceDescKey, SlotKey};
pub use execute::{layout_of, Bound, GpuTimings, PassContext, TimingMode, TransientCache};
pub use layers::Layers;

pub use crate::vk::ImageDesc;

/// Marker types so image and buffer handles cannot be confused.
#[derive(Debug)]
pub enum ImageKind {}
#[derive(Debug)]
pub enum BufferKind {}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BufferDesc {
    pub size: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ResourceDesc {
    Image(ImageDesc),
    Buffer(BufferDesc),
}

/// A resource in the graph at one version. Not `Clone`: writing takes `&mut` and bumps the
/// version, so a reader can never hold on to contents that a later pass has overwritten.
#[derive(Debug)]
pub struct Handle<K> {
    id: usize,
    version: u32,
    _kind: PhantomData<K>,
}

/// What a pass's closure holds to find the Vulkan object behind a declared access.
#[derive(Debug)]
pub struct Ref<K> {
    pub(crate) id: usize,
    pub(crate) access: Access,
    /// Declared through `read_layers` / `write_layers`: the pass binds this one layer through its
    /// own 2D view. `None`: the pass binds the whole image's view.
    pub(crate) layer: Option<u32>,
    _kind: PhantomData<K>,
}

impl<K> Clone for Ref<K> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<K> Copy for Ref<K> {}

impl<K> Handle<K> {
    pub fn id(&self) -> usize {
        self.id
    }
}

/// A Vulkan object that lives outside the graph. An image's `stencil` is a view of its stencil
/// aspect alone (what accesses that `Access::views_stencil` bind), or null; `layer_views` holds a
/// 2D view of each layer of an array image (what `read_layers` / `write_layers` bind), or nothing.
#[derive(Clone, Debug)]
pub enum External {
    Image { image: vk::Image, view: vk::ImageView, stencil: vk::ImageView, layer_views: Vec<vk::ImageView> },
    Buffer { buffer: vk::Buffer },
}

#[derive(Clone, Debug)]
pub(crate) struct ResourceDecl {
    pub name: &'static str,
    pub desc: ResourceDesc,
    /// Imported resources: the object and the access it was last used with.
    pub imported: Option<(External, Access)>,
    /// Imported resources: the usage flags they were created with (raw image or buffer flags),
    /// which the graph checks its derived usage against.
    pub created_usage: u32,
    pub version: u32,
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct PassAccess {
    pub resource: usize,
    pub access: Access,
    /// The layers it touches (all of them for `read` / `write`; buffers have one).
    pub layers: Layers,
}

pub(crate) type PassFn<'a> = Box<dyn FnOnce(&mut PassContext) -> crate::vk::GpuResult<()> + 'a>;

pub(crate) struct PassDecl<'a> {
    pub name: &'static str,
    pub detail: Option<String>,
    pub accesses: Vec<PassAccess>,
    pub run: Option<PassFn<'a>>,
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct ExportDecl {
    pub resource: usize,
    pub access: Access,
    /// Passes declared before the export: the version it exports is what they wrote, and their
    /// writers of it survive culling even where a later pass writes the resource again (a
    /// partial write, such as a buffer's rows, leaves the earlier writes in place).
    pub after: usize,
}

/// One frame's graph, built fresh each frame; `'a` is the lifetime of what pass closures borrow.
#[derive(Default)]
pub struct RenderGraph<'a> {
    pub(crate) resources: Vec<ResourceDecl>,
    pub(crate) passes: Vec<PassDecl<'a>>,
    pub(crate) exports: Vec<ExportDecl>,
}

impl<'a> RenderGraph<'a> {
    pub fn new() -> Self {
        RenderGraph { resources: Vec::new(), passes: Vec::new(), exports: Vec::new() }
    }

    fn declare<K>(
        &mut self,
        name: &'static str,
        desc: ResourceDesc,
        imported: Option<(External, Access)>,
        created_usage: u32,
    ) -> Handle<K> {
        self.resources.push(ResourceDecl { name, desc, imported, created_usage, version: 0 });
        Handle { id: self.resources.len() - 1, version: 0, _kind: PhantomData }
    }

    /// A transient image: created (or taken from the cache) by the graph, usage derived.
    pub fn create_image(&mut self, name: &'static str, desc: ImageDesc) -> Handle<ImageKind> {
        self.declare(name, ResourceDesc::Image(desc), None, 0)
    }

    pub fn create_buffer(&mut self, name: &'static str, size: u64) -> Handle<BufferKind> {
        self.declare(name, ResourceDesc::Buffer(BufferDesc { size }), None, 0)
    }

    /// An image that lives outside the graph, created with `usage`, last used with `access`.
    /// Compilation fails loudly if the graph would use it in a way `usage` does not allow.
    pub fn import_image(
        &mut self,
        name: &'static str,
        desc: ImageDesc,
        (image, view, usage): (vk::Image, vk::ImageView, vk::ImageUsageFlags),
        access: Access,
    ) -> Handle<ImageKind> {
        assert!(access.applies_to_image(), "{name}: {access:?} is not an image access");
        let views = Vec::new();
        let external =
            Some((External::Image { image, view, stencil: vk::ImageView::null(), layer_views: views }, access));
        self.declare(name, ResourceDesc::Image(desc), external, usage.as_raw())
    }

    /// A buffer that lives outside the graph, created with `usage`, last used with `access`.
    pub fn import_raw_buffer(
        &mut self,
        name: &'static str,
        (buffer, size, usage): (vk::Buffer, u64, vk::BufferUsageFlags),
        access: Access,
    ) -> Handle<BufferKind> {
        assert!(access.applies_to_buffer(), "{name}: {access:?} is not a buffer access");
        let external = Some((External::Buffer { buffer }, access));
        self.declare(name, ResourceDesc::Buffer(BufferDesc { size }), external, usage.as_raw())
    }

    /// Imports one of umbra's own buffers (its handle, size and usage).
    pub fn import_buffer(
        &mut self,
        name: &'static str,
        buffer: &crate::vk::Buffer,
        access: Access,
    ) -> Handle<BufferKind> {
        self.import_raw_buffer(name, (buffer.raw, buffer.size, buffer.usage), access)
    }

    /// Imports one of umbra's own images.
    pub fn import_owned_image(
        &mut self,
        name: &'static str,
        image: &crate::vk::Image,
        access: Access,
    ) -> Handle<ImageKind> {
        let handle = self.import_image(name, image.desc, (image.raw, image.view, image.usage), access);
        if let Some((External::Image { stencil, layer_views, .. }, _)) = &mut self.resources[handle.id].imported {
            *stencil = image.stencil_view;
            layer_views.clone_from(&image.layer_views);
        }
        handle
    }

    /// Marks a result as leaving the graph, to be used next with `access`: the passes that lead
    /// to it survive culling and a final barrier brings it to that access.
    pub fn export<K>(&mut self, handle: Handle<K>, access: Access) {
        self.export_version(&handle, access);
    }

    /// `export` of the handle's current version, which later passes may still read (a write
    /// after this call would leave the export stale, which `check_version` catches at the
    /// write's next use).
    pub fn export_version<K>(&mut self, handle: &Handle<K>, access: Access) {
        self.check_version(handle);
        self.exports.push(ExportDecl { resource: handle.id, access, after: self.passes.len() });
    }

    /// Compiles the graph, records it into a command buffer of its own with transients from a
    /// fresh cache, submits it and waits: a one-off graph (an upload, a read-back, a bake).
    pub fn run_once(self, ctx: &std::sync::Arc<crate::vk::GpuContext>) -> crate::vk::GpuResult<()> {
        let plan = CompiledGraph::compile(&self);
        let mut cache = TransientCache::new(ctx)?;
        ctx.submit_and_wait(|cmd| cache.execute(self, &plan, cmd, false))?;
        Ok(())
    }

    pub fn add_pass<'g>(&'g mut self, name: &'static str) -> PassBuilder<'g, 'a> {
        PassBuilder { graph: self, pass: PassDecl { name, detail: None, accesses: Vec::new(), run: None } }
    }

    fn check_version<K>(&self, handle: &Handle<K>) {
        let r = &self.resources[handle.id];
        assert_eq!(handle.version, r.version, "{}: stale handle (version {} of {})", r.name, handle.version, r.version);
    }

    /// Every layer of a resource (buffers have one).
    pub(crate) fn all_layers(&self, id: usize) -> Layers {
        match self.resources[id].desc {
            ResourceDesc::Image(d) => Layers::all(d.layers),
            ResourceDesc::Buffer(_) => Layers::all(1),
        }
    }

    /// What an image handle refers to (typed handles make this infallible).
    pub fn image_desc(&self, handle: &Handle<ImageKind>) -> ImageDesc {
        match self.resources[handle.id].desc {
            ResourceDesc::Image(d) => d,
            ResourceDesc::Buffer(_) => unreachable!("an image handle names an image"),
        }
    }
}

pub struct PassBuilder<'g, 'a> {
    graph: &'g mut RenderGraph<'a>,
    pass: PassDecl<'a>,
}

impl<'a> PassBuilder<'_, 'a> {
    fn check_kind(&self, id: usize, access: Access) {
        let r = &self.graph.resources[id];
        let fits = match r.desc {
            ResourceDesc::Image(_) => access.applies_to_image(),
            ResourceDesc::Buffer(_) => access.applies_to_buffer(),
        };
        assert!(fits, "pass {}: {access:?} does not apply to {} ({:?})", self.pass.name, r.name, r.desc);
        assert!(access != Access::Nothing, "pass {}: Access::Nothing is not a use", self.pass.name);
    }

    /// Declares a read of every layer. Rejects write accesses: those go through `write`.
    pub fn read<K>(&mut self, handle: &Handle<K>, access: Access) -> Ref<K> {
        let layers = self.graph.all_layers(handle.id);
        self.declare_read(handle, layers, access, None)
    }

    /// Declares a write of every layer and bumps the handle's version. Rejects read accesses.
    pub fn write<K>(&mut self, handle: &mut Handle<K>, access: Access) -> Ref<K> {
        let layers = self.graph.all_layers(handle.id);
        self.declare_write(handle, layers, access, None)
    }

    /// Declares a read of one layer of an array image, which the pass binds through that
    /// layer's own 2D view: earlier writers of other layers are neither kept nor waited for.
    pub fn read_layer(&mut self, handle: &Handle<ImageKind>, layer: u32, access: Access) -> Ref<ImageKind> {
        self.declare_read(handle, self.one_layer(handle.id, layer), access, Some(layer))
    }

    /// Declares a write of one layer of an array image, bound through that layer's 2D view.
    /// Passes that write other layers need no barrier against this one. The handle's version
    /// still moves on: a later reader of any layer names the image after this write, and the
    /// graph finds each layer's own last writer.
    pub fn write_layer(&mut self, handle: &mut Handle<ImageKind>, layer: u32, access: Access) -> Ref<ImageKind> {
        let layers = self.one_layer(handle.id, layer);
        self.declare_write(handle, layers, access, Some(layer))
    }

    fn one_layer(&self, id: usize, layer: u32) -> Layers {
        let r = &self.graph.resources[id];
        let ResourceDesc::Image(d) = r.desc else { unreachable!("an image handle names an image") };
        assert!(d.array && layer < d.layers, "pass {}: {} has no layer {layer} ({d:?})", self.pass.name, r.name);
        Layers::one(layer)
    }

    fn declare_read<K>(&mut self, handle: &Handle<K>, layers: Layers, access: Access, layer: Option<u32>) -> Ref<K> {
        assert!(!access.is_write(), "pass {}: {access:?} is a write; declare it with write()", self.pass.name);
        self.graph.check_version(handle);
        self.check_kind(handle.id, access);
        self.pass.accesses.push(PassAccess { resource: handle.id, access, layers });
        Ref { id: handle.id, access, layer, _kind: PhantomData }
    }

    fn declare_write<K>(
        &mut self,
        handle: &mut Handle<K>,
        layers: Layers,
        access: Access,
        layer: Option<u32>,
    ) -> Ref<K> {
        assert!(access.is_write(), "pass {}: {access:?} is a read; declare it with read()", self.pass.name);
        self.graph.check_version(handle);
        self.check_kind(handle.id, access);
        self.pass.accesses.push(PassAccess { resource: handle.id, access, layers });
        let r = &mut self.graph.resources[handle.id];
        r.version += 1;
        handle.version = r.version;
        Ref { id: handle.id, access, layer, _kind: PhantomData }
    }

    /// A note on the pass's work for the printed plan (for example how many draws it makes).
    pub fn detail(&mut self, text: String) {
        self.pass.detail = Some(text);
    }

    /// Records the pass's commands when the graph executes (skipped if the pass is culled).
    pub fn render(mut self, run: impl FnOnce(&mut PassContext) -> crate::vk::GpuResult<()> + 'a) {
        self.pass.run = Some(Box::new(run));
        self.graph.passes.push(self.pass);
    }
}
