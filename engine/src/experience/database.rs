//! What every experience database is: primitive → [`LocalSampler`], with an exact retrieval
//! index and a linear-scan oracle, saved to and loaded from one file.
//!
//! [`Database`] is the contract ([`SparkDb`](super::SparkDb) and [`FlameDb`](super::FlameDb)
//! implement it, and the conformance tests in `engine/tests/it/experience.rs` run against both);
//! `Entries` is the storage they share.

use super::file::DbError;
use super::sampler::{LocalSampler, Retrieval};
use super::ExperienceParams;
use rustc_hash::FxHashMap;
use std::hash::Hash;
use std::path::Path;

/// An experience database: local primitives, each with the local sampler learned for it.
pub trait Database: Sized {
    /// The local primitive the database is keyed by.
    type Primitive: Clone;
    /// The method's name (`"SPARK"`, `"FLAME"`), as files and messages name it.
    const NAME: &'static str;
    /// The file name inside an experience folder.
    const FILE_NAME: &'static str;

    /// The hyperparameters (σ and λ of the sampler, the retrieval radius, ...).
    fn params(&self) -> &ExperienceParams;

    /// The stored primitives, in entry order.
    fn keys(&self) -> &[Self::Primitive];

    /// The stored local samplers, in entry order (one per primitive).
    fn samplers(&self) -> &[LocalSampler];

    /// Adds critical configurations for a primitive (merged into an equal primitive's entry).
    fn insert(&mut self, key: Self::Primitive, configs: Vec<Vec<f64>>);

    /// The local samplers of every entry the query primitives retrieve, each entry once.
    fn retrieve(&self, primitives: &[Self::Primitive]) -> Retrieval<'_>;

    /// The same retrieval (same samplers, same order, same counts) by a linear scan of the
    /// entries: the test oracle.
    fn retrieve_linear(&self, primitives: &[Self::Primitive]) -> Retrieval<'_>;

    /// Saves atomically to `path` (see [`file`](super::file)).
    fn save(&self, path: &Path) -> Result<(), DbError>;

    /// Loads a database saved by [`Database::save`].
    fn load(path: &Path) -> Result<Self, DbError>;

    /// Entries as (primitive, sampler), in entry order.
    fn entries(&self) -> impl ExactSizeIterator<Item = (&Self::Primitive, &LocalSampler)> {
        self.keys().iter().zip(self.samplers())
    }

    /// Number of entries (distinct primitives).
    fn len(&self) -> usize {
        self.keys().len()
    }

    /// True when empty.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Total stored configurations.
    fn configurations(&self) -> usize {
        self.samplers().iter().map(LocalSampler::len).sum()
    }

    /// Adds every entry of `other`.
    fn merge(&mut self, other: &Self) {
        for (k, s) in other.entries() {
            let means: Vec<Vec<f64>> = s.means().map(<[f64]>::to_vec).collect();
            self.insert(k.clone(), means);
        }
    }
}

/// A database's storage: primitives and their samplers side by side, and the map from a
/// primitive's deduplication key to its entry.
#[derive(Debug, Clone)]
pub(crate) struct Entries<K, D> {
    keys: Vec<K>,
    samplers: Vec<LocalSampler>,
    by_key: FxHashMap<D, usize>,
}

impl<K, D> Default for Entries<K, D> {
    fn default() -> Self {
        Entries {
            keys: Vec::new(),
            samplers: Vec::new(),
            by_key: FxHashMap::default(),
        }
    }
}

impl<K, D> Entries<K, D> {
    /// The primitives, in entry order.
    pub(crate) fn keys(&self) -> &[K] {
        &self.keys
    }

    /// The local samplers, in entry order.
    pub(crate) fn samplers(&self) -> &[LocalSampler] {
        &self.samplers
    }

    /// The retrieval of the entries `union` (in entry order), found `found` times in all.
    pub(crate) fn gather(
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
            r.push_sampler(&self.samplers[e]);
        }
        r
    }
}

impl<K, D: Hash + Eq> Entries<K, D> {
    /// Adds `configs` under `key` (deduplication key `dedup`): merged into the entry of an equal
    /// key, or a new entry, whose index is returned for the caller's retrieval index.
    pub(crate) fn insert(&mut self, key: K, dedup: D, configs: &[Vec<f64>]) -> Option<usize> {
        if configs.is_empty() {
            return None;
        }
        if let Some(&i) = self.by_key.get(&dedup) {
            self.samplers[i].add(configs);
            return None;
        }
        let i = self.keys.len();
        self.keys.push(key);
        let mut s = LocalSampler::default();
        s.add(configs);
        self.samplers.push(s);
        self.by_key.insert(dedup, i);
        Some(i)
    }
}
