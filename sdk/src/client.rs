//! The client: what a robot stack links to talk to `emberd`.

use crate::services::{self, Open, Wake};
use crate::status::Status;
use crate::wire::plan::MAX_PLAN_VALUES;
use crate::wire::{
    self, CancelReply, CancelRequest, CloudHeader, GoalKind, JointState, Method, ObjectUpdate,
    PlanRequestHeader, PlanResponseHeader, Point, ShapeKind, MAX_CLOUD_POINTS, MAX_JOINTS,
    PROTOCOL_VERSION,
};
use iceoryx2::pending_response::PendingResponse;
use iceoryx2::port::client::Client as RrClient;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::prelude::*;
use std::cell::Cell;
use std::time::{Duration, Instant, SystemTime};
use thiserror::Error;

/// Why a client call failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ClientError {
    /// The instance name is not usable.
    #[error("invalid instance name '{0}' (letters, digits, '-' and '_', 1-64 characters)")]
    InvalidInstance(String),
    /// iceoryx2 refused an operation; the sentence says which.
    #[error("shared-memory transport: {0}")]
    Transport(String),
    /// No daemon serves this instance.
    #[error("no daemon serves instance '{0}'")]
    NoDaemon(String),
    /// The daemon serves, but a service has all its ports of one kind taken.
    #[error(
        "the daemon's {service} service admits {max} {kind} and all are taken (emberd's `limits.{kind}` sets how many)"
    )]
    LimitReached {
        /// Service name (`cloud`, `plan`, ...).
        service: &'static str,
        /// `publishers` or `clients`.
        kind: &'static str,
        /// How many the service admits.
        max: usize,
    },
    /// The daemon did not answer in time.
    #[error("no reply within {0:?}")]
    Timeout(Duration),
    /// The input does not fit the protocol (too many points or joints, wrong lengths).
    #[error("invalid input: {0}")]
    InvalidInput(String),
}

fn transport(e: impl std::fmt::Debug) -> ClientError {
    ClientError::Transport(format!("{e:?}"))
}

/// Why a port could not attach to a service: `LimitReached` when the service has all its
/// `kind` taken (iceoryx2's `ExceedsMaxSupported...`), otherwise the transport's reason.
fn attach_error(
    e: impl std::fmt::Debug,
    service: &'static str,
    kind: &'static str,
    max: usize,
) -> ClientError {
    let reason = format!("{e:?}");
    match reason.starts_with("ExceedsMaxSupported") {
        true => ClientError::LimitReached { service, kind, max },
        false => ClientError::Transport(reason),
    }
}

/// Nanoseconds since the Unix epoch.
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// A plan request.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanCall {
    /// Start configuration.
    pub start: Vec<f64>,
    /// Goal configurations (joint goal); empty with `pose`.
    pub goals: Vec<Vec<f64>>,
    /// Pose goal for the tip link (x, y, z, qx, qy, qz, qw) with position and orientation
    /// tolerances.
    pub pose: Option<([f64; 7], f64, f64)>,
    /// Sampling method.
    pub method: Method,
    /// Time limit, seconds.
    pub time_limit_s: f64,
    /// Seed.
    pub seed: u64,
    /// Ask for the path timed under the robot's limits: velocity and acceleration scaling
    /// factors in (0, 1], 0 for the daemon's ([`wire::FLAG_TRAJECTORY`]).
    pub trajectory: Option<(f64, f64)>,
}

/// The daemon's answer.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanReply {
    /// Outcome (unknown codes map to `Internal`).
    pub status: Status,
    /// Waypoints.
    pub path: Vec<Vec<f64>>,
    /// The header as received (timings, counts, message).
    pub header: PlanResponseHeader,
    /// The timed trajectory, when asked for and solved (`samples` empty when the daemon could
    /// not time the path; the message says why).
    pub trajectory: Option<wire::TrajectoryBlock>,
}

impl PlanReply {
    /// The daemon's sentence about the outcome.
    pub fn message(&self) -> String {
        wire::name_str(&self.header.message)
    }
}

