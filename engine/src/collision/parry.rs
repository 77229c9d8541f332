//! The exact path: minimum distances between the robot's link primitives and objects with
//! parry3d (GJK on the primitives themselves, not the sphere model). SPARK's criticality test
//! and FLAME's "robot touches the octobox" test use it.
//!
//! All parry3d conversions live here (parry3d 0.31 works in f32 glam types; cylinders run
//! along its local Y axis, ours along Z).

use super::Shape;
use crate::robot::Robot;
use crate::world::Object;
use crate::Pose;
use nalgebra::{Point3, UnitQuaternion, Vector3};
use parry3d::math::{Pose as PPose, Rotation as PRot, Vector as PVec};
use parry3d::shape::{Ball, Capsule, Cuboid, Cylinder};

fn to_parry_pose(p: &Pose) -> PPose {
    let t = p.translation.vector;
    let q = p.rotation.coords; // x, y, z, w
    PPose::from_parts(
        PVec::new(t.x as f32, t.y as f32, t.z as f32),
        PRot::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32).normalize(),
    )
}

/// Minimum distance between two posed primitives; 0 when they touch or overlap.
///
/// ```
/// use ember_engine::collision::{parry::shape_distance, Shape};
/// use ember_engine::Pose;
/// let a = Shape::Sphere { radius: 1.0 };
/// let b = Shape::Sphere { radius: 2.0 };
/// let d = shape_distance(&a, &Pose::identity(), &b, &Pose::translation(10.0, 0.0, 0.0));
/// assert!((d - 7.0).abs() < 1e-5);
/// ```
pub fn shape_distance(a: &Shape, pose_a: &Pose, b: &Shape, pose_b: &Pose) -> f64 {
    with_parry(a, pose_a, &|sa, pa| {
        with_parry(b, pose_b, &|sb, pb| {
            parry3d::query::distance(&pa, sa, &pb, sb)
                .map(|d| d.distance as f64)
                .expect("parry3d supports every pair of convex primitives")
        })
    })
}

fn with_parry(
    shape: &Shape,
    pose: &Pose,
    f: &dyn Fn(&dyn parry3d::shape::Shape, PPose) -> f64,
) -> f64 {
    match *shape {
        Shape::Sphere { radius } => f(&Ball::new(radius as f32), to_parry_pose(pose)),
        Shape::Box { half_extents: h } => f(
            &Cuboid::new(PVec::new(h[0] as f32, h[1] as f32, h[2] as f32)),
            to_parry_pose(pose),
        ),
        Shape::Capsule {
            radius,
            half_length,
        } => f(
            &Capsule::new_z(half_length as f32, radius as f32),
            to_parry_pose(pose),
        ),
        Shape::Cylinder {
            radius,
            half_length,
        } => {
            // parry's cylinder runs along Y: rotate +90° about X so it runs along our Z.
            let y_to_z =
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2);
            let p = pose * y_to_z;
            f(
                &Cylinder::new(half_length as f32, radius as f32),
                to_parry_pose(&p),
            )
        }
    }
}

/// Minimum distance from link `link`'s collision primitives (at `poses`, from
/// [`Robot::forward_kinematics`]) to `object`; infinite for a link without geometry.
pub fn link_object_distance(robot: &Robot, poses: &[Pose], link: usize, object: &Object) -> f64 {
    robot.links()[link]
        .collision
        .iter()
        .map(|ls| {
            shape_distance(
                &ls.shape,
                &(poses[link] * ls.origin),
                &object.shape,
                &object.pose,
            )
        })
        .fold(f64::INFINITY, f64::min)
}

/// Minimum distance between the robot (all links' primitives) and `object`; 0 on contact.
///
/// Links whose bounding sphere is already farther than the best distance found are skipped.
pub fn robot_object_distance(robot: &Robot, poses: &[Pose], object: &Object) -> f64 {
    let model = robot.spheres();
    let obj_center = object.pose.translation.vector;
    let obj_radius = object.shape.bounding_radius();
    let mut best = f64::INFINITY;
    for li in 0..robot.links().len() {
        if let Some((c, r)) = model.bounds[li] {
            let w = poses[li] * Point3::from(c);
            let lower = (w.coords - obj_center).norm() - r - obj_radius;
            if lower >= best {
                continue;
            }
        } else {
            continue;
        }
        best = best.min(link_object_distance(robot, poses, li, object));
        if best <= 0.0 {
            return 0.0;
        }
    }
    best
}

/// True when any link primitive touches or penetrates `object` (distance ≤ `tolerance`).
pub fn robot_touches(robot: &Robot, poses: &[Pose], object: &Object, tolerance: f64) -> bool {
    robot_object_distance(robot, poses, object) <= tolerance
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::distance::distance_point_shape;

    #[test]
    fn cylinder_runs_along_z() {
        let cyl = Shape::Cylinder {
            radius: 0.1,
            half_length: 1.0,
        };
        let ball = Shape::Sphere { radius: 0.1 };
        // A ball 0.5 above the centre is inside a z-cylinder of half length 1.
        let d = shape_distance(
            &cyl,
            &Pose::identity(),
            &ball,
            &Pose::translation(0.0, 0.0, 0.5),
        );
        assert_eq!(d, 0.0);
        let d = shape_distance(
            &cyl,
            &Pose::identity(),
            &ball,
            &Pose::translation(0.0, 0.5, 0.0),
        );
        assert!((d - 0.3).abs() < 1e-5, "{d}");
    }

    #[test]
    fn exact_distance_matches_point_queries_for_balls() {
        for shape in [
            Shape::cuboid([0.2, 0.4, 0.6]),
            Shape::Capsule {
                radius: 0.1,
                half_length: 0.3,
            },
            Shape::Cylinder {
                radius: 0.2,
                half_length: 0.1,
            },
        ] {
            for p in [[0.5, 0.0, 0.0], [0.3, 0.4, 0.5], [0.0, 0.0, 0.9]] {
                let expect = distance_point_shape(p, &shape) - 0.05;
                let sut = shape_distance(
                    &shape,
                    &Pose::identity(),
                    &Shape::Sphere { radius: 0.05 },
                    &Pose::translation(p[0], p[1], p[2]),
                );
                assert!(
                    (sut - expect.max(0.0)).abs() < 1e-4,
                    "{shape:?} {p:?}: {sut} vs {expect}"
                );
            }
        }
    }
}
