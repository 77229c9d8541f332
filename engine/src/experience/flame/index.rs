//! FLAME's match index: entries listed by occupancy mask and coarse cell of the octobox lattice.
//!
//! Two octoboxes match when their masks are equal and their centres lie at most `flame_radius`
//! apart, i.e. when their lattice keys differ by at most `max_d2` in squared lattice distance
//! ([`FlameMetric`]). Cells are `2^shift ≥ 2·reach` octoboxes a side (`reach` the largest
//! per-axis offset that can match), so an entry is listed in at most two cells per axis (eight in
//! all) and a query octobox reads one list: a shift instead of a division finds it, and the list
//! holds each candidate's key, so testing it reads no entry.

use super::primitive::Octobox;
use crate::experience::{prefetch, ExperienceParams};
use crate::world::map::BlockKey;

/// The exact match test on lattice keys, shared by the index and the linear-scan oracle.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct FlameMetric {
    /// Largest squared lattice distance that matches.
    max_d2: i64,
    /// Largest per-axis offset that matches: ⌊√max_d2⌋.
    reach: i32,
}

impl FlameMetric {
    /// The test for maps of leaf size `resolution`: centres of octoboxes (4 leaves a side) at
    /// most `flame_radius` apart, with 1e-12 m² of slack against rounding.
    pub fn new(params: &ExperienceParams, resolution: f64) -> Self {
        let side = 4.0 * resolution;
        let limit = params.flame_radius.powi(2) + 1e-12;
        if side.is_nan() || side <= 0.0 || !limit.is_finite() {
            return FlameMetric::default();
        }
        // The largest integer d² with d²·side² ≤ limit, evaluated as the float test it replaces
        // (capped: a radius a million octoboxes long matches everything a map can hold anyway).
        const CAP: i64 = 1_000_000_000_000;
        let fits = |d2: i64| d2 as f64 * side * side <= limit;
        let mut max_d2 = (limit / (side * side)).floor().clamp(0.0, CAP as f64) as i64;
        while max_d2 > 0 && !fits(max_d2) {
            max_d2 -= 1;
        }
        while max_d2 < CAP && fits(max_d2 + 1) {
            max_d2 += 1;
        }
        let mut reach = (max_d2 as f64).sqrt() as i64;
        while reach * reach > max_d2 {
            reach -= 1;
        }
        while (reach + 1) * (reach + 1) <= max_d2 {
            reach += 1;
        }
        FlameMetric {
            max_d2,
            reach: reach as i32,
        }
    }

    /// True when octoboxes at keys `a` and `b` are close enough to match.
    #[inline(always)]
    pub fn close(&self, a: BlockKey, b: BlockKey) -> bool {
        let d = |i: usize| a[i] as i64 - b[i] as i64;
        d(0) * d(0) + d(1) * d(1) + d(2) * d(2) <= self.max_d2
    }
}

/// One listing of an entry in a cell: the entry's number and its octobox's key.
#[derive(Debug, Clone, Copy)]
struct Listing {
    key: BlockKey,
    entry: u32,
}

/// One cell of one mask: the entries whose reach overlaps it (none: an empty slot).
#[derive(Debug, Clone, Default)]
struct Slot {
    mask: u64,
    cell: BlockKey,
    listings: Vec<Listing>,
}

/// The index over a database's octoboxes (numbered by the database).
///
/// Its cells live in one open-addressing table (linear probing, at most ¾ full) keyed by mask and
/// cell, so a query octobox costs one probe and one list. The index is cold in the usual case
/// (one retrieval per plan), so two things keep cache misses down: a bit filter of 16 bits per
/// slot (small enough to stay cached) turns away most query octoboxes whose cell holds nothing
/// without touching the table; and queries are pipelined, the table slot of the query [`AHEAD`]
/// places further on being prefetched while the next one's list is fetched.
#[derive(Debug, Clone, Default)]
pub(crate) struct FlameIndex {
    metric: FlameMetric,
    /// log2 of the cell side, in octoboxes.
    shift: u32,
    /// The table; its length is zero or a power of two.
    slots: Vec<Slot>,
    /// Occupied slots.
    occupied: usize,
    /// Bit filter over the occupied slots' keys (16 bits per slot): a clear bit proves a key
    /// absent.
    filter: Vec<u64>,
}

