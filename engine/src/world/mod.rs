//! What the robot plans in.
//!
//! - [`environment`]: named geometric objects (from scenes or motion capture) and, optionally, an
//!   occupancy map, with the fast sphere queries the checker uses;
//! - [`map`]: the occupancy map built from depth clouds;
//! - [`model`]: the world model kept up to date from sensor inputs, and its snapshots.

pub mod environment;
pub mod map;
pub mod model;

pub use environment::{Environment, Object, WorldError};
