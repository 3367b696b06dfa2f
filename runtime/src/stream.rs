//! Streaming under a byte budget: a [`StreamingVolume`] keeps a *window* of consecutive frames
//! on the GPU — the bricks they use in a fixed pool of slots sized from the budget, and the
//! window's topology (every level of detail of its frames, every channel) — and moving the
//! window writes only the bricks it newly uses. It is the one uploader: [`GpuVolume::upload`]
//! is a pool holding every brick with the whole asset as its window
//! ([`StreamingVolume::upload_whole`]), and [`GpuVolume::upload_set`] one pool holding several
//! assets, each with its whole flip-book as its window and its own topology section.
//!
//! # How the unchanged `volume.wgsl` reads a streamed pool
//! The shader reads brick `b` at a place derived from `b` alone (`vdb_brick_voxel`: its format
//! group from `groups[g].first`, then a buffer offset or a texture tile of `b − first + base`),
//! and reads `brick_ranges` / `brick_quant` at `b`. So the streamed volume numbers bricks by
//! *slot*: every format gets a slot range `[first_f, first_f + cap_f)` (in
//! [`PayloadFormat::ORDER`], as an asset groups its bricks), the pool is planned exactly as
//! [`GpuVolume::upload`] plans an asset with `cap_f` bricks per format, and each window gets
//! its own topology — the window's frames' roots, the L2 nodes they use (renumbered in first
//! use order), their refs with every brick index replaced by the brick's slot, all tiles, and
//! the ranges and quantization ranges per slot. The topology is small and rewritten whole per
//! window (a new buffer and bind group); the pool's buffers and textures never change and only
//! the slots of newly used bricks are written (`Queue::write_buffer` / `write_texture`: nothing
//! here waits on the GPU).
//!
//! # Budget rule
//! `budget` bytes cover the pool (each slot: the brick as the layout stores it, plus 16 bytes of
//! ranges in the topology) and a topology reserve (the largest topology of a window of the
//! initial length, plus the `VolumeInfo` uniform). Every format first gets as many slots as the
//! largest single frame uses of it; what is left is shared between the formats in proportion to
//! their bytes in the whole asset, capped at the format's brick count. A budget below "one frame
//! per format + the reserve" is refused ([`RuntimeError::Budget`], naming both numbers); so is a
//! window that needs more slots of a format, or more topology bytes, than the budget left it.
//!
//! Frames inside the streamed [`GpuVolume`] are *window-local* (`frame − first`,
//! [`StreamingVolume::local_frame`]); a [`crate::Renderer`] or [`crate::VolumeDrawer`] keeps the
//! volume's bind group and per-frame boxes, so call its `rebind(stream.volume())` after each
//! window change (the pipelines stay: every window has the pool's layout). Submit the work recorded against the old
//! window before moving it: the slot writes take effect at the next submission.

use std::collections::{BTreeSet, HashMap, HashSet};
use std::ops::RangeInclusive;
use std::sync::Arc;

use super::*;
use vdbcook_asset::{EMPTY, TILE_BIT};

/// What one window change did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WindowStats {
    /// The window now resident (first frame, last frame).
    pub window: (usize, usize),
    /// Bricks written into the pool (those the window uses and the previous one did not).
    pub uploaded_bricks: usize,
    /// Bytes of those bricks as the pool stores them.
    pub uploaded_bytes: u64,
    /// Bytes of the window's topology and info uniform (written whole per window).
    pub topology_bytes: u64,
    /// Bricks resident now (exactly those the window uses).
    pub resident_bricks: usize,
    /// Bricks the previous window used and this one does not (their slots are free again).
    pub evicted: usize,
}

/// A window of an asset's frames on the GPU under a byte budget (see the module docs).
pub struct StreamingVolume {
    /// The asset streamed (`None` for the whole-asset upload, which borrows it once).
    asset: Option<Arc<Asset>>,
    budget: u64,
    /// Bytes allocated for the pool (slots and their 16 bytes of ranges).
    pool_bytes: u64,
    plan_textures: [Option<Plan>; 3],
    buffers: BufferLayout,
    layout: Layout,
    /// Slots per format (in `PayloadFormat::ORDER`) and the first slot number of each.
    caps: [u32; FORMATS],
    firsts: [u32; FORMATS],
    groups: [GroupInfo; GROUPS],
    /// Bytes one slot of each format takes in the pool.
    slot_bytes: [u64; FORMATS],
    payload_buffers: Vec<wgpu::Buffer>,
    buffer_bytes: u64,
    /// Of `buffer_bytes`, the packed bricks' words.
    packed_bytes: u64,
    textures: [Option<wgpu::Texture>; 3],
    views: [Option<wgpu::TextureView>; 3],
    dummy3: wgpu::TextureView,
    dummy_array: wgpu::TextureView,
    bind_group_layout: wgpu::BindGroupLayout,
    /// Free slots (within the format) per format.
    free: [BTreeSet<u32>; FORMATS],
    /// Resident (asset, brick) → slot number.
    slot_of: HashMap<(u32, u32), u32>,
    /// Slot number → resident (asset, brick) (`FREE`: free).
    slot_brick: Vec<(u32, u32)>,
    /// Per asset of the pool: what is known of it.
    residents: Vec<Resident>,
    stats: WindowStats,
    volume: Option<GpuVolume>,
}

type Box3 = Option<([f64; 3], [f64; 3])>;

