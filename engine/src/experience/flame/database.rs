//! FLAME's database: octoboxes with the same occupancy mask whose centres lie within
//! `flame_radius` (a hash lookup by mask and coarse cell, [`index`](super::index)); a linear
//! scan is the test oracle. Equal octoboxes share one entry.

use super::index::{FlameIndex, FlameMetric};
use super::primitive::Octobox;
use crate::experience::database::{Database, Entries};
use crate::experience::file::{self, DbError};
use crate::experience::sampler::{LocalSampler, Retrieval};
use crate::experience::ExperienceParams;
use std::path::Path;

/// FLAME's database.
#[derive(Debug, Clone, Default)]
pub struct FlameDb {
    params: ExperienceParams,
    resolution: f64,
    entries: Entries<Octobox, Octobox>,
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

    /// Map resolution the keys refer to.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Entry indices matching `query`: the same occupancy mask, centres at most
    /// `flame_radius` apart (entry order).
    pub fn matches(&self, query: &Octobox) -> Vec<usize> {
        let mut out = Vec::new();
        self.search_index
            .search(std::slice::from_ref(query), |_, e| out.push(e as usize));
        out
    }

    /// Entry indices matching `query`, by linear scan (the oracle).
    pub fn matches_linear(&self, query: &Octobox) -> Vec<usize> {
        let metric = FlameMetric::new(&self.params, self.resolution);
        let keys = self.entries.keys();
        (0..keys.len())
            .filter(|&i| keys[i].mask == query.mask && metric.close(keys[i].key, query.key))
            .collect()
    }
}

impl Database for FlameDb {
    type Primitive = Octobox;
    const NAME: &'static str = "FLAME";
    const FILE_NAME: &'static str = "flame.emberdb";

    fn params(&self) -> &ExperienceParams {
        &self.params
    }

    fn keys(&self) -> &[Octobox] {
        self.entries.keys()
    }

    fn samplers(&self) -> &[LocalSampler] {
        self.entries.samplers()
    }

    fn insert(&mut self, key: Octobox, configs: Vec<Vec<f64>>) {
        if let Some(i) = self.entries.insert(key, key, &configs) {
            self.search_index.add(i as u32, &key);
        }
    }

    fn retrieve(&self, primitives: &[Octobox]) -> Retrieval<'_> {
        let mut seen = vec![false; self.len()];
        let (mut found, mut union) = (0, Vec::new());
        self.search_index.search(primitives, |_, e| {
            found += 1;
            if !std::mem::replace(&mut seen[e as usize], true) {
                union.push(e as usize);
            }
        });
        self.entries
            .gather(primitives.len(), found, union.into_iter())
    }

    fn retrieve_linear(&self, primitives: &[Octobox]) -> Retrieval<'_> {
        let mut seen = vec![false; self.len()];
        let (mut found, mut union) = (0, Vec::new());
        for p in primitives {
            for e in self.matches_linear(p) {
                found += 1;
                if !std::mem::replace(&mut seen[e], true) {
                    union.push(e);
                }
            }
        }
        self.entries
            .gather(primitives.len(), found, union.into_iter())
    }

    fn save(&self, path: &Path) -> Result<(), DbError> {
        file::save_flame(self, path)
    }

    fn load(path: &Path) -> Result<Self, DbError> {
        file::load_flame(path)
    }
}
