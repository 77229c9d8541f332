//! The exact Euclidean distance transform the clearance grids are built with: from every cell
//! centre of a box of cells to the nearest cube of a set of cells, separable along the axes,
//! saturated at a padding, stored in one byte per cell.

use super::VoxelKey;
#[cfg(target_arch = "x86_64")]
use crate::collision::batch::lanes::has_avx2;

/// A squared distance in the transform, in quarter cells squared (`4·d²`, a whole number as
/// every gap to a cube is a whole number of cells less a half): at most `4·60²` within the
/// padding, so 16 bits hold it and a row of them fills twice the vector lanes `f32` would.
type Squared = i16;

/// Unreached: above every squared distance within the padding, and still below `i16::MAX`
/// with any gap's square added.
const UNREACHED: Squared = 1 << 14;

/// The farthest padding, cells (2.5 mm voxels at the default 15 cm; finer ones pad less): its
/// squared distances stay below [`UNREACHED`].
pub(super) const MAX_PAD: usize = 60;

/// Along one axis, `4·gap²` from a cell centre to the cube of the cell `cells` away: the gap is
/// half a cell less than the offset, none for the cell itself.
#[inline]
fn cube_gap_squared(cells: usize) -> Squared {
    if cells == 0 {
        0
    } else {
        let twice = (2 * cells.min(MAX_PAD + 1) - 1) as Squared;
        twice * twice
    }
}

/// Exact distances (cell units) from every cell centre of the grid to the nearest cube of the
/// cells `keys`, one axis at a time, stored as `floor(steps·distance)` saturated at `cap` (the
/// grid's `pad` cells).
/// The squared distance to a cube is a sum over the axes of the squared gap of the offset, so
/// the transform is separable as for centres. As results saturate, each pass needs only the
/// neighbours within `pad` cells: a cell under the padding has its nearest key within `pad`
/// along every axis. The first pass (along `z`, on the bare keys) counts cells to the nearest
/// key; the others take, row by row, the minimum of the `2·pad + 1` neighbouring rows each
/// raised by its squared gap, over whole contiguous rows of 16-bit integers at once (which
/// vectorises, with AVX2 where the CPU has it), skipping rows nothing finite has reached.
pub(super) fn distance_transform(
    keys: &[VoxelKey],
    lo: VoxelKey,
    dims: [usize; 3],
    pad: i32,
    steps: f64,
    cap: u8,
) -> Vec<u8> {
    let pad = (pad.max(0) as usize).min(MAX_PAD);
    let n = dims[0] * dims[1] * dims[2];
    let far = 4 * (pad * pad) as Squared;
    let mut d = vec![UNREACHED; n];
    let mut lines = Vec::with_capacity(keys.len());
    for k in keys {
        let c = [0, 1, 2].map(|a| (k[a] - lo[a]) as usize);
        let line = c[0] * dims[1] + c[1];
        d[line * dims[2] + c[2]] = 0;
        lines.push(line);
    }
    lines.sort_unstable();
    lines.dedup();
    // Along z: cells to the nearest key in the line, forwards then backwards.
    let mut runs = vec![0usize; dims[2]];
    for &line in &lines {
        let row = &mut d[line * dims[2]..][..dims[2]];
        let mut run = usize::MAX;
        for (v, r) in row.iter().zip(runs.iter_mut()) {
            run = if *v == 0 { 0 } else { run.saturating_add(1) };
            *r = run;
        }
        let mut run = usize::MAX;
        for (v, r) in row.iter_mut().zip(&runs).rev() {
            run = if *v == 0 { 0 } else { run.saturating_add(1) };
            let m = cube_gap_squared(run.min(*r));
            *v = if m <= far { m } else { UNREACHED };
        }
    }
    // Along y, then along x.
    let rows = dims[0] * dims[1];
    let mut finite = vec![false; rows];
    for &line in &lines {
        finite[line] = true;
    }
    let mut src = vec![0; n];
    for axis in [1, 0] {
        src.copy_from_slice(&d);
        let pass = Pass {
            src: &src,
            finite: &finite,
            dims,
            axis,
            pad,
            far,
        };
        finite = pass.run(&mut d);
    }
    // Rounded down: a lower bound. Unreached cells take the cap.
    let table: Vec<u8> = (0..=far)
        .map(|v| ((f64::from(v).sqrt() * steps / 2.0) as u8).min(cap))
        .collect();
    d.iter()
        .map(|&v| table.get(v as usize).copied().unwrap_or(cap))
        .collect()
}

/// One pass of [`distance_transform`] along `axis` (1: y, 0: x): each row of `z` takes the
/// minimum over the rows of `src` within the padding along the axis, each raised by its
/// squared gap; rows `finite` marks none of are skipped.
struct Pass<'a> {
    src: &'a [Squared],
    finite: &'a [bool],
    dims: [usize; 3],
    axis: usize,
    pad: usize,
    far: Squared,
}

impl Pass<'_> {
    /// Writes the pass into `d`, compiled for AVX2 where the CPU runs it; returns the rows
    /// reached.
    fn run(&self, d: &mut [Squared]) -> Vec<bool> {
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            // SAFETY: the CPU runs AVX2 (checked just above).
            return unsafe { self.run_avx2(d) };
        }
        self.rows(d)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(&self, d: &mut [Squared]) -> Vec<bool> {
        self.rows(d)
    }

    #[inline(always)]
    fn rows(&self, d: &mut [Squared]) -> Vec<bool> {
        let Pass {
            src,
            finite,
            dims,
            axis,
            pad,
            far,
        } = *self;
        let row_of = |x: usize, y: usize| x * dims[1] + y;
        let mut reached = vec![false; dims[0] * dims[1]];
        for x in 0..dims[0] {
            for y in 0..dims[1] {
                let (t, len) = if axis == 1 {
                    (y, dims[1])
                } else {
                    (x, dims[0])
                };
                let at = |p: usize| {
                    if axis == 1 {
                        row_of(x, p)
                    } else {
                        row_of(p, y)
                    }
                };
                let r = row_of(x, y);
                let out = &mut d[r * dims[2]..][..dims[2]];
                for p in t.saturating_sub(pad)..=(t + pad).min(len - 1) {
                    let q = at(p);
                    if !finite[q] {
                        continue;
                    }
                    reached[r] = true;
                    if p == t {
                        continue;
                    }
                    let w = cube_gap_squared(p.abs_diff(t));
                    for (o, &v) in out.iter_mut().zip(&src[q * dims[2]..][..dims[2]]) {
                        *o = (*o).min(v + w);
                    }
                }
                if reached[r] {
                    for o in out.iter_mut() {
                        *o = if *o > far { UNREACHED } else { *o };
                    }
                }
            }
        }
        reached
    }
}
