//! Clearance: a dense grid of lower bounds on the distance to the nearest occupied voxel, so
//! most sphere queries against the map cost one array read instead of a walk over blocks.
//!
//! Two grids: the fine one's cells are the map's voxels, the coarse one's its 4×4×4 blocks
//! (reaching three times as far, for the links' and clusters' larger balls). Each cell holds
//! the exact Euclidean distance (Felzenszwalb and Huttenlocher's separable transform, in cell
//! units) from its centre to the nearest occupied cell centre, rounded down to 1/32 of a cell and saturated at the grid's padding. A ball at
//! `p` (in cell `q`) with radius `r` is clear of every occupied cell cube (and so of every
//! occupied voxel) when `d(q) − |p − c(q)| − h ≥ r`, with `h` a cell's half diagonal: the
//! triangle inequality twice.
//! The grid covers the occupied voxels' box grown by the padding; farther out the box itself
//! bounds the distance. A query the grid cannot clear is decided exactly by the map
//! ([`OccupancyMap::sphere_collides`](super::OccupancyMap::sphere_collides)).

use super::{OccupancyMap, VoxelKey};
use crate::collision::batch::lanes::{F8, LANES};

/// Distances are stored in these fractions of a voxel.
const STEPS: f64 = 32.0;

/// Slack of the `f32` queries, metres: far above their rounding at robot scale.
const F32_SLACK: f32 = 1e-5;

/// Largest grid built (cells, 2 bytes each); a map spread wider gets none and is checked
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
    /// Occupied voxel cubes' bounding box, metres.
    occupied_lo: [f64; 3],
    occupied_hi: [f64; 3],
}

/// One grid: cells of edge `res` holding distances to the nearest occupied cell.
#[derive(Debug, Clone)]
struct Level {
    res: f64,
    inv_res: f64,
    /// Key of cell `[0, 0, 0]`.
    lo: VoxelKey,
    dims: [usize; 3],
    /// Per cell (`z` fastest, then `y`, then `x`): distance in 1/32 cells, saturated.
    cells: Vec<u16>,
    /// Half diagonal of a cell, metres.
    half_diagonal: f64,
}

/// The coarse grid reaches this many times the fine grid's padding.
const COARSE_REACH: f64 = 3.0;

impl Clearance {
    /// The grids of `map`, the fine one padded by `pad` metres around its occupied voxels;
    /// `None` when the map has no occupied voxel or a grid would exceed [`MAX_CELLS`].
    pub fn of(map: &OccupancyMap, pad: f64) -> Option<Self> {
        let res = map.resolution();
        let mut keys = Vec::new();
        let mut blocks = Vec::new();
        for (b, &i) in &map.index {
            let occupied = map.blocks[i as usize].occupied;
            if occupied != 0 {
                blocks.push(*b);
            }
            for bit in super::bits(occupied) {
                keys.push([
                    b[0] * 4 + (bit / 16) as i32,
                    b[1] * 4 + (bit / 4 % 4) as i32,
                    b[2] * 4 + (bit % 4) as i32,
                ]);
            }
        }
        let (fine, (klo, khi)) = Level::of(&keys, res, pad)?;
        let (coarse, _) = Level::of(&blocks, 4.0 * res, COARSE_REACH * pad)?;
        Some(Clearance {
            fine_radius: pad - 2.0 * fine.half_diagonal,
            fine,
            coarse,
            occupied_lo: klo.map(|v| v as f64 * res),
            occupied_hi: khi.map(|v| (v + 1) as f64 * res),
        })
    }

