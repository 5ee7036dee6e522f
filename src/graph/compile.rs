//! Compiling a declared graph, in named phases that need no device: cull passes that reach no
//! exported output, find lifetimes, derive usage flags, assign transient storage (reusing a slot
//! of the same description once its last user is done), and plan one batched barrier per pass.
//! The result prints as a plan that tests can check.

use std::collections::BTreeMap;
use std::fmt;

use ash::vk;

use super::layers::{Layers, PerLayer};
use super::{Access, RenderGraph, ResourceDesc};

/// One memory/execution dependency (plus layout transition for images) before a pass.
#[derive(Clone, Debug, PartialEq)]
pub struct Barrier {
    pub resource: usize,
    /// The layers it covers (buffers: their one layer).
    pub layers: Layers,
    /// The accesses this barrier waits for (the last write, or the reads since it).
    pub after: Vec<Access>,
    pub before: Vec<Access>,
    pub src_stage: vk::PipelineStageFlags2,
    pub src_access: vk::AccessFlags2,
    pub dst_stage: vk::PipelineStageFlags2,
    pub dst_access: vk::AccessFlags2,
    /// `None` for buffers.
    pub layouts: Option<(vk::ImageLayout, vk::ImageLayout)>,
}

#[derive(Clone, Debug)]
pub struct CompiledPass {
    pub name: &'static str,
    /// What the pass says of its work (draw counts, say), printed after its name.
    pub detail: Option<String>,
    pub culled: bool,
    pub barriers: Vec<Barrier>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    /// No live pass uses it.
    Unused,
    Imported,
    /// Index into the transient slots; resources with disjoint lifetimes share a slot.
    Transient(usize),
}

#[derive(Clone, Debug)]
pub struct ResourcePlan {
    pub name: &'static str,
    pub desc: ResourceDesc,
    pub storage: Storage,
    pub image_usage: vk::ImageUsageFlags,
    pub buffer_usage: vk::BufferUsageFlags,
    /// First and last live pass using it.
    pub lifetime: Option<(usize, usize)>,
}

/// A transient slot: what the cache must provide.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SlotKey {
    pub desc: ResourceDescKey,
    pub image_usage: u32,
    pub buffer_usage: u32,
}

/// `ResourceDesc` flattened to something orderable, for cache keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ResourceDescKey {
    Image { format: i32, width: u32, height: u32, layers: u32, array: bool },
    Buffer { size: u64 },
}

#[derive(Clone, Debug)]
pub struct CompiledGraph {
    pub passes: Vec<CompiledPass>,
    pub resources: Vec<ResourcePlan>,
    pub slots: Vec<SlotKey>,
    /// Barriers that bring exported resources to their export access, after the last pass.
    pub export_barriers: Vec<Barrier>,
}

impl CompiledGraph {
    pub fn compile(graph: &RenderGraph<'_>) -> CompiledGraph {
        let live = cull(graph);
        let mut resources = derive_usage_and_lifetimes(graph, &live);
        let slots = assign_transients(&mut resources);
        let (barriers, export_barriers) = plan_barriers(graph, &live, &resources);
        let passes = graph
            .passes
            .iter()
            .zip(barriers)
            .zip(&live)
            .map(|((p, barriers), &live)| CompiledPass {
                name: p.name,
                detail: p.detail.clone(),
                culled: !live,
                barriers,
            })
            .collect();
        CompiledGraph { passes, resources, slots, export_barriers }
    }

    pub fn live_pass_names(&self) -> Vec<&'static str> {
        self.passes.iter().filter(|p| !p.culled).map(|p| p.name).collect()
    }

    pub fn barriers_before(&self, pass: &str) -> &[Barrier] {
        self.passes.iter().find(|p| p.name == pass).map(|p| p.barriers.as_slice()).unwrap_or(&[])
    }
}

