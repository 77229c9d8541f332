//! SPARK's criticality test: a configuration is critical for a pair when the summed minimum
//! distances between the robot's link primitives and each of the pair's two objects (exact
//! geometry) is below `d_pairs`.

use super::primitive::SparkPair;
use crate::collision::parry::robot_object_distance;
use crate::experience::ExperienceParams;
use crate::robot::Robot;
use crate::scene::Scene;
use crate::Pose;

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
