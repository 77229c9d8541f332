//! The ingest thread: clouds, objects and joint states in (each through its service's port and
//! decoder), world model updated incrementally, snapshots out. Never waits on planning; a
//! refused input is counted, logged and dropped.

use super::cloud::CloudPort;
use super::joints::JointsPort;
use super::objects::ObjectsPort;
use super::{Rejection, SnapshotCell, Stats, IDLE_WAIT};
use crate::config::Config;
use crate::recorder::Recorder;
use ember_engine::robot::Robot;
use ember_engine::world::model::{ObjectChange, World};
use ember_sdk::client::now_ns;
use ember_sdk::monitor::InputsDoc;
use ember_sdk::recording::Event;
use ember_sdk::services::{self, Open, Wake};
use ember_sdk::wire;
use iceoryx2::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use tracing::warn;

/// What the ingest thread works with.
pub struct Ingest {
    /// Daemon settings.
    pub config: Config,
    /// The robot (joint states are checked against it; the map filters it out).
    pub robot: Arc<Robot>,
    /// Where snapshots go.
    pub snapshot: SnapshotCell,
    /// Counters.
    pub stats: Arc<Stats>,
    /// Set to stop the thread.
    pub stop: Arc<AtomicBool>,
    /// The session recorder, when recording.
    pub recorder: Option<Recorder>,
}

