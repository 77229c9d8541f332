//! Nearest-neighbour search over a growing set of configurations: a tree of buckets with
//! tight bounding boxes, built incrementally.
//!
//! A leaf holds up to [`LEAF`] points in `f32`, stored joint-major (structure of arrays) so
//! the distances of a whole leaf are computed in vector lanes (AVX2 when the CPU has it, chosen
//! at run time; the same arithmetic, no FMA, so both paths give the same answer); the exact
//! coordinates, read for the answer's distance and for splits, stay in the order added, so a
//! new leaf zeroes only its lanes and a split moves row numbers. A full leaf
//! splits at the median of its widest joint. Every node keeps the bounding box of the points
//! below it, and a query visits nodes nearest box first, skipping any box farther than the
//! best point found. Continuous joints are stored wrapped into [-π, π) and their boxes are
//! arcs measured around the circle, so the index answers exactly the configuration-space
//! metric.
//!
//! Tight boxes prune far better than split planes in eight dimensions, where queries are
//! uniform samples, mostly far from a tree that grows along narrow branches.

use crate::collision::batch::lanes::has_avx2;
use crate::robot::config_space::wrap_angle;
use std::f64::consts::{PI, TAU};

/// Points per leaf before it splits (one less than a multiple of eight, so a leaf's slots
/// fill whole vectors).
pub const LEAF: usize = 255;

/// Slots per leaf: one more than [`LEAF`], for the point that triggers the split.
const SLOTS: usize = LEAF + 1;

const NONE: u32 = u32::MAX;

/// Relative and absolute slack (squared distance) between the lanes' `f32` distance and the
/// exact one, far above their rounding: coordinates of a few radians or metres carry errors of
/// ~1e-7 each, and eight squared differences of a few units sum to errors of ~1e-5. (Joints
/// ranging over hundreds of units could round past it; the only effect would be a sample at a
/// node's dynamic-domain radius taken as beyond it: a sampling choice, never a verdict.)
const APPROX_SLACK: f64 = 1e-3;

/// Coordinate of an empty slot: its distance to any query is huge but finite in `f32`.
const EMPTY: f32 = 1e15;

/// The index (see the module docs).
pub struct NearestIndex {
    dof: usize,
    continuous: Vec<bool>,
    /// Per joint: 2π on continuous joints, infinite on bounded ones.
    period: Vec<f64>,
    /// Per node: children, or `[NONE, leaf]` for a leaf.
    children: Vec<[u32; 2]>,
    /// Per node: the split (joint, value) of an inner node; left holds values below it.
    split: Vec<(u32, f64)>,
    /// Per node: box corners, `dof` values each (continuous joints wrapped).
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// Per point, in the order added: its coordinates, wrapped (exact, for splits and
    /// answers), `dof` values each; appended, so a new leaf costs no zeroing of them.
    points: Vec<f64>,
    /// Per point, in the order added: its number as given to [`NearestIndex::insert`].
    ids: Vec<u32>,
    /// Per leaf: `dof × SLOTS` coordinates in `f32`, joint-major, scanned by queries (eight
    /// lanes per vector).
    lanes: Vec<f32>,
    /// Per leaf: `SLOTS` rows of `points`, one per slot.
    rows: Vec<u32>,
    /// Per leaf: points held.
    len: Vec<u32>,
    /// Query stack (node, lower bound of its distance²), kept between queries.
    stack: Vec<(u32, f64)>,
    /// The query, wrapped, and in `f32`.
    target: Vec<f64>,
    target32: Vec<f32>,
    /// Per joint: the range values are stored in, [-π, π) on continuous joints, else all.
    inside_lo: Vec<f64>,
    inside_hi: Vec<f64>,
    /// Read only where the AVX2 paths are compiled (x86-64).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    avx2: bool,
}

impl NearestIndex {
    /// An empty index; `continuous[j]` when joint `j` wraps.
    pub fn new(continuous: &[bool]) -> Self {
        let dof = continuous.len();
        NearestIndex {
            dof,
            continuous: continuous.to_vec(),
            period: continuous
                .iter()
                .map(|&c| if c { TAU } else { f64::INFINITY })
                .collect(),
            children: Vec::with_capacity(16),
            split: Vec::with_capacity(16),
            lo: Vec::with_capacity(16 * dof),
            hi: Vec::with_capacity(16 * dof),
            points: Vec::with_capacity(SLOTS * dof),
            ids: Vec::with_capacity(SLOTS),
            lanes: Vec::with_capacity(2 * SLOTS * dof),
            rows: Vec::with_capacity(2 * SLOTS),
            len: Vec::with_capacity(2),
            stack: Vec::with_capacity(64),
            target: vec![0.0; dof],
            target32: vec![0.0; dof],
            inside_lo: continuous
                .iter()
                .map(|&c| if c { -PI } else { f64::NEG_INFINITY })
                .collect(),
            inside_hi: continuous
                .iter()
                .map(|&c| if c { PI } else { f64::INFINITY })
                .collect(),
            avx2: has_avx2(),
        }
    }

