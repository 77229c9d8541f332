//! Forward kinematics: the pose of every link in the robot's base frame.

use super::{ConfigError, Motion, Robot};
use crate::Pose;
use nalgebra::{IsometryMatrix3, Rotation3, Translation3, UnitQuaternion};

/// A link frame as rotation matrix plus translation: the checker's representation, cheaper
/// than quaternions for transforming many points.
pub type Frame = IsometryMatrix3<f64>;

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
            let local = match link.motion {
                Motion::Fixed => link.origin,
                Motion::Revolute { axis, variable } => {
                    link.origin * UnitQuaternion::from_axis_angle(&axis, q[variable])
                }
                Motion::Prismatic { axis, variable } => {
                    link.origin * Translation3::from(axis.into_inner() * q[variable])
                }
            };
            poses[i] = match link.parent {
                None => local,
                Some(p) => poses[p] * local,
            };
        }
    }

    /// Like [`Robot::forward_kinematics`], writing rotation-matrix [`Frame`]s (the form the
    /// collision checker uses).
    #[inline]
    pub fn forward_kinematics_frames(&self, q: &[f64], frames: &mut [Frame]) {
        debug_assert_eq!(q.len(), self.dof());
        debug_assert_eq!(frames.len(), self.links.len());
        for (i, link) in self.links.iter().enumerate() {
            let origin = &self.origin_frames[i];
            let local = match link.motion {
                Motion::Fixed => *origin,
                Motion::Revolute { axis, variable } => {
                    origin * Rotation3::from_axis_angle(&axis, q[variable])
                }
                Motion::Prismatic { axis, variable } => {
                    origin * Translation3::from(axis.into_inner() * q[variable])
                }
            };
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
