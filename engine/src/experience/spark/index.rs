//! SPARK's retrieval index: the distinct boxes of the stored pairs, a metric tree over them, and
//! per box the entries that hold it.
//!
//! A pair is within `r` of a query pair only if, in one of the two pairings, each of its boxes
//! lies within `r` of its counterpart (box distances are not negative). So the tree finds the
//! boxes near each query box, and only the entries holding such a box are tested, with the same
//! sums, bit for bit, as [`SparkPair::distance`].

use super::primitive::{raw_distance, BoxPrimitive, RawBox, SparkPair};
use super::vptree::VpTree;
use crate::experience::{prefetch, ExperienceParams};
use rustc_hash::FxHashMap;

/// The index over a database's entries (numbered by the database).
#[derive(Debug, Clone, Default)]
pub(crate) struct SparkIndex {
    boxes: Boxes,
    /// Per box, the entries holding it, each with its other box.
    box_entries: Vec<Vec<[u32; 2]>>,
    /// The metric tree over the distinct boxes (box metric), with their ids.
    tree: VpTree<(RawBox, u32)>,
}

/// Distinct boxes, numbered in order of arrival (bit-exact equality).
#[derive(Debug, Clone, Default)]
struct Boxes {
    list: Vec<RawBox>,
    ids: FxHashMap<[u64; 10], u32>,
}

impl Boxes {
    /// The id of `b`, and whether it is new.
    fn id(&mut self, b: &BoxPrimitive) -> (u32, bool) {
        let raw = b.raw();
        let mut bits = [0u64; 10];
        for (slot, v) in bits
            .iter_mut()
            .zip(raw.t.iter().chain(&raw.q).chain(&raw.s))
        {
            *slot = v.to_bits();
        }
        let next = self.list.len() as u32;
        let id = *self.ids.entry(bits).or_insert(next);
        if id == next {
            self.list.push(raw);
        }
        (id, id == next)
    }
}

impl SparkIndex {
    /// Indexes entry `entry`, whose key is `pair`.
    pub fn add(&mut self, entry: u32, pair: &SparkPair, params: &ExperienceParams) {
        let a = self.add_box(&pair.a, params);
        let b = self.add_box(&pair.b, params);
        self.box_entries[a as usize].push([entry, b]);
        if a != b {
            self.box_entries[b as usize].push([entry, a]);
        }
    }

    /// The id of a box, indexing it in the tree when it is new.
    fn add_box(&mut self, b: &BoxPrimitive, params: &ExperienceParams) -> u32 {
        let (id, new) = self.boxes.id(b);
        if new {
            self.box_entries.push(Vec::new());
            self.tree
                .insert((b.raw(), id), |x, y| raw_distance(&x.0, &y.0, params));
        }
        id
    }

    /// Calls `hit(p, e)` for each query pair `p` and entry `e` within `d_radius` of it (an
    /// entry may be reported more than once per pair).
    pub fn search(
        &self,
        params: &ExperienceParams,
        primitives: &[SparkPair],
        mut hit: impl FnMut(u32, u32),
    ) {
        let r = params.d_radius;
        let mut query = Boxes::default();
        let ids: Vec<[u32; 2]> = primitives
            .iter()
            .map(|p| [query.id(&p.a).0, query.id(&p.b).0])
            .collect();
        let (nq, nb) = (query.list.len(), self.boxes.list.len());
        // Per query box: its near boxes, and the same as a bit set for quick rejection. Their
        // distances: `slot[box]` indexes `dist`, `nq` values per near box (infinite where the box
        // is not near that query box).
        const FAR: u32 = u32::MAX;
        let words = nb.div_ceil(64);
        let mut bits = vec![0u64; nq * words];
        let mut slot = vec![FAR; nb];
        let mut dist: Vec<f64> = Vec::new();
        let mut near: Vec<Vec<u32>> = vec![Vec::new(); nq];
        for (qi, qb) in query.list.iter().enumerate() {
            let d = |b: &(RawBox, u32)| raw_distance(qb, &b.0, params);
            self.tree.within(r, d, |b, known| {
                let id = b.1 as usize;
                if slot[id] == FAR {
                    slot[id] = (dist.len() / nq) as u32;
                    dist.resize(dist.len() + nq, f64::INFINITY);
                }
                // Subtrees reported wholesale come without distances.
                dist[slot[id] as usize * nq + qi] = known.unwrap_or_else(|| d(b));
                bits[qi * words + id / 64] |= 1 << (id % 64);
                near[qi].push(b.1);
            });
        }
        let is_near =
            |q: u32, b: u32| bits[q as usize * words + b as usize / 64] >> (b % 64) & 1 != 0;
        let d = |q: u32, b: u32| dist[slot[b as usize] as usize * nq + q as usize];
        // An entry within `r` holds a box near each of the query pair's boxes, so the entries
        // of either query box's near boxes are enough: take the shorter list (a box every scene
        // shares, like the floor, is in thousands of entries).
        let candidates: Vec<usize> = near
            .iter()
            .map(|n| n.iter().map(|&b| self.box_entries[b as usize].len()).sum())
            .collect();
        for (p, &[qa, qb]) in ids.iter().enumerate() {
            let (s, t) = if candidates[qa as usize] <= candidates[qb as usize] {
                (qa, qb)
            } else {
                (qb, qa)
            };
            let near_s = &near[s as usize];
            for (k, &b) in near_s.iter().enumerate() {
                // The lists are scattered on the heap: start loading one a few boxes ahead.
                if let Some(&ahead) = near_s.get(k + 4) {
                    prefetch(self.box_entries[ahead as usize].as_ptr());
                }
                let (d_sb, b_near_t) = (d(s, b), is_near(t, b));
                for &[e, o] in &self.box_entries[b as usize] {
                    // The smaller of the two pairings' sums (the same sums as
                    // `SparkPair::distance`, whichever of the entry's boxes `b` is).
                    let via_b = if is_near(t, o) {
                        d_sb + d(t, o)
                    } else {
                        f64::INFINITY
                    };
                    let via_o = if b_near_t && is_near(s, o) {
                        d(s, o) + d(t, b)
                    } else {
                        f64::INFINITY
                    };
                    if via_b.min(via_o) <= r {
                        hit(p as u32, e);
                    }
                }
            }
        }
    }
}
