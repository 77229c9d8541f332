//! Experience databases: primitive → local sampler (the critical configurations, each the mean
//! of one Gaussian component).
//!
//! - [`SparkDb`]: radius retrieval (`d_radius`) in a vantage-point tree under the pair metric,
//!   with a linear scan kept as the test oracle. Pairs equal up to 1 cm share one entry.
//! - [`FlameDb`]: exact match of octobox position and mask (a hash lookup).

use super::primitive::{raw_distance, BoxPrimitive, OctoboxPrimitive, RawBox, SparkPair};
use super::vptree::VpTree;
use super::ExperienceParams;
use crate::world::map::BlockKey;
use rustc_hash::FxHashMap;

/// What one retrieval found: the retrieved local samplers, as flat component means.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Retrieval {
    /// Values per component.
    pub dof: usize,
    /// Component means, `dof` values each.
    pub means: Vec<f64>,
    /// Per retrieved local sampler: the range of its components.
    pub samplers: Vec<std::ops::Range<usize>>,
    /// Primitives of the query scene.
    pub query_primitives: usize,
    /// Entries retrieved (with repetitions across query primitives).
    pub entries: usize,
}

impl Retrieval {
    /// A retrieval holding the given local samplers (each a list of means of length `dof`).
    pub fn from_samplers(dof: usize, samplers: &[Vec<Vec<f64>>]) -> Self {
        let mut r = Retrieval {
            dof,
            ..Default::default()
        };
        for s in samplers {
            r.push_sampler(s);
        }
        r
    }

    /// Appends one local sampler (means of the wrong length are skipped).
    pub fn push_sampler(&mut self, means: &[Vec<f64>]) {
        if self.dof == 0 {
            self.dof = means.first().map_or(0, Vec::len);
        }
        if self.dof == 0 {
            return;
        }
        let start = self.means.len() / self.dof;
        for m in means.iter().filter(|m| m.len() == self.dof) {
            self.means.extend_from_slice(m);
        }
        let end = self.means.len() / self.dof;
        if end > start {
            self.samplers.push(start..end);
        }
    }
}