/// A free slot in `slot_brick`.
const FREE: (u32, u32) = (u32::MAX, u32::MAX);

/// One asset of the pool: what is known of it, filled in as its bricks and frames are loaded.
struct Resident {
    /// Per brick: the box of its non-background voxels, once known (computed when the brick is
    /// first written).
    brick_boxes: Vec<Option<([u8; 3], [u8; 3])>>,
    brick_box_known: Vec<bool>,
    /// Per frame, once computed: stored box and content box.
    frame_boxes: Vec<Option<FrameBoxes>>,
    /// Channels 1..: background and per-frame boxes above it (all frames).
    channel_boxes: Vec<ChannelBoxes>,
}

impl Resident {
    fn of(asset: &Asset) -> Resident {
        Resident {
            brick_boxes: vec![None; asset.brick_count()],
            brick_box_known: vec![false; asset.brick_count()],
            frame_boxes: vec![None; asset.frame_count()],
            channel_boxes: ChannelBoxes::of(asset),
        }
    }
}
#[derive(Clone, Copy)]
struct FrameBoxes {
    stored: Box3,
    content: Box3,
}

/// The L2 nodes of a window (first use order) and its bricks (ascending).
struct WindowUse {
    nodes: Vec<u32>,
    bricks: Vec<u32>,
    refs: usize,
}

fn window_use(asset: &Asset, first: usize, last: usize) -> WindowUse {
    let nch = asset.channel_count();
    let mut seen = HashSet::new();
    let mut nodes = Vec::new();
    // Every level of detail of the window's frames (level 0 first), as the topology lays them.
    for level in 0..asset.level_count() {
        for f in first..=last {
            for &e in asset.frame_roots(asset.lod_set(f, level)) {
                if e != EMPTY && e & TILE_BIT == 0 && seen.insert(e) {
                    nodes.push(e);
                }
            }
        }
    }
    let mut bricks = BTreeSet::new();
    let mut refs = 0;
    for &n in &nodes {
        let (lo, count) = node_refs(asset, n);
        refs += count * nch;
        for &r in &asset.l3_refs[lo * nch..(lo + count) * nch] {
            if r != EMPTY && r & TILE_BIT == 0 {
                bricks.insert(r);
            }
        }
    }
    WindowUse {
        nodes,
        bricks: bricks.into_iter().collect(),
        refs,
    }
}

/// First leaf slot and slot count of L2 node `n` (its refs: `channels` per slot from
/// `first · channels`).
fn node_refs(asset: &Asset, n: u32) -> (usize, usize) {
    let count = asset
        .l2_mask(n as usize)
        .iter()
        .map(|w| w.count_ones() as usize)
        .sum();
    (asset.l2_base[n as usize] as usize, count)
}

/// Topology words of a window, without the per-slot ranges: the roots of every level, the
/// nodes (masks, base, prefixes, a range per channel), the refs, the tiles, the channels'
/// backgrounds.
fn topology_words(asset: &Asset, frames: usize, u: &WindowUse) -> u64 {
    let nch = asset.channel_count();
    (asset.level_count() * frames * asset.root_len()
        + u.nodes.len() * (2 * L2_WORDS + 1 + L2_WORDS + 2 * nch)
        + u.refs) as u64
        + asset.tiles.len() as u64
        + if nch > 1 { nch as u64 } else { 0 }
}

/// Bytes of a slot's ranges (`brick_ranges` and `brick_quant` pairs) in the topology.
const SLOT_RANGE_BYTES: u64 = 16;
const INFO_BYTES: u64 = std::mem::size_of::<VolumeInfo>() as u64;

/// Bytes one brick of `format` takes in the pool under `layout` (`buffered_f16`: the buffered
/// bricks are all f16).
fn nominal_slot_bytes(layout: Layout, format: PayloadFormat, buffered_f16: bool) -> u64 {
    let textured = layout != Layout::Buffers && format.is_quantized();
    match (textured, format, layout.native_bc()) {
        (true, PayloadFormat::Bc7, true) => 128,
        (true, PayloadFormat::Bc4, true) => 256,
        (true, f, _) if f.packed_bits().is_some() => f.bytes_per_brick() as u64,
        (true, _, _) => 512,
        (false, _, _) if buffered_f16 => 1024,
        _ => 2048,
    }
}

