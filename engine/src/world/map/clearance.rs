//! Clearance: a dense grid of lower bounds on the distance to the nearest occupied voxel, so
//! most sphere queries against the map cost one array read instead of a walk over blocks.
//!
//! Two grids: the fine one's cells are the map's voxels, the coarse one's its 4×4×4 blocks
//! (reaching three times as far, for the links' and clusters' larger balls). Each cell holds
//! the exact Euclidean distance (a separable transform, in cell units) from its centre to the
//! nearest occupied cell's cube, rounded down to 1/16 of a cell and saturated at the grid's
//! padding. A ball at `p` (in cell `q`) with radius `r` is clear of every occupied cell cube
//! (and so of every occupied voxel) when `d(q) − |p − c(q)| ≥ r` (a distance to a set changes
//! no faster than the point moves), and surely touches one when `d(q) + |p − c(q)|` (plus the
//! rounding) is below `r`. A ball the centre's own cell cannot decide is asked of the eight
//! cells whose centres surround `p`, each giving the same two bounds.
//! The grid covers a box holding every occupied voxel (the cover) grown by the padding; farther
//! out the cover itself bounds the distance. A query the grid cannot decide is decided exactly by
//! the map ([`OccupancyMap::sphere_collides`](super::OccupancyMap::sphere_collides)). A few
//! boxes holding every occupied block ([`CoverBoxes`], [`Clearance::missed8`]) clear eight
//! balls at once without a read when they miss them all in every lane (the batch checker asks
//! them first for the links' bounds).
//!
//! Kept incrementally: as distances saturate at the padding, a change of occupancy alters only
//! cells within the padding of it, and those depend only on occupied cells within twice the
//! padding; [`Clearance::update`] recomputes just that much around the blocks a cloud changed
//! (growing the cover when occupied space appears past it). Cells live in bricks that copies
//! share, so a snapshot holding the grids costs the next update only the bricks it rewrites.

use super::cover::CoverBoxes;
use super::distance::{distance_transform, MAX_PAD};
use super::{BlockKey, OccupancyMap, VoxelKey};
use crate::collision::batch::lanes::{Mask8, F8, LANES};
use std::sync::Arc;

/// Distances are stored in these fractions of a cell where the padding allows (up to 15
/// cells: the default 2 cm and 1 cm voxels); a grid padded farther (finer voxels) stores
/// coarser fractions, so that one byte reaches its padding (see [`Level::steps`]).
const STEPS: f64 = 16.0;

/// A stored distance: one byte, so the grids are half as large in the caches.
type Cell = u8;

/// Slack of the `f32` queries, metres: far above their rounding at robot scale.
const F32_SLACK: f32 = 1e-5;

/// Slack of the `f64` queries, metres: far above their rounding.
const F64_SLACK: f64 = 1e-9;

/// Cell coordinates (in cells, on each axis) a grid stays within, so that they and any point
/// the batch checker reads them for are exact in `f32`; a map reaching farther is checked
/// exactly there.
const CELL_LIMIT: f32 = 4_194_304.0;

/// Largest grid built (cells, one byte each); a map spread wider gets none and is checked
/// exactly.
pub const MAX_CELLS: usize = 1 << 26;

/// The clearance grids of one map state (see the module docs): a fine one at the map's
/// resolution for the robot's spheres, and a coarse one over its 4×4×4 blocks, reaching farther,
/// for the links' and clusters' larger bounding balls.
#[derive(Debug, Clone)]
pub struct Clearance {
    fine: Level,
    coarse: Level,
    /// Balls at most this large (metres) are asked of the fine grid.
    fine_radius: f64,
    /// Blocks `[lo, hi]` holding every occupied voxel; the grids cover them grown by their
    /// padding.
    cover: (BlockKey, BlockKey),
    /// The cover's box, metres.
    occupied_lo: [f64; 3],
    occupied_hi: [f64; 3],
    /// The same in `f32`, rounded outwards.
    occupied_lo32: [f32; 3],
    occupied_hi32: [f32; 3],
    /// A few boxes holding every occupied block ([`Clearance::missed8`]).
    boxes: CoverBoxes,
}

/// One grid: cells of edge `res` holding distances to the nearest occupied cell, stored in
/// bricks of `BRICK`³ cells that copies share (a copy of the grids copies no cell; an update
/// copies only the bricks it writes, and bricks far from everything share one saturated brick).
#[derive(Debug, Clone)]
struct Level {
    res: f64,
    inv_res: f64,
    /// Key of cell `[0, 0, 0]` (a multiple of `BRICK` on each axis).
    lo: VoxelKey,
    /// Cells per axis (multiples of `BRICK`).
    dims: [usize; 3],
    /// Bricks per axis.
    bdims: [usize; 3],
    /// Per brick (`z` fastest, then `y`, then `x`), per cell likewise: distance in 1/16 cells,
    /// saturated.
    bricks: Vec<Arc<Brick>>,
    /// The brick every cell of which is saturated.
    far: Arc<Brick>,
    /// Half diagonal of a cell, metres.
    half_diagonal: f64,
    /// Stored units per cell: [`STEPS`], or fewer where the padding is more than a byte of
    /// sixteenths holds.
    steps: f64,
    /// Padding in cells: distances saturate here, and the grid reaches this far past the cover.
    pad: i32,
    /// The figures [`Clearance::unclear8`] needs, in `f32`.
    lanes: LaneGrid,
}

/// A grid's placement in `f32`, for queries in eight lanes.
#[derive(Debug, Clone, Copy, Default)]
struct LaneGrid {
    res: f32,
    inv_res: f32,
    /// The first and last cell on each axis.
    lo: [f32; 3],
    last: [f32; 3],
    bdims: [u32; 3],
    /// A stored unit, metres.
    step: f32,
    /// The queries' slack, metres.
    reach: f32,
}

/// Edge of a brick, cells.
const BRICK: usize = 8;
const BRICK_BITS: u32 = 3;
type Brick = [Cell; BRICK * BRICK * BRICK];

/// The coarse grid reaches this many times the fine grid's padding.
const COARSE_REACH: f64 = 3.0;