/// Phase 1: a pass lives if something it writes is read by a live pass or exported. Each read
/// depends on the last writer of every layer it reads (a later write of other layers does not
/// hide an earlier writer), and a pass's reads see what was there before its own writes.
fn cull(graph: &RenderGraph<'_>) -> Vec<bool> {
    let layer_count = |r: usize| graph.all_layers(r).count;
    let mut last_writer: Vec<PerLayer<Option<usize>>> =
        (0..graph.resources.len()).map(|r| PerLayer::new(layer_count(r), None)).collect();
    let writers_of = |r: usize, layers: Layers, last_writer: &[PerLayer<Option<usize>>]| -> Vec<usize> {
        last_writer[r].overlapping(layers).filter_map(|(_, w)| *w).collect()
    };
    let mut depends_on: Vec<Vec<usize>> = Vec::with_capacity(graph.passes.len());
    // Each export keeps the writers of the version it exported (see `ExportDecl::after`).
    let mut pending: Vec<usize> = Vec::new();
    let exported_after = |i: usize, last_writer: &[PerLayer<Option<usize>>], pending: &mut Vec<usize>| {
        for e in graph.exports.iter().filter(|e| e.after == i) {
            pending.extend(writers_of(e.resource, Layers::all(layer_count(e.resource)), last_writer));
        }
    };
    for (i, pass) in graph.passes.iter().enumerate() {
        exported_after(i, &last_writer, &mut pending);
        let mut deps = Vec::new();
        // Reads, and read-modify-writes (atomics), depend on what was written before.
        for a in pass.accesses.iter().filter(|a| !a.access.is_write() || a.access.reads_previous()) {
            deps.extend(writers_of(a.resource, a.layers, &last_writer));
        }
        for a in pass.accesses.iter().filter(|a| a.access.is_write()) {
            for (_, w) in last_writer[a.resource].runs_in(a.layers) {
                *w = Some(i);
            }
            last_writer[a.resource].merge();
        }
        depends_on.push(deps);
    }
    exported_after(graph.passes.len(), &last_writer, &mut pending);
    let mut live = vec![false; graph.passes.len()];
    while let Some(p) = pending.pop() {
        if !live[p] {
            live[p] = true;
            pending.extend(&depends_on[p]);
        }
    }
    live
}

/// Phases 2 and 3: lifetimes and usage flags from the live accesses (and exports).
fn derive_usage_and_lifetimes(graph: &RenderGraph<'_>, live: &[bool]) -> Vec<ResourcePlan> {
    let mut plans: Vec<ResourcePlan> = graph
        .resources
        .iter()
        .map(|r| ResourcePlan {
            name: r.name,
            desc: r.desc,
            storage: if r.imported.is_some() { Storage::Imported } else { Storage::Unused },
            image_usage: vk::ImageUsageFlags::empty(),
            buffer_usage: vk::BufferUsageFlags::empty(),
            lifetime: None,
        })
        .collect();
    let add = |plan: &mut ResourcePlan, access: Access, at: usize| {
        let info = access.info();
        plan.image_usage |= info.image_usage;
        plan.buffer_usage |= info.buffer_usage;
        plan.lifetime = Some(match plan.lifetime {
            None => (at, at),
            Some((first, _)) => (first, at),
        });
    };
    for (i, pass) in graph.passes.iter().enumerate() {
        if live[i] {
            for a in &pass.accesses {
                add(&mut plans[a.resource], a.access, i);
            }
        }
    }
    for e in &graph.exports {
        add(&mut plans[e.resource], e.access, graph.passes.len());
    }
    // An imported resource must have been created for every use the graph makes of it.
    for (plan, decl) in plans.iter().zip(&graph.resources) {
        if decl.imported.is_none() {
            continue;
        }
        let (needed, created) = match plan.desc {
            ResourceDesc::Image(_) => (plan.image_usage.as_raw(), decl.created_usage),
            ResourceDesc::Buffer(_) => (plan.buffer_usage.as_raw(), decl.created_usage),
        };
        let missing = needed & !created;
        if missing != 0 {
            let what = match plan.desc {
                ResourceDesc::Image(_) => format!("{:?}", vk::ImageUsageFlags::from_raw(missing)),
                ResourceDesc::Buffer(_) => format!("{:?}", vk::BufferUsageFlags::from_raw(missing)),
            };
            panic!("imported resource {:?} is used as {what}, which it was not created with", plan.name);
        }
    }
    plans
}

