//! parry3d conversions and queries on the exact geometry: minimum distances between the
//! robot's link geometry (primitives, mesh hulls) and objects (GJK, not the sphere model), as
//! SPARK's criticality test and FLAME's "robot touches the octobox" test need, and the
//! intersection tests the exact checker ([`super::exact`]) runs.
//!
//! All parry3d conversions live here (parry3d 0.31 works in f32 glam types; cylinders run
//! along its local Y axis, ours along Z).

use super::gjk::{self, Convex};
use super::Shape;
use crate::robot::{Geometry, Robot};
use crate::world::Object;
use crate::Pose;
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};
use parry3d::math::{Pose as PPose, Rotation as PRot, Vector as PVec};
use parry3d::shape::{Capsule, ConvexPolyhedron, SharedShape};

pub(crate) fn to_parry_pose(p: &Pose) -> PPose {
    let t = p.translation.vector;
    let q = p.rotation.coords; // x, y, z, w
    PPose::from_parts(
        PVec::new(t.x as f32, t.y as f32, t.z as f32),
        PRot::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32).normalize(),
    )
}

/// A parry3d shape for a primitive, and the pose of parry's frame in the primitive's frame
/// (identity except for cylinders: parry's run along Y, ours along Z).
pub(crate) fn shared_shape(shape: &Shape) -> (SharedShape, Pose) {
    let f = |v: f64| v as f32;
    let parry = match *shape {
        Shape::Sphere { radius } => SharedShape::ball(f(radius)),
        Shape::Box { half_extents: h } => SharedShape::cuboid(f(h[0]), f(h[1]), f(h[2])),
        Shape::Capsule {
            radius,
            half_length,
        } => SharedShape::new(Capsule::new_z(f(half_length), f(radius))),
        Shape::Cylinder {
            radius,
            half_length,
        } => SharedShape::cylinder(f(half_length), f(radius)),
    };
    (parry, parry_frame(shape))
}

/// The exact checker's form of a primitive: the shape [`shared_shape`] makes (its sizes
/// rounded through `f32` likewise) and the same frame, without building the parry3d shape.
pub(crate) fn exact_shape(shape: &Shape) -> (Convex, Pose) {
    let f = |v: f64| v as f32 as f64;
    let convex = match *shape {
        Shape::Sphere { radius } => Convex::Ball(f(radius)),
        Shape::Box { half_extents: h } => Convex::Cuboid(Vector3::new(f(h[0]), f(h[1]), f(h[2]))),
        Shape::Capsule {
            radius,
            half_length,
        } => {
            let b = Vector3::new(0.0, 0.0, f(half_length));
            Convex::Capsule {
                a: -b,
                b,
                r: f(radius),
            }
        }
        Shape::Cylinder {
            radius,
            half_length,
        } => Convex::Cylinder {
            h: f(half_length),
            r: f(radius),
        },
    };
    (convex, parry_frame(shape))
}

/// The pose of parry's frame for `shape` in the primitive's frame.
fn parry_frame(shape: &Shape) -> Pose {
    match shape {
        Shape::Cylinder { .. } => Pose::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2),
        ),
        _ => Pose::identity(),
    }
}

/// A parry3d shape for link geometry (primitives as above, hulls as convex polyhedra).
pub(crate) fn shared_geometry(g: &Geometry) -> (SharedShape, Pose) {
    match g {
        Geometry::Primitive(s) => shared_shape(s),
        Geometry::Convex(hull) => {
            let points: Vec<PVec> = hull
                .points
                .iter()
                .map(|p| PVec::new(p[0] as f32, p[1] as f32, p[2] as f32))
                .collect();
            let shape = ConvexPolyhedron::from_convex_hull(&points)
                .map(SharedShape::new)
                // A hull that parry cannot rebuild (numerically flat): its bounding ball.
                .unwrap_or_else(|| {
                    let (lo, hi) = hull.aabb();
                    SharedShape::cuboid(
                        ((hi[0] - lo[0]) / 2.0) as f32,
                        ((hi[1] - lo[1]) / 2.0) as f32,
                        ((hi[2] - lo[2]) / 2.0) as f32,
                    )
                });
            (shape, Pose::identity())
        }
    }
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
    let (sa, fa) = shared_shape(a);
    let (sb, fb) = shared_shape(b);
    posed_distance(&*sa, &(pose_a * fa), &*sb, &(pose_b * fb))
}

