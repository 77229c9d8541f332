//! Forward kinematics: the pose of every link in the robot's base frame.

use super::{ConfigError, Motion, Robot};
use crate::Pose;
use nalgebra::{IsometryMatrix3, Rotation3, Translation3, UnitQuaternion};

/// A link frame as rotation matrix plus translation: the checker's representation, cheaper
/// than quaternions for transforming many points.
pub type Frame = IsometryMatrix3<f64>;

/// The frame of `link` in its parent's frame: the joint `origin` moved by the joint's value.
#[inline]
fn joint_frame(link: &super::Link, origin: &Frame, q: &[f64]) -> Frame {
    match link.motion {
        Motion::Fixed => *origin,
        Motion::Revolute { axis, variable } => {
            origin * Rotation3::from_axis_angle(&axis, q[variable])
        }
        Motion::Prismatic { axis, variable } => {
            origin * Translation3::from(axis.into_inner() * q[variable])
        }
    }
}

/// The base-frame pose of `link` at `q`, its parent's already in `poses`: the joint origin
/// moved by the joint's value, placed in the parent's frame.
#[inline(always)]
fn link_pose(link: &super::Link, q: &[f64], poses: &[Pose]) -> Pose {
    let local = match link.motion {
        Motion::Fixed => link.origin,
        Motion::Revolute { axis, variable } => {
            link.origin * UnitQuaternion::from_axis_angle(&axis, q[variable])
        }
        Motion::Prismatic { axis, variable } => {
            link.origin * Translation3::from(axis.into_inner() * q[variable])
        }
    };
    match link.parent {
        None => local,
        Some(p) => poses[p] * local,
    }
}

impl Robot {
    /// Writes the base-frame pose of every link for configuration `q` into `poses`
    /// (indexed like [`Robot::links`]). No checks, no allocation: the planner's inner loop.
    ///
    /// `q` must have [`Robot::dof`] values and `poses` one slot per link.
    #[inline]
    pub fn forward_kinematics(&self, q: &[f64], poses: &mut [Pose]) {
        debug_assert_eq!(q.len(), self.dof());
        debug_assert_eq!(poses.len(), self.links.len());
        for (i, link) in self.links.iter().enumerate() {
            poses[i] = link_pose(link, q, poses);
        }
    }

    /// [`Robot::forward_kinematics`] for `links` alone (in the order of [`Robot::links`], each
    /// link's parent among them or the root): the other slots of `poses` are left as they are.
    #[inline]
    pub fn forward_kinematics_of(&self, links: &[usize], q: &[f64], poses: &mut [Pose]) {
        for &i in links {
            poses[i] = link_pose(&self.links[i], q, poses);
        }
    }

    /// Like [`Robot::forward_kinematics`], writing rotation-matrix [`Frame`]s (the form the
    /// collision checker uses).
    #[inline]
    pub fn forward_kinematics_frames(&self, q: &[f64], frames: &mut [Frame]) {
        debug_assert_eq!(q.len(), self.dof());
        debug_assert_eq!(frames.len(), self.links.len());
        for (i, link) in self.links.iter().enumerate() {
            let local = joint_frame(link, &self.origin_frames[i], q);
            frames[i] = match link.parent {
                None => local,
                Some(p) => frames[p] * local,
            };
        }
    }

    /// Base-frame poses of all links, after validating `q`.
    ///
    /// ```
    /// let fetch = ember_engine::robot::Robot::builtin("fetch").unwrap();
    /// let poses = fetch.link_poses(&[0.0; 8]).unwrap();
    /// let gripper = &poses[fetch.link_index("gripper_link").unwrap()];
    /// assert!((gripper.translation.x - 1.1281).abs() < 1e-6);
    /// ```
    pub fn link_poses(&self, q: &[f64]) -> Result<Vec<Pose>, ConfigError> {
        self.validate(q)?;
        let mut poses = vec![Pose::identity(); self.links.len()];
        self.forward_kinematics(q, &mut poses);
        Ok(poses)
    }