/// When occupied space appears outside the cover, the cover grows this many blocks past it, so
/// a map growing at its edge does not regrow the grids every cloud.
const GROW_SLACK: i32 = 4;

/// Dirty regions are gathered per tile of this many blocks along each axis.
const TILE_BLOCKS: i32 = 8;

impl Clearance {
    /// The grids of `map`, the fine one padded by `pad` metres around its occupied voxels;
    /// `None` when the map has no occupied voxel or a grid would exceed [`MAX_CELLS`].
    pub fn of(map: &OccupancyMap, pad: f64) -> Option<Self> {
        let mut cover: Option<(BlockKey, BlockKey)> = None;
        let mut occupied = Vec::new();
        for (b, &i) in &map.index {
            if map.blocks[i as usize].occupied != 0 {
                occupied.push(*b);
                let (lo, hi) = cover.get_or_insert((*b, *b));
                for a in 0..3 {
                    lo[a] = lo[a].min(b[a]);
                    hi[a] = hi[a].max(b[a]);
                }
            }
        }
        let cover = cover?;
        let res = map.resolution();
        let boxes = CoverBoxes::around(&mut occupied, 4.0 * res);
        let fine = Level::empty(
            res,
            pad,
            (cover.0.map(|v| 4 * v), cover.1.map(|v| 4 * v + 3)),
        )?;
        let coarse = Level::empty(4.0 * res, COARSE_REACH * pad, cover)?;
        let mut c = Clearance {
            // Balls the fine grid can clear: within its saturation.
            fine_radius: (fine.cap() as f64 * fine.unit()).min(pad) - fine.half_diagonal,
            fine,
            coarse,
            cover,
            occupied_lo: [0.0; 3],
            occupied_hi: [0.0; 3],
            occupied_lo32: [0.0; 3],
            occupied_hi32: [0.0; 3],
            boxes,
        };
        c.set_cover(cover, res);
        c.recompute(map, cover);
        Some(c)
    }

    fn set_cover(&mut self, cover: (BlockKey, BlockKey), res: f64) {
        self.cover = cover;
        self.occupied_lo = cover.0.map(|v| (4 * v) as f64 * res);
        self.occupied_hi = cover.1.map(|v| (4 * v + 4) as f64 * res);
        self.occupied_lo32 = self.occupied_lo.map(|v| (v as f32).next_down());
        self.occupied_hi32 = self.occupied_hi.map(|v| (v as f32).next_up());
    }

    /// Recomputes both grids around the blocks `[lo, hi]` (as far as their padding reaches).
    fn recompute(&mut self, map: &OccupancyMap, (lo, hi): (BlockKey, BlockKey)) {
        let mut keys = Vec::new();
        self.fine.recompute(
            (lo.map(|v| 4 * v), hi.map(|v| 4 * v + 3)),
            &mut keys,
            |(wlo, whi), keys| {
                map.occupied_blocks(wlo.map(|v| v >> 2), whi.map(|v| v >> 2), |b, mask| {
                    for bit in super::bits(mask) {
                        let k = super::voxel_key(b, bit);
                        if (0..3).all(|a| wlo[a] <= k[a] && k[a] <= whi[a]) {
                            keys.push(k);
                        }
                    }
                    false
                });
            },
        );
        self.coarse
            .recompute((lo, hi), &mut keys, |(wlo, whi), keys| {
                map.occupied_blocks(wlo, whi, |b, _| {
                    keys.push(b);
                    false
                });
            });
    }

    /// Brings the grids up to date with `map` after the occupancy masks of the blocks `changed`
    /// changed, recomputing only around them (growing the grids when occupied space appears
    /// past their cover). False, leaving the grids unusable, when that would exceed
    /// [`MAX_CELLS`]; the caller builds anew.
    pub(crate) fn update(&mut self, map: &OccupancyMap, changed: &[BlockKey]) -> bool {
        let (mut lo, mut hi) = self.cover;
        for b in changed {
            if map.octobox(*b) != 0 {
                self.boxes.hold(*b);
                for a in 0..3 {
                    if b[a] < lo[a] {
                        lo[a] = b[a] - GROW_SLACK;
                    }
                    if b[a] > hi[a] {
                        hi[a] = b[a] + GROW_SLACK;
                    }
                }
            }
        }
        if (lo, hi) != self.cover {
            let fine = (lo.map(|v| 4 * v), hi.map(|v| 4 * v + 3));
            if !self.fine.grow(fine) || !self.coarse.grow((lo, hi)) {
                return false;
            }
            self.set_cover((lo, hi), map.resolution());
        }
        // Recompute around the changed blocks' bounding box per tile, or around their one
        // bounding box, or everything: whichever transforms the fewest cells.
        let mut tiles: rustc_hash::FxHashMap<BlockKey, (BlockKey, BlockKey)> = Default::default();
        let Some(&first) = changed.first() else {
            return true;
        };
        let mut all = (first, first);
        for b in changed {
            for (lo, hi) in [
                tiles
                    .entry(b.map(|v| v.div_euclid(TILE_BLOCKS)))
                    .or_insert((*b, *b)),
                &mut all,
            ] {
                for a in 0..3 {
                    lo[a] = lo[a].min(b[a]);
                    hi[a] = hi[a].max(b[a]);
                }
            }
        }
        let window = |(lo, hi): &(BlockKey, BlockKey)| -> usize {
            (0..3)
                .map(|a| (4 * (hi[a] - lo[a] + 1) + 4 * self.fine.pad) as usize)
                .product()
        };
        let per_tile: usize = tiles.values().map(window).sum();
        let one = window(&all);
        if one.min(per_tile) > self.fine.len() {
            self.recompute(map, self.cover);
        } else if one <= per_tile {
            self.recompute(map, all);
        } else {
            for region in tiles.into_values() {
                self.recompute(map, region);
            }
        }
        true
    }

    /// True when a ball at `p` with radius `r` surely touches no occupied voxel; false means
    /// it may (the map decides). A centre with a NaN coordinate is never clear.
    #[inline]
    pub fn clear(&self, p: [f64; 3], r: f64) -> bool {
        self.decide(p, r) == Some(false)
    }

