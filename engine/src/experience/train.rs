//! Learning from solved paths: extract a scene's primitives, test the path's configurations for
//! criticality, and add the critical ones to the databases.

use super::criticality::{flame_critical, path_states, spark_critical};
use super::primitive::{octoboxes, spark_pairs};
use super::{FlameDb, SparkDb};
use crate::robot::Robot;
use crate::scene::Scene;
use crate::world::map::OccupancyMap;

/// What learning from one path added.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Learned {
    /// SPARK primitives of the scene.
    pub spark_primitives: usize,
    /// SPARK primitives with at least one critical configuration.
    pub spark_entries: usize,
    /// FLAME octoboxes of the map.
    pub flame_primitives: usize,
    /// FLAME octoboxes with at least one critical configuration.
    pub flame_entries: usize,
}

/// Adds what `path` (solved in `scene`, sensed as `map`) teaches to the databases.
/// `step`: also test states every `step` along the path's edges (None: waypoints only, as the
/// authors' code does).
pub fn learn(
    robot: &Robot,
    scene: &Scene,
    map: Option<&OccupancyMap>,
    path: &[Vec<f64>],
    step: Option<f64>,
    spark: &mut SparkDb,
    flame: Option<&mut FlameDb>,
) -> Learned {
    let states = path_states(robot, path, step);
    let mut out = Learned::default();
    let pairs = spark_pairs(scene, spark.params());
    out.spark_primitives = pairs.len();
    let critical = spark_critical(robot, scene, &pairs, &states, spark.params());
    for (pair, configs) in pairs.into_iter().zip(critical) {
        if !configs.is_empty() {
            out.spark_entries += 1;
            spark.insert(pair, configs);
        }
    }
    if let (Some(map), Some(flame)) = (map, flame) {
        let boxes = octoboxes(map);
        out.flame_primitives = boxes.len();
        let critical = flame_critical(robot, map, &boxes, &states);
        for (b, configs) in boxes.into_iter().zip(critical) {
            if !configs.is_empty() {
                out.flame_entries += 1;
                flame.insert(b, configs);
            }
        }
    }
    out
}
