//! `ember/<instance>/plan`: planning, request-response with `f64` slices.
//!
//! Request payload: the start configuration (`dof` values) followed by `goal_count` goal
//! configurations (`dof` values each) for a joint goal, nothing more for a pose goal.
//! Response payload: the path, `waypoints × dof` values.

use iceoryx2::prelude::*;

/// Largest request or response payload (values).
pub const MAX_PLAN_VALUES: usize = 16 * 4096;

/// [`PlanRequestHeader::flags`]: answer, but do not learn from this plan (for evaluation runs
/// that must not train on their own test problems).
pub const FLAG_NO_LEARN: u32 = 1;

/// Every flag bit this protocol version knows.
pub const KNOWN_FLAGS: u32 = FLAG_NO_LEARN;

/// [`PlanRequestHeader::goal_kind`] codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum GoalKind {
    /// Goal configurations in the payload.
    Joints = 0,
    /// `pose` for the robot's tip link, with tolerances.
    Pose = 1,
}

/// [`PlanRequestHeader::method`] codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Method {
    /// SPARK when its database has entries, else uniform.
    Auto = 0,
    /// Uniform sampling.
    Uniform = 1,
    /// SPARK (object pairs).
    Spark = 2,
    /// FLAME (octoboxes of the map).
    Flame = 3,
}

/// The request header.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("EmberPlanRequest")]
#[repr(C)]
pub struct PlanRequestHeader {
    /// [`super::PROTOCOL_VERSION`].
    pub version: u32,
    /// Values per configuration (must equal the robot's DOF).
    pub dof: u32,
    /// A [`GoalKind`] code.
    pub goal_kind: u32,
    /// Goal configurations in the payload (joint goals).
    pub goal_count: u32,
    /// A [`Method`] code.
    pub method: u32,
    /// Flag bits: [`FLAG_NO_LEARN`]; other bits are refused.
    pub flags: u32,
    /// Planning time limit, seconds.
    pub time_limit_s: f64,
    /// Seed of every random choice.
    pub seed: u64,
    /// Pose goal for the tip link: x, y, z, qx, qy, qz, qw.
    pub pose: [f64; 7],
    /// Pose goal position tolerance, metres.
    pub position_tolerance: f64,
    /// Pose goal orientation tolerance, radians.
    pub orientation_tolerance: f64,
}

/// The response header.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("EmberPlanResponse")]
#[repr(C)]
pub struct PlanResponseHeader {
    /// [`super::PROTOCOL_VERSION`].
    pub version: u32,
    /// A [`crate::Status`] code.
    pub status: u32,
    /// Values per waypoint.
    pub dof: u32,
    /// Waypoints in the payload.
    pub waypoints: u32,
    /// Search iterations.
    pub iterations: u64,
    /// Retrieval time (experience lookup), microseconds.
    pub retrieval_us: f64,
    /// Planning time (IK + search), microseconds.
    pub planning_us: f64,
    /// Simplification time, microseconds.
    pub simplify_us: f64,
    /// Time in the daemon from receipt to reply, microseconds.
    pub total_us: f64,
    /// Local samplers used (0 for uniform).
    pub local_samplers: u32,
    /// The [`Method`] actually used.
    pub method: u32,
    /// One sentence on the outcome, NUL-padded UTF-8.
    pub message: [u8; 160],
}

impl Default for PlanResponseHeader {
    fn default() -> Self {
        PlanResponseHeader {
            version: super::PROTOCOL_VERSION,
            status: 0,
            dof: 0,
            waypoints: 0,
            iterations: 0,
            retrieval_us: 0.0,
            planning_us: 0.0,
            simplify_us: 0.0,
            total_us: 0.0,
            local_samplers: 0,
            method: 0,
            message: [0; 160],
        }
    }
}
