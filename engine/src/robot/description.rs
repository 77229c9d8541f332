//! The robot file and loading.
//!
//! A robot is a URDF (kinematics and collision primitives) plus a small TOML robot file:
//!
//! ```toml
//! urdf = "fetch.urdf"                     # relative to the robot file
//! [group]
//! name = "arm_with_torso"
//! joints = ["torso_lift_joint", "..."]    # configuration order
//! tip = "wrist_roll_link"                 # frame of pose goals
//! [fixed_joints]                          # joints outside the group (default 0)
//! r_gripper_finger_joint = 0.05
//! [named_states]
//! stow = [0.05, 1.32, 1.40, -0.2, 1.72, 0.0, 1.66, 0.0]
//! [spheres]
//! max_growth = 0.03                       # how far spheres may stick out of the primitives
//! [self_collision]
//! pairs = [["base_link", "elbow_flex_link"]]
//! ```
//!
//! Adding a robot is a data change: write these two files.

use super::spheres::{SphereModel, SpherizeParams};
use super::Robot;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why a robot could not be loaded. Every variant names the file and the element at fault.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LoadRobotError {
    /// The file could not be read.
    #[error("cannot read {path}: {message}")]
    Io {
        /// File path.
        path: String,
        /// The operating system's reason.
        message: String,
    },
    /// The robot file is not valid TOML or misses a field.
    #[error("{path}: invalid robot file: {message}")]
    RobotFile {
        /// File path.
        path: String,
        /// Parser message (names the key).
        message: String,
    },
    /// The URDF is not valid XML/URDF.
    #[error("{path}: invalid URDF: {message}")]
    Urdf {
        /// File path.
        path: String,
        /// Parser message.
        message: String,
    },
    /// An element of the URDF or the robot file is unusable.
    #[error("{path}: {element}: {message}")]
    Element {
        /// File path.
        path: String,
        /// The element at fault, e.g. `joint 'elbow_flex_joint'`.
        element: String,
        /// What is wrong with it.
        message: String,
    },
    /// No robot of that name is built in.
    #[error("no built-in robot named '{0}' (built in: fetch, panda)")]
    UnknownBuiltin(String),
}

