//! Scenes: named objects posed in the robot base frame, and their file formats.
//!
//! - [`file`]: Ember's own scene file (YAML);
//! - [`moveit`]: MoveIt `PlanningScene`, `MotionPlanRequest` and `RobotTrajectory` YAML as
//!   MotionBenchMaker writes them (import and export), so existing datasets run unchanged.

pub mod file;
pub mod moveit;

use crate::robot::Robot;
use crate::world::{Environment, Object, WorldError};
use crate::Pose;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use std::borrow::Cow;
use thiserror::Error;

/// A set of named objects in the robot base frame, and objects the robot holds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// Objects, poses in the robot base frame.
    pub objects: Vec<Object>,
    /// Objects attached to robot links (held in the gripper), poses in the link's frame.
    pub attached: Vec<AttachedObject>,
}

/// An object rigidly attached to a robot link (MoveIt's `AttachedCollisionObject`).
#[derive(Debug, Clone, PartialEq)]
pub struct AttachedObject {
    /// The link holding it.
    pub link: String,
    /// The object, posed in the link's frame.
    pub object: Object,
}

impl Scene {
    /// The environment the checker uses for this scene.
    pub fn environment(&self) -> Result<Environment, WorldError> {
        Environment::from_objects(self.objects.iter().cloned())
    }

    /// The robot as this scene has it: `robot` itself, or a copy carrying the attached objects
    /// ([`Robot::with_attached`]). An attachment to a link the robot lacks is an error naming it.
    pub fn robot<'r>(&self, robot: &'r Robot) -> Result<Cow<'r, Robot>, SceneError> {
        self.robot_with(robot, &[])
    }

    /// The robot as this scene and a request's start state have it: joints outside the
    /// planning group at the values `start_joints` gives them (MoveIt's semantics, see
    /// [`Robot::with_joint_values`]), carrying the attached objects.
    pub fn robot_with<'r>(
        &self,
        robot: &'r Robot,
        start_joints: &[(String, f64)],
    ) -> Result<Cow<'r, Robot>, SceneError> {
        let mut out = robot
            .with_joint_values(start_joints.iter().map(|(n, v)| (n.as_str(), *v)))
            .map_err(|e| SceneError::Field {
                path: self.name.clone(),
                field: "start_state".into(),
                message: e.to_string(),
            })?;
        for (i, a) in self.attached.iter().enumerate() {
            let link = robot.link_index(&a.link).ok_or_else(|| SceneError::Field {
                path: self.name.clone(),
                field: format!("attached[{i}].link"),
                message: format!("robot {} has no link '{}'", robot.name(), a.link),
            })?;
            let o = &a.object;
            out = Cow::Owned(out.with_attached(link, &o.name, o.shape, o.pose));
        }
        Ok(out)
    }
}

/// A scene or request file that cannot be used. Names the file and the field at fault.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SceneError {
    /// The file could not be read or written.
    #[error("cannot access {path}: {message}")]
    Io {
        /// File path.
        path: String,
        /// The operating system's reason.
        message: String,
    },
    /// The file is not valid YAML.
    #[error("{path}: not valid YAML: {message}")]
    Syntax {
        /// File path.
        path: String,
        /// Parser message.
        message: String,
    },
    /// A field is missing or has the wrong form.
    #[error("{path}: field {field}: {message}")]
    Field {
        /// File path.
        path: String,
        /// Dotted path of the field, e.g. `world.collision_objects[2].primitives[0].dimensions`.
        field: String,
        /// What is wrong.
        message: String,
    },
}

/// A pose from a position and a quaternion `[x, y, z, w]` (normalised; must not be zero).
pub fn pose_from_xyz_xyzw(xyz: [f64; 3], xyzw: [f64; 4]) -> Option<Pose> {
    let [x, y, z, w] = xyzw;
    let n = (x * x + y * y + z * z + w * w).sqrt();
    if !(n.is_finite() && n > 1e-9 && xyz.iter().all(|v| v.is_finite())) {
        return None;
    }
    Some(Pose::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
    ))
}

/// Position and quaternion `[x, y, z, w]` of a pose.
pub fn pose_to_xyz_xyzw(p: &Pose) -> ([f64; 3], [f64; 4]) {
    let t = p.translation.vector;
    let q = p.rotation.coords;
    ([t.x, t.y, t.z], [q.x, q.y, q.z, q.w])
}

pub(crate) fn read_text(path: &std::path::Path) -> Result<String, SceneError> {
    std::fs::read_to_string(path).map_err(|e| SceneError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

pub(crate) fn write_text(path: &std::path::Path, text: &str) -> Result<(), SceneError> {
    std::fs::write(path, text).map_err(|e| SceneError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}
