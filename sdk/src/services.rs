//! The service definitions, shared by the daemon and clients so both open them with identical
//! settings. Sizes are deliberate: the cloud service reserves shared memory for a few 640×480
//! clouds, not iceoryx2's generous defaults.
//!
//! The daemon creates every service ([`Open::Serve`]) with its configured [`Limits`]: how many
//! clients, publishers and subscribers may attach. Clients attach to what the daemon created
//! ([`Open::Attach`]) and never create a service, so a client started before its daemon is told
//! that no daemon serves the instance.

use crate::names::service;
use crate::wire::plan::MAX_PLAN_VALUES;
use crate::wire::{
    CancelReply, CancelRequest, CloudHeader, JointState, ObjectUpdate, PlanRequestHeader,
    PlanResponseHeader, Point, StatusReply,
};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{publish_subscribe, request_response};

/// How many ports of each kind a daemon's services admit (fixed when the daemon creates them;
/// emberd's `[limits]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Clients of the plan and status services (each `Client` is one of each).
    pub clients: usize,
    /// Publishers of the cloud, object and joint-state services (each `Client` is one of each).
    pub publishers: usize,
    /// Subscribers of the cloud, object and joint-state services (the daemon is one).
    pub subscribers: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            clients: 16,
            publishers: 16,
            subscribers: 2,
        }
    }
}

/// Who opens a service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Open {
    /// The daemon: opens or creates the service with these limits.
    Serve(Limits),
    /// A client: attaches to the service the daemon created (an error when there is none).
    Attach,
}

/// Opens a publish-subscribe service `b` as `open` says.
macro_rules! open_pub_sub {
    ($b:expr, $open:expr, $what:literal) => {
        match $open {
            Open::Serve(l) => $b
                .max_publishers(l.publishers)
                .max_subscribers(l.subscribers)
                .open_or_create()
                .map_err(|e| format!(concat!($what, " service: {:?}"), e)),
            Open::Attach => $b
                .open()
                .map_err(|e| format!(concat!($what, " service: {:?}"), e)),
        }
    };
}

/// Opens a request-response service `b` as `open` says.
macro_rules! open_req_res {
    ($b:expr, $open:expr, $what:literal) => {
        match $open {
            Open::Serve(l) => $b
                .max_clients(l.clients)
                .max_servers(1)
                .open_or_create()
                .map_err(|e| format!(concat!($what, " service: {:?}"), e)),
            Open::Attach => $b
                .open()
                .map_err(|e| format!(concat!($what, " service: {:?}"), e)),
        }
    };
}

/// Opens (or creates) the cloud service of `instance`.
pub fn cloud(
    node: &Node<ipc::Service>,
    instance: &str,
    open: Open,
) -> Result<publish_subscribe::PortFactory<ipc::Service, [Point], CloudHeader>, String> {
    let name = ServiceName::new(&service(instance, "cloud")).map_err(|e| format!("{e:?}"))?;
    let b = node
        .service_builder(&name)
        .publish_subscribe::<[Point]>()
        .user_header::<CloudHeader>()
        .subscriber_max_buffer_size(2)
        .history_size(0)
        .enable_safe_overflow(true);
    open_pub_sub!(b, open, "cloud")
}

/// Opens (or creates) the object service of `instance`.
pub fn objects(
    node: &Node<ipc::Service>,
    instance: &str,
    open: Open,
) -> Result<publish_subscribe::PortFactory<ipc::Service, ObjectUpdate, ()>, String> {
    let name = ServiceName::new(&service(instance, "objects")).map_err(|e| format!("{e:?}"))?;
    let b = node
        .service_builder(&name)
        .publish_subscribe::<ObjectUpdate>()
        .subscriber_max_buffer_size(256)
        .history_size(0);
    open_pub_sub!(b, open, "object")
}

/// Opens (or creates) the joint-state service of `instance`.
pub fn joints(
    node: &Node<ipc::Service>,
    instance: &str,
    open: Open,
) -> Result<publish_subscribe::PortFactory<ipc::Service, JointState, ()>, String> {
    let name = ServiceName::new(&service(instance, "joints")).map_err(|e| format!("{e:?}"))?;
    let b = node
        .service_builder(&name)
        .publish_subscribe::<JointState>()
        .subscriber_max_buffer_size(16)
        .history_size(1)
        .enable_safe_overflow(true);
    open_pub_sub!(b, open, "joint")
}

/// The plan service type.
pub type PlanService = request_response::PortFactory<
    ipc::Service,
    [f64],
    PlanRequestHeader,
    [f64],
    PlanResponseHeader,
>;

/// Opens (or creates) the plan service of `instance`.
pub fn plan(node: &Node<ipc::Service>, instance: &str, open: Open) -> Result<PlanService, String> {
    let name = ServiceName::new(&service(instance, "plan")).map_err(|e| format!("{e:?}"))?;
    let _ = MAX_PLAN_VALUES;
    let b = node
        .service_builder(&name)
        .request_response::<[f64], [f64]>()
        .request_user_header::<PlanRequestHeader>()
        .response_user_header::<PlanResponseHeader>()
        .max_active_requests_per_client(2)
        .max_response_buffer_size(2);
    open_req_res!(b, open, "plan")
}

/// The status service type.
pub type StatusService = request_response::PortFactory<ipc::Service, u64, (), StatusReply, ()>;

/// Opens (or creates) the status service of `instance`.
pub fn status(
    node: &Node<ipc::Service>,
    instance: &str,
    open: Open,
) -> Result<StatusService, String> {
    let name = ServiceName::new(&service(instance, "status")).map_err(|e| format!("{e:?}"))?;
    let b = node
        .service_builder(&name)
        .request_response::<u64, StatusReply>();
    open_req_res!(b, open, "status")
}

/// The cancel service type.
pub type CancelService =
    request_response::PortFactory<ipc::Service, CancelRequest, (), CancelReply, ()>;

/// Opens (or creates) the cancel service of `instance`.
pub fn cancel(
    node: &Node<ipc::Service>,
    instance: &str,
    open: Open,
) -> Result<CancelService, String> {
    let name = ServiceName::new(&service(instance, "cancel")).map_err(|e| format!("{e:?}"))?;
    let b = node
        .service_builder(&name)
        .request_response::<CancelRequest, CancelReply>();
    open_req_res!(b, open, "cancel")
}

/// The daemon threads a notification wakes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// Ingest: a cloud, object update or joint state was published
    /// (`ember/<instance>/inputs_ready`).
    Inputs,
    /// The service thread: a plan, status or cancel request was sent
    /// (`ember/<instance>/requests_ready`).
    Requests,
}

/// The event service type.
pub type WakeService = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

/// Opens (or creates) one of the event services that wake the daemon instead of polling:
/// clients notify after they publish or send (a client that does not is still served, within
/// the daemon's fallback wait of 10 ms).
pub fn wake(
    node: &Node<ipc::Service>,
    instance: &str,
    which: Wake,
    open: Open,
) -> Result<WakeService, String> {
    let kind = match which {
        Wake::Inputs => "inputs_ready",
        Wake::Requests => "requests_ready",
    };
    let name = ServiceName::new(&service(instance, kind)).map_err(|e| format!("{e:?}"))?;
    let b = node.service_builder(&name).event();
    match open {
        // Every client is one notifier of each; the daemon's planning workers notify too.
        Open::Serve(l) => b
            .max_notifiers(l.clients.max(l.publishers) + 64)
            .max_listeners(2)
            .open_or_create()
            .map_err(|e| format!("{kind} service: {e:?}")),
        Open::Attach => b.open().map_err(|e| format!("{kind} service: {e:?}")),
    }
}
