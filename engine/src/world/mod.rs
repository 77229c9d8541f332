//! What the robot plans in.
//!
//! - [`environment`]: named geometric objects (from scenes or motion capture), with the fast
//!   sphere queries the checker uses.

pub mod environment;

pub use environment::{Environment, Object, WorldError};
