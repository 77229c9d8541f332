//! MoveIt YAML as MotionBenchMaker and robowflex write it: `PlanningScene` (scene),
//! `MotionPlanRequest` (request) and `RobotTrajectory` (path). Import and export.
//!
//! - Poses: `position` and `orientation` as lists (`[x, y, z]`, `[x, y, z, w]`) or as maps
//!   (`{x: .., y: .., z: ..}`); both are read, lists are written.
//! - Primitive types as names (`box`, `sphere`, `cylinder`) or MoveIt's numbers (1, 2, 3);
//!   cylinder `dimensions` are `[height, radius]`; an object-level `pose` is composed with its
//!   `primitive_poses`. Meshes and cones are rejected with the object's id.
//! - Joint states name all robot joints; the planning group's are picked by name.

use super::{pose_from_xyz_xyzw, pose_to_xyz_xyzw, AttachedObject, Scene, SceneError};
use crate::collision::Shape;
use crate::planning::{Goal, PoseGoal};
use crate::robot::Robot;
use crate::world::Object;
use crate::Pose;
use serde::Serialize;
use serde_yaml_ng::Value;

/// A cursor into a YAML document that knows its dotted path, for errors that name the field.
struct Node<'a> {
    v: &'a Value,
    path: String,
    origin: &'a str,
}

impl<'a> Node<'a> {
    fn root(v: &'a Value, origin: &'a str) -> Self {
        Node {
            v,
            path: String::new(),
            origin,
        }
    }

    fn err(&self, message: impl Into<String>) -> SceneError {
        SceneError::Field {
            path: self.origin.to_string(),
            field: if self.path.is_empty() {
                "(document)".into()
            } else {
                self.path.clone()
            },
            message: message.into(),
        }
    }

    fn child_path(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_string()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    fn opt(&self, key: &str) -> Option<Node<'a>> {
        self.v.get(key).filter(|v| !v.is_null()).map(|v| Node {
            v,
            path: self.child_path(key),
            origin: self.origin,
        })
    }

    fn get(&self, key: &str) -> Result<Node<'a>, SceneError> {
        self.opt(key).ok_or_else(|| SceneError::Field {
            path: self.origin.to_string(),
            field: self.child_path(key),
            message: "missing".into(),
        })
    }

    fn seq(&self) -> Result<Vec<Node<'a>>, SceneError> {
        let s = self
            .v
            .as_sequence()
            .ok_or_else(|| self.err("expected a list"))?;
        Ok(s.iter()
            .enumerate()
            .map(|(i, v)| Node {
                v,
                path: format!("{}[{i}]", self.path),
                origin: self.origin,
            })
            .collect())
    }

    fn seq_or_empty(&self, key: &str) -> Result<Vec<Node<'a>>, SceneError> {
        match self.opt(key) {
            Some(n) => n.seq(),
            None => Ok(Vec::new()),
        }
    }

    fn f64(&self) -> Result<f64, SceneError> {
        let x = self
            .v
            .as_f64()
            .ok_or_else(|| self.err("expected a number"))?;
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err("must be finite"))
        }
    }

    fn str(&self) -> Result<&'a str, SceneError> {
        self.v.as_str().ok_or_else(|| self.err("expected a string"))
    }

    fn f64s(&self) -> Result<Vec<f64>, SceneError> {
        self.seq()?.iter().map(|n| n.f64()).collect()
    }

    /// A list `[a, b, ...]` or a map with the given keys.
    fn fixed<const N: usize>(&self, keys: [&str; N]) -> Result<[f64; N], SceneError> {
        if self.v.is_sequence() {
            let v = self.f64s()?;
            return v
                .try_into()
                .map_err(|v: Vec<f64>| self.err(format!("expected {N} numbers, got {}", v.len())));
        }
        let mut out = [0.0; N];
        for (o, k) in out.iter_mut().zip(keys) {
            *o = self.get(k)?.f64()?;
        }
        Ok(out)
    }

    fn pose(&self) -> Result<Pose, SceneError> {
        let xyz = self.get("position")?.fixed(["x", "y", "z"])?;
        let xyzw = match self.opt("orientation") {
            Some(o) => o.fixed(["x", "y", "z", "w"])?,
            None => [0.0, 0.0, 0.0, 1.0],
        };
        pose_from_xyz_xyzw(xyz, xyzw).ok_or_else(|| self.err("quaternion is zero"))
    }
}

