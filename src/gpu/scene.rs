//! The scene's buffers on the device: vertices, indices, lights, draws (with their caster flag
//! and bounds), the material table of a scene without textures, and `SceneGpu::upload`.

use std::sync::Arc;

use std::collections::HashMap;

use ash::vk;
use glam::{DVec3, Vec3};

use crate::gpu::SCENE_ACCESS;
use crate::graph::Access;
use crate::maths::Bounds;
use crate::scene::bvh::ShadowBvh;
use crate::scene::{Camera, Material, Scene};
use crate::shading::gpu_lights;
use crate::vk::{Buffer, GpuContext, GpuError, GpuResult, TexelView};

use super::*;

/// One mesh's slice of the shared vertex and index buffers.
pub struct Draw {
    pub first_index: u32,
    pub index_count: u32,
    pub vertex_offset: i32,
    /// Its `InstanceRows` (0: the identity).
    pub instance: u32,
    /// Its material's textures (`SceneGpu::materials`), where it has any.
    pub maps: Option<crate::gpu::textures::DrawMaps>,
    pub material: Material,
    /// In a scene without textures, its material's texel in `SceneGpu::material_table`.
    pub table_texel: u32,
    pub cast_shadows: bool,
    /// Drawn without back-face culling (glTF doubleSided).
    pub double_sided: bool,
    /// Flat-shaded (`shading::flat_shaded`): the geometry pass reads none of its triangles.
    pub flat: bool,
    /// The mesh's bounds in the scene-local frame (shadow maps cull draws by them).
    pub bounds: Bounds,
}

/// The scene on the device: uploaded once, imported into every frame's graph.
pub struct SceneGpu {
    /// `vertices` and `indices` as RG32F and R32UI texels: how the geometry pass reads each
    /// fragment's triangle (a texel fetch is one call that reads every lane's texel on lavapipe,
    /// where a storage load whose address it cannot prove the same for every lane is a loop over
    /// them). Declared before
    /// the buffers, so they are dropped first.
    pub vertex_view: TexelView,
    pub index_view: TexelView,
    /// `vertex_count` `Vertex`es, then the `InstanceRows` from byte `instance_offset`: one
    /// buffer, so every pass that binds the vertices has the instances too.
    pub vertices: Buffer,
    pub vertex_count: u32,
    pub instance_offset: u64,
    /// In a moving scene, where the instance rows as the previous frame drew them start (a copy
    /// of the rows after them, for motion vectors); in a static scene they are the rows at
    /// `instance_offset`.
    pub previous_offset: Option<u64>,
    /// Where the `SurfaceVertex`es start in `vertices` (after the instances), in a scene with
    /// textures; they are bound at vertex binding 2 by textured draws.
    pub surface_offset: Option<u64>,
    /// Where the second texture-coordinate set starts in `vertices` (after the `SurfaceVertex`es),
    /// in a scene where some material's maps use two sets; `None` otherwise, and the vertex
    /// buffer is as large as it was with one set. Textured draws bind vertex binding 3 here, or
    /// (with no second set) at `surface_offset`, whose bytes it then reads as coordinates no map
    /// selects (`UvTransforms::second_set` is all false).
    pub second_uv_offset: Option<u64>,
    /// The material textures; `None` in a scene without textures.
    pub materials: Option<crate::gpu::textures::MaterialSets>,
    /// In a scene without textures, its materials, read in place of the G-buffer's material
    /// channel (which such a scene's geometry pass does not write).
    pub material_table: Option<MaterialTable>,
    pub indices: Buffer,
    pub draws: Vec<Draw>,
    pub lights: Buffer,
    pub light_count: u32,
    /// The lights in the scene-local frame (what the buffer holds, before packing).
    pub local_lights: Vec<crate::scene::Light>,
    /// The rect lights in the scene-local frame (`lighting::rects::RectsGpu` holds them on the
    /// device); not counted by `light_count`.
    pub local_rects: Vec<crate::scene::RectLight>,
    pub bvh: BvhBuffers,
    pub has_casters: bool,
    /// Bounds of the geometry in the scene-local frame.
    pub bounds: (Vec3, Vec3),
    /// World position of the scene-local frame's origin (see `Renderer::new`).
    pub origin: DVec3,
    /// The scene's own camera, in the scene-local frame.
    pub camera: Camera,
    /// The draws whose meshes move, in draw order (empty in a static scene).
    pub moving: Vec<MovingDraw>,
    /// The moving draws' instance rows, posed and drawn, and what the next frame writes.
    rows: std::sync::Mutex<Tracked>,
    /// The draws whose meshes deform (skins, morph targets), in draw order: their vertices are
    /// rewritten whenever the scene is posed.
    pub deforming: Vec<DeformingDraw>,
    /// The deforming draws' poses (`skin::pose_bytes`) the next frame's first passes write
    /// into the skin pass's buffer, until a frame that wrote them is recorded.
    deformed: std::sync::Mutex<Tracked>,
    /// The skin pass's data, in a scene with deforming draws.
    skin: Option<super::skin::SkinGpu>,
    /// In a scene with deforming draws, where a copy of the vertices as the previous frame drew
    /// them starts (the motion channel's previous positions, vertex binding 5); `None` otherwise,
    /// and the motion variant reads the vertices themselves there.
    pub previous_vertex_offset: Option<u64>,
    /// The lights as the next frame's first pass writes them, where animated nodes moved some
    /// since the last recorded frame.
    moved_lights: std::sync::Mutex<Option<Arc<Vec<u8>>>>,
}

