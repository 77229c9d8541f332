//! URDF → [`Robot`]. urdf-rs types never leave this file, so their upgrades stay private.
//!
//! The planning group comes from a robot file (listed joints), an SRDF group (chains, joints,
//! links, subgroups; passive joints left out) or, for a bare URDF, every movable joint; it must
//! be a chain. Movable joints outside it are folded into their child's origin at their value
//! and kept as [`PassiveJoint`]s, so a request's start state can set them.

use super::description::{LoadInfo, LoadRobotError, MeshInfo};
use super::mesh::{self, PackagePaths};
use super::spheres::SphereModel;
use super::srdf::{Group, Srdf};
use super::{Geometry, Link, LinkShape, Motion, PassiveJoint, Robot, Variable};
use crate::collision::exact::ExactModel;
use crate::collision::Shape;
use crate::Pose;
use nalgebra::{Translation3, Unit, UnitQuaternion, Vector3};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::f64::consts::PI;
use std::path::Path;
use std::sync::Arc;

/// Where the planning group comes from.
pub(crate) enum GroupSource<'a> {
    /// A robot file: joints in configuration order and the tip link.
    Listed {
        name: &'a str,
        joints: &'a [String],
        tip: &'a str,
    },
    /// An SRDF group.
    Srdf { srdf: &'a Srdf, group: &'a Group },
    /// No SRDF: every movable joint (they must form a chain).
    AllMovable,
}

/// Which link pairs are checked for self-collision.
pub(crate) enum SelfCollision<'a> {
    /// Exactly these (a robot file).
    Check(&'a [[String; 2]]),
    /// All but these (an SRDF's `disable_collisions`).
    Disable(&'a [(String, String, String)]),
    /// To be computed by sampling (no SRDF).
    Compute,
}

/// Everything [`build`] reads.
pub(crate) struct BuildInput<'a> {
    pub urdf: &'a urdf_rs::Robot,
    /// Names the URDF in errors.
    pub urdf_name: &'a str,
    /// Folder relative mesh paths start from; `None` for an embedded URDF (no meshes).
    pub base_dir: Option<&'a Path>,
    pub packages: &'a PackagePaths,
    /// Names the file the group came from in errors (robot file or SRDF).
    pub semantics_name: &'a str,
    pub group: GroupSource<'a>,
    /// Values of joints outside the group (others: 0, or the nearest limit).
    pub fixed_joints: &'a BTreeMap<String, f64>,
    pub self_collision: SelfCollision<'a>,
}

/// The robot (no spheres or exact model yet), and whether its self-collision pairs still have
/// to be computed.
pub(crate) struct Built {
    pub robot: Robot,
    pub compute_pairs: bool,
}

fn element_err(path: &str, element: String, message: String) -> LoadRobotError {
    LoadRobotError::Element {
        path: path.to_string(),
        element,
        message,
    }
}

fn is_movable(j: &urdf_rs::Joint) -> bool {
    matches!(
        j.joint_type,
        urdf_rs::JointType::Revolute
            | urdf_rs::JointType::Continuous
            | urdf_rs::JointType::Prismatic
    )
}