/// Phase 4: transient resources share a slot when description and usage match and lifetimes
/// do not overlap.
fn assign_transients(plans: &mut [ResourcePlan]) -> Vec<SlotKey> {
    let mut order: Vec<usize> =
        (0..plans.len()).filter(|&i| plans[i].storage != Storage::Imported && plans[i].lifetime.is_some()).collect();
    order.sort_by_key(|&i| plans[i].lifetime.map(|l| l.0));
    let mut slots: Vec<SlotKey> = Vec::new();
    let mut busy_until: Vec<usize> = Vec::new();
    for i in order {
        let (first, last) = plans[i].lifetime.expect("filtered");
        let key = slot_key(&plans[i]);
        let free = (0..slots.len()).find(|&s| slots[s] == key && busy_until[s] < first);
        let slot = free.unwrap_or_else(|| {
            slots.push(key);
            busy_until.push(0);
            slots.len() - 1
        });
        busy_until[slot] = last;
        plans[i].storage = Storage::Transient(slot);
    }
    slots
}

fn slot_key(plan: &ResourcePlan) -> SlotKey {
    let desc = match plan.desc {
        ResourceDesc::Image(d) => ResourceDescKey::Image {
            format: d.format.as_raw(),
            width: d.width,
            height: d.height,
            layers: d.layers,
            array: d.array,
        },
        ResourceDesc::Buffer(b) => ResourceDescKey::Buffer { size: b.size },
    };
    SlotKey { desc, image_usage: plan.image_usage.as_raw(), buffer_usage: plan.buffer_usage.as_raw() }
}

/// Where a resource's synchronisation state lives: its slot (transients alias) or itself.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Location {
    Slot(usize),
    Imported(usize),
}

#[derive(Clone, Default, PartialEq)]
struct SyncState {
    layout: Option<vk::ImageLayout>,
    write: Option<Access>,
    /// Reads since the last write, and the stage/access scopes they were made visible to.
    reads: Vec<Access>,
    visible_stage: vk::PipelineStageFlags2,
    visible_access: vk::AccessFlags2,
    /// The resource currently occupying the location; a new occupant starts from UNDEFINED.
    occupant: Option<usize>,
}