/// A connection to one daemon instance.
pub struct Client {
    node: Node<ipc::Service>,
    instance: String,
    cloud: Publisher<ipc::Service, [Point], CloudHeader>,
    objects: Publisher<ipc::Service, ObjectUpdate, ()>,
    joints: Publisher<ipc::Service, JointState, ()>,
    plan: RrClient<ipc::Service, [f64], PlanRequestHeader, [f64], PlanResponseHeader>,
    status: RrClient<ipc::Service, u64, (), wire::StatusReply, ()>,
    cancel: RrClient<ipc::Service, CancelRequest, (), CancelReply, ()>,
    /// Wake the daemon's ingest thread and service thread after publishing or sending.
    wake_inputs: Notifier<ipc::Service>,
    wake_requests: Notifier<ipc::Service>,
    /// The last message number per input kind (cloud, object, joints).
    seq: [Cell<u64>; 3],
    /// The last request id handed out.
    last_request_id: Cell<u64>,
}

/// A plan request sent and not yet answered ([`Client::submit`]).
pub struct PendingPlan {
    pending: PendingResponse<ipc::Service, [f64], PlanRequestHeader, [f64], PlanResponseHeader>,
    header: PlanRequestHeader,
}

impl PendingPlan {
    /// The id the request carries: pass it to [`Client::cancel`] to cancel the plan.
    pub fn request_id(&self) -> u64 {
        self.header.request_id
    }

    /// The reply, if it has arrived.
    pub fn try_receive(&self) -> Result<Option<PlanReply>, ClientError> {
        let Some(response) = self.pending.receive().map_err(transport)? else {
            return Ok(None);
        };
        let h = *response.user_header();
        let data = response.payload();
        let (dof, waypoints) = (h.dof as usize, h.waypoints as usize);
        let path_values = (dof * waypoints).min(data.len());
        let path = if dof == 0 {
            Vec::new()
        } else {
            data[..path_values]
                .chunks_exact(dof)
                .map(<[f64]>::to_vec)
                .collect()
        };
        let trajectory =
            if self.header.flags & wire::FLAG_TRAJECTORY != 0 && data.len() > path_values {
                Some(
                    wire::TrajectoryBlock::decode(&data[path_values..], dof, waypoints)
                        .map_err(|e| ClientError::Transport(format!("malformed reply: {e}")))?,
                )
            } else {
                None
            };
        Ok(Some(PlanReply {
            status: Status::from_code(h.status).unwrap_or(Status::Internal),
            path,
            header: h,
            trajectory,
        }))
    }

    /// Waits at most `timeout` for the reply.
    pub fn wait(&self, timeout: Duration) -> Result<PlanReply, ClientError> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(reply) = self.try_receive()? {
                return Ok(reply);
            }
            if Instant::now() >= deadline {
                return Err(ClientError::Timeout(timeout));
            }
            // The caller is blocked on this reply anyway: give the core away without sleeping,
            // so the reply is seen within microseconds.
            std::thread::yield_now();
        }
    }
}

/// A request id base unlikely to repeat across clients: the process, the time and the
/// client's address mixed (splitmix64); ids count up from it and are never 0.
fn request_id_base(salt: usize) -> u64 {
    let mut z = now_ns() ^ ((std::process::id() as u64) << 40) ^ (salt as u64).rotate_left(17);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    (z ^ (z >> 31)) & !0xffff
}

