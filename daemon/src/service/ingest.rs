//! The ingest thread: clouds, objects and joint states in, world model updated incrementally,
//! snapshots out. Never waits on planning; a bad input is counted, logged and dropped.

use super::Stats;
use crate::config::Config;
use crate::recorder::{Record, Recorder};
use crate::world::{Snapshot, World};
use ember_engine::collision::Shape;
use ember_engine::robot::Robot;
use ember_engine::scene::pose_from_xyz_xyzw;
use ember_engine::world::Object;
use ember_sdk::client::now_ns;
use ember_sdk::recording as messages;
use ember_sdk::services;
use ember_sdk::wire::{self, Point, ShapeKind, PROTOCOL_VERSION};
use iceoryx2::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tracing::warn;

/// Shared handle to the latest snapshot.
pub type SnapshotCell = Arc<Mutex<Arc<Snapshot>>>;

pub fn object_of(u: &wire::ObjectUpdate) -> Result<Option<Object>, String> {
    let id = wire::name_str(&u.id);
    if id.is_empty() {
        return Err("object update without an id".into());
    }
    if !u.dims.iter().chain(u.pose.iter()).all(|v| v.is_finite()) {
        return Err(format!("object '{id}': NaN or infinite dimension or pose"));
    }
    let d = u.dims;
    let shape = match u.shape {
        s if s == ShapeKind::Remove as u32 => return Ok(None),
        s if s == ShapeKind::Box as u32 => Shape::cuboid(d),
        s if s == ShapeKind::Cylinder as u32 => Shape::Cylinder {
            radius: d[0],
            half_length: d[1] / 2.0,
        },
        s if s == ShapeKind::Sphere as u32 => Shape::Sphere { radius: d[0] },
        s if s == ShapeKind::Capsule as u32 => Shape::Capsule {
            radius: d[0],
            half_length: d[1] / 2.0,
        },
        other => return Err(format!("object '{id}': unknown shape code {other}")),
    };
    if !shape.is_valid() {
        return Err(format!(
            "object '{id}': dimensions must be positive, got {d:?}"
        ));
    }
    let p = u.pose;
    let pose = pose_from_xyz_xyzw([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]])
        .ok_or_else(|| format!("object '{id}': zero quaternion"))?;
    Ok(Some(Object {
        name: id,
        shape,
        pose,
    }))
}

/// The wire update that adds or moves `object` (the inverse of [`object_of`]).
pub fn update_of(object: &Object) -> wire::ObjectUpdate {
    let (shape, dims) = match object.shape {
        Shape::Box { half_extents: h } => (ShapeKind::Box, [2.0 * h[0], 2.0 * h[1], 2.0 * h[2]]),
        Shape::Cylinder {
            radius,
            half_length,
        } => (ShapeKind::Cylinder, [radius, 2.0 * half_length, 0.0]),
        Shape::Sphere { radius } => (ShapeKind::Sphere, [radius, 0.0, 0.0]),
        Shape::Capsule {
            radius,
            half_length,
        } => (ShapeKind::Capsule, [radius, 2.0 * half_length, 0.0]),
    };
    let (t, q) = ember_engine::scene::pose_to_xyz_xyzw(&object.pose);
    wire::ObjectUpdate {
        version: PROTOCOL_VERSION,
        shape: shape as u32,
        stamp_ns: now_ns(),
        id: wire::name(&object.name),
        dims,
        pose: [t[0], t[1], t[2], q[0], q[1], q[2], q[3]],
    }
}