/// Parts of the vertex buffer a moving scene rewrites, per item (a moving draw's instance row,
/// a deforming draw's vertices): where the item is, and where its copy as the previous frame
/// drew it is (the motion channel's); its bytes as posed last and as the last recorded frame
/// drew them; and the writes the next frame's first pass makes (`import_vertices`), until a
/// frame that made them is recorded.
struct Tracked {
    /// Per item: (byte offset now, byte offset of the previous frame's copy).
    at: Vec<(u64, u64)>,
    posed: Vec<Arc<Vec<u8>>>,
    drawn: Vec<Arc<Vec<u8>>>,
    pending: Option<Arc<Vec<BufferWrite>>>,
}

/// Bytes to write into the vertex buffer at a byte offset.
type BufferWrite = (u64, Arc<Vec<u8>>);

impl Tracked {
    /// Items at `at`, at rest (`rest`: their bytes as uploaded).
    fn new(at: Vec<(u64, u64)>, rest: Vec<Arc<Vec<u8>>>) -> Tracked {
        Tracked { at, posed: rest.clone(), drawn: rest, pending: None }
    }

    /// The items posed anew: the next frame writes them, and the previous copies as drawn.
    /// Returns the bytes it will write.
    fn pose(&mut self, now: Vec<Arc<Vec<u8>>>) -> u64 {
        self.posed = now;
        self.pend(true)
    }

    /// Where the items were in the previous frame (for a first frame, which has no previous one
    /// drawn): the next frame's motion starts there.
    fn pose_previous(&mut self, before: Vec<Arc<Vec<u8>>>) {
        self.drawn = before;
        self.pend(true);
    }

    /// A frame that imported the buffer was recorded: its writes are done, and what it drew is
    /// the next frame's previous copy (written by the next frame where it changed).
    fn recorded(&mut self) {
        self.pending = None;
        if !self.drawn.iter().zip(&self.posed).all(|(a, b)| Arc::ptr_eq(a, b)) {
            self.drawn = self.posed.clone();
            self.pend(false);
        }
    }

    /// Sets the pending writes: the previous copies as drawn, and with `now` the items as posed.
    fn pend(&mut self, now: bool) -> u64 {
        let mut writes = Vec::with_capacity(2 * self.at.len());
        for ((now_at, before_at), (posed, drawn)) in self.at.iter().zip(self.posed.iter().zip(&self.drawn)) {
            if now {
                writes.push((*now_at, posed.clone()));
            }
            writes.push((*before_at, drawn.clone()));
        }
        let bytes = writes.iter().map(|(_, w)| w.len() as u64).sum();
        self.pending = Some(Arc::new(writes));
        bytes
    }

    /// A first pass named `name` making the pending writes into `vertices`, if there are any.
    fn write_pass<'a>(
        &self,
        g: &mut crate::graph::RenderGraph<'a>,
        vertices: &mut crate::graph::Handle<crate::graph::BufferKind>,
        name: &'static str,
    ) {
        let Some(writes) = self.pending.clone() else { return };
        let mut pass = g.add_pass(name);
        pass.detail(format!(
            "{} items, {} KiB",
            self.at.len(),
            writes.iter().map(|(_, w)| w.len()).sum::<usize>() >> 10
        ));
        let dst = pass.write(vertices, Access::TransferWrite);
        pass.render(move |ctx| {
            for (at, bytes) in writes.iter() {
                ctx.update_buffer(dst, *at, bytes);
            }
            Ok(())
        });
        // Exported, so the writes survive a frame that draws nothing.
        g.export_version(vertices, SCENE_ACCESS);
    }
}