    /// Empties the index, keeping its buffers (a search reusing it allocates nothing until it
    /// outgrows them).
    pub fn clear(&mut self) {
        self.children.clear();
        self.split.clear();
        self.lo.clear();
        self.hi.clear();
        self.points.clear();
        self.ids.clear();
        self.lanes.clear();
        self.rows.clear();
        self.len.clear();
        self.stack.clear();
    }

    /// Per joint, whether it wraps (as given to [`NearestIndex::new`]).
    pub fn continuous(&self) -> &[bool] {
        &self.continuous
    }

    /// Points indexed (exact duplicates of an indexed point may be left out).
    pub fn len(&self) -> usize {
        self.len.iter().map(|&n| n as usize).sum()
    }

    /// True when nothing is indexed.
    pub fn is_empty(&self) -> bool {
        self.children.is_empty()
    }

    /// Adds point `id` at `p`.
    pub fn insert(&mut self, p: &[f64], id: u32) {
        let mut q = std::mem::take(&mut self.target);
        self.wrapped(p, &mut q);
        if self.children.is_empty() {
            self.new_leaf(None);
            self.push_node([NONE, 0], &q);
        }
        let row = self.ids.len() as u32;
        self.points.extend_from_slice(&q);
        self.ids.push(id);
        let mut at = 0usize;
        loop {
            self.grow_box(at, &q);
            let [a, b] = self.children[at];
            if a == NONE {
                let leaf = b as usize;
                self.put(leaf, &q, row);
                if self.len[leaf] as usize == SLOTS {
                    self.split(at);
                }
                break;
            }
            // The split plane routes: the children's boxes stay apart along its joint.
            let (dim, value) = self.split[at];
            at = if q[dim as usize] < value { a } else { b } as usize;
        }
        self.target = q;
    }

    /// The number and squared distance of the point nearest to `target`; `None` when empty.
    pub fn nearest(&mut self, target: &[f64]) -> Option<(u32, f64)> {
        self.nearest_unless_beyond(target, &[])
            .map(|(i, d2)| (i, d2.expect("no radius given")))
    }