/// The robot file, as written on disk.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RobotFile {
    pub urdf: String,
    pub group: GroupSection,
    #[serde(default)]
    pub fixed_joints: BTreeMap<String, f64>,
    #[serde(default)]
    pub named_states: BTreeMap<String, Vec<f64>>,
    #[serde(default)]
    pub spheres: SpherizeParams,
    #[serde(default)]
    pub self_collision: SelfCollisionSection,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GroupSection {
    pub name: String,
    pub joints: Vec<String>,
    pub tip: String,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SelfCollisionSection {
    #[serde(default)]
    pub pairs: Vec<[String; 2]>,
}

const FETCH_TOML: &str = include_str!("../../../config/robots/fetch/fetch.toml");
const FETCH_URDF: &str = include_str!("../../../config/robots/fetch/fetch.urdf");
const PANDA_TOML: &str = include_str!("../../../config/robots/panda/panda.toml");
const PANDA_URDF: &str = include_str!("../../../config/robots/panda/panda.urdf");

impl Robot {
    /// Loads a robot from its robot file (TOML); the URDF path inside is relative to it.
    pub fn load(robot_file: impl AsRef<Path>) -> Result<Robot, LoadRobotError> {
        let path = robot_file.as_ref();
        let toml_text = read(path)?;
        let file = parse_robot_file(&toml_text, &path.display().to_string())?;
        let urdf_path: PathBuf = path
            .parent()
            .unwrap_or_else(|| Path::new("."))
            .join(&file.urdf);
        let urdf_text = read(&urdf_path)?;
        Self::from_parts(
            &file,
            &path.display().to_string(),
            &urdf_text,
            &urdf_path.display().to_string(),
        )
    }

    /// A robot shipped inside the binary: `fetch` or `panda`. Needs no files.
    ///
    /// ```
    /// let fetch = ember_engine::robot::Robot::builtin("fetch").unwrap();
    /// assert_eq!(fetch.dof(), 8);
    /// ```
    pub fn builtin(name: &str) -> Result<Robot, LoadRobotError> {
        let (toml_text, urdf_text) = match name {
            "fetch" => (FETCH_TOML, FETCH_URDF),
            "panda" => (PANDA_TOML, PANDA_URDF),
            other => return Err(LoadRobotError::UnknownBuiltin(other.to_string())),
        };
        let toml_name = format!("<built-in>/{name}.toml");
        let file = parse_robot_file(toml_text, &toml_name)?;
        Self::from_parts(
            &file,
            &toml_name,
            urdf_text,
            &format!("<built-in>/{name}.urdf"),
        )
    }

    /// Loads `spec` as a built-in name when it has no path separator or extension, else as a
    /// robot file path.
    pub fn from_spec(spec: &str) -> Result<Robot, LoadRobotError> {
        if spec.contains('/') || spec.ends_with(".toml") {
            Self::load(spec)
        } else {
            Self::builtin(spec)
        }
    }

    fn from_parts(
        file: &RobotFile,
        toml_name: &str,
        urdf_text: &str,
        urdf_name: &str,
    ) -> Result<Robot, LoadRobotError> {
        let parsed = urdf_rs::read_from_string(urdf_text).map_err(|e| LoadRobotError::Urdf {
            path: urdf_name.to_string(),
            message: e.to_string(),
        })?;
        let mut robot = super::urdf::build(&parsed, file, toml_name, urdf_name)?;
        robot.spheres = SphereModel::generate(&robot.links, &file.spheres);
        Ok(robot)
    }
}

fn read(path: &Path) -> Result<String, LoadRobotError> {
    std::fs::read_to_string(path).map_err(|e| LoadRobotError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

fn parse_robot_file(text: &str, name: &str) -> Result<RobotFile, LoadRobotError> {
    toml::from_str(text).map_err(|e| LoadRobotError::RobotFile {
        path: name.to_string(),
        message: e.to_string().trim().replace('\n', " "),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_robots_load() {
        for name in ["fetch", "panda"] {
            let sut = Robot::builtin(name).unwrap();
            assert!(sut.dof() >= 7);
            assert!(sut.spheres().len() > 10);
        }
    }

    #[test]
    fn unknown_group_joint_is_named() {
        let bad = FETCH_TOML.replace("\"elbow_flex_joint\"", "\"elbow_joint\"");
        let file = parse_robot_file(&bad, "x.toml").unwrap();
        let err = Robot::from_parts(&file, "x.toml", FETCH_URDF, "x.urdf").unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("elbow_joint") && text.contains("x.toml"),
            "{text}"
        );
    }

    #[test]
    fn bad_urdf_names_the_file() {
        let file = parse_robot_file(FETCH_TOML, "x.toml").unwrap();
        let err = Robot::from_parts(&file, "x.toml", "<robot name=", "broken.urdf").unwrap_err();
        assert!(err.to_string().contains("broken.urdf"), "{err}");
    }

    #[test]
    fn mesh_geometry_is_rejected_with_the_link_name() {
        let urdf = FETCH_URDF.replacen(
            "<box size=\"0.12 0.13 0.09\"/>",
            "<mesh filename=\"package://x/gripper.stl\"/>",
            1,
        );
        let file = parse_robot_file(FETCH_TOML, "x.toml").unwrap();
        let err = Robot::from_parts(&file, "x.toml", &urdf, "x.urdf").unwrap_err();
        assert!(err.to_string().contains("gripper_link"), "{err}");
    }

    #[test]
    fn unknown_key_in_robot_file_is_named() {
        let bad = format!("{FETCH_TOML}\nbogus_key = 1\n");
        let err = parse_robot_file(&bad, "x.toml").unwrap_err();
        assert!(err.to_string().contains("bogus_key"), "{err}");
    }

    #[test]
    fn named_state_of_wrong_length_is_rejected() {
        let bad = FETCH_TOML.replace(
            "tuck = [0.1, 1.32, 1.40, -0.2, 1.72, 0.0, 1.66, 0.0]",
            "tuck = [0.1, 1.32]",
        );
        let file = parse_robot_file(&bad, "x.toml").unwrap();
        let err = Robot::from_parts(&file, "x.toml", FETCH_URDF, "x.urdf").unwrap_err();
        assert!(err.to_string().contains("tuck"), "{err}");
    }
}
