//! What names a robot, and loading it.
//!
//! A robot comes as one of:
//! - a **built-in** name (`fetch`, `panda`): our own descriptions, embedded in the binary;
//! - a **robot file** (TOML) next to a URDF: group, named states, joint values, spheres and
//!   self-collision pairs, as our built-ins are written:
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
//! protrusion = 0.01                       # how far spheres may stick out of the geometry
//! [self_collision]
//! pairs = [["base_link", "elbow_flex_link"]]
//! ```
//! - a **URDF** (meshes or primitives) with an optional MoveIt **SRDF** and group: the way
//!   users bring their robot ([`RobotSpec`]).

use super::limits::{LimitEntry, LimitsFile};
use super::mesh::PackagePaths;
use super::spheres::cache::SphereCache;
use super::spheres::{SphereModel, SpherizeParams};
use super::srdf::Srdf;
use super::urdf::{self, GroupSource, SelfCollision};
use super::Robot;
use crate::collision::exact::ExactModel;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
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
    /// The SRDF is not valid XML/SRDF.
    #[error("{path}: invalid SRDF: {message}")]
    Srdf {
        /// File path.
        path: String,
        /// Parser message.
        message: String,
    },
    /// An element of the URDF, SRDF or robot file is unusable.
    #[error("{path}: {element}: {message}")]
    Element {
        /// File path.
        path: String,
        /// The element at fault, e.g. `joint 'elbow_flex_joint'`.
        element: String,
        /// What is wrong with it.
        message: String,
    },
    /// The options do not fit the kind of robot named.
    #[error("robot {robot}: {message}")]
    Options {
        /// The robot as named.
        robot: String,
        /// What is wrong.
        message: String,
    },
    /// No robot of that name is built in.
    #[error("no built-in robot named '{0}' (built in: fetch, panda; or give a .toml robot file or a .urdf)")]
    UnknownBuiltin(String),
}

/// What names a robot and how to read it: the `--robot`, `--srdf`, `--group`,
/// `--package-path` and `--sphere-protrusion` options (and the `robot`, `srdf`, `group`,
/// `package_path` keys of the daemon's config).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RobotSpec {
    /// A built-in name, a robot file (`.toml`) or a URDF (`.urdf`, `.xml`).
    pub robot: String,
    /// MoveIt SRDF of a URDF robot.
    pub srdf: Option<PathBuf>,
    /// Planning group (default: `arm_with_torso` when the SRDF has it, else its only chain).
    pub group: Option<String>,
    /// Folders where `package://` mesh URIs are looked up first.
    pub package_paths: Vec<PathBuf>,
    /// Sphere protrusion overriding the description's, metres.
    pub protrusion: Option<f64>,
    /// Sphere protrusion on the hand (the tip link and the links below it) overriding the
    /// description's, metres.
    pub hand_protrusion: Option<f64>,
    /// Where fitted spheres are cached.
    pub sphere_cache: SphereCache,
    /// A MoveIt `joint_limits.yaml` overriding the description's velocity limits and adding
    /// acceleration and jerk limits.
    pub joint_limits: Option<PathBuf>,
}

/// The command-line options that name a robot, for any tool built on the engine (feature
/// `clap`): flatten it into a clap command and call [`RobotArgs::spec`].
#[cfg(feature = "clap")]
#[derive(Debug, Clone, Default, PartialEq, clap::Args)]
pub struct RobotArgs {
    /// Robot: a built-in name (fetch, panda), a robot file (.toml) or a URDF (.urdf) [default: fetch].
    #[arg(long)]
    pub robot: Option<String>,
    /// MoveIt SRDF of a URDF robot: groups, named states, disabled collision pairs.
    #[arg(long)]
    pub srdf: Option<PathBuf>,
    /// Planning group of the SRDF [default: arm_with_torso if present, else its only chain group].
    #[arg(long)]
    pub group: Option<String>,
    /// Folder searched first for package:// mesh URIs (repeat); then ROS_PACKAGE_PATH and AMENT_PREFIX_PATH.
    #[arg(long = "package-path")]
    pub package_path: Vec<PathBuf>,
    /// How far fitted spheres may stick out of the robot's geometry, metres [default: the robot file's, else 0.01].
    #[arg(long)]
    pub sphere_protrusion: Option<f64>,
    /// Sphere protrusion on the hand: the group's tip link and the links below it, metres [default: the robot file's, else as the rest].
    #[arg(long)]
    pub sphere_protrusion_hand: Option<f64>,
    /// MoveIt joint_limits.yaml: velocity, acceleration and jerk limits per joint (over the URDF's).
    #[arg(long)]
    pub joint_limits: Option<PathBuf>,
}

