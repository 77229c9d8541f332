//! The documents the monitor publishes, made from the daemon's shared state.

use crate::config::Config;
use crate::recorder::RecorderStats;
use crate::service::plan::decode::method_of;
use crate::service::plan::Answer;
use crate::service::SnapshotCell;
use crate::service::Stats;
use ember_engine::experience;
use ember_engine::robot::Robot;
use ember_sdk::monitor::{
    DatabaseDoc, InputsDoc, MapDoc, MapSnapshot, PlanSummary, PlansDoc, RecordingDoc, StatusDoc,
};
use ember_sdk::wire::{GoalKind, PlanRequestHeader, PROTOCOL_VERSION};
use ember_sdk::Status;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Everything the documents are made from; shared with the query callbacks.
pub struct Sources {
    pub instance: String,
    pub robot: String,
    pub dof: u32,
    pub started: Instant,
    pub stats: Arc<Stats>,
    pub snapshot: SnapshotCell,
    pub recorder: Option<Arc<RecorderStats>>,
    pub database: DatabaseDoc,
    pub resolution: f64,
    /// Summaries dropped because the publisher fell behind.
    pub dropped: AtomicU64,
    /// How the monitor's Zenoh session admits peers (`usrpwd` or `none`).
    pub monitor_auth: &'static str,
    rates: Mutex<Rates>,
}

/// Input and plan rates over the last status period.
#[derive(Default, Clone, Copy)]
struct Rates {
    at: Option<Instant>,
    counts: [u64; 4],
    hz: [f64; 4],
}

impl Sources {
    /// Sources with no rates measured yet.
    pub fn new(
        config: &Config,
        robot: &Robot,
        stats: Arc<Stats>,
        snapshot: SnapshotCell,
        recorder: Option<Arc<RecorderStats>>,
    ) -> Sources {
        Sources {
            instance: config.instance.clone(),
            robot: robot.name().to_string(),
            dof: robot.dof() as u32,
            started: Instant::now(),
            stats,
            snapshot,
            recorder,
            database: DatabaseDoc {
                online_learning: config.experience.online_learning,
                dir: config.experience.db_dir.display().to_string(),
                ..Default::default()
            },
            resolution: config.map.resolution,
            dropped: AtomicU64::new(0),
            monitor_auth: match config.monitor.enabled {
                true => super::session::Authentication::of(
                    (!config.monitor.zenoh_config.as_os_str().is_empty())
                        .then_some(config.monitor.zenoh_config.as_path()),
                )
                .map(|a| a.required())
                .unwrap_or("none"),
                false => "none",
            },
            rates: Mutex::new(Rates::default()),
        }
    }

