//! Experience databases: primitive → local sampler (the critical configurations, each the mean
//! of one Gaussian component).
//!
//! - [`SparkDb`]: radius retrieval (`d_radius`) under the pair metric: a vantage-point tree
//!   over the distinct boxes finds the boxes near each query box, and only the entries holding
//!   them are tested; a linear scan is kept as the test oracle. Pairs equal up to 1 cm share one
//!   entry.
//! - [`FlameDb`]: octoboxes with the same occupancy mask whose centres lie within
//!   `flame_radius` (a hash lookup by mask and coarse cell, `flame_index.rs`).

use super::flame_index::{FlameIndex, FlameMetric};
use super::primitive::{OctoboxPrimitive, SparkPair};
use super::spark_index::SparkIndex;
use super::ExperienceParams;
use crate::world::map::BlockKey;
use rustc_hash::FxHashMap;
use std::borrow::Cow;

/// What one retrieval found: the retrieved local samplers, each the list of its components'
/// means. Samplers found in a database borrow its storage: nothing is copied.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Retrieval<'a> {
    /// Per retrieved local sampler: its component means.
    pub samplers: Vec<Cow<'a, [Vec<f64>]>>,
    /// Primitives of the query scene.
    pub query_primitives: usize,
    /// Entries retrieved (with repetitions across query primitives).
    pub entries: usize,
}

impl<'a> Retrieval<'a> {
    /// A retrieval holding the given local samplers (each a list of means).
    pub fn from_samplers(samplers: Vec<Vec<Vec<f64>>>) -> Self {
        Retrieval {
            samplers: samplers
                .into_iter()
                .filter(|s| !s.is_empty())
                .map(Cow::Owned)
                .collect(),
            ..Default::default()
        }
    }

    /// Appends one local sampler, borrowed (an empty one is skipped).
    pub fn push_sampler(&mut self, means: &'a [Vec<f64>]) {
        if !means.is_empty() {
            self.samplers.push(Cow::Borrowed(means));
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
    /// The retrieval index over the entries.
    search_index: SparkIndex,
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
        self.search_index.add(i as u32, &key, &self.params);
        self.keys.push(key);
        let mut configs = configs;
        dedup_means(&mut configs);
        self.values.push(configs);
        self.index.insert(dk, i);
    }

    /// Adds every entry of `other`.
    pub fn merge(&mut self, other: &SparkDb) {
        for (k, v) in other.entries() {
            self.insert(k.clone(), v.clone());
        }
    }

    /// Entry indices within `d_radius` of `query` (metric tree), in entry order.
    pub fn within(&self, query: &SparkPair) -> Vec<usize> {
        let mut hits = Vec::new();
        self.search_index
            .search(&self.params, std::slice::from_ref(query), |_, e| {
                hits.push(e as usize)
            });
        hits.sort_unstable();
        hits.dedup();
        hits
    }

    /// Entry indices within `d_radius` of `query` by linear scan (the oracle), in entry order.
    pub fn within_linear(&self, query: &SparkPair) -> Vec<usize> {
        (0..self.keys.len())
            .filter(|&i| query.distance(&self.keys[i], &self.params) <= self.params.d_radius)
            .collect()
    }

    /// The local samplers of every entry near any of the scene's primitives, each entry once
    /// and in entry order.
    pub fn retrieve(&self, primitives: &[SparkPair]) -> Retrieval<'_> {
        // `stamp[e]` = 1 + the last query pair that found entry `e` (0: none), so repeated
        // finds within one pair count once and the union needs no sorting of hit lists.
        let mut stamp = vec![0u32; self.keys.len()];
        let (mut found, mut union) = (0, Vec::new());
        self.search_index.search(&self.params, primitives, |p, e| {
            let s = &mut stamp[e as usize];
            if *s != p + 1 {
                if *s == 0 {
                    union.push(e);
                }
                *s = p + 1;
                found += 1;
            }
        });
        union.sort_unstable();
        self.gather(
            primitives.len(),
            found,
            union.into_iter().map(|e| e as usize),
        )
    }

