//! Robot models: our own [`Robot`] type built once from a URDF plus either a MoveIt SRDF or a
//! small robot file.
//!
//! - [`description`]: what names a robot ([`RobotSpec`]: built-in, robot file, URDF + SRDF)
//!   and loading, including the built-in robots;
//! - [`srdf`]: MoveIt's SRDF (groups, named states, end effectors, disabled collisions);
//! - [`mesh`]: collision meshes (URIs, STL/OBJ/DAE, checks, convex hulls);
//! - `urdf`: URDF → [`Robot`] conversion (urdf-rs types never leave that file);
//! - [`self_collision`]: which link pairs to check, computed the way MoveIt's setup assistant
//!   does when no SRDF says;
//! - [`fk`]: forward kinematics;
//! - [`spheres`]: the sphere model fitted to the collision geometry;
//! - [`config_space`]: joint limits, wrapping, distances and interpolation;
//! - [`sweep`]: how far a motion can move each link's geometry.

pub mod config_space;
pub mod description;
pub mod fk;
pub mod limits;
pub mod mesh;
pub mod primitives;
pub mod self_collision;
pub mod spheres;
pub mod srdf;
pub mod sweep;
mod urdf;

pub use config_space::ConfigError;
#[cfg(feature = "clap")]
pub use description::RobotArgs;
pub use description::{LoadRobotError, RobotSpec};

use crate::collision::convex::ConvexHull;
use crate::collision::exact::ExactModel;
use crate::collision::prepared::{Prepared, PreparedCell};
use crate::collision::Shape;
use crate::Pose;
use nalgebra::{Translation3, Unit, UnitQuaternion, Vector3};
use spheres::SphereModel;
use std::sync::Arc;

/// Link index pairs.
pub(crate) type LinkPairs = Vec<(usize, usize)>;

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

/// Collision geometry of one part of a link.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// A primitive (URDF box, cylinder, capsule, sphere).
    Primitive(Shape),
    /// The convex hull of a mesh, or of one part of its convex decomposition.
    Convex(Arc<ConvexHull>),
}

/// One collision part of a link, posed in the link frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkShape {
    /// Pose of the part in the link frame.
    pub origin: Pose,
    /// The geometry.
    pub geometry: Geometry,
}

/// A movable URDF joint outside the planning group: it holds the value the request's start
/// state gives it (MoveIt's semantics), folded into its child link's origin.
#[derive(Debug, Clone, PartialEq)]
pub struct PassiveJoint {
    /// Joint name.
    pub name: String,
    /// Index of the child link.
    pub link: usize,
    /// Joint origin before the joint's motion (parent frame).
    pub origin: Pose,
    /// Unit axis.
    pub axis: Unit<Vector3<f64>>,
    /// True for prismatic joints.
    pub prismatic: bool,
    /// Current value.
    pub value: f64,
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
    /// Collision parts in the link frame.
    pub collision: Vec<LinkShape>,
    /// Name of the joint that connects it to its parent (empty for the root).
    pub joint: String,
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
    /// The variables' limits and which of them wrap, flat, for the vector paths: derived from
    /// `variables` where the robot is built (see [`config_space::LimitBox`]).
    pub(crate) limit_box: config_space::LimitBox,
    /// Per variable: velocity, acceleration and jerk limits.
    pub(crate) limits: Vec<limits::JointLimits>,
    pub(crate) tip: usize,
    pub(crate) named_states: Vec<(String, Vec<f64>)>,
    pub(crate) self_pairs: Vec<(usize, usize)>,
    pub(crate) passive: Vec<PassiveJoint>,
    pub(crate) spheres: SphereModel,
    pub(crate) exact: Arc<ExactModel>,
    pub(crate) info: Arc<description::LoadInfo>,
    /// Joint origins as rotation-matrix frames (for [`Robot::forward_kinematics_frames`]).
    pub(crate) origin_frames: Vec<fk::Frame>,
    /// The checkers' robot-only data, built on first use (after the robot is complete).
    pub(crate) prepared: PreparedCell,
}

