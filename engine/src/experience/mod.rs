//! Experience: SPARK and FLAME (Chamzas et al., ICRA 2021) — sampling distributions learned from
//! past solutions, keyed by local workspace primitives.
//!
//! [`Experience`] is the one type the daemon, `ember train` and the benchmarks use: it owns both
//! databases and their folder, hands out a sampler per method and scene, and learns from solved
//! paths. Inside:
//! - [`database`]: the [`Database`] contract (primitive → [`LocalSampler`], exact retrieval
//!   with a linear-scan oracle, one file) and the storage both databases share;
//! - [`spark`] and [`flame`]: each method's primitive, criticality test, retrieval index and
//!   database;
//! - [`sampler`]: local samplers, retrievals and the global sampler (λ-mix of uniform and the
//!   retrieved Gaussian mixtures) that plugs into the planner;
//! - [`file`]: the on-disk form; [`learn`]: learning from solved paths; [`store`]: the
//!   [`Experience`] type.
//!
//! Where we differ from the authors' code (on purpose):
//! - the orientation term of the SE(3) distance is the rotation angle `2·acos(|q₁·q₂|)` instead of
//!   the paper's `1 − (q₁·q₂)²`, so the box distance is a true metric; the pair distance (minimum
//!   over the two pairings of summed box distances) is then a metric too, because swapping the
//!   boxes of a pair is an isometry of the summed metric — so the metric tree prunes exactly;
//! - FLAME retrieval is a hash lookup of the octoboxes with the query's 64-bit mask and a centre
//!   within `flame_radius` (the authors' GNAT radius query with their distance and hard-coded
//!   radius amounts to the same match);
//! - `d_radius` defaults to 0.2 under the paper's box distance: the authors' code sums the pose
//!   and size terms without the `w_s` weights and queries 0.4, which is the same set of entries
//!   when `w_s` = 0.5.
//! - the global sampler picks a retrieved local sampler uniformly, then one of its components
//!   (the paper's mixture of mixtures), where the authors' code flattens all unique means.

pub mod database;
pub mod file;
pub mod flame;
pub mod learn;
pub mod sampler;
pub mod spark;
pub mod store;

pub use database::Database;
pub use file::DbError;
pub use flame::{FlameDb, Octobox};
pub use learn::Learned;
pub use sampler::{GlobalSampler, LocalSampler, Retrieval};
pub use spark::{BoxPrimitive, SparkDb, SparkPair};
pub use store::{Experience, Method, SetAside};

/// Hyperparameters (paper, Table I).
#[derive(Debug, Clone, PartialEq)]
pub struct ExperienceParams {
    /// Standard deviation of every Gaussian component, per joint (radians or metres).
    pub sigma: f64,
    /// Probability of a uniform sample.
    pub lambda: f64,
    /// SPARK retrieval radius (pair metric).
    pub d_radius: f64,
    /// SPARK: objects closer than this form a pair; criticality threshold too (metres).
    pub d_pairs: f64,
    /// Weight of translation against rotation in the pose distance.
    pub w_t: f64,
    /// Weight of pose against size in the box distance.
    pub w_s: f64,
    /// FLAME: largest distance between the centres of matching octoboxes (metres).
    pub flame_radius: f64,
}

impl Default for ExperienceParams {
    fn default() -> Self {
        ExperienceParams {
            sigma: 0.2,
            lambda: 0.5,
            d_radius: 0.2,
            d_pairs: 0.2,
            w_t: 0.75,
            w_s: 0.5,
            flame_radius: 0.2,
        }
    }
}

/// Asks the CPU to start loading the cache line at `p` (a hint: never faults).
#[inline(always)]
pub(crate) fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint and does not access memory; SSE is baseline on x86_64.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast())
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