/// A draw whose mesh deforms: its vertices in the shared buffer, rewritten as it is posed.
#[derive(Clone, Debug)]
pub struct DeformingDraw {
    /// Its index in `SceneGpu::draws` and in `Scene::meshes`.
    pub draw: usize,
    pub mesh: usize,
    pub first_vertex: u32,
    pub vertex_count: u32,
}

/// The casters' BVH as the scene uploads it: one level, or two for a scene where something moves.
/// The one level is handed over, to be dropped as soon as the device holds it.
#[allow(clippy::large_enum_variant)] // made once a scene and moved once: no boxing needed
pub enum BvhSource<'b> {
    One(ShadowBvh),
    Two(&'b crate::scene::bvh::levels::TwoLevel),
}

/// A draw whose mesh moves: its instance row is rewritten whenever the scene is posed.
#[derive(Clone, Debug)]
pub struct MovingDraw {
    /// Its index in `SceneGpu::draws` and in `Scene::meshes` (the uploaded scene's).
    pub draw: usize,
    pub mesh: usize,
    /// Its own instance row (`InstanceRows`).
    pub row: u32,
    /// The mesh's placement before the motion: its shared geometry's to-local transform, or the
    /// identity for a mesh uploaded in place.
    pub base: glam::DMat4,
    /// Its bounds at rest (moved with it to give `Draw::bounds`).
    pub rest_bounds: Bounds,
}

/// The scene's meshes packed for the device, mesh by mesh (`add`), before the upload.
#[derive(Default)]
struct Packing {
    vertices: Vec<Vertex>,
    indices: Vec<u32>,
    draws: Vec<Draw>,
    instances: Vec<InstanceRows>,
    /// Shared geometry already packed: its first index, vertex offset and flatness.
    shared: HashMap<*const crate::scene::InstanceGeometry, (u32, i32, bool)>,
    /// Parallel to `vertices` once any mesh has textures.
    textured: bool,
    surface_vertices: Vec<SurfaceVertex>,
    /// Parallel to `vertices` once any material's maps use two texture-coordinate sets.
    two_sets: bool,
    second_uvs: Vec<[f32; 2]>,
    materials: Vec<Arc<crate::scene::MaterialTextures>>,
    table_texels: TableTexels,
    moving: Vec<MovingDraw>,
    deforming: Vec<DeformingDraw>,
    lo: Vec3,
    hi: Vec3,
}

/// The vertex buffer's bytes and where its parts start (see `SceneGpu`'s fields).
struct VertexBytes {
    bytes: Vec<u8>,
    instance_offset: u64,
    previous_offset: Option<u64>,
    surface_offset: Option<u64>,
    second_uv_offset: Option<u64>,
    previous_vertex_offset: Option<u64>,
}

impl Packing {
    fn new(scene: &Scene) -> Packing {
        Packing {
            instances: vec![InstanceRows::IDENTITY],
            textured: scene.meshes.iter().any(|m| m.surface.is_some()),
            two_sets: scene.meshes.iter().any(|m| {
                let shared = m.instance.as_ref().is_some_and(|i| !i.geometry.uvs_1.is_empty());
                m.surface.as_ref().is_some_and(|s| !s.uvs_1.is_empty() || shared)
            }),
            lo: Vec3::splat(f32::INFINITY),
            hi: Vec3::splat(f32::NEG_INFINITY),
            ..Packing::default()
        }
    }