/// Runs until `stop` is set; `ready` is sent once the subscribers exist.
pub fn run(
    config: Config,
    robot: Arc<Robot>,
    snapshot: SnapshotCell,
    stats: Arc<Stats>,
    stop: Arc<AtomicBool>,
    ready: std::sync::mpsc::Sender<()>,
    recorder: Option<Recorder>,
) -> anyhow::Result<()> {
    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| anyhow::anyhow!("ingest node: {e:?}"))?;
    let instance = &config.instance;
    let clouds = services::cloud(&node, instance)
        .map_err(anyhow::Error::msg)?
        .subscriber_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let objects = services::objects(&node, instance)
        .map_err(anyhow::Error::msg)?
        .subscriber_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let joints = services::joints(&node, instance)
        .map_err(anyhow::Error::msg)?
        .subscriber_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut world = World::new(&config);
    let dof = robot.dof();
    let _ = ready.send(());
    let reject = |why: String| {
        warn!("rejected input: {why}");
        stats.inner.lock().expect("stats lock").rejected += 1;
    };
    while !stop.load(Ordering::Relaxed) {
        let mut changed = false;
        while let Ok(Some(s)) = joints.receive() {
            let js = *s.payload();
            if js.version != PROTOCOL_VERSION {
                reject(format!(
                    "joint state of protocol version {}, expected {PROTOCOL_VERSION}",
                    js.version
                ));
                continue;
            }
            if js.count as usize != dof {
                reject(format!(
                    "joint state with {} joints, the robot has {dof}",
                    js.count
                ));
                continue;
            }
            let q = js.positions[..dof].to_vec();
            if let Err(e) = robot.validate(&q) {
                reject(format!("joint state: {e}"));
                continue;
            }
            if let Some(r) = &recorder {
                let names = robot.variables().iter().map(|v| v.name.clone()).collect();
                r.record(Record::Joints {
                    recv_ns: now_ns(),
                    stamp_ns: js.stamp_ns,
                    names,
                    positions: q.clone(),
                });
            }
            world.set_joints(q);
            stats.inner.lock().expect("stats lock").joint_states += 1;
        }
        while let Ok(Some(s)) = objects.receive() {
            let u = *s.payload();
            if u.version != PROTOCOL_VERSION {
                reject(format!(
                    "object update of protocol version {}, expected {PROTOCOL_VERSION}",
                    u.version
                ));
                continue;
            }
            if let Some(r) = &recorder {
                let update = messages::ObjectUpdate {
                    header: messages::Header {
                        stamp: messages::Time::from_ns(u.stamp_ns),
                        frame_id: "base_link".into(),
                    },
                    id: wire::name_str(&u.id),
                    shape: u.shape,
                    dims: u.dims,
                    pose: messages::Pose::from_wire(u.pose),
                };
                r.record(Record::Object {
                    recv_ns: now_ns(),
                    update,
                });
            }
            match object_of(&u) {
                Ok(Some(o)) => world.upsert_object(o),
                Ok(None) => {
                    if !world.remove_object(&wire::name_str(&u.id)) {
                        reject(format!(
                            "removal of unknown object '{}'",
                            wire::name_str(&u.id)
                        ));
                        continue;
                    }
                }
                Err(why) => {
                    reject(why);
                    continue;
                }
            }
            changed = true;
            stats.inner.lock().expect("stats lock").objects += 1;
        }
        #[allow(clippy::never_loop)]
        while let Ok(Some(s)) = clouds.receive() {
            let h = *s.user_header();
            let points: &[Point] = s.payload();
            if h.version != PROTOCOL_VERSION {
                reject(format!(
                    "cloud of protocol version {}, expected {PROTOCOL_VERSION}",
                    h.version
                ));
                continue;
            }
            if points.is_empty() || h.point_count as usize != points.len() {
                reject(format!(
                    "cloud header says {} points, payload holds {}",
                    h.point_count,
                    points.len()
                ));
                continue;
            }
            if points.len() > config.map.max_points {
                reject(format!(
                    "cloud of {} points, the limit is {}",
                    points.len(),
                    config.map.max_points
                ));
                continue;
            }
            let p = h.sensor_pose;
            let Some(pose) = p
                .iter()
                .all(|v| v.is_finite())
                .then(|| pose_from_xyz_xyzw([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]]))
                .flatten()
            else {
                reject(format!(
                    "cloud from frame '{}': invalid sensor pose",
                    wire::name_str(&h.frame_id)
                ));
                continue;
            };
            let recv_ns = now_ns();
            let latency_us = recv_ns.saturating_sub(h.stamp_ns) as f64 / 1e3;
            world.insert_cloud(&robot, Point::as_arrays(points), &pose);
            if let Some(r) = &recorder {
                r.record(Record::Cloud {
                    recv_ns,
                    stamp_ns: h.stamp_ns,
                    frame_id: wire::name_str(&h.frame_id),
                    pose: h.sensor_pose,
                    points: Point::as_arrays(points).to_vec(),
                });
            }
            let mut st = stats.inner.lock().expect("stats lock");
            st.clouds += 1;
            st.last_cloud_stamp_ns = h.stamp_ns;
            st.cloud_latency_us.push(latency_us);
            changed = true;
            // One cloud per round: objects and joint states never wait behind a cloud stream
            // that arrives as fast as the map takes it.
            break;
        }
        if changed {
            let snap = world.snapshot();
            {
                let mut st = stats.inner.lock().expect("stats lock");
                st.map_blocks = snap.map.block_count() as u64;
                st.map_occupied_blocks = snap.octoboxes.len() as u64;
                st.map_memory_bytes = snap.map.memory_bytes() as u64;
                st.world_objects = snap.scene.objects.len() as u64;
                st.spark_pairs = snap.pairs.len() as u64;
            }
            *snapshot.lock().expect("snapshot lock") = Arc::new(snap);
        } else if node.wait(Duration::from_micros(50)).is_err() {
            break;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_updates_round_trip_every_shape() {
        let pose =
            pose_from_xyz_xyzw([0.5, -0.2, 0.8], [0.0, 0.0, 0.38268343, 0.92387953]).unwrap();
        for shape in [
            Shape::cuboid([0.4, 1.0, 0.04]),
            Shape::Cylinder {
                radius: 0.035,
                half_length: 0.06,
            },
            Shape::Sphere { radius: 0.1 },
            Shape::Capsule {
                radius: 0.05,
                half_length: 0.2,
            },
        ] {
            let o = Object {
                name: "thing".into(),
                shape,
                pose,
            };
            let back = object_of(&update_of(&o)).unwrap().unwrap();
            assert_eq!((back.name.as_str(), back.shape), ("thing", shape));
            assert!((back.pose.translation.vector - pose.translation.vector).norm() < 1e-12);
            assert!(back.pose.rotation.angle_to(&pose.rotation) < 1e-9);
        }
    }
}
