//! SPARK: pairs of nearby objects as local primitives, retrieved within `d_radius` under the
//! pair metric.
//!
//! - [`primitive`]: box pairs and their metric;
//! - [`criticality`]: which path configurations belong to a pair;
//! - [`database`]: the database ([`SparkDb`]); its retrieval index lives in `index` and the
//!   metric tree under it in [`vptree`].

pub mod criticality;
pub mod database;
mod index;
pub mod primitive;
pub mod vptree;

pub use database::SparkDb;
pub use primitive::{spark_pairs, spark_pairs_of, BoxPrimitive, SparkPair};