fn parse(text: &str, origin: &str) -> Result<Value, SceneError> {
    serde_yaml_ng::from_str(text).map_err(|e| SceneError::Syntax {
        path: origin.to_string(),
        message: e.to_string(),
    })
}

/// True when the text looks like a MoveIt `PlanningScene` rather than Ember's scene file.
pub fn looks_like_planning_scene(text: &str) -> bool {
    text.lines()
        .any(|l| l.starts_with("world:") || l.starts_with("robot_state:"))
}

/// Imports a MoveIt `PlanningScene` YAML (`world.collision_objects`).
pub fn scene_from_yaml(text: &str, origin: &str) -> Result<Scene, SceneError> {
    let doc = parse(text, origin)?;
    let root = Node::root(&doc, origin);
    let mut scene = Scene {
        name: match root.opt("name") {
            Some(n) => n.str()?.to_string(),
            None => String::new(),
        },
        ..Default::default()
    };
    if let Some(world) = root.opt("world") {
        for obj in world.seq_or_empty("collision_objects")? {
            for o in collision_object(&obj)? {
                if scene.objects.iter().any(|x| x.name == o.name) {
                    return Err(obj.err(format!("duplicate object id '{}'", o.name)));
                }
                scene.objects.push(o);
            }
        }
    }
    if let Some(state) = root.opt("robot_state") {
        for att in state.seq_or_empty("attached_collision_objects")? {
            let link = att.get("link_name")?.str()?.to_string();
            for object in collision_object(&att.get("object")?)? {
                scene.attached.push(AttachedObject {
                    link: link.clone(),
                    object,
                });
            }
        }
    }
    Ok(scene)
}

/// The primitives of one `CollisionObject` as objects (`id`, then `id/1`, `id/2`, ... for the
/// further primitives of a compound object), posed in the object's header frame.
fn collision_object(obj: &Node) -> Result<Vec<Object>, SceneError> {
    let id = obj.get("id")?.str()?.to_string();
    if !obj.seq_or_empty("meshes")?.is_empty() {
        return Err(obj.err(format!(
            "object '{id}' has meshes; only box, sphere and cylinder primitives are supported"
        )));
    }
    let base = match obj.opt("pose") {
        Some(p) => p.pose()?,
        None => Pose::identity(),
    };
    let prims = obj.seq_or_empty("primitives")?;
    let poses = obj.seq_or_empty("primitive_poses")?;
    if prims.len() != poses.len() {
        return Err(obj.err(format!(
            "object '{id}' has {} primitives but {} primitive_poses",
            prims.len(),
            poses.len()
        )));
    }
    let mut out = Vec::new();
    for (k, (prim, pose)) in prims.iter().zip(&poses).enumerate() {
        out.push(Object {
            name: if k == 0 {
                id.clone()
            } else {
                format!("{id}/{k}")
            },
            shape: primitive(prim)?,
            pose: base * pose.pose()?,
        });
    }
    Ok(out)
}

fn primitive(prim: &Node) -> Result<Shape, SceneError> {
    let t = prim.get("type")?;
    let kind = match (t.v.as_str(), t.v.as_u64()) {
        (Some(s), _) => s.to_ascii_lowercase(),
        (None, Some(1)) => "box".into(),
        (None, Some(2)) => "sphere".into(),
        (None, Some(3)) => "cylinder".into(),
        (None, Some(4)) => "cone".into(),
        _ => return Err(t.err("expected box, sphere, cylinder or 1..3")),
    };
    let dims_node = prim.get("dimensions")?;
    let d = dims_node.f64s()?;
    let need = |n: usize| -> Result<(), SceneError> {
        if d.len() < n {
            Err(dims_node.err(format!("{kind} needs {n} dimensions, got {}", d.len())))
        } else {
            Ok(())
        }
    };
    let shape = match kind.as_str() {
        "box" => {
            need(3)?;
            Shape::cuboid([d[0], d[1], d[2]])
        }
        "sphere" => {
            need(1)?;
            Shape::Sphere { radius: d[0] }
        }
        "cylinder" => {
            need(2)?;
            // MoveIt: [height, radius].
            Shape::Cylinder {
                radius: d[1],
                half_length: d[0] / 2.0,
            }
        }
        other => return Err(t.err(format!("primitive type '{other}' is not supported"))),
    };
    if shape.is_valid() {
        Ok(shape)
    } else {
        Err(dims_node.err("dimensions must be positive"))
    }
}