    /// [`NearestIndex::nearest`], except that when the nearest point `i` is surely farther from
    /// `target` than `radius[i]` (where given) its exact distance is not computed: `(i, None)`.
    /// (A dynamic-domain search rejects most samples so, on the distance the lanes found,
    /// which is far closer than the margin taken here.)
    #[inline]
    pub fn nearest_unless_beyond(
        &mut self,
        target: &[f64],
        radius: &[f64],
    ) -> Option<(u32, Option<f64>)> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            return unsafe { self.nearest_avx2(target, radius) };
        }
        self.nearest_portable(target, radius)
    }

    /// [`NearestIndex::nearest_unless_beyond`] without AVX2, kept out of line so the query
    /// above stays a test and a call where the planner inlines it.
    #[inline(never)]
    fn nearest_portable(&mut self, target: &[f64], radius: &[f64]) -> Option<(u32, Option<f64>)> {
        self.nearest_any::<false>(target, radius)
    }

    /// [`NearestIndex::nearest_unless_beyond`] compiled for AVX2 as a whole: the query's set-up
    /// and the answer's exact distance in vector registers too, around the kernel.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn nearest_avx2(
        &mut self,
        target: &[f64],
        radius: &[f64],
    ) -> Option<(u32, Option<f64>)> {
        self.nearest_any::<true>(target, radius)
    }

    /// The query; `AVX2` when compiled inside [`NearestIndex::nearest_avx2`].
    #[inline(always)]
    fn nearest_any<const AVX2: bool>(
        &mut self,
        target: &[f64],
        radius: &[f64],
    ) -> Option<(u32, Option<f64>)> {
        // The common arm sizes get their number of joints known: the query's set-up and the
        // answer's exact distance unrolled, without bounds checks (they had cost more than
        // the distance kernel on small trees).
        match self.dof {
            6 => self.nearest_of::<6, AVX2>(target, radius),
            7 => self.nearest_of::<7, AVX2>(target, radius),
            8 => self.nearest_of::<8, AVX2>(target, radius),
            _ => self.nearest_of::<0, AVX2>(target, radius),
        }
    }

    /// [`NearestIndex::nearest_unless_beyond`] over `DOF` joints (all of them when `DOF` is 0).
    #[inline(always)]
    fn nearest_of<const DOF: usize, const AVX2: bool>(
        &mut self,
        target: &[f64],
        radius: &[f64],
    ) -> Option<(u32, Option<f64>)> {
        if self.children.is_empty() {
            return None;
        }
        self.set_query::<DOF>(target);
        let (leaf, k, approx) = match self.children[0] {
            // A tree of one bucket (most trees, most of the time): no walk.
            [NONE, leaf] => {
                let (approx, k) = self.leaf_nearest(leaf as usize);
                (leaf as usize, k, approx)
            }
            _ => self.walk(),
        };
        let row = self.rows[leaf * SLOTS + k] as usize;
        let id = self.ids[row];
        if let Some(&r) = radius.get(id as usize) {
            if f64::from(approx) > r * r * (1.0 + APPROX_SLACK) + APPROX_SLACK {
                return Some((id, None));
            }
        }
        // The lanes chose; the exact coordinates give the distance.
        #[cfg(target_arch = "x86_64")]
        if AVX2 && (DOF == 6 || DOF == 7 || DOF == 8) {
            // SAFETY: `AVX2` only inside `nearest_avx2`, which the CPU can run.
            return Some((id, Some(unsafe { self.exact_dist2_avx2::<DOF>(row) })));
        }
        Some((id, Some(self.exact_dist2::<DOF>(row))))
    }

    /// Holds `p` as the query: wrapped, and in `f32`. Values already inside their range
    /// (every joint of a sample within the limits) are copied in one pass.
    #[inline(always)]
    fn set_query<const DOF: usize>(&mut self, p: &[f64]) {
        let dof = if DOF == 0 { self.dof } else { DOF };
        let (p, lo, hi) = (&p[..dof], &self.inside_lo[..dof], &self.inside_hi[..dof]);
        let (q, q32) = (&mut self.target[..dof], &mut self.target32[..dof]);
        #[cfg(target_arch = "x86_64")]
        let inside = if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            unsafe { copy_query_avx2(p, lo, hi, q, q32) }
        } else {
            copy_query(p, lo, hi, q, q32)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let inside = copy_query(p, lo, hi, q, q32);
        if !inside {
            let mut q = std::mem::take(&mut self.target);
            self.wrapped(p, &mut q);
            for (l, &v) in self.target32.iter_mut().zip(&q) {
                *l = v as f32;
            }
            self.target = q;
        }
    }

    /// The leaf and slot of the point nearest to the query, and its squared distance in the
    /// lanes' `f32`, down the tree of buckets: nodes nearest box first, skipping any box
    /// farther than the best point found.
    fn walk(&mut self) -> (usize, usize, f32) {
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        stack.push((0, 0.0));
        let mut best = f64::INFINITY;
        let mut best_slot = (0, 0, f32::INFINITY);
        while let Some((at, bound)) = stack.pop() {
            if bound >= best {
                continue;
            }
            let [a, b] = self.children[at as usize];
            if a == NONE {
                let leaf = b as usize;
                let (nearest_here, k) = self.leaf_nearest(leaf);
                if nearest_here as f64 >= best {
                    continue;
                }
                best = nearest_here as f64;
                best_slot = (leaf, k, nearest_here);
                continue;
            }
            let da = self.box_dist2(a as usize);
            let db = self.box_dist2(b as usize);
            let (near, dn, far, df) = if da <= db {
                (a, da, b, db)
            } else {
                (b, db, a, da)
            };
            if df < best {
                stack.push((far, df));
            }
            if dn < best {
                stack.push((near, dn));
            }
        }
        self.stack = stack;
        best_slot
    }

    /// `p` with continuous joints wrapped into [-π, π).
    #[inline]
    fn wrapped(&self, p: &[f64], out: &mut [f64]) {
        for ((o, &v), &c) in out.iter_mut().zip(p).zip(&self.continuous) {
            *o = if c { wrap_angle(v) } else { v };
        }
    }

    fn push_node(&mut self, children: [u32; 2], p: &[f64]) -> usize {
        self.children.push(children);
        self.split.push((0, 0.0));
        self.lo.extend_from_slice(p);
        self.hi.extend_from_slice(p);
        self.children.len() - 1
    }

    fn grow_box(&mut self, at: usize, p: &[f64]) {
        let dof = self.dof;
        let lo = &mut self.lo[at * dof..][..dof];
        let hi = &mut self.hi[at * dof..][..dof];
        for ((l, h), &v) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
            *l = l.min(v);
            *h = h.max(v);
        }
    }

    /// A new empty leaf (or `slot` emptied), returning its number.
    fn new_leaf(&mut self, slot: Option<usize>) -> usize {
        match slot {
            Some(l) => {
                self.len[l] = 0;
                self.lanes[l * SLOTS * self.dof..][..SLOTS * self.dof].fill(EMPTY);
                l
            }
            None => {
                self.lanes
                    .resize(self.lanes.len() + SLOTS * self.dof, EMPTY);
                self.rows.resize(self.rows.len() + SLOTS, 0);
                self.len.push(0);
                self.len.len() - 1
            }
        }
    }

    /// Puts row `row` of `points` (`p`) in the next slot of `leaf`.
    fn put(&mut self, leaf: usize, p: &[f64], row: u32) {
        let k = self.len[leaf] as usize;
        let base = leaf * SLOTS * self.dof;
        for (j, &v) in p.iter().enumerate() {
            self.lanes[base + j * SLOTS + k] = v as f32;
        }
        self.rows[leaf * SLOTS + k] = row;
        self.len[leaf] += 1;
    }

    /// Squared distance from the query to the point in row `row`, in `f64`, over `DOF` joints
    /// (all when 0). Both are wrapped, so on a continuous joint the way around is |d| or
    /// 2π − |d| (`period` is infinite on the others): what [`wrap_angle`] of the difference
    /// gives, squared.
    #[inline(always)]
    fn exact_dist2<const DOF: usize>(&self, row: usize) -> f64 {
        let dof = if DOF == 0 { self.dof } else { DOF };
        let point = &self.points[row * dof..][..dof];
        let (q, period) = (&self.target[..dof], &self.period[..dof]);
        let mut d2 = 0.0;
        for j in 0..dof {
            let d = (q[j] - point[j]).abs();
            let around = period[j] - d;
            let d = if around < d { around } else { d };
            d2 += d * d;
        }
        d2
    }

    /// [`NearestIndex::exact_dist2`] for 6 to 8 joints, the squared differences four joints
    /// per instruction and summed in joint order (the same value, bit for bit: each term is
    /// the same operations, and the sum's order is kept).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn exact_dist2_avx2<const DOF: usize>(&self, row: usize) -> f64 {
        use std::arch::x86_64::*;
        const { assert!(DOF <= 8) };
        let point = &self.points[row * DOF..][..DOF];
        let (q, period) = (&self.target[..DOF], &self.period[..DOF]);
        // Joints past DOF hold zeros: their terms are zero and not summed.
        let (mut p8, mut q8, mut t8) = ([0.0f64; 8], [0.0f64; 8], [f64::INFINITY; 8]);
        p8[..DOF].copy_from_slice(point);
        q8[..DOF].copy_from_slice(q);
        t8[..DOF].copy_from_slice(period);
        let sign = _mm256_set1_pd(-0.0);
        let terms = |at: usize| {
            let d = _mm256_sub_pd(
                _mm256_loadu_pd(q8.as_ptr().add(at)),
                _mm256_loadu_pd(p8.as_ptr().add(at)),
            );
            let d = _mm256_andnot_pd(sign, d);
            // `around < d ? around : d`, as the scalar code chooses.
            let around = _mm256_sub_pd(_mm256_loadu_pd(t8.as_ptr().add(at)), d);
            let d = _mm256_min_pd(around, d);
            _mm256_mul_pd(d, d)
        };
        let mut t = [0.0f64; 8];
        _mm256_storeu_pd(t.as_mut_ptr(), terms(0));
        _mm256_storeu_pd(t.as_mut_ptr().add(4), terms(4));
        let mut d2 = 0.0;
        for term in &t[..DOF] {
            d2 += term;
        }
        d2
    }

    /// Coordinate `j` of the point in slot `k` of `leaf`.
    fn coord(&self, leaf: usize, j: usize, k: usize) -> f64 {
        self.points[self.rows[leaf * SLOTS + k] as usize * self.dof + j]
    }

    /// Splits the full leaf of node `at` at the median of its widest joint into two leaves.
    fn split(&mut self, at: usize) {
        let dof = self.dof;
        let leaf = self.children[at][1] as usize;
        let dim = (0..dof)
            .max_by(|&i, &j| {
                let w = |d: usize| self.hi[at * dof + d] - self.lo[at * dof + d];
                w(i).total_cmp(&w(j))
            })
            .unwrap_or(0);
        let mut order: [(f64, u16); SLOTS] = [(0.0, 0); SLOTS];
        for (k, o) in order.iter_mut().enumerate() {
            *o = (self.coord(leaf, dim, k), k as u16);
        }
        order.sort_by(|x, y| x.0.total_cmp(&y.0));
        let median = order[SLOTS / 2].0;
        // Values equal to the median go right, unless that leaves the left side empty.
        let mut cut = order.partition_point(|x| x.0 < median);
        if cut == 0 {
            cut = order.partition_point(|x| x.0 <= median);
        }
        if cut == SLOTS {
            // Every point is the same (the widest joint has no width): the newest point
            // duplicates the others, and a query finds them instead.
            self.len[leaf] -= 1;
            return;
        }
        // The rows in order, then this leaf refilled with the left side and a new one with
        // the right side.
        let mut rows = [0u32; SLOTS];
        for (r, &(_, k)) in rows.iter_mut().zip(&order) {
            *r = self.rows[leaf * SLOTS + k as usize];
        }
        let left = self.new_leaf(Some(leaf));
        let right = self.new_leaf(None);
        let mut nodes = [NONE; 2];
        let mut p = vec![0.0; dof];
        for (side, (l, range)) in [(left, 0..cut), (right, cut..SLOTS)]
            .into_iter()
            .enumerate()
        {
            let mut node = None;
            for &row in &rows[range] {
                p.copy_from_slice(&self.points[row as usize * dof..][..dof]);
                let at = *node.get_or_insert_with(|| self.push_node([NONE, l as u32], &p));
                self.put(l, &p, row);
                self.grow_box(at, &p);
            }
            nodes[side] = node.expect("both sides hold points") as u32;
        }
        self.children[at] = nodes;
        self.split[at] = (dim as u32, order[cut].0);
    }

    /// The least squared distance (in `f32`) from `q` (wrapped) to a point of `leaf`, and the
    /// first slot at it.
    #[inline(always)]
    fn leaf_nearest(&self, leaf: usize) -> (f32, usize) {
        let q = &self.target32;
        let blocks = (self.len[leaf] as usize).div_ceil(8);
        let coords = &self.lanes[leaf * SLOTS * self.dof..][..SLOTS * self.dof];
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            return unsafe { leaf_nearest_avx2(coords, q, &self.continuous, blocks) };
        }
        leaf_nearest(coords, q, &self.continuous, blocks)
    }

    /// Squared distance from `p` (wrapped) to node `at`'s box. Branch-free over the joints:
    /// the gap below or above the box, and on continuous joints the way around the circle
    /// when shorter (`period` is 2π there and infinite elsewhere).
    #[inline]
    fn box_dist2(&self, at: usize) -> f64 {
        let (dof, p) = (self.dof, &self.target);
        let (lo, hi) = (&self.lo[at * dof..][..dof], &self.hi[at * dof..][..dof]);
        let (p, period) = (&p[..dof], &self.period[..dof]);
        let mut d2 = 0.0;
        for j in 0..dof {
            let d = (lo[j] - p[j]).max(p[j] - hi[j]).max(0.0);
            let d = d.min(period[j] - (hi[j] - lo[j]) - d);
            d2 += d * d;
        }
        d2
    }
}

