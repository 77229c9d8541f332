//! Answering a plan request: plan on the latest world snapshot with the sampler the method
//! asks for, and build the reply (status, path, trajectory) and the lesson to learn later.

use super::decode::{decode, method_code};
use crate::config::Config;
use crate::service::SnapshotCell;
use ember_engine::experience::Experience;
use ember_engine::planning::{self, Cancel, PlanError};
use ember_engine::robot::{ConfigError, Robot};
use ember_engine::trajectory::Trajectory;
use ember_engine::world::model::Snapshot;
use ember_sdk::recording::{self, Event};
use ember_sdk::wire::plan::MAX_PLAN_VALUES;
use ember_sdk::wire::{self, PlanRequestHeader, PlanResponseHeader, TrajectoryBlock};
use ember_sdk::Status;
use std::sync::{Arc, RwLock};
use std::time::Instant;

/// An answer before it goes on the wire.
pub struct Answer {
    /// The response header (status, message, timings).
    pub header: PlanResponseHeader,
    /// The path's waypoints (empty unless solved).
    pub path: Vec<Vec<f64>>,
    /// The timed path, when the request asked for it and the plan was solved.
    pub trajectory: Option<TrajectoryBlock>,
}

impl Answer {
    /// The response payload: the path, then the trajectory block when there is one.
    pub fn payload(&self) -> Vec<f64> {
        let mut out = self.path.concat();
        if let Some(t) = &self.trajectory {
            t.encode(&mut out);
        }
        out
    }
}

/// An answer that carries no path: a refusal or a failure.
pub fn fail(status: Status, message: impl AsRef<str>) -> Answer {
    let mut header = PlanResponseHeader {
        status: status as u32,
        ..Default::default()
    };
    let m = message.as_ref().as_bytes();
    let n = m.len().min(header.message.len());
    header.message[..n].copy_from_slice(&m[..n]);
    Answer {
        header,
        path: Vec::new(),
        trajectory: None,
    }
}

/// The status a planning error is answered with.
fn status_of(e: &PlanError) -> Status {
    match e {
        PlanError::InvalidStart(ConfigError::WrongLength { .. })
        | PlanError::InvalidGoal(ConfigError::WrongLength { .. }) => Status::WrongDof,
        PlanError::InvalidStart(ConfigError::NotFinite { .. })
        | PlanError::InvalidGoal(ConfigError::NotFinite { .. }) => Status::NotFinite,
        PlanError::InvalidStart(_) => Status::InvalidStart,
        PlanError::StartInCollision(_) => Status::StartInCollision,
        PlanError::InvalidGoal(_) => Status::InvalidGoal,
        PlanError::GoalInCollision(_) => Status::GoalInCollision,
        PlanError::UnknownLink(_) => Status::UnknownLink,
        PlanError::UnreachablePose { .. } => Status::UnreachablePose,
        PlanError::Timeout { .. } => Status::Timeout,
        PlanError::Cancelled { .. } => Status::Cancelled,
        PlanError::InvalidPath(_) => Status::Internal,
        PlanError::InvalidTiming(_) => Status::BadRequest,
    }
}

/// What learning from a solved plan needs once the reply is out: the world it was planned in
/// (the path is the answer's).
pub struct Lesson {
    /// The world the plan saw.
    pub snapshot: Arc<Snapshot>,
}

impl Lesson {
    /// Adds what the solution `path` teaches to `experience` (`robot` without what it holds).
    pub fn learn(&self, robot: &Robot, path: &[Vec<f64>], experience: &mut Experience) {
        let s = &self.snapshot;
        experience.learn(
            s.robot(robot),
            &s.scene,
            Some((&s.map, &s.octoboxes)),
            path,
            None,
        );
    }
}

