//! FLAME: octoboxes of the occupancy map as local primitives, matched by equal occupancy masks
//! within `flame_radius`.
//!
//! - [`primitive`]: the octoboxes of a map;
//! - [`criticality`]: which path configurations touch an octobox;
//! - [`database`]: the database ([`FlameDb`]); its match index lives in `index`.

pub mod criticality;
pub mod database;
mod index;
pub mod primitive;

pub use database::FlameDb;
pub use primitive::{octoboxes, octoboxes_updated, Octobox};