/// A list of strings.
fn strings<'a>(node: &Node<'a>) -> Result<Vec<&'a str>, SceneError> {
    node.seq()?.iter().map(|n| n.str()).collect()
}

/// Joint names with values.
type JointValues = Vec<(String, f64)>;

/// Picks the planning group's joints out of a `joint_state {name[], position[]}`, and returns
/// every named joint's value too (joints outside the group take them, as in MoveIt).
fn group_config(js: &Node, robot: &Robot) -> Result<(Vec<f64>, JointValues), SceneError> {
    let names_node = js.get("name")?;
    let names = strings(&names_node)?;
    let pos_node = js.get("position")?;
    let pos = pos_node.f64s()?;
    if names.len() != pos.len() {
        return Err(pos_node.err(format!("{} names but {} positions", names.len(), pos.len())));
    }
    let q = robot
        .group_positions(&names, &pos)
        .map_err(|joint| names_node.err(format!("group joint '{joint}' is missing")))?;
    let all = names
        .iter()
        .zip(&pos)
        .map(|(n, v)| (n.to_string(), *v))
        .collect();
    Ok((q, all))
}

/// A MoveIt `MotionPlanRequest` reduced to what Ember plans with.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionRequest {
    /// Planning group named in the request (may be empty).
    pub group_name: String,
    /// Start configuration in group order.
    pub start: Vec<f64>,
    /// Every joint the start state names, with its value: joints outside the planning group
    /// keep these values while planning ([`Robot::with_joint_values`]).
    pub start_joints: Vec<(String, f64)>,
    /// Goal: joint configurations (one per goal constraint) or a pose.
    pub goal: Goal,
    /// `allowed_planning_time`, seconds, when given.
    pub allowed_planning_time: Option<f64>,
    /// `max_velocity_scaling_factor` and `max_acceleration_scaling_factor`, when given and
    /// not 0 (MoveIt reads 0 as "not set").
    pub scaling: (Option<f64>, Option<f64>),
}

/// Imports a `MotionPlanRequest` YAML for `robot`.
pub fn request_from_yaml(
    text: &str,
    origin: &str,
    robot: &Robot,
) -> Result<MotionRequest, SceneError> {
    let doc = parse(text, origin)?;
    let root = Node::root(&doc, origin);
    let group_name = match root.opt("group_name") {
        Some(n) => n.str()?.to_string(),
        None => String::new(),
    };
    if !group_name.is_empty() && group_name != robot.group_name() {
        return Err(root.get("group_name")?.err(format!(
            "request is for group '{group_name}', the robot's group is '{}'",
            robot.group_name()
        )));
    }
    let (start, start_joints) = group_config(&root.get("start_state")?.get("joint_state")?, robot)?;
    let goals = root.get("goal_constraints")?.seq()?;
    if goals.is_empty() {
        return Err(root.get("goal_constraints")?.err("no goal constraints"));
    }
    let mut joint_goals = Vec::new();
    let mut pose_goal = None;
    for g in &goals {
        let jcs = g.seq_or_empty("joint_constraints")?;
        if !jcs.is_empty() {
            let mut q = vec![f64::NAN; robot.dof()];
            for jc in &jcs {
                let name = jc.get("joint_name")?.str()?;
                let value = jc.get("position")?.f64()?;
                if let Some(i) = robot.variables().iter().position(|v| v.name == name) {
                    q[i] = value;
                }
            }
            if let Some(i) = q.iter().position(|v| v.is_nan()) {
                return Err(g.get("joint_constraints")?.err(format!(
                    "no constraint for group joint '{}'",
                    robot.variables()[i].name
                )));
            }
            joint_goals.push(q);
            continue;
        }
        let pcs = g.seq_or_empty("position_constraints")?;
        let ocs = g.seq_or_empty("orientation_constraints")?;
        if let Some(pc) = pcs.first() {
            pose_goal = Some(pose_goal_from(pc, ocs.first())?);
        }
    }
    let goal = match (joint_goals.is_empty(), pose_goal) {
        (false, _) => Goal::Joints(joint_goals),
        (true, Some(p)) => Goal::Pose(p),
        (true, None) => {
            return Err(root
                .get("goal_constraints")?
                .err("needs joint_constraints or a position_constraint"))
        }
    };
    Ok(MotionRequest {
        group_name,
        start,
        start_joints,
        goal,
        allowed_planning_time: match root.opt("allowed_planning_time") {
            Some(n) => {
                let v = n.f64()?;
                // A planner cannot run for ever, nor for a negative time.
                if !(v > 0.0 && v <= MAX_PLANNING_TIME_S) {
                    return Err(n.err(format!(
                        "allowed_planning_time must be in (0, {MAX_PLANNING_TIME_S}] s, got {v}"
                    )));
                }
                Some(v)
            }
            None => None,
        },
        scaling: (
            scaling_factor(&root, "max_velocity_scaling_factor")?,
            scaling_factor(&root, "max_acceleration_scaling_factor")?,
        ),
    })
}

