//! The occupancy map: OctoMap's probabilistic semantics on a hashed grid of 4×4×4 leaf blocks.
//!
//! - Leaves hold log-odds; a cloud is inserted by ray casting from the sensor origin (free cells
//!   along each ray, the end cell occupied; points beyond the maximum range only clear), each cell
//!   updated at most once per cloud, occupied winning over free (OctoMap's `insertPointCloud`).
//! - Defaults as OctoMap: hit 0.7, miss 0.4, clamping 0.12–0.97, occupied above 0.5.
//! - A block is exactly FLAME's octobox: the node two levels above the leaves of a depth-16
//!   octree on OctoMap's key lattice, with its 64-bit occupancy mask (bit `16x + 4y + z`).
//! - Blocks exist only where something was observed; blocks whose 64 leaves are all known and
//!   equal (saturated free space, typically) are compacted to one value.
//!
//! Files: `insert.rs` (ray casting; the robot's own points are removed with its
//! [`PlacedSpheres`](crate::robot::spheres::PlacedSpheres)), `bt_file.rs` (OctoMap's binary
//! `.bt` format).
//!
//! A block is stored as `Block` (leaves and masks), in chunks that copies of the map share; what
//! the map shows of it is an
//! [`Octobox`] (key and occupancy mask), which is also FLAME's local primitive.

mod bt_file;
mod clearance;
mod cover;
mod distance;
mod insert;

pub use bt_file::BtError;
pub use clearance::Clearance;
pub use insert::{CloudMask, InsertReport};

use rustc_hash::FxHashMap;
use std::sync::Arc;

/// Integer voxel coordinates: `floor(coordinate / resolution)` per axis.
pub type VoxelKey = [i32; 3];
/// Integer block coordinates: voxel key `>> 2` per axis.
pub type BlockKey = [i32; 3];

/// Map settings. Probabilities as in OctoMap.
#[derive(Debug, Clone, PartialEq)]
pub struct MapParams {
    /// Leaf edge length, metres.
    pub resolution: f64,
    /// Probability of a cell given a hit.
    pub prob_hit: f64,
    /// Probability of a cell given a miss (ray passes through).
    pub prob_miss: f64,
    /// Lower clamping probability.
    pub clamp_min: f64,
    /// Upper clamping probability.
    pub clamp_max: f64,
    /// Occupied above this probability.
    pub occupancy_threshold: f64,
    /// Rays are cut at this range (metres); points beyond only clear. Non-positive: unlimited.
    pub max_range: f64,
    /// Cells outside this box (base frame, metres) are never stored.
    pub bounds: Option<([f64; 3], [f64; 3])>,
    /// OctoMap's `discretize`: one ray per distinct endpoint voxel, to its centre (about 2.5×
    /// faster on camera frames; slightly less free space carved next to surfaces).
    pub discretize: bool,
}

impl Default for MapParams {
    fn default() -> Self {
        MapParams {
            resolution: 0.02,
            prob_hit: 0.7,
            prob_miss: 0.4,
            clamp_min: 0.12,
            clamp_max: 0.97,
            occupancy_threshold: 0.5,
            max_range: 3.0,
            bounds: None,
            discretize: false,
        }
    }
}

fn logit(p: f64) -> f32 {
    (p / (1.0 - p)).ln() as f32
}

/// State of a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Occupancy {
    /// Never observed.
    Unknown,
    /// Observed, at or below the threshold.
    Free,
    /// Observed, above the threshold.
    Occupied,
}

/// Leaf storage of a block.
#[derive(Debug, Clone)]
pub(crate) enum Leaves {
    /// All 64 leaves known and equal.
    Uniform(f32),
    /// Per-leaf log-odds (meaningful where `known` is set).
    Each(Box<[f32; 64]>),
}

/// A 4×4×4 block of leaves (an octobox).
#[derive(Debug, Clone)]
pub(crate) struct Block {
    pub(crate) key: BlockKey,
    pub(crate) leaves: Leaves,
    /// Leaves observed at least once.
    pub(crate) known: u64,
    /// Leaves above the occupancy threshold.
    pub(crate) occupied: u64,
}

