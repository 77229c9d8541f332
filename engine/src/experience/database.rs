//! Experience databases: primitive → local sampler (the critical configurations, each the mean
//! of one Gaussian component).
//!
//! - [`SparkDb`]: radius retrieval (`d_radius`) in a vantage-point tree under the pair metric,
//!   with a linear scan kept as the test oracle. Pairs equal up to 1 cm share one entry.
//! - [`FlameDb`]: exact match of octobox position and mask (a hash lookup).

use super::primitive::{OctoboxPrimitive, SparkPair};
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
    pub fn retrieve(&self, primitives: &[SparkPair]) -> Retrieval {
        self.gather(primitives, |p| self.within(p))
    }

    /// The same retrieval by linear scan (the oracle, and the benchmark's reference).
    pub fn retrieve_linear(&self, primitives: &[SparkPair]) -> Retrieval {
        self.gather(primitives, |p| self.within_linear(p))
    }

    fn gather(
        &self,
        primitives: &[SparkPair],
        within: impl Fn(&SparkPair) -> Vec<usize>,
    ) -> Retrieval {
        let mut seen = vec![false; self.keys.len()];
        let mut r = Retrieval {
            query_primitives: primitives.len(),
            ..Default::default()
        };
        for p in primitives {
            for i in within(p) {
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
