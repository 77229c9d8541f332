//! The service definitions, shared by the daemon and clients so both open them with identical
//! settings. Sizes are deliberate: the cloud service reserves shared memory for a few 640×480
//! clouds, not iceoryx2's generous defaults.

use crate::names::service;
use crate::wire::plan::MAX_PLAN_VALUES;
use crate::wire::{
    CloudHeader, JointState, ObjectUpdate, PlanRequestHeader, PlanResponseHeader, Point,
    StatusReply,
};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{publish_subscribe, request_response};

/// Opens (or creates) the cloud service of `instance`.
pub fn cloud(
    node: &Node<ipc::Service>,
    instance: &str,
) -> Result<publish_subscribe::PortFactory<ipc::Service, [Point], CloudHeader>, String> {
    let name = ServiceName::new(&service(instance, "cloud")).map_err(|e| format!("{e:?}"))?;
    node.service_builder(&name)
        .publish_subscribe::<[Point]>()
        .user_header::<CloudHeader>()
        .max_publishers(2)
        .max_subscribers(2)
        .subscriber_max_buffer_size(2)
        .history_size(0)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| format!("cloud service: {e:?}"))
}

/// Opens (or creates) the object service of `instance`.
pub fn objects(
    node: &Node<ipc::Service>,
    instance: &str,
) -> Result<publish_subscribe::PortFactory<ipc::Service, ObjectUpdate, ()>, String> {
    let name = ServiceName::new(&service(instance, "objects")).map_err(|e| format!("{e:?}"))?;
    node.service_builder(&name)
        .publish_subscribe::<ObjectUpdate>()
        .max_publishers(8)
        .max_subscribers(4)
        .subscriber_max_buffer_size(256)
        .history_size(0)
        .open_or_create()
        .map_err(|e| format!("object service: {e:?}"))
}

/// Opens (or creates) the joint-state service of `instance`.
pub fn joints(
    node: &Node<ipc::Service>,
    instance: &str,
) -> Result<publish_subscribe::PortFactory<ipc::Service, JointState, ()>, String> {
    let name = ServiceName::new(&service(instance, "joints")).map_err(|e| format!("{e:?}"))?;
    node.service_builder(&name)
        .publish_subscribe::<JointState>()
        .max_publishers(4)
        .max_subscribers(4)
        .subscriber_max_buffer_size(16)
        .history_size(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| format!("joint service: {e:?}"))
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
pub fn plan(node: &Node<ipc::Service>, instance: &str) -> Result<PlanService, String> {
    let name = ServiceName::new(&service(instance, "plan")).map_err(|e| format!("{e:?}"))?;
    let _ = MAX_PLAN_VALUES;
    node.service_builder(&name)
        .request_response::<[f64], [f64]>()
        .request_user_header::<PlanRequestHeader>()
        .response_user_header::<PlanResponseHeader>()
        .max_clients(16)
        .max_servers(1)
        .max_active_requests_per_client(2)
        .max_response_buffer_size(2)
        .open_or_create()
        .map_err(|e| format!("plan service: {e:?}"))
}

/// The status service type.
pub type StatusService = request_response::PortFactory<ipc::Service, u64, (), StatusReply, ()>;

/// Opens (or creates) the status service of `instance`.
pub fn status(node: &Node<ipc::Service>, instance: &str) -> Result<StatusService, String> {
    let name = ServiceName::new(&service(instance, "status")).map_err(|e| format!("{e:?}"))?;
    node.service_builder(&name)
        .request_response::<u64, StatusReply>()
        .max_clients(16)
        .max_servers(1)
        .open_or_create()
        .map_err(|e| format!("status service: {e:?}"))
}
