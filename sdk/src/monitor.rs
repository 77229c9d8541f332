//! What `emberd` publishes over Zenoh for remote monitoring: the key expressions, the JSON
//! documents (serde types, so a Rust watcher parses them in one line) and the binary map snapshot.
//!
//! Key expressions, per daemon instance (`*` in place of the instance watches a fleet):
//!
//! | key                         | kind                     | payload                        |
//! |-----------------------------|--------------------------|--------------------------------|
//! | `ember/<instance>/alive`    | liveliness token         | none                           |
//! | `ember/<instance>/status`   | publication (1 Hz), query | [`StatusDoc`] JSON            |
//! | `ember/<instance>/plans`    | publication per plan     | [`PlanSummary`] JSON           |
//! | `ember/<instance>/objects`  | publication on change, query | the scene file's document as JSON |
//! | `ember/<instance>/map`      | publication (low rate), query | [`MapSnapshot`] binary    |
//! | `ember/<instance>/database` | query                    | [`DatabaseDoc`] JSON           |
//!
//! Fields are only ever added; a watcher ignores fields it does not know.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Key expression of `leaf` (`alive`, `status`, `plans`, `objects`, `map`, `database`) of
/// `instance` (or `*` for every instance).
pub fn key(instance: &str, leaf: &str) -> String {
    crate::names::service(instance, leaf)
}

/// The instance named by a key expression `ember/<instance>/...`.
pub fn instance_of(key: &str) -> Option<&str> {
    let mut parts = key.split('/');
    (parts.next()? == "ember").then_some(())?;
    parts.next().filter(|i| crate::names::valid_instance(i))
}

/// The daemon's state, published at `status_hz` and answered on query.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StatusDoc {
    /// Instance name.
    pub instance: String,
    /// Robot served.
    pub robot: String,
    /// Its degrees of freedom.
    pub dof: u32,
    /// Daemon process id.
    pub pid: u32,
    /// Ember version of the daemon.
    pub version: String,
    /// Wire protocol version (iceoryx2 services).
    pub protocol: u32,
    /// Seconds since the daemon started.
    pub uptime_s: f64,
    /// When this document was made, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// Sensor and world inputs.
    pub inputs: InputsDoc,
    /// Occupancy map.
    pub map: MapDoc,
    /// Objects and their SPARK pairs.
    pub world: WorldDoc,
    /// Experience database sizes.
    pub experience: DatabaseDoc,
    /// Planning.
    pub plans: PlansDoc,
    /// Session recording.
    pub recording: RecordingDoc,
    /// Monitoring messages dropped because the publisher fell behind.
    pub monitor_dropped: u64,
    /// How the daemon's Zenoh session admits peers: `usrpwd` (only those with a user and
    /// password in its dictionary: what a watcher reads through it came from authenticated
    /// sessions) or `none` (empty in documents of older daemons).
    pub monitor_auth: String,
}

impl From<&StatusDoc> for crate::wire::StatusReply {
    /// The status service's reply: the document's counters in wire form.
    fn from(d: &StatusDoc) -> Self {
        crate::wire::StatusReply {
            version: crate::wire::PROTOCOL_VERSION,
            dof: d.dof,
            uptime_s: d.uptime_s,
            clouds: d.inputs.clouds,
            objects: d.inputs.objects,
            joint_states: d.inputs.joint_states,
            rejected: d.inputs.rejected,
            plans: d.plans.total,
            solved: d.plans.solved,
            cloud_latency_p50_us: d.inputs.cloud_latency_p50_us,
            cloud_latency_p99_us: d.inputs.cloud_latency_p99_us,
            last_cloud_stamp_ns: d.inputs.last_cloud_stamp_ns,
            map_blocks: d.map.blocks,
            world_objects: d.world.objects,
            spark_entries: d.experience.spark_entries,
            flame_entries: d.experience.flame_entries,
            recorded: d.recording.written,
            recording_dropped: d.recording.dropped,
            recording_failures: d.recording.failures,
            recording_failing: d.recording.failing as u64,
            plans_in_flight: d.plans.in_flight,
            oldest_plan_ms: d.plans.oldest_in_flight_ms,
            cancelled: d.plans.cancelled,
            dropped_clouds: d.inputs.dropped_clouds,
            dropped_objects: d.inputs.dropped_objects,
            dropped_joints: d.inputs.dropped_joints,
            world_attached: d.world.attached,
            last_rejection: {
                let mut m = [0u8; 128];
                let b = d.inputs.last_rejection.as_bytes();
                let n = b.len().min(m.len());
                m[..n].copy_from_slice(&b[..n]);
                m
            },
            last_rejection_status: d.inputs.last_rejection_status,
        }
    }
}

