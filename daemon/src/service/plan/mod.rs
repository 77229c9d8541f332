//! The plan service: requests are taken off the port on the service thread and planned by a
//! pool of workers ([`workers`]), so status, ingest, cancels and other plans are answered
//! while a long plan runs. Each request is decoded into an engine request or a typed
//! rejection ([`decode`]), planned on the latest world snapshot ([`answer`]) and replied to;
//! then — off the request's latency — recorded, reported to the monitor, and learned from.
//! [`in_flight`] keeps the plans not yet answered: their age and cancel flags.

pub mod answer;
pub mod decode;
pub mod in_flight;
pub mod workers;

pub use answer::{answer, answer_events, message, Answer};

use crate::config::Config;
use crate::monitor::Monitor;
use crate::recorder::Recorder;
use crate::service::{SnapshotCell, Stats};
use ember_engine::planning::Cancel;
use ember_engine::robot::Robot;
use ember_sdk::client::now_ns;
use ember_sdk::services::{self, Limits, Open};
use ember_sdk::wire::{PlanRequestHeader, PlanResponseHeader};
use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use std::collections::HashMap;
use std::sync::mpsc::Sender;
use std::time::Instant;
use tracing::warn;

/// What answering needs besides the experience: the daemon's settings, robot and world, and
/// where answers are counted, recorded and reported.
pub struct PlanContext<'a> {
    /// Daemon settings.
    pub config: &'a Config,
    /// The robot served.
    pub robot: &'a Robot,
    /// The latest world.
    pub snapshot: &'a SnapshotCell,
    /// Counters (and the plans in flight).
    pub stats: &'a Stats,
    /// The session recorder, when recording.
    pub recorder: Option<&'a Recorder>,
    /// The monitor, when monitoring.
    pub monitor: Option<&'a Monitor>,
}

/// A request taken off the port, for a worker.
pub struct Job {
    /// The daemon's number for it.
    pub id: u64,
    /// The header as received.
    pub header: PlanRequestHeader,
    /// The payload as received.
    pub values: Vec<f64>,
    /// Receipt time, ns since the Unix epoch.
    pub recv_ns: u64,
    /// Receipt time, for the time in the daemon.
    pub received: Instant,
    /// Set to cancel it.
    pub cancel: Cancel,
}

/// A worker's reply to job `id`.
pub struct Reply {
    /// The job answered.
    pub id: u64,
    /// The response header.
    pub header: PlanResponseHeader,
    /// The response payload.
    pub payload: Vec<f64>,
}

type Request = ActiveRequest<ipc::Service, [f64], PlanRequestHeader, [f64], PlanResponseHeader>;

/// The plan requests port, and the requests taken off it and not yet answered.
pub struct PlanPort {
    server: Server<ipc::Service, [f64], PlanRequestHeader, [f64], PlanResponseHeader>,
    waiting: HashMap<u64, Request>,
    next_job: u64,
}

impl PlanPort {
    /// Serves the instance's plan requests (configurations of `dof` joints); fails when another
    /// daemon serves the instance.
    pub fn open(
        node: &Node<ipc::Service>,
        instance: &str,
        limits: Limits,
        dof: usize,
    ) -> anyhow::Result<Self> {
        let server = services::plan(node, instance, Open::Serve(limits))
            .map_err(anyhow::Error::msg)?
            .server_builder()
            .initial_max_slice_len(dof * 64)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(|e| {
                anyhow::anyhow!(
                    "cannot serve instance '{instance}' (is another daemon serving it?): {e:?}"
                )
            })?;
        Ok(PlanPort {
            server,
            waiting: HashMap::new(),
            next_job: 0,
        })
    }

    /// Takes every waiting request off the port, registers it in flight and hands it to the
    /// workers; returns how many.
    pub fn take(&mut self, stats: &Stats, jobs: &Sender<Job>) -> usize {
        let mut taken = 0;
        while let Ok(Some(active)) = self.server.receive() {
            taken += 1;
            self.next_job += 1;
            let id = self.next_job;
            let header = *active.user_header();
            let received = Instant::now();
            let cancel = stats.in_flight.start(id, header.request_id, received);
            let job = Job {
                id,
                header,
                values: active.payload().to_vec(),
                recv_ns: now_ns(),
                received,
                cancel,
            };
            self.waiting.insert(id, active);
            if jobs.send(job).is_err() {
                // No worker left (the daemon is stopping): the request is dropped unanswered.
                self.waiting.remove(&id);
                stats.in_flight.finish(id);
            }
        }
        taken
    }

    /// Sends a worker's reply to the client that asked.
    pub fn reply(&mut self, reply: Reply) {
        let Some(active) = self.waiting.remove(&reply.id) else {
            return;
        };
        match active.loan_slice_uninit(reply.payload.len()) {
            Ok(mut response) => {
                *response.user_header_mut() = reply.header;
                let response = response.write_from_slice(&reply.payload);
                if let Err(e) = response.send() {
                    warn!("sending a plan response failed: {e:?}");
                }
            }
            Err(e) => warn!("loaning a plan response failed: {e:?}"),
        }
    }
}
