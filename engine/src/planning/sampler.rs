//! Where the planner draws its random configurations from.
//!
//! The [`Sampler`] trait is the plug-in point: [`UniformSampler`] is the default; SPARK and FLAME
//! provide experience-biased samplers that implement the same trait.

use crate::robot::Robot;

pub use super::rng::PlannerRng;

/// Draws configurations for the planner.
pub trait Sampler {
    /// Writes one configuration, within `robot`'s limits, into `out`.
    fn sample(&mut self, robot: &Robot, rng: &mut PlannerRng, out: &mut [f64]);
}

/// Uniform sampling within the joint limits (continuous joints over `[-π, π)`).
#[derive(Debug, Clone, Copy, Default)]
pub struct UniformSampler;

impl Sampler for UniformSampler {
    #[inline]
    fn sample(&mut self, robot: &Robot, rng: &mut PlannerRng, out: &mut [f64]) {
        robot.sample_uniform_fast(rng, out);
    }
}