impl Block {
    fn new(key: BlockKey) -> Self {
        Block {
            key,
            leaves: Leaves::Each(Box::new([0.0; 64])),
            known: 0,
            occupied: 0,
        }
    }

    pub(crate) fn logodds(&self, bit: usize) -> f32 {
        match &self.leaves {
            Leaves::Uniform(v) => *v,
            Leaves::Each(a) => a[bit],
        }
    }
}

/// Blocks stored in chunks that copies of the map share: copying the map copies no block, and
/// a write copies only the chunk it lands in (when another copy still holds it).
#[derive(Debug, Clone, Default)]
pub(crate) struct Blocks {
    chunks: Vec<Arc<Vec<Block>>>,
    len: usize,
}

/// Blocks per chunk.
const CHUNK: usize = 256;

impl Blocks {
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The block at `i`, for writing.
    #[inline]
    pub(crate) fn get_mut(&mut self, i: u32) -> &mut Block {
        let i = i as usize;
        &mut Arc::make_mut(&mut self.chunks[i / CHUNK])[i % CHUNK]
    }

    /// Appends a block; returns its index.
    fn push(&mut self, b: Block) -> u32 {
        if self.len.is_multiple_of(CHUNK) {
            self.chunks.push(Arc::new(Vec::with_capacity(CHUNK)));
        }
        let last = self.chunks.last_mut().expect("pushed above");
        Arc::make_mut(last).push(b);
        self.len += 1;
        (self.len - 1) as u32
    }

    fn iter(&self) -> impl Iterator<Item = &Block> {
        self.chunks.iter().flat_map(|c| c.iter())
    }
}

impl std::ops::Index<usize> for Blocks {
    type Output = Block;
    #[inline]
    fn index(&self, i: usize) -> &Block {
        &self.chunks[i / CHUNK][i % CHUNK]
    }
}

/// A non-empty octobox: block key, centre (metres) and occupancy mask.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Octobox {
    /// Block coordinates.
    pub key: BlockKey,
    /// Bit `16x + 4y + z` set when leaf `(x, y, z)` of the block is occupied.
    pub mask: u64,
}

/// The occupancy map.
#[derive(Debug, Clone)]
pub struct OccupancyMap {
    params: MapParams,
    pub(crate) hit: f32,
    pub(crate) miss: f32,
    pub(crate) min: f32,
    pub(crate) max: f32,
    pub(crate) threshold: f32,
    pub(crate) blocks: Blocks,
    pub(crate) index: FxHashMap<BlockKey, u32>,
    /// Per 4×4×4 group of blocks (16³ leaves): how many of its blocks hold an occupied leaf.
    /// The broad phase of [`OccupancyMap::sphere_collides`].
    coarse: FxHashMap<BlockKey, u32>,
    /// The clearance grids of the current state, built on first use after a change (or
    /// brought up to date by [`OccupancyMap::refresh_clearance`]).
    clearance: std::sync::OnceLock<Option<Arc<Clearance>>>,
    /// The last grids built and the blocks whose occupancy changed since (`None`: build anew).
    stale: Option<(Arc<Clearance>, Vec<BlockKey>)>,
}

/// Past this many changed blocks the clearance grids are built anew rather than updated.
const STALE_MAX: usize = 1 << 16;

/// How far the clearance grid reaches beyond the occupied voxels, metres: balls larger than
/// this near the map are decided exactly.
pub const CLEARANCE_PAD: f64 = 0.15;

/// Key of the voxel at bit `bit` of block `b` (the inverse of [`leaf_bit`]).
#[inline]
pub(crate) fn voxel_key(b: BlockKey, bit: usize) -> VoxelKey {
    [
        b[0] * 4 + (bit / 16) as i32,
        b[1] * 4 + (bit / 4 % 4) as i32,
        b[2] * 4 + (bit % 4) as i32,
    ]
}

/// Bit of leaf `(x, y, z)` (each 0..4) inside its block.
#[inline]
pub fn leaf_bit(x: usize, y: usize, z: usize) -> usize {
    16 * x + 4 * y + z
}