/// Input counters and rates.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct InputsDoc {
    /// Clouds folded into the map.
    pub clouds: u64,
    /// Object updates applied.
    pub objects: u64,
    /// Joint states received.
    pub joint_states: u64,
    /// Inputs and requests rejected as malformed.
    pub rejected: u64,
    /// Why an input was last refused (empty: never).
    pub last_rejection: String,
    /// The status code of that refusal (`ember_sdk::Status`; 0: none).
    pub last_rejection_status: u32,
    /// Clouds per second over the last status period.
    pub cloud_hz: f64,
    /// Object updates per second over the last status period.
    pub object_hz: f64,
    /// Joint states per second over the last status period.
    pub joint_hz: f64,
    /// Cloud hand-off latency (sensor stamp to daemon), median, µs.
    pub cloud_latency_p50_us: f64,
    /// Cloud hand-off latency, 99th percentile, µs.
    pub cloud_latency_p99_us: f64,
    /// Stamp of the last cloud, ns since the Unix epoch (0: none yet).
    pub last_cloud_stamp_ns: u64,
    /// Cloud points dropped because a coordinate was NaN or infinite (no-return pixels of
    /// depth cameras; the rest of the cloud is used).
    pub invalid_points: u64,
    /// Clouds dropped before the daemon read them (its buffer was full; counted from gaps in
    /// the publishers' message numbers).
    pub dropped_clouds: u64,
    /// Object updates dropped likewise.
    pub dropped_objects: u64,
    /// Joint states dropped likewise.
    pub dropped_joints: u64,
}

/// The occupancy map's size.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MapDoc {
    /// Leaf size, metres.
    pub resolution: f64,
    /// Stored 4×4×4 leaf blocks.
    pub blocks: u64,
    /// Non-empty octoboxes (blocks with an occupied leaf).
    pub occupied_blocks: u64,
    /// Memory held by the map, bytes.
    pub memory_bytes: u64,
}

/// The objects in the world.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WorldDoc {
    /// Objects.
    pub objects: u64,
    /// SPARK pairs among them.
    pub spark_pairs: u64,
    /// Objects the robot holds.
    pub attached: u64,
}

/// Experience database statistics (also answered on `ember/<instance>/database`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DatabaseDoc {
    /// SPARK entries (one per learned pair).
    pub spark_entries: u64,
    /// FLAME entries (one per learned octobox).
    pub flame_entries: u64,
    /// Whether the daemon learns from each solved plan.
    pub online_learning: bool,
    /// Directory of the database files.
    pub dir: String,
}

/// Planning counters and latencies.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PlansDoc {
    /// Requests answered.
    pub total: u64,
    /// Solved.
    pub solved: u64,
    /// Refused or failed.
    pub failed: u64,
    /// Requests per second over the last status period.
    pub rate_hz: f64,
    /// Time in the daemon from receipt to reply over the last 1000 plans, median, ms.
    pub latency_p50_ms: f64,
    /// Same, 99th percentile, ms.
    pub latency_p99_ms: f64,
    /// Answered `cancelled` (a cancel request, or the daemon stopping).
    pub cancelled: u64,
    /// Being planned or waiting for a worker now.
    pub in_flight: u64,
    /// Age of the oldest plan in flight, ms (0 when none): a watchdog's stuck-planner signal.
    pub oldest_in_flight_ms: f64,
}

/// Session recording.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RecordingDoc {
    /// Whether the session is being recorded.
    pub enabled: bool,
    /// The file being written (empty when off).
    pub path: String,
    /// Records written.
    pub written: u64,
    /// Records dropped because the writer fell behind or was paused by a failure.
    pub dropped: u64,
    /// Times writing failed (a full disk, an I/O error) and recording paused.
    pub failures: u64,
    /// Paused by a failure now; a new file is tried with back-off (0.1 s doubling to 2 s).
    pub failing: bool,
}

/// One answered plan request.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PlanSummary {
    /// Instance name.
    pub instance: String,
    /// Plans answered so far by this daemon, this one included.
    pub seq: u64,
    /// When the request arrived, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// Numbered status ([`crate::Status`]); 0 is success.
    pub status: u32,
    /// Its name (`ok`, `timeout`, ...).
    pub status_name: String,
    /// The daemon's one-sentence outcome.
    pub message: String,
    /// Goal kind: `joints` or `pose`.
    pub goal: String,
    /// Method used: `uniform`, `spark` or `flame`.
    pub method: String,
    /// Waypoints in the path.
    pub waypoints: u32,
    /// Search iterations.
    pub iterations: u64,
    /// Local samplers retrieved from experience.
    pub local_samplers: u32,
    /// Experience retrieval, µs.
    pub retrieval_us: f64,
    /// IK and search, µs.
    pub planning_us: f64,
    /// Simplification, µs.
    pub simplify_us: f64,
    /// Receipt to reply, µs.
    pub total_us: f64,
    /// How long the timed trajectory takes to execute, seconds (0: none was asked for or
    /// made).
    pub duration_s: f64,
}