/// Builds the robot; errors name the file and element.
pub(crate) fn build(input: &BuildInput, info: &mut LoadInfo) -> Result<Built, LoadRobotError> {
    let urdf = input.urdf;
    let urdf_name = input.urdf_name;
    let urdf_err = |element: String, message: String| element_err(urdf_name, element, message);
    let sem_err =
        |element: String, message: String| element_err(input.semantics_name, element, message);

    // Tree structure: child link -> joint.
    let mut joint_of_child: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
    let link_names: HashSet<&str> = urdf.links.iter().map(|l| l.name.as_str()).collect();
    if link_names.len() != urdf.links.len() {
        return Err(urdf_err(
            "robot".into(),
            "has two links with the same name".into(),
        ));
    }
    for j in &urdf.joints {
        for end in [&j.parent.link, &j.child.link] {
            if !link_names.contains(end.as_str()) {
                return Err(urdf_err(
                    format!("joint '{}'", j.name),
                    format!("refers to unknown link '{end}'"),
                ));
            }
        }
        if joint_of_child.insert(&j.child.link, j).is_some() {
            return Err(urdf_err(
                format!("link '{}'", j.child.link),
                "is the child of more than one joint".into(),
            ));
        }
    }
    let roots: Vec<&str> = urdf
        .links
        .iter()
        .map(|l| l.name.as_str())
        .filter(|l| !joint_of_child.contains_key(l))
        .collect();
    let root = match roots.as_slice() {
        [r] => *r,
        _ => {
            return Err(urdf_err(
                "robot".into(),
                format!("needs exactly one root link, found {roots:?}"),
            ))
        }
    };

    // Depth-first joint order (MoveIt's variable order) and breadth-first link order.
    let dfs_joints = preorder_joints(urdf, root);
    let mut order: Vec<&str> = vec![root];
    let mut i = 0;
    while i < order.len() {
        let parent = order[i];
        for j in urdf.joints.iter().filter(|j| j.parent.link == parent) {
            order.push(&j.child.link);
        }
        i += 1;
    }
    if order.len() != urdf.links.len() {
        return Err(urdf_err(
            "robot".into(),
            "has links not connected to the root (a cycle?)".into(),
        ));
    }
    let index: HashMap<&str, usize> = order.iter().enumerate().map(|(i, n)| (*n, i)).collect();

    // The planning group.
    let (group_name, group_joints, tip_name): (String, Vec<String>, String) = match &input.group {
        GroupSource::Listed { name, joints, tip } => {
            for j in joints.iter() {
                if !urdf.joints.iter().any(|u| &u.name == j) {
                    return Err(sem_err(
                        format!("group joint '{j}'"),
                        format!("is not a joint of {urdf_name}"),
                    ));
                }
            }
            (name.to_string(), joints.to_vec(), tip.to_string())
        }
        GroupSource::Srdf { srdf, group } => {
            let (joints, tip) = srdf_group(srdf, group, urdf, &dfs_joints, input.semantics_name)?;
            info.warnings.extend(
                srdf.warnings
                    .iter()
                    .map(|w| format!("{}: {w}", input.semantics_name)),
            );
            if let Some(v) = srdf.virtual_joints.first() {
                if v.child_link != root {
                    return Err(sem_err(
                        format!("virtual_joint '{}'", v.name),
                        format!(
                            "holds link '{}', but the URDF's root is '{root}'",
                            v.child_link
                        ),
                    ));
                }
                info.virtual_joint = Some((v.name.clone(), v.kind.clone()));
            }
            for e in &srdf.end_effectors {
                if !link_names.contains(e.parent_link.as_str()) {
                    return Err(sem_err(
                        format!("end_effector '{}'", e.name),
                        format!("names unknown link '{}'", e.parent_link),
                    ));
                }
                info.end_effectors
                    .push((e.name.clone(), e.parent_link.clone()));
            }
            for p in &srdf.passive_joints {
                if !urdf.joints.iter().any(|j| &j.name == p) {
                    return Err(sem_err(
                        format!("passive_joint '{p}'"),
                        format!("is not a joint of {urdf_name}"),
                    ));
                }
            }
            (group.name.clone(), joints, tip)
        }
        GroupSource::AllMovable => {
            let joints: Vec<String> = dfs_joints
                .iter()
                .filter(|j| is_movable(j) && j.mimic.is_none())
                .map(|j| j.name.clone())
                .collect();
            check_chain(
                &joints,
                urdf,
                urdf_name,
                "the movable joints (no SRDF given)",
            )?;
            let tip = joints
                .last()
                .and_then(|n| urdf.joints.iter().find(|j| &j.name == n))
                .map(|j| j.child.link.clone())
                .ok_or_else(|| urdf_err("robot".into(), "has no movable joint to plan".into()))?;
            ("all".to_string(), joints, tip)
        }
    };

    // Group variables.
    let mut variables = Vec::new();
    let mut limits = Vec::new();
    let mut variable_of_joint: HashMap<&str, usize> = HashMap::new();
    for name in &group_joints {
        let j = urdf
            .joints
            .iter()
            .find(|j| &j.name == name)
            .expect("group joints were checked");
        let (lower, upper, continuous) = match j.joint_type {
            urdf_rs::JointType::Continuous => (-PI, PI, true),
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Prismatic => {
                let (lo, hi) = (j.limit.lower, j.limit.upper);
                if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    return Err(urdf_err(
                        format!("joint '{name}'"),
                        format!("has unusable limits [{lo}, {hi}]"),
                    ));
                }
                (lo, hi, false)
            }
            ref other => {
                return Err(sem_err(
                    format!("group joint '{name}'"),
                    format!(
                    "is {other:?}; only revolute, continuous and prismatic joints can be planned"
                ),
                ))
            }
        };
        if variable_of_joint
            .insert(name.as_str(), variables.len())
            .is_some()
        {
            return Err(sem_err(
                format!("group joint '{name}'"),
                "is listed twice".into(),
            ));
        }
        variables.push(Variable {
            name: name.clone(),
            lower,
            upper,
            continuous,
        });
        // URDF `<limit velocity>`: 0 (urdf-rs's default) when absent.
        let velocity = j.limit.velocity;
        limits.push(super::limits::JointLimits {
            velocity: (velocity > 0.0).then_some(velocity),
            ..Default::default()
        });
    }
    for name in input.fixed_joints.keys() {
        if !urdf.joints.iter().any(|j| &j.name == name) {
            return Err(sem_err(
                format!("fixed joint '{name}'"),
                format!("is not a joint of {urdf_name}"),
            ));
        }
        if variable_of_joint.contains_key(name.as_str()) {
            return Err(sem_err(
                format!("fixed joint '{name}'"),
                "is also in the planning group".into(),
            ));
        }
    }

    let mut links = Vec::with_capacity(order.len());
    let mut passive = Vec::new();
    for (li, name) in order.iter().enumerate() {
        let ul = urdf.links.iter().find(|l| l.name == *name).expect("listed");
        let mut collision = Vec::new();
        for (ci, c) in ul.collision.iter().enumerate() {
            let element = format!(
                "link '{name}' collision {}",
                c.name.clone().unwrap_or_else(|| ci.to_string())
            );
            let origin = pose(&c.origin);
            for geometry in convert_geometry(&c.geometry, input, name, info)
                .map_err(|m| urdf_err(element.clone(), m))?
            {
                collision.push(LinkShape { origin, geometry });
            }
        }
        let (parent, origin, motion, joint) = match joint_of_child.get(name) {
            None => (None, Pose::identity(), Motion::Fixed, String::new()),
            Some(j) => {
                let origin = pose(&j.origin);
                let parent = Some(index[j.parent.link.as_str()]);
                let axis = Vector3::from(*j.axis.xyz);
                let unit_axis = if is_movable(j) {
                    Some(Unit::try_new(axis, 1e-9).ok_or_else(|| {
                        urdf_err(format!("joint '{}'", j.name), "has a zero axis".into())
                    })?)
                } else {
                    None
                };
                let prismatic = matches!(j.joint_type, urdf_rs::JointType::Prismatic);
                match (variable_of_joint.get(j.name.as_str()), unit_axis) {
                    (Some(&variable), Some(axis)) => {
                        let motion = if prismatic {
                            Motion::Prismatic { axis, variable }
                        } else {
                            Motion::Revolute { axis, variable }
                        };
                        (parent, origin, motion, j.name.clone())
                    }
                    (_, Some(axis)) => {
                        // Not planned: fold its value into the origin; requests may change it.
                        let value = input
                            .fixed_joints
                            .get(&j.name)
                            .copied()
                            .unwrap_or_else(|| default_value(j));
                        let folded = if prismatic {
                            origin * Translation3::from(axis.into_inner() * value)
                        } else {
                            origin * UnitQuaternion::from_axis_angle(&axis, value)
                        };
                        passive.push(PassiveJoint {
                            name: j.name.clone(),
                            link: li,
                            origin,
                            axis,
                            prismatic,
                            value,
                        });
                        (parent, folded, Motion::Fixed, j.name.clone())
                    }
                    (_, None) => (parent, origin, Motion::Fixed, j.name.clone()),
                }
            }
        };
        links.push(Link {
            name: name.to_string(),
            parent,
            origin,
            motion,
            collision,
            joint,
        });
    }

    let tip = *index.get(tip_name.as_str()).ok_or_else(|| {
        sem_err(
            format!("group tip '{tip_name}'"),
            format!("is not a link of {urdf_name}"),
        )
    })?;

    let with_geometry: Vec<usize> = (0..links.len())
        .filter(|&i| !links[i].collision.is_empty())
        .collect();
    let mut self_pairs = Vec::new();
    let mut compute_pairs = false;
    match &input.self_collision {
        SelfCollision::Check(pairs) => {
            for [a, b] in pairs.iter() {
                match (index.get(a.as_str()), index.get(b.as_str())) {
                    (Some(&ia), Some(&ib)) if ia != ib => self_pairs.push((ia.min(ib), ia.max(ib))),
                    _ => {
                        return Err(sem_err(
                            format!("self-collision pair ['{a}', '{b}']"),
                            format!("needs two different links of {urdf_name}"),
                        ))
                    }
                }
            }
        }
        SelfCollision::Disable(disabled) => {
            let mut skip: HashSet<(usize, usize)> = HashSet::new();
            for (a, b, reason) in disabled.iter() {
                match (index.get(a.as_str()), index.get(b.as_str())) {
                    (Some(&ia), Some(&ib)) => {
                        skip.insert((ia.min(ib), ia.max(ib)));
                    }
                    _ => {
                        let unknown = if index.contains_key(a.as_str()) { b } else { a };
                        info.warnings.push(format!(
                            "{}: disable_collisions '{a}'–'{b}' names link '{unknown}', which {urdf_name} does not have (ignored, as MoveIt does)",
                            input.semantics_name
                        ));
                    }
                }
                if index.contains_key(a.as_str()) && index.contains_key(b.as_str()) {
                    info.skipped_pairs
                        .push((a.clone(), b.clone(), reason.clone()));
                }
            }
            for (k, &a) in with_geometry.iter().enumerate() {
                for &b in &with_geometry[k + 1..] {
                    let key = (a.min(b), a.max(b));
                    if !skip.contains(&key) {
                        self_pairs.push(key);
                    }
                }
            }
        }
        SelfCollision::Compute => compute_pairs = true,
    }
    self_pairs.sort_unstable();
    self_pairs.dedup();

    let mut robot = Robot {
        name: urdf.name.clone(),
        group_name,
        links,
        limit_box: super::config_space::LimitBox::of(&variables),
        variables,
        limits,
        tip,
        named_states: Vec::new(),
        self_pairs,
        passive,
        spheres: SphereModel::default(),
        exact: Arc::new(ExactModel::default()),
        info: Arc::default(),
        origin_frames: Vec::new(),
        prepared: Default::default(),
    };
    robot.origin_frames = robot
        .links
        .iter()
        .map(|l| {
            super::fk::Frame::from_parts(
                l.origin.translation,
                l.origin.rotation.to_rotation_matrix(),
            )
        })
        .collect();
    Ok(Built {
        robot,
        compute_pairs,
    })
}

