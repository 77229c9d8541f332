//! Removing the robot's own body from clouds: points inside the robot's spheres (plus padding)
//! at the current joint state.

use crate::robot::Robot;
use crate::Pose;
use nalgebra::Point3;

/// A ball: world centre and radius.
type Ball = ([f64; 3], f64);

/// The robot's spheres placed at one configuration, grown by a padding.
#[derive(Debug, Clone)]
pub struct RobotFilter {
    /// Per link with spheres: its bounding ball and its balls.
    links: Vec<(Ball, Vec<Ball>)>,
}

impl RobotFilter {
    /// Places `robot`'s spheres at configuration `q` (unchecked length; see `Robot::validate`),
    /// each grown by `padding` metres.
    pub fn new(robot: &Robot, q: &[f64], padding: f64) -> Self {
        let mut poses = vec![Pose::identity(); robot.links().len()];
        robot.forward_kinematics(q, &mut poses);
        let model = robot.spheres();
        let links = (0..robot.links().len())
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
        RobotFilter { links }
    }

    /// True when `p` (base frame) lies on the robot.
    #[inline]
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let inside = |c: &[f64; 3], r: f64| {
            let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
            d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= r * r
        };
        self.links.iter().any(|((c, r), spheres)| {
            inside(c, *r) && spheres.iter().any(|(sc, sr)| inside(sc, *sr))
        })
    }
}
