//! `ember/<instance>/plan`: planning, request-response with `f64` slices.
//!
//! Request payload: the start configuration (`dof` values) followed by `goal_count` goal
//! configurations (`dof` values each) for a joint goal, nothing more for a pose goal; with
//! [`FLAG_TRAJECTORY`], two more values: the velocity and acceleration scaling factors.
//! Response payload: the path, `waypoints × dof` values; with [`FLAG_TRAJECTORY`] and a solved
//! plan, the timed trajectory after it ([`TrajectoryBlock`]).
//!
//! Clients that do not set the flag see the protocol unchanged; a daemon that predates it
//! refuses the flag (`BadRequest`, "unknown flag bits"), so a client can tell.

use iceoryx2::prelude::*;

/// Largest request or response payload (values).
pub const MAX_PLAN_VALUES: usize = 16 * 4096;

/// [`PlanRequestHeader::flags`]: answer, but do not learn from this plan (for evaluation runs
/// that must not train on their own test problems).
pub const FLAG_NO_LEARN: u32 = 1;

/// [`PlanRequestHeader::flags`]: reply with the path timed under the robot's joint limits
/// ([`TrajectoryBlock`] after the path). The request payload ends with the velocity and
/// acceleration scaling factors, each in (0, 1], or 0 for the daemon's configured ones.
pub const FLAG_TRAJECTORY: u32 = 2;

/// Every flag bit this protocol version knows.
pub const KNOWN_FLAGS: u32 = FLAG_NO_LEARN | FLAG_TRAJECTORY;

/// A timed trajectory as it follows the path in a response: `[samples, duration]`, then per
/// sample `[time, positions (dof), velocities (dof), accelerations (dof)]`, then the time at
/// which each waypoint is passed (`waypoints` values). `samples = 0`: none could be made (the
/// message says why).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrajectoryBlock {
    /// Total duration, seconds.
    pub duration: f64,
    /// Sample times, seconds from the start.
    pub times: Vec<f64>,
    /// Positions per sample.
    pub positions: Vec<Vec<f64>>,
    /// Velocities per sample.
    pub velocities: Vec<Vec<f64>>,
    /// Accelerations per sample.
    pub accelerations: Vec<Vec<f64>>,
    /// When each waypoint of the path is passed, seconds.
    pub waypoint_times: Vec<f64>,
}

impl TrajectoryBlock {
    /// Values the block takes for `samples` samples of `dof` joints and `waypoints` waypoints.
    pub fn len_for(samples: usize, dof: usize, waypoints: usize) -> usize {
        2 + samples * (1 + 3 * dof) + if samples > 0 { waypoints } else { 0 }
    }

    /// Appends the block to `out`.
    pub fn encode(&self, out: &mut Vec<f64>) {
        out.push(self.times.len() as f64);
        out.push(self.duration);
        for (k, &t) in self.times.iter().enumerate() {
            out.push(t);
            out.extend_from_slice(&self.positions[k]);
            out.extend_from_slice(&self.velocities[k]);
            out.extend_from_slice(&self.accelerations[k]);
        }
        if !self.times.is_empty() {
            out.extend_from_slice(&self.waypoint_times);
        }
    }

    /// Reads a block of `dof` joints and `waypoints` waypoints from `values` (what follows
    /// the path); `Err` names what does not fit.
    pub fn decode(values: &[f64], dof: usize, waypoints: usize) -> Result<Self, String> {
        let [count, duration, rest @ ..] = values else {
            return Err(format!(
                "{} values, a trajectory block needs 2 at least",
                values.len()
            ));
        };
        if !(count.is_finite() && *count >= 0.0 && count.fract() == 0.0) {
            return Err(format!("sample count {count} is not a count"));
        }
        let samples = *count as usize;
        let expected = Self::len_for(samples, dof, waypoints) - 2;
        if rest.len() != expected {
            return Err(format!(
                "{} values after the header, {samples} samples of {dof} joints and {waypoints} waypoint times take {expected}",
                rest.len()
            ));
        }
        let mut block = TrajectoryBlock {
            duration: *duration,
            ..Default::default()
        };
        let row = 1 + 3 * dof;
        for chunk in rest[..samples * row].chunks_exact(row) {
            block.times.push(chunk[0]);
            block.positions.push(chunk[1..1 + dof].to_vec());
            block.velocities.push(chunk[1 + dof..1 + 2 * dof].to_vec());
            block.accelerations.push(chunk[1 + 2 * dof..].to_vec());
        }
        block.waypoint_times = rest[samples * row..].to_vec();
        Ok(block)
    }
}

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
#[derive(
    Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, serde::Serialize, serde::Deserialize,
)]
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
    /// The client's id for this request (0: none), for cancelling it on the cancel service.
    pub request_id: u64,
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