    /// Whether a ball at `p` with radius `r` touches an occupied voxel, when the grids can
    /// tell: `Some(false)` when it surely touches none ([`Clearance::clear`]), `Some(true)` when
    /// it surely touches one (the fine grid's distance plus the ball's offset from the cell
    /// centre, and the stored rounding, fall short of `r`), `None` when the voxels must decide.
    #[inline]
    pub fn decide(&self, p: [f64; 3], r: f64) -> Option<bool> {
        let fine = r <= self.fine_radius;
        let level = if fine { &self.fine } else { &self.coarse };
        match level.bounds(p) {
            Some((d, off)) => {
                if d - off >= r + F64_SLACK {
                    Some(false)
                } else if !fine {
                    None
                } else if d + off + level.unit() + F64_SLACK < r {
                    Some(true)
                } else {
                    self.refine(p, r)
                }
            }
            None => {
                // Beyond the padding: the occupied box bounds the distance. (A NaN coordinate
                // makes the sum NaN: `d.max(0.0)` would drop it.)
                let d2: f64 = (0..3)
                    .map(|a| {
                        let d = (self.occupied_lo[a] - p[a]).max(p[a] - self.occupied_hi[a]);
                        if d <= 0.0 {
                            0.0
                        } else {
                            d * d
                        }
                    })
                    .sum();
                (d2 >= r * r).then_some(false)
            }
        }
    }

    /// [`Clearance::decide`] for a ball its centre's own cell could not decide: the eight cells
    /// whose centres surround `p` bound the distance tighter (the fine grid only; `None` for
    /// larger balls, or when the voxels must decide).
    #[inline]
    pub fn refine(&self, p: [f64; 3], r: f64) -> Option<bool> {
        if r <= self.fine_radius {
            self.fine.bracket(p, r)
        } else {
            None
        }
    }

    /// Of the lanes in `lanes` (bits), those whose ball (centres `p`, radius `r`) the grids
    /// cannot clear: the batch checker's form of [`Clearance::clear`], in `f32` with a hair
    /// of slack.
    ///
    /// Written in whole-lane operations, so that inside the batch checker's AVX2 code the
    /// cells, their bricks and the offsets are a few vector instructions for all eight lanes
    /// (computed for every lane, clamped into the grid, so no lane branches); only the stored
    /// distances are read lane by lane. A lane outside the grid is decided, in the same vector
    /// operations, by its distance to the box holding every occupied voxel, as
    /// [`Clearance::clear`] decides it (a lane that is not a number stays unclear).
    #[inline(always)]
    pub fn unclear8(&self, p: [F8; 3], r: f32, lanes: u32) -> u32 {
        self.unclear8_within(p, r, lanes).0
    }

    /// True when the balls (centres `p` in eight lanes, radius `r`) miss, in every lane, each of
    /// the few boxes that hold every occupied block (see the module docs): clear without a
    /// read. False when a lane is not a number.
    #[inline(always)]
    pub fn missed8(&self, p: [F8; 3], r: f32) -> bool {
        self.boxes.missed8(p, r)
    }

    /// [`Clearance::unclear8`], with a lower bound per lane on the distance (metres) from the
    /// lane's centre to the occupied voxels, from the same read (minus the queries' slack;
    /// zero in a lane the grids do not hold). A distance to a set changes no faster than the
    /// point moves, so a ball of radius `ρ` whose centre lies within `δ` of `p` is clear in
    /// the lanes whose bound is at least `δ + ρ`: the balls a larger one holds (a cluster's
    /// spheres, a link's clusters) are cleared there without reading the grids again.
    #[inline(always)]
    pub fn unclear8_within(&self, p: [F8; 3], r: f32, lanes: u32) -> (u32, F8) {
        self.test8::<false>(p, r, lanes)
            .unwrap_or((lanes, F8::splat(0.0)))
    }

    /// [`Clearance::unclear8`] for balls of the robot's geometry, which also confirms
    /// contacts: `None` when the ball surely touches an occupied voxel in some lane of
    /// `lanes`. From the same read: the cube of the occupied voxel nearest the cell centre is
    /// nearer to the ball's centre than the cell's distance (rounded down, so plus one stored
    /// unit) and the centre's offset from the cell centre, so a ball larger than that reaches
    /// it. (The fine grid only: a coarse cell is a block, whose occupied voxel may lie anywhere
    /// in it.)
    #[inline(always)]
    pub fn sphere8(&self, p: [F8; 3], r: f32, lanes: u32) -> Option<u32> {
        self.test8::<true>(p, r, lanes).map(|(unclear, _)| unclear)
    }