/// Minimum distance between two parry shapes at world poses; 0 on contact. Computed by our
/// `f64` GJK ([`super::gjk`]): parry3d 0.31's own queries err on some pairs (`distance` and
/// `intersection_test` call a cuboid and a cylinder 4.8–9 mm apart touching; `intersection_test`
/// misses a cuboid inside a capsule's reach).
pub(crate) fn posed_distance(
    a: &dyn parry3d::shape::Shape,
    pose_a: &Pose,
    b: &dyn parry3d::shape::Shape,
    pose_b: &Pose,
) -> f64 {
    let convex = |s: &dyn parry3d::shape::Shape| Convex::from_parry(s).expect("convex shapes only");
    convex_distance(&convex(a), pose_a, &convex(b), pose_b)
}

/// Minimum distance between two convex shapes at world poses; 0 on contact.
pub(crate) fn convex_distance(a: &Convex, pose_a: &Pose, b: &Convex, pose_b: &Pose) -> f64 {
    gjk::distance(
        &gjk::Placed {
            shape: a,
            pose: pose_a,
        },
        &gjk::Placed {
            shape: b,
            pose: pose_b,
        },
    )
}

/// Shapes this close (metres) count as touching.
pub(crate) const TOUCH: f64 = 1e-9;

/// True when two convex shapes at world poses touch or overlap.
#[cfg(test)]
pub(crate) fn convex_touch(a: &Convex, pose_a: &Pose, b: &Convex, pose_b: &Pose) -> bool {
    convex_within_along(a, pose_a, b, pose_b, 0.0, &mut gjk::Witness::default())
}

/// True when two convex shapes at world poses come within `gap` metres of each other (touch
/// or overlap at 0), trying the separating axis and support points of an earlier answer
/// (`witness`) first and leaving this answer's (see [`gjk::separated_along`]).
pub(crate) fn convex_within_along(
    a: &Convex,
    pose_a: &Pose,
    b: &Convex,
    pose_b: &Pose,
    gap: f64,
    witness: &mut gjk::Witness,
) -> bool {
    // A ball against anything but a hull: the distance from its centre, in closed form (a
    // spherized robot's parts are all balls).
    let ball = match (a, b) {
        (Convex::Ball(r), other) => Some((*r, pose_a, other, pose_b)),
        (other, Convex::Ball(r)) => Some((*r, pose_b, other, pose_a)),
        _ => None,
    };
    if let Some((r, ball_pose, other, other_pose)) = ball {
        let centre = other_pose.inverse_transform_point(&ball_pose.translation.vector.into());
        if let Some(d) = other.point_gap(&centre.coords) {
            return d - r <= TOUCH + gap;
        }
    }
    let (a, b) = (
        gjk::Placed {
            shape: a,
            pose: pose_a,
        },
        gjk::Placed {
            shape: b,
            pose: pose_b,
        },
    );
    !gjk::separated_along(&a, &b, TOUCH + gap, witness)
}

/// True when two parry shapes at world poses touch or overlap.
#[cfg(test)]
pub(crate) fn posed_intersect(
    a: &dyn parry3d::shape::Shape,
    pose_a: &Pose,
    b: &dyn parry3d::shape::Shape,
    pose_b: &Pose,
) -> bool {
    posed_distance(a, pose_a, b, pose_b) <= TOUCH
}

/// Minimum distance from link `link`'s collision geometry (at `poses`, from
/// [`Robot::forward_kinematics`]) to `object`; infinite for a link without geometry.
pub fn link_object_distance(robot: &Robot, poses: &[Pose], link: usize, object: &Object) -> f64 {
    let (so, fo) = shared_shape(&object.shape);
    let co = Convex::from_parry(&*so).expect("primitives are convex");
    let pose_o = object.pose * fo;
    robot
        .exact_model()
        .link_parts(link)
        .iter()
        .map(|part| convex_distance(&part.convex, &(poses[link] * part.origin), &co, &pose_o))
        .fold(f64::INFINITY, f64::min)
}

