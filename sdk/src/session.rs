//! Reading recorded sessions: the MCAP messages of a recording as typed events, in recorded
//! order, with each cloud joined to its sensor pose. `ember replay` sends them to a daemon;
//! `ember train` (and tests) rebuild the world from them in process.
//!
//! Ember's own recordings need no configuration. A ROS 2 bag is read through a [`TopicMap`]:
//! `TOPIC=cloud` (`sensor_msgs/msg/PointCloud2`, x/y/z float32 fields at any offsets),
//! `TOPIC=cloud_pose` (`geometry_msgs/msg/PoseStamped`: the sensor pose used for the clouds that
//! follow), `TOPIC=joints` (`sensor_msgs/msg/JointState`, joints matched by name), and
//! `TOPIC=object:ID:SHAPE:D1,D2,D3` (`geometry_msgs/msg/PoseStamped` of a tracked object with
//! shape `box`, `cylinder`, `sphere` or `capsule` and its dimensions).

pub use crate::recording::Event;
use crate::recording::{self, PointCloud2, PoseStamped};
use crate::wire::{self, ObjectUpdate, PROTOCOL_VERSION};
use std::collections::HashMap;
use std::path::Path;
use thiserror::Error;

/// A recording or topic mapping that cannot be used. Each names the file or the entry.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SessionError {
    /// The file could not be read.
    #[error("cannot read {path}: {message}")]
    Io {
        /// File path.
        path: String,
        /// The operating system's reason.
        message: String,
    },
    /// The file is not MCAP.
    #[error("{0}: not a readable MCAP file (no MCAP magic at the start)")]
    NotMcap(String),
    /// The file is damaged after some intact messages.
    #[error("{path}: damaged after {after} messages: {message} (use --allow-truncated to use what is intact)")]
    Damaged {
        /// File path.
        path: String,
        /// Intact messages before the damage.
        after: usize,
        /// What the reader found.
        message: String,
    },
    /// A message does not decode as its topic's type.
    #[error("{path}: {topic} message {sequence}: {message}")]
    BadMessage {
        /// File path.
        path: String,
        /// Topic.
        topic: String,
        /// The message's sequence number.
        sequence: u32,
        /// What is wrong.
        message: String,
    },
    /// A `TOPIC=ROLE` entry is malformed.
    #[error("topic mapping '{entry}': {message}")]
    BadMapping {
        /// The entry as given.
        entry: String,
        /// What is wrong.
        message: String,
    },
}

/// What a topic of a foreign bag stands for.
#[derive(Debug, Clone, PartialEq)]
pub enum Role {
    /// Point clouds.
    Cloud,
    /// The sensor pose of the clouds.
    CloudPose,
    /// Joint states.
    Joints,
    /// A tracked object: id, shape code, dimensions.
    Object(String, u32, [f64; 3]),
}

/// Topic → role, for bags not written by Ember.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TopicMap(pub HashMap<String, Role>);

impl TopicMap {
    /// Parses `TOPIC=ROLE` entries (see the module docs); errors name the entry.
    pub fn parse(entries: &[String]) -> Result<TopicMap, SessionError> {
        let mut map = HashMap::new();
        for e in entries {
            let bad = |message: String| SessionError::BadMapping {
                entry: e.clone(),
                message,
            };
            let (topic, role) = e
                .split_once('=')
                .ok_or_else(|| bad("expected TOPIC=ROLE".into()))?;
            let role = match role {
                "cloud" => Role::Cloud,
                "cloud_pose" => Role::CloudPose,
                "joints" => Role::Joints,
                r if r.starts_with("object:") => {
                    let parts: Vec<&str> = r.splitn(4, ':').collect();
                    let [_, id, shape, dims] = parts[..] else {
                        return Err(bad("expected object:ID:SHAPE:D1,D2,D3".into()));
                    };
                    let code = match shape {
                        "box" => 1,
                        "cylinder" => 2,
                        "sphere" => 3,
                        "capsule" => 4,
                        other => {
                            return Err(bad(format!(
                                "unknown shape '{other}' (box, cylinder, sphere, capsule)"
                            )))
                        }
                    };
                    let d: Vec<f64> = dims
                        .split(',')
                        .map(str::parse)
                        .collect::<Result<_, _>>()
                        .map_err(|_| bad("dimensions must be numbers".into()))?;
                    let mut dims3 = [0.0; 3];
                    for (o, v) in dims3.iter_mut().zip(&d) {
                        *o = *v;
                    }
                    Role::Object(id.to_string(), code, dims3)
                }
                other => {
                    return Err(bad(format!(
                    "unknown role '{other}' (cloud, cloud_pose, joints, object:ID:SHAPE:D1,D2,D3)"
                )))
                }
            };
            map.insert(topic.to_string(), role);
        }
        Ok(TopicMap(map))
    }

    /// The role of `topic`: Ember's own topics first, then the mapping.
    fn role(&self, topic: &str) -> Option<Role> {
        match topic {
            recording::topic::CLOUD => Some(Role::Cloud),
            recording::topic::CLOUD_POSE => Some(Role::CloudPose),
            recording::topic::JOINTS => Some(Role::Joints),
            _ => self.0.get(topic).cloned(),
        }
    }
}

/// A recording loaded in memory.
pub struct Session {
    path: String,
    bytes: Vec<u8>,
}

/// The longest record or uncompressed chunk a file of `len` bytes is read with: 16 times the
/// file, at least 256 MiB (a small file may hold a well-compressed chunk), at most 1 GiB
/// (recorders write chunks of a few MB).
fn record_length_limit(len: usize) -> usize {
    len.saturating_mul(16).clamp(256 << 20, 1 << 30)
}