impl StreamingVolume {
    /// Plans a pool for `budget` bytes and uploads the window `window` (first and last frame).
    /// `options.force` pins the layout as for [`GpuVolume::upload_with`].
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        asset: Arc<Asset>,
        budget: u64,
        window: RangeInclusive<usize>,
        options: UploadOptions,
    ) -> Result<StreamingVolume> {
        let (first, last) = check_window(&asset, &window)?;
        let max_binding = check_limits(device)?;
        let counts = asset.header.brick_counts;
        let frames = asset.frame_count();
        // Per format, the most bricks one frame uses.
        let mut frame_need = [0u32; FORMATS];
        for f in 0..frames {
            let mut n = [0u32; FORMATS];
            for b in window_use(&asset, f, f).bricks {
                n[asset.brick_format(b).0.rank()] += 1;
            }
            for i in 0..FORMATS {
                frame_need[i] = frame_need[i].max(n[i]);
            }
        }
        // Per format, the most bricks a window of this length uses, and the topology reserve:
        // the largest topology of such a window.
        let len = last - first + 1;
        let mut window_need = [0u32; FORMATS];
        let mut reserve_words = 0;
        for s in 0..=frames - len {
            let u = window_use(&asset, s, s + len - 1);
            let mut n = [0u32; FORMATS];
            for &b in &u.bricks {
                n[asset.brick_format(b).0.rank()] += 1;
            }
            for i in 0..FORMATS {
                window_need[i] = window_need[i].max(n[i]);
            }
            reserve_words = reserve_words.max(topology_words(&asset, len, &u));
        }
        let reserve = reserve_words * 4 + INFO_BYTES;

        let order = match options.force {
            Some(l) => vec![l],
            None => Layout::automatic_order(device).to_vec(),
        };
        let mut refusals = Vec::new();
        let mut chosen = None;
        for layout in order {
            match plan_pool(
                device,
                &counts,
                [frame_need, window_need],
                len,
                layout,
                max_binding,
                budget,
                reserve,
            ) {
                Ok(p) => {
                    chosen = Some(p);
                    break;
                }
                Err(PoolError::Budget(e)) => return Err(RuntimeError::Budget(e)),
                Err(PoolError::Layout(e)) => refusals.push(format!("{}: {e}", layout.name())),
            }
        }
        let Some(pool) = chosen else {
            return Err(RuntimeError::Limits(format!(
                "no payload layout fits: {}",
                refusals.join("; ")
            )));
        };

        let caps = pool.caps;
        let mut s = Self::build(device, &[&asset], caps, &pool.plan, budget)?;
        s.load(device, queue, &[(&asset, first, last)])?;
        s.asset = Some(asset);
        log::info!(
            "vdbcook: streaming pool for a budget of {budget} bytes: slots per format {caps:?} \
             ({} bytes), {}",
            s.pool_bytes,
            s.volume().describe()
        );
        Ok(s)
    }

    /// The pool of `caps` slots per format laid out by `plan` (its buffers and textures empty),
    /// under `budget` bytes, its window not loaded yet (`load` loads it).
    fn build(
        device: &wgpu::Device,
        assets: &[&Asset],
        caps: [u32; FORMATS],
        plan: &FullPlan,
        budget: u64,
    ) -> Result<StreamingVolume> {
        let mut firsts = [0u32; FORMATS];
        for i in 1..FORMATS {
            firsts[i] = firsts[i - 1] + caps[i - 1];
        }
        // Group slots: BC7, BC4, unorm8 (textures or buffers), the floats (buffers), the packed
        // widths (their own words after the buffered bricks, or buffers under `Layout::Buffers`).
        let mut groups = [GroupInfo::default(); GROUPS];
        let keep_packed = plan.layout != Layout::Buffers;
        let mut buffered_before = 0u32;
        for (g, grp) in groups.iter_mut().enumerate() {
            let f0 = group_first_format(g);
            grp.first = firsts[f0];
            let n = if g == 3 { caps[3] + caps[4] } else { caps[f0] };
            match plan.textures.get(g).copied().flatten() {
                Some(p) => {
                    grp.kind = if p.dim3 { KIND_3D } else { KIND_ARRAY };
                    grp.tiles_x = p.tiles[0];
                    grp.tiles_y = p.tiles[1];
                }
                None if g >= 4 && keep_packed => {}
                None => {
                    grp.kind = KIND_BUFFER;
                    grp.base = buffered_before;
                    buffered_before += n;
                }
            }
        }
        let brick_words = plan.buffers.brick_words();
        let mut packed_total = 0u64;
        for (g, grp) in groups
            .iter_mut()
            .enumerate()
            .skip(4)
            .filter(|_| keep_packed)
        {
            let f = PayloadFormat::ORDER[group_first_format(g)];
            grp.kind = KIND_PACKED;
            grp.base = u32::try_from(buffered_before as u64 * brick_words + packed_total)
                .map_err(|_| RuntimeError::Limits("packed bricks beyond 2^32 words".into()))?;
            let bits = f.packed_bits().expect("packed");
            grp.tiles_x = bits;
            grp.tiles_y = (255.0f32 / ((1u32 << bits) - 1) as f32).to_bits();
            packed_total += caps[f.rank()] as u64 * packed_words(f);
        }

        // The pool: buffers of `per` bricks' words each (the buffered bricks, then the packed
        // words), empty textures.
        let per_words = plan.buffers.words_per_buffer();
        let words = buffered_before as u64 * brick_words + packed_total;
        let mut buffer_bytes = 0;
        let payload_buffers: Vec<wgpu::Buffer> = (0..PAYLOAD_BINDINGS as u64)
            .map(|i| {
                let n = words.saturating_sub(i * per_words).min(per_words);
                let size = (n * 4).max(4);
                if n > 0 {
                    buffer_bytes += size;
                }
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("vdbcook streamed brick pool"),
                    size,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let mut textures: [Option<wgpu::Texture>; 3] = Default::default();
        let mut views: [Option<wgpu::TextureView>; 3] = Default::default();
        for (slot, p) in plan.textures.iter().enumerate() {
            if let Some(p) = p {
                let (t, v) = empty_group_texture(device, p, "vdbcook streamed brick texture");
                textures[slot] = Some(t);
                views[slot] = Some(v);
            }
        }
        let pool_bytes = buffer_bytes
            + plan
                .textures
                .iter()
                .flatten()
                .map(|p| p.bytes())
                .sum::<u64>()
            + SLOT_RANGE_BYTES * caps.iter().map(|&c| c as u64).sum::<u64>();
        let slot_bytes = std::array::from_fn(|i| {
            if i < 3 {
                if let Some(p) = plan.textures[i] {
                    let u = (8 / p.unit_dim) as u64;
                    return u * u * p.slices as u64 * p.unit_bytes as u64;
                }
            }
            match PayloadFormat::ORDER[i] {
                f if keep_packed && f.packed_bits().is_some() => f.bytes_per_brick() as u64,
                _ => brick_words * 4,
            }
        });
        let total_slots = firsts[FORMATS - 1] + caps[FORMATS - 1];
        let s = StreamingVolume {
            budget,
            pool_bytes,
            plan_textures: plan.textures,
            buffers: plan.buffers,
            layout: plan.layout,
            caps,
            firsts,
            groups,
            slot_bytes,
            payload_buffers,
            buffer_bytes,
            packed_bytes: packed_total * 4,
            textures,
            views,
            dummy3: dummy_view(device, true),
            dummy_array: dummy_view(device, false),
            bind_group_layout: volume_bind_group_layout(device),
            free: std::array::from_fn(|i| (0..caps[i]).collect()),
            slot_of: HashMap::new(),
            slot_brick: vec![FREE; total_slots as usize],
            residents: assets.iter().map(|a| Resident::of(a)).collect(),
            stats: WindowStats {
                window: (0, 0),
                uploaded_bricks: 0,
                uploaded_bytes: 0,
                topology_bytes: 0,
                resident_bricks: 0,
                evicted: 0,
            },
            volume: None,
            asset: None,
        };
        Ok(s)
    }

    /// Every frame of each of `assets` as the windows of one pool holding every brick: what
    /// [`GpuVolume::upload_with`] (one asset) and [`GpuVolume::upload_set`] upload (one
    /// uploader: the whole-asset volume is the streamed volume whose window is the whole asset).
    /// Layout: the forced one, or the first of [`Layout::automatic_order`] the device's features
    /// and limits take.
    pub(crate) fn upload_whole(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        assets: &[&Asset],
        options: UploadOptions,
    ) -> Result<GpuVolume> {
        if assets.is_empty() || assets.len() > MAX_ASSETS {
            return Err(RuntimeError::Setting(format!(
                "a volume set holds 1 to {MAX_ASSETS} assets, not {}",
                assets.len()
            )));
        }
        let max_binding = check_limits(device)?;
        let mut counts = [0u64; FORMATS];
        for a in assets {
            for (c, n) in counts.iter_mut().zip(a.header.brick_counts) {
                *c += n;
            }
        }
        if counts.iter().sum::<u64>() > u32::MAX as u64 / 2 {
            return Err(RuntimeError::Limits(format!(
                "{} bricks",
                counts.iter().sum::<u64>()
            )));
        }
        let plan = match options.force {
            Some(layout) => plan_layout(device, &counts, layout, max_binding).map_err(|e| {
                RuntimeError::Limits(format!("forced layout {}: {e}", layout.name()))
            })?,
            None => {
                let mut refusals = Vec::new();
                let mut chosen = None;
                for layout in Layout::automatic_order(device) {
                    match plan_layout(device, &counts, layout, max_binding) {
                        Ok(p) => {
                            chosen = Some(p);
                            break;
                        }
                        Err(e) => refusals.push(format!("{}: {e}", layout.name())),
                    }
                }
                match chosen {
                    Some(p) => {
                        if !refusals.is_empty() {
                            log::info!("vdbcook: layouts passed over: {}", refusals.join("; "));
                        }
                        p
                    }
                    None => {
                        return Err(RuntimeError::Limits(format!(
                            "no payload layout fits: {}",
                            refusals.join("; ")
                        )))
                    }
                }
            }
        };
        let caps = counts.map(|c| c as u32);
        let mut s = Self::build(device, assets, caps, &plan, u64::MAX)?;
        let windows: Vec<(&Asset, usize, usize)> = assets
            .iter()
            .map(|&a| (a, 0, a.frame_count() - 1))
            .collect();
        s.load(device, queue, &windows)?;
        let volume = s.volume.take().expect("loaded");
        log::info!(
            "vdbcook: uploaded {} asset(s), {} frames, {} bricks: {} (device BC features: {:?})",
            assets.len(),
            assets.iter().map(|a| a.frame_count()).sum::<usize>(),
            counts.iter().sum::<u64>(),
            volume.describe(),
            device.features() & OPTIONAL_FEATURES
        );
        Ok(volume)
    }

    /// Makes `window` (first and last frame) resident: evicts the bricks it does not use and
    /// writes those it newly uses. On error nothing changed.
    pub fn set_window(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        window: RangeInclusive<usize>,
    ) -> Result<WindowStats> {
        let asset = Arc::clone(self.asset.as_ref().expect("a stream holds its asset"));
        let (first, last) = check_window(&asset, &window)?;
        self.load(device, queue, &[(&asset, first, last)])?;
        Ok(self.stats.clone())
    }

    /// Moves the window one frame on (an error past the last frame).
    pub fn advance(&mut self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<WindowStats> {
        let (a, b) = self.stats.window;
        self.set_window(device, queue, a + 1..=b + 1)
    }

    /// The resident window as a volume (frames are window-local, see [`Self::local_frame`]).
    pub fn volume(&self) -> &GpuVolume {
        self.volume.as_ref().expect("a window is always loaded")
    }
    /// First and last frame of the resident window.
    pub fn window(&self) -> (usize, usize) {
        self.stats.window
    }
    /// What the last window change did.
    pub fn stats(&self) -> &WindowStats {
        &self.stats
    }
    /// The index in [`Self::volume`] of asset frame `frame`, or an error when it is outside the
    /// window.
    pub fn local_frame(&self, frame: usize) -> Result<usize> {
        let (a, b) = self.stats.window;
        if frame < a || frame > b {
            return Err(RuntimeError::Setting(format!(
                "frame {frame} is outside the resident window {a}..={b}"
            )));
        }
        Ok(frame - a)
    }
    /// Slots per format, in [`PayloadFormat::ORDER`].
    pub fn slots(&self) -> [u32; FORMATS] {
        self.caps
    }
    /// Bytes one slot of `format` takes in the pool (as the layout stores the brick).
    pub fn slot_bytes(&self, format: PayloadFormat) -> u64 {
        self.slot_bytes[format.rank()]
    }
    /// The budget and the bytes the pool takes of it (the rest is for the topology).
    pub fn budget(&self) -> (u64, u64) {
        (self.budget, self.pool_bytes)
    }
    /// The pool's layout.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Makes the windows `windows` (per asset of the pool, in pool order: the asset, its first
    /// and last frame) resident: evicts the bricks they do not use and writes those they newly
    /// use, then writes the topology of every asset's window. On error nothing changed.
    fn load(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        windows: &[(&Asset, usize, usize)],
    ) -> Result<()> {
        debug_assert_eq!(windows.len(), self.residents.len());
        let uses: Vec<WindowUse> = windows
            .iter()
            .map(|&(asset, first, last)| window_use(asset, first, last))
            .collect();
        let span = |i: usize| {
            let (_, first, last) = windows[i];
            if windows.len() == 1 {
                format!("window {first}..={last}")
            } else {
                format!("asset {i}'s window {first}..={last}")
            }
        };
        // Checks first: slots per format, topology bytes.
        let mut need = [0u32; FORMATS];
        for (&(asset, ..), u) in windows.iter().zip(&uses) {
            for &b in &u.bricks {
                need[asset.brick_format(b).0.rank()] += 1;
            }
        }
        for (i, f) in PayloadFormat::ORDER.iter().enumerate() {
            if need[i] > self.caps[i] {
                let what = if windows.len() == 1 {
                    span(0)
                } else {
                    "the windows".to_string()
                };
                return Err(RuntimeError::Budget(format!(
                    "{what} use {} {} bricks, the budget of {} bytes holds {} of them",
                    need[i],
                    f.name(),
                    self.budget,
                    self.caps[i]
                )));
            }
        }
        let total_slots = self.slot_brick.len() as u64;
        let topo_words: u64 = windows
            .iter()
            .zip(&uses)
            .map(|(&(asset, first, last), u)| topology_words(asset, last - first + 1, u))
            .sum();
        let topo_bytes = topo_words * 4 + total_slots * SLOT_RANGE_BYTES + INFO_BYTES;
        let topo_room = self.budget - self.pool_bytes + total_slots * SLOT_RANGE_BYTES;
        if topo_bytes > topo_room {
            return Err(RuntimeError::Budget(format!(
                "{} needs {topo_bytes} bytes of topology, the budget of {} bytes leaves \
                 {topo_room} beside the pool",
                span(0),
                self.budget
            )));
        }
        let limits = device.limits();
        let max_binding = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if topo_bytes - INFO_BYTES > max_binding {
            return Err(RuntimeError::Limits(format!(
                "topology takes {topo_bytes} bytes, one storage binding holds {max_binding}"
            )));
        }

        // Evict, then write the new bricks (per asset, ascending, each into the lowest free
        // slot of its format).
        let wanted: HashSet<(u32, u32)> = uses
            .iter()
            .enumerate()
            .flat_map(|(a, u)| u.bricks.iter().map(move |&b| (a as u32, b)))
            .collect();
        let mut leaving: Vec<(u32, u32)> = self
            .slot_of
            .keys()
            .copied()
            .filter(|k| !wanted.contains(k))
            .collect();
        leaving.sort_unstable();
        for k in &leaving {
            let slot = self.slot_of.remove(k).expect("resident");
            let f = windows[k.0 as usize].0.brick_format(k.1).0.rank();
            self.free[f].insert(slot - self.firsts[f]);
            self.slot_brick[slot as usize] = FREE;
        }
        let (mut uploaded, mut uploaded_bytes) = (0, 0);
        let mut values = [0.0f32; BRICK_VOXELS];
        let mut units = Vec::new();
        for (a, (&(asset, ..), u)) in windows.iter().zip(&uses).enumerate() {
            for &b in &u.bricks {
                let key = (a as u32, b);
                if self.slot_of.contains_key(&key) {
                    continue;
                }
                let (format, bytes) = asset.brick_bytes(b);
                let f = format.rank();
                let local = self.free[f].pop_first().expect("checked against the caps");
                let slot = self.firsts[f] + local;
                self.slot_of.insert(key, slot);
                self.slot_brick[slot as usize] = key;
                asset.decode_brick(b, &mut values);
                let r = &mut self.residents[a];
                if !r.brick_box_known[b as usize] {
                    r.brick_boxes[b as usize] = brick_box(&values, asset.header.background);
                    r.brick_box_known[b as usize] = true;
                }
                uploaded += 1;
                uploaded_bytes += self.write_brick(queue, slot, format, bytes, &values, &mut units);
            }
        }

        // Per-frame boxes (every brick of the windows' frames is known now).
        for (a, &(asset, first, last)) in windows.iter().enumerate() {
            let r = &mut self.residents[a];
            for f in first..=last {
                if r.frame_boxes[f].is_none() {
                    r.frame_boxes[f] = Some(FrameBoxes {
                        stored: frame_box(asset, f, &r.brick_boxes),
                        content: vdbcook_scene::content_box(asset, f),
                    });
                }
            }
        }

        // Each asset's window topology in turn (bricks numbered by slot), then the per-slot
        // ranges of the whole pool.
        let mut topo: Vec<u32> = Vec::with_capacity((topo_bytes / 4) as usize);
        let mut infos = [AssetInfo::default(); MAX_ASSETS];
        for (a, (&(asset, first, last), u)) in windows.iter().zip(&uses).enumerate() {
            infos[a] = self.write_topology(&mut topo, a as u32, asset, first, last, u);
        }
        let per_slot = |pick: fn(&Asset) -> &Vec<[f32; 2]>| -> Vec<u32> {
            self.slot_brick
                .iter()
                .flat_map(|&(a, b)| {
                    let r = if (a, b) == FREE {
                        [0.0, 0.0]
                    } else {
                        pick(windows[a as usize].0)[b as usize]
                    };
                    [r[0].to_bits(), r[1].to_bits()]
                })
                .collect()
        };
        let off_brick_ranges = topo.len();
        topo.extend(per_slot(|a| &a.brick_ranges));
        let off_brick_quant = topo.len();
        topo.extend(per_slot(|a| &a.brick_quant));
        if topo.is_empty() {
            topo.push(0);
        }
        debug_assert_eq!(
            topo.len() as u64 * 4 + INFO_BYTES,
            topo_bytes.max(4 + INFO_BYTES)
        );

        let info = VolumeInfo {
            bricks_per_binding: self.buffers.bricks_per_buffer(),
            payload_layout: self.buffers.code(),
            off_brick_ranges: off_brick_ranges as u32,
            off_brick_quant: off_brick_quant as u32,
            asset_count: windows.len() as u32,
            _pad: [0; 3],
            groups: self.groups,
            assets: infos,
        };
        let bind_group = self.bind(device, &info, &topo);
        let assets = windows
            .iter()
            .zip(&self.residents)
            .map(|(&(asset, first, last), r)| {
                let boxes: Vec<FrameBoxes> = (first..=last)
                    .map(|f| r.frame_boxes[f].expect("computed above"))
                    .collect();
                AssetMeta {
                    frames: last - first + 1,
                    levels: vdbcook_scene::LevelChain::of(asset),
                    root_len: asset.root_len(),
                    root_dims: asset.header.root_dims,
                    index_to_world: asset.header.index_to_world,
                    bboxes: boxes.iter().map(|b| b.stored).collect(),
                    content: boxes.iter().map(|b| b.content).collect(),
                    frame_max: (first..=last).map(|f| asset.frame_range(f, 0)[1]).collect(),
                    channels: r
                        .channel_boxes
                        .iter()
                        .map(|c| ChannelBoxes {
                            background: c.background,
                            boxes: c.boxes[first..=last].to_vec(),
                        })
                        .collect(),
                }
            })
            .collect();
        self.volume = Some(GpuVolume {
            bind_group_layout: self.bind_group_layout.clone(),
            bind_group,
            layout: PayloadLayout {
                layout: self.layout,
                buffers: self.buffers,
                buffer_bytes: self.buffer_bytes,
                packed_bytes: self.packed_bytes,
                textures: self
                    .plan_textures
                    .iter()
                    .flatten()
                    .map(|p| p.group())
                    .collect(),
            },
            gpu_bytes: self.pool_bytes - total_slots * SLOT_RANGE_BYTES + topo_bytes,
            assets,
        });
        let (_, first, last) = windows[0];
        self.stats = WindowStats {
            window: (first, last),
            uploaded_bricks: uploaded,
            uploaded_bytes,
            topology_bytes: topo_bytes,
            resident_bricks: self.slot_of.len(),
            evicted: leaving.len(),
        };
        Ok(())
    }

    /// Appends asset `a`'s window topology to `topo` — the roots of every level, the nodes the
    /// window uses (renumbered in first use order: masks, base, prefixes, ranges per channel),
    /// their refs with bricks numbered by slot, the tiles, the channels' backgrounds — and
    /// returns where its sections lie.
    fn write_topology(
        &self,
        topo: &mut Vec<u32>,
        a: u32,
        asset: &Asset,
        first: usize,
        last: usize,
        u: &WindowUse,
    ) -> AssetInfo {
        let mut node_index = HashMap::new();
        for (i, &n) in u.nodes.iter().enumerate() {
            node_index.insert(n, i as u32);
        }
        let off_roots = topo.len();
        // Level k of window frame i at root set i + k·frames (`GpuVolume::levels`).
        for level in 0..asset.level_count() {
            for f in first..=last {
                topo.extend(asset.frame_roots(asset.lod_set(f, level)).iter().map(|&e| {
                    if e == EMPTY || e & TILE_BIT != 0 {
                        e
                    } else {
                        node_index[&e]
                    }
                }));
            }
        }
        let off_masks = topo.len();
        for &n in &u.nodes {
            topo.extend(
                asset
                    .l2_mask(n as usize)
                    .iter()
                    .flat_map(|&w| [w as u32, (w >> 32) as u32]),
            );
        }
        let off_base = topo.len();
        let mut base = 0u32;
        for &n in &u.nodes {
            topo.push(base);
            base += node_refs(asset, n).1 as u32;
        }
        let off_prefix = topo.len();
        for &n in &u.nodes {
            let n = n as usize;
            topo.extend(
                asset.l2_prefix[n * L2_WORDS..(n + 1) * L2_WORDS]
                    .iter()
                    .map(|&p| p as u32),
            );
        }
        let nch = asset.channel_count();
        let off_l2_ranges = topo.len();
        for &n in &u.nodes {
            for c in 0..nch {
                let r = asset.l2_range(n as usize, c);
                topo.extend([r[0].to_bits(), r[1].to_bits()]);
            }
        }
        let off_refs = topo.len();
        for &n in &u.nodes {
            let (lo, count) = node_refs(asset, n);
            topo.extend(
                asset.l3_refs[lo * nch..(lo + count) * nch]
                    .iter()
                    .map(|&r| {
                        if r == EMPTY || r & TILE_BIT != 0 {
                            r
                        } else {
                            self.slot_of[&(a, r)]
                        }
                    }),
            );
        }
        let off_tiles = topo.len();
        topo.extend(asset.tiles.iter().map(|t| t.to_bits()));
        let off_channel_bg = topo.len();
        if nch > 1 {
            topo.extend((0..nch).map(|c| asset.header.channel_background(c).to_bits()));
        }
        AssetInfo {
            root_dims: asset.header.root_dims,
            root_len: asset.root_len() as u32,
            off_roots: off_roots as u32,
            off_masks: off_masks as u32,
            off_base: off_base as u32,
            off_prefix: off_prefix as u32,
            off_l2_ranges: off_l2_ranges as u32,
            off_refs: off_refs as u32,
            off_tiles: off_tiles as u32,
            off_channel_bg: off_channel_bg as u32,
            background: asset.header.background,
            frames: (last - first + 1) as u32,
            channels: nch as u32,
            _pad: 0,
        }
    }

    /// The bind group of the pool with this `info` and topology (the bindings of
    /// `volume_bind_group_layout`).
    fn bind(&self, device: &wgpu::Device, info: &VolumeInfo, topo: &[u32]) -> wgpu::BindGroup {
        let info_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vdbcook volume info"),
            contents: bytemuck::bytes_of(info),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let topo_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vdbcook volume topology"),
            contents: bytemuck::cast_slice(topo),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: info_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: topo_buffer.as_entire_binding(),
            },
        ];
        for (i, b) in self.payload_buffers.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 2 + i as u32,
                resource: b.as_entire_binding(),
            });
        }
        for (slot, (p, v)) in self.plan_textures.iter().zip(&self.views).enumerate() {
            for dim3 in [true, false] {
                let own = p.filter(|p| p.dim3 == dim3).and(v.as_ref());
                let view = own.unwrap_or(if dim3 {
                    &self.dummy3
                } else {
                    &self.dummy_array
                });
                entries.push(wgpu::BindGroupEntry {
                    binding: FIRST_TEXTURE_BINDING + 2 * slot as u32 + (!dim3) as u32,
                    resource: wgpu::BindingResource::TextureView(view),
                });
            }
        }
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook volume"),
            layout: &self.bind_group_layout,
            entries: &entries,
        })
    }

    /// Writes one brick into `slot`; returns the bytes written.
    fn write_brick(
        &self,
        queue: &wgpu::Queue,
        slot: u32,
        format: PayloadFormat,
        bytes: &[u8],
        values: &[f32; BRICK_VOXELS],
        units: &mut Vec<u8>,
    ) -> u64 {
        let g = group_of(format);
        let grp = self.groups[g];
        let local = slot - grp.first + grp.base;
        if grp.kind == KIND_PACKED {
            // The brick's own words at `base + (slot − first)·16·bits`, split where they cross
            // from one payload buffer into the next.
            let n = packed_words(format);
            let at = grp.base as u64 + (slot - grp.first) as u64 * n;
            let per = self.buffers.words_per_buffer();
            let mut done = 0;
            while done < n {
                let w = at + done;
                let (buffer, offset) = (w / per, w % per);
                let take = (n - done).min(per - offset);
                queue.write_buffer(
                    &self.payload_buffers[buffer as usize],
                    offset * 4,
                    &bytes[(done * 4) as usize..((done + take) * 4) as usize],
                );
                done += take;
            }
            return n * 4;
        }
        if grp.kind == KIND_BUFFER {
            let half = matches!(self.buffers, BufferLayout::F16 { .. });
            let mut words = Vec::with_capacity(BRICK_VOXELS);
            push_brick_words(&mut words, format, bytes, values, half);
            let per = self.buffers.bricks_per_buffer();
            let offset = (local % per) as u64 * words.len() as u64 * 4;
            queue.write_buffer(
                &self.payload_buffers[(local / per) as usize],
                offset,
                bytemuck::cast_slice(&words),
            );
            return words.len() as u64 * 4;
        }
        let plan = self.plan_textures[g].expect("texture group");
        let texture = self.textures[g].as_ref().expect("texture group");
        brick_units(&plan, format, bytes, units);
        let [tx, ty, _] = plan.tiles;
        let tile = [local % tx, (local / tx) % ty, local / (tx * ty)];
        let tile_units = 8 / plan.unit_dim;
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: 8 * tile[0],
                    y: 8 * tile[1],
                    z: plan.slices * tile[2],
                },
                aspect: wgpu::TextureAspect::All,
            },
            units,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(tile_units * plan.unit_bytes as u32),
                rows_per_image: Some(tile_units),
            },
            wgpu::Extent3d {
                width: 8,
                height: 8,
                depth_or_array_layers: plan.slices,
            },
        );
        units.len() as u64
    }
}

