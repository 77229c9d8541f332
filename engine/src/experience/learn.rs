//! Learning from solved paths: extract a scene's primitives, test the path's configurations for
//! criticality, and add the critical ones to the databases ([`Experience::learn`]).

use super::database::Database;
use super::flame::criticality::flame_critical;
use super::spark::criticality::spark_critical;
use super::spark::spark_pairs;
use super::Experience;
use crate::robot::Robot;
use crate::scene::Scene;
use crate::world::map::{OccupancyMap, Octobox};

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

/// The configurations to test: the waypoints, plus states every `step` along each edge.
pub fn path_states(robot: &Robot, path: &[Vec<f64>], step: Option<f64>) -> Vec<Vec<f64>> {
    let Some(step) = step.filter(|s| *s > 0.0) else {
        return path.to_vec();
    };
    let mut out = Vec::new();
    for w in path.windows(2) {
        let n = (robot.distance(&w[0], &w[1]) / step).ceil().max(1.0) as usize;
        for k in 0..n {
            let mut q = vec![0.0; robot.dof()];
            robot.interpolate(&w[0], &w[1], k as f64 / n as f64, &mut q);
            out.push(q);
        }
    }
    out.extend(path.last().cloned());
    out
}

impl Experience {
    /// Adds what `path` (solved in `scene`, sensed as `map` with its octoboxes) teaches: SPARK
    /// learns from the scene's objects, FLAME from the octoboxes when there is a map. `step`: also test states every
    /// `step` along the path's edges (None: waypoints only, as the authors' code does).
    pub fn learn(
        &mut self,
        robot: &Robot,
        scene: &Scene,
        map: Option<(&OccupancyMap, &[Octobox])>,
        path: &[Vec<f64>],
        step: Option<f64>,
    ) -> Learned {
        let states = path_states(robot, path, step);
        let mut out = Learned::default();
        let pairs = spark_pairs(scene, self.spark.params());
        out.spark_primitives = pairs.len();
        let critical = spark_critical(robot, scene, &pairs, &states, self.spark.params());
        for (pair, configs) in pairs.into_iter().zip(critical) {
            if !configs.is_empty() {
                out.spark_entries += 1;
                self.spark.insert(pair, configs);
            }
        }
        if let Some((map, boxes)) = map {
            out.flame_primitives = boxes.len();
            let critical = flame_critical(robot, map, boxes, &states);
            for (b, configs) in boxes.iter().copied().zip(critical) {
                if !configs.is_empty() {
                    out.flame_entries += 1;
                    self.flame.insert(b, configs);
                }
            }
        }
        self.dirty |= out.spark_entries + out.flame_entries > 0;
        out
    }
}