impl Session {
    /// Reads a recording; refuses files that are not MCAP.
    pub fn open(path: &Path) -> Result<Session, SessionError> {
        let bytes = std::fs::read(path).map_err(|e| SessionError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        Self::from_bytes(&path.display().to_string(), bytes)
    }

    /// A recording held in memory; `name` names it in errors. Refuses bytes that are not MCAP.
    pub fn from_bytes(name: &str, bytes: Vec<u8>) -> Result<Session, SessionError> {
        if !bytes.starts_with(mcap::MAGIC) {
            return Err(SessionError::NotMcap(name.to_string()));
        }
        Ok(Session {
            path: name.to_string(),
            bytes,
        })
    }

    /// Messages recorded, when the file has its summary.
    pub fn message_count(&self) -> Option<u64> {
        mcap::Summary::read(&self.bytes)
            .ok()
            .flatten()
            .and_then(|s| s.stats)
            .map(|s| s.message_count)
    }

    /// Calls `f` with every event (and its log time, ns) in order. Damaged data (including a chunk
    /// whose CRC does not match) ends the walk:
    /// with `lenient` quietly (the count of intact messages is returned), otherwise as an error
    /// naming the file.
    pub fn for_each<E>(
        &self,
        lenient: bool,
        topics: &TopicMap,
        mut f: impl FnMut(u64, Event) -> Result<(), E>,
    ) -> Result<usize, E>
    where
        E: From<SessionError>,
    {
        let mut read = 0usize;
        let mut pending_cloud: Option<PointCloud2> = None;
        // In foreign bags a cloud uses the latest sensor pose; Ember's pair up by stamp.
        let mut sensor_pose: Option<[f64; 7]> = None;
        let damaged = |after: usize, message: String| SessionError::Damaged {
            path: self.path.clone(),
            after,
            message,
        };
        // Chunk CRCs checked: a flipped byte is damage, not data. Record and chunk lengths are
        // bounded (mcap's MessageStream sets no bound: a damaged length asked for exabytes and
        // aborted the process; found by fuzzing).
        let options = mcap::sans_io::LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_record_length_limit(record_length_limit(self.bytes.len()));
        let stream = mcap::io::MessageReader::new_with_options(&self.bytes[..], options);
        for message in stream {
            let m = match message {
                Ok(m) => m,
                Err(_) if lenient => break,
                Err(e) => return Err(damaged(read, e.to_string()).into()),
            };
            read += 1;
            let topic = m.channel.topic.as_str();
            let bad = |message: String| SessionError::BadMessage {
                path: self.path.clone(),
                topic: topic.to_string(),
                sequence: m.sequence,
                message,
            };
            let ember = topic.starts_with("/ember/");
            let event = match (topic, topics.role(topic)) {
                (recording::topic::OBJECTS, _) => {
                    let schema = m.channel.schema.as_ref().map_or(&[][..], |s| &s.data[..]);
                    let o = recording::ObjectUpdate::decode(&m.data, schema).map_err(bad)?;
                    Event::Object(ObjectUpdate::from(&o))
                }
                (recording::topic::PLAN_REQUEST, _) => {
                    let schema = m.channel.schema.as_ref().map_or(&[][..], |s| &s.data[..]);
                    Event::PlanRequest(
                        recording::PlanRequest::decode(&m.data, schema).map_err(bad)?,
                    )
                }
                (recording::topic::PLAN_RESPONSE, _) => {
                    Event::PlanResponse(recording::decode(&m.data).map_err(bad)?)
                }
                (recording::topic::PLAN_TRAJECTORY, _) => {
                    Event::PlanTrajectory(recording::decode(&m.data).map_err(bad)?)
                }
                (_, Some(Role::Joints)) => {
                    let js: recording::JointState = recording::decode(&m.data).map_err(bad)?;
                    Event::Joints {
                        stamp_ns: js.header.stamp.ns(),
                        names: js.name,
                        positions: js.position,
                    }
                }
                (_, Some(Role::Cloud)) => {
                    let cloud: PointCloud2 = recording::decode(&m.data).map_err(bad)?;
                    if ember {
                        pending_cloud = Some(cloud);
                        continue;
                    }
                    let Some(pose) = sensor_pose else {
                        continue; // No sensor pose seen yet: the cloud cannot be placed.
                    };
                    let points = cloud
                        .xyz_points()
                        .ok_or_else(|| bad("cloud without float32 x, y, z".into()))?;
                    Event::Cloud {
                        frame_id: cloud.header.frame_id,
                        stamp_ns: cloud.header.stamp.ns(),
                        pose,
                        points,
                    }
                }
                (_, Some(Role::CloudPose)) => {
                    let pose: PoseStamped = recording::decode(&m.data).map_err(bad)?;
                    sensor_pose = Some(pose.pose.to_wire());
                    let Some(cloud) = pending_cloud
                        .take()
                        .filter(|c| c.header.stamp == pose.header.stamp)
                    else {
                        continue;
                    };
                    let points = cloud
                        .xyz_points()
                        .ok_or_else(|| bad("cloud without float32 x, y, z".into()))?;
                    Event::Cloud {
                        frame_id: cloud.header.frame_id,
                        stamp_ns: cloud.header.stamp.ns(),
                        pose: pose.pose.to_wire(),
                        points,
                    }
                }
                (_, Some(Role::Object(id, shape, dims))) => {
                    let pose: PoseStamped = recording::decode(&m.data).map_err(bad)?;
                    Event::Object(ObjectUpdate {
                        version: PROTOCOL_VERSION,
                        shape,
                        stamp_ns: pose.header.stamp.ns(),
                        id: wire::name(&id),
                        dims,
                        pose: pose.pose.to_wire(),
                        seq: 0,
                        link: [0; 32],
                    })
                }
                _ => continue,
            };
            f(m.log_time, event)?;
        }
        Ok(read)
    }
}