impl OccupancyMap {
    /// An empty map.
    pub fn new(params: MapParams) -> Self {
        OccupancyMap {
            hit: logit(params.prob_hit),
            miss: logit(params.prob_miss),
            min: logit(params.clamp_min),
            max: logit(params.clamp_max),
            threshold: logit(params.occupancy_threshold),
            params,
            blocks: Blocks::default(),
            index: FxHashMap::default(),
            coarse: FxHashMap::default(),
            clearance: Default::default(),
            stale: None,
        }
    }

    /// The clearance grid of the map as it is now (built on the first call after a change;
    /// `None` when nothing is occupied or the map is spread too wide for a grid).
    pub fn clearance(&self) -> Option<&Clearance> {
        self.clearance
            .get_or_init(|| Clearance::of(self, CLEARANCE_PAD).map(Arc::new))
            .as_deref()
    }

    /// Brings the clearance grids up to date, recomputing them only around the blocks whose
    /// occupancy changed since they were last built (the ingest's per-cloud cost then follows
    /// what the cloud changed, not the map's size).
    pub fn refresh_clearance(&mut self) {
        if self.clearance.get().is_some() {
            return;
        }
        if let Some((mut grids, changed)) = self.stale.take() {
            if Arc::make_mut(&mut grids).update(self, &changed) {
                let _ = self.clearance.set(Some(grids));
                return;
            }
        }
        let _ = self
            .clearance
            .set(Clearance::of(self, CLEARANCE_PAD).map(Arc::new));
    }

    /// True when some voxel is occupied.
    pub fn has_occupied(&self) -> bool {
        !self.coarse.is_empty()
    }

    /// The settings.
    pub fn params(&self) -> &MapParams {
        &self.params
    }

    /// Leaf edge length, metres.
    pub fn resolution(&self) -> f64 {
        self.params.resolution
    }

    /// Voxel key of a point.
    #[inline]
    pub fn key_of(&self, p: [f64; 3]) -> VoxelKey {
        let inv = 1.0 / self.params.resolution;
        p.map(|v| fast_floor(v * inv))
    }

    /// Centre of a voxel, metres.
    #[inline]
    pub fn voxel_center(&self, k: VoxelKey) -> [f64; 3] {
        let r = self.params.resolution;
        k.map(|v| (v as f64 + 0.5) * r)
    }

    /// Centre of an octobox (block), metres.
    pub fn block_center(&self, k: BlockKey) -> [f64; 3] {
        let r = self.params.resolution;
        k.map(|v| (4 * v + 2) as f64 * r)
    }

    /// Edge length of an octobox, metres.
    pub fn block_size(&self) -> f64 {
        4.0 * self.params.resolution
    }

    pub(crate) fn split(k: VoxelKey) -> (BlockKey, usize) {
        let b = k.map(|v| v >> 2);
        let bit = leaf_bit(
            (k[0] & 3) as usize,
            (k[1] & 3) as usize,
            (k[2] & 3) as usize,
        );
        (b, bit)
    }

    /// State of the voxel holding `p`.
    ///
    /// ```
    /// use ember_engine::world::map::{MapParams, Occupancy, OccupancyMap};
    /// use ember_engine::Pose;
    /// let mut map = OccupancyMap::new(MapParams::default());
    /// map.insert_cloud(&[[1.0, 0.0, 0.0]], &Pose::identity(), None);
    /// assert_eq!(map.occupancy([1.0, 0.0, 0.0]), Occupancy::Occupied);
    /// assert_eq!(map.occupancy([0.5, 0.0, 0.0]), Occupancy::Free);
    /// assert_eq!(map.occupancy([0.0, 1.0, 0.0]), Occupancy::Unknown);
    /// ```
    pub fn occupancy(&self, p: [f64; 3]) -> Occupancy {
        self.voxel_occupancy(self.key_of(p))
    }

    /// State of a voxel.
    pub fn voxel_occupancy(&self, k: VoxelKey) -> Occupancy {
        let (b, bit) = Self::split(k);
        match self.index.get(&b) {
            None => Occupancy::Unknown,
            Some(&i) => {
                let blk = &self.blocks[i as usize];
                if blk.known & (1 << bit) == 0 {
                    Occupancy::Unknown
                } else if blk.occupied & (1 << bit) != 0 {
                    Occupancy::Occupied
                } else {
                    Occupancy::Free
                }
            }
        }
    }