    /// True when a ball at `p` with radius `r` surely touches no occupied voxel; false means
    /// it may (the map decides).
    #[inline]
    pub fn clear(&self, p: [f64; 3], r: f64) -> bool {
        let level = if r <= self.fine_radius {
            &self.fine
        } else {
            &self.coarse
        };
        match level.clearance(p) {
            Some(d) => d >= r,
            None => {
                // Beyond the padding: the occupied box bounds the distance.
                let d2: f64 = (0..3)
                    .map(|a| {
                        let d = (self.occupied_lo[a] - p[a]).max(p[a] - self.occupied_hi[a]);
                        d.max(0.0).powi(2)
                    })
                    .sum();
                d2 >= r * r
            }
        }
    }

    /// The lanes (bits) whose ball (centres `p`, radius `r`) the grids cannot clear: the
    /// batch checker's form of [`Clearance::clear`], in `f32` with a hair of slack.
    #[inline(always)]
    pub fn unclear8(&self, p: [F8; 3], r: f32) -> u32 {
        let g = if f64::from(r) <= self.fine_radius {
            &self.fine
        } else {
            &self.coarse
        };
        let res = g.res as f32;
        let inv = g.inv_res as f32;
        let step = res / STEPS as f32;
        let need = r + g.half_diagonal as f32 + F32_SLACK;
        let mut out = 0;
        for i in 0..LANES {
            let c = [p[0].0[i], p[1].0[i], p[2].0[i]];
            let k = c.map(|v| (v * inv).floor() as i32);
            let cell = [0, 1, 2].map(|a| k[a].wrapping_sub(g.lo[a]) as u32 as usize);
            let clear = if cell[0] < g.dims[0] && cell[1] < g.dims[1] && cell[2] < g.dims[2] {
                let at = (cell[0] * g.dims[1] + cell[1]) * g.dims[2] + cell[2];
                let d = g.cells[at] as f32 * step;
                let o = [0, 1, 2].map(|a| c[a] - (k[a] as f32 + 0.5) * res);
                let off = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
                d - off >= need
            } else {
                self.clear(c.map(f64::from), f64::from(r + F32_SLACK))
            };
            out |= (!clear as u32) << i;
        }
        out
    }

    /// Cells in the grids.
    pub fn cells(&self) -> usize {
        self.fine.cells.len() + self.coarse.cells.len()
    }
}

impl Level {
    /// The grid over `keys` (cells of edge `res`) padded by `pad` metres, with the keys'
    /// bounding box; `None` without keys or past [`MAX_CELLS`].
    fn of(keys: &[VoxelKey], res: f64, pad: f64) -> Option<(Self, (VoxelKey, VoxelKey))> {
        let first = *keys.first()?;
        let (mut klo, mut khi) = (first, first);
        for k in keys {
            for a in 0..3 {
                klo[a] = klo[a].min(k[a]);
                khi[a] = khi[a].max(k[a]);
            }
        }
        let pad_cells = (pad / res).ceil().clamp(1.0, 2000.0) as i32;
        let lo = klo.map(|v| v - pad_cells);
        let dims = [0, 1, 2].map(|a| (khi[a] + pad_cells - lo[a] + 1) as usize);
        if dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d))? > MAX_CELLS {
            return None;
        }
        let cells = distance_transform(keys, lo, dims, pad_cells as f64);
        let level = Level {
            res,
            inv_res: 1.0 / res,
            lo,
            dims,
            cells,
            half_diagonal: res * 3f64.sqrt() / 2.0,
        };
        Some((level, (klo, khi)))
    }

    /// A lower bound on the distance from `p` to the nearest occupied cell's cube (`None`
    /// outside the grid): the cell's distance less `p`'s offset from the cell centre and a half
    /// diagonal.
    #[inline]
    fn clearance(&self, p: [f64; 3]) -> Option<f64> {
        let k = p.map(|v| super::fast_floor(v * self.inv_res));
        let cell = [0, 1, 2].map(|a| k[a] as i64 - self.lo[a] as i64);
        if (0..3).any(|a| cell[a] < 0 || cell[a] >= self.dims[a] as i64) {
            return None;
        }
        let i =
            (cell[0] as usize * self.dims[1] + cell[1] as usize) * self.dims[2] + cell[2] as usize;
        let d = self.cells[i] as f64 * (self.res / STEPS);
        let off: f64 = (0..3)
            .map(|a| (p[a] - (k[a] as f64 + 0.5) * self.res).powi(2))
            .sum::<f64>()
            .sqrt();
        Some(d - off - self.half_diagonal)
    }
}