/// A decimated picture of the occupied map: one record per non-empty 4×4×4 leaf block (FLAME's
/// octobox) with its 64-bit leaf mask. Viewers draw each block as one cube of `4 × resolution`,
/// or unpack the mask (bit `16x + 4y + z` for leaf `(x, y, z)`) for full detail.
///
/// Binary, little endian: magic `EMBERMAP`, `u32` version (1), `f32` leaf resolution (m),
/// `u64` stamp (ns since the Unix epoch), `u32` block count, then per block `i32 × 3` block
/// coordinates and `u64` mask (20 bytes). Block `(i, j, k)` spans
/// `[i, i+1) × 4 × resolution` on x, and likewise on y and z.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MapSnapshot {
    /// Leaf size, metres.
    pub resolution: f32,
    /// When the map was taken, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// Non-empty blocks: coordinates and leaf mask.
    pub blocks: Vec<([i32; 3], u64)>,
}

/// A map snapshot that cannot be decoded.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MapSnapshotError {
    /// Not a map snapshot.
    #[error("not an Ember map snapshot (bad magic)")]
    BadMagic,
    /// Written by a newer Ember.
    #[error("map snapshot version {0} is not supported (this reader knows version 1)")]
    Version(u32),
    /// Shorter or longer than its header says.
    #[error("map snapshot of {got} bytes, its header announces {expected}")]
    Length {
        /// Bytes announced by the header.
        expected: usize,
        /// Bytes received.
        got: usize,
    },
}

const MAP_MAGIC: &[u8; 8] = b"EMBERMAP";
const MAP_HEADER: usize = 8 + 4 + 4 + 8 + 4;
const MAP_RECORD: usize = 20;

impl MapSnapshot {
    /// The binary form.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(MAP_HEADER + MAP_RECORD * self.blocks.len());
        out.extend_from_slice(MAP_MAGIC);
        out.extend_from_slice(&1u32.to_le_bytes());
        out.extend_from_slice(&self.resolution.to_le_bytes());
        out.extend_from_slice(&self.stamp_ns.to_le_bytes());
        out.extend_from_slice(&(self.blocks.len() as u32).to_le_bytes());
        for (k, mask) in &self.blocks {
            for c in k {
                out.extend_from_slice(&c.to_le_bytes());
            }
            out.extend_from_slice(&mask.to_le_bytes());
        }
        out
    }

    /// Reads the binary form.
    pub fn decode(bytes: &[u8]) -> Result<MapSnapshot, MapSnapshotError> {
        if bytes.len() < MAP_HEADER || &bytes[..8] != MAP_MAGIC {
            return Err(MapSnapshotError::BadMagic);
        }
        let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes"));
        let version = u32_at(8);
        if version != 1 {
            return Err(MapSnapshotError::Version(version));
        }
        let resolution = f32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes"));
        let stamp_ns = u64::from_le_bytes(bytes[16..24].try_into().expect("8 bytes"));
        let count = u32_at(24) as usize;
        let expected = MAP_HEADER + MAP_RECORD * count;
        if bytes.len() != expected {
            return Err(MapSnapshotError::Length {
                expected,
                got: bytes.len(),
            });
        }
        let blocks = bytes[MAP_HEADER..]
            .chunks_exact(MAP_RECORD)
            .map(|r| {
                let i = |o: usize| i32::from_le_bytes(r[o..o + 4].try_into().expect("4 bytes"));
                (
                    [i(0), i(4), i(8)],
                    u64::from_le_bytes(r[12..20].try_into().expect("8 bytes")),
                )
            })
            .collect();
        Ok(MapSnapshot {
            resolution,
            stamp_ns,
            blocks,
        })
    }

    /// Occupied leaves in the snapshot.
    pub fn occupied_leaves(&self) -> u64 {
        self.blocks.iter().map(|(_, m)| m.count_ones() as u64).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_snapshot_round_trips_and_rejects_damage() {
        let sut = MapSnapshot {
            resolution: 0.02,
            stamp_ns: 42,
            blocks: vec![([1, -2, 3], 0x8000_0000_0000_0001), ([0, 0, 0], 7)],
        };
        let bytes = sut.encode();
        assert_eq!(MapSnapshot::decode(&bytes).unwrap(), sut);
        assert_eq!(sut.occupied_leaves(), 5);
        assert_eq!(
            MapSnapshot::decode(&bytes[..bytes.len() - 1]),
            Err(MapSnapshotError::Length {
                expected: bytes.len(),
                got: bytes.len() - 1
            })
        );
        assert_eq!(
            MapSnapshot::decode(b"not a map at all, really not a map"),
            Err(MapSnapshotError::BadMagic)
        );
    }

    #[test]
    fn instance_is_read_from_keys() {
        assert_eq!(instance_of("ember/arm-1/status"), Some("arm-1"));
        assert_eq!(instance_of("other/arm-1/status"), None);
        assert_eq!(instance_of("ember/*/status"), None);
    }
}