    /// The unclear lanes and the lanes' lower bounds (see [`Clearance::unclear8_within`]),
    /// or `None` for a confirmed contact (only with `CONFIRM`).
    #[inline(always)]
    fn test8<const CONFIRM: bool>(&self, p: [F8; 3], r: f32, lanes: u32) -> Option<(u32, F8)> {
        let fine = f64::from(r) <= self.fine_radius;
        let g = if fine { &self.fine } else { &self.coarse };
        let l = &g.lanes;
        let res = F8::splat(l.res);
        let inv = F8::splat(l.inv_res);
        let zero = F8::splat(0.0);
        let mut brick = [0u32; LANES];
        let mut within = [0u32; LANES];
        let mut off2 = zero;
        let mut inside = None;
        for (a, &pa) in p.iter().enumerate() {
            let x = pa * inv;
            let f = x.floor();
            // Cell coordinates are exact in `f32`: the grid lies within `CELL_LIMIT`, so a lane
            // whose cell falls in it has `|x|` below that too (farther out, `f − lo` lies past
            // either end however it rounds; a NaN or an infinity compares false or past them).
            let c = f - F8::splat(l.lo[a]);
            let last = F8::splat(l.last[a]);
            let ok = zero.le(c) & c.le(last);
            inside = Some(inside.map_or(ok, |m| m & ok));
            // Whole numbers below 2²⁰ (MAX_CELLS / 64: the other two axes hold a brick each).
            let k = c.max(zero).min(last).small_uints();
            for i in 0..LANES {
                brick[i] = brick[i] * l.bdims[a] + (k[i] >> BRICK_BITS);
                within[i] = (within[i] << BRICK_BITS) | (k[i] & (BRICK as u32 - 1));
            }
            let o = pa - (f + F8::splat(0.5)) * res;
            off2 = o.mul_add(o, off2);
        }
        // A loop, not `array::from_fn`: its closure was left uninlined in the batch checker.
        let mut d = [0.0f32; LANES];
        for i in 0..LANES {
            // SAFETY: each axis' cell was clamped to `[0, last]`, so its brick lies within
            // `bdims`, and the bricks are as many as `bdims` holds (both set in
            // `Level::grow`). The place in the brick is masked, so it needs no check.
            let brick = unsafe { g.bricks.get_unchecked(brick[i] as usize) };
            d[i] = f32::from(brick[within[i] as usize & (BRICK * BRICK * BRICK - 1)]);
        }
        let d = F8(d);
        let need = F8::splat(r + l.reach);
        let d = d * F8::splat(l.step);
        let off = off2.sqrt();
        // Not `<`: a lane with a NaN stays unclear.
        let clear = need.le(d - off);
        let inside = inside.expect("three axes");
        let asked = Mask8::from_bits(lanes);
        if CONFIRM && fine {
            let touch = (d + off + F8::splat(l.step + F32_SLACK)).le(F8::splat(r));
            if (touch & asked & inside).any() {
                return None;
            }
        }
        let unclear = (asked & inside).and_not(clear);
        let outside = asked.and_not(inside);
        if !(unclear.any() || outside.any()) {
            return Some((0, zero));
        }
        let below = F8::select(inside, d - off - F8::splat(F32_SLACK), zero);
        let out = unclear.bits();
        let outside = outside.bits();
        if outside == 0 {
            return Some((out, below));
        }
        Some((out | (outside & !self.beyond8(p, r)), below))
    }

    /// The lanes (bits) whose ball (centres `p`, radius `r`) surely misses the box holding
    /// every occupied voxel: what bounds the distance beyond the grids. A lane with a NaN
    /// coordinate is never among them.
    #[inline(always)]
    fn beyond8(&self, p: [F8; 3], r: f32) -> u32 {
        let zero = F8::splat(0.0);
        let mut d2 = zero;
        let mut number: Option<Mask8> = None;
        for (a, &pa) in p.iter().enumerate() {
            let gap = (F8::splat(self.occupied_lo32[a]) - pa)
                .max(pa - F8::splat(self.occupied_hi32[a]))
                .max(zero);
            d2 = gap.mul_add(gap, d2);
            let n = pa.le(pa);
            number = Some(number.map_or(n, |m| m & n));
        }
        let need = r + F32_SLACK;
        (F8::splat(need * need).le(d2) & number.expect("three axes")).bits()
    }

    /// Cells in the grids.
    pub fn cells(&self) -> usize {
        self.fine.len() + self.coarse.len()
    }
}

impl Level {
    /// A grid of cells of edge `res` over the cells `[lo, hi]` grown by `pad` metres, every
    /// cell saturated; `None` past [`MAX_CELLS`].
    fn empty(res: f64, pad: f64, (lo, hi): (VoxelKey, VoxelKey)) -> Option<Self> {
        let pad = (pad / res).ceil().clamp(1.0, MAX_PAD as f64);
        // As fine as one byte allows up to the padding.
        let steps = (Cell::MAX as f64 / pad).floor().min(STEPS);
        let cap = (pad * steps) as Cell;
        let pad = pad as i32;
        let mut level = Level {
            res,
            inv_res: 1.0 / res,
            lo: [0; 3],
            dims: [0; 3],
            bdims: [0; 3],
            bricks: Vec::new(),
            far: Arc::new([cap; BRICK * BRICK * BRICK]),
            half_diagonal: res * 3f64.sqrt() / 2.0,
            steps,
            pad,
            lanes: LaneGrid::default(),
        };
        level.grow((lo, hi)).then_some(level)
    }

    /// Saturated distance in stored units.
    fn cap(&self) -> Cell {
        self.far[0]
    }

    /// A stored unit, metres.
    fn unit(&self) -> f64 {
        self.res / self.steps
    }

    /// Cells in the grid.
    fn len(&self) -> usize {
        self.dims.iter().product()
    }

    /// The brick holding cell `c` (grid coordinates) and the cell's place in it.
    #[inline(always)]
    fn locate(&self, c: [usize; 3]) -> (usize, usize) {
        let b = c.map(|v| v >> BRICK_BITS);
        let i = c.map(|v| v & (BRICK - 1));
        (
            (b[0] * self.bdims[1] + b[1]) * self.bdims[2] + b[2],
            (((i[0] << BRICK_BITS) | i[1]) << BRICK_BITS) | i[2],
        )
    }

    /// The stored value of cell `c` (grid coordinates, inside the grid).
    #[inline(always)]
    fn get(&self, c: [usize; 3]) -> Cell {
        let (b, i) = self.locate(c);
        self.bricks[b][i]
    }