    /// Packs mesh `index` of the scene (`moving`: its instance row is its own, rewritten as the
    /// scene is posed).
    fn add(&mut self, index: usize, mesh: &crate::scene::Mesh, moving: bool) {
        let mut bounds = Bounds::EMPTY;
        // The local frame's f32: where the GPU's triangles are (for an instance, where its
        // world-space copy is).
        let positions: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
        positions.iter().filter(|p| p.is_finite()).for_each(|&p| bounds.include(p));
        for p in &positions {
            self.lo = self.lo.min(*p);
            self.hi = self.hi.max(*p);
        }
        // A kept instance (no world-space copy) by its geometry's box moved.
        if let Some((lo, hi)) = mesh.kept_bounds() {
            let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
            bounds.include(lo);
            bounds.include(hi);
            self.lo = self.lo.min(lo);
            self.hi = self.hi.max(hi);
        }
        let (first_index, index_count, vertex_offset, instance, flat) = match &mesh.instance {
            Some(instance) => {
                let (first, offset, flat) = self.add_shared(&instance.geometry);
                self.instances.push(InstanceRows::of(&instance.to_world));
                (first, instance.geometry.indices.len() as u32, offset, self.instances.len() as u32 - 1, flat)
            }
            None => {
                let row = if moving {
                    self.instances.push(InstanceRows::IDENTITY);
                    self.instances.len() as u32 - 1
                } else {
                    0
                };
                let at = (
                    self.indices.len() as u32,
                    mesh.indices.len() as u32,
                    self.vertices.len() as i32,
                    row,
                    crate::shading::flat_shaded(&positions, &mesh.normals, &mesh.indices),
                );
                self.add_own(mesh, &positions, at.2 as usize);
                at
            }
        };
        if mesh.deform.is_some() && mesh.instance.is_none() {
            self.deforming.push(DeformingDraw {
                draw: self.draws.len(),
                mesh: index,
                first_vertex: vertex_offset as u32,
                vertex_count: mesh.positions.len() as u32,
            });
        }
        if moving {
            let base = mesh.instance.as_ref().map_or(glam::DMat4::IDENTITY, |i| i.to_world);
            self.moving.push(MovingDraw {
                draw: self.draws.len(),
                mesh: index,
                row: instance,
                base,
                rest_bounds: bounds,
            });
        }
        let maps = mesh.surface.as_ref().map(|surface| {
            // Set 0 is for meshes without textures (textures::upload).
            let set = 1 + match self.materials.iter().position(|m| Arc::ptr_eq(m, &surface.textures)) {
                Some(set) => set,
                None => {
                    self.materials.push(surface.textures.clone());
                    self.materials.len() - 1
                }
            };
            crate::gpu::textures::draw_maps(set, &surface.textures)
        });
        self.draws.push(Draw {
            first_index,
            index_count,
            vertex_offset,
            instance,
            maps,
            material: mesh.material,
            table_texel: self.table_texels.texel(mesh.material),
            cast_shadows: mesh.cast_shadows,
            double_sided: mesh.double_sided,
            flat,
            bounds,
        });
    }

    /// Packs shared geometry the first time a mesh draws it; returns its first index, vertex
    /// offset and flatness.
    fn add_shared(&mut self, g: &Arc<crate::scene::InstanceGeometry>) -> (u32, i32, bool) {
        if let Some(&at) = self.shared.get(&Arc::as_ptr(g)) {
            return at;
        }
        let at = (
            self.indices.len() as u32,
            self.vertices.len() as i32,
            crate::shading::flat_shaded(&g.positions, &g.normals, &g.indices),
        );
        self.vertices.extend(
            g.positions.iter().zip(&g.normals).map(|(p, n)| Vertex { position: p.to_array(), normal: n.to_array() }),
        );
        if !g.uvs.is_empty() {
            self.surface_vertices.resize(at.1 as usize, SurfaceVertex::default());
            for (k, uv) in g.uvs.iter().enumerate() {
                let tangent = g.tangents.get(k).map_or([0.0; 4], |t| t.to_array());
                self.surface_vertices.push(SurfaceVertex { uv: uv.to_array(), tangent });
            }
        }
        if !g.uvs_1.is_empty() {
            self.second_uvs.resize(at.1 as usize, [0.0; 2]);
            self.second_uvs.extend(g.uvs_1.iter().map(|uv| uv.to_array()));
        }
        self.indices.extend_from_slice(&g.indices);
        self.shared.insert(Arc::as_ptr(g), at);
        at
    }

