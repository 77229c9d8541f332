//! The global sampler: with probability λ a uniform sample; otherwise a uniformly chosen
//! retrieved local sampler, one of its components uniformly, plus N(0, σ²) per joint, clamped to
//! the limits (wrapped for continuous joints). Nothing retrieved: uniform.

use super::database::Retrieval;
use crate::planning::{PlannerRng, Sampler};
use crate::robot::Robot;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use std::borrow::Cow;

/// A Gaussian-mixture-of-mixtures sampler mixed with uniform sampling, borrowing what the
/// retrieval found.
#[derive(Debug, Clone)]
pub struct GlobalSampler<'a> {
    /// Per local sampler: its component means.
    samplers: Vec<Cow<'a, [Vec<f64>]>>,
    sigma: f64,
    lambda: f64,
}

impl<'a> GlobalSampler<'a> {
    /// Builds the sampler from a retrieval (taking its samplers, no copy).
    pub fn new(retrieval: Retrieval<'a>, sigma: f64, lambda: f64) -> Self {
        GlobalSampler {
            samplers: retrieval.samplers,
            sigma,
            lambda,
        }
    }

    /// Number of local samplers.
    pub fn local_samplers(&self) -> usize {
        self.samplers.len()
    }
}

impl Sampler for GlobalSampler<'_> {
    fn sample(&mut self, robot: &Robot, rng: &mut PlannerRng, out: &mut [f64]) {
        if self.samplers.is_empty() || rng.random::<f64>() < self.lambda {
            robot.sample_uniform(rng, out);
            return;
        }
        let s = &self.samplers[rng.random_range(0..self.samplers.len())];
        let mean = &s[rng.random_range(0..s.len())];
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
