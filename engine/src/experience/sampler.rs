//! Samplers built from experience.
//!
//! - [`LocalSampler`]: what a database stores per primitive — the critical configurations, each
//!   the mean of one Gaussian component;
//! - [`Retrieval`]: the local samplers one query found;
//! - [`GlobalSampler`]: with probability λ a uniform sample; otherwise a uniformly chosen
//!   retrieved local sampler, one of its components uniformly, plus N(0, σ²) per joint, clamped
//!   to the limits (wrapped for continuous joints). Nothing retrieved: uniform.

use crate::planning::{PlannerRng, Sampler};
use crate::robot::Robot;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use std::borrow::Cow;

/// A local sampler: the means of its Gaussian components, `dof` values each, stored flat.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LocalSampler {
    dof: usize,
    means: Vec<f64>,
}

impl LocalSampler {
    /// A sampler with the given means, in the given order (all of one length).
    ///
    /// ```
    /// use ember_engine::experience::LocalSampler;
    /// let s = LocalSampler::from_means(&[vec![0.0, 1.0], vec![2.0, 3.0]]);
    /// assert_eq!((s.len(), s.dof()), (2, 2));
    /// assert_eq!(s.mean(1), &[2.0, 3.0]);
    /// ```
    pub fn from_means(means: &[Vec<f64>]) -> Self {
        let dof = means.first().map_or(0, Vec::len);
        LocalSampler {
            dof,
            means: means
                .iter()
                .filter(|m| m.len() == dof)
                .flatten()
                .copied()
                .collect(),
        }
    }

    /// Values per mean (the robot's joints).
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// Number of components.
    pub fn len(&self) -> usize {
        self.means.len().checked_div(self.dof).unwrap_or(0)
    }

    /// True when the sampler has no component.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// The mean of component `i`.
    pub fn mean(&self, i: usize) -> &[f64] {
        &self.means[i * self.dof..(i + 1) * self.dof]
    }

    /// The component means, in order.
    pub fn means(&self) -> impl ExactSizeIterator<Item = &[f64]> + '_ {
        self.means.chunks_exact(self.dof.max(1))
    }

    /// Adds means and keeps the set sorted (lexicographically) and free of exact duplicates: the
    /// form a database stores. Means of another length than the first stored are ignored.
    pub fn add(&mut self, means: &[Vec<f64>]) {
        if self.dof == 0 {
            self.dof = means.first().map_or(0, Vec::len);
        }
        let dof = self.dof;
        if dof == 0 {
            return;
        }
        let mut all: Vec<&[f64]> = self.means.chunks_exact(dof).collect();
        all.extend(means.iter().filter(|m| m.len() == dof).map(Vec::as_slice));
        all.sort_by(|a, b| {
            a.iter()
                .zip(*b)
                .map(|(x, y)| x.total_cmp(y))
                .find(|o| o.is_ne())
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        all.dedup();
        self.means = all.concat();
    }
}

/// What one retrieval found: the retrieved local samplers. Samplers found in a database borrow
/// its storage: nothing is copied.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Retrieval<'a> {
    /// The retrieved local samplers.
    pub samplers: Vec<Cow<'a, LocalSampler>>,
    /// Primitives of the query scene.
    pub query_primitives: usize,
    /// Entries retrieved (with repetitions across query primitives).
    pub entries: usize,
}

impl<'a> Retrieval<'a> {
    /// A retrieval holding the given local samplers (empty ones skipped).
    pub fn from_samplers(samplers: Vec<LocalSampler>) -> Self {
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
    pub fn push_sampler(&mut self, sampler: &'a LocalSampler) {
        if !sampler.is_empty() {
            self.samplers.push(Cow::Borrowed(sampler));
        }
    }
}

/// A Gaussian-mixture-of-mixtures sampler mixed with uniform sampling, borrowing what the
/// retrieval found.
#[derive(Debug, Clone)]
pub struct GlobalSampler<'a> {
    samplers: Vec<Cow<'a, LocalSampler>>,
    entries: usize,
    sigma: f64,
    lambda: f64,
}

impl<'a> GlobalSampler<'a> {
    /// Builds the sampler from a retrieval (taking its samplers, no copy).
    pub fn new(retrieval: Retrieval<'a>, sigma: f64, lambda: f64) -> Self {
        GlobalSampler {
            samplers: retrieval.samplers,
            entries: retrieval.entries,
            sigma,
            lambda,
        }
    }

    /// Number of local samplers.
    pub fn local_samplers(&self) -> usize {
        self.samplers.len()
    }

    /// Entries the retrieval found (with repetitions across query primitives).
    pub fn retrieved_entries(&self) -> usize {
        self.entries
    }

    /// The same sampler owning what it borrowed (copies the retrieved local samplers), so
    /// the databases may change while it plans.
    pub fn into_owned(self) -> GlobalSampler<'static> {
        GlobalSampler {
            samplers: self
                .samplers
                .into_iter()
                .map(|s| Cow::Owned(s.into_owned()))
                .collect(),
            entries: self.entries,
            sigma: self.sigma,
            lambda: self.lambda,
        }
    }
}

impl Sampler for GlobalSampler<'_> {
    fn sample(&mut self, robot: &Robot, rng: &mut PlannerRng, out: &mut [f64]) {
        if self.samplers.is_empty() || rng.random::<f64>() < self.lambda {
            robot.sample_uniform(rng, out);
            return;
        }
        let s = &self.samplers[rng.random_range(0..self.samplers.len())];
        let mean = s.mean(rng.random_range(0..s.len()));
        if mean.len() != out.len() {
            // A component of another robot's database: ignore it.
            robot.sample_uniform(rng, out);
            return;
        }
        for (o, m) in out.iter_mut().zip(mean) {
            let n: f64 = StandardNormal.sample(rng);
            *o = m + self.sigma * n;
        }
        robot.enforce_bounds(out);
    }
}
