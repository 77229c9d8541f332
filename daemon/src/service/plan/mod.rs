//! The plan service: each request is decoded into an engine request or a typed rejection
//! ([`decode`]), planned on the latest world snapshot ([`answer`]) and replied to; then — off
//! the request's latency — recorded, reported to the monitor, and learned from.

pub mod answer;
pub mod decode;

pub use answer::{answer, answer_events, message, Answer};

use super::{SnapshotCell, Stats};
use crate::config::Config;
use crate::monitor::docs::plan_summary;
use crate::monitor::Monitor;
use crate::recorder::Recorder;
use ember_engine::experience::Experience;
use ember_engine::planning::Cancel;
use ember_engine::robot::Robot;
use ember_sdk::client::now_ns;
use ember_sdk::recording::{self, Event};
use ember_sdk::services::{self, Limits, Open};
use ember_sdk::wire::{PlanRequestHeader, PlanResponseHeader};
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
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
    /// Counters.
    pub stats: &'a Stats,
    /// The session recorder, when recording.
    pub recorder: Option<&'a Recorder>,
    /// The monitor, when monitoring.
    pub monitor: Option<&'a Monitor>,
    /// Set when the daemon is asked to stop: plans in flight end as `cancelled`.
    pub cancel: Cancel,
}

/// The plan requests port.
pub struct PlanPort(Server<ipc::Service, [f64], PlanRequestHeader, [f64], PlanResponseHeader>);

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
        Ok(PlanPort(server))
    }

    /// Answers every waiting request; returns how many.
    pub fn serve(&self, cx: &PlanContext, experience: &mut Experience) -> usize {
        let mut served = 0;
        while let Ok(Some(active)) = self.0.receive() {
            served += 1;
            let h = *active.user_header();
            let values: &[f64] = active.payload();
            let recv_ns = now_ns();
            let (a, lesson) = answer(
                cx.config,
                cx.robot,
                cx.snapshot,
                experience,
                &cx.cancel,
                &h,
                values,
            );
            let seq = cx.stats.planned(&a.header, experience);
            if a.header.status != 0 {
                warn!("plan request refused or failed: {}", message(&a.header));
            }
            let flat = a.payload();
            match active.loan_slice_uninit(flat.len()) {
                Ok(mut response) => {
                    *response.user_header_mut() = a.header;
                    let response = response.write_from_slice(&flat);
                    if let Err(e) = response.send() {
                        warn!("sending a plan response failed: {e:?}");
                    }
                }
                Err(e) => warn!("loaning a plan response failed: {e:?}"),
            }
            // The reply is out: recording, monitoring and learning never delay an answer.
            if let Some(r) = cx.recorder {
                let request = recording::PlanRequest::new(recv_ns, &h, values);
                r.record(recv_ns, Event::PlanRequest(request));
                for event in answer_events(recv_ns, cx.robot, &a) {
                    r.record(now_ns(), event);
                }
            }
            if let Some(m) = cx.monitor {
                m.plan(plan_summary(&cx.config.instance, seq, recv_ns, &h, &a));
            }
            if let Some(lesson) = lesson {
                lesson.learn(cx.robot, &a.path, experience);
                cx.stats.learned(experience);
            }
        }
        served
    }
}
