//! The cancel service: cancels the plans in flight that carry a request id. Answered on the
//! service thread, so it works while every worker is busy.

use crate::service::plan::in_flight::InFlight;
use ember_sdk::services::{self, Limits, Open};
use ember_sdk::wire::{CancelReply, CancelRequest, PROTOCOL_VERSION};
use ember_sdk::Status;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use tracing::{info, warn};

/// The cancel port.
pub struct CancelPort(Server<ipc::Service, CancelRequest, (), CancelReply, ()>);

impl CancelPort {
    /// Serves the instance's cancel requests.
    pub fn open(node: &Node<ipc::Service>, instance: &str, limits: Limits) -> anyhow::Result<Self> {
        let server = services::cancel(node, instance, Open::Serve(limits))
            .map_err(anyhow::Error::msg)?
            .server_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("cancel service: {e:?}"))?;
        Ok(CancelPort(server))
    }

    /// Answers every waiting request: how many plans in flight it cancelled.
    pub fn serve(&self, in_flight: &InFlight) {
        while let Ok(Some(active)) = self.0.receive() {
            let request = *active.payload();
            let reply = match request.version == PROTOCOL_VERSION {
                true => {
                    let n = in_flight.cancel_request(request.request_id);
                    info!("cancel request {}: {n} plan(s)", request.request_id);
                    CancelReply {
                        version: PROTOCOL_VERSION,
                        status: Status::Ok as u32,
                        cancelled: n as u32,
                    }
                }
                false => CancelReply {
                    version: PROTOCOL_VERSION,
                    status: Status::VersionMismatch as u32,
                    cancelled: 0,
                },
            };
            if let Err(e) = active.send_copy(reply) {
                warn!("sending a cancel reply failed: {e:?}");
            }
        }
    }
}