#[cfg(feature = "clap")]
impl RobotArgs {
    /// The spec these options name, `default_robot` when `--robot` is absent.
    pub fn spec(&self, default_robot: &str) -> RobotSpec {
        RobotSpec {
            robot: self
                .robot
                .clone()
                .unwrap_or_else(|| default_robot.to_string()),
            srdf: self.srdf.clone(),
            group: self.group.clone(),
            package_paths: self.package_path.clone(),
            protrusion: self.sphere_protrusion,
            hand_protrusion: self.sphere_protrusion_hand,
            sphere_cache: SphereCache::Default,
            joint_limits: self.joint_limits.clone(),
        }
    }
}

/// What loading found, for `ember robot check` and for logs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LoadInfo {
    /// The files read (URDF, SRDF or robot file).
    pub sources: Vec<String>,
    /// Per mesh: link, file, triangles, convex parts.
    pub meshes: Vec<MeshInfo>,
    /// Things MoveIt would also only warn about (unknown links in `disable_collisions`, ...).
    pub warnings: Vec<String>,
    /// Link pairs with geometry that are not checked against each other, and why.
    pub skipped_pairs: Vec<(String, String, String)>,
    /// The SRDF's end effectors (name, parent link).
    pub end_effectors: Vec<(String, String)>,
    /// The SRDF's virtual joint (name, type), when it has one: planning is in the root link's
    /// frame, so a planar or floating one is treated as fixed.
    pub virtual_joint: Option<(String, String)>,
}

/// One collision mesh as loaded.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshInfo {
    /// Link it belongs to.
    pub link: String,
    /// The file.
    pub path: PathBuf,
    /// Triangles in the file.
    pub triangles: usize,
    /// Convex parts it became (1: its hull).
    pub parts: usize,
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
    /// Per joint: MoveIt `joint_limits.yaml` keys (`max_velocity`, `max_acceleration`, ...).
    #[serde(default)]
    pub joint_limits: BTreeMap<String, LimitEntry>,
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

/// Overrides the limits of the planning-group joints `entries` names (other joints, such as
/// grippers in a MoveIt file, are not planned and are skipped).
fn apply_limits(robot: &mut Robot, entries: &BTreeMap<String, LimitEntry>) {
    for (v, limits) in robot.variables.iter().zip(robot.limits.iter_mut()) {
        if let Some(entry) = entries.get(&v.name) {
            *limits = limits.overridden_by(entry);
        }
    }
}

const FETCH_TOML: &str = include_str!("../../../config/robots/fetch/fetch.toml");
const FETCH_URDF: &str = include_str!("../../../config/robots/fetch/fetch.urdf");
const PANDA_TOML: &str = include_str!("../../../config/robots/panda/panda.toml");
const PANDA_URDF: &str = include_str!("../../../config/robots/panda/panda.urdf");

/// How a spec string is read.
enum Kind {
    Builtin,
    RobotFile,
    Urdf,
}

fn kind_of(robot: &str) -> Kind {
    let lower = robot.to_lowercase();
    if lower.ends_with(".urdf") || lower.ends_with(".xml") {
        Kind::Urdf
    } else if lower.ends_with(".toml") || robot.contains('/') {
        Kind::RobotFile
    } else {
        Kind::Builtin
    }
}

impl RobotSpec {
    /// A spec naming `robot` with every option at its default.
    pub fn new(robot: impl Into<String>) -> Self {
        RobotSpec {
            robot: robot.into(),
            ..Default::default()
        }
    }

