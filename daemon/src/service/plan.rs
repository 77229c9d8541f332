//! The plan and status services: validate each request, plan on the latest world snapshot, reply
//! with a status code and the path, then (optionally) learn from the solution.

use super::ingest::SnapshotCell;
use super::Stats;
use crate::config::Config;
use ember_engine::experience::database::Retrieval;
use ember_engine::experience::train::learn;
use ember_engine::experience::{FlameDb, GlobalSampler, SparkDb};
use ember_engine::planning::{
    self, Goal, PlanError, PlanRequest, PlannerParams, PoseGoal, Sampler, UniformSampler,
};
use ember_engine::robot::{ConfigError, Robot};
use ember_engine::scene::pose_from_xyz_xyzw;
use ember_engine::trajectory::{TimingParams, Trajectory};
use ember_sdk::wire::plan::MAX_PLAN_VALUES;
use ember_sdk::wire::{
    self, GoalKind, Method, PlanRequestHeader, PlanResponseHeader, StatusReply, TrajectoryBlock,
    PROTOCOL_VERSION,
};
use ember_sdk::Status;
use std::time::{Duration, Instant};

/// The experience databases the planner uses and extends.
pub struct Experience {
    pub spark: SparkDb,
    pub flame: FlameDb,
    pub dirty: bool,
}

/// An answer before it goes on the wire.
pub struct Answer {
    pub header: PlanResponseHeader,
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

fn fail(status: Status, message: impl AsRef<str>) -> Answer {
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
        PlanError::InvalidPath(_) => Status::Internal,
        PlanError::InvalidTiming(_) => Status::BadRequest,
    }
}