impl Client {
    /// Connects to the daemon serving `instance`. Fails with `NoDaemon` when no daemon serves it.
    pub fn connect(instance: &str) -> Result<Client, ClientError> {
        if !crate::names::valid_instance(instance) {
            return Err(ClientError::InvalidInstance(instance.into()));
        }
        set_log_level(LogLevel::Error);
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(transport)?;
        let no_daemon = |e: String| match e.contains("DoesNotExist") {
            true => ClientError::NoDaemon(instance.into()),
            false => ClientError::Transport(e),
        };
        let plan_service = services::plan(&node, instance, Open::Attach).map_err(no_daemon)?;
        if plan_service.dynamic_config().number_of_servers() == 0 {
            return Err(ClientError::NoDaemon(instance.into()));
        }
        let cloud = services::cloud(&node, instance, Open::Attach).map_err(no_daemon)?;
        let max = cloud.static_config().max_publishers();
        let cloud = cloud
            .publisher_builder()
            .initial_max_slice_len(MAX_CLOUD_POINTS)
            .create()
            .map_err(|e| attach_error(e, "cloud", "publishers", max))?;
        let objects = services::objects(&node, instance, Open::Attach).map_err(no_daemon)?;
        let max = objects.static_config().max_publishers();
        let objects = objects
            .publisher_builder()
            .create()
            .map_err(|e| attach_error(e, "object", "publishers", max))?;
        let joints = services::joints(&node, instance, Open::Attach).map_err(no_daemon)?;
        let max = joints.static_config().max_publishers();
        let joints = joints
            .publisher_builder()
            .create()
            .map_err(|e| attach_error(e, "joint-state", "publishers", max))?;
        let max = plan_service.static_config().max_clients();
        let plan = plan_service
            .client_builder()
            .initial_max_slice_len(16 * 64)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(|e| attach_error(e, "plan", "clients", max))?;
        let status = services::status(&node, instance, Open::Attach).map_err(no_daemon)?;
        let max = status.static_config().max_clients();
        let status = status
            .client_builder()
            .create()
            .map_err(|e| attach_error(e, "status", "clients", max))?;
        let cancel = services::cancel(&node, instance, Open::Attach).map_err(no_daemon)?;
        let max = cancel.static_config().max_clients();
        let cancel = cancel
            .client_builder()
            .create()
            .map_err(|e| attach_error(e, "cancel", "clients", max))?;
        let notifier = |which| {
            let wake = services::wake(&node, instance, which, Open::Attach).map_err(no_daemon)?;
            let max = wake.static_config().max_notifiers();
            wake.notifier_builder()
                .create()
                .map_err(|e| attach_error(e, "wake", "clients", max))
        };
        let (wake_inputs, wake_requests) = (notifier(Wake::Inputs)?, notifier(Wake::Requests)?);
        let base = request_id_base(&node as *const _ as usize);
        Ok(Client {
            node,
            instance: instance.into(),
            cloud,
            objects,
            joints,
            plan,
            status,
            cancel,
            wake_inputs,
            wake_requests,
            seq: Default::default(),
            last_request_id: Cell::new(base),
        })
    }

    /// The instance connected to.
    pub fn instance(&self) -> &str {
        &self.instance
    }

    /// Wakes the daemon thread that serves what was just sent. Best effort: the daemon also
    /// looks on its own every 10 ms.
    fn wake(&self, which: Wake) {
        let notifier = match which {
            Wake::Inputs => &self.wake_inputs,
            Wake::Requests => &self.wake_requests,
        };
        let _ = notifier.notify();
    }

    /// The next message number of input kind `kind` (0 cloud, 1 object, 2 joints).
    fn next_seq(&self, kind: usize) -> u64 {
        let n = self.seq[kind].get() + 1;
        self.seq[kind].set(n);
        n
    }

    /// Publishes a cloud of `count` points, written by `fill` straight into shared memory.
    /// `stamp_ns` 0 stamps the cloud at the moment it is handed over.
    pub fn publish_cloud(
        &self,
        frame_id: &str,
        sensor_pose: [f64; 7],
        stamp_ns: u64,
        count: usize,
        mut fill: impl FnMut(usize) -> Point,
    ) -> Result<(), ClientError> {
        if count > MAX_CLOUD_POINTS {
            return Err(ClientError::InvalidInput(format!(
                "{count} points, the cloud service carries at most {MAX_CLOUD_POINTS}"
            )));
        }
        let sample = self.cloud.loan_slice_uninit(count).map_err(transport)?;
        let mut sample = sample.write_from_fn(&mut fill);
        // The header last, so the stamp (when `stamp_ns` is 0) marks the hand-off itself.
        *sample.user_header_mut() = CloudHeader {
            version: PROTOCOL_VERSION,
            point_count: count as u32,
            stamp_ns: if stamp_ns == 0 { now_ns() } else { stamp_ns },
            frame_id: wire::name(frame_id),
            sensor_pose,
            seq: self.next_seq(0),
        };
        sample.send().map_err(transport)?;
        self.wake(Wake::Inputs);
        Ok(())
    }

