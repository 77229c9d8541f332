//! [`Event`]: one recorded input or answer, and its conversions to and from the wire payloads
//! and the recorded messages.

use super::{
    encode, topic, Header, JointState, JointTrajectory, ObjectUpdate, PlanRequest, PlanResponse,
    PointCloud2, Pose, PoseStamped, Time,
};
use crate::wire::{self, PlanRequestHeader, PlanResponseHeader, PROTOCOL_VERSION};

/// One recorded event: what the recorder writes and a session reader gives back.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// An object update, in wire form.
    Object(wire::ObjectUpdate),
    /// Joint positions with their names (empty names: already in planning-group order).
    Joints {
        /// Measurement time, ns since the Unix epoch.
        stamp_ns: u64,
        /// Joint names.
        names: Vec<String>,
        /// Positions, radians or metres.
        positions: Vec<f64>,
    },
    /// A cloud with its sensor pose (wire form `[x, y, z, qx, qy, qz, qw]`).
    Cloud {
        /// Sensor frame name.
        frame_id: String,
        /// Capture time, ns since the Unix epoch.
        stamp_ns: u64,
        /// Sensor pose in the robot base frame.
        pose: [f64; 7],
        /// Points in the sensor frame, metres.
        points: Vec<[f32; 3]>,
    },
    /// A plan request as received.
    PlanRequest(PlanRequest),
    /// A plan reply as sent.
    PlanResponse(PlanResponse),
    /// A plan's timed trajectory as sent (after its reply, same stamp).
    PlanTrajectory(JointTrajectory),
}

fn header(stamp_ns: u64, frame: &str) -> Header {
    Header {
        stamp: Time::from_ns(stamp_ns),
        frame_id: frame.into(),
    }
}

impl Event {
    /// The recorded messages of the event as (topic, publish time in ns, CDR bytes); a cloud
    /// is two (the points, then the sensor pose with the same stamp). `recv_ns` stamps plan
    /// messages, whose senders' clocks are not recorded.
    pub fn messages(&self, recv_ns: u64) -> Vec<(&'static str, u64, Vec<u8>)> {
        match self {
            Event::Cloud {
                frame_id,
                stamp_ns,
                pose,
                points,
            } => {
                let cloud = PointCloud2::xyz(header(*stamp_ns, frame_id), points);
                let ps = PoseStamped {
                    header: header(*stamp_ns, "base_link"),
                    pose: Pose::from_wire(*pose),
                };
                vec![
                    (topic::CLOUD, *stamp_ns, encode(&cloud)),
                    (topic::CLOUD_POSE, *stamp_ns, encode(&ps)),
                ]
            }
            Event::Joints {
                stamp_ns,
                names,
                positions,
            } => {
                let js = JointState {
                    header: header(*stamp_ns, "base_link"),
                    name: names.clone(),
                    position: positions.clone(),
                    velocity: vec![],
                    effort: vec![],
                };
                vec![(topic::JOINTS, *stamp_ns, encode(&js))]
            }
            Event::Object(u) => {
                vec![(topic::OBJECTS, u.stamp_ns, encode(&ObjectUpdate::from(u)))]
            }
            Event::PlanRequest(r) => vec![(topic::PLAN_REQUEST, recv_ns, encode(r))],
            Event::PlanResponse(r) => vec![(topic::PLAN_RESPONSE, recv_ns, encode(r))],
            Event::PlanTrajectory(t) => {
                vec![(topic::PLAN_TRAJECTORY, t.header.stamp.ns(), encode(t))]
            }
        }
    }
}

impl From<&wire::ObjectUpdate> for ObjectUpdate {
    fn from(u: &wire::ObjectUpdate) -> Self {
        ObjectUpdate {
            header: header(u.stamp_ns, "base_link"),
            id: wire::name_str(&u.id),
            shape: u.shape,
            dims: u.dims,
            pose: Pose::from_wire(u.pose),
            link: wire::name_str(&u.link),
        }
    }
}

impl From<&ObjectUpdate> for wire::ObjectUpdate {
    fn from(o: &ObjectUpdate) -> Self {
        wire::ObjectUpdate {
            version: PROTOCOL_VERSION,
            shape: o.shape,
            stamp_ns: o.header.stamp.ns(),
            id: wire::name(&o.id),
            dims: o.dims,
            pose: o.pose.to_wire(),
            seq: 0,
            link: wire::name(&o.link),
        }
    }
}

impl PlanRequest {
    /// The recorded form of a request received at `recv_ns` with payload `values`.
    pub fn new(recv_ns: u64, h: &PlanRequestHeader, values: &[f64]) -> Self {
        PlanRequest {
            header: header(recv_ns, "base_link"),
            request: *h,
            values: values.to_vec(),
        }
    }
}

impl PlanResponse {
    /// The recorded form of a reply (header `h`, path flattened) to the request received at
    /// `recv_ns`.
    pub fn new(recv_ns: u64, h: &PlanResponseHeader, path: Vec<f64>) -> Self {
        PlanResponse {
            header: header(recv_ns, "base_link"),
            status: h.status,
            dof: h.dof,
            waypoints: h.waypoints,
            iterations: h.iterations,
            retrieval_us: h.retrieval_us,
            planning_us: h.planning_us,
            simplify_us: h.simplify_us,
            total_us: h.total_us,
            method: h.method,
            message: wire::name_str(&h.message),
            path,
        }
    }
}