/// Lines transformed together in the strided passes: one cache line's worth of neighbours.
const TILE: usize = 16;

/// Exact squared distances (voxel units) from every cell of the grid to the nearest of `keys`,
/// one axis at a time; stored as `floor(32·distance)`, saturated at `pad` voxels. Values past
/// the padding are set back to infinity after each pass (they cannot bring a cell under the
/// padding), so lines far from everything stay empty and are skipped. The passes across `z`
/// (the contiguous axis) move `TILE` neighbouring lines at once, so memory is read in runs
/// rather than one value per cache line.
fn distance_transform(keys: &[VoxelKey], lo: VoxelKey, dims: [usize; 3], pad: f64) -> Vec<u16> {
    let n = dims[0] * dims[1] * dims[2];
    let mut d = vec![f32::INFINITY; n];
    for k in keys {
        let c = [0, 1, 2].map(|a| (k[a] - lo[a]) as usize);
        d[(c[0] * dims[1] + c[1]) * dims[2] + c[2]] = 0.0;
    }
    let longest = dims.iter().copied().max().unwrap_or(0);
    let mut env = Envelope::new(longest);
    let mut out = vec![0.0; longest];
    let far = (pad * pad) as f32;
    let clip = |v: f32| if v > far { f32::INFINITY } else { v };
    // Along z: contiguous lines.
    for line in d.chunks_exact_mut(dims[2]) {
        if line.iter().any(|v| v.is_finite()) {
            env.transform(line, &mut out[..dims[2]]);
            for (v, o) in line.iter_mut().zip(&out) {
                *v = clip(*o);
            }
        }
    }
    // Along y, then x: TILE lines side by side (neighbouring z).
    let mut tile = vec![0.0f32; TILE * longest];
    for axis in [1, 0] {
        let len = dims[axis];
        let stride = if axis == 1 {
            dims[2]
        } else {
            dims[1] * dims[2]
        };
        let outer = if axis == 1 { dims[0] } else { dims[1] };
        let outer_stride = if axis == 1 {
            dims[1] * dims[2]
        } else {
            dims[2]
        };
        for o in 0..outer {
            for z0 in (0..dims[2]).step_by(TILE) {
                let width = TILE.min(dims[2] - z0);
                let base = o * outer_stride + z0;
                for t in 0..len {
                    let row = &d[base + t * stride..][..width];
                    for (w, v) in row.iter().enumerate() {
                        tile[w * len + t] = *v;
                    }
                }
                for w in 0..width {
                    let line = &mut tile[w * len..][..len];
                    if line.iter().any(|v| v.is_finite()) {
                        env.transform(line, &mut out[..len]);
                        for (v, o) in line.iter_mut().zip(&out) {
                            *v = clip(*o);
                        }
                    }
                }
                for t in 0..len {
                    let row = &mut d[base + t * stride..][..width];
                    for (w, v) in row.iter_mut().enumerate() {
                        *v = tile[w * len + t];
                    }
                }
            }
        }
    }
    let cap = (pad * STEPS).min(u16::MAX as f64) as f32;
    d.iter()
        // Rounded down (the cast truncates): a lower bound, to the square root's last bit.
        .map(|&v| (v.sqrt() * STEPS as f32).min(cap) as u16)
        .collect()
}

/// Scratch of the one-dimensional transform (lower envelope of parabolas).
struct Envelope {
    v: Vec<usize>,
    /// Boundaries between the envelope's parabolas, in f64: they must order exactly against
    /// the integers.
    z: Vec<f64>,
}