/// The longest `allowed_planning_time` accepted, seconds (a day).
pub const MAX_PLANNING_TIME_S: f64 = 86_400.0;

fn scaling_factor(root: &Node, key: &str) -> Result<Option<f64>, SceneError> {
    match root.opt(key) {
        Some(n) => Ok(Some(n.f64()?).filter(|&v| v != 0.0)),
        None => Ok(None),
    }
}

fn pose_goal_from(pc: &Node, oc: Option<&Node>) -> Result<PoseGoal, SceneError> {
    let link = pc.get("link_name")?.str()?.to_string();
    let region = pc.get("constraint_region")?;
    let prims = region.seq_or_empty("primitives")?;
    let poses = region.seq_or_empty("primitive_poses")?;
    let (Some(prim), Some(pose)) = (prims.first(), poses.first()) else {
        return Err(region.err("needs one primitive and one primitive pose"));
    };
    let tol = match primitive(prim)? {
        Shape::Sphere { radius } => radius,
        Shape::Box { half_extents: h } => h[0].min(h[1]).min(h[2]),
        Shape::Cylinder { radius, .. } | Shape::Capsule { radius, .. } => radius,
    };
    let position = pose.pose()?.translation;
    let (rotation, orientation_tolerance) = match oc {
        Some(oc) => {
            let q = oc.get("orientation")?.fixed(["x", "y", "z", "w"])?;
            let r = pose_from_xyz_xyzw([0.0; 3], q)
                .ok_or_else(|| oc.err("orientation quaternion is zero"))?
                .rotation;
            let mut tol = f64::INFINITY;
            for k in [
                "absolute_x_axis_tolerance",
                "absolute_y_axis_tolerance",
                "absolute_z_axis_tolerance",
            ] {
                if let Some(n) = oc.opt(k) {
                    tol = tol.min(n.f64()?);
                }
            }
            (r, if tol.is_finite() { tol } else { 0.01 })
        }
        None => (nalgebra::UnitQuaternion::identity(), f64::INFINITY),
    };
    Ok(PoseGoal {
        link: Some(link),
        pose: Pose::from_parts(position, rotation),
        position_tolerance: tol,
        orientation_tolerance,
    })
}

