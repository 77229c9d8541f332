//! URDF → [`Robot`]. urdf-rs types never leave this file, so their upgrades stay private.

use super::description::{LoadRobotError, RobotFile};
use super::spheres::SphereModel;
use super::{Link, LinkShape, Motion, Robot, Variable};
use crate::collision::Shape;
use crate::Pose;
use nalgebra::{Translation3, Unit, UnitQuaternion, Vector3};
use std::collections::HashMap;
use std::f64::consts::PI;

/// Builds the robot; `toml_name` and `urdf_name` name the files in errors.
pub(crate) fn build(
    urdf: &urdf_rs::Robot,
    file: &RobotFile,
    toml_name: &str,
    urdf_name: &str,
) -> Result<Robot, LoadRobotError> {
    let urdf_err = |element: String, message: String| LoadRobotError::Element {
        path: urdf_name.to_string(),
        element,
        message,
    };
    let file_err = |element: String, message: String| LoadRobotError::Element {
        path: toml_name.to_string(),
        element,
        message,
    };

    // Tree structure: child link -> joint.
    let mut joint_of_child: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
    let link_names: Vec<&str> = urdf.links.iter().map(|l| l.name.as_str()).collect();
    for j in &urdf.joints {
        for end in [&j.parent.link, &j.child.link] {
            if !link_names.contains(&end.as_str()) {
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
    let roots: Vec<&str> = link_names
        .iter()
        .copied()
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

    // Group variables.
    let mut variables = Vec::new();
    let mut variable_of_joint: HashMap<&str, usize> = HashMap::new();
    for name in &file.group.joints {
        let j = urdf
            .joints
            .iter()
            .find(|j| &j.name == name)
            .ok_or_else(|| {
                file_err(
                    format!("group joint '{name}'"),
                    format!("is not a joint of {urdf_name}"),
                )
            })?;
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
                return Err(file_err(
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
            return Err(file_err(
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
    }
    for name in file.fixed_joints.keys() {
        if !urdf.joints.iter().any(|j| &j.name == name) {
            return Err(file_err(
                format!("fixed joint '{name}'"),
                format!("is not a joint of {urdf_name}"),
            ));
        }
        if variable_of_joint.contains_key(name.as_str()) {
            return Err(file_err(
                format!("fixed joint '{name}'"),
                "is also in the planning group".into(),
            ));
        }
    }

    // Links in breadth-first order from the root.
    let mut order: Vec<&str> = vec![root];
    let mut i = 0;
    while i < order.len() {
        let parent = order[i];
        for j in urdf.joints.iter().filter(|j| j.parent.link == parent) {
            order.push(&j.child.link);
        }
        i += 1;
    }
    let index: HashMap<&str, usize> = order.iter().enumerate().map(|(i, n)| (*n, i)).collect();

    let mut links = Vec::with_capacity(order.len());
    for name in &order {
        let ul = urdf.links.iter().find(|l| l.name == *name).expect("listed");
        let collision = ul
            .collision
            .iter()
            .map(|c| {
                let shape = convert_geometry(&c.geometry)
                    .map_err(|m| urdf_err(format!("link '{name}' collision"), m))?;
                Ok(LinkShape {
                    origin: pose(&c.origin),
                    shape,
                })
            })
            .collect::<Result<Vec<_>, LoadRobotError>>()?;
        let (parent, origin, motion) = match joint_of_child.get(name) {
            None => (None, Pose::identity(), Motion::Fixed),
            Some(j) => {
                let origin = pose(&j.origin);
                let parent = Some(index[j.parent.link.as_str()]);
                let axis = Vector3::from(*j.axis.xyz);
                let movable = !matches!(j.joint_type, urdf_rs::JointType::Fixed);
                let unit_axis = if movable {
                    Some(Unit::try_new(axis, 1e-9).ok_or_else(|| {
                        urdf_err(format!("joint '{}'", j.name), "has a zero axis".into())
                    })?)
                } else {
                    None
                };
                match (variable_of_joint.get(j.name.as_str()), unit_axis) {
                    (Some(&variable), Some(axis)) => {
                        let motion = if matches!(j.joint_type, urdf_rs::JointType::Prismatic) {
                            Motion::Prismatic { axis, variable }
                        } else {
                            Motion::Revolute { axis, variable }
                        };
                        (parent, origin, motion)
                    }
                    (_, axis) => {
                        // Not planned: fold the fixed value into the origin.
                        let value = file.fixed_joints.get(&j.name).copied().unwrap_or(0.0);
                        let origin = match (axis, &j.joint_type) {
                            (Some(a), urdf_rs::JointType::Prismatic) => {
                                origin * Translation3::from(a.into_inner() * value)
                            }
                            (Some(a), _) => origin * UnitQuaternion::from_axis_angle(&a, value),
                            (None, _) => origin,
                        };
                        (parent, origin, Motion::Fixed)
                    }
                }
            }
        };
        links.push(Link {
            name: name.to_string(),
            parent,
            origin,
            motion,
            collision,
        });
    }

    let tip = *index.get(file.group.tip.as_str()).ok_or_else(|| {
        file_err(
            format!("group tip '{}'", file.group.tip),
            format!("is not a link of {urdf_name}"),
        )
    })?;

    let mut self_pairs = Vec::new();
    for [a, b] in &file.self_collision.pairs {
        let ia = index.get(a.as_str());
        let ib = index.get(b.as_str());
        match (ia, ib) {
            (Some(&ia), Some(&ib)) if ia != ib => self_pairs.push((ia.min(ib), ia.max(ib))),
            _ => {
                return Err(file_err(
                    format!("self-collision pair ['{a}', '{b}']"),
                    format!("needs two different links of {urdf_name}"),
                ))
            }
        }
    }
    self_pairs.sort_unstable();
    self_pairs.dedup();

    let mut robot = Robot {
        name: urdf.name.clone(),
        group_name: file.group.name.clone(),
        links,
        variables,
        tip,
        named_states: Vec::new(),
        self_pairs,
        spheres: SphereModel::default(),
        origin_frames: Vec::new(),
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
    for (name, q) in &file.named_states {
        robot
            .validate(q)
            .map_err(|e| file_err(format!("named state '{name}'"), e.to_string()))?;
        robot.named_states.push((name.clone(), q.clone()));
    }
    Ok(robot)
}

fn pose(p: &urdf_rs::Pose) -> Pose {
    let [x, y, z] = *p.xyz;
    let [r, pi, ya] = *p.rpy;
    Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, pi, ya),
    )
}

fn convert_geometry(g: &urdf_rs::Geometry) -> Result<Shape, String> {
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
        urdf_rs::Geometry::Mesh { filename, .. } => {
            return Err(format!(
                "mesh '{filename}' is not supported: approximate it with boxes, cylinders, capsules or spheres"
            ))
        }
    };
    if shape.is_valid() {
        Ok(shape)
    } else {
        Err(format!(
            "{shape:?} has a non-positive or non-finite dimension"
        ))
    }
}