    /// Loads the robot.
    pub fn load(&self) -> Result<Robot, LoadRobotError> {
        let options_err = |message: &str| LoadRobotError::Options {
            robot: self.robot.clone(),
            message: message.to_string(),
        };
        let packages = PackagePaths {
            explicit: self.package_paths.clone(),
        };
        match kind_of(&self.robot) {
            Kind::Urdf => self.load_urdf(&packages),
            kind => {
                if self.srdf.is_some() || self.group.is_some() {
                    return Err(options_err(
                        "--srdf and --group apply to URDF robots (a .urdf file); a robot file names its group itself",
                    ));
                }
                let (toml_text, toml_name, urdf_text, urdf_path) = match kind {
                    Kind::Builtin => {
                        let (t, u) = match self.robot.as_str() {
                            "fetch" => (FETCH_TOML, FETCH_URDF),
                            "panda" => (PANDA_TOML, PANDA_URDF),
                            other => return Err(LoadRobotError::UnknownBuiltin(other.to_string())),
                        };
                        let name = &self.robot;
                        (
                            t.to_string(),
                            format!("<built-in>/{name}.toml"),
                            u.to_string(),
                            PathBuf::from(format!("<built-in>/{name}.urdf")),
                        )
                    }
                    _ => {
                        let path = Path::new(&self.robot);
                        let text = read(path)?;
                        let file = parse_robot_file(&text, &self.robot)?;
                        let urdf_path = path.parent().unwrap_or(Path::new(".")).join(&file.urdf);
                        let urdf_text = read(&urdf_path)?;
                        (text, self.robot.clone(), urdf_text, urdf_path)
                    }
                };
                let file = parse_robot_file(&toml_text, &toml_name)?;
                let builtin = matches!(kind, Kind::Builtin);
                self.load_robot_file(
                    &file, &toml_name, &urdf_text, &urdf_path, builtin, &packages,
                )
            }
        }
    }

    fn load_robot_file(
        &self,
        file: &RobotFile,
        toml_name: &str,
        urdf_text: &str,
        urdf_path: &Path,
        builtin: bool,
        packages: &PackagePaths,
    ) -> Result<Robot, LoadRobotError> {
        let urdf_name = urdf_path.display().to_string();
        let parsed = parse_urdf(urdf_text, &urdf_name)?;
        let input = urdf::BuildInput {
            urdf: &parsed,
            urdf_name: &urdf_name,
            base_dir: (!builtin).then(|| urdf_path.parent().unwrap_or(Path::new("."))),
            packages,
            semantics_name: toml_name,
            group: GroupSource::Listed {
                name: &file.group.name,
                joints: &file.group.joints,
                tip: &file.group.tip,
            },
            fixed_joints: &file.fixed_joints,
            self_collision: SelfCollision::Check(&file.self_collision.pairs),
        };
        let mut info = LoadInfo {
            sources: vec![toml_name.to_string(), urdf_name.clone()],
            ..Default::default()
        };
        let built = urdf::build(&input, &mut info)?;
        let compute_pairs = built.compute_pairs;
        let mut robot = built.robot;
        for (name, q) in &file.named_states {
            robot.validate(q).map_err(|e| LoadRobotError::Element {
                path: toml_name.to_string(),
                element: format!("named state '{name}'"),
                message: e.to_string(),
            })?;
            robot.named_states.push((name.clone(), q.clone()));
        }
        apply_limits(&mut robot, &file.joint_limits);
        self.finish(robot, compute_pairs, &file.spheres, info, toml_name)
    }

