//! The global sampler: with probability λ a uniform sample; otherwise a uniformly chosen
//! retrieved local sampler, one of its components uniformly, plus N(0, σ²) per joint, clamped to
//! the limits (wrapped for continuous joints). Nothing retrieved: uniform.

use super::database::Retrieval;
use crate::planning::{PlannerRng, Sampler};
use crate::robot::Robot;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

/// A Gaussian-mixture-of-mixtures sampler mixed with uniform sampling.
#[derive(Debug, Clone)]
pub struct GlobalSampler {
    dof: usize,
    /// Component means, flat (`dof` values each).
    means: Vec<f64>,
    /// Per local sampler: its range of components.
    samplers: Vec<std::ops::Range<usize>>,
    sigma: f64,
    lambda: f64,
}

impl GlobalSampler {
    /// Builds the sampler from a retrieval (taking its arrays, no copy).
    pub fn new(retrieval: Retrieval, sigma: f64, lambda: f64) -> Self {
        GlobalSampler {
            dof: retrieval.dof,
            means: retrieval.means,
            samplers: retrieval.samplers,
            sigma,
            lambda,
        }
    }

    /// Number of local samplers.
    pub fn local_samplers(&self) -> usize {
        self.samplers.len()
    }

    /// Number of Gaussian components.
    pub fn components(&self) -> usize {
        self.means.len() / self.dof.max(1)
    }
}

impl Sampler for GlobalSampler {
    fn sample(&mut self, robot: &Robot, rng: &mut PlannerRng, out: &mut [f64]) {
        if self.samplers.is_empty() || rng.random::<f64>() < self.lambda {
            robot.sample_uniform(rng, out);
            return;
        }
        let s = &self.samplers[rng.random_range(0..self.samplers.len())];
        let c = rng.random_range(s.clone());
        let mean = &self.means[c * self.dof..(c + 1) * self.dof];
        for (o, m) in out.iter_mut().zip(mean) {
            let n: f64 = StandardNormal.sample(rng);
            *o = m + self.sigma * n;
        }
        robot.enforce_bounds(out);
    }
}