    /// Occupancy probability of a voxel, if known.
    pub fn probability(&self, k: VoxelKey) -> Option<f64> {
        let (b, bit) = Self::split(k);
        let blk = &self.blocks[*self.index.get(&b)? as usize];
        (blk.known & (1 << bit) != 0).then(|| {
            let l = blk.logodds(bit) as f64;
            1.0 - 1.0 / (1.0 + l.exp())
        })
    }

    /// Every known voxel with its state.
    pub fn known_voxels(&self) -> impl Iterator<Item = (VoxelKey, Occupancy)> + '_ {
        self.index.iter().flat_map(move |(b, &i)| {
            let blk = &self.blocks[i as usize];
            bits(blk.known).map(move |bit| {
                let k = voxel_key(*b, bit);
                let state = if blk.occupied & (1 << bit) != 0 {
                    Occupancy::Occupied
                } else {
                    Occupancy::Free
                };
                (k, state)
            })
        })
    }

    /// Centres of all occupied voxels, metres.
    pub fn occupied_voxels(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        self.known_voxels()
            .filter(|(_, s)| *s == Occupancy::Occupied)
            .map(|(k, _)| self.voxel_center(k))
    }

    /// All octoboxes with at least one occupied leaf.
    pub fn octoboxes(&self) -> impl Iterator<Item = Octobox> + '_ {
        self.index.iter().filter_map(move |(b, &i)| {
            let mask = self.blocks[i as usize].occupied;
            (mask != 0).then_some(Octobox { key: *b, mask })
        })
    }

    /// The octobox with key `k` (mask 0 when unknown or empty).
    pub fn octobox(&self, k: BlockKey) -> u64 {
        self.index
            .get(&k)
            .map(|&i| self.blocks[i as usize].occupied)
            .unwrap_or(0)
    }

    /// Number of stored blocks.
    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    /// Approximate heap memory in bytes.
    pub fn memory_bytes(&self) -> usize {
        let per_block = std::mem::size_of::<Block>();
        let leaves: usize = self
            .blocks
            .iter()
            .map(|b| match b.leaves {
                Leaves::Each(_) => 256,
                Leaves::Uniform(_) => 0,
            })
            .sum();
        self.blocks.chunks.len() * CHUNK * per_block
            + leaves
            + self.index.capacity() * (std::mem::size_of::<(BlockKey, u32)>() + 1)
    }

    /// True when a ball at `c` with radius `r` overlaps an occupied voxel (as a cube): the
    /// clearance grid first, the voxels near the ball when it cannot tell.
    #[inline]
    pub fn sphere_collides(&self, c: [f64; 3], r: f64) -> bool {
        if self.coarse.is_empty() {
            return false;
        }
        self.sphere_collides_in(self.clearance(), c, r)
    }

    /// [`OccupancyMap::sphere_collides`] with the map's clearance grid already at hand
    /// (`grid`, from [`OccupancyMap::clearance`]), as the batch checker holds it.
    #[inline]
    pub(crate) fn sphere_collides_in(&self, grid: Option<&Clearance>, c: [f64; 3], r: f64) -> bool {
        match grid.and_then(|g| g.decide(c, r)) {
            Some(touches) => touches,
            None => self.sphere_touches_voxels(c, r),
        }
    }

    /// [`OccupancyMap::sphere_collides`] without the grid: the voxels near the ball, one by one.
    pub fn sphere_touches_voxels(&self, c: [f64; 3], r: f64) -> bool {
        self.any_occupied_in(
            [c[0] - r, c[1] - r, c[2] - r],
            [c[0] + r, c[1] + r, c[2] + r],
            |v| self.voxel_gap2(c, v) < r * r,
        )
    }

    /// Squared distance from `p` to the cube of the voxel centred at `v` (0 inside it).
    #[inline]
    pub fn voxel_gap2(&self, p: [f64; 3], v: [f64; 3]) -> f64 {
        let half = self.params.resolution / 2.0;
        let d = [0, 1, 2].map(|a| ((p[a] - v[a]).abs() - half).max(0.0));
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    }

    /// Calls `f` with the centre of each occupied voxel in the 4×4×4 blocks overlapping the box
    /// `[lo, hi]` until it returns true; returns whether it did. The coarse index skips empty
    /// regions.
    pub fn any_occupied_in(
        &self,
        lo: [f64; 3],
        hi: [f64; 3],
        mut f: impl FnMut([f64; 3]) -> bool,
    ) -> bool {
        let lo = self.key_of(lo).map(|v| v >> 2);
        let hi = self.key_of(hi).map(|v| v >> 2);
        self.occupied_blocks(lo, hi, |b, mask| {
            bits(mask).any(|bit| f(self.voxel_center(voxel_key(b, bit))))
        })
    }

    /// Calls `f` with the key and occupancy mask of each block in `[lo, hi]` (block keys) that
    /// holds an occupied voxel until it returns true; returns whether it did. The coarse index
    /// skips empty regions.
    pub(crate) fn occupied_blocks(
        &self,
        lo: BlockKey,
        hi: BlockKey,
        mut f: impl FnMut(BlockKey, u64) -> bool,
    ) -> bool {
        if self.coarse.is_empty() {
            return false;
        }
        for gx in (lo[0] >> 2)..=(hi[0] >> 2) {
            for gy in (lo[1] >> 2)..=(hi[1] >> 2) {
                for gz in (lo[2] >> 2)..=(hi[2] >> 2) {
                    if !self.coarse.contains_key(&[gx, gy, gz]) {
                        continue;
                    }
                    for bx in lo[0].max(gx * 4)..=hi[0].min(gx * 4 + 3) {
                        for by in lo[1].max(gy * 4)..=hi[1].min(gy * 4 + 3) {
                            for bz in lo[2].max(gz * 4)..=hi[2].min(gz * 4 + 3) {
                                let Some(&i) = self.index.get(&[bx, by, bz]) else {
                                    continue;
                                };
                                let mask = self.blocks[i as usize].occupied;
                                if mask != 0 && f([bx, by, bz], mask) {
                                    return true;
                                }
                            }
                        }
                    }
                }
            }
        }
        false
    }

    /// Keeps the coarse broad-phase counts when a block's mask goes between empty and not, and
    /// the clearance grids' list of changed blocks.
    pub(crate) fn note_mask_change(&mut self, b: BlockKey, before: u64, after: u64) {
        if before == after {
            return;
        }
        match self.clearance.take() {
            Some(Some(grids)) => self.stale = Some((grids, vec![b])),
            Some(None) => self.stale = None,
            None => {
                if let Some((_, changed)) = &mut self.stale {
                    changed.push(b);
                    if changed.len() > STALE_MAX {
                        self.stale = None;
                    }
                }
            }
        }
        let g = b.map(|v| v >> 2);
        match (before != 0, after != 0) {
            (false, true) => *self.coarse.entry(g).or_insert(0) += 1,
            (true, false) => {
                if let Some(n) = self.coarse.get_mut(&g) {
                    *n -= 1;
                    if *n == 0 {
                        self.coarse.remove(&g);
                    }
                }
            }
            _ => {}
        }
    }

    /// Marks free (clamped) every occupied voxel in the box `[lo, hi]` whose centre `inside`
    /// accepts: space a newly placed object fills, cleared at once rather than after many rays.
    /// Returns how many were cleared.
    pub fn clear_occupied(
        &mut self,
        lo: [f64; 3],
        hi: [f64; 3],
        inside: impl Fn([f64; 3]) -> bool,
    ) -> usize {
        let mut keys = Vec::new();
        self.any_occupied_in(lo, hi, |c| {
            if inside(c) {
                keys.push(self.key_of(c));
            }
            false
        });
        for &k in &keys {
            self.set_voxel(k, false);
        }
        keys.len()
    }

    /// The box `[lo, hi]` (metres) cut to the map's bounds; `None` when nothing of it is left
    /// (or a corner is not a number).
    pub fn clip_to_bounds(&self, lo: [f64; 3], hi: [f64; 3]) -> Option<([f64; 3], [f64; 3])> {
        let (mut lo, mut hi) = (lo, hi);
        if let Some((blo, bhi)) = self.params.bounds {
            for a in 0..3 {
                lo[a] = lo[a].max(blo[a]);
                hi[a] = hi[a].min(bhi[a]);
            }
        }
        (0..3).all(|a| lo[a] <= hi[a]).then_some((lo, hi))
    }

    /// The keys `[klo, khi]` of the voxels whose centre lies in the box `[lo, hi]` (metres)
    /// cut to the map's bounds; `None` when there are none.
    fn keys_centred_in(&self, lo: [f64; 3], hi: [f64; 3]) -> Option<(VoxelKey, VoxelKey)> {
        let (lo, hi) = self.clip_to_bounds(lo, hi)?;
        let half = self.params.resolution / 2.0;
        let klo = self.key_of(lo.map(|v| v - half + self.params.resolution));
        let khi = self.key_of(hi.map(|v| v - half));
        (0..3).all(|a| klo[a] <= khi[a]).then_some((klo, khi))
    }

    /// A copy of the map in which every voxel never observed whose centre lies in the box
    /// `[lo, hi]` (metres, within the map's bounds) is occupied: the map planning avoids when
    /// unknown space there counts as an obstacle. The copy shares the blocks it does not
    /// write, and its clearance grids follow from this map's by the blocks it changed.
    pub fn with_unknown_occupied(&self, lo: [f64; 3], hi: [f64; 3]) -> OccupancyMap {
        let mut out = self.clone();
        if let Some((klo, khi)) = self.keys_centred_in(lo, hi) {
            self.unknown_leaves(klo, khi, |b, unknown| out.set_leaves(b, unknown, self.max));
        }
        out
    }

    /// Calls `f` with each block meeting the voxel keys `[klo, khi]` and the mask of its leaves
    /// in that range never observed, where there are any.
    fn unknown_leaves(&self, klo: VoxelKey, khi: VoxelKey, mut f: impl FnMut(BlockKey, u64)) {
        let (blo, bhi) = (klo.map(|v| v >> 2), khi.map(|v| v >> 2));
        for bx in blo[0]..=bhi[0] {
            for by in blo[1]..=bhi[1] {
                for bz in blo[2]..=bhi[2] {
                    let b = [bx, by, bz];
                    let known = self
                        .index
                        .get(&b)
                        .map_or(0, |&i| self.blocks[i as usize].known);
                    let unknown = leaves_within(b, klo, khi) & !known;
                    if unknown != 0 {
                        f(b, unknown);
                    }
                }
            }
        }
    }

    /// Observes free, as one ray through them would, the voxels of `blocks` (key and mask, as
    /// [`OccupancyMap::unknown_touched`] gives them); returns how many.
    pub fn observe_free(&mut self, blocks: &[(BlockKey, u64)]) -> usize {
        for &(b, mask) in blocks {
            self.set_leaves(b, mask, self.miss);
        }
        blocks.iter().map(|&(_, m)| m.count_ones() as usize).sum()
    }

    /// The voxels never observed whose centre lies in the box `[lo, hi]` and whose cube one of
    /// `balls` (centre, radius, metres) touches — space the robot fills, where nothing else can
    /// be — per block (its key and a mask of its voxels), each block once; empty when there are
    /// none. [`OccupancyMap::observe_free`] marks them.
    pub fn unknown_touched<'a>(
        &self,
        balls: impl IntoIterator<Item = &'a ([f64; 3], f64)>,
        lo: [f64; 3],
        hi: [f64; 3],
    ) -> Vec<(BlockKey, u64)> {
        let Some((klo, khi)) = self.keys_centred_in(lo, hi) else {
            return Vec::new();
        };
        let mut touched: Vec<(BlockKey, u64)> = Vec::new();
        for &(c, r) in balls {
            // The voxels of the ball's box, within the box's.
            let (vlo, vhi) = (self.key_of(c.map(|v| v - r)), self.key_of(c.map(|v| v + r)));
            let vlo: VoxelKey = std::array::from_fn(|a| vlo[a].max(klo[a]));
            let vhi: VoxelKey = std::array::from_fn(|a| vhi[a].min(khi[a]));
            if (0..3).any(|a| vlo[a] > vhi[a]) {
                continue;
            }
            self.unknown_leaves(vlo, vhi, |b, unknown| {
                let mask = bits(unknown)
                    .filter(|&bit| {
                        self.voxel_gap2(c, self.voxel_center(voxel_key(b, bit))) <= r * r
                    })
                    .fold(0u64, |m, bit| m | 1 << bit);
                if mask != 0 {
                    touched.push((b, mask));
                }
            });
        }
        // Neighbouring balls touch the same blocks: one entry per block.
        touched.sort_unstable_by_key(|&(b, _)| b);
        touched.dedup_by(|next, kept| {
            let same = next.0 == kept.0;
            if same {
                kept.1 |= next.1;
            }
            same
        });
        touched
    }

    /// Sets a voxel to `occupied` (clamped log-odds), as reading a binary map does.
    pub fn set_voxel(&mut self, k: VoxelKey, occupied: bool) {
        let v = if occupied { self.max } else { self.min };
        self.set_logodds(k, v);
    }

    fn set_logodds(&mut self, k: VoxelKey, v: f32) {
        let (b, bit) = Self::split(k);
        self.set_leaves(b, 1 << bit, v);
    }

    /// Sets the leaves `mask` of block `b` (created when missing) to log-odds `v`, known.
    fn set_leaves(&mut self, b: BlockKey, mask: u64, v: f32) {
        let threshold = self.threshold;
        let blk = self.block_mut(b);
        let before = blk.occupied;
        let leaves = blk.expand();
        for bit in bits(mask) {
            leaves[bit] = v;
        }
        blk.known |= mask;
        if v > threshold {
            blk.occupied |= mask;
        } else {
            blk.occupied &= !mask;
        }
        let after = blk.occupied;
        self.note_mask_change(b, before, after);
    }

    pub(crate) fn block_mut(&mut self, b: BlockKey) -> &mut Block {
        let i = self.block_index(b);
        self.blocks.get_mut(i)
    }

    /// Index of block `b`, created empty when missing.
    pub(crate) fn block_index(&mut self, b: BlockKey) -> u32 {
        match self.index.get(&b) {
            Some(&i) => i,
            None => {
                let i = self.blocks.push(Block::new(b));
                self.index.insert(b, i);
                i
            }
        }
    }

    /// Compacts blocks whose leaves are all known and equal.
    pub fn compact(&mut self) {
        for blk in self
            .blocks
            .chunks
            .iter_mut()
            .flat_map(|c| Arc::make_mut(c).iter_mut())
        {
            if let Leaves::Each(a) = &blk.leaves {
                if blk.known == u64::MAX && a.iter().all(|v| *v == a[0]) {
                    blk.leaves = Leaves::Uniform(a[0]);
                }
            }
        }
    }
}