    /// The status; `tick` also restarts the rate window (the periodic publication does).
    pub fn status(&self, tick: bool) -> StatusDoc {
        let st = self.stats.inner.lock().expect("stats lock");
        let counts = [
            st.inputs.clouds,
            st.inputs.objects,
            st.inputs.joint_states,
            st.plans.total,
        ];
        let hz = {
            let mut r = self.rates.lock().expect("rates lock");
            if tick {
                let now = Instant::now();
                let old = r.counts;
                if let Some(at) = r.at {
                    let dt = now.duration_since(at).as_secs_f64().max(1e-9);
                    for ((hz, now), before) in r.hz.iter_mut().zip(counts).zip(old) {
                        *hz = now.saturating_sub(before) as f64 / dt;
                    }
                }
                r.at = Some(now);
                r.counts = counts;
            }
            r.hz
        };
        let (cloud_p50, cloud_p99) = st.cloud_latency_us.p50_p99();
        let (plan_p50, plan_p99) = st.plan_latency_us.p50_p99();
        let in_flight = self.stats.in_flight.summary();
        StatusDoc {
            instance: self.instance.clone(),
            robot: self.robot.clone(),
            dof: self.dof,
            pid: std::process::id(),
            version: env!("CARGO_PKG_VERSION").into(),
            protocol: PROTOCOL_VERSION,
            uptime_s: self.started.elapsed().as_secs_f64(),
            stamp_ns: ember_sdk::client::now_ns(),
            inputs: InputsDoc {
                cloud_hz: hz[0],
                object_hz: hz[1],
                joint_hz: hz[2],
                cloud_latency_p50_us: cloud_p50,
                cloud_latency_p99_us: cloud_p99,
                ..st.inputs.clone()
            },
            map: MapDoc {
                resolution: self.resolution,
                ..st.map.clone()
            },
            world: st.world.clone(),
            experience: DatabaseDoc {
                spark_entries: st.experience.spark_entries,
                flame_entries: st.experience.flame_entries,
                ..self.database.clone()
            },
            plans: PlansDoc {
                failed: st.plans.total - st.plans.solved,
                rate_hz: hz[3],
                latency_p50_ms: plan_p50 / 1e3,
                latency_p99_ms: plan_p99 / 1e3,
                in_flight: in_flight.count,
                oldest_in_flight_ms: in_flight.oldest.as_secs_f64() * 1e3,
                ..st.plans.clone()
            },
            recording: match &self.recorder {
                Some(r) => RecordingDoc {
                    enabled: true,
                    path: r
                        .current
                        .lock()
                        .expect("recorder path lock")
                        .display()
                        .to_string(),
                    written: r.written.load(Ordering::Relaxed),
                    dropped: r.dropped.load(Ordering::Relaxed),
                    failures: r.failures.load(Ordering::Relaxed),
                    failing: r.failing.load(Ordering::Relaxed),
                },
                None => RecordingDoc::default(),
            },
            monitor_dropped: self.dropped.load(Ordering::Relaxed),
            monitor_auth: self.monitor_auth.to_string(),
        }
    }

    /// Database statistics.
    pub fn database(&self) -> DatabaseDoc {
        let st = self.stats.inner.lock().expect("stats lock");
        DatabaseDoc {
            spark_entries: st.experience.spark_entries,
            flame_entries: st.experience.flame_entries,
            ..self.database.clone()
        }
    }

    /// The version of the world's objects (changes with every object update).
    pub fn objects_version(&self) -> u64 {
        self.snapshot.lock().expect("snapshot lock").objects_version
    }

    /// The world's objects as the scene file's JSON document, and their version.
    pub fn objects(&self) -> (u64, String) {
        let snap = self.snapshot.lock().expect("snapshot lock").clone();
        (snap.objects_version, snap.scene.to_json())
    }

    /// The occupied map, decimated to octoboxes (binary), and the clouds folded in so far (the
    /// map changes only with them).
    pub fn map(&self) -> (u64, Vec<u8>) {
        let clouds = self.stats.inner.lock().expect("stats lock").inputs.clouds;
        let snap = self.snapshot.lock().expect("snapshot lock").clone();
        let snapshot = MapSnapshot {
            resolution: self.resolution as f32,
            stamp_ns: ember_sdk::client::now_ns(),
            blocks: snap.map.octoboxes().map(|o| (o.key, o.mask)).collect(),
        };
        (clouds, snapshot.encode())
    }
}

/// The summary of one answered request.
pub fn plan_summary(
    instance: &str,
    seq: u64,
    stamp_ns: u64,
    request: &PlanRequestHeader,
    answer: &Answer,
) -> PlanSummary {
    let h = &answer.header;
    // Replies carry the method used (`auto` resolved); a code no version knows shows as uniform.
    let method = method_of(h.method, experience::Method::Uniform)
        .unwrap_or(experience::Method::Uniform)
        .name();
    PlanSummary {
        instance: instance.to_string(),
        seq,
        stamp_ns,
        status: h.status,
        status_name: Status::from_code(h.status)
            .map_or("unknown", Status::name)
            .into(),
        message: crate::service::plan::message(h),
        goal: if request.goal_kind == GoalKind::Pose as u32 {
            "pose"
        } else {
            "joints"
        }
        .into(),
        method: method.into(),
        waypoints: h.waypoints,
        iterations: h.iterations,
        local_samplers: h.local_samplers,
        retrieval_us: h.retrieval_us,
        planning_us: h.planning_us,
        simplify_us: h.simplify_us,
        total_us: h.total_us,
        duration_s: answer.trajectory.as_ref().map_or(0.0, |t| t.duration),
    }
}
