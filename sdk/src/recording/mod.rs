//! Messages of session recordings (MCAP), shared by the daemon's recorder and readers: ROS 2 message types in CDR for the standard data
//! (`sensor_msgs/msg/PointCloud2`, `sensor_msgs/msg/JointState`, `geometry_msgs/msg/PoseStamped`,
//! `trajectory_msgs/msg/JointTrajectory`)
//! and documented schemas of our own (`ember_msgs/msg/...`) for objects and plans, with their
//! `ros2msg` schema texts, so ROS 2 tools and the Python `mcap` readers decode them.

//!
//! This module is the one home of the recording format: topic names ([`topic`], [`TOPICS`]),
//! message types and schemas, the conversions between wire payloads and recorded messages, and
//! [`Event`] — one recorded input or answer, what the daemon's recorder writes
//! ([`Event::messages`]) and what [`crate::session`] reads back.

#![allow(missing_docs)] // Field names mirror the ROS 2 message definitions above them.

mod event;

pub use event::Event;
use serde::{Deserialize, Serialize};

const SEP: &str =
    "================================================================================\n";
const TIME: &str = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
const HEADER: &str = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n";
const POSE: &str =
    "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n";
const POINT: &str = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n";
const QUAT: &str = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";

fn with_deps(main: &str, deps: &[&str]) -> String {
    let mut s = main.to_string();
    for d in deps {
        s.push_str(SEP);
        s.push_str(d);
    }
    s
}

/// Topic names of Ember's recordings (written by the daemon's recorder, read by
/// [`crate::session`]).
pub mod topic {
    pub const CLOUD: &str = "/ember/cloud";
    pub const CLOUD_POSE: &str = "/ember/cloud_pose";
    pub const JOINTS: &str = "/ember/joints";
    pub const OBJECTS: &str = "/ember/objects";
    pub const PLAN_REQUEST: &str = "/ember/plan_request";
    pub const PLAN_RESPONSE: &str = "/ember/plan_response";
    pub const PLAN_TRAJECTORY: &str = "/ember/plan_trajectory";
}

/// Every recorded topic with the schema its messages carry (one channel each).
pub const TOPICS: [(&str, &str); 7] = [
    (topic::CLOUD, "sensor_msgs/msg/PointCloud2"),
    (topic::CLOUD_POSE, "geometry_msgs/msg/PoseStamped"),
    (topic::JOINTS, "sensor_msgs/msg/JointState"),
    (topic::OBJECTS, "ember_msgs/msg/ObjectUpdate"),
    (topic::PLAN_REQUEST, "ember_msgs/msg/PlanRequest"),
    (topic::PLAN_RESPONSE, "ember_msgs/msg/PlanResponse"),
    (
        topic::PLAN_TRAJECTORY,
        "trajectory_msgs/msg/JointTrajectory",
    ),
];