    /// Packs a mesh uploaded in place (its local-frame `positions`), from vertex `first`.
    fn add_own(&mut self, mesh: &crate::scene::Mesh, positions: &[Vec3], first: usize) {
        for (p, n) in positions.iter().zip(&mesh.normals) {
            self.vertices.push(Vertex { position: p.to_array(), normal: n.to_array() });
        }
        if let Some(surface) = &mesh.surface {
            self.surface_vertices.resize(first, SurfaceVertex::default());
            for (k, uv) in surface.uvs.iter().enumerate() {
                let tangent = surface.tangents.get(k).map_or([0.0; 4], |t| t.to_array());
                self.surface_vertices.push(SurfaceVertex { uv: uv.to_array(), tangent });
            }
            if !surface.uvs_1.is_empty() {
                self.second_uvs.resize(first, [0.0; 2]);
                self.second_uvs.extend(surface.uvs_1.iter().map(|uv| uv.to_array()));
            }
        }
        self.indices.extend_from_slice(&mesh.indices);
    }

    /// The vertex buffer: vertices, instance rows (twice in a moving scene: now and as the
    /// previous frame drew them), then the surface vertices and the second texture-coordinate
    /// set where the scene has them. The packed vertices move into it: freed before the
    /// device's buffers are made (126 MB at the 10M-triangle scene).
    fn vertex_bytes(&mut self) -> VertexBytes {
        let vertices = std::mem::take(&mut self.vertices);
        let mut bytes: Vec<u8> = bytemuck::cast_slice(&vertices).to_vec();
        let instance_offset = bytes.len() as u64;
        bytes.extend_from_slice(bytemuck::cast_slice(&self.instances));
        let previous_offset = (!self.moving.is_empty()).then(|| {
            let at = bytes.len() as u64;
            bytes.extend_from_slice(bytemuck::cast_slice(&self.instances));
            at
        });
        let count = vertices.len();
        let surface_offset = self.textured.then(|| {
            self.surface_vertices.resize(count, SurfaceVertex::default());
            let at = bytes.len() as u64;
            bytes.extend_from_slice(bytemuck::cast_slice(&self.surface_vertices));
            at
        });
        let second_uv_offset = self.two_sets.then(|| {
            self.second_uvs.resize(count, [0.0; 2]);
            let at = bytes.len() as u64;
            bytes.extend_from_slice(bytemuck::cast_slice(&self.second_uvs));
            at
        });
        let previous_vertex_offset = (!self.deforming.is_empty()).then(|| {
            let at = bytes.len() as u64;
            bytes.extend_from_slice(bytemuck::cast_slice(&vertices));
            at
        });
        VertexBytes {
            bytes,
            instance_offset,
            previous_offset,
            surface_offset,
            second_uv_offset,
            previous_vertex_offset,
        }
    }
}

/// Whether the geometry pass can read `vertex_bytes` and `indices` as texel buffers (a view holds
/// at most `maxTexelBufferElements` texels): an error naming the limit where it cannot.
fn check_texel_limits(ctx: &GpuContext, vertex_bytes: usize, indices: &[u32]) -> GpuResult<()> {
    let limit = u64::from(ctx.capabilities.max_texel_buffer_elements);
    for (what, bytes, format) in [
        ("vertices", vertex_bytes, VERTEX_TEXEL_FORMAT),
        ("triangle indices", std::mem::size_of_val(indices), INDEX_TEXEL_FORMAT),
    ] {
        let texel = crate::vk::texel_bytes(format);
        if bytes as u64 / texel > limit {
            return Err(GpuError::Unsupported(format!(
                "the scene's {what} take {} MiB, over {}'s limit of {} MiB for one texel buffer \
                 (maxTexelBufferElements of {texel} bytes): use fewer or simpler meshes",
                bytes >> 20,
                ctx.device_name(),
                (limit * texel) >> 20
            )));
        }
    }
    Ok(())
}

