//! A few boxes that together hold every occupied voxel: the clearance grids' first test for the
//! large balls (links' and clusters' bounds). A ball that misses every box in every lane is
//! clear without reading the grids; the arm's links far above a table or beside a shelf mostly
//! are.
//!
//! The boxes are built around the occupied blocks by splitting the largest box where the two
//! halves hold the least volume, and grown as blocks become occupied (never shrunk: a box
//! larger than what it holds is still a cover).

use super::BlockKey;
use crate::collision::batch::lanes::{F8, LANES};

/// Slack of the lane test, metres: far above its `f32` rounding at robot scale.
const SLACK: f32 = 1e-5;

/// At most [`LANES`] boxes, one per lane, holding every occupied voxel (see the module docs).
#[derive(Debug, Clone)]
pub(super) struct CoverBoxes {
    /// The boxes in blocks (inclusive), for growing.
    blocks: Vec<(BlockKey, BlockKey)>,
    /// Block edge, metres.
    edge: f64,
    /// The boxes in metres, rounded outwards; lanes without a box hold an empty one.
    lo: [F8; 3],
    hi: [F8; 3],
}

impl CoverBoxes {
    /// Boxes around the blocks `blocks` (non-empty), of edge `edge` metres.
    pub(super) fn around(blocks: &mut [BlockKey], edge: f64) -> Self {
        let mut leaves = vec![(0, blocks.len())];
        while leaves.len() < LANES {
            // The largest box that holds more than one block, split where its halves hold
            // the least volume.
            let best = leaves
                .iter()
                .enumerate()
                .filter(|(_, &(s, e))| e - s > 1)
                .max_by_key(|(_, &(s, e))| volume(bounds(&blocks[s..e])));
            let Some((i, &(s, e))) = best else {
                break;
            };
            let Some(at) = best_split(&mut blocks[s..e]) else {
                break;
            };
            leaves[i] = (s, s + at);
            leaves.push((s + at, e));
        }
        let mut cover = CoverBoxes {
            blocks: leaves.iter().map(|&(s, e)| bounds(&blocks[s..e])).collect(),
            edge,
            lo: [F8::splat(f32::INFINITY); 3],
            hi: [F8::splat(f32::NEG_INFINITY); 3],
        };
        for k in 0..cover.blocks.len() {
            cover.place(k);
        }
        cover
    }

    /// Grows the boxes to hold block `b`, if none does: the box that grows the least in volume.
    pub(super) fn hold(&mut self, b: BlockKey) {
        if self.holds(b) {
            return;
        }
        let k = (0..self.blocks.len())
            .min_by_key(|&k| volume(join(self.blocks[k], b)) - volume(self.blocks[k]))
            .expect("a cover holds a box");
        self.blocks[k] = join(self.blocks[k], b);
        self.place(k);
    }

    /// True when a box holds block `b`.
    pub(super) fn holds(&self, b: BlockKey) -> bool {
        self.blocks.iter().any(|&c| join(c, b) == c)
    }

    /// Writes box `k` into its lane, in metres rounded outwards.
    fn place(&mut self, k: usize) {
        let (lo, hi) = self.blocks[k];
        for a in 0..3 {
            self.lo[a].0[k] = ((lo[a] as f64 * self.edge) as f32).next_down();
            self.hi[a].0[k] = (((hi[a] + 1) as f64 * self.edge) as f32).next_up();
        }
    }

    /// True when the ball (centres `p` in eight lanes, radius `r`) misses every box in every
    /// lane; false when some lane is not a number.
    #[inline(always)]
    pub(super) fn missed8(&self, p: [F8; 3], r: f32) -> bool {
        let number = p[0].le(p[0]) & p[1].le(p[1]) & p[2].le(p[2]);
        if number.bits() != (1 << LANES) - 1 {
            return false;
        }
        // The box around the lanes' balls against the eight boxes at once.
        let reach = r + SLACK;
        let mut meets = None;
        for (a, &pa) in p.iter().enumerate() {
            let (qlo, qhi) = (pa.hmin() - reach, pa.hmax() + reach);
            let m = self.lo[a].le(F8::splat(qhi)) & F8::splat(qlo).le(self.hi[a]);
            meets = Some(meets.map_or(m, |n| n & m));
        }
        !meets.expect("three axes").any()
    }
}

/// The box (inclusive) holding `blocks` (non-empty).
fn bounds(blocks: &[BlockKey]) -> (BlockKey, BlockKey) {
    let mut lo = blocks[0];
    let mut hi = blocks[0];
    for b in blocks {
        for a in 0..3 {
            lo[a] = lo[a].min(b[a]);
            hi[a] = hi[a].max(b[a]);
        }
    }
    (lo, hi)
}