/// Copies `p` into `q`, and into `q32` rounded to `f32`, and says whether every value lies
/// in `[lo, hi)` (a NaN does not). All slices have the length of `p`.
#[inline(always)]
fn copy_query(p: &[f64], lo: &[f64], hi: &[f64], q: &mut [f64], q32: &mut [f32]) -> bool {
    let mut inside = true;
    for (j, &v) in p.iter().enumerate() {
        // Not short-circuited: one pass of comparisons.
        inside &= (v >= lo[j]) & (v < hi[j]);
        q[j] = v;
        q32[j] = v as f32;
    }
    inside
}

/// [`copy_query`] four joints per AVX2 instruction (the same comparisons and rounding).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn copy_query_avx2(
    p: &[f64],
    lo: &[f64],
    hi: &[f64],
    q: &mut [f64],
    q32: &mut [f32],
) -> bool {
    use std::arch::x86_64::*;
    let n = p.len();
    assert!(lo.len() >= n && hi.len() >= n && q.len() >= n && q32.len() >= n);
    let four = n / 4 * 4;
    let mut inside = 0xf;
    for j in (0..four).step_by(4) {
        // SAFETY: j + 4 <= n, within every slice (asserted above).
        let v = _mm256_loadu_pd(p.as_ptr().add(j));
        let ge = _mm256_cmp_pd::<_CMP_GE_OQ>(v, _mm256_loadu_pd(lo.as_ptr().add(j)));
        let lt = _mm256_cmp_pd::<_CMP_LT_OQ>(v, _mm256_loadu_pd(hi.as_ptr().add(j)));
        inside &= _mm256_movemask_pd(_mm256_and_pd(ge, lt));
        _mm256_storeu_pd(q.as_mut_ptr().add(j), v);
        _mm_storeu_ps(q32.as_mut_ptr().add(j), _mm256_cvtpd_ps(v));
    }
    let rest = copy_query(
        &p[four..],
        &lo[four..n],
        &hi[four..n],
        &mut q[four..n],
        &mut q32[four..n],
    );
    inside == 0xf && rest
}