/// Joints in depth-first pre-order from `root` (children in file order).
fn preorder_joints<'a>(urdf: &'a urdf_rs::Robot, root: &str) -> Vec<&'a urdf_rs::Joint> {
    let mut out = Vec::new();
    let mut stack: Vec<&'a urdf_rs::Joint> = urdf
        .joints
        .iter()
        .filter(|j| j.parent.link == root)
        .rev()
        .collect();
    while let Some(j) = stack.pop() {
        out.push(j);
        stack.extend(
            urdf.joints
                .iter()
                .filter(|c| c.parent.link == j.child.link)
                .rev(),
        );
    }
    out
}

/// MoveIt's default for a joint nobody sets: 0 when within limits, else the nearer limit.
fn default_value(j: &urdf_rs::Joint) -> f64 {
    match j.joint_type {
        urdf_rs::JointType::Continuous => 0.0,
        _ if j.limit.lower < j.limit.upper => 0.0f64.clamp(j.limit.lower, j.limit.upper),
        _ => 0.0,
    }
}

/// The group's planned joints (depth-first order) and tip link, resolved against the URDF.
fn srdf_group(
    srdf: &Srdf,
    group: &Group,
    urdf: &urdf_rs::Robot,
    dfs_joints: &[&urdf_rs::Joint],
    srdf_name: &str,
) -> Result<(Vec<String>, String), LoadRobotError> {
    let err = |element: String, message: String| element_err(srdf_name, element, message);
    let mut members: HashSet<String> = HashSet::new();
    let mut seen = HashSet::new();
    let mut todo = vec![group];
    while let Some(g) = todo.pop() {
        if !seen.insert(g.name.clone()) {
            continue;
        }
        let ge = |what: &str, name: &str| format!("group '{}' {what} '{name}'", g.name);
        for j in &g.joints {
            if !urdf.joints.iter().any(|u| &u.name == j) {
                return Err(err(ge("joint", j), "is not a joint of the URDF".into()));
            }
            members.insert(j.clone());
        }
        for l in &g.links {
            if !urdf.links.iter().any(|u| &u.name == l) {
                return Err(err(ge("link", l), "is not a link of the URDF".into()));
            }
            if let Some(j) = urdf.joints.iter().find(|j| &j.child.link == l) {
                members.insert(j.name.clone());
            }
        }
        for (base, tip) in &g.chains {
            for l in [base, tip] {
                if !urdf.links.iter().any(|u| &u.name == l) {
                    return Err(err(ge("chain link", l), "is not a link of the URDF".into()));
                }
            }
            // Walk up from the tip to the base.
            let mut link = tip.as_str();
            while link != base {
                let Some(j) = urdf.joints.iter().find(|j| j.child.link == link) else {
                    return Err(err(
                        format!("group '{}' chain '{base}'–'{tip}'", g.name),
                        format!("'{tip}' does not descend from '{base}'"),
                    ));
                };
                members.insert(j.name.clone());
                link = &j.parent.link;
            }
        }
        for s in &g.subgroups {
            let sub = srdf
                .group(s)
                .ok_or_else(|| err(ge("subgroup", s), "is not a group of the SRDF".into()))?;
            todo.push(sub);
        }
    }
    let joints: Vec<String> = dfs_joints
        .iter()
        .filter(|j| {
            members.contains(&j.name)
                && is_movable(j)
                && j.mimic.is_none()
                && !srdf.passive_joints.contains(&j.name)
        })
        .map(|j| j.name.clone())
        .collect();
    if joints.is_empty() {
        return Err(err(
            format!("group '{}'", group.name),
            "has no movable joint to plan".into(),
        ));
    }
    check_chain(&joints, urdf, srdf_name, &format!("group '{}'", group.name))?;
    let last_child = urdf
        .joints
        .iter()
        .find(|j| Some(&j.name) == joints.last())
        .map(|j| j.child.link.clone())
        .expect("joint exists");
    let tip = match group.chains.as_slice() {
        [(_, tip)] if group.joints.is_empty() && group.subgroups.is_empty() => tip.clone(),
        _ => srdf
            .end_effectors
            .iter()
            .find(|e| e.parent_group.as_deref() == Some(&group.name) || e.parent_link == last_child)
            .map(|e| e.parent_link.clone())
            .unwrap_or(last_child),
    };
    Ok((joints, tip))
}