/// Removes duplicate means (exactly equal configurations).
fn dedup_means(values: &mut Vec<Vec<f64>>) {
    values.sort_by(|a, b| {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.total_cmp(y))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    values.dedup();
}

/// SPARK's database.
#[derive(Debug, Clone, Default)]
pub struct SparkDb {
    pub(crate) params: ExperienceParams,
    pub(crate) keys: Vec<SparkPair>,
    pub(crate) values: Vec<Vec<Vec<f64>>>,
    index: FxHashMap<Vec<i64>, usize>,
    tree: VpTree,
    /// The distinct boxes of the entries (pairs of one scene share them), and each entry's two.
    boxes: Boxes,
    entry_boxes: Vec<[u32; 2]>,
}

/// Distinct boxes, numbered in order of arrival (bit-exact equality).
#[derive(Debug, Clone, Default)]
struct Boxes {
    list: Vec<RawBox>,
    ids: FxHashMap<[u64; 10], u32>,
}

impl Boxes {
    fn id(&mut self, b: &BoxPrimitive) -> u32 {
        let raw = b.raw();
        let mut bits = [0u64; 10];
        for (slot, v) in bits
            .iter_mut()
            .zip(raw.t.iter().chain(&raw.q).chain(&raw.s))
        {
            *slot = v.to_bits();
        }
        let next = self.list.len() as u32;
        *self.ids.entry(bits).or_insert_with(|| {
            self.list.push(raw);
            next
        })
    }
}

impl SparkDb {
    /// An empty database using `params` for its metric and radius.
    pub fn new(params: ExperienceParams) -> Self {
        SparkDb {
            params,
            ..Default::default()
        }
    }

    /// The hyperparameters.
    pub fn params(&self) -> &ExperienceParams {
        &self.params
    }

    /// Number of entries (distinct primitives).
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Total stored configurations.
    pub fn configurations(&self) -> usize {
        self.values.iter().map(Vec::len).sum()
    }

    /// Entries as (primitive, configurations).
    pub fn entries(&self) -> impl Iterator<Item = (&SparkPair, &Vec<Vec<f64>>)> {
        self.keys.iter().zip(&self.values)
    }

    /// Adds critical configurations for a primitive (merged into an equal primitive's entry).
    pub fn insert(&mut self, key: SparkPair, configs: Vec<Vec<f64>>) {
        if configs.is_empty() {
            return;
        }
        let dk = key.dedup_key();
        if let Some(&i) = self.index.get(&dk) {
            self.values[i].extend(configs);
            dedup_means(&mut self.values[i]);
            return;
        }
        let i = self.keys.len();
        self.entry_boxes
            .push([self.boxes.id(&key.a), self.boxes.id(&key.b)]);
        self.keys.push(key);
        let mut configs = configs;
        dedup_means(&mut configs);
        self.values.push(configs);
        self.index.insert(dk, i);
        let (keys, params) = (&self.keys, &self.params);
        self.tree
            .insert(i, &|a, b| keys[a].distance(&keys[b], params));
    }

    /// Adds every entry of `other`.
    pub fn merge(&mut self, other: &SparkDb) {
        for (k, v) in other.entries() {
            self.insert(k.clone(), v.clone());
        }
    }

    /// Entry indices within `d_radius` of `query` (metric tree).
    pub fn within(&self, query: &SparkPair) -> Vec<usize> {
        let mut out = Vec::new();
        let r = self.params.d_radius;
        self.tree.within(
            r,
            &|i| query.distance(&self.keys[i], &self.params),
            &mut out,
        );
        out.sort_unstable();
        out
    }

    /// Entry indices within `d_radius` of `query` by linear scan (the oracle).
    pub fn within_linear(&self, query: &SparkPair) -> Vec<usize> {
        (0..self.keys.len())
            .filter(|&i| query.distance(&self.keys[i], &self.params) <= self.params.d_radius)
            .collect()
    }

    /// The local samplers of every entry near any of the scene's primitives (each entry once).
    ///
    /// The pair distances are assembled from box distances computed once per (query box,
    /// stored box), in one pass, and shared by every pair holding them: the same sums, bit for
    /// bit, as [`SparkPair::distance`], at a fraction of the cost.
    pub fn retrieve(&self, primitives: &[SparkPair]) -> Retrieval {
        let mut query = Boxes::default();
        let ids: Vec<[u32; 2]> = primitives
            .iter()
            .map(|p| [query.id(&p.a), query.id(&p.b)])
            .collect();
        // Every (query box, stored box) distance, computed in one branch-free pass: in the
        // low-variation scenes SPARK works on, the search needs most of them anyway.
        let nb = self.boxes.list.len();
        let mut table = vec![0.0; query.list.len() * nb];
        for (row, qb) in table.chunks_exact_mut(nb.max(1)).zip(&query.list) {
            for (d, eb) in row.iter_mut().zip(&self.boxes.list) {
                *d = raw_distance(qb, eb, &self.params);
            }
        }
        let box_distance = |q: u32, e: u32| table[q as usize * nb + e as usize];
        self.gather(primitives, |k, _| {
            let [qa, qb] = ids[k];
            let d = |i: usize| {
                let [ea, eb] = self.entry_boxes[i];
                let straight = box_distance(qa, ea) + box_distance(qb, eb);
                let crossed = box_distance(qa, eb) + box_distance(qb, ea);
                straight.min(crossed)
            };
            let mut out = Vec::new();
            self.tree.within(self.params.d_radius, &d, &mut out);
            // Entry order, as the linear scan: the sampler does not depend on tree layout.
            out.sort_unstable();
            out
        })
    }

    /// The same retrieval by linear scan with [`SparkPair::distance`] (the oracle, and the
    /// benchmark's reference).
    pub fn retrieve_linear(&self, primitives: &[SparkPair]) -> Retrieval {
        self.gather(primitives, |_, p| self.within_linear(p))
    }

    /// Collects the samplers of the entries `within(k, primitive)` finds for each primitive.
    fn gather(
        &self,
        primitives: &[SparkPair],
        within: impl Fn(usize, &SparkPair) -> Vec<usize>,
    ) -> Retrieval {
        let mut seen = vec![false; self.keys.len()];
        let mut r = Retrieval {
            query_primitives: primitives.len(),
            ..Default::default()
        };
        for (k, p) in primitives.iter().enumerate() {
            for i in within(k, p) {
                r.entries += 1;
                if !std::mem::replace(&mut seen[i], true) {
                    r.push_sampler(&self.values[i]);
                }
            }
        }
        r
    }

    /// Rebuilds the metric tree over all entries (after loading).
    pub(crate) fn reindex(&mut self) {
        self.boxes = Boxes::default();
        self.entry_boxes = self
            .keys
            .iter()
            .map(|k| [self.boxes.id(&k.a), self.boxes.id(&k.b)])
            .collect();
        self.index = self
            .keys
            .iter()
            .enumerate()
            .map(|(i, k)| (k.dedup_key(), i))
            .collect();
        let (keys, params) = (&self.keys, &self.params);
        let mut tree = VpTree::default();
        tree.build((0..keys.len()).collect(), &|a, b| {
            keys[a].distance(&keys[b], params)
        });
        self.tree = tree;
    }
}

/// FLAME's database.
#[derive(Debug, Clone, Default)]
pub struct FlameDb {
    pub(crate) params: ExperienceParams,
    pub(crate) resolution: f64,
    pub(crate) entries: FxHashMap<(BlockKey, u64), Vec<Vec<f64>>>,
}

impl FlameDb {
    /// An empty database for maps of `resolution`.
    pub fn new(params: ExperienceParams, resolution: f64) -> Self {
        FlameDb {
            params,
            resolution,
            entries: FxHashMap::default(),
        }
    }

    /// The hyperparameters.
    pub fn params(&self) -> &ExperienceParams {
        &self.params
    }

    /// Map resolution the keys refer to.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Total stored configurations.
    pub fn configurations(&self) -> usize {
        self.entries.values().map(Vec::len).sum()
    }

    /// Adds critical configurations for an octobox.
    pub fn insert(&mut self, key: OctoboxPrimitive, configs: Vec<Vec<f64>>) {
        if configs.is_empty() {
            return;
        }
        let v = self.entries.entry((key.key, key.mask)).or_default();
        v.extend(configs);
        dedup_means(v);
    }

    /// Adds every entry of `other`.
    pub fn merge(&mut self, other: &FlameDb) {
        for ((k, m), v) in &other.entries {
            self.insert(OctoboxPrimitive { key: *k, mask: *m }, v.clone());
        }
    }

    /// The local samplers of the octoboxes that match exactly.
    pub fn retrieve(&self, primitives: &[OctoboxPrimitive]) -> Retrieval {
        let mut r = Retrieval {
            query_primitives: primitives.len(),
            ..Default::default()
        };
        for p in primitives {
            if let Some(v) = self.entries.get(&(p.key, p.mask)) {
                r.entries += 1;
                r.push_sampler(v);
            }
        }
        r
    }
}