impl Ingest {
    /// Runs until `stop` is set; `ready` is sent once the subscribers exist.
    pub fn run(self, ready: std::sync::mpsc::Sender<()>) -> anyhow::Result<()> {
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| anyhow::anyhow!("ingest node: {e:?}"))?;
        let instance = &self.config.instance;
        let limits = self.config.limits.get();
        let clouds = CloudPort::open(&node, instance, limits)?;
        let objects = ObjectsPort::open(&node, instance, limits)?;
        let joints = JointsPort::open(&node, instance, limits)?;
        let wake = services::wake(&node, instance, Wake::Inputs, Open::Serve(limits))
            .map_err(anyhow::Error::msg)?
            .listener_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("inputs wake-up listener: {e:?}"))?;
        let mut world = World::new(&self.config.world_params());
        let max_extent = self.config.map.max_object_extent();
        let max_objects = self.config.limits.objects;
        let (mut cloud_gaps, mut object_gaps, mut joint_gaps) = Default::default();
        let spin = std::time::Duration::from_micros(self.config.ingest.spin_us);
        let mut last_input = std::time::Instant::now() - spin;
        let _ = ready.send(());
        // This round's inputs, recorded together with the snapshot they make (see below).
        let mut batch: Vec<(u64, Event)> = Vec::new();
        while !self.stop.load(Ordering::Relaxed) {
            let mut changed = false;
            // Joint states taken this round: counted once the snapshot they make is out.
            let mut moved = 0u64;
            while let Some((dropped, input)) = joints.receive(&self.robot, &mut joint_gaps) {
                self.dropped(dropped, |i| &mut i.dropped_joints);
                match input {
                    Ok(js) => {
                        batch.push((
                            now_ns(),
                            Event::Joints {
                                stamp_ns: js.stamp_ns,
                                names: self
                                    .robot
                                    .variables()
                                    .iter()
                                    .map(|v| v.name.clone())
                                    .collect(),
                                positions: js.positions.clone(),
                            },
                        ));
                        // Where unknown space is an obstacle, the robot's volume there is
                        // observed free (a change the round's snapshot carries).
                        changed |= world.set_joints(&self.robot, js.positions);
                        moved += 1;
                    }
                    Err(why) => self.stats.rejected(&why),
                }
            }
            while let Some((dropped, update, input)) = objects.receive(max_extent, &mut object_gaps)
            {
                self.dropped(dropped, |i| &mut i.dropped_objects);
                // Recorded as received, whether or not it applies.
                if Rejection::check_version("object update", update.version).is_ok() {
                    batch.push((now_ns(), Event::Object(update)));
                }
                let applied = match input {
                    Ok(ObjectChange::Upsert(o)) if world.would_exceed(&o.name, max_objects) => {
                        Err(Rejection::TooManyObjects {
                            id: o.name,
                            limit: max_objects,
                        })
                    }
                    Ok(change) => world.apply(&self.robot, change).map_err(Rejection::from),
                    Err(why) => Err(why),
                };
                match applied {
                    Ok(()) => {
                        changed = true;
                        self.stats.inner.lock().expect("stats lock").inputs.objects += 1;
                    }
                    Err(why) => self.stats.rejected(&why),
                }
            }
            // One cloud per round: objects and joint states never wait behind a cloud stream
            // that arrives as fast as the map takes it.
            let cloud = clouds.receive(self.config.map.max_points, &mut cloud_gaps);
            // A cloud folded in this round: (invalid points, stamp, received), counted below.
            let mut folded = None;
            if let Some((dropped, _)) = &cloud {
                self.dropped(*dropped, |i| &mut i.dropped_clouds);
            }
            match cloud.map(|(_, c)| c) {
                Some(Ok(cloud)) => {
                    let h = *cloud.header();
                    let recv_ns = now_ns();
                    let report = world.insert_cloud(&self.robot, cloud.points(), &cloud.pose);
                    batch.push((
                        recv_ns,
                        Event::Cloud {
                            frame_id: wire::name_str(&h.frame_id),
                            stamp_ns: h.stamp_ns,
                            pose: h.sensor_pose,
                            points: cloud.points().to_vec(),
                        },
                    ));
                    folded = Some((report.invalid as u64, h.stamp_ns, recv_ns));
                    changed = true;
                }
                Some(Err(why)) => self.stats.rejected(&why),
                None => {}
            }
            if changed {
                last_input = std::time::Instant::now();
                let snap = world.snapshot();
                {
                    // The cloud is counted with the map it made: a status that counts it shows
                    // its voxels.
                    let mut st = self.stats.inner.lock().expect("stats lock");
                    if let Some((invalid, stamp_ns, recv_ns)) = folded.take() {
                        st.inputs.clouds += 1;
                        st.inputs.invalid_points += invalid;
                        st.inputs.last_cloud_stamp_ns = stamp_ns;
                        st.cloud_latency_us
                            .push(recv_ns.saturating_sub(stamp_ns) as f64 / 1e3);
                    }
                    st.map.blocks = snap.map.block_count() as u64;
                    st.map.occupied_blocks = snap.octoboxes.len() as u64;
                    st.map.memory_bytes = snap.map.memory_bytes() as u64;
                    st.world.objects = snap.scene.objects.len() as u64;
                    st.world.spark_pairs = snap.pairs.len() as u64;
                    st.world.attached = snap.scene.attached.len() as u64;
                }
                let snap = Arc::new(snap);
                // The inputs are recorded under the snapshot lock, as a plan request is when it
                // takes its snapshot: what precedes a request in the recording is exactly the
                // world it was planned in (a replay rebuilds that world from the file).
                let mut cell = self.snapshot.lock().expect("snapshot lock");
                self.record_all(&mut batch);
                *cell = snap;
            } else if !batch.is_empty() {
                // Inputs that changed nothing (refused ones, joint states that freed nothing):
                // recorded as received.
                let _cell = self.snapshot.lock().expect("snapshot lock");
                self.record_all(&mut batch);
            } else if last_input.elapsed() < spin {
                // A stream is flowing: look again at once (see `ingest.spin_us`).
                let _ = wake.try_wait(|_| {});
                std::thread::yield_now();
            } else if wake.timed_wait(|_| {}, IDLE_WAIT).is_err() {
                // Nothing was waiting: this slept until a client said it sent something (or
                // the idle wait ended); should the wake-up service fail, sleep anyway.
                std::thread::sleep(IDLE_WAIT);
            }
            if moved > 0 {
                // Counted after the snapshot: a status that counts a joint state shows the
                // robot's volume it freed.
                let mut st = self.stats.inner.lock().expect("stats lock");
                st.inputs.joint_states += moved;
            }
        }
        Ok(())
    }

    /// Counts `n` inputs of one kind (`counter`) dropped before they reached the daemon.
    fn dropped(&self, n: u64, counter: impl FnOnce(&mut InputsDoc) -> &mut u64) {
        if n > 0 {
            let mut st = self.stats.inner.lock().expect("stats lock");
            let total = counter(&mut st.inputs);
            let before = *total;
            *total += n;
            // One line each time the count passes a power of two: a flood does not flood the log.
            if before.checked_ilog2() != total.checked_ilog2() {
                warn!("inputs dropped before the daemon read them: {total} of this kind so far");
            }
        }
    }

    /// Records the events of `batch` (emptying it), when recording.
    fn record_all(&self, batch: &mut Vec<(u64, Event)>) {
        match &self.recorder {
            Some(r) => batch.drain(..).for_each(|(t, e)| r.record(t, e)),
            None => batch.clear(),
        }
    }
}
