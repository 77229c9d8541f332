//! Criticality tests: which configurations of a solved path belong to a local primitive.
//!
//! - SPARK: the configuration is critical for a pair when the summed minimum distances between
//!   the robot's link primitives and each of the pair's two objects (parry3d GJK, exact
//!   geometry) is below `d_pairs`.
//! - FLAME: the configuration is critical for an octobox when the robot's link primitives touch
//!   or penetrate the octobox cube.
//!
//! Paths are taken at their waypoints, and optionally also every `step` along each edge.

use super::primitive::{OctoboxPrimitive, SparkPair};
use super::ExperienceParams;
use crate::collision::parry::robot_object_distance;
use crate::collision::Shape;
use crate::robot::Robot;
use crate::scene::Scene;
use crate::world::map::OccupancyMap;
use crate::world::Object;
use crate::Pose;

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

/// For each SPARK pair of `scene`, the configurations of `states` critical to it.
pub fn spark_critical(
    robot: &Robot,
    scene: &Scene,
    pairs: &[SparkPair],
    states: &[Vec<f64>],
    params: &ExperienceParams,
) -> Vec<Vec<Vec<f64>>> {
    let mut out = vec![Vec::new(); pairs.len()];
    let mut poses = vec![Pose::identity(); robot.links().len()];
    let object = |name: &str| scene.objects.iter().find(|o| o.name == name);
    for q in states {
        if robot.validate(q).is_err() {
            continue;
        }
        robot.forward_kinematics(q, &mut poses);
        // Distances to each object once per configuration.
        let mut cache: Vec<(String, f64)> = Vec::new();
        let mut dist = |name: &str| -> f64 {
            if let Some((_, d)) = cache.iter().find(|(n, _)| n == name) {
                return *d;
            }
            let d = object(name).map_or(f64::INFINITY, |o| robot_object_distance(robot, &poses, o));
            cache.push((name.to_string(), d));
            d
        };
        for (i, pair) in pairs.iter().enumerate() {
            let d = dist(&pair.names[0]) + dist(&pair.names[1]);
            if d < params.d_pairs {
                out[i].push(q.clone());
            }
        }
    }
    out
}

/// For each octobox, the configurations of `states` whose robot geometry touches its cube.
pub fn flame_critical(
    robot: &Robot,
    map: &OccupancyMap,
    boxes: &[OctoboxPrimitive],
    states: &[Vec<f64>],
) -> Vec<Vec<Vec<f64>>> {
    let mut out = vec![Vec::new(); boxes.len()];
    let mut poses = vec![Pose::identity(); robot.links().len()];
    let side = map.block_size();
    let cube = Shape::cuboid([side; 3]);
    let model = robot.spheres();
    for q in states {
        if robot.validate(q).is_err() {
            continue;
        }
        robot.forward_kinematics(q, &mut poses);
        // Link bounding spheres in the base frame, for a cheap reject before GJK.
        let bounds: Vec<([f64; 3], f64)> = (0..robot.links().len())
            .filter_map(|li| {
                let (c, r) = model.bounds[li]?;
                let w = poses[li] * nalgebra::Point3::from(c);
                Some(([w.x, w.y, w.z], r))
            })
            .collect();
        for (i, b) in boxes.iter().enumerate() {
            let c = map.block_center(b.key);
            let reach = side * 0.8661; // half diagonal of the cube
            let near = bounds.iter().any(|(bc, r)| {
                let d = [bc[0] - c[0], bc[1] - c[1], bc[2] - c[2]];
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() <= r + reach
            });
            if !near {
                continue;
            }
            let object = Object {
                name: "octobox".into(),
                shape: cube,
                pose: Pose::translation(c[0], c[1], c[2]),
            };
            if robot_object_distance(robot, &poses, &object) <= 0.0 {
                out[i].push(q.clone());
            }
        }
    }
    out
}