/// Phase 5: one batched barrier per pass, from each location's state to the pass's accesses.
/// State is kept per layer range: a pass's barrier covers only the layers it touches, and ranges
/// in the same state (the layers one pass wrote, say) share one barrier.
fn plan_barriers(graph: &RenderGraph<'_>, live: &[bool], plans: &[ResourcePlan]) -> (Vec<Vec<Barrier>>, Vec<Barrier>) {
    let layer_count = |r: usize| graph.all_layers(r).count;
    let mut states: BTreeMap<Location, PerLayer<SyncState>> = BTreeMap::new();
    for (i, r) in graph.resources.iter().enumerate() {
        if let Some((_, access)) = r.imported {
            let mut st = SyncState { occupant: Some(i), ..Default::default() };
            if matches!(r.desc, ResourceDesc::Image(_)) {
                st.layout = Some(access.info().layout);
            }
            if access.is_write() {
                st.write = Some(access);
            } else if access != Access::Nothing {
                st.reads.push(access);
            }
            states.insert(Location::Imported(i), PerLayer::new(layer_count(i), st));
        }
    }
    let location = |id: usize| match plans[id].storage {
        Storage::Transient(s) => Some(Location::Slot(s)),
        Storage::Imported => Some(Location::Imported(id)),
        Storage::Unused => None,
    };
    let first_writes = first_writes(graph, live);
    let mut per_pass = Vec::with_capacity(graph.passes.len());
    for (i, pass) in graph.passes.iter().enumerate() {
        let mut barriers = Vec::new();
        if live[i] {
            // Group this pass's accesses by resource, in declaration order.
            let mut groups: Vec<(usize, Vec<(Access, Layers)>)> = Vec::new();
            for a in &pass.accesses {
                match groups.iter_mut().find(|g| g.0 == a.resource) {
                    Some(g) => g.1.push((a.access, a.layers)),
                    None => groups.push((a.resource, vec![(a.access, a.layers)])),
                }
            }
            for (resource, mut accesses) in groups {
                let loc = location(resource).expect("live access has storage");
                let st =
                    states.entry(loc).or_insert_with(|| PerLayer::new(layer_count(resource), SyncState::default()));
                let is_image = matches!(graph.resources[resource].desc, ResourceDesc::Image(_));
                let early = early_transitions(st, resource, &accesses, &first_writes[resource]);
                let first_early = accesses.len();
                accesses.extend(early);
                for b in transition_layers(st, resource, &accesses, first_early, is_image, pass.name) {
                    push_merged(&mut barriers, b);
                }
            }
        }
        per_pass.push(barriers);
    }
    let mut exports = Vec::new();
    for e in &graph.exports {
        let Some(loc) = location(e.resource) else { continue };
        let n = layer_count(e.resource);
        let st = states.entry(loc).or_insert_with(|| PerLayer::new(n, SyncState::default()));
        let is_image = matches!(graph.resources[e.resource].desc, ResourceDesc::Image(_));
        for b in transition_layers(st, e.resource, &[(e.access, Layers::all(n))], 1, is_image, "export") {
            push_merged(&mut exports, b);
        }
    }
    (per_pass, exports)
}

/// For each image, the access of the first live pass to touch each layer, when that pass only
/// writes the layer (its old contents are not wanted): `None` where it reads it, or nothing does.
fn first_writes(graph: &RenderGraph<'_>, live: &[bool]) -> Vec<PerLayer<Option<Option<Access>>>> {
    let mut first: Vec<PerLayer<Option<Option<Access>>>> = graph
        .resources
        .iter()
        .map(|r| match r.desc {
            // Imported images keep what they hold: only transient ones start undefined.
            ResourceDesc::Image(d) => PerLayer::new(d.layers, r.imported.is_some().then_some(None)),
            ResourceDesc::Buffer(_) => PerLayer::new(1, Some(None)),
        })
        .collect();
    for (pass, _) in graph.passes.iter().zip(live).filter(|(_, &l)| l) {
        for a in &pass.accesses {
            let reads_it = |run: Layers| {
                pass.accesses.iter().any(|b| b.resource == a.resource && !b.access.is_write() && b.layers.overlaps(run))
            };
            for (run, f) in first[a.resource].runs_in(a.layers) {
                if f.is_none() {
                    *f = Some((a.access.is_write() && !reads_it(*run)).then_some(a.access));
                }
            }
        }
    }
    first
}

/// The layers a pass may bring from UNDEFINED to their first layout now, beside the layers it
/// writes: layers this resource has not touched yet whose first use is a write in the layout
/// this pass writes in (transient images only: an import holds what it holds). Done in this
/// pass's barrier, the later writers of those layers need no barrier of their own (a barrier's
/// second scope holds every later command), so techniques writing disjoint layers run back to
/// back.
fn early_transitions(
    st: &mut PerLayer<SyncState>,
    resource: usize,
    accesses: &[(Access, Layers)],
    first: &PerLayer<Option<Option<Access>>>,
) -> Vec<(Access, Layers)> {
    let Some(&(write, _)) = accesses.first() else { return Vec::new() };
    let layout = write.info().layout;
    if accesses.iter().any(|(a, _)| !a.is_write() || a.info().layout != layout) {
        return Vec::new();
    }
    let mine = |run: Layers| accesses.iter().any(|(_, l)| l.overlaps(run));
    let mut early = Vec::new();
    for (run, f) in first.overlapping(Layers::all(u32::MAX)) {
        let Some(Some(later)) = *f else { continue };
        if later.info().layout != layout || mine(*run) {
            continue;
        }
        // Another occupant of the slot is done with it (lifetimes do not overlap); the barrier
        // waits for its last use as it would before the first write.
        if st.overlapping(*run).all(|(_, s)| s.occupant != Some(resource)) {
            early.push((later, *run));
        }
    }
    early
}

