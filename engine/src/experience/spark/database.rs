//! SPARK's database: radius retrieval (`d_radius`) under the pair metric. A vantage-point tree
//! over the distinct boxes finds the boxes near each query box, and only the entries holding
//! them are tested ([`index`](super::index)); a linear scan is the test oracle. Pairs equal up
//! to 1 cm share one entry.

use super::index::SparkIndex;
use super::primitive::SparkPair;
use crate::experience::database::{Database, Entries};
use crate::experience::file::{self, DbError};
use crate::experience::sampler::{LocalSampler, Retrieval};
use crate::experience::ExperienceParams;
use std::path::Path;

/// SPARK's database.
#[derive(Debug, Clone, Default)]
pub struct SparkDb {
    params: ExperienceParams,
    entries: Entries<SparkPair, Vec<i64>>,
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
        let keys = self.entries.keys();
        (0..keys.len())
            .filter(|&i| query.distance(&keys[i], &self.params) <= self.params.d_radius)
            .collect()
    }
}

impl Database for SparkDb {
    type Primitive = SparkPair;
    const NAME: &'static str = "SPARK";
    const FILE_NAME: &'static str = "spark.emberdb";

    fn params(&self) -> &ExperienceParams {
        &self.params
    }

    fn keys(&self) -> &[SparkPair] {
        self.entries.keys()
    }

    fn samplers(&self) -> &[LocalSampler] {
        self.entries.samplers()
    }

    fn insert(&mut self, key: SparkPair, configs: Vec<Vec<f64>>) {
        let dedup = key.dedup_key();
        let pair = key.clone();
        if let Some(i) = self.entries.insert(key, dedup, &configs) {
            self.search_index.add(i as u32, &pair, &self.params);
        }
    }

    fn retrieve(&self, primitives: &[SparkPair]) -> Retrieval<'_> {
        // `stamp[e]` = 1 + the last query pair that found entry `e` (0: none), so repeated
        // finds within one pair count once and the union needs no sorting of hit lists.
        let mut stamp = vec![0u32; self.len()];
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
        self.entries.gather(
            primitives.len(),
            found,
            union.into_iter().map(|e| e as usize),
        )
    }

    fn retrieve_linear(&self, primitives: &[SparkPair]) -> Retrieval<'_> {
        let mut hit = vec![false; self.len()];
        let mut found = 0;
        for p in primitives {
            for e in self.within_linear(p) {
                hit[e] = true;
                found += 1;
            }
        }
        let union = (0..hit.len()).filter(|&e| hit[e]);
        self.entries.gather(primitives.len(), found, union)
    }

    fn save(&self, path: &Path) -> Result<(), DbError> {
        file::save_spark(self, path)
    }

    fn load(path: &Path) -> Result<Self, DbError> {
        file::load_spark(path)
    }
}
