//! FLAME's criticality test: a configuration is critical for an octobox when the robot's link
//! primitives touch or penetrate the octobox cube.

use super::primitive::Octobox;
use crate::collision::parry::robot_object_distance;
use crate::collision::Shape;
use crate::robot::spheres::PlacedSpheres;
use crate::robot::Robot;
use crate::world::map::OccupancyMap;
use crate::world::Object;
use crate::Pose;

/// For each octobox, the configurations of `states` whose robot geometry touches its cube.
pub fn flame_critical(
    robot: &Robot,
    map: &OccupancyMap,
    boxes: &[Octobox],
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
        let placed = PlacedSpheres::from_poses(model, &poses, 0.0);
        for (i, b) in boxes.iter().enumerate() {
            let c = map.block_center(b.key);
            let reach = side * 0.8661; // half diagonal of the cube
            if !placed.bounds_near(c, reach) {
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
