//! SPARK: pairs of nearby objects as local primitives, retrieved within `d_radius` under the
//! pair metric.
//!
//! - [`primitive`]: box pairs and their metric; [`pairs`]: the pairs of a changing scene, kept
//!   incrementally through a grid broad phase;
//! - [`criticality`]: which path configurations belong to a pair;
//! - [`database`]: the database ([`SparkDb`]); its retrieval index lives in `index` and the
//!   metric tree under it in [`vptree`].

pub mod criticality;
pub mod database;
mod index;
pub mod pairs;
pub mod primitive;
pub mod vptree;

pub use database::SparkDb;
pub use pairs::{PairSet, PairsSnapshot};
pub use primitive::{spark_pairs, BoxPrimitive, SparkPair};
