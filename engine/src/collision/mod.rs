//! Collision checking.
//!
//! - [`shape`]: primitives as plain data;
//! - [`distance`]: point-to-primitive signed distances, one file per pair;
//! - [`checker`]: the fast path the planner uses (robot spheres against the environment, per-link
//!   bounding spheres as broad phase, self-collision over configured pairs, edge checks);
//! - [`parry`]: the exact path (GJK distances between the robot's link primitives and an object),
//!   as SPARK's criticality test needs. All parry3d conversions live there.

pub mod checker;
pub mod distance;
pub mod parry;
pub mod ray;
pub mod shape;

pub use checker::SphereChecker;
pub use shape::Shape;