impl Block {
    /// Per-leaf storage, expanding a uniform block.
    pub(crate) fn expand(&mut self) -> &mut [f32; 64] {
        if let Leaves::Uniform(v) = self.leaves {
            self.leaves = Leaves::Each(Box::new([v; 64]));
        }
        match &mut self.leaves {
            Leaves::Each(a) => a,
            Leaves::Uniform(_) => unreachable!("expanded above"),
        }
    }
}

/// `floor` for |v| < 2³¹, without a libm call or a saturating conversion: adding 1.5·2⁵² leaves
/// `v` rounded to the nearest integer in the low mantissa bits (larger values give meaningless
/// keys, never a panic).
#[inline]
pub(crate) fn fast_floor(v: f64) -> i32 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let t = (v + MAGIC).to_bits() as u32 as i32;
    t - ((t as f64) > v) as i32
}

/// The leaves of block `b` whose keys lie within `[klo, khi]` on every axis, as a mask.
fn leaves_within(b: BlockKey, klo: VoxelKey, khi: VoxelKey) -> u64 {
    // Per axis, the leaf offsets (0–3) inside the range.
    let span = |a: usize| (klo[a] - 4 * b[a]).max(0)..=(khi[a] - 4 * b[a]).min(3);
    let mut mask = 0u64;
    for x in span(0) {
        for y in span(1) {
            for z in span(2) {
                mask |= 1 << leaf_bit(x as usize, y as usize, z as usize);
            }
        }
    }
    mask
}

/// Indices of the set bits of `m`, ascending.
pub(crate) fn bits(mut m: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let b = m.trailing_zeros() as usize;
            m &= m - 1;
            b
        })
    })
}