    /// The same retrieval by linear scan with [`SparkPair::distance`] (the oracle, and the
    /// benchmark's reference).
    pub fn retrieve_linear(&self, primitives: &[SparkPair]) -> Retrieval<'_> {
        let mut hit = vec![false; self.keys.len()];
        let mut found = 0;
        for p in primitives {
            for e in self.within_linear(p) {
                hit[e] = true;
                found += 1;
            }
        }
        let union = (0..hit.len()).filter(|&e| hit[e]);
        self.gather(primitives.len(), found, union)
    }

    /// The retrieval of the entries `union` (in entry order), found `found` times in all.
    fn gather(
        &self,
        query_primitives: usize,
        found: usize,
        union: impl Iterator<Item = usize>,
    ) -> Retrieval<'_> {
        let mut r = Retrieval {
            query_primitives,
            entries: found,
            ..Default::default()
        };
        for e in union {
            r.push_sampler(&self.values[e]);
        }
        r
    }
}

/// FLAME's database.
#[derive(Debug, Clone, Default)]
pub struct FlameDb {
    pub(crate) params: ExperienceParams,
    pub(crate) resolution: f64,
    pub(crate) keys: Vec<OctoboxPrimitive>,
    pub(crate) values: Vec<Vec<Vec<f64>>>,
    index: FxHashMap<(BlockKey, u64), usize>,
    /// The match index over the entries.
    search_index: FlameIndex,
}

impl FlameDb {
    /// An empty database for maps of `resolution`.
    pub fn new(params: ExperienceParams, resolution: f64) -> Self {
        FlameDb {
            search_index: FlameIndex::new(FlameMetric::new(&params, resolution)),
            params,
            resolution,
            ..Default::default()
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

    /// Entries as (octobox, configurations).
    pub fn entries(&self) -> impl Iterator<Item = (&OctoboxPrimitive, &Vec<Vec<f64>>)> {
        self.keys.iter().zip(&self.values)
    }

    /// Adds critical configurations for an octobox.
    pub fn insert(&mut self, key: OctoboxPrimitive, configs: Vec<Vec<f64>>) {
        if configs.is_empty() {
            return;
        }
        if let Some(&i) = self.index.get(&(key.key, key.mask)) {
            self.values[i].extend(configs);
            dedup_means(&mut self.values[i]);
            return;
        }
        let i = self.keys.len();
        self.search_index.add(i as u32, &key);
        self.index.insert((key.key, key.mask), i);
        self.keys.push(key);
        let mut configs = configs;
        dedup_means(&mut configs);
        self.values.push(configs);
    }

    /// Adds every entry of `other`.
    pub fn merge(&mut self, other: &FlameDb) {
        for (k, v) in other.entries() {
            self.insert(*k, v.clone());
        }
    }

    /// Entry indices matching `query`: the same occupancy mask, centres at most
    /// `flame_radius` apart (entry order).
    pub fn matches(&self, query: &OctoboxPrimitive) -> Vec<usize> {
        let mut out = Vec::new();
        self.search_index
            .search(std::slice::from_ref(query), |_, e| out.push(e as usize));
        out
    }

    /// Entry indices matching `query`, by linear scan (the oracle).
    pub fn matches_linear(&self, query: &OctoboxPrimitive) -> Vec<usize> {
        let metric = FlameMetric::new(&self.params, self.resolution);
        (0..self.keys.len())
            .filter(|&i| {
                let k = &self.keys[i];
                k.mask == query.mask && metric.close(k.key, query.key)
            })
            .collect()
    }

    /// The local samplers of the stored octoboxes that match the query's (each entry once).
    pub fn retrieve(&self, primitives: &[OctoboxPrimitive]) -> Retrieval<'_> {
        let mut seen = vec![false; self.keys.len()];
        let mut r = Retrieval {
            query_primitives: primitives.len(),
            ..Default::default()
        };
        self.search_index.search(primitives, |_, e| {
            r.entries += 1;
            if !std::mem::replace(&mut seen[e as usize], true) {
                r.push_sampler(&self.values[e as usize]);
            }
        });
        r
    }
}