impl Envelope {
    fn new(n: usize) -> Self {
        Envelope {
            v: vec![0; n],
            z: vec![0.0; n + 1],
        }
    }

    /// `out[q] = min_p f[p] + (q − p)²`.
    fn transform(&mut self, f: &[f32], out: &mut [f32]) {
        let n = f.len();
        let Some(first) = f.iter().position(|v| v.is_finite()) else {
            out.fill(f32::INFINITY);
            return;
        };
        let (v, z) = (&mut self.v, &mut self.z);
        let mut k = 0;
        v[0] = first;
        z[0] = f64::NEG_INFINITY;
        z[1] = f64::INFINITY;
        for q in first + 1..n {
            if !f[q].is_finite() {
                continue;
            }
            // z[0] is −∞, so the search stops at k = 0 at the latest.
            let mut s;
            loop {
                let p = v[k];
                s = ((f[q] as f64 + (q * q) as f64) - (f[p] as f64 + (p * p) as f64))
                    / (2.0 * (q as f64 - p as f64));
                if s > z[k] {
                    break;
                }
                k -= 1;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
        }
        let mut k = 0;
        for (q, o) in out.iter_mut().enumerate() {
            while z[k + 1] < q as f64 {
                k += 1;
            }
            let p = v[k];
            let dq = q as f32 - p as f32;
            *o = dq * dq + f[p];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::map::MapParams;
    use proptest::prelude::*;

    fn map_of(voxels: &[[i32; 3]]) -> OccupancyMap {
        let mut map = OccupancyMap::new(MapParams::default());
        for &k in voxels {
            map.set_voxel(k, true);
        }
        map
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
        let at = |k: [i32; 3]| {
            let cell = [0, 1, 2].map(|a| (k[a] - g.lo[a]) as usize);
            g.cells[(cell[0] * g.dims[1] + cell[1]) * g.dims[2] + cell[2]] as f64 / STEPS
        };
        assert_eq!(at([0, 0, 0]), 0.0);
        assert_eq!(at([2, 0, 0]), 2.0);
        assert_eq!(at([3, 0, 0]), 2.0);
        assert!((at([0, 3, 4]) - 5.0).abs() < 1.0 / STEPS);
        assert!((at([1, 1, 1]) - 3f64.sqrt()).abs() < 1.0 / STEPS);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Whatever the grid clears, the exact test finds clear too.
        #[test]
        fn a_cleared_ball_touches_no_occupied_voxel(
            voxels in prop::collection::vec(prop::array::uniform3(-12i32..12), 1..40),
            queries in prop::collection::vec((prop::array::uniform3(-0.5f64..0.5), 0.0f64..0.3), 50),
        ) {
            let map = map_of(&voxels);
            let c = Clearance::of(&map, 0.1).unwrap();
            for (p, r) in queries {
                if c.clear(p, r) {
                    prop_assert!(!map.sphere_touches_voxels(p, r), "cleared {p:?} r {r}");
                }
            }
            // Every cell holds the brute-force distance (rounded down, saturated).
            let g = &c.fine;
            for (i, &cell) in g.cells.iter().enumerate() {
                let at = [i / (g.dims[1] * g.dims[2]), i / g.dims[2] % g.dims[1], i % g.dims[2]];
                let k = [0, 1, 2].map(|a| at[a] as i32 + g.lo[a]);
                let d2 = voxels
                    .iter()
                    .map(|v| (0..3).map(|a| ((v[a] - k[a]) as f64).powi(2)).sum::<f64>())
                    .fold(f64::INFINITY, f64::min);
                let want = ((d2.sqrt() * STEPS).floor()).min(5.0 * STEPS) as u16;
                prop_assert_eq!(cell, want, "cell {:?}", k);
            }
            // The grid is not vacuous: far or small balls are cleared.
            prop_assert!(c.clear([5.0, 5.0, 5.0], 0.1));
        }
    }
}