/// How far the spheres of a held object may stand proud of it, at least (metres).
const HELD_PROTRUSION: f64 = 0.02;

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

    /// Per variable (configuration order): its velocity, acceleration and jerk limits.
    pub fn limits(&self) -> &[limits::JointLimits] {
        &self.limits
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

    /// The hand: the tip link and every link below it (a gripper and its fingers).
    pub fn hand_links(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.links.len()).filter(|&i| self.ancestry(i).any(|l| l == self.tip))
    }

    /// Link `link`, then its parent, and so on up to the root.
    pub fn ancestry(&self, link: usize) -> impl Iterator<Item = usize> + '_ {
        std::iter::successors(Some(link), |&l| self.links[l].parent)
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
        self.ancestry(link)
            .any(|l| !matches!(self.links[l].motion, Motion::Fixed))
    }

    /// The sphere model used by the fast checker.
    pub fn spheres(&self) -> &SphereModel {
        &self.spheres
    }

    /// The exact collision geometry (parry3d shapes) used for the decisions that must be exact.
    pub fn exact_model(&self) -> &ExactModel {
        &self.exact
    }

    /// What loading found: sources, warnings, the self-collision pairs skipped and why.
    pub fn load_info(&self) -> &description::LoadInfo {
        &self.info
    }

    /// Movable joints outside the planning group, with their current values.
    pub fn passive_joints(&self) -> &[PassiveJoint] {
        &self.passive
    }

    /// A copy whose joints outside the planning group take `values` (joint name → value, as a
    /// MoveIt request's start state gives them). Names of group joints, fixed joints or joints
    /// the robot lacks are ignored, as MoveIt ignores them; non-finite values are refused.
    pub fn with_joint_values<'a>(
        &self,
        values: impl IntoIterator<Item = (&'a str, f64)>,
    ) -> Result<std::borrow::Cow<'_, Robot>, ConfigError> {
        let mut out: Option<Robot> = None;
        for (name, value) in values {
            let Some(k) = self.passive.iter().position(|p| p.name == name) else {
                continue;
            };
            if !value.is_finite() {
                return Err(ConfigError::NotFinite {
                    joint: name.to_string(),
                    index: k,
                });
            }
            if self.passive[k].value == value {
                continue;
            }
            let robot = out.get_or_insert_with(|| self.clone());
            let p = &mut robot.passive[k];
            p.value = value;
            let origin = if p.prismatic {
                p.origin * Translation3::from(p.axis.into_inner() * value)
            } else {
                p.origin * UnitQuaternion::from_axis_angle(&p.axis, value)
            };
            let link = p.link;
            robot.links[link].origin = origin;
            robot.origin_frames[link] =
                fk::Frame::from_parts(origin.translation, origin.rotation.to_rotation_matrix());
        }
        Ok(match out {
            Some(r) => std::borrow::Cow::Owned(r),
            None => std::borrow::Cow::Borrowed(self),
        })
    }

    /// What the checkers derive from this robot alone (built on first use).
    pub(crate) fn prepared(&self) -> &Prepared {
        self.prepared.get(self)
    }

    /// Self-collision pairs split into those whose relative pose changes with the group
    /// (checked per configuration) and those that never move relative to each other (checked
    /// once).
    pub(crate) fn partition_pairs(&self) -> (LinkPairs, LinkPairs) {
        // Per link, the root of its rigid body (up through fixed joints): two links share a
        // body exactly when they share that root (see [`Robot::rigid_body`]). Parents come
        // first, so one pass finds every root.
        let mut body = Vec::with_capacity(self.links.len());
        for (i, l) in self.links.iter().enumerate() {
            body.push(match (&l.motion, l.parent) {
                (Motion::Fixed, Some(p)) => body[p],
                _ => i,
            });
        }
        self.self_pairs
            .iter()
            .partition(|&&(a, b)| (self.link_moves(a) || self.link_moves(b)) && body[a] != body[b])
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
    /// against the environment, and against every link with geometry outside the hand that
    /// holds it for self-collision. The hand is `parent`'s rigid body and the links jointed
    /// directly to it (the fingers), as MoveIt's touch links for an end effector.
    pub fn with_attached(&self, parent: usize, name: &str, shape: Shape, origin: Pose) -> Robot {
        let mut robot = self.clone();
        let index = robot.links.len();
        robot.links.push(Link {
            name: name.to_string(),
            parent: Some(parent),
            origin: Pose::identity(),
            motion: Motion::Fixed,
            collision: vec![LinkShape {
                origin,
                geometry: Geometry::Primitive(shape),
            }],
            joint: String::new(),
        });
        robot.origin_frames.push(fk::Frame::identity());
        // Held objects are fitted as they are attached, on the world's thread: a coarser fit
        // than the robot's links (tens of ms for a can, a few hundred for a 30 cm box;
        // memoised per shape), coarser still for large objects.
        let protrusion = HELD_PROTRUSION.max(shape.bounding_radius() * 0.1);
        robot.spheres.push_link(
            index,
            &robot.links[index],
            protrusion,
            &spheres::cache::SphereCache::Off,
        );
        robot.exact = Arc::new(ExactModel::build(&robot.links));
        let mut touching = robot.rigid_body(index);
        let fingers: Vec<usize> = (0..index)
            .filter(|&i| robot.links[i].parent.is_some_and(|p| touching.contains(&p)))
            .collect();
        touching.extend(fingers);
        for (i, l) in robot.links.iter().enumerate() {
            if !l.collision.is_empty() && !touching.contains(&i) {
                robot.self_pairs.push((i, index));
            }
        }
        robot.self_pairs.sort_unstable();
        robot
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_split_by_whether_they_move_apart() {
        let fetch = Robot::builtin("fetch").unwrap();
        let hand = fetch.link_index("gripper_link").unwrap();
        let holding = fetch.with_attached(
            hand,
            "can",
            Shape::Cylinder {
                radius: 0.03,
                half_length: 0.06,
            },
            Pose::identity(),
        );
        for mut robot in [Robot::builtin("panda").unwrap(), fetch, holding] {
            // Every pair, the ones a description would disable (same body) included.
            let n = robot.links.len();
            robot.self_pairs = (0..n)
                .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
                .collect();
            let (moving, fixed) = robot.partition_pairs();
            assert!(!moving.is_empty(), "{}", robot.name());
            for &(a, b) in robot.self_collision_pairs() {
                let apart = (robot.link_moves(a) || robot.link_moves(b))
                    && !robot.rigid_body(a).contains(&b);
                assert_eq!(moving.contains(&(a, b)), apart, "{a} {b}");
                assert_eq!(fixed.contains(&(a, b)), !apart, "{a} {b}");
            }
        }
    }
}
