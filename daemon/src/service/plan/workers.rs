//! The planning workers: each takes jobs from the shared queue, answers them, hands the reply
//! to the service thread, then records, reports and learns from the answer.

use super::answer::fail;
use super::{answer, answer_events, message, Job, PlanContext, Reply};
use crate::monitor::docs::plan_summary;
use ember_engine::experience::Experience;
use ember_sdk::client::now_ns;
use ember_sdk::recording::{self, Event};
use ember_sdk::services::{self, Open, Wake};
use ember_sdk::Status;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use std::panic::AssertUnwindSafe;
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Mutex, PoisonError, RwLock};
use tracing::{error, warn};

/// Runs one worker until the job queue closes.
pub fn work(
    cx: &PlanContext,
    experience: &RwLock<Experience>,
    jobs: &Mutex<Receiver<Job>>,
    replies: Sender<Reply>,
) {
    let waker = Waker::open(&cx.config.instance);
    loop {
        let job = match jobs.lock().expect("job queue lock").recv() {
            Ok(job) => job,
            Err(_) => return,
        };
        let (h, values) = (&job.header, &job.values[..]);
        // The request is recorded as it takes its snapshot (inputs are recorded as they enter
        // one): what precedes it in the recording is the world it was planned in. A request
        // refused before is recorded with its answer.
        let mut recorded = false;
        let mut on_snapshot = || {
            record_request(cx, &job);
            recorded = true;
        };
        // A bug in planning answers this request `internal` and the worker serves on.
        let answered = std::panic::catch_unwind(AssertUnwindSafe(|| {
            answer(
                cx.config,
                cx.robot,
                cx.snapshot,
                experience,
                &job.cancel,
                (h, values),
                &mut on_snapshot,
            )
        }));
        let (mut a, lesson) = answered.unwrap_or_else(|panic| {
            let why = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            error!("planning failed on an internal error: {why}");
            (
                fail(Status::Internal, format!("internal error: {why}")),
                None,
            )
        });
        // Time in the daemon, from receipt: waiting for a worker included.
        a.header.total_us = job.received.elapsed().as_secs_f64() * 1e6;
        let seq = cx.stats.planned(&a.header);
        cx.stats.in_flight.finish(job.id);
        if a.header.status != 0 {
            warn!("plan request refused or failed: {}", message(&a.header));
        }
        let reply = Reply {
            id: job.id,
            header: a.header,
            payload: a.payload(),
        };
        // A request that arrives after this reply must plan with what it teaches (as when one
        // thread answered and learned in turn; a replayed session depends on it): the
        // databases are locked before the reply goes, so its retrieval waits for the lesson.
        // (A panic elsewhere while it was held leaves the databases usable: never poisoned.)
        let learning = lesson.map(|l| {
            (
                l,
                experience.write().unwrap_or_else(PoisonError::into_inner),
            )
        });
        if replies.send(reply).is_err() {
            return;
        }
        waker.wake();
        // The reply is out: recording, monitoring and learning never delay an answer.
        if !recorded {
            record_request(cx, &job);
        }
        if let Some(r) = cx.recorder {
            for event in answer_events(job.recv_ns, cx.robot, &a) {
                r.record(now_ns(), event);
            }
        }
        if let Some(m) = cx.monitor {
            m.plan(plan_summary(&cx.config.instance, seq, job.recv_ns, h, &a));
        }
        if let Some((lesson, mut experience)) = learning {
            let learned = std::panic::catch_unwind(AssertUnwindSafe(|| {
                lesson.learn(cx.robot, &a.path, &mut experience)
            }));
            if learned.is_err() {
                error!("learning from a plan failed on an internal error; the worker serves on");
            }
            cx.stats.learned(&experience);
        }
    }
}

/// Records `job`'s request as received, when recording.
fn record_request(cx: &PlanContext, job: &Job) {
    if let Some(r) = cx.recorder {
        let request = recording::PlanRequest::new(job.recv_ns, &job.header, &job.values);
        r.record(job.recv_ns, Event::PlanRequest(request));
    }
}

/// Wakes the service thread when a reply is ready (it sleeps on the requests wake-up service;
/// without one it finds the reply within its idle wait).
struct Waker(Option<(Node<ipc::Service>, Notifier<ipc::Service>)>);

impl Waker {
    fn open(instance: &str) -> Waker {
        let opened = (|| {
            let node = NodeBuilder::new()
                .signal_handling_mode(SignalHandlingMode::Disabled)
                .create::<ipc::Service>()
                .ok()?;
            let notifier = services::wake(&node, instance, Wake::Requests, Open::Attach)
                .ok()?
                .notifier_builder()
                .create()
                .ok()?;
            Some((node, notifier))
        })();
        if opened.is_none() {
            warn!("a planning worker cannot wake the service thread: replies wait up to its idle wait");
        }
        Waker(opened)
    }

    fn wake(&self) {
        if let Some((_, n)) = &self.0 {
            let _ = n.notify();
        }
    }
}