/// The barriers that make `accesses` (each on its layers) safe, one per run of layers in one
/// state, and the new state of each run. Accesses from `early` on are early transitions (see
/// `early_transitions`): their layers end in the new layout with nothing written yet.
fn transition_layers(
    st: &mut PerLayer<SyncState>,
    resource: usize,
    accesses: &[(Access, Layers)],
    early: usize,
    is_image: bool,
    pass: &str,
) -> Vec<Barrier> {
    for &(_, layers) in accesses {
        let _ = st.runs_in(layers);
    }
    let first = accesses.iter().map(|a| a.1.first).min().expect("a group has accesses");
    let end = accesses.iter().map(|a| a.1.end()).max().expect("a group has accesses");
    let mut barriers = Vec::new();
    for (run, state) in st.runs_in(Layers { first, count: end - first }) {
        let here: Vec<Access> = accesses.iter().filter(|(_, l)| l.contains(*run)).map(|(a, _)| *a).collect();
        if !here.is_empty() {
            if let Some(b) = transition(state, resource, *run, &here, is_image, pass) {
                push_merged(&mut barriers, b);
            }
            let is_early = accesses[early..].iter().any(|(_, l)| l.contains(*run));
            if is_early {
                // Only the layout moved: the write itself is still to come.
                *state = SyncState { layout: state.layout, occupant: state.occupant, ..Default::default() };
            }
        }
    }
    st.merge();
    barriers
}

/// Appends `b`, or widens the last barrier when `b` is the same dependency on the next layers.
fn push_merged(barriers: &mut Vec<Barrier>, b: Barrier) {
    if let Some(last) = barriers.last_mut() {
        let same = Barrier { layers: last.layers, ..b.clone() };
        if *last == same && last.layers.end() == b.layers.first {
            last.layers.count += b.layers.count;
            return;
        }
    }
    barriers.push(b);
}