    fn load_urdf(&self, packages: &PackagePaths) -> Result<Robot, LoadRobotError> {
        let urdf_path = Path::new(&self.robot);
        let urdf_name = self.robot.clone();
        let parsed = parse_urdf(&read(urdf_path)?, &urdf_name)?;
        let mut info = LoadInfo {
            sources: vec![urdf_name.clone()],
            ..Default::default()
        };
        let srdf_name = self.srdf.as_ref().map(|p| p.display().to_string());
        let srdf = match &self.srdf {
            Some(p) => {
                info.sources.push(p.display().to_string());
                Some(
                    Srdf::parse(&read(p)?).map_err(|message| LoadRobotError::Srdf {
                        path: p.display().to_string(),
                        message,
                    })?,
                )
            }
            None => None,
        };
        let fixed = BTreeMap::new();
        let (group, self_collision, semantics_name) = match &srdf {
            Some(s) => {
                let srdf_name = srdf_name.as_deref().expect("srdf named");
                let group = match &self.group {
                    Some(g) => s.group(g).ok_or_else(|| LoadRobotError::Element {
                        path: srdf_name.to_string(),
                        element: format!("group '{g}'"),
                        message: format!(
                            "is not defined (groups: {})",
                            s.groups
                                .iter()
                                .map(|g| g.name.as_str())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    })?,
                    None => s.default_group().map_err(|message| LoadRobotError::Srdf {
                        path: srdf_name.to_string(),
                        message,
                    })?,
                };
                (
                    GroupSource::Srdf { srdf: s, group },
                    SelfCollision::Disable(&s.disabled),
                    srdf_name.to_string(),
                )
            }
            None => {
                if self.group.is_some() {
                    return Err(LoadRobotError::Options {
                        robot: self.robot.clone(),
                        message: "--group needs --srdf (groups are defined in the SRDF)".into(),
                    });
                }
                (
                    GroupSource::AllMovable,
                    SelfCollision::Compute,
                    urdf_name.clone(),
                )
            }
        };
        let input = urdf::BuildInput {
            urdf: &parsed,
            urdf_name: &urdf_name,
            base_dir: Some(urdf_path.parent().unwrap_or(Path::new("."))),
            packages,
            semantics_name: &semantics_name,
            group,
            fixed_joints: &fixed,
            self_collision,
        };
        let built = urdf::build(&input, &mut info)?;
        let mut robot = built.robot;
        if let Some(s) = &srdf {
            urdf::add_srdf_states(&mut robot, s, &semantics_name)?;
        }
        self.finish(
            robot,
            built.compute_pairs,
            &SpherizeParams::default(),
            info,
            &semantics_name,
        )
    }

    /// Spheres, exact geometry and (without an SRDF) computed self-collision pairs.
    fn finish(
        &self,
        mut robot: Robot,
        compute_pairs: bool,
        spheres: &SpherizeParams,
        mut info: LoadInfo,
        params_name: &str,
    ) -> Result<Robot, LoadRobotError> {
        if let Some(path) = &self.joint_limits {
            let file =
                LimitsFile::parse(&read(path)?).map_err(|message| LoadRobotError::RobotFile {
                    path: path.display().to_string(),
                    message: format!("not a MoveIt joint_limits.yaml: {message}"),
                })?;
            info.sources.push(path.display().to_string());
            apply_limits(&mut robot, &file.joint_limits);
        }
        let mut params = spheres.clone();
        if let Some(p) = self.protrusion {
            params.protrusion = p;
        }
        if let Some(h) = self.hand_protrusion {
            params.hand = Some(h);
        }
        params
            .validate()
            .map_err(|message| LoadRobotError::Element {
                path: params_name.to_string(),
                element: "spheres".into(),
                message,
            })?;
        let params = params.with_hand(robot.hand_links().map(|i| robot.links[i].name.as_str()));
        for link in &robot.links {
            let protrusion = params.protrusion_of(&link.name);
            let area = super::spheres::fit::surface_area(&link.collision);
            let samples = area / (protrusion * protrusion);
            if samples.is_nan() || samples > super::spheres::fit::MAX_FIT_SAMPLES {
                return Err(LoadRobotError::Element {
                    path: self.robot.clone(),
                    element: format!("link '{}'", link.name),
                    message: format!(
                        "its collision geometry has {area:.3e} m² of surface, too large to fit                          spheres at {protrusion} m protrusion ({samples:.1e} surface samples, at                          most {:.0e}); is a mesh in millimetres without                          scale=\"0.001 0.001 0.001\"?",
                        super::spheres::fit::MAX_FIT_SAMPLES
                    ),
                });
            }
        }
        robot.exact = Arc::new(ExactModel::build(&robot.links));
        if compute_pairs {
            let skipped = super::self_collision::skipped_pairs(
                &robot,
                super::self_collision::DEFAULT_SAMPLES,
                &self.sphere_cache,
            );
            robot.self_pairs = super::self_collision::pairs_except(&robot, &skipped);
            info.skipped_pairs = skipped;
        }
        robot.spheres = SphereModel::generate(&robot.links, &params, &self.sphere_cache);
        robot.info = Arc::new(info);
        Ok(robot)
    }
}

impl Robot {
    /// Loads a robot from its robot file (TOML); the URDF path inside is relative to it.
    pub fn load(robot_file: impl AsRef<Path>) -> Result<Robot, LoadRobotError> {
        RobotSpec::new(robot_file.as_ref().display().to_string()).load()
    }

