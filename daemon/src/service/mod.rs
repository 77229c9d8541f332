//! The daemon's boundary: one module per iceoryx2 service, each owning its port and decoding
//! the wire payload into engine terms or a typed [`Rejection`]:
//! - [`cloud`], [`objects`], [`joints`]: sensor and world inputs, read by the [`ingest`] thread,
//!   which folds them into the world model and publishes snapshots;
//! - [`plan`]: plan requests, taken on the service thread and planned by a worker pool;
//!   [`cancel`]: cancels plans in flight by request id; [`status`]: the counters.
//!
//! `command/run.rs` only wires them together.

pub mod cancel;
pub mod cloud;
pub mod drops;
#[cfg(test)]
mod fuzz;
pub mod ingest;
pub mod joints;
pub mod objects;
pub mod plan;
pub mod rejection;
pub mod status;

pub use rejection::Rejection;

use ember_engine::experience::{Database, Experience};
use ember_engine::world::model::Snapshot;
use ember_sdk::monitor::{DatabaseDoc, InputsDoc, MapDoc, PlansDoc, WorldDoc};
use ember_sdk::wire::PlanResponseHeader;
use std::sync::{Arc, Mutex};

/// How long a daemon thread sleeps waiting for a client's wake-up before looking at its ports
/// on its own (clients that do not notify are served within this).
pub const IDLE_WAIT: std::time::Duration = std::time::Duration::from_millis(10);

/// Shared handle to the latest world snapshot (written by ingest, read by planning).
pub type SnapshotCell = Arc<Mutex<Arc<Snapshot>>>;

/// Counters shared by the threads (read by the status service and the monitor).
#[derive(Debug, Default)]
pub struct Stats {
    pub inner: Mutex<StatsInner>,
    /// The plans taken and not yet answered.
    pub in_flight: plan::in_flight::InFlight,
}

impl Stats {
    /// Counts an answered request; returns its sequence number.
    pub fn planned(&self, h: &PlanResponseHeader) -> u64 {
        let mut st = self.inner.lock().expect("stats lock");
        st.plans.total += 1;
        st.plans.solved += (h.status == 0) as u64;
        st.plans.cancelled += (h.status == ember_sdk::Status::Cancelled as u32) as u64;
        st.plan_latency_us.push(h.total_us);
        st.plans.total
    }

    /// Records the databases' sizes after learning.
    pub fn learned(&self, experience: &Experience) {
        self.inner
            .lock()
            .expect("stats lock")
            .set_experience(experience);
    }

    /// Counts a refused input, and logs why.
    pub fn rejected(&self, why: &Rejection) {
        tracing::warn!("rejected input: {why}");
        let inputs = &mut self.inner.lock().expect("stats lock").inputs;
        inputs.rejected += 1;
        inputs.last_rejection = why.to_string();
        inputs.last_rejection_status = why.status() as u32;
    }
}

/// The counters, kept in the monitor's document types ([`ember_sdk::monitor::StatusDoc`]'s
/// parts); rates and percentiles are filled in when a document is made.
#[derive(Debug, Default)]
pub struct StatsInner {
    /// Input counts (rates and latency percentiles left at zero here).
    pub inputs: InputsDoc,
    /// Map size (resolution filled in when published).
    pub map: MapDoc,
    /// World size.
    pub world: WorldDoc,
    /// Database sizes (settings filled in when published).
    pub experience: DatabaseDoc,
    /// Plans answered and solved (the rest filled in when published).
    pub plans: PlansDoc,
    /// Cloud hand-off latencies, µs.
    pub cloud_latency_us: Recent,
    /// Plan latencies in the daemon (receipt to reply), µs.
    pub plan_latency_us: Recent,
}

impl StatsInner {
    fn set_experience(&mut self, experience: &Experience) {
        self.experience.spark_entries = experience.spark.len() as u64;
        self.experience.flame_entries = experience.flame.len() as u64;
    }
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
        let q = ember_sdk::stats::quantile;
        (q(&mut v, 0.5), q(&mut v, 0.99))
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