/// Minimum distance between the robot (all links' geometry) and `object`; 0 on contact.
///
/// Links whose bounding sphere is already farther than the best distance found are skipped.
pub fn robot_object_distance(robot: &Robot, poses: &[Pose], object: &Object) -> f64 {
    let obj_center = object.pose.translation.vector;
    let obj_radius = object.shape.bounding_radius();
    let mut best = f64::INFINITY;
    for li in 0..robot.links().len() {
        let Some((c, r)) = robot.exact_model().link_bound(li) else {
            continue;
        };
        let w = poses[li] * Point3::from(c);
        if (w.coords - obj_center).norm() - r - obj_radius >= best {
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

    /// The exact checker's shapes made directly are the ones converted from parry3d's, value
    /// for value (the searches do not change with the shortcut).
    #[test]
    fn exact_shapes_are_parrys() {
        let shapes = [
            Shape::Sphere { radius: 0.1234567 },
            Shape::Box {
                half_extents: [0.1, 0.2345678, 0.3],
            },
            Shape::Capsule {
                radius: 0.05,
                half_length: 0.2345678,
            },
            Shape::Cylinder {
                radius: 0.0333333,
                half_length: 0.4567891,
            },
        ];
        for shape in shapes {
            let (parry, frame) = shared_shape(&shape);
            let (direct, direct_frame) = exact_shape(&shape);
            let converted = Convex::from_parry(&*parry).unwrap();
            assert_eq!(format!("{direct:?}"), format!("{converted:?}"), "{shape:?}");
            assert_eq!(direct_frame, frame, "{shape:?}");
        }
    }

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
    fn intersection_agrees_with_distance_for_every_primitive_pair() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
        let shapes = [
            Shape::cuboid([0.06, 0.013, 0.025]),
            Shape::Cylinder {
                radius: 0.03,
                half_length: 0.06,
            },
            Shape::Capsule {
                radius: 0.04,
                half_length: 0.05,
            },
            Shape::Sphere { radius: 0.05 },
        ];
        let mut contacts = 0;
        for _ in 0..4000 {
            let a = shapes[rng.random_range(0..4)];
            let b = shapes[rng.random_range(0..4)];
            let mut pose = || {
                Pose::from_parts(
                    nalgebra::Translation3::new(
                        0.8 + rng.random_range(-0.08..0.08),
                        rng.random_range(-0.08..0.08),
                        0.7 + rng.random_range(-0.08..0.08),
                    ),
                    UnitQuaternion::from_euler_angles(
                        rng.random_range(-3.0..3.0),
                        rng.random_range(-3.0..3.0),
                        rng.random_range(-3.0..3.0),
                    ),
                )
            };
            let (pa, pb) = (pose(), pose());
            let (sa, fa) = shared_shape(&a);
            let (sb, fb) = shared_shape(&b);
            let hit = posed_intersect(&*sa, &(pa * fa), &*sb, &(pb * fb));
            // An independent oracle: a vertex of one tessellated surface 1 mm inside the other.
            let deep = |x: &Shape, px: &Pose, y: &Shape, py: &Pose| {
                let part = crate::robot::LinkShape {
                    origin: *px,
                    geometry: crate::robot::Geometry::Primitive(*x),
                };
                crate::robot::spheres::surface_triangles(&part)
                    .iter()
                    .flatten()
                    .any(|p| {
                        let l = py.inverse() * nalgebra::Point3::from(*p);
                        distance_point_shape([l.x, l.y, l.z], y) < -1e-3
                    })
            };
            if deep(&a, &pa, &b, &pb) || deep(&b, &pb, &a, &pa) {
                contacts += 1;
                assert!(hit, "{a:?} {b:?} overlap but no intersection");
            }
            let d = posed_distance(&*sa, &(pa * fa), &*sb, &(pb * fb));
            if d > 1e-5 {
                assert!(!hit, "{a:?} {b:?}: intersection at distance {d}");
            }
        }
        assert!(contacts > 500, "{contacts}");
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
