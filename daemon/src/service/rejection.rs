//! Why the daemon refused an input: one typed reason per check at the boundary, each with the
//! status code a plan reply carries and the message logs and replies show.

use ember_engine::robot::ConfigError;
use ember_engine::world::model::ChangeError;
use ember_sdk::wire::PROTOCOL_VERSION;
use ember_sdk::Status;
use thiserror::Error;

/// An input the daemon refused. Inputs are counted (`rejected` in the status reply); plan
/// requests are answered with [`Rejection::status`] and the message.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Rejection {
    /// Written for another protocol version.
    #[error("{input} of protocol version {found}, this daemon speaks {PROTOCOL_VERSION}")]
    Version {
        /// What was sent (`"request"`, `"cloud"`, ...).
        input: &'static str,
        /// Its version.
        found: u32,
    },
    /// Configurations of the wrong length.
    #[error("{input} has {found} joints per configuration, the robot has {expected}")]
    WrongDof {
        /// What was sent.
        input: &'static str,
        /// Joints it has.
        found: u32,
        /// Joints the robot has.
        expected: usize,
    },
    /// A goal kind code no version defines.
    #[error("unknown goal kind {0}")]
    UnknownGoalKind(u32),
    /// A method code no version defines.
    #[error("unknown method {0}")]
    UnknownMethod(u32),
    /// Flag bits no version defines.
    #[error("unknown flag bits {0:#x}")]
    UnknownFlags(u32),
    /// A joint goal without configurations.
    #[error("joint goal without goal configurations")]
    NoGoal,
    /// The payload's length does not match the header.
    #[error(
        "payload holds {found} values, expected {expected} ({configurations} configurations of {dof}{})",
        if *timed { " and 2 scaling factors" } else { "" }
    )]
    PayloadLength {
        /// Values sent.
        found: usize,
        /// Values the header implies.
        expected: usize,
        /// Configurations the header implies.
        configurations: usize,
        /// Joints per configuration.
        dof: usize,
        /// Whether a trajectory (2 scaling factors) was asked for.
        timed: bool,
    },
    /// A NaN or infinite number in a request.
    #[error("the request holds a NaN or infinite number")]
    NotFinite,
    /// A time limit above the daemon's cap.
    #[error(
        "time limit {requested} s exceeds the daemon's cap (planner.max_time_limit_s = {cap} s)"
    )]
    TimeLimit {
        /// The limit asked for, seconds.
        requested: f64,
        /// `planner.max_time_limit_s`.
        cap: f64,
    },
    /// Trajectory settings out of range.
    #[error("{0}")]
    Timing(String),
    /// A pose goal whose quaternion is zero.
    #[error("pose goal with a zero quaternion")]
    ZeroQuaternion,
    /// A pose goal with a tolerance that is not positive.
    #[error("pose goal tolerances must be positive")]
    Tolerances,
    /// A joint state outside the limits or not finite.
    #[error("joint state: {0}")]
    JointState(ConfigError),
    /// An object update without a name.
    #[error("object update without an id")]
    ObjectWithoutId,
    /// An object update with a NaN or infinite number.
    #[error("object '{0}': NaN or infinite dimension or pose")]
    ObjectNotFinite(String),
    /// An object shape code no version defines.
    #[error("object '{id}': unknown shape code {code}")]
    UnknownShape {
        /// Object name.
        id: String,
        /// The code sent.
        code: u32,
    },
    /// An object with a dimension that is not positive.
    #[error("object '{id}': dimensions must be positive, got {dims:?}")]
    ObjectDimensions {
        /// Object name.
        id: String,
        /// The dimensions sent.
        dims: [f64; 3],
    },
    /// An object larger, or farther from the base, than ten times the map's bounds.
    #[error("object '{id}': dimensions or position beyond {limit} m (ten times the map bounds)")]
    ObjectExtent {
        /// Object name.
        id: String,
        /// The largest dimension or distance accepted, metres.
        limit: f64,
    },
    /// A new object while the world already holds `limits.objects`.
    #[error("object '{id}': the world already holds {limit} objects (limits.objects)")]
    TooManyObjects {
        /// Object name.
        id: String,
        /// `limits.objects`.
        limit: usize,
    },
    /// An object pose whose quaternion is zero.
    #[error("object '{0}': zero quaternion")]
    ObjectQuaternion(String),
    /// An object change the world refused (unknown object or link, attach twice, ...).
    #[error(transparent)]
    Change(#[from] ChangeError),
    /// A cloud whose header and payload disagree, or an empty one.
    #[error("cloud header says {header} points, payload holds {payload}")]
    PointCount {
        /// Points the header announces.
        header: u32,
        /// Points in the payload.
        payload: usize,
    },
    /// A cloud larger than the configured limit.
    #[error("cloud of {found} points, the limit is {limit}")]
    TooManyPoints {
        /// Points sent.
        found: usize,
        /// `map.max_points`.
        limit: usize,
    },
    /// A cloud whose sensor pose is not finite or has a zero quaternion.
    #[error("cloud from frame '{0}': invalid sensor pose")]
    SensorPose(String),
}

impl Rejection {
    /// Refuses an `input` written for protocol version `found` when it is not this daemon's.
    pub fn check_version(input: &'static str, found: u32) -> Result<(), Rejection> {
        match found == PROTOCOL_VERSION {
            true => Ok(()),
            false => Err(Rejection::Version { input, found }),
        }
    }

    /// Refuses an `input` whose configurations have `found` joints where the robot has
    /// `expected`.
    pub fn check_dof(input: &'static str, found: u32, expected: usize) -> Result<(), Rejection> {
        match found as usize == expected {
            true => Ok(()),
            false => Err(Rejection::WrongDof {
                input,
                found,
                expected,
            }),
        }
    }

    /// The status a plan reply carries for this rejection.
    pub fn status(&self) -> Status {
        match self {
            Rejection::Version { .. } => Status::VersionMismatch,
            Rejection::WrongDof { .. } => Status::WrongDof,
            Rejection::NotFinite => Status::NotFinite,
            Rejection::Change(c) => match c {
                ChangeError::UnknownObject(_) => Status::UnknownObject,
                ChangeError::UnknownLink(_) => Status::UnknownLink,
                ChangeError::AlreadyAttached(_) => Status::AlreadyAttached,
                ChangeError::NotAttached(_) => Status::NotAttached,
                ChangeError::AttachCollides { .. } => Status::AttachCollides,
            },
            _ => Status::BadRequest,
        }
    }
}