/// The distance kernel: block by block of eight slots, each block's sums kept in lanes over
/// the joints; returns the least squared distance and the first slot at it (empty slots hold
/// [`EMPTY`], far from everything). Continuous joints are wrapped values, so their
/// difference needs one correction at most.
#[inline(always)]
fn leaf_nearest(coords: &[f32], q: &[f32], continuous: &[bool], blocks: usize) -> (f32, usize) {
    use std::f32::consts::TAU;
    const B: usize = 8;
    let mut least = [f32::INFINITY; B];
    let mut block_of = [0u32; B];
    for block in 0..blocks {
        let mut sum = [0.0f32; B];
        for (j, &qj) in q.iter().enumerate() {
            let column: &[f32; B] = coords[j * SLOTS + block * B..][..B]
                .try_into()
                .expect("eight slots");
            if continuous[j] {
                for k in 0..B {
                    // The way around the circle when shorter: |d| or 2π − |d|.
                    let d = (qj - column[k]).abs();
                    let around = TAU - d;
                    let d = if around < d { around } else { d };
                    sum[k] += d * d;
                }
            } else {
                for k in 0..B {
                    let d = qj - column[k];
                    sum[k] += d * d;
                }
            }
        }
        // Strictly less: a lane keeps its earliest block at a tie.
        for k in 0..B {
            let closer = sum[k] < least[k];
            least[k] = if closer { sum[k] } else { least[k] };
            block_of[k] = if closer { block as u32 } else { block_of[k] };
        }
    }
    first_least(&least, &block_of)
}