    /// A robot shipped inside the binary: `fetch` or `panda`. Needs no files.
    ///
    /// ```
    /// let fetch = ember_engine::robot::Robot::builtin("fetch").unwrap();
    /// assert_eq!(fetch.dof(), 8);
    /// ```
    pub fn builtin(name: &str) -> Result<Robot, LoadRobotError> {
        match name {
            "fetch" | "panda" => RobotSpec::new(name).load(),
            other => Err(LoadRobotError::UnknownBuiltin(other.to_string())),
        }
    }

    /// Loads `spec`: a built-in name, a robot file (`.toml` or any path) or a URDF (`.urdf`),
    /// every other option at its default.
    pub fn from_spec(spec: &str) -> Result<Robot, LoadRobotError> {
        RobotSpec::new(spec).load()
    }
}

fn parse_urdf(text: &str, name: &str) -> Result<urdf_rs::Robot, LoadRobotError> {
    urdf_rs::read_from_string(text).map_err(|e| LoadRobotError::Urdf {
        path: name.to_string(),
        message: e.to_string(),
    })
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

    fn from_parts(toml_text: &str, urdf_text: &str) -> Result<Robot, LoadRobotError> {
        let file = parse_robot_file(toml_text, "x.toml")?;
        RobotSpec::new("x.toml").load_robot_file(
            &file,
            "x.toml",
            urdf_text,
            Path::new("x.urdf"),
            true,
            &PackagePaths::default(),
        )
    }

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
        let text = from_parts(&bad, FETCH_URDF).unwrap_err().to_string();
        assert!(
            text.contains("elbow_joint") && text.contains("x.toml"),
            "{text}"
        );
    }

    #[test]
    fn bad_urdf_names_the_file() {
        let err = from_parts(FETCH_TOML, "<robot name=").unwrap_err();
        assert!(err.to_string().contains("x.urdf"), "{err}");
    }

    #[test]
    fn mesh_in_an_embedded_robot_is_refused_with_the_link_name() {
        let at = FETCH_URDF.find("<link name=\"gripper_link\">").unwrap();
        let start = at + FETCH_URDF[at..].find("<geometry>").unwrap();
        let end = start + FETCH_URDF[start..].find("</geometry>").unwrap();
        let urdf = format!(
            "{}<geometry><mesh filename=\"package://x/gripper.stl\"/>{}",
            &FETCH_URDF[..start],
            &FETCH_URDF[end..]
        );
        let err = from_parts(FETCH_TOML, &urdf).unwrap_err();
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
        let err = from_parts(&bad, FETCH_URDF).unwrap_err();
        assert!(err.to_string().contains("tuck"), "{err}");
    }

    #[test]
    fn srdf_options_on_a_builtin_are_refused() {
        let spec = RobotSpec {
            srdf: Some("x.srdf".into()),
            ..RobotSpec::new("fetch")
        };
        let err = spec.load().unwrap_err().to_string();
        assert!(err.contains("--srdf"), "{err}");
    }
}