/// How many queries ahead each pipeline stage of [`FlameIndex::search`] runs.
const AHEAD: usize = 8;

impl FlameIndex {
    /// An empty index matching under `metric`.
    pub fn new(metric: FlameMetric) -> Self {
        let side = (2 * metric.reach as u32).max(1);
        FlameIndex {
            metric,
            shift: side.next_power_of_two().trailing_zeros(),
            ..Default::default()
        }
    }

    /// The cell holding lattice key `key`.
    #[inline(always)]
    fn cell(&self, key: BlockKey) -> BlockKey {
        key.map(|v| v >> self.shift)
    }

    /// The hash of (`mask`, `cell`).
    #[inline(always)]
    fn hash(mask: u64, cell: BlockKey) -> u64 {
        let c =
            (cell[0] as u32 as u64) << 42 ^ (cell[1] as u32 as u64) << 21 ^ cell[2] as u32 as u64;
        (mask ^ c.wrapping_mul(0x9E37_79B9_7F4A_7C15)).wrapping_mul(0xD6E8_FEB8_6659_FD93)
    }

    /// The first slot to probe for hash `h`; the table must not be empty.
    #[inline(always)]
    fn home(&self, h: u64) -> usize {
        (h >> (64 - self.slots.len().trailing_zeros())) as usize
    }

    /// The filter bit of hash `h`: (word, bit); the table must not be empty.
    #[inline(always)]
    fn filter_bit(&self, h: u64) -> (usize, u32) {
        let bits = 64 * self.filter.len();
        let f = (h ^ h >> 29).wrapping_mul(0x94D0_49BB_1331_11EB) >> (64 - bits.trailing_zeros());
        (f as usize / 64, f as u32 % 64)
    }

    /// True when the filter lets hash `h` through (its key may be present).
    #[inline(always)]
    fn may_hold(&self, h: u64) -> bool {
        let (word, bit) = self.filter_bit(h);
        self.filter[word] >> bit & 1 != 0
    }

    /// The slot holding (`mask`, `cell`) of hash `h`, or the empty slot where it would go.
    #[inline(always)]
    fn probe(&self, mask: u64, cell: BlockKey, h: u64) -> usize {
        let wrap = self.slots.len() - 1;
        let mut i = self.home(h);
        loop {
            let s = &self.slots[i];
            if s.listings.is_empty() || (s.mask == mask && s.cell == cell) {
                return i;
            }
            i = (i + 1) & wrap;
        }
    }