/// The least of the lanes' least values, and of the slots holding it (lane `k` of block
/// `block_of[k]`) the first.
#[inline(always)]
fn first_least(least: &[f32; 8], block_of: &[u32; 8]) -> (f32, usize) {
    // Halving, with plain comparisons (the values are never NaN).
    let min = |a: f32, b: f32| if a < b { a } else { b };
    let half: [f32; 4] = std::array::from_fn(|k| min(least[k], least[k + 4]));
    let value = min(min(half[0], half[2]), min(half[1], half[3]));
    let mut slot = u32::MAX;
    for k in 0..8 {
        let here = if least[k] == value {
            block_of[k] * 8 + k as u32
        } else {
            u32::MAX
        };
        slot = slot.min(here);
    }
    (value, if slot == u32::MAX { 0 } else { slot as usize })
}

/// [`leaf_nearest`] in AVX2 registers: the same operations in the same order (no fused
/// multiply-add), so the same answer. The common arm sizes get the kernel with their number
/// of joints known: its loop over the joints unrolled and the query's broadcasts kept in
/// registers across the blocks (the loop's own work had been a third of the kernel's).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn leaf_nearest_avx2(
    coords: &[f32],
    q: &[f32],
    continuous: &[bool],
    blocks: usize,
) -> (f32, usize) {
    match q.len().min(continuous.len()) {
        6 => leaf_kernel_avx2::<6>(coords, q, continuous, blocks),
        7 => leaf_kernel_avx2::<7>(coords, q, continuous, blocks),
        8 => leaf_kernel_avx2::<8>(coords, q, continuous, blocks),
        _ => leaf_kernel_avx2::<0>(coords, q, continuous, blocks),
    }
}

