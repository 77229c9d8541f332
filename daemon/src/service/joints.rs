//! The joint-state service: the robot's measured joint positions (planning-group order).

use super::drops::Gaps;
use super::rejection::Rejection;
use ember_engine::robot::Robot;
use ember_sdk::services::{self, Limits, Open};
use ember_sdk::wire::JointState;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

/// A decoded joint state.
pub struct JointsInput {
    /// Sender's stamp, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// Positions in planning-group order, within the limits.
    pub positions: Vec<f64>,
}

/// The joint states port.
pub struct JointsPort(Subscriber<ipc::Service, JointState, ()>);

impl JointsPort {
    /// Subscribes to the instance's joint states.
    pub fn open(node: &Node<ipc::Service>, instance: &str, limits: Limits) -> anyhow::Result<Self> {
        let sub = services::joints(node, instance, Open::Serve(limits))
            .map_err(anyhow::Error::msg)?
            .subscriber_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("joint state subscriber: {e:?}"))?;
        Ok(JointsPort(sub))
    }

    /// The next waiting joint state, decoded for `robot`; None when none waits. `gaps` counts
    /// the states its publisher sent that never arrived.
    pub fn receive(
        &self,
        robot: &Robot,
        gaps: &mut Gaps,
    ) -> Option<(u64, Result<JointsInput, Rejection>)> {
        let s = self.0.receive().ok().flatten()?;
        let dropped = gaps.saw(s.header().publisher_id().value(), s.payload().seq);
        Some((dropped, decode(s.payload(), robot)))
    }
}

/// Decodes a joint state for `robot`.
pub fn decode(js: &JointState, robot: &Robot) -> Result<JointsInput, Rejection> {
    Rejection::check_version("joint state", js.version)?;
    let dof = robot.dof();
    Rejection::check_dof("joint state", js.count, dof)?;
    let positions = js.positions[..dof].to_vec();
    robot.validate(&positions).map_err(Rejection::JointState)?;
    Ok(JointsInput {
        stamp_ns: js.stamp_ns,
        positions,
    })
}