    /// Publishes one object (add or move) in the base frame.
    pub fn publish_object(
        &self,
        id: &str,
        shape: ShapeKind,
        dims: [f64; 3],
        pose: [f64; 7],
    ) -> Result<(), ClientError> {
        self.send_object(id, shape, dims, pose, "")
    }

    /// Tells the daemon the robot holds the tracked object `id` on `link`, at `grasp` in the
    /// link's frame: it leaves the world and moves with the robot (in planning, and in the
    /// map's self-filter) until [`Client::detach`]. A refusal (unknown object or link, already
    /// held, touching the robot at the current joint state) is counted in the status reply
    /// with its reason ([`wire::StatusReply::last_rejection`]).
    pub fn attach(&self, id: &str, link: &str, grasp: [f64; 7]) -> Result<(), ClientError> {
        self.send_object(id, ShapeKind::Tracked, [0.0; 3], grasp, link)
    }

    /// As [`Client::attach`], for an object given by its shape (replacing a tracked object of
    /// the same id, if any).
    pub fn attach_shape(
        &self,
        id: &str,
        link: &str,
        shape: ShapeKind,
        dims: [f64; 3],
        grasp: [f64; 7],
    ) -> Result<(), ClientError> {
        self.send_object(id, shape, dims, grasp, link)
    }

    /// Tells the daemon the robot let go of `id`: it is a world object again, at `pose` in the
    /// base frame.
    pub fn detach(&self, id: &str, pose: [f64; 7]) -> Result<(), ClientError> {
        self.send_object(id, ShapeKind::Tracked, [0.0; 3], pose, "")
    }

    fn send_object(
        &self,
        id: &str,
        shape: ShapeKind,
        dims: [f64; 3],
        pose: [f64; 7],
        link: &str,
    ) -> Result<(), ClientError> {
        let update = ObjectUpdate {
            version: PROTOCOL_VERSION,
            shape: shape as u32,
            stamp_ns: now_ns(),
            id: wire::name(id),
            dims,
            pose,
            seq: self.next_seq(1),
            link: wire::name(link),
        };
        self.objects.send_copy(update).map_err(transport)?;
        self.wake(Wake::Inputs);
        Ok(())
    }

    /// Publishes a raw object update (for tools and tests that send exactly what they choose).
    pub fn publish_object_raw(&self, update: ObjectUpdate) -> Result<(), ClientError> {
        self.objects.send_copy(update).map_err(transport)?;
        self.wake(Wake::Inputs);
        Ok(())
    }

    /// Publishes the robot's planning-group joint positions.
    pub fn publish_joints(&self, positions: &[f64]) -> Result<(), ClientError> {
        if positions.len() > MAX_JOINTS {
            return Err(ClientError::InvalidInput(format!(
                "{} joints, at most {MAX_JOINTS}",
                positions.len()
            )));
        }
        let mut js = JointState {
            version: PROTOCOL_VERSION,
            count: positions.len() as u32,
            stamp_ns: now_ns(),
            positions: [0.0; MAX_JOINTS],
            seq: self.next_seq(2),
        };
        js.positions[..positions.len()].copy_from_slice(positions);
        self.joints.send_copy(js).map_err(transport)?;
        self.wake(Wake::Inputs);
        Ok(())
    }

    /// Plans; waits at most `timeout` for the reply.
    pub fn plan(&self, call: &PlanCall, timeout: Duration) -> Result<PlanReply, ClientError> {
        self.submit(call, 0)?.wait(timeout)
    }

    /// Plans with request flags ([`wire::FLAG_NO_LEARN`]).
    pub fn plan_with_flags(
        &self,
        call: &PlanCall,
        flags: u32,
        timeout: Duration,
    ) -> Result<PlanReply, ClientError> {
        self.submit(call, flags)?.wait(timeout)
    }

