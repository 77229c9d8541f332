//! The status service: the daemon's counters on request, converted from the same document the
//! monitor publishes.

use crate::monitor::docs::Sources;
use ember_sdk::services::{self, Limits, Open};
use ember_sdk::wire::StatusReply;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use tracing::warn;

/// The status port.
pub struct StatusPort(Server<ipc::Service, u64, (), StatusReply, ()>);

impl StatusPort {
    /// Serves the instance's status requests.
    pub fn open(node: &Node<ipc::Service>, instance: &str, limits: Limits) -> anyhow::Result<Self> {
        let server = services::status(node, instance, Open::Serve(limits))
            .map_err(anyhow::Error::msg)?
            .server_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("status service: {e:?}"))?;
        Ok(StatusPort(server))
    }

    /// Answers every waiting request with the current counters.
    pub fn serve(&self, sources: &Sources) {
        while let Ok(Some(active)) = self.0.receive() {
            let reply = StatusReply::from(&sources.status(false));
            if let Err(e) = active.send_copy(reply) {
                warn!("sending status failed: {e:?}");
            }
        }
    }
}