/// (schema name, ros2msg text) of every recorded type.
pub fn schemas() -> Vec<(&'static str, String)> {
    vec![
        (
            "sensor_msgs/msg/PointCloud2",
            with_deps(
                "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
                &[HEADER, TIME, "MSG: sensor_msgs/PointField\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n"],
            ),
        ),
        (
            "sensor_msgs/msg/JointState",
            with_deps("std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n", &[HEADER, TIME]),
        ),
        (
            "geometry_msgs/msg/PoseStamped",
            with_deps("std_msgs/Header header\ngeometry_msgs/Pose pose\n", &[HEADER, TIME, POSE, POINT, QUAT]),
        ),
        (
            "trajectory_msgs/msg/JointTrajectory",
            with_deps(
                "std_msgs/Header header\nstring[] joint_names\nJointTrajectoryPoint[] points\n",
                &[
                    HEADER,
                    TIME,
                    "MSG: trajectory_msgs/JointTrajectoryPoint\nfloat64[] positions\nfloat64[] velocities\nfloat64[] accelerations\nfloat64[] effort\nbuiltin_interfaces/Duration time_from_start\n",
                    "MSG: builtin_interfaces/Duration\nint32 sec\nuint32 nanosec\n",
                ],
            ),
        ),
        (
            "ember_msgs/msg/ObjectUpdate",
            with_deps(
                "# shape: 0 remove, 1 box (dims = size), 2 cylinder (radius, length), 3 sphere (radius), 4 capsule (radius, length), 5 the tracked shape\n# link: the robot link holding the object (attach; pose in its frame), empty: a world object in the base frame (detach when shape is 5)\nstd_msgs/Header header\nstring id\nuint32 shape\nfloat64[3] dims\ngeometry_msgs/Pose pose\nstring link\n",
                &[HEADER, TIME, POSE, POINT, QUAT],
            ),
        ),
        (
            "ember_msgs/msg/PlanRequest",
            with_deps(
                "# The plan request as received: values = start, then goal_count goal configurations.\nstd_msgs/Header header\nuint32 version\nuint32 dof\nuint32 goal_kind\nuint32 goal_count\nuint32 method\nuint32 flags\nfloat64 time_limit_s\nuint64 seed\nfloat64[7] pose\nfloat64 position_tolerance\nfloat64 orientation_tolerance\nuint64 request_id\nfloat64[] values\n",
                &[HEADER, TIME],
            ),
        ),
        (
            "ember_msgs/msg/PlanResponse",
            with_deps(
                "# The reply: status code, timings, and the path (waypoints x dof values).\nstd_msgs/Header header\nuint32 status\nuint32 dof\nuint32 waypoints\nuint64 iterations\nfloat64 retrieval_us\nfloat64 planning_us\nfloat64 simplify_us\nfloat64 total_us\nuint32 method\nstring message\nfloat64[] path\n",
                &[HEADER, TIME],
            ),
        ),
    ]
}

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    pub fn from_ns(ns: u64) -> Self {
        Time {
            sec: (ns / 1_000_000_000) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    pub fn ns(&self) -> u64 {
        self.sec.max(0) as u64 * 1_000_000_000 + self.nanosec as u64
    }
}

impl Time {
    /// A duration of `seconds` (non-negative) as `builtin_interfaces/Duration` (same layout).
    pub fn from_secs(seconds: f64) -> Self {
        Time::from_ns((seconds.max(0.0) * 1e9).round() as u64)
    }

    /// Seconds.
    pub fn secs(&self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `sensor_msgs/PointField`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointField {
    pub name: String,
    pub offset: u32,
    pub datatype: u8,
    pub count: u32,
}

/// `sensor_msgs/msg/PointCloud2` (x, y, z as float32, unorganised).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2 {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
    pub is_dense: bool,
}

impl PointCloud2 {
    /// An xyz float32 cloud.
    pub fn xyz(header: Header, points: &[[f32; 3]]) -> Self {
        let mut data = Vec::with_capacity(points.len() * 12);
        for p in points {
            for v in p {
                data.extend_from_slice(&v.to_le_bytes());
            }
        }
        let field = |name: &str, offset| PointField {
            name: name.into(),
            offset,
            datatype: 7,
            count: 1,
        };
        PointCloud2 {
            header,
            height: 1,
            width: points.len() as u32,
            fields: vec![field("x", 0), field("y", 4), field("z", 8)],
            is_bigendian: false,
            point_step: 12,
            row_step: 12 * points.len() as u32,
            data,
            is_dense: true,
        }
    }

    /// The xyz points, if the cloud holds float32 x, y, z (any offsets, little endian).
    pub fn xyz_points(&self) -> Option<Vec<[f32; 3]>> {
        let off = |n: &str| {
            self.fields
                .iter()
                .find(|f| f.name == n && f.datatype == 7)
                .map(|f| f.offset as usize)
        };
        let (ox, oy, oz) = (off("x")?, off("y")?, off("z")?);
        let step = self.point_step as usize;
        if self.is_bigendian || step < 12 || [ox, oy, oz].iter().any(|o| o + 4 > step) {
            return None;
        }
        let n = (self.width as usize) * (self.height as usize);
        if self.data.len() < n * step {
            return None;
        }
        let f = |i: usize, o: usize| {
            f32::from_le_bytes(
                self.data[i * step + o..i * step + o + 4]
                    .try_into()
                    .expect("4 bytes"),
            )
        };
        Some((0..n).map(|i| [f(i, ox), f(i, oy), f(i, oz)]).collect())
    }
}

/// `sensor_msgs/msg/JointState`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

/// `geometry_msgs/Pose` (position, orientation x y z w).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position: [f64; 3],
    pub orientation: [f64; 4],
}

impl Pose {
    pub fn from_wire(p: [f64; 7]) -> Self {
        Pose {
            position: [p[0], p[1], p[2]],
            orientation: [p[3], p[4], p[5], p[6]],
        }
    }

    pub fn to_wire(self) -> [f64; 7] {
        let (p, q) = (self.position, self.orientation);
        [p[0], p[1], p[2], q[0], q[1], q[2], q[3]]
    }
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    pub header: Header,
    pub pose: Pose,
}

/// `ember_msgs/msg/ObjectUpdate`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ObjectUpdate {
    pub header: Header,
    pub id: String,
    pub shape: u32,
    pub dims: [f64; 3],
    pub pose: Pose,
    pub link: String,
}

/// `ember_msgs/msg/ObjectUpdate` as protocol versions 1 and 2 recorded it (no `link`).
#[derive(Deserialize)]
struct ObjectUpdateV2 {
    header: Header,
    id: String,
    shape: u32,
    dims: [f64; 3],
    pose: Pose,
}

impl ObjectUpdate {
    /// Decodes a recorded update whose channel carries `schema` (ros2msg text); files written
    /// before attachments (no `link`) hold world objects only.
    pub fn decode(data: &[u8], schema: &[u8]) -> Result<ObjectUpdate, String> {
        if String::from_utf8_lossy(schema).contains("string link") {
            return decode(data);
        }
        let o: ObjectUpdateV2 = decode(data)?;
        Ok(ObjectUpdate {
            header: o.header,
            id: o.id,
            shape: o.shape,
            dims: o.dims,
            pose: o.pose,
            link: String::new(),
        })
    }
}