    /// Sends a plan request with `flags` and returns at once: wait for the reply on the
    /// [`PendingPlan`], or cancel it with [`Client::cancel`] and its request id.
    pub fn submit(&self, call: &PlanCall, flags: u32) -> Result<PendingPlan, ClientError> {
        let dof = call.start.len();
        let (kind, pose, pt, ot) = match call.pose {
            Some((p, pt, ot)) => (GoalKind::Pose, p, pt, ot),
            None => (
                GoalKind::Joints,
                [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
                0.0,
                0.0,
            ),
        };
        let flags = if call.trajectory.is_some() {
            flags | wire::FLAG_TRAJECTORY
        } else {
            flags
        };
        let request_id = self.last_request_id.get().wrapping_add(1).max(1);
        self.last_request_id.set(request_id);
        let header = PlanRequestHeader {
            version: PROTOCOL_VERSION,
            dof: dof as u32,
            goal_kind: kind as u32,
            goal_count: call.goals.len() as u32,
            method: call.method as u32,
            flags,
            time_limit_s: call.time_limit_s,
            seed: call.seed,
            pose,
            position_tolerance: pt,
            orientation_tolerance: ot,
            request_id,
        };
        let mut values = call.start.clone();
        for g in &call.goals {
            values.extend_from_slice(g);
        }
        if let Some((v, a)) = call.trajectory {
            values.extend_from_slice(&[v, a]);
        }
        self.submit_raw(header, &values)
    }

    /// Cancels the plans in flight whose request carried `request_id` (they are answered
    /// `cancelled`); returns how many there were (0: none, e.g. already answered). Waits at
    /// most `timeout` for the daemon's answer.
    pub fn cancel(&self, request_id: u64, timeout: Duration) -> Result<u32, ClientError> {
        let pending = self
            .cancel
            .send_copy(CancelRequest {
                version: PROTOCOL_VERSION,
                reserved: 0,
                request_id,
            })
            .map_err(transport)?;
        self.wake(Wake::Requests);
        let r = self.reply_within(timeout, || {
            Ok(pending.receive().map_err(transport)?.map(|r| *r.payload()))
        })?;
        match Status::from_code(r.status) {
            Some(Status::Ok) => Ok(r.cancelled),
            _ => Err(ClientError::Transport(format!(
                "the daemon refused the cancel request (status {}, protocol version {})",
                r.status, r.version
            ))),
        }
    }

    /// The daemon's counters and latencies.
    pub fn status(&self, timeout: Duration) -> Result<wire::StatusReply, ClientError> {
        let pending = self.status.send_copy(0).map_err(transport)?;
        self.wake(Wake::Requests);
        self.reply_within(timeout, || {
            Ok(pending.receive().map_err(transport)?.map(|r| *r.payload()))
        })
    }

    /// Polls `receive` (every 50 µs) until it gives a reply or `timeout` passes.
    fn reply_within<T>(
        &self,
        timeout: Duration,
        mut receive: impl FnMut() -> Result<Option<T>, ClientError>,
    ) -> Result<T, ClientError> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(r) = receive()? {
                return Ok(r);
            }
            if Instant::now() >= deadline {
                return Err(ClientError::Timeout(timeout));
            }
            if self.node.wait(Duration::from_micros(50)).is_err() {
                return Err(ClientError::Transport("interrupted".into()));
            }
        }
    }

    /// Sends a request exactly as given (header and payload unchecked) and waits for the reply.
    pub fn plan_raw(
        &self,
        header: PlanRequestHeader,
        values: &[f64],
        timeout: Duration,
    ) -> Result<PlanReply, ClientError> {
        self.submit_raw(header, values)?.wait(timeout)
    }

    /// Sends a request exactly as given and returns at once.
    pub fn submit_raw(
        &self,
        header: PlanRequestHeader,
        values: &[f64],
    ) -> Result<PendingPlan, ClientError> {
        if values.len() > MAX_PLAN_VALUES {
            return Err(ClientError::InvalidInput(format!(
                "{} values, at most {MAX_PLAN_VALUES}",
                values.len()
            )));
        }
        let mut request = self
            .plan
            .loan_slice_uninit(values.len())
            .map_err(transport)?;
        *request.user_header_mut() = header;
        let request = request.write_from_slice(values);
        let pending = request.send().map_err(transport)?;
        self.wake(Wake::Requests);
        Ok(PendingPlan { pending, header })
    }
}