impl SceneGpu {
    /// Uploads `scene`, already moved into the local frame whose origin is `origin`
    /// (`Scene::local_frame`); positions are rounded to f32 here. `moving`: per mesh, whether it
    /// moves (its draw gets an instance row of its own, `SceneGpu::moving`).
    pub fn upload(
        ctx: &Arc<GpuContext>,
        scene: &Scene,
        bvh: BvhSource<'_>,
        moving: &[bool],
        origin: DVec3,
    ) -> GpuResult<SceneGpu> {
        // The BVH first, its host copy dropped once the device holds it: at the 10M-triangle
        // scene its 455 MB would otherwise sit beside the scene's packed vertices and indices.
        let (bvh_buffers, has_casters) = match bvh {
            BvhSource::One(bvh) => (BvhBuffers::upload(ctx, &bvh)?, !bvh.is_empty()),
            BvhSource::Two(levels) => (BvhBuffers::upload_levels(ctx, levels)?, levels.triangle_count() > 0),
        };
        let mut packing = Packing::new(scene);
        for (index, mesh) in scene.meshes.iter().enumerate().filter(|(_, m)| m.triangle_count() > 0) {
            packing.add(index, mesh, moving.get(index).copied().unwrap_or(false));
        }
        let (lo, hi) = if packing.draws.is_empty() { (Vec3::ZERO, Vec3::ZERO) } else { (packing.lo, packing.hi) };
        let lights = gpu_lights(&scene.lights);
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let vertex_count = packing.vertices.len() as u32;
        let vertex = packing.vertex_bytes();
        let materials = match packing.textured {
            true => Some(crate::gpu::textures::upload(ctx, &packing.materials)?),
            false => None,
        };
        let material_table = match packing.textured {
            true => None,
            false => Some(MaterialTable::upload(ctx, &packing.table_texels.texels)?),
        };
        check_texel_limits(ctx, vertex.bytes.len(), &packing.indices)?;
        // The moving draws' rows and the deforming draws' vertices, where they are now and as the
        // previous frame drew them, at rest.
        let row_size = std::mem::size_of::<InstanceRows>() as u64;
        let moving_rows = Tracked::new(
            packing
                .moving
                .iter()
                .map(|m| {
                    let previous = vertex.previous_offset.unwrap_or(vertex.instance_offset);
                    let at = u64::from(m.row) * row_size;
                    (vertex.instance_offset + at, previous + at)
                })
                .collect(),
            packing
                .moving
                .iter()
                .map(|m| Arc::new(bytemuck::bytes_of(&packing.instances[m.row as usize]).to_vec()))
                .collect(),
        );
        let (skin, deformed) = match packing.deforming.is_empty() {
            true => (None, Tracked::new(Vec::new(), Vec::new())),
            false => {
                let previous = vertex.previous_vertex_offset.unwrap_or(0);
                let skin = super::skin::SkinGpu::new(ctx, scene, &packing.deforming, previous)?;
                let tracked = Tracked::new(skin.pose_offsets(), skin.held_poses());
                (Some(skin), tracked)
            }
        };
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        // A moving scene's frames rewrite the instance rows; the skin pass, deforming vertices.
        let rows = match packing.moving.is_empty() {
            true => vk::BufferUsageFlags::empty(),
            false => vk::BufferUsageFlags::TRANSFER_DST,
        } | match packing.deforming.is_empty() {
            true => vk::BufferUsageFlags::empty(),
            // The skin pass writes deforming vertices and copies their previous copy; the tests
            // read them back.
            false => storage | vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST,
        };
        let [vertices, indices, lights] = upload(
            ctx,
            [
                ("vertices", &vertex.bytes, vk::BufferUsageFlags::VERTEX_BUFFER | texel | rows),
                ("indices", bytemuck::cast_slice(&packing.indices), vk::BufferUsageFlags::INDEX_BUFFER | texel),
                // Lights on animated nodes are rewritten as they move.
                ("lights", bytemuck::cast_slice(&lights), storage | vk::BufferUsageFlags::TRANSFER_DST),
            ],
        )?;
        Ok(SceneGpu {
            vertex_view: TexelView::new(ctx, &vertices, VERTEX_TEXEL_FORMAT)?,
            index_view: TexelView::new(ctx, &indices, INDEX_TEXEL_FORMAT)?,
            vertices,
            vertex_count,
            instance_offset: vertex.instance_offset,
            previous_offset: vertex.previous_offset,
            previous_vertex_offset: vertex.previous_vertex_offset,
            surface_offset: vertex.surface_offset,
            second_uv_offset: vertex.second_uv_offset,
            materials,
            material_table,
            indices,
            draws: packing.draws,
            lights,
            light_count: scene.lights.len() as u32,
            local_lights: scene.lights.clone(),
            local_rects: scene.rect_lights.clone(),
            bvh: bvh_buffers,
            has_casters,
            bounds: (lo, hi),
            origin,
            camera: scene.camera,
            rows: std::sync::Mutex::new(moving_rows),
            moving: packing.moving,
            deforming: packing.deforming,
            deformed: std::sync::Mutex::new(deformed),
            skin,
            moved_lights: std::sync::Mutex::new(None),
        })
    }

