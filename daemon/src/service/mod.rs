//! The daemon's iceoryx2 services: `ingest` (clouds, objects, joint states → world model, on its
//! own thread) and `plan` (plan and status requests, on the main thread).

pub mod ingest;
pub mod plan;

use std::sync::Mutex;

/// Counters shared by the threads (read by the status service).
#[derive(Debug, Default)]
pub struct Stats {
    pub inner: Mutex<StatsInner>,
}

#[derive(Debug, Default)]
pub struct StatsInner {
    pub clouds: u64,
    pub objects: u64,
    pub joint_states: u64,
    pub rejected: u64,
    pub plans: u64,
    pub solved: u64,
    pub last_cloud_stamp_ns: u64,
    /// Recent cloud hand-off latencies, µs (ring of the last 1000).
    pub cloud_latency_us: Vec<f64>,
    pub map_blocks: u64,
    pub world_objects: u64,
}

impl StatsInner {
    pub fn record_cloud_latency(&mut self, us: f64) {
        if self.cloud_latency_us.len() >= 1000 {
            self.cloud_latency_us.remove(0);
        }
        self.cloud_latency_us.push(us);
    }

    /// Median and 99th percentile of the recent cloud latencies.
    pub fn cloud_latency(&self) -> (f64, f64) {
        let mut v = self.cloud_latency_us.clone();
        if v.is_empty() {
            return (0.0, 0.0);
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() as f64 * q).ceil() as usize).clamp(1, v.len()) - 1];
        (at(0.5), at(0.99))
    }
}