/// Imports a `RobotTrajectory` YAML (`joint_trajectory.points[].positions`) in group order.
pub fn path_from_yaml(
    text: &str,
    origin: &str,
    robot: &Robot,
) -> Result<Vec<Vec<f64>>, SceneError> {
    let doc = parse(text, origin)?;
    let root = Node::root(&doc, origin);
    let jt = root.get("joint_trajectory")?;
    let names_node = jt.get("joint_names")?;
    let names = strings(&names_node)?;
    let index: Vec<usize> = robot
        .variables()
        .iter()
        .map(|v| {
            names
                .iter()
                .position(|n| *n == v.name)
                .ok_or_else(|| names_node.err(format!("group joint '{}' is missing", v.name)))
        })
        .collect::<Result<_, _>>()?;
    jt.get("points")?
        .seq()?
        .iter()
        .map(|p| {
            let pos_node = p.get("positions")?;
            let pos = pos_node.f64s()?;
            if pos.len() != names.len() {
                return Err(pos_node.err(format!(
                    "{} positions for {} joint names",
                    pos.len(),
                    names.len()
                )));
            }
            Ok(index.iter().map(|&i| pos[i]).collect())
        })
        .collect()
}

// ---- export -------------------------------------------------------------------------------

#[derive(Serialize)]
struct PoseOut {
    position: [f64; 3],
    orientation: [f64; 4],
}

impl From<&Pose> for PoseOut {
    fn from(p: &Pose) -> Self {
        let (position, orientation) = pose_to_xyz_xyzw(p);
        PoseOut {
            position,
            orientation,
        }
    }
}

#[derive(Serialize)]
struct JointStateOut {
    name: Vec<String>,
    position: Vec<f64>,
}

fn joint_state(robot: &Robot, q: &[f64]) -> JointStateOut {
    JointStateOut {
        name: robot.variables().iter().map(|v| v.name.clone()).collect(),
        position: q.to_vec(),
    }
}

/// A MoveIt `PlanningScene` YAML for `scene` with the robot at `q`.
pub fn scene_to_yaml(scene: &Scene, robot: &Robot, q: &[f64]) -> String {
    #[derive(Serialize)]
    struct Header {
        frame_id: String,
    }
    #[derive(Serialize)]
    struct Primitive {
        #[serde(rename = "type")]
        kind: &'static str,
        dimensions: Vec<f64>,
    }
    #[derive(Serialize)]
    struct CollisionObject {
        header: Header,
        id: String,
        primitives: Vec<Primitive>,
        primitive_poses: Vec<PoseOut>,
    }
    #[derive(Serialize)]
    struct World {
        collision_objects: Vec<CollisionObject>,
    }
    #[derive(Serialize)]
    struct AttachedOut {
        link_name: String,
        object: CollisionObject,
    }
    #[derive(Serialize)]
    struct RobotState {
        joint_state: JointStateOut,
        #[serde(skip_serializing_if = "Vec::is_empty")]
        attached_collision_objects: Vec<AttachedOut>,
    }
    #[derive(Serialize)]
    struct PlanningScene {
        name: String,
        robot_state: RobotState,
        robot_model_name: String,
        world: World,
        is_diff: bool,
    }
    let base = robot.links()[0].name.clone();
    let collision_object = |o: &Object, frame: &str| {
        // Capsules have no MoveIt primitive: written as their bounding cylinder.
        let (kind, dimensions) = match o.shape {
            Shape::Box { half_extents: h } => ("box", vec![2.0 * h[0], 2.0 * h[1], 2.0 * h[2]]),
            Shape::Sphere { radius } => ("sphere", vec![radius]),
            Shape::Cylinder {
                radius,
                half_length,
            } => ("cylinder", vec![2.0 * half_length, radius]),
            Shape::Capsule {
                radius,
                half_length,
            } => ("cylinder", vec![2.0 * (half_length + radius), radius]),
        };
        CollisionObject {
            header: Header {
                frame_id: frame.to_string(),
            },
            id: o.name.clone(),
            primitives: vec![Primitive { kind, dimensions }],
            primitive_poses: vec![(&o.pose).into()],
        }
    };
    let objects = scene
        .objects
        .iter()
        .map(|o| collision_object(o, &base))
        .collect();
    let attached = scene
        .attached
        .iter()
        .map(|a| AttachedOut {
            link_name: a.link.clone(),
            object: collision_object(&a.object, &a.link),
        })
        .collect();
    let doc = PlanningScene {
        name: scene.name.clone(),
        robot_state: RobotState {
            joint_state: joint_state(robot, q),
            attached_collision_objects: attached,
        },
        robot_model_name: robot.name().to_string(),
        world: World {
            collision_objects: objects,
        },
        is_diff: false,
    };
    serde_yaml_ng::to_string(&doc).expect("scene serialises")
}