/// `ember_msgs/msg/PlanRequest`: the wire header's fields after the message header (CDR lays a
/// nested struct out as its fields), then the payload.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PlanRequest {
    pub header: Header,
    pub request: crate::wire::PlanRequestHeader,
    pub values: Vec<f64>,
}

impl PlanRequest {
    /// Decodes a recorded request whose channel carries `schema` (ros2msg text): files of
    /// protocol version 1 (no `request_id`) are read too; requests of earlier versions (1, 2)
    /// are brought to the current version, so a replay is answered as it was then (version 3
    /// changed object updates only).
    pub fn decode(data: &[u8], schema: &[u8]) -> Result<PlanRequest, String> {
        let current = String::from_utf8_lossy(schema).contains("uint64 request_id");
        if current {
            let mut r: PlanRequest = decode(data)?;
            if r.request.version == 2 {
                r.request.version = crate::wire::PROTOCOL_VERSION;
            }
            return Ok(r);
        }
        let old: PlanRequestV1 = decode(data)?;
        let h = old.request;
        Ok(PlanRequest {
            header: old.header,
            request: crate::wire::PlanRequestHeader {
                version: match h.version {
                    1 => crate::wire::PROTOCOL_VERSION,
                    v => v,
                },
                dof: h.dof,
                goal_kind: h.goal_kind,
                goal_count: h.goal_count,
                method: h.method,
                flags: h.flags,
                time_limit_s: h.time_limit_s,
                seed: h.seed,
                pose: h.pose,
                position_tolerance: h.position_tolerance,
                orientation_tolerance: h.orientation_tolerance,
                request_id: 0,
            },
            values: old.values,
        })
    }
}

/// `ember_msgs/msg/PlanRequest` as protocol version 1 recorded it.
#[derive(Deserialize)]
struct PlanRequestV1 {
    header: Header,
    request: PlanRequestHeaderV1,
    values: Vec<f64>,
}

/// The version 1 request header (no `request_id`).
#[derive(Deserialize)]
struct PlanRequestHeaderV1 {
    version: u32,
    dof: u32,
    goal_kind: u32,
    goal_count: u32,
    method: u32,
    flags: u32,
    time_limit_s: f64,
    seed: u64,
    pose: [f64; 7],
    position_tolerance: f64,
    orientation_tolerance: f64,
}

/// `ember_msgs/msg/PlanResponse`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PlanResponse {
    pub header: Header,
    pub status: u32,
    pub dof: u32,
    pub waypoints: u32,
    pub iterations: u64,
    pub retrieval_us: f64,
    pub planning_us: f64,
    pub simplify_us: f64,
    pub total_us: f64,
    pub method: u32,
    pub message: String,
    pub path: Vec<f64>,
}

/// `trajectory_msgs/JointTrajectoryPoint` (`time_from_start` is a
/// `builtin_interfaces/Duration`, laid out as [`Time`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointTrajectoryPoint {
    pub positions: Vec<f64>,
    pub velocities: Vec<f64>,
    pub accelerations: Vec<f64>,
    pub effort: Vec<f64>,
    pub time_from_start: Time,
}

/// `trajectory_msgs/msg/JointTrajectory`: a plan's timed path, stamped with its request's
/// receive time.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointTrajectory {
    pub header: Header,
    pub joint_names: Vec<String>,
    pub points: Vec<JointTrajectoryPoint>,
}

impl JointTrajectory {
    /// The message of a trajectory block, for `joint_names`, stamped `stamp_ns`.
    pub fn from_block(
        stamp_ns: u64,
        joint_names: Vec<String>,
        b: &crate::wire::TrajectoryBlock,
    ) -> Self {
        JointTrajectory {
            header: Header {
                stamp: Time::from_ns(stamp_ns),
                frame_id: "base_link".into(),
            },
            joint_names,
            points: (0..b.times.len())
                .map(|k| JointTrajectoryPoint {
                    positions: b.positions[k].clone(),
                    velocities: b.velocities[k].clone(),
                    accelerations: b.accelerations[k].clone(),
                    effort: Vec::new(),
                    time_from_start: Time::from_secs(b.times[k]),
                })
                .collect(),
        }
    }

    /// True when `b` holds the same samples (times to the nanosecond the message keeps).
    pub fn matches(&self, b: &crate::wire::TrajectoryBlock) -> bool {
        self.points.len() == b.times.len()
            && self.points.iter().enumerate().all(|(k, p)| {
                p.time_from_start == Time::from_secs(b.times[k])
                    && p.positions == b.positions[k]
                    && p.velocities == b.velocities[k]
                    && p.accelerations == b.accelerations[k]
            })
    }
}

/// CDR (little endian) with the encapsulation header, as ROS 2 writes it.
pub fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    cdr::serialize::<_, _, cdr::CdrLe>(msg, cdr::Infinite).expect("plain data serialises")
}

/// Decodes CDR written by [`encode`] or by ROS 2.
pub fn decode<T: for<'de> Deserialize<'de>>(data: &[u8]) -> Result<T, String> {
    cdr::deserialize::<T>(data).map_err(|e| e.to_string())
}