    /// Moves the lights to `lights` (the same lights, in the local frame, as animated nodes
    /// carry them now): the shadow techniques read them at once, the next frame's first pass
    /// writes the device's copy. Returns the bytes that frame will move.
    pub fn move_lights(&mut self, lights: Vec<crate::scene::Light>) -> u64 {
        assert_eq!(lights.len(), self.local_lights.len(), "moving lights keeps them");
        let bytes: Vec<u8> = bytemuck::cast_slice(&gpu_lights(&lights)).to_vec();
        let size = bytes.len() as u64;
        self.local_lights = lights;
        *self.moved_lights.lock().unwrap_or_else(|e| e.into_inner()) = Some(Arc::new(bytes));
        size
    }

    /// Imports the lights into `g`, written first where they moved since the last recorded
    /// frame.
    pub fn import_lights<'a>(
        &'a self,
        g: &mut crate::graph::RenderGraph<'a>,
    ) -> crate::graph::Handle<crate::graph::BufferKind> {
        let mut lights = g.import_buffer("lights", &self.lights, SCENE_ACCESS);
        let Some(bytes) = self.moved_lights.lock().unwrap_or_else(|e| e.into_inner()).clone() else {
            return lights;
        };
        let mut pass = g.add_pass("moved lights");
        let dst = pass.write(&mut lights, Access::TransferWrite);
        pass.render(move |ctx| {
            ctx.update_buffer(dst, 0, &bytes);
            Ok(())
        });
        g.export_version(&lights, SCENE_ACCESS);
        lights
    }

    /// Poses the deforming draws: `frames` gives what poses their meshes now
    /// (`Scene::deform_frames`, in the local frame), `positions` their positions so posed (on the
    /// CPU: `Scene::posed_by`); their bounds and the scene's follow at once, the next frame's
    /// skin pass writes their vertices (and, for its motion channel, those the last recorded
    /// frame drew). Returns the bytes that frame will move.
    pub fn deform(
        &mut self,
        frames: &[(usize, crate::scene::deform::DeformFrame)],
        positions: &[(usize, crate::scene::deform::Posed)],
    ) -> u64 {
        let Some(now) = self.pose_bytes(frames) else { return 0 };
        for d in &self.deforming {
            let Some((_, p)) = positions.iter().find(|(mesh, _)| *mesh == d.mesh) else { continue };
            let mut box_ = Bounds::EMPTY;
            p.positions.iter().map(|q| q.as_vec3()).filter(|q| q.is_finite()).for_each(|q| box_.include(q));
            self.draws[d.draw].bounds = box_;
        }
        self.bound_draws();
        self.deformed.lock().unwrap_or_else(|e| e.into_inner()).pose(now)
    }

    /// The scene's bounds, after its draws' moved.
    fn bound_draws(&mut self) {
        let all = self.draws.iter().fold(Bounds::EMPTY, |b, d| b.union(&d.bounds));
        if !all.is_empty() {
            self.bounds = (all.min, all.max);
        }
    }

    /// Sets the deforming draws' poses as the previous frame drew them to `frames` (for a first
    /// frame, which has no previous one drawn): the next frame's motion starts there.
    pub fn deform_previous(&mut self, frames: &[(usize, crate::scene::deform::DeformFrame)]) {
        let Some(before) = self.pose_bytes(frames) else { return };
        self.deformed.lock().unwrap_or_else(|e| e.into_inner()).pose_previous(before);
    }

    /// The deforming draws' poses as the skin pass reads them, for `frames` (a draw it leaves out
    /// keeps its pose); `None` when it poses none.
    fn pose_bytes(&self, frames: &[(usize, crate::scene::deform::DeformFrame)]) -> Option<Vec<Arc<Vec<u8>>>> {
        let skin = self.skin.as_ref()?;
        let mut out = self.deformed.lock().unwrap_or_else(|e| e.into_inner()).posed.clone();
        let mut any = false;
        for (k, d) in self.deforming.iter().enumerate() {
            let Some((_, frame)) = frames.iter().find(|(mesh, _)| *mesh == d.mesh) else { continue };
            out[k] = Arc::new(skin.pose_bytes(k, frame));
            any = true;
        }
        any.then_some(out)
    }

    /// Poses the moving draws: `delta(mesh)` is the local-frame transform from mesh `mesh`'s
    /// rest pose to its pose now (`None`: at rest). Their bounds and the scene's follow at once;
    /// their instance rows are written by the next frame's first pass. Returns the bytes that
    /// frame will move.
    pub fn pose(&mut self, delta: impl Fn(usize) -> Option<glam::DMat4>) -> u64 {
        if self.moving.is_empty() {
            return 0;
        }
        let rows = self.moving_rows(&delta);
        for m in &self.moving {
            let d = delta(m.mesh).unwrap_or(glam::DMat4::IDENTITY);
            self.draws[m.draw].bounds = m.rest_bounds.transformed(&d.as_mat4());
        }
        self.bound_draws();
        self.rows.lock().unwrap_or_else(|e| e.into_inner()).pose(rows)
    }

    /// Sets where the moving draws were in the previous frame, as `pose`'s `delta` says (for a
    /// first frame, which has no previous one drawn): the next frame's motion vectors start there.
    pub fn pose_previous(&mut self, delta: impl Fn(usize) -> Option<glam::DMat4>) {
        if self.moving.is_empty() {
            return;
        }
        let rows = self.moving_rows(&delta);
        self.rows.lock().unwrap_or_else(|e| e.into_inner()).pose_previous(rows);
    }

    /// The moving draws' rows' bytes, each mesh moved by `delta`.
    fn moving_rows(&self, delta: &impl Fn(usize) -> Option<glam::DMat4>) -> Vec<Arc<Vec<u8>>> {
        let at = |m: &MovingDraw| {
            let rows = InstanceRows::of(&(delta(m.mesh).unwrap_or(glam::DMat4::IDENTITY) * m.base));
            Arc::new(bytemuck::bytes_of(&rows).to_vec())
        };
        self.moving.iter().map(at).collect()
    }

    /// A frame that imported the scene was recorded: the updates it wrote are done, and the
    /// rows and vertices it drew are the next frame's previous ones (written by the next frame
    /// where they differ from what the device holds).
    pub fn recorded(&self) {
        self.rows.lock().unwrap_or_else(|e| e.into_inner()).recorded();
        self.deformed.lock().unwrap_or_else(|e| e.into_inner()).recorded();
        if let Some(skin) = &self.skin {
            skin.recorded();
        }
        self.moved_lights.lock().unwrap_or_else(|e| e.into_inner()).take();
        self.bvh.recorded();
    }

    /// Imports the vertex buffer into `g`; where the scene was posed since the last recorded
    /// frame, first passes write the moving draws' instance rows and pose the deforming draws'
    /// vertices (the skin pass), now and as the previous frame drew them (after every read of
    /// the old ones that earlier frames submitted).
    pub fn import_vertices<'a>(
        &'a self,
        g: &mut crate::graph::RenderGraph<'a>,
        pipelines: crate::vk::PipelineSource<'a>,
    ) -> GpuResult<crate::graph::Handle<crate::graph::BufferKind>> {
        let mut vertices = g.import_buffer("vertices", &self.vertices, SCENE_ACCESS);
        if let Some(skin) = &self.skin {
            let deformed = self.deformed.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(writes) = deformed.pending.clone() {
                let mut poses = g.import_buffer("skin poses", &skin.poses, SCENE_ACCESS);
                deformed.write_pass(g, &mut poses, "skin poses");
                skin.add(g, pipelines, &poses, &mut vertices, &writes)?;
            }
        }
        self.rows.lock().unwrap_or_else(|e| e.into_inner()).write_pass(g, &mut vertices, "instance rows");
        Ok(vertices)
    }

    /// Bytes of the scene's buffers on the device.
    pub fn bytes(&self) -> u64 {
        [&self.vertices, &self.indices, &self.lights, &self.bvh.nodes.buffer, &self.bvh.triangles.buffer]
            .iter()
            .map(|b| b.size)
            .sum::<u64>()
            + self.bvh.masks.as_ref().map_or(0, |m| m.buffer.size)
            + self.skin.as_ref().map_or(0, |s| s.bytes())
    }

    /// A world-space camera in the scene-local frame (subtracted in f64).
    pub fn to_local(&self, cam: &Camera) -> Camera {
        Camera { eye: cam.eye - self.origin, target: cam.target - self.origin, ..*cam }
    }
}
