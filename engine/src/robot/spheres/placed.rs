//! The sphere model placed at one configuration: every link's bounding ball and its balls in the
//! base frame, grown by a padding. What the map's self filter and FLAME's criticality test ask
//! of the robot (the planner's checkers place spheres in their own flat lanes).

use super::SphereModel;
use crate::robot::Robot;
use crate::Pose;
use nalgebra::Point3;

/// A ball: centre in the base frame and radius.
pub type Ball = ([f64; 3], f64);

/// The robot's spheres at one configuration.
#[derive(Debug, Clone)]
pub struct PlacedSpheres {
    /// Per link with spheres: its bounding ball and its balls.
    links: Vec<(Ball, Vec<Ball>)>,
}

fn inside(p: [f64; 3], (c, r): &Ball) -> bool {
    let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= r * r
}

impl PlacedSpheres {
    /// Places `robot`'s spheres at configuration `q` (unchecked length; see
    /// `Robot::validate`), each grown by `padding` metres.
    pub fn at(robot: &Robot, q: &[f64], padding: f64) -> Self {
        let mut poses = vec![Pose::identity(); robot.links().len()];
        robot.forward_kinematics(q, &mut poses);
        Self::from_poses(robot.spheres(), &poses, padding)
    }

    /// Places `model`'s spheres at link poses `poses`, each grown by `padding` metres.
    pub fn from_poses(model: &SphereModel, poses: &[Pose], padding: f64) -> Self {
        let links = (0..poses.len().min(model.bounds.len()))
            .filter_map(|li| {
                let (c, r) = model.bounds[li]?;
                let w = poses[li] * Point3::from(c);
                let spheres = model.ranges[li]
                    .clone()
                    .map(|s| {
                        let p = poses[li] * Point3::from(model.center[s]);
                        ([p.x, p.y, p.z], model.radius[s] + padding)
                    })
                    .collect();
                Some((([w.x, w.y, w.z], r + padding), spheres))
            })
            .collect();
        PlacedSpheres { links }
    }

    /// True when `p` (base frame) lies inside a ball.
    #[inline]
    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.links
            .iter()
            .any(|(bound, balls)| inside(p, bound) && balls.iter().any(|b| inside(p, b)))
    }

    /// Every ball of every link.
    pub fn balls(&self) -> impl Iterator<Item = &Ball> {
        self.links.iter().flat_map(|(_, balls)| balls)
    }

    /// True when some link's bounding ball comes within `reach` of `c`.
    pub fn bounds_near(&self, c: [f64; 3], reach: f64) -> bool {
        self.links
            .iter()
            .any(|((b, r), _)| inside(c, &(*b, r + reach)))
    }
}