/// Blocks in the box (inclusive).
fn volume((lo, hi): (BlockKey, BlockKey)) -> i64 {
    (0..3).map(|a| (hi[a] - lo[a] + 1) as i64).product()
}

/// Sorts `blocks` along the axis whose split leaves the least volume in the two halves' boxes
/// and returns where it splits them; `None` when every block is the same.
fn best_split(blocks: &mut [BlockKey]) -> Option<usize> {
    let mut best: Option<(i64, usize, usize)> = None;
    let mut suffix = vec![(blocks[0], blocks[0]); blocks.len()];
    for a in 0..3 {
        blocks.sort_unstable_by_key(|b| b[a]);
        let mut acc = bounds(&blocks[blocks.len() - 1..]);
        for i in (0..blocks.len()).rev() {
            acc = join(acc, blocks[i]);
            suffix[i] = acc;
        }
        let mut prefix = bounds(&blocks[..1]);
        for i in 1..blocks.len() {
            // Split only between different coordinates along the axis.
            if blocks[i][a] != blocks[i - 1][a] {
                let v = volume(prefix) + volume(suffix[i]);
                if best.is_none_or(|(bv, _, _)| v < bv) {
                    best = Some((v, a, i));
                }
            }
            prefix = join(prefix, blocks[i]);
        }
    }
    let (_, a, i) = best?;
    blocks.sort_unstable_by_key(|b| b[a]);
    Some(i)
}

/// The box `(lo, hi)` grown to hold block `b`.
fn join((lo, hi): (BlockKey, BlockKey), b: BlockKey) -> (BlockKey, BlockKey) {
    (
        [0, 1, 2].map(|a| lo[a].min(b[a])),
        [0, 1, 2].map(|a| hi[a].max(b[a])),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const EDGE: f64 = 0.04;

    /// Distance from `p` to block `b`'s cube, metres.
    fn gap(p: [f32; 3], b: BlockKey) -> f64 {
        (0..3)
            .map(|a| {
                let (lo, hi) = (b[a] as f64 * EDGE, (b[a] + 1) as f64 * EDGE);
                let x = f64::from(p[a]);
                (lo - x).max(x - hi).max(0.0).powi(2)
            })
            .sum::<f64>()
            .sqrt()
    }

    fn lanes(centres: &[[f32; 3]]) -> [F8; 3] {
        std::array::from_fn(|a| F8(std::array::from_fn(|i| centres[i][a])))
    }

    #[test]
    fn two_far_groups_leave_the_space_between_clear() {
        let mut blocks = vec![[0, 0, 0], [1, 0, 0], [0, 1, 0], [30, 0, 0], [30, 1, 1]];
        let cover = CoverBoxes::around(&mut blocks, EDGE);
        // Midway, 0.6 m from either group: one box around both would hold it.
        let mid = [[0.62f32, 0.04, 0.02]; LANES];
        assert!(cover.missed8(lanes(&mid), 0.1));
        assert!(!cover.missed8(lanes(&mid), 0.7));
        // A lane near a block is not missed, nor is a lane that is not a number.
        let mut near = mid;
        near[5] = [0.02, 0.02, 0.02];
        assert!(!cover.missed8(lanes(&near), 0.01));
        let mut nan = mid;
        nan[2][1] = f32::NAN;
        assert!(!cover.missed8(lanes(&nan), 0.1));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]
        /// Every block lies in a box, as built and as grown, in at most eight boxes; a ball the
        /// boxes miss in every lane is farther than its radius from every block.
        #[test]
        fn boxes_hold_every_block_and_missed_balls_touch_none(
            first in prop::collection::vec(prop::array::uniform3(-20i32..20), 1..120),
            added in prop::collection::vec(prop::array::uniform3(-30i32..30), 0..20),
            base in prop::array::uniform3(-1.2f32..1.2),
            offsets in prop::collection::vec(prop::array::uniform3(-0.1f32..0.1), LANES),
            r in 0.0f32..0.3,
        ) {
            let centres: Vec<[f32; 3]> =
                offsets.iter().map(|o| [0, 1, 2].map(|a| base[a] + o[a])).collect();
            let mut blocks = first.clone();
            let mut cover = CoverBoxes::around(&mut blocks, EDGE);
            prop_assert!(cover.blocks.len() <= LANES);
            for &b in &added {
                cover.hold(b);
            }
            let all: Vec<BlockKey> = first.iter().chain(&added).copied().collect();
            for &b in &all {
                prop_assert!(cover.holds(b), "block {:?} outside {:?}", b, cover.blocks);
            }
            if cover.missed8(lanes(&centres), r) {
                for (c, b) in centres.iter().flat_map(|c| all.iter().map(move |b| (c, b))) {
                    prop_assert!(gap(*c, *b) > f64::from(r), "{:?} r {} touches {:?}", c, r, b);
                }
            }
        }
    }
}
