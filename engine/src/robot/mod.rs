//! Robot models: our own [`Robot`] type built once from a URDF plus a small robot file.
//!
//! - [`description`]: the robot file (TOML: group, named states, fixed joints, self-collision
//!   pairs) and loading, including the built-in robots;
//! - `urdf`: URDF → [`Robot`] conversion (urdf-rs types never leave that file);
//! - [`fk`]: forward kinematics;
//! - [`spheres`]: the sphere model generated from the collision primitives;
//! - [`config_space`]: joint limits, wrapping, distances and interpolation.

pub mod config_space;
pub mod description;
pub mod fk;
pub mod spheres;
mod urdf;

pub use config_space::ConfigError;
pub use description::LoadRobotError;

use crate::collision::Shape;
use crate::Pose;
use nalgebra::{Unit, Vector3};
use spheres::SphereModel;

/// How a link moves relative to its parent, after its joint origin.
#[derive(Debug, Clone, PartialEq)]
pub enum Motion {
    /// Rigidly attached (fixed joints, and joints outside the planning group, whose value is
    /// folded into the origin at load time).
    Fixed,
    /// Rotation about `axis` by the value of group variable `variable`.
    Revolute {
        /// Unit axis in the joint frame.
        axis: Unit<Vector3<f64>>,
        /// Index of the planning-group variable that drives it.
        variable: usize,
    },
    /// Translation along `axis` by the value of group variable `variable`.
    Prismatic {
        /// Unit axis in the joint frame.
        axis: Unit<Vector3<f64>>,
        /// Index of the planning-group variable that drives it.
        variable: usize,
    },
}

/// One collision primitive of a link, posed in the link frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkShape {
    /// Pose of the primitive in the link frame.
    pub origin: Pose,
    /// The primitive.
    pub shape: Shape,
}

/// A rigid body of the robot.
#[derive(Debug, Clone)]
pub struct Link {
    /// Name as in the URDF.
    pub name: String,
    /// Parent link index; `None` for the root. Parents always come before children.
    pub parent: Option<usize>,
    /// Pose of the joint frame in the parent link frame.
    pub origin: Pose,
    /// Motion of the link about its joint frame.
    pub motion: Motion,
    /// Collision primitives in the link frame.
    pub collision: Vec<LinkShape>,
}

/// A planning-group variable (one joint).
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// Joint name.
    pub name: String,
    /// Lower limit (radians or metres); `-π` for continuous joints.
    pub lower: f64,
    /// Upper limit; `π` for continuous joints.
    pub upper: f64,
    /// Continuous (unbounded, wrapping) revolute joint.
    pub continuous: bool,
}

/// A robot model: kinematic tree, planning group, collision geometry and sphere model.
///
/// Built by [`Robot::load`] or [`Robot::builtin`]; immutable afterwards and cheap to share.
#[derive(Debug, Clone)]
pub struct Robot {
    pub(crate) name: String,
    pub(crate) group_name: String,
    pub(crate) links: Vec<Link>,
    pub(crate) variables: Vec<Variable>,
    pub(crate) tip: usize,
    pub(crate) named_states: Vec<(String, Vec<f64>)>,
    pub(crate) self_pairs: Vec<(usize, usize)>,
    pub(crate) spheres: SphereModel,
    /// Joint origins as rotation-matrix frames (for [`Robot::forward_kinematics_frames`]).
    pub(crate) origin_frames: Vec<fk::Frame>,
}

impl Robot {
    /// Robot name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Planning-group name.
    pub fn group_name(&self) -> &str {
        &self.group_name
    }

    /// Number of planning-group variables (degrees of freedom).
    pub fn dof(&self) -> usize {
        self.variables.len()
    }

    /// Planning-group variables, in configuration order.
    pub fn variables(&self) -> &[Variable] {
        &self.variables
    }

    /// Links in topological order (parents first).
    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// Index of the link named `name`.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.links.iter().position(|l| l.name == name)
    }

    /// Index of the tip link (the frame pose goals refer to).
    pub fn tip(&self) -> usize {
        self.tip
    }

    /// A named configuration (`stow`, `ready`, ...).
    pub fn named_state(&self, name: &str) -> Option<&[f64]> {
        self.named_states
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, q)| q.as_slice())
    }

    /// Names of all named configurations.
    pub fn named_state_names(&self) -> impl Iterator<Item = &str> {
        self.named_states.iter().map(|(n, _)| n.as_str())
    }

    /// Link pairs checked for self-collision (link indices).
    pub fn self_collision_pairs(&self) -> &[(usize, usize)] {
        &self.self_pairs
    }

    /// True when the link moves with some planning-group joint (false for the base and
    /// everything rigidly attached to it).
    pub fn link_moves(&self, link: usize) -> bool {
        let mut i = link;
        loop {
            let l = &self.links[i];
            if !matches!(l.motion, Motion::Fixed) {
                return true;
            }
            match l.parent {
                Some(p) => i = p,
                None => return false,
            }
        }
    }

    /// The sphere model used by the fast checker.
    pub fn spheres(&self) -> &SphereModel {
        &self.spheres
    }

    /// Links moving rigidly with `link` (itself included): up through fixed joints to the body's
    /// root, then down through fixed joints (a gripper's palm and fingers, for its wrist).
    pub fn rigid_body(&self, link: usize) -> Vec<usize> {
        let mut root = link;
        while let (Motion::Fixed, Some(p)) = (&self.links[root].motion, self.links[root].parent) {
            root = p;
        }
        let mut body = vec![root];
        // Parents come before children, so one pass in order finds every fixed descendant.
        for (i, l) in self.links.iter().enumerate().skip(root + 1) {
            if matches!(l.motion, Motion::Fixed) && l.parent.is_some_and(|p| body.contains(&p)) {
                body.push(i);
            }
        }
        body
    }

    /// A copy of this robot holding `shape` rigidly at `origin` in the frame of link `parent`
    /// (an object in the gripper). The object becomes a fixed link named `name`: it is checked
    /// against the environment, and against every link with geometry outside `parent`'s rigid
    /// body for self-collision (the hand that holds it may touch it).
    pub fn with_attached(&self, parent: usize, name: &str, shape: Shape, origin: Pose) -> Robot {
        /// Tighter than the robot's own spheres: held objects are small.
        const ATTACHED_GROWTH: f64 = 0.01;
        let mut robot = self.clone();
        let index = robot.links.len();
        robot.links.push(Link {
            name: name.to_string(),
            parent: Some(parent),
            origin: Pose::identity(),
            motion: Motion::Fixed,
            collision: vec![LinkShape { origin, shape }],
        });
        robot.origin_frames.push(fk::Frame::identity());
        robot
            .spheres
            .push_link(index, &robot.links[index], ATTACHED_GROWTH);
        let touching = robot.rigid_body(index);
        for (i, l) in robot.links.iter().enumerate() {
            if !l.collision.is_empty() && !touching.contains(&i) {
                robot.self_pairs.push((i, index));
            }
        }
        robot.self_pairs.sort_unstable();
        robot
    }
}