    /// Indexes entry `entry`, whose key is `octobox`.
    pub fn add(&mut self, entry: u32, octobox: &Octobox) {
        let reach = self.metric.reach;
        let lo = self.cell(octobox.key.map(|v| v.saturating_sub(reach)));
        let hi = self.cell(octobox.key.map(|v| v.saturating_add(reach)));
        let listing = Listing {
            key: octobox.key,
            entry,
        };
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    self.list(octobox.mask, [x, y, z], listing);
                }
            }
        }
    }

    /// Appends `listing` to the list of (`mask`, `cell`), growing the table when ¾ full.
    fn list(&mut self, mask: u64, cell: BlockKey, listing: Listing) {
        if 4 * (self.occupied + 1) > 3 * self.slots.len() {
            let old = std::mem::take(&mut self.slots);
            self.slots = vec![Slot::default(); (2 * old.len()).max(64)];
            self.filter = vec![0; self.slots.len() / 4];
            self.occupied = 0;
            for s in old.into_iter().filter(|s| !s.listings.is_empty()) {
                let h = Self::hash(s.mask, s.cell);
                let i = self.probe(s.mask, s.cell, h);
                self.occupy(i, h, s);
            }
        }
        let h = Self::hash(mask, cell);
        let i = self.probe(mask, cell, h);
        if self.slots[i].listings.is_empty() {
            let listings = Vec::new();
            self.occupy(
                i,
                h,
                Slot {
                    mask,
                    cell,
                    listings,
                },
            );
        }
        self.slots[i].listings.push(listing);
    }

    /// Puts `slot` (of hash `h`) in the empty slot `i`.
    fn occupy(&mut self, i: usize, h: u64, slot: Slot) {
        let (word, bit) = self.filter_bit(h);
        self.filter[word] |= 1 << bit;
        self.slots[i] = slot;
        self.occupied += 1;
    }

    /// Calls `hit(q, e)` for each query octobox `q` (its index in `queries`) and each entry `e`
    /// matching it, queries in order and entries in listing (entry) order per query.
    pub fn search(&self, queries: &[Octobox], mut hit: impl FnMut(usize, u32)) {
        if self.slots.is_empty() {
            return;
        }
        const RING: usize = 2 * AHEAD;
        // Three stages, AHEAD queries apart: filter, and prefetch the home slot; probe it and
        // prefetch the list; test the list.
        let mut hashes = [None; RING];
        let mut lists: [&[Listing]; RING] = [&[]; RING];
        for i in 0..queries.len() + 2 * AHEAD {
            if let Some(query) = queries.get(i) {
                let h = Self::hash(query.mask, self.cell(query.key));
                let pass = self.may_hold(h);
                if pass {
                    prefetch(&self.slots[self.home(h)]);
                }
                hashes[i % RING] = pass.then_some(h);
            }
            if let Some(q) = i.checked_sub(AHEAD).filter(|&q| q < queries.len()) {
                lists[q % RING] = match hashes[q % RING] {
                    Some(h) => {
                        let (mask, cell) = (queries[q].mask, self.cell(queries[q].key));
                        let list = &self.slots[self.probe(mask, cell, h)].listings;
                        prefetch(list.as_ptr());
                        list
                    }
                    None => &[],
                };
            }
            if let Some(q) = i.checked_sub(2 * AHEAD) {
                let query = queries[q].key;
                for l in lists[q % RING] {
                    if self.metric.close(l.key, query) {
                        hit(q, l.entry);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metric(flame_radius: f64, resolution: f64) -> FlameMetric {
        let params = ExperienceParams {
            flame_radius,
            ..Default::default()
        };
        FlameMetric::new(&params, resolution)
    }

    #[test]
    fn the_metric_is_the_largest_lattice_distance_within_the_radius() {
        // 0.2 m over 0.08 m octoboxes: 2.5 octoboxes, so d² ≤ 6 and at most 2 along one axis.
        let m = metric(0.2, 0.02);
        assert_eq!((m.max_d2, m.reach), (6, 2));
        assert!(m.close([0, 0, 0], [2, 1, 1]) && !m.close([0, 0, 0], [2, 2, 0]));
        // Exactly on the radius still matches (0.16 m = 2 octoboxes).
        let on_radius = metric(0.16, 0.02);
        assert_eq!((on_radius.max_d2, on_radius.reach), (4, 2));
        assert_eq!(metric(0.05, 0.02).reach, 0);
    }

    #[test]
    fn degenerate_parameters_give_a_bounded_metric() {
        for (radius, resolution) in [
            (1e9, 0.02),
            (f64::INFINITY, 0.02),
            (f64::NAN, 0.02),
            (0.2, 0.0),
            (0.2, -1.0),
            (0.2, f64::NAN),
        ] {
            let m = metric(radius, resolution);
            assert!(
                m.max_d2 <= 1_000_000_000_000 && m.reach <= 1_000_000,
                "{m:?}"
            );
            // An index over it still works.
            let mut index = FlameIndex::new(m);
            let octobox = Octobox {
                key: [1, -2, 3],
                mask: 7,
            };
            index.add(0, &octobox);
            let mut hits = Vec::new();
            index.search(&[octobox], |q, e| hits.push((q, e)));
            assert_eq!(hits, [(0, 0)], "{radius} {resolution}");
        }
    }
}