fn check_window(asset: &Asset, window: &RangeInclusive<usize>) -> Result<(usize, usize)> {
    let (first, last) = (*window.start(), *window.end());
    let frames = asset.frame_count();
    if last >= frames {
        return Err(RuntimeError::Frame {
            frame: last,
            frames,
        });
    }
    if first > last {
        return Err(RuntimeError::Setting(format!(
            "empty frame window {first}..={last}"
        )));
    }
    Ok((first, last))
}

enum PoolError {
    /// The budget is too small whatever the layout.
    Budget(String),
    /// This layout does not fit the device.
    Layout(String),
}

struct PoolPlan {
    caps: [u32; FORMATS],
    plan: FullPlan,
}

/// Slots per format for `budget` under `layout` (the module docs' rule) and the pool's plan.
#[allow(clippy::too_many_arguments)]
fn plan_pool(
    device: &wgpu::Device,
    counts: &[u64; FORMATS],
    [frame_need, window_need]: [[u32; FORMATS]; 2],
    window_len: usize,
    layout: Layout,
    max_binding: u64,
    budget: u64,
    reserve: u64,
) -> std::result::Result<PoolPlan, PoolError> {
    let buffered_f16 = (0..FORMATS).all(|i| {
        let f = PayloadFormat::ORDER[i];
        let textured = layout != Layout::Buffers && f.is_quantized();
        counts[i] == 0 || textured || f == PayloadFormat::F16
    });
    let cost: [u64; FORMATS] = std::array::from_fn(|i| {
        nominal_slot_bytes(layout, PayloadFormat::ORDER[i], buffered_f16) + SLOT_RANGE_BYTES
    });
    let frame_bytes: u64 = (0..FORMATS).map(|i| frame_need[i] as u64 * cost[i]).sum();
    if budget < frame_bytes + reserve {
        return Err(PoolError::Budget(format!(
            "budget {budget} bytes is smaller than one frame: {frame_bytes} bytes of brick slots \
             (the most bricks a frame uses, per format, under layout {}) + {reserve} bytes of \
             topology",
            layout.name()
        )));
    }
    let window_bytes: u64 = (0..FORMATS).map(|i| window_need[i] as u64 * cost[i]).sum();
    if budget < window_bytes + reserve {
        return Err(PoolError::Budget(format!(
            "budget {budget} bytes is smaller than a window of {window_len} frames: {window_bytes} \
             bytes of brick slots (the most bricks such a window uses, per format, under layout \
             {}) + {reserve} bytes of topology",
            layout.name()
        )));
    }
    // From here on `frame_need` is what every window of the initial length needs.
    let frame_need = window_need;
    let spare = (budget - window_bytes - reserve) as u128;
    let total: u128 = (0..FORMATS)
        .map(|i| counts[i] as u128 * cost[i] as u128)
        .sum();
    let mut caps: [u32; FORMATS] = std::array::from_fn(|i| {
        let extra = (spare * counts[i] as u128).checked_div(total).unwrap_or(0);
        (frame_need[i] as u128 + extra).min(counts[i] as u128) as u32
    });
    // Texture grids round up to whole tile rows: take slots off until the pool fits.
    for _ in 0..64 {
        let c = caps.map(|c| c as u64);
        let plan = plan_layout(device, &c, layout, max_binding).map_err(PoolError::Layout)?;
        let textured: u64 = plan.textures.iter().flatten().map(|p| p.bytes()).sum();
        let keep_packed = layout != Layout::Buffers;
        let (mut buffered, mut packed) = (0u64, 0u64);
        for (i, f) in PayloadFormat::ORDER.iter().enumerate() {
            if i < 3 && plan.textures[i].is_some() {
                continue;
            }
            match f.packed_bits() {
                Some(_) if keep_packed => packed += c[i] * f.bytes_per_brick() as u64,
                _ => buffered += c[i],
            }
        }
        let brick = plan.buffers.brick_words() * 4;
        let bytes = textured + buffered * brick + packed + SLOT_RANGE_BYTES * c.iter().sum::<u64>();
        if bytes + reserve <= budget {
            return Ok(PoolPlan { caps, plan });
        }
        let over = bytes + reserve - budget;
        // The format with the most slots beyond one frame's need gives some up.
        let i = (0..FORMATS)
            .max_by_key(|&i| caps[i].saturating_sub(frame_need[i]))
            .expect("formats");
        if caps[i] <= frame_need[i] {
            break;
        }
        let give = over.div_ceil(cost[i]).max(1) as u32;
        caps[i] = caps[i].saturating_sub(give).max(frame_need[i]);
    }
    Err(PoolError::Budget(format!(
        "budget {budget} bytes: the {} texture tiles of one frame's bricks + {reserve} bytes of \
         topology do not fit",
        layout.name()
    )))
}