    /// Base-frame pose of the group's tip link.
    pub fn tip_pose(&self, q: &[f64]) -> Result<Pose, ConfigError> {
        Ok(self.link_poses(q)?[self.tip])
    }
}

impl Robot {
    /// The robot's collision primitives at configuration `q` as world objects named
    /// `robot/<link>/<i>` (for rendering the robot into simulated sensor data). Mesh geometry
    /// is rendered as the link's fitted spheres.
    pub fn collision_objects(&self, q: &[f64]) -> Result<Vec<crate::world::Object>, ConfigError> {
        let poses = self.link_poses(q)?;
        let mut out = Vec::new();
        for (li, link) in self.links.iter().enumerate() {
            let mut meshes = false;
            for (i, ls) in link.collision.iter().enumerate() {
                match &ls.geometry {
                    super::Geometry::Primitive(shape) => out.push(crate::world::Object {
                        name: format!("robot/{}/{i}", link.name),
                        shape: *shape,
                        pose: poses[li] * ls.origin,
                    }),
                    super::Geometry::Convex(_) => meshes = true,
                }
            }
            if meshes {
                for (k, (c, r)) in self.spheres.link_spheres(li).enumerate() {
                    out.push(crate::world::Object {
                        name: format!("robot/{}/sphere{k}", link.name),
                        shape: crate::collision::Shape::Sphere { radius: r },
                        pose: poses[li] * Pose::translation(c[0], c[1], c[2]),
                    });
                }
            }
        }
        Ok(out)
    }
}

/// Forward kinematics over joints only: links on fixed joints ride in the frame of their
/// nearest ancestor on a moving joint (or the root), so only those frames are computed. The
/// checkers place a fixed link's spheres in that frame once ([`JointFrames::to_frame`]).
#[derive(Debug, Clone, Default)]
pub struct JointFrames {
    /// Per link: the link whose frame it rides in (itself for a joint link or the root).
    pub frame: Vec<usize>,
    /// Per link: its pose in that frame (identity for joint links and the root).
    pub to_frame: Vec<Frame>,
    /// Per link: its joint origin in the frame of its parent's frame link.
    pub origin: Vec<Frame>,
    /// Joint links and roots, parents first: the frames computed per configuration.
    pub joints: Vec<usize>,
}

impl JointFrames {
    /// The frames of `robot`.
    pub fn new(robot: &Robot) -> Self {
        let n = robot.links.len();
        let mut frame = vec![0; n];
        let mut to_frame = vec![Frame::identity(); n];
        let mut origin = Vec::with_capacity(n);
        let mut joints = Vec::new();
        for (i, link) in robot.links.iter().enumerate() {
            let o = match link.parent {
                Some(p) => to_frame[p] * robot.origin_frames[i],
                None => robot.origin_frames[i],
            };
            match (&link.motion, link.parent) {
                (Motion::Fixed, Some(p)) => {
                    frame[i] = frame[p];
                    to_frame[i] = o;
                }
                _ => {
                    frame[i] = i;
                    joints.push(i);
                }
            }
            origin.push(o);
        }
        JointFrames {
            frame,
            to_frame,
            origin,
            joints,
        }
    }

    /// Writes the base-frame pose of every joint link and root for `q` into `frames` (other
    /// slots untouched).
    #[inline]
    pub fn compute(&self, robot: &Robot, q: &[f64], frames: &mut [Frame]) {
        for &i in &self.joints {
            let link = &robot.links[i];
            let local = joint_frame(link, &self.origin[i], q);
            frames[i] = match link.parent {
                None => local,
                Some(p) => frames[self.frame[p]] * local,
            };
        }
    }

    /// Point `c` of link `l`'s frame in the frame it rides in.
    pub fn place(&self, l: usize, c: [f64; 3]) -> [f64; 3] {
        let w = self.to_frame[l] * nalgebra::Point3::from(c);
        [w.x, w.y, w.z]
    }
}