/// The kernel of [`leaf_nearest_avx2`] over `DOF` joints (all of them when `DOF` is 0).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn leaf_kernel_avx2<const DOF: usize>(
    coords: &[f32],
    q: &[f32],
    continuous: &[bool],
    blocks: usize,
) -> (f32, usize) {
    use std::arch::x86_64::*;
    use std::f32::consts::TAU;
    let all = q.len().min(continuous.len());
    let dof = if DOF == 0 { all } else { DOF };
    assert!(dof <= all);
    assert!(blocks * 8 <= SLOTS && coords.len() >= dof * SLOTS);
    let (sign, tau) = (_mm256_set1_ps(-0.0), _mm256_set1_ps(TAU));
    let mut least = _mm256_set1_ps(f32::INFINITY);
    let mut block_of = _mm256_setzero_si256();
    for block in 0..blocks {
        let mut sum = _mm256_setzero_ps();
        for j in 0..dof {
            // SAFETY: j < dof and block < blocks, so the eight values lie inside `coords`
            // (asserted above).
            let c = _mm256_loadu_ps(coords.as_ptr().add(j * SLOTS + block * 8));
            let mut d = _mm256_sub_ps(_mm256_set1_ps(q[j]), c);
            if continuous[j] {
                // The way around the circle when shorter: |d| or 2π − |d| (the sign bit
                // cleared for |d|).
                d = _mm256_andnot_ps(sign, d);
                d = _mm256_min_ps(d, _mm256_sub_ps(tau, d));
            }
            sum = _mm256_add_ps(sum, _mm256_mul_ps(d, d));
        }
        let closer = _mm256_cmp_ps::<_CMP_LT_OQ>(sum, least);
        least = _mm256_blendv_ps(least, sum, closer);
        let this = _mm256_set1_epi32(block as i32);
        block_of = _mm256_blendv_epi8(block_of, this, _mm256_castps_si256(closer));
    }
    // [`first_least`] in registers: the least value in every lane, then the least slot
    // number among the lanes holding it.
    let m = _mm256_min_ps(least, _mm256_permute2f128_ps::<1>(least, least));
    let m = _mm256_min_ps(m, _mm256_shuffle_ps::<0b01_00_11_10>(m, m));
    let m = _mm256_min_ps(m, _mm256_shuffle_ps::<0b10_11_00_01>(m, m));
    let at_least = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_EQ_OQ>(least, m));
    let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let slot = _mm256_add_epi32(_mm256_slli_epi32::<3>(block_of), lane);
    let slot = _mm256_blendv_epi8(_mm256_set1_epi32(-1), slot, at_least);
    let slot = _mm256_min_epu32(slot, _mm256_permute2x128_si256::<1>(slot, slot));
    let slot = _mm256_min_epu32(slot, _mm256_shuffle_epi32::<0b01_00_11_10>(slot));
    let slot = _mm256_min_epu32(slot, _mm256_shuffle_epi32::<0b10_11_00_01>(slot));
    let slot = _mm256_cvtsi256_si32(slot) as u32;
    (
        _mm256_cvtss_f32(m),
        if slot == u32::MAX { 0 } else { slot as usize },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::config_space::wrap_angle;
    use rand::{Rng, SeedableRng};

    fn dist2(a: &[f64], b: &[f64], cont: &[bool]) -> f64 {
        (0..a.len())
            .map(|j| {
                let d = b[j] - a[j];
                let d = if cont[j] { wrap_angle(d) } else { d };
                d * d
            })
            .sum()
    }

    #[test]
    fn nearest_equals_a_linear_scan() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for (dof, cont) in [
            (8, vec![false, false, false, true, false, true, false, true]),
            (3, vec![true, true, true]),
            (2, vec![false, false]),
        ] {
            let mut points: Vec<Vec<f64>> = Vec::new();
            let mut idx = NearestIndex::new(&cont);
            for i in 0..3000u32 {
                // A branching random walk (as trees grow), with values on continuous joints
                // beyond ±π, and exact duplicates.
                let p: Vec<f64> = match i {
                    0 => vec![0.0; dof],
                    _ => {
                        let from = &points[rng.random_range(0..i as usize)];
                        if i % 97 == 0 {
                            from.clone()
                        } else {
                            from.iter()
                                .map(|v| v + rng.random_range(-0.3..0.3))
                                .collect()
                        }
                    }
                };
                idx.insert(&p, i);
                points.push(p);
                if i % 10 == 0 {
                    let q: Vec<f64> = (0..dof).map(|_| rng.random_range(-7.0..7.0)).collect();
                    let (got, d2) = idx.nearest(&q).unwrap();
                    let truth = points
                        .iter()
                        .map(|p| dist2(p, &q, &cont))
                        .fold(f64::INFINITY, f64::min);
                    assert!((d2 - truth).abs() < 1e-9, "dof {dof}, {i} points");
                    let direct = dist2(&points[got as usize], &q, &cont);
                    assert!((direct - truth).abs() < 1e-9);
                }
            }
        }
    }

    /// Every kernel the vector path has (six, seven and eight joints, and any other number)
    /// gives the portable kernel's answer, ties included.
    #[test]
    fn vector_kernel_equals_the_portable_one() {
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            let mut rng = rand::rngs::StdRng::seed_from_u64(11);
            let pattern = [false, true, false, true, false, true, false, true, true];
            for dof in [5, 6, 7, 8, 9] {
                let continuous = &pattern[..dof];
                for _ in 0..500 {
                    let blocks = rng.random_range(1..=SLOTS / 8);
                    let mut coords = vec![EMPTY; dof * SLOTS];
                    let filled = rng.random_range(1..=blocks * 8);
                    for j in 0..dof {
                        for k in 0..filled {
                            // Few distinct values, so ties between slots are common.
                            coords[j * SLOTS + k] = rng.random_range(-4..=4) as f32 * 0.75;
                        }
                    }
                    // Duplicates of slots in the same lane of an earlier block: exact ties.
                    for k in 8..filled {
                        if rng.random_bool(0.3) {
                            for j in 0..dof {
                                coords[j * SLOTS + k] = coords[j * SLOTS + k % 8];
                            }
                        }
                    }
                    let q: Vec<f32> = (0..dof).map(|_| rng.random_range(-3.2..3.2)).collect();
                    let portable = leaf_nearest(&coords, &q, continuous, blocks);
                    // SAFETY: the CPU has AVX2.
                    let vector = unsafe { leaf_nearest_avx2(&coords, &q, continuous, blocks) };
                    assert_eq!(portable, vector, "{dof} joints");
                }
            }
        }
    }

    /// A radius leaves out the exact distance only of a point surely beyond it, and otherwise
    /// the answer is the plain query's.
    #[test]
    fn radius_skips_only_points_surely_beyond_it() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let cont = [false, true, false, true, false, false, true, false];
        let mut idx = NearestIndex::new(&cont);
        let mut radius = Vec::new();
        let (mut skipped, mut kept) = (0, 0);
        for i in 0..600u32 {
            let p: Vec<f64> = (0..8).map(|_| rng.random_range(-3.0..3.0)).collect();
            idx.insert(&p, i);
            radius.push(if i % 5 == 0 {
                f64::INFINITY
            } else {
                rng.random_range(1.0..4.0)
            });
            let q: Vec<f64> = (0..8).map(|_| rng.random_range(-3.5..3.5)).collect();
            let (id, d2) = idx.nearest(&q).unwrap();
            match idx.nearest_unless_beyond(&q, &radius).unwrap() {
                (got, None) => {
                    assert_eq!(got, id);
                    assert!(
                        d2.sqrt() > radius[id as usize],
                        "{d2} within {}",
                        radius[id as usize]
                    );
                    skipped += 1;
                }
                (got, Some(exact)) => {
                    assert_eq!((got, exact), (id, d2));
                    kept += 1;
                }
            }
        }
        assert!(skipped > 50 && kept > 50, "{skipped} skipped, {kept} kept");
    }

    /// The query's set-up in vector registers copies, rounds and checks the range as the
    /// portable loop does (NaN and values on either side of each bound included).
    #[test]
    fn vector_query_copy_equals_the_portable_one() {
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            let mut rng = rand::rngs::StdRng::seed_from_u64(5);
            for dof in [3, 4, 5, 7, 8, 9] {
                let lo: Vec<f64> = (0..dof)
                    .map(|j| if j % 2 == 0 { -PI } else { -1e300 })
                    .collect();
                let hi: Vec<f64> = (0..dof)
                    .map(|j| if j % 2 == 0 { PI } else { 1e300 })
                    .collect();
                for _ in 0..2000 {
                    let p: Vec<f64> = (0..dof)
                        .map(|j| match rng.random_range(0..20) {
                            0 => f64::NAN,
                            1 => lo[j],
                            2 => hi[j],
                            _ => rng.random_range(-4.0..4.0),
                        })
                        .collect();
                    let (mut q, mut q32) = (vec![0.0; dof], vec![0.0f32; dof]);
                    let (mut v, mut v32) = (vec![0.0; dof], vec![0.0f32; dof]);
                    let inside = copy_query(&p, &lo, &hi, &mut q, &mut q32);
                    // SAFETY: the CPU has AVX2.
                    let vector = unsafe { copy_query_avx2(&p, &lo, &hi, &mut v, &mut v32) };
                    assert_eq!(inside, vector, "{p:?}");
                    let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&q), bits(&v));
                    let bits32 = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits32(&q32), bits32(&v32));
                }
            }
        }
    }

    #[test]
    fn many_duplicates_stay_findable() {
        let mut idx = NearestIndex::new(&[false, true]);
        for i in 0..200 {
            idx.insert(&[1.0, 3.0], i);
        }
        idx.insert(&[2.0, -3.0], 200);
        assert_eq!(idx.nearest(&[1.0, 3.1]).unwrap().0, 0);
        let (id, d2) = idx.nearest(&[2.0, 3.2]).unwrap();
        assert_eq!(id, 200);
        assert!((d2 - (TAU - 6.2).powi(2)).abs() < 1e-12);
    }
}