/// A MoveIt `MotionPlanRequest` YAML with a joint goal.
pub fn request_to_yaml(robot: &Robot, start: &[f64], goal: &[f64], allowed_time: f64) -> String {
    #[derive(Serialize)]
    struct JointConstraint {
        joint_name: String,
        position: f64,
        tolerance_above: f64,
        tolerance_below: f64,
        weight: f64,
    }
    #[derive(Serialize)]
    struct Constraints {
        joint_constraints: Vec<JointConstraint>,
    }
    #[derive(Serialize)]
    struct StartState {
        joint_state: JointStateOut,
    }
    #[derive(Serialize)]
    struct Request {
        start_state: StartState,
        goal_constraints: Vec<Constraints>,
        group_name: String,
        planner_id: String,
        num_planning_attempts: u32,
        allowed_planning_time: f64,
    }
    let doc = Request {
        start_state: StartState {
            joint_state: joint_state(robot, start),
        },
        goal_constraints: vec![Constraints {
            joint_constraints: robot
                .variables()
                .iter()
                .zip(goal)
                .map(|(v, &position)| JointConstraint {
                    joint_name: v.name.clone(),
                    position,
                    tolerance_above: 0.001,
                    tolerance_below: 0.001,
                    weight: 1.0,
                })
                .collect(),
        }],
        group_name: robot.group_name().to_string(),
        planner_id: "RRTConnect".into(),
        num_planning_attempts: 1,
        allowed_planning_time: allowed_time,
    };
    serde_yaml_ng::to_string(&doc).expect("request serialises")
}

/// The `RobotTrajectory` document, points of either kind.
#[derive(Serialize)]
struct RobotTrajectoryDoc<P> {
    joint_trajectory: JointTrajectoryDoc<P>,
}

#[derive(Serialize)]
struct JointTrajectoryDoc<P> {
    joint_names: Vec<String>,
    points: Vec<P>,
}

/// A `RobotTrajectory` YAML for a timed trajectory: every sample with positions, velocities,
/// accelerations and `time_from_start` (`sec`, `nanosec`), as MoveIt writes it.
pub fn trajectory_to_yaml(t: &crate::trajectory::Trajectory) -> String {
    #[derive(Serialize)]
    struct Duration {
        sec: i32,
        nanosec: u32,
    }
    #[derive(Serialize)]
    struct Point {
        positions: Vec<f64>,
        velocities: Vec<f64>,
        accelerations: Vec<f64>,
        effort: Vec<f64>,
        time_from_start: Duration,
    }
    let doc = RobotTrajectoryDoc {
        joint_trajectory: JointTrajectoryDoc {
            joint_names: t.joint_names.clone(),
            points: (0..t.times.len())
                .map(|k| {
                    let ns = (t.times[k] * 1e9).round() as u64;
                    Point {
                        positions: t.positions[k].clone(),
                        velocities: t.velocities[k].clone(),
                        accelerations: t.accelerations[k].clone(),
                        effort: Vec::new(),
                        time_from_start: Duration {
                            sec: (ns / 1_000_000_000) as i32,
                            nanosec: (ns % 1_000_000_000) as u32,
                        },
                    }
                })
                .collect(),
        },
    };
    serde_yaml_ng::to_string(&doc).expect("trajectory serialises")
}

/// A `RobotTrajectory` YAML for a path (no timing: `time_from_start` counts waypoints).
pub fn path_to_yaml(robot: &Robot, path: &[Vec<f64>]) -> String {
    #[derive(Serialize)]
    struct Point {
        positions: Vec<f64>,
        time_from_start: f64,
    }
    let doc = RobotTrajectoryDoc {
        joint_trajectory: JointTrajectoryDoc {
            joint_names: robot.variables().iter().map(|v| v.name.clone()).collect(),
            points: path
                .iter()
                .enumerate()
                .map(|(i, q)| Point {
                    positions: q.clone(),
                    time_from_start: i as f64,
                })
                .collect(),
        },
    };
    serde_yaml_ng::to_string(&doc).expect("path serialises")
}
