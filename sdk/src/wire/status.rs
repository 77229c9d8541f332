//! `ember/<instance>/status`: counters and latencies of the daemon, request-response (the request
//! payload is ignored; send 0).

use iceoryx2::prelude::*;

/// The daemon's state at the time of the reply.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("EmberStatus")]
#[repr(C)]
pub struct StatusReply {
    /// [`super::PROTOCOL_VERSION`].
    pub version: u32,
    /// Degrees of freedom of the robot served.
    pub dof: u32,
    /// Seconds since the daemon started.
    pub uptime_s: f64,
    /// Clouds folded into the map.
    pub clouds: u64,
    /// Object updates applied.
    pub objects: u64,
    /// Joint states received.
    pub joint_states: u64,
    /// Inputs rejected (bad version, sizes, NaN, ...).
    pub rejected: u64,
    /// Plans answered.
    pub plans: u64,
    /// Plans solved.
    pub solved: u64,
    /// Cloud hand-off latency (stamp to receipt in the daemon), median and 99th percentile, µs.
    pub cloud_latency_p50_us: f64,
    /// See `cloud_latency_p50_us`.
    pub cloud_latency_p99_us: f64,
    /// Stamp of the last cloud folded in, ns since the Unix epoch.
    pub last_cloud_stamp_ns: u64,
    /// Map blocks stored.
    pub map_blocks: u64,
    /// Objects in the world.
    pub world_objects: u64,
    /// SPARK database entries.
    pub spark_entries: u64,
    /// FLAME database entries.
    pub flame_entries: u64,
    /// Records written to the session recording.
    pub recorded: u64,
    /// Records dropped because the recorder fell behind.
    pub recording_dropped: u64,
    /// Plans being planned or waiting for a worker.
    pub plans_in_flight: u64,
    /// Age of the oldest plan in flight, ms (0 when none).
    pub oldest_plan_ms: f64,
    /// Plans answered `cancelled` (by a cancel request or the daemon stopping).
    pub cancelled: u64,
    /// Clouds dropped before the daemon read them (its buffer was full).
    pub dropped_clouds: u64,
    /// Object updates dropped before the daemon read them.
    pub dropped_objects: u64,
    /// Joint states dropped before the daemon read them.
    pub dropped_joints: u64,
    /// Times recording failed (a full disk, an I/O error) and paused.
    pub recording_failures: u64,
    /// 1 while recording is paused by a failure (retrying), else 0.
    pub recording_failing: u64,
    /// Objects the robot holds.
    pub world_attached: u64,
    /// Why the daemon last refused an input or request, NUL-padded UTF-8 (empty: never).
    pub last_rejection: [u8; 128],
    /// The [`crate::Status`] code of that refusal (0: none).
    pub last_rejection_status: u32,
}
