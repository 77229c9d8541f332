//! The daemon's iceoryx2 services: `ingest` (clouds, objects, joint states → world model, on its
//! own thread) and `plan` (plan and status requests, on the main thread).

pub mod ingest;
pub mod plan;

use std::sync::Mutex;

/// Counters shared by the threads (read by the status service and the monitor).
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
    /// Cloud hand-off latencies, µs.
    pub cloud_latency_us: Recent,
    /// Plan latencies in the daemon (receipt to reply), µs.
    pub plan_latency_us: Recent,
    pub map_blocks: u64,
    pub map_occupied_blocks: u64,
    pub map_memory_bytes: u64,
    pub world_objects: u64,
    pub spark_pairs: u64,
    pub spark_entries: u64,
    pub flame_entries: u64,
}

/// The last 1000 values of a measurement, for percentiles.
#[derive(Debug, Default)]
pub struct Recent {
    values: Vec<f64>,
    next: usize,
}

impl Recent {
    const CAPACITY: usize = 1000;

    /// Adds a value, replacing the oldest once full.
    pub fn push(&mut self, v: f64) {
        if self.values.len() < Self::CAPACITY {
            self.values.push(v);
        } else {
            self.values[self.next] = v;
        }
        self.next = (self.next + 1) % Self::CAPACITY;
    }

    /// Median and 99th percentile (zeros when empty).
    pub fn p50_p99(&self) -> (f64, f64) {
        let mut v = self.values.clone();
        if v.is_empty() {
            return (0.0, 0.0);
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() as f64 * q).ceil() as usize).clamp(1, v.len()) - 1];
        (at(0.5), at(0.99))
    }
}

#[cfg(test)]
mod tests {
    use super::Recent;

    #[test]
    fn recent_keeps_the_last_values() {
        let mut sut = Recent::default();
        for i in 0..1500 {
            sut.push(i as f64);
        }
        // 500..1500 remain: median 999, p99 1489.
        assert_eq!(sut.p50_p99(), (999.0, 1489.0));
    }
}