    /// Regrows the grid to the cover `[lo, hi]` (cells), keeping the cells it had; the new
    /// ones are saturated, as they are farther than the padding from every occupied cell the
    /// grid knew. False past [`MAX_CELLS`].
    fn grow(&mut self, (lo, hi): (VoxelKey, VoxelKey)) -> bool {
        let b = BRICK as i32;
        let new_lo = lo.map(|v| (v - self.pad).div_euclid(b) * b);
        let bdims =
            [0, 1, 2].map(|a| ((hi[a] + self.pad).div_euclid(b) - new_lo[a] / b + 1) as usize);
        let dims = bdims.map(|d| d * BRICK);
        let limit = CELL_LIMIT as i64;
        let within = (0..3).all(|a| {
            (new_lo[a] as i64).abs() < limit && (new_lo[a] as i64 + dims[a] as i64) < limit
        });
        match dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d)) {
            Some(n) if n <= MAX_CELLS && within => {
                let mut bricks = vec![self.far.clone(); bdims.iter().product()];
                let off = [0, 1, 2].map(|a| ((self.lo[a] - new_lo[a]) / b) as usize);
                for x in 0..self.bdims[0] {
                    for y in 0..self.bdims[1] {
                        for z in 0..self.bdims[2] {
                            let from = (x * self.bdims[1] + y) * self.bdims[2] + z;
                            let to = ((x + off[0]) * bdims[1] + y + off[1]) * bdims[2] + z + off[2];
                            bricks[to] = self.bricks[from].clone();
                        }
                    }
                }
                self.lo = new_lo;
                self.dims = dims;
                self.bdims = bdims;
                self.bricks = bricks;
                self.lanes = LaneGrid {
                    res: self.res as f32,
                    inv_res: self.inv_res as f32,
                    lo: new_lo.map(|v| v as f32),
                    last: dims.map(|d| (d - 1) as f32),
                    bdims: bdims.map(|d| d as u32),
                    step: self.unit() as f32,
                    reach: F32_SLACK,
                };
                true
            }
            _ => false,
        }
    }

    /// Recomputes the cells within the padding of the cells `[lo, hi]`: a transform over that
    /// region grown by the padding again (every occupied cell that can bring a region cell under
    /// the padding lies in it), whose occupied cells `seeds` pushes onto `keys`.
    fn recompute(
        &mut self,
        (lo, hi): (VoxelKey, VoxelKey),
        keys: &mut Vec<VoxelKey>,
        seeds: impl FnOnce((VoxelKey, VoxelKey), &mut Vec<VoxelKey>),
    ) {
        let glo = self.lo;
        let ghi = [0, 1, 2].map(|a| glo[a] + self.dims[a] as i32 - 1);
        let clip = |k: VoxelKey, by: i32| -> (VoxelKey, VoxelKey) {
            (
                [0, 1, 2].map(|a| (k[a] - by).max(glo[a])),
                [0, 1, 2].map(|a| (k[a] + by).min(ghi[a])),
            )
        };
        let (rlo, _) = clip(lo, self.pad);
        let (_, rhi) = clip(hi, self.pad);
        if (0..3).any(|a| rlo[a] > rhi[a]) {
            return;
        }
        let (wlo, _) = clip(rlo, self.pad);
        let (_, whi) = clip(rhi, self.pad);
        keys.clear();
        seeds((wlo, whi), keys);
        let wdims = [0, 1, 2].map(|a| (whi[a] - wlo[a] + 1) as usize);
        let cap = self.cap();
        let d = distance_transform(keys, wlo, wdims, self.pad, self.steps, cap);
        // Brick by brick over the region.
        let (clo, chi) = (
            [0, 1, 2].map(|a| (rlo[a] - glo[a]) as usize),
            [0, 1, 2].map(|a| (rhi[a] - glo[a]) as usize),
        );
        let (blo, bhi) = (clo.map(|v| v / BRICK), chi.map(|v| v / BRICK));
        let woff = [0, 1, 2].map(|a| (glo[a] - wlo[a]) as isize);
        let window = |c: [usize; 3]| -> usize {
            let w = [0, 1, 2].map(|a| (c[a] as isize + woff[a]) as usize);
            (w[0] * wdims[1] + w[1]) * wdims[2] + w[2]
        };
        for bx in blo[0]..=bhi[0] {
            for by in blo[1]..=bhi[1] {
                for bz in blo[2]..=bhi[2] {
                    let b = [bx, by, bz];
                    let lo = [0, 1, 2].map(|a| clo[a].max(b[a] * BRICK));
                    let hi = [0, 1, 2].map(|a| chi[a].min(b[a] * BRICK + BRICK - 1));
                    let at = (bx * self.bdims[1] + by) * self.bdims[2] + bz;
                    let whole = (0..3).all(|a| lo[a] == b[a] * BRICK && hi[a] == lo[a] + BRICK - 1);
                    let all_far = (lo[0]..=hi[0]).all(|x| {
                        (lo[1]..=hi[1]).all(|y| {
                            let from = window([x, y, lo[2]]);
                            d[from..=from + hi[2] - lo[2]].iter().all(|&v| v == cap)
                        })
                    });
                    if all_far && (whole || Arc::ptr_eq(&self.bricks[at], &self.far)) {
                        self.bricks[at] = self.far.clone();
                        continue;
                    }
                    let brick = Arc::make_mut(&mut self.bricks[at]);
                    for x in lo[0]..=hi[0] {
                        for y in lo[1]..=hi[1] {
                            let from = window([x, y, lo[2]]);
                            let to = ((((x & (BRICK - 1)) << BRICK_BITS) | (y & (BRICK - 1)))
                                << BRICK_BITS)
                                | (lo[2] & (BRICK - 1));
                            let run = hi[2] - lo[2] + 1;
                            brick[to..to + run].copy_from_slice(&d[from..from + run]);
                        }
                    }
                }
            }
        }
    }

    /// The stored distance of `p`'s cell to the nearest occupied cell's cube (rounded down)
    /// and `p`'s offset from the cell centre, metres (`None` outside the grid): the distance
    /// from `p` lies between their difference and their sum plus one stored unit.
    #[inline]
    fn bounds(&self, p: [f64; 3]) -> Option<(f64, f64)> {
        let k = p.map(|v| super::fast_floor(v * self.inv_res));
        let cell = [0, 1, 2].map(|a| k[a] as i64 - self.lo[a] as i64);
        if (0..3).any(|a| cell[a] < 0 || cell[a] >= self.dims[a] as i64) {
            return None;
        }
        let d = self.get(cell.map(|v| v as usize)) as f64 * self.unit();
        let off: f64 = (0..3)
            .map(|a| (p[a] - (k[a] as f64 + 0.5) * self.res).powi(2))
            .sum::<f64>()
            .sqrt();
        Some((d, off))
    }

    /// Whether a ball at `p` with radius `r` touches an occupied cell's cube, as the eight
    /// cells whose centres surround `p` can tell (`None` when they cannot, or one lies outside
    /// the grid). Each bounds the distance from `p` by its stored distance less `p`'s offset
    /// from its centre (below) and plus the offset and one stored unit (above); a cell on the
    /// far side of `p` from the obstacle gives a lower bound near the distance itself, where
    /// `p`'s own cell may lose up to its half diagonal. Compared squared, without roots.
    fn bracket(&self, p: [f64; 3], r: f64) -> Option<bool> {
        let step = self.unit();
        let k = p.map(|v| super::fast_floor(v * self.inv_res - 0.5));
        let cell = [0, 1, 2].map(|a| k[a] as i64 - self.lo[a] as i64);
        if (0..3).any(|a| cell[a] < 0 || cell[a] + 1 >= self.dims[a] as i64) {
            return None;
        }
        // Per axis, the squared offsets from the lower and the upper cell's centre.
        let sq = [0, 1, 2].map(|a| {
            let e = p[a] - (f64::from(k[a]) + 0.5) * self.res;
            [e * e, (e - self.res) * (e - self.res)]
        });
        for corner in 0..8 {
            let o = [corner >> 2, (corner >> 1) & 1, corner & 1];
            let d = f64::from(self.get([0, 1, 2].map(|a| cell[a] as usize + o[a]))) * step;
            let off2 = sq[0][o[0]] + sq[1][o[1]] + sq[2][o[2]];
            // Clear: d − off ≥ r (with slack); touching: d + off + step < r.
            let room = d - r - F64_SLACK;
            if room >= 0.0 && room * room >= off2 {
                return Some(false);
            }
            let short = r - F64_SLACK - d - step;
            if short > 0.0 && off2 < short * short {
                return Some(true);
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::batch::lanes::ALL_LANES;
    use crate::world::map::MapParams;
    use proptest::prelude::*;

    impl Level {
        /// The stored value of cell `k`, when in the grid.
        fn at(&self, k: VoxelKey) -> Option<Cell> {
            let c = [0, 1, 2].map(|a| k[a] - self.lo[a]);
            (0..3)
                .all(|a| c[a] >= 0 && (c[a] as usize) < self.dims[a])
                .then(|| self.get(c.map(|v| v as usize)))
        }

        /// Every cell's key and stored value.
        fn cells(&self) -> impl Iterator<Item = (VoxelKey, Cell)> + '_ {
            let d = self.dims;
            (0..d[0] * d[1] * d[2]).map(move |i| {
                let c = [i / (d[1] * d[2]), i / d[2] % d[1], i % d[2]];
                ([0, 1, 2].map(|a| c[a] as i32 + self.lo[a]), self.get(c))
            })
        }
    }

    /// Asserts that every cell of `g` holds the brute-force distance from its centre to the
    /// nearest cube of `voxels`, rounded down to its stored unit and saturated; returns how
    /// many cells are saturated.
    fn assert_brute_force(g: &Level, voxels: &[[i32; 3]]) -> usize {
        let mut saturated = 0;
        for (k, cell) in g.cells() {
            let gap = |d: i32| (f64::from(d.abs()) - 0.5).max(0.0);
            let d2 = voxels
                .iter()
                .map(|v| (0..3).map(|a| gap(v[a] - k[a]).powi(2)).sum::<f64>())
                .fold(f64::INFINITY, f64::min);
            let want = ((d2.sqrt() * g.steps).floor()).min(f64::from(g.cap())) as Cell;
            assert_eq!(cell, want, "cell {k:?}");
            saturated += usize::from(cell == g.cap());
        }
        saturated
    }

    fn map_of(voxels: &[[i32; 3]]) -> OccupancyMap {
        let mut map = OccupancyMap::new(MapParams::default());
        for &k in voxels {
            map.set_voxel(k, true);
        }
        map
    }

    #[test]
    fn a_lane_with_a_nan_centre_stays_unclear() {
        let c = Clearance::of(&map_of(&[[0, 0, 0]]), 0.2).unwrap();
        let far = F8::splat(5.0);
        let mut x = far;
        x.0[3] = f32::NAN;
        let mut y = far;
        y.0[5] = f32::NAN;
        assert_eq!(c.unclear8([x, y, far], 0.05, ALL_LANES), 1 << 3 | 1 << 5);
    }

    #[test]
    fn lanes_far_past_the_grid_are_cleared_by_the_occupied_box() {
        let map = map_of(&[[0, 0, 0]]);
        let c = Clearance::of(&map, 0.2).unwrap();
        let res = map.resolution() as f32;
        // Where `x / res` leaves the cell limit, `f32` floors, differences and infinities.
        let far = [
            CELL_LIMIT * res * 1.5,
            -CELL_LIMIT * res * 1.5,
            CELL_LIMIT * res * 4.0 + 0.5 * res,
            -CELL_LIMIT * res * 4.0 - 0.5 * res,
            1e30,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        let centre = map.voxel_center([0, 0, 0]).map(|v| v as f32);
        for axis in 0..3 {
            let p: [F8; 3] = std::array::from_fn(|a| {
                if a == axis {
                    F8(far)
                } else {
                    F8::splat(centre[a])
                }
            });
            assert_eq!(c.unclear8(p, 0.05, ALL_LANES), 0, "axis {axis}");
            // The occupied voxel's own lane stays unclear beside them.
            let mut p = p;
            p[axis].0[2] = centre[axis];
            assert_eq!(c.unclear8(p, 0.05, ALL_LANES), 1 << 2, "axis {axis}");
        }
    }

    #[test]
    fn a_ball_holding_an_occupied_voxel_is_confirmed() {
        let map = map_of(&[[0, 0, 0]]);
        let c = Clearance::of(&map, 0.2).unwrap();
        let p = map
            .voxel_center([0, 0, 0])
            .map(|v| F8::splat(v as f32 + 0.004));
        let res = map.resolution() as f32;
        assert_eq!(c.sphere8(p, 2.0 * res, 1 << 2), None);
        // Not in a lane not asked, nor by a ball that only grazes the voxel.
        assert_eq!(c.sphere8(p, 2.0 * res, 0), Some(0));
        assert!(c.sphere8(p, 0.4 * res, ALL_LANES).is_some());
        // The scalar query likewise.
        let q = map.voxel_center([0, 0, 0]).map(|v| v + 0.004);
        let res = f64::from(res);
        assert_eq!(c.decide(q, 2.0 * res), Some(true));
        assert_eq!(c.decide(q, 0.4 * res), None);
    }

    #[test]
    fn the_cells_around_a_centre_decide_balls_near_a_wall() {
        // A wall of voxels, and balls a few millimetres short of it or into it, whose centres
        // lie anywhere in their cells (2 cm): the centre's own cell decides under a quarter of
        // them, the eight around it about two thirds.
        let wall: Vec<[i32; 3]> = (-8..8)
            .flat_map(|y| (-8..8).map(move |z| [0, y, z]))
            .collect();
        let map = map_of(&wall);
        let c = Clearance::of(&map, 0.2).unwrap();
        let face = map.voxel_center([0, 0, 0])[0] + map.resolution() / 2.0;
        let (mut decided, mut asked) = (0, 0);
        for i in 0..200 {
            let t = f64::from(i) / 200.0;
            let p = [face + 0.03 + 0.02 * t, 0.013 * t, -0.017 * t];
            let d = p[0] - face;
            for r in [d - 0.003, d + 0.003] {
                asked += 1;
                if let Some(touches) = c.decide(p, r) {
                    assert_eq!(touches, r > d, "{p:?} r {r}");
                    decided += 1;
                }
            }
        }
        assert!(decided * 10 >= asked * 6, "{decided} of {asked} decided");
    }

    #[test]
    fn a_map_past_the_lane_limit_has_no_grid() {
        let far = CELL_LIMIT as i32;
        assert!(Clearance::of(&map_of(&[[far, 0, 0]]), 0.2).is_none());
        assert!(Clearance::of(&map_of(&[[far / 2, 0, 0]]), 0.2).is_some());
    }

    #[test]
    fn an_empty_map_has_no_grid() {
        assert!(Clearance::of(&map_of(&[]), 0.2).is_none());
    }

    #[test]
    fn cells_hold_the_distance_to_the_nearest_occupied_voxel() {
        let map = map_of(&[[0, 0, 0], [5, 0, 0]]);
        let c = Clearance::of(&map, 0.2).unwrap();
        let g = &c.fine;
        // Cell units, to the occupied cells' cubes (half a cell short of their centres along
        // each axis).
        let at = |k: [i32; 3]| g.at(k).unwrap() as f64 / STEPS;
        assert_eq!(at([0, 0, 0]), 0.0);
        assert_eq!(at([1, 0, 0]), 0.5);
        assert_eq!(at([2, 0, 0]), 1.5);
        assert_eq!(at([3, 0, 0]), 1.5);
        assert!((at([0, 3, 4]) - 18.5f64.sqrt()).abs() < 1.0 / STEPS);
        assert!((at([1, 1, 1]) - 0.75f64.sqrt()).abs() < 1.0 / STEPS);
    }

    /// Half-centimetre voxels with the default padding (30 cells, past the 15.9 a byte of
    /// sixteenths holds): the grid stores eighths, and its cells hold the brute-force
    /// distance, saturated at 30 cells.
    #[test]
    fn fine_voxels_pad_as_far_as_a_cell_stores() {
        let mut map = OccupancyMap::new(MapParams {
            resolution: 0.005,
            ..MapParams::default()
        });
        let voxels = [[0, 0, 0], [9, 2, -3], [-20, 0, 1]];
        for &k in &voxels {
            map.set_voxel(k, true);
        }
        let c = Clearance::of(&map, super::super::CLEARANCE_PAD).unwrap();
        let g = &c.fine;
        assert_eq!((g.pad, g.steps, g.cap()), (30, 8.0, 240));
        assert!(assert_brute_force(g, &voxels) > 0);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Whatever the grids decide (clear, or surely touching), the voxels decide alike.
        #[test]
        fn grid_verdicts_are_the_voxels_own(
            voxels in prop::collection::vec(prop::array::uniform3(-12i32..12), 1..40),
            queries in prop::collection::vec((prop::array::uniform3(-0.5f64..0.5), 0.0f64..0.3), 80),
        ) {
            let map = map_of(&voxels);
            let c = Clearance::of(&map, 0.1).unwrap();
            let mut decided = [0; 2];
            for (p, r) in queries {
                if let Some(touches) = c.decide(p, r) {
                    prop_assert_eq!(touches, map.sphere_touches_voxels(p, r), "{:?} r {}", p, r);
                    decided[touches as usize] += 1;
                }
                // Balls a little short of the nearest cube and a little into it (a millimetre
                // or more at the default 2 cm voxels): a bound loose by that much is caught.
                let d = voxels
                    .iter()
                    .map(|&k| map.voxel_gap2(p, map.voxel_center(k)))
                    .fold(f64::INFINITY, f64::min)
                    .sqrt();
                for r in [1.0, 2.0, 4.0, 8.0].iter().flat_map(|e| [d - e * 1e-3, d + e * 1e-3]) {
                    if let (true, Some(touches)) = (r > 0.0, c.decide(p, r)) {
                        prop_assert_eq!(touches, r > d, "{:?} r {} distance {}", p, r, d);
                    }
                }
            }
            prop_assert!(decided[0] > 0, "nothing cleared");
            // Every cell holds the brute-force distance to the cubes (rounded down, saturated).
            prop_assert_eq!(c.fine.cap(), 80);
            assert_brute_force(&c.fine, &voxels);
            // The grid is not vacuous: far or small balls are cleared.
            prop_assert!(c.clear([5.0, 5.0, 5.0], 0.1));
        }

        /// The lower bounds the eight-lane query gives in its unclear lanes are at most the
        /// distance to the nearest occupied voxel, and not vacuous: each lies within a cell's
        /// diagonal and a stored unit of it where the centre's cell holds an unsaturated distance.
        #[test]
        fn lower_bounds_lie_below_the_voxels(
            voxels in prop::collection::vec(prop::array::uniform3(-12i32..12), 1..40),
            centres in prop::collection::vec(prop::array::uniform3(-0.3f32..0.3), 8),
            r in 0.0f32..0.3,
        ) {
            let map = map_of(&voxels);
            let c = Clearance::of(&map, 0.2).unwrap();
            let p: [F8; 3] = std::array::from_fn(|a| F8(std::array::from_fn(|i| centres[i][a])));
            let (unclear, below) = c.unclear8_within(p, r, ALL_LANES);
            let g = if f64::from(r) <= c.fine_radius { &c.fine } else { &c.coarse };
            let slack = (2.0 * g.half_diagonal + g.unit()) as f32 + 1e-4;
            for i in (0..LANES).filter(|i| unclear >> i & 1 != 0) {
                let x = centres[i].map(f64::from);
                let d = voxels
                    .iter()
                    .map(|&k| map.voxel_gap2(x, map.voxel_center(k)))
                    .fold(f64::INFINITY, f64::min)
                    .sqrt() as f32;
                prop_assert!(below.0[i] <= d, "lane {} bound {} distance {}", i, below.0[i], d);
                let stored = g.bounds(x).map(|(s, _)| s);
                let unsaturated = stored.is_some_and(|s| s < f64::from(g.cap()) * g.unit());
                if std::ptr::eq(g, &c.fine) && unsaturated {
                    prop_assert!(below.0[i] >= d - slack, "lane {} bound {} distance {}", i, below.0[i], d);
                }
            }
        }

        /// The eight-lane query answers as the same test made lane by lane (the cell by a
        /// floor, then its stored distance less the centre's offset), lanes outside the grids
        /// included, whichever lanes are asked.
        #[test]
        fn eight_lanes_answer_as_each_lane_alone(
            voxels in prop::collection::vec(prop::array::uniform3(-12i32..12), 1..40),
            centres in prop::collection::vec(prop::array::uniform3(-0.6f32..0.6), 8),
            r in 0.0f32..0.3,
            lanes in 0u32..256,
        ) {
            let map = map_of(&voxels);
            let c = Clearance::of(&map, 0.2).unwrap();
            let p: [F8; 3] = std::array::from_fn(|a| F8(std::array::from_fn(|i| centres[i][a])));
            let g = if f64::from(r) <= c.fine_radius { &c.fine } else { &c.coarse };
            let (res, inv) = (g.res as f32, g.inv_res as f32);
            let mut want = 0;
            for i in (0..LANES).filter(|i| lanes >> i & 1 != 0) {
                let x = centres[i];
                let k = x.map(|v| (v * inv).floor() as i32);
                let cell = [0, 1, 2].map(|a| k[a].wrapping_sub(g.lo[a]) as u32 as usize);
                let clear = if (0..3).all(|a| cell[a] < g.dims[a]) {
                    let d = g.get(cell) as f32 * g.unit() as f32;
                    let o = [0, 1, 2].map(|a| x[a] - (k[a] as f32 + 0.5) * res);
                    let off = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
                    d - off >= r + F32_SLACK
                } else {
                    c.clear(x.map(f64::from), f64::from(r + F32_SLACK))
                };
                want |= (!clear as u32) << i;
            }
            prop_assert_eq!(c.unclear8(p, r, lanes), want);
        }

        /// A contact the grid confirms is one the voxels confirm in a lane asked; otherwise the
        /// answer is `unclear8`'s.
        #[test]
        fn confirmed_contacts_are_contacts(
            voxels in prop::collection::vec(prop::array::uniform3(-6i32..6), 1..40),
            centres in prop::collection::vec(prop::array::uniform3(-0.1f32..0.1), 8),
            r in 0.0f32..0.08,
            lanes in 0u32..256,
        ) {
            let map = map_of(&voxels);
            let c = Clearance::of(&map, 0.2).unwrap();
            let p: [F8; 3] = std::array::from_fn(|a| F8(std::array::from_fn(|i| centres[i][a])));
            match c.sphere8(p, r, lanes) {
                Some(unclear) => prop_assert_eq!(unclear, c.unclear8(p, r, lanes)),
                None => {
                    let touches = (0..LANES).filter(|i| lanes >> i & 1 != 0).any(|i| {
                        map.sphere_touches_voxels(centres[i].map(f64::from), f64::from(r))
                    });
                    prop_assert!(touches, "confirmed, but no lane asked touches");
                }
            }
        }

        /// Grids updated around the changes hold what grids built anew hold, cell for cell,
        /// whether the changes add or clear voxels, inside the grids' cover or past it.
        #[test]
        fn updated_grids_equal_grids_built_anew(
            first in prop::collection::vec(prop::array::uniform3(-12i32..12), 1..40),
            rounds in prop::collection::vec(
                prop::collection::vec((prop::array::uniform3(-40i32..40), any::<bool>()), 1..12),
                1..5,
            ),
        ) {
            let mut map = map_of(&first);
            map.refresh_clearance();
            for round in rounds {
                for (k, occupied) in round {
                    map.set_voxel(k, occupied);
                }
                map.refresh_clearance();
                let fresh = Clearance::of(&map, super::super::CLEARANCE_PAD);
                let updated = map.clearance();
                let (Some(fresh), Some(updated)) = (fresh, updated) else {
                    prop_assert!(!map.has_occupied());
                    continue;
                };
                // The cover boxes, grown rather than built anew, still hold every occupied block.
                for (b, &i) in &map.index {
                    if map.blocks[i as usize].occupied != 0 {
                        prop_assert!(updated.boxes.holds(*b), "block {:?}", b);
                    }
                }
                for (f, u) in [(&fresh.fine, &updated.fine), (&fresh.coarse, &updated.coarse)] {
                    for (k, want) in f.cells() {
                        prop_assert_eq!(u.at(k), Some(want), "cell {:?}", k);
                    }
                    // Past the fresh grid, the updated one is saturated.
                    for (k, got) in u.cells() {
                        if f.at(k).is_none() {
                            prop_assert_eq!(got, u.cap(), "cell {:?}", k);
                        }
                    }
                }
                for a in 0..3 {
                    prop_assert!(updated.occupied_lo[a] <= fresh.occupied_lo[a]);
                    prop_assert!(updated.occupied_hi[a] >= fresh.occupied_hi[a]);
                }
            }
        }
    }
}