/// Validates and answers one request.
pub fn answer(
    config: &Config,
    robot: &Robot,
    snapshot: &SnapshotCell,
    experience: &mut Experience,
    h: &PlanRequestHeader,
    values: &[f64],
) -> Answer {
    let t0 = Instant::now();
    if h.version != PROTOCOL_VERSION {
        return fail(
            Status::VersionMismatch,
            format!(
                "request of protocol version {}, this daemon speaks {PROTOCOL_VERSION}",
                h.version
            ),
        );
    }
    let dof = robot.dof();
    if h.dof as usize != dof {
        return fail(
            Status::WrongDof,
            format!(
                "request has {} joints per configuration, the robot has {dof}",
                h.dof
            ),
        );
    }
    let goal_kind = match h.goal_kind {
        k if k == GoalKind::Joints as u32 => GoalKind::Joints,
        k if k == GoalKind::Pose as u32 => GoalKind::Pose,
        k => return fail(Status::BadRequest, format!("unknown goal kind {k}")),
    };
    let method = match h.method {
        m if m == Method::Auto as u32 => {
            if experience.spark.is_empty() {
                Method::Uniform
            } else {
                Method::Spark
            }
        }
        m if m == Method::Uniform as u32 => Method::Uniform,
        m if m == Method::Spark as u32 => Method::Spark,
        m if m == Method::Flame as u32 => Method::Flame,
        m => return fail(Status::BadRequest, format!("unknown method {m}")),
    };
    if h.flags & !wire::KNOWN_FLAGS != 0 {
        return fail(
            Status::BadRequest,
            format!("unknown flag bits {:#x}", h.flags & !wire::KNOWN_FLAGS),
        );
    }
    let goals = if goal_kind == GoalKind::Joints {
        h.goal_count as usize
    } else {
        0
    };
    if goal_kind == GoalKind::Joints && goals == 0 {
        return fail(Status::BadRequest, "joint goal without goal configurations");
    }
    let timed = h.flags & wire::FLAG_TRAJECTORY != 0;
    let expected = dof * (1 + goals) + if timed { 2 } else { 0 };
    if values.len() != expected {
        return fail(
            Status::BadRequest,
            format!(
                "payload holds {} values, expected {expected} ({} configurations of {dof}{})",
                values.len(),
                1 + goals,
                if timed { " and 2 scaling factors" } else { "" }
            ),
        );
    }
    let numbers = values.iter().chain(&h.pose).chain([
        &h.time_limit_s,
        &h.position_tolerance,
        &h.orientation_tolerance,
    ]);
    if numbers.clone().any(|v| !v.is_finite()) {
        return fail(
            Status::NotFinite,
            "the request holds a NaN or infinite number",
        );
    }
    let timing = if timed {
        // 0 keeps the configured factor; anything else must be in (0, 1].
        let configured = config.trajectory.params();
        let pick = |v: f64, default: f64| if v == 0.0 { default } else { v };
        let n = values.len();
        let timing = TimingParams {
            velocity_scaling: pick(values[n - 2], configured.velocity_scaling),
            acceleration_scaling: pick(values[n - 1], configured.acceleration_scaling),
            ..configured
        };
        if let Err(e) = timing.validate() {
            return fail(Status::BadRequest, e.to_string());
        }
        Some(timing)
    } else {
        None
    };
    let start = values[..dof].to_vec();
    let goal = match goal_kind {
        GoalKind::Joints => Goal::Joints(
            values[dof..dof * (1 + goals)]
                .chunks_exact(dof)
                .map(<[f64]>::to_vec)
                .collect(),
        ),
        GoalKind::Pose => {
            let p = h.pose;
            let Some(pose) = pose_from_xyz_xyzw([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]])
            else {
                return fail(Status::BadRequest, "pose goal with a zero quaternion");
            };
            if !(h.position_tolerance > 0.0 && h.orientation_tolerance > 0.0) {
                return fail(Status::BadRequest, "pose goal tolerances must be positive");
            }
            Goal::Pose(PoseGoal {
                link: None,
                pose,
                position_tolerance: h.position_tolerance,
                orientation_tolerance: h.orientation_tolerance,
            })
        }
    };
    let snap = snapshot.lock().expect("snapshot lock").clone();
    let t_ret = Instant::now();
    let retrieval = match method {
        Method::Spark => experience.spark.retrieve(&snap.pairs),
        Method::Flame => experience.flame.retrieve(&snap.octoboxes),
        _ => Retrieval::default(),
    };
    let local_samplers = retrieval.samplers.len() as u32;
    let mut sampler: Box<dyn Sampler + '_> = match method {
        Method::Uniform | Method::Auto => Box::new(UniformSampler),
        _ => Box::new(GlobalSampler::new(
            retrieval,
            experience.spark.params().sigma,
            experience.spark.params().lambda,
        )),
    };
    let retrieval_us = t_ret.elapsed().as_secs_f64() * 1e6;
    let time_limit = if h.time_limit_s > 0.0 {
        h.time_limit_s
    } else {
        config.planner.default_time_limit_s
    };
    let request = PlanRequest {
        start,
        goal,
        params: PlannerParams {
            seed: h.seed,
            time_limit: Duration::from_secs_f64(time_limit.min(3600.0)),
            range: config.planner.range,
            simplify: config.planner.simplify,
            timing,
            ..Default::default()
        },
    };
    let outcome = planning::plan(robot, &snap.env, &request, sampler.as_mut());
    // The sampler borrows the databases, which learning below extends.
    drop(sampler);
    match outcome {
        Ok(res) => {
            let s = res.stats;
            let mut header = PlanResponseHeader {
                status: Status::Ok as u32,
                dof: dof as u32,
                waypoints: res.path.len() as u32,
                iterations: s.iterations,
                retrieval_us,
                planning_us: (s.ik_s + s.search_s) * 1e6,
                simplify_us: s.simplify_s * 1e6,
                total_us: 0.0,
                local_samplers,
                method: method as u32,
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
            if config.experience.online_learning && h.flags & wire::FLAG_NO_LEARN == 0 {
                // After the reply is built: learning never delays the answer's timing fields.
                let _ = learn(
                    robot,
                    &snap.scene,
                    Some(&snap.map),
                    &res.path,
                    None,
                    &mut experience.spark,
                    Some(&mut experience.flame),
                );
                experience.dirty = true;
            }
            Answer {
                header,
                path: res.path,
                trajectory,
            }
        }
        Err(e) => {
            let mut a = fail(status_of(&e), e.to_string());
            a.header.retrieval_us = retrieval_us;
            a.header.method = method as u32;
            a.header.total_us = t0.elapsed().as_secs_f64() * 1e6;
            a
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

/// The status reply.
pub fn status(stats: &Stats, robot: &Robot, started: Instant) -> StatusReply {
    let st = stats.inner.lock().expect("stats lock");
    let (p50, p99) = st.cloud_latency_us.p50_p99();
    StatusReply {
        version: PROTOCOL_VERSION,
        dof: robot.dof() as u32,
        uptime_s: started.elapsed().as_secs_f64(),
        clouds: st.clouds,
        objects: st.objects,
        joint_states: st.joint_states,
        rejected: st.rejected,
        plans: st.plans,
        solved: st.solved,
        cloud_latency_p50_us: p50,
        cloud_latency_p99_us: p99,
        last_cloud_stamp_ns: st.last_cloud_stamp_ns,
        map_blocks: st.map_blocks,
        world_objects: st.world_objects,
        spark_entries: st.spark_entries,
        flame_entries: st.flame_entries,
        recorded: 0,
        recording_dropped: 0,
    }
}

/// The message of a reply as text (for logs).
pub fn message(h: &PlanResponseHeader) -> String {
    wire::name_str(&h.message)
}

/// The request as a recorded message.
pub fn request_message(
    recv_ns: u64,
    h: &PlanRequestHeader,
    values: &[f64],
) -> ember_sdk::recording::PlanRequest {
    use ember_sdk::recording::{Header, PlanRequest, Time};
    PlanRequest {
        header: Header {
            stamp: Time::from_ns(recv_ns),
            frame_id: "base_link".into(),
        },
        version: h.version,
        dof: h.dof,
        goal_kind: h.goal_kind,
        goal_count: h.goal_count,
        method: h.method,
        flags: h.flags,
        time_limit_s: h.time_limit_s,
        seed: h.seed,
        pose: h.pose,
        position_tolerance: h.position_tolerance,
        orientation_tolerance: h.orientation_tolerance,
        values: values.to_vec(),
    }
}

/// The answer as a recorded message (stamped with its request's receive time).
pub fn response_message(recv_ns: u64, a: &Answer) -> ember_sdk::recording::PlanResponse {
    use ember_sdk::recording::{Header, PlanResponse, Time};
    let h = &a.header;
    PlanResponse {
        header: Header {
            stamp: Time::from_ns(recv_ns),
            frame_id: "base_link".into(),
        },
        status: h.status,
        dof: h.dof,
        waypoints: h.waypoints,
        iterations: h.iterations,
        retrieval_us: h.retrieval_us,
        planning_us: h.planning_us,
        simplify_us: h.simplify_us,
        total_us: h.total_us,
        method: h.method,
        message: message(h),
        path: a.path.concat(),
    }
}

/// The answer's trajectory as a recorded `trajectory_msgs/msg/JointTrajectory` (stamped with
/// its request's receive time), when it has one with samples.
pub fn trajectory_message(
    recv_ns: u64,
    robot: &Robot,
    a: &Answer,
) -> Option<ember_sdk::recording::JointTrajectory> {
    let block = a.trajectory.as_ref().filter(|b| !b.times.is_empty())?;
    let names = robot.variables().iter().map(|v| v.name.clone()).collect();
    Some(ember_sdk::recording::JointTrajectory::from_block(
        recv_ns, names, block,
    ))
}
