//! Collision checking.
//!
//! - [`shape`]: primitives as plain data;
//! - [`distance`]: point-to-primitive signed distances, one file per pair;
//! - [`checker`]: the fast path the planner uses (robot spheres against the environment, per-link
//!   bounding spheres as broad phase, self-collision over configured pairs, edge checks);
//! - [`batch`]: eight configurations at once in `f32` lanes, for the planner's edge checks
//!   (errs towards contact; the scalar checker decides what it flags);
//! - [`exact`]: the exact checker (the robot's own geometry, meshes as convex hulls, with
//!   parry3d) for start/goal validity, path validation and contacts named precisely;
//! - [`parry`]: parry3d conversions and exact distances (SPARK's criticality test). All parry3d
//!   conversions live there;
//! - [`convex`]: convex hulls of mesh geometry;
//! - `prepared`: what the checkers derive from a robot alone, built once per robot.

pub mod batch;
pub mod checker;
pub mod convex;
pub mod distance;
pub mod exact;
pub mod gjk;
pub mod parry;
pub(crate) mod prepared;
pub mod ray;
pub mod shape;

pub use checker::SphereChecker;

use crate::robot::Robot;

/// Anything that decides whether a configuration is free: the sphere checker, the exact
/// checker, the planner's combination of both.
pub trait ConfigCheck<'a> {
    /// The robot checked.
    fn robot(&self) -> &'a Robot;
    /// True when `q` (the robot's DOF, validated) is collision free.
    fn is_valid(&mut self, q: &[f64]) -> bool;
}
pub use shape::Shape;