/// The barrier (if any) that makes `accesses` safe given the location's state, and the new state.
fn transition(
    st: &mut SyncState,
    resource: usize,
    layers: Layers,
    accesses: &[Access],
    is_image: bool,
    pass: &str,
) -> Option<Barrier> {
    let mut dst_stage = vk::PipelineStageFlags2::NONE;
    let mut dst_access = vk::AccessFlags2::NONE;
    let mut layout = None;
    let writes = accesses.iter().any(|a| a.is_write());
    for a in accesses {
        let info = a.info();
        dst_stage |= info.stage;
        dst_access |= info.access;
        if is_image {
            if let Some(l) = layout {
                assert_eq!(l, info.layout, "pass {pass}: one image used in two layouts at once");
            }
            layout = Some(info.layout);
        }
    }
    let new_occupant = st.occupant != Some(resource);
    let old_layout =
        if new_occupant { vk::ImageLayout::UNDEFINED } else { st.layout.unwrap_or(vk::ImageLayout::UNDEFINED) };
    let layout_change = is_image && layout != Some(old_layout);
    let read_stages = st.reads.iter().fold(vk::PipelineStageFlags2::NONE, |s, a| s | a.info().stage);
    let write_info = st.write.map(|w| w.info());
    let covered = st.visible_stage.contains(dst_stage) && st.visible_access.contains(dst_access);
    let needed = layout_change
        || (writes && (st.write.is_some() || !st.reads.is_empty()))
        || (!writes && st.write.is_some() && !covered);

    let barrier = needed.then(|| {
        // Reads since the last write each waited for it behind a barrier, so that write is
        // already available: a later write or transition only has to wait for those reads.
        let (after, src_stage, src_access) = if (writes || layout_change) && !st.reads.is_empty() {
            (st.reads.clone(), read_stages, vk::AccessFlags2::NONE)
        } else {
            (
                st.write.into_iter().collect::<Vec<_>>(),
                write_info.map_or(vk::PipelineStageFlags2::NONE, |w| w.stage),
                write_info.map_or(vk::AccessFlags2::NONE, |w| w.access),
            )
        };
        Barrier {
            resource,
            layers,
            after,
            before: accesses.to_vec(),
            src_stage,
            src_access,
            dst_stage,
            dst_access,
            layouts: is_image.then(|| (old_layout, layout.expect("image access has a layout"))),
        }
    });

    st.occupant = Some(resource);
    st.layout = layout.or(st.layout);
    if writes {
        st.write = accesses.iter().copied().find(|a| a.is_write());
        st.reads.clear();
        st.visible_stage = vk::PipelineStageFlags2::NONE;
        st.visible_access = vk::AccessFlags2::NONE;
    } else {
        if barrier.as_ref().is_some_and(|b| b.layouts.is_some_and(|(o, n)| o != n)) {
            // A layout transition is itself a write; later readers chain on this barrier.
            st.visible_stage = vk::PipelineStageFlags2::NONE;
            st.visible_access = vk::AccessFlags2::NONE;
        }
        st.reads.extend(accesses.iter().copied());
        st.visible_stage |= dst_stage;
        st.visible_access |= dst_access;
    }
    barrier
}

impl fmt::Display for CompiledGraph {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "frame graph plan:")?;
        for (i, r) in self.resources.iter().enumerate() {
            let what = match r.desc {
                ResourceDesc::Image(d) => {
                    if d.array {
                        format!(
                            "image {:?} {}x{}x{} layers usage {:?}",
                            d.format, d.width, d.height, d.layers, r.image_usage
                        )
                    } else {
                        format!("image {:?} {}x{} usage {:?}", d.format, d.width, d.height, r.image_usage)
                    }
                }
                ResourceDesc::Buffer(b) => format!("buffer {} B usage {:?}", b.size, r.buffer_usage),
            };
            let storage = match r.storage {
                Storage::Unused => "unused".to_string(),
                Storage::Imported => "imported".to_string(),
                Storage::Transient(s) => format!("transient slot {s}"),
            };
            let life = r.lifetime.map_or(String::new(), |(a, b)| format!(", passes {a}..={b}"));
            writeln!(f, "  resource {i} {}: {what}, {storage}{life}", r.name)?;
        }
        for (i, p) in self.passes.iter().enumerate() {
            if p.culled {
                writeln!(f, "  pass {i} {}: culled", p.name)?;
                continue;
            }
            match &p.detail {
                Some(d) => writeln!(f, "  pass {i} {} ({d})", p.name)?,
                None => writeln!(f, "  pass {i} {}", p.name)?,
            }
            for b in &p.barriers {
                writeln!(f, "    {}", self.describe_barrier(b))?;
            }
        }
        for b in &self.export_barriers {
            writeln!(f, "  export: {}", self.describe_barrier(b))?;
        }
        Ok(())
    }
}

impl CompiledGraph {
    pub fn describe_barrier(&self, b: &Barrier) -> String {
        let layouts = b.layouts.map_or(String::new(), |(o, n)| format!(" [{o:?} -> {n:?}]"));
        let r = &self.resources[b.resource];
        let part = match r.desc {
            ResourceDesc::Image(d) if b.layers != Layers::all(d.layers) => format!(" {}", b.layers),
            _ => String::new(),
        };
        format!("barrier {}{part}: {:?} -> {:?}{layouts}", r.name, b.after, b.before)
    }
}