/// Refuses joints that do not lie on one path from the root (a tree is not a chain).
fn check_chain(
    joints: &[String],
    urdf: &urdf_rs::Robot,
    file: &str,
    what: &str,
) -> Result<(), LoadRobotError> {
    let joint = |n: &str| urdf.joints.iter().find(|j| j.name == n).expect("checked");
    for w in joints.windows(2) {
        let (a, b) = (joint(&w[0]), joint(&w[1]));
        // b must descend from a's child.
        let mut link = b.parent.link.as_str();
        loop {
            if link == a.child.link {
                break;
            }
            match urdf.joints.iter().find(|j| j.child.link == link) {
                Some(j) => link = &j.parent.link,
                None => {
                    return Err(element_err(
                        file,
                        what.to_string(),
                        format!(
                            "is not a chain: joints '{}' and '{}' are on different branches",
                            a.name, b.name
                        ),
                    ))
                }
            }
        }
    }
    Ok(())
}

/// Named states of the planned group from the SRDF's `group_state`s.
pub(crate) fn add_srdf_states(
    robot: &mut Robot,
    srdf: &Srdf,
    srdf_name: &str,
) -> Result<(), LoadRobotError> {
    for s in srdf.states.iter().filter(|s| s.group == robot.group_name) {
        let element = format!("group_state '{}'", s.name);
        let mut q = vec![f64::NAN; robot.dof()];
        for (joint, value) in &s.values {
            match robot.variables.iter().position(|v| &v.name == joint) {
                Some(i) => q[i] = *value,
                None if robot.links.iter().any(|l| &l.joint == joint) => {}
                None => {
                    return Err(element_err(
                        srdf_name,
                        element,
                        format!("names unknown joint '{joint}'"),
                    ))
                }
            }
        }
        if let Some(i) = q.iter().position(|v| v.is_nan()) {
            return Err(element_err(
                srdf_name,
                element,
                format!(
                    "gives no value for group joint '{}'",
                    robot.variables[i].name
                ),
            ));
        }
        robot
            .validate(&q)
            .map_err(|e| element_err(srdf_name, element.clone(), e.to_string()))?;
        robot.named_states.push((s.name.clone(), q));
    }
    Ok(())
}

