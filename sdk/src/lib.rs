//! Ember's SDK: the wire protocol spoken with `emberd` over iceoryx2 shared memory, and a client.
//!
//! - [`wire`]: `#[repr(C)]` payloads, one file per service, each carrying [`wire::PROTOCOL_VERSION`];
//! - [`names`]: service names per daemon instance;
//! - [`status`]: the numbered status codes of plan replies (codes never change);
//! - [`services`]: the service definitions shared by daemon and clients;
//! - [`recording`]: the message types and schemas of session recordings (MCAP, ROS 2 CDR);
//! - [`session`]: reading recorded sessions (and ROS 2 bags through a topic map) as typed events;
//! - [`monitor`]: what the daemon publishes over Zenoh (keys, JSON documents, map snapshot);
//! - [`launch`]: starting a daemon process and reading its readiness line;
//! - [`stats`]: latency quantiles as the status, demo and benchmarks report them;
//! - [`client`]: connect, publish clouds (written straight into shared memory), objects and joint
//!   states, plan with a timeout.
#![warn(missing_docs)]

pub mod client;
pub mod launch;
pub mod monitor;
pub mod names;
pub mod recording;
pub mod services;
pub mod session;
pub mod stats;
pub mod status;
pub mod wire;

pub use client::{Client, ClientError, PlanCall, PlanReply};
pub use status::Status;
