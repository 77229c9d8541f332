//! `ember/<instance>/joints`: the robot's joint state (planning-group order), publish-subscribe.

use iceoryx2::prelude::*;

/// Most joints a joint state carries.
pub const MAX_JOINTS: usize = 16;

/// Planning-group joint positions.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("EmberJointState")]
#[repr(C)]
pub struct JointState {
    /// [`super::PROTOCOL_VERSION`].
    pub version: u32,
    /// Number of valid entries in `positions` (must equal the group's DOF).
    pub count: u32,
    /// Measurement time, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// Positions, radians or metres, group order.
    pub positions: [f64; MAX_JOINTS],
    /// The publisher's message number, counting from 1 (0: not numbered); the daemon counts
    /// the numbers it never saw as dropped.
    pub seq: u64,
}