fn pose(p: &urdf_rs::Pose) -> Pose {
    let [x, y, z] = *p.xyz;
    let [r, pi, ya] = *p.rpy;
    Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, pi, ya),
    )
}

fn convert_geometry(
    g: &urdf_rs::Geometry,
    input: &BuildInput,
    link: &str,
    info: &mut LoadInfo,
) -> Result<Vec<Geometry>, String> {
    let shape = match g {
        urdf_rs::Geometry::Box { size } => Shape::cuboid(**size),
        urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
            radius: *radius,
            half_length: length / 2.0,
        },
        urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
            radius: *radius,
            half_length: length / 2.0,
        },
        urdf_rs::Geometry::Sphere { radius } => Shape::Sphere { radius: *radius },
        urdf_rs::Geometry::Mesh { filename, scale } => {
            let Some(base) = input.base_dir else {
                return Err(format!(
                    "mesh '{filename}' cannot be used in an embedded description (load the URDF from a file)"
                ));
            };
            let scale = scale.map(|s| *s).unwrap_or([1.0; 3]);
            if scale.iter().any(|v| !v.is_finite() || *v == 0.0) {
                return Err(format!("mesh '{filename}' has an unusable scale {scale:?}"));
            }
            let path = mesh::resolve(filename, base, input.packages)?;
            let m = mesh::read_mesh(&path, scale)?;
            if let Some(issue) = m.manifold_issue() {
                info.warnings.push(format!(
                    "{}: link '{link}': mesh {} {issue}; its convex hull is used",
                    input.urdf_name,
                    path.display()
                ));
            }
            let parts = m
                .convex_parts()
                .map_err(|e| format!("mesh {} {e}", path.display()))?;
            info.meshes.push(MeshInfo {
                link: link.to_string(),
                path,
                triangles: m.triangles.len(),
                parts: parts.len(),
            });
            return Ok(parts
                .into_iter()
                .map(|h| Geometry::Convex(Arc::new(h)))
                .collect());
        }
    };
    if shape.is_valid() {
        Ok(vec![Geometry::Primitive(shape)])
    } else {
        Err(format!(
            "{shape:?} has a non-positive or non-finite dimension"
        ))
    }
}
