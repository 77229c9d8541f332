//! Reading recorded sessions: the MCAP messages of a recording as typed events, in recorded
//! order, with each cloud joined to its sensor pose. `ember replay` sends them to a daemon;
//! `ember train` (and tests) rebuild the world from them in process.

use ember_sdk::recording::{self, PlanRequest, PlanResponse, PointCloud2, PoseStamped};
use ember_sdk::wire::{self, ObjectUpdate, PROTOCOL_VERSION};
use std::path::Path;

/// One recorded event.
pub enum Event {
    /// An object update, in wire form.
    Object(ObjectUpdate),
    /// Joint positions (planning group).
    Joints(Vec<f64>),
    /// A cloud with its sensor pose (wire form `[x, y, z, qx, qy, qz, qw]`).
    Cloud {
        frame_id: String,
        stamp_ns: u64,
        pose: [f64; 7],
        points: Vec<[f32; 3]>,
    },
    /// A plan request as received.
    PlanRequest(PlanRequest),
    /// A plan reply as sent.
    PlanResponse(PlanResponse),
}

/// A recording loaded in memory.
pub struct Session {
    path: String,
    bytes: Vec<u8>,
}

impl Session {
    /// Reads a recording; refuses files that are not MCAP.
    pub fn open(path: &Path) -> anyhow::Result<Session> {
        let bytes = std::fs::read(path)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
        if !bytes.starts_with(mcap::MAGIC) {
            anyhow::bail!(
                "{}: not a readable MCAP file (no MCAP magic at the start)",
                path.display()
            );
        }
        Ok(Session {
            path: path.display().to_string(),
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

    /// Calls `f` with every event (and its log time, ns) in order. Damaged data ends the walk:
    /// with `lenient` quietly (the count of intact messages is returned), otherwise as an error
    /// naming the file.
    pub fn for_each(
        &self,
        lenient: bool,
        mut f: impl FnMut(u64, Event) -> anyhow::Result<()>,
    ) -> anyhow::Result<usize> {
        let mut read = 0usize;
        let mut pending_cloud: Option<PointCloud2> = None;
        for message in mcap::MessageStream::new(&self.bytes)? {
            let m = match message {
                Ok(m) => m,
                Err(_) if lenient => break,
                Err(e) => anyhow::bail!("{}: damaged after {read} messages: {e} (use --allow-truncated to use what is intact)", self.path),
            };
            read += 1;
            let topic = m.channel.topic.as_str();
            let bad =
                |e: String| anyhow::anyhow!("{}: {topic} message {}: {e}", self.path, m.sequence);
            let event = match topic {
                "/ember/objects" => {
                    let o: recording::ObjectUpdate = recording::decode(&m.data).map_err(bad)?;
                    Event::Object(ObjectUpdate {
                        version: PROTOCOL_VERSION,
                        shape: o.shape,
                        stamp_ns: o.header.stamp.ns(),
                        id: wire::name(&o.id),
                        dims: o.dims,
                        pose: o.pose.to_wire(),
                    })
                }
                "/ember/joints" => {
                    let js: recording::JointState = recording::decode(&m.data).map_err(bad)?;
                    Event::Joints(js.position)
                }
                "/ember/cloud" => {
                    pending_cloud = Some(recording::decode(&m.data).map_err(bad)?);
                    continue;
                }
                "/ember/cloud_pose" => {
                    let pose: PoseStamped = recording::decode(&m.data).map_err(bad)?;
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
                "/ember/plan_request" => {
                    Event::PlanRequest(recording::decode(&m.data).map_err(bad)?)
                }
                "/ember/plan_response" => {
                    Event::PlanResponse(recording::decode(&m.data).map_err(bad)?)
                }
                _ => continue,
            };
            f(m.log_time, event)?;
        }
        Ok(read)
    }
}