/// Answers one request: the reply, and the lesson to learn after it is sent (when solved and
/// learning is on for it). `on_snapshot` runs while the world is held, as the request takes
/// its snapshot (not for requests refused before).
pub fn answer(
    config: &Config,
    robot: &Robot,
    snapshot: &SnapshotCell,
    experience: &RwLock<Experience>,
    cancel: &Cancel,
    (h, values): (&PlanRequestHeader, &[f64]),
    on_snapshot: &mut dyn FnMut(),
) -> (Answer, Option<Lesson>) {
    let t0 = Instant::now();
    // The databases are read only while retrieving: learning and saving wait for no plan.
    let experience = experience
        .read()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let mut d = match decode(config, robot, experience.default_method(), h, values) {
        Ok(d) => d,
        Err(why) => return (fail(why.status(), why.to_string()), None),
    };
    d.request.params.cancel = cancel.clone();
    let snap = {
        let cell = snapshot.lock().expect("snapshot lock");
        on_snapshot();
        cell.clone()
    };
    let t_ret = Instant::now();
    let mut sampler = experience
        .sampler_for(d.method, snap.pairs.pairs(), &snap.octoboxes)
        .into_owned();
    drop(experience);
    let local_samplers = sampler.local_samplers() as u32;
    let retrieval_us = t_ret.elapsed().as_secs_f64() * 1e6;
    // The robot with what it holds in this world.
    let outcome = planning::plan(snap.robot(robot), &snap.env, &d.request, &mut sampler);
    let method = method_code(d.method);
    match outcome {
        Ok(res) => {
            let s = res.stats;
            let mut header = PlanResponseHeader {
                status: Status::Ok as u32,
                dof: robot.dof() as u32,
                waypoints: res.path.len() as u32,
                iterations: s.iterations,
                retrieval_us,
                planning_us: (s.ik_s + s.search_s) * 1e6,
                simplify_us: s.simplify_s * 1e6,
                total_us: 0.0,
                local_samplers,
                method,
                ..Default::default()
            };
            let (trajectory, timing_note) = match &res.trajectory {
                None => (None, String::new()),
                Some(Ok(t)) => (
                    Some(block_of(t, res.path.len())),
                    format!(", executes in {:.2} s", t.duration),
                ),
                Some(Err(e)) => (
                    Some(TrajectoryBlock::default()),
                    format!("; not timed: {e}"),
                ),
            };
            let msg = format!(
                "solved: {} waypoints, {} iterations{timing_note}",
                res.path.len(),
                s.iterations
            );
            let n = msg.len().min(header.message.len());
            header.message[..n].copy_from_slice(&msg.as_bytes()[..n]);
            header.total_us = t0.elapsed().as_secs_f64() * 1e6;
            let lesson = d.learn.then(|| Lesson {
                snapshot: snap.clone(),
            });
            let answer = Answer {
                header,
                path: res.path,
                trajectory,
            };
            (answer, lesson)
        }
        Err(e) => {
            let mut a = fail(status_of(&e), e.to_string());
            a.header.retrieval_us = retrieval_us;
            a.header.method = method;
            a.header.total_us = t0.elapsed().as_secs_f64() * 1e6;
            (a, None)
        }
    }
}

/// The trajectory as it goes on the wire, resampled coarser when the samples would not fit in
/// a response beside the path.
fn block_of(t: &Trajectory, waypoints: usize) -> TrajectoryBlock {
    let dof = t.joint_names.len();
    let room = MAX_PLAN_VALUES.saturating_sub(waypoints * dof);
    let mut block = TrajectoryBlock {
        duration: t.duration,
        times: t.times.clone(),
        positions: t.positions.clone(),
        velocities: t.velocities.clone(),
        accelerations: t.accelerations.clone(),
        waypoint_times: t.waypoint_times.clone(),
    };
    let mut samples = block.times.len();
    while TrajectoryBlock::len_for(samples, dof, waypoints) > room && samples > 2 {
        samples = samples.div_ceil(2);
        let times: Vec<f64> = (0..samples)
            .map(|k| t.duration * k as f64 / (samples - 1) as f64)
            .collect();
        let states: Vec<_> = times.iter().map(|&x| t.state_at(x)).collect();
        block.positions = states.iter().map(|s| s.0.clone()).collect();
        block.velocities = states.iter().map(|s| s.1.clone()).collect();
        block.accelerations = states.iter().map(|s| s.2.clone()).collect();
        block.times = times;
    }
    block
}

/// The message of a reply as text (for logs).
pub fn message(h: &PlanResponseHeader) -> String {
    wire::name_str(&h.message)
}

/// The recorded events of an answer (stamped with its request's receive time): the response,
/// then its trajectory when it has one with samples.
pub fn answer_events(recv_ns: u64, robot: &Robot, a: &Answer) -> Vec<Event> {
    let mut out = vec![Event::PlanResponse(recording::PlanResponse::new(
        recv_ns,
        &a.header,
        a.path.concat(),
    ))];
    if let Some(block) = a.trajectory.as_ref().filter(|b| !b.times.is_empty()) {
        let names = robot.variables().iter().map(|v| v.name.clone()).collect();
        out.push(Event::PlanTrajectory(
            recording::JointTrajectory::from_block(recv_ns, names, block),
        ));
    }
    out
}
