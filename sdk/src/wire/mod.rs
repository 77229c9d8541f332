//! Wire payloads, one file per service. All are `#[repr(C)]`, carry the protocol version first,
//! and use metres, seconds (nanosecond stamps since the Unix epoch), the robot base frame and
//! quaternions `[x, y, z, w]`. Poses are `[x, y, z, qx, qy, qz, qw]`.

pub mod cancel;
pub mod cloud;
pub mod joints;
pub mod objects;
pub mod plan;
pub mod status;

pub use cancel::{CancelReply, CancelRequest};
pub use cloud::{CloudHeader, Point, MAX_CLOUD_POINTS};
pub use joints::{JointState, MAX_JOINTS};
pub use objects::{ObjectUpdate, ShapeKind};
pub use plan::{
    GoalKind, Method, PlanRequestHeader, PlanResponseHeader, TrajectoryBlock, FLAG_NO_LEARN,
    FLAG_TRAJECTORY, KNOWN_FLAGS,
};
pub use status::StatusReply;

/// Version of the protocol these types define.
pub const PROTOCOL_VERSION: u32 = 3;

/// A fixed-size, NUL-padded UTF-8 string.
pub type Name = [u8; 32];

/// Packs `s` into a [`Name`] (cut at 32 bytes).
pub fn name(s: &str) -> Name {
    let mut n = [0u8; 32];
    let b = s.as_bytes();
    let len = b.len().min(32);
    n[..len].copy_from_slice(&b[..len]);
    n
}

/// The text of a [`Name`] (up to the first NUL; invalid UTF-8 replaced).
pub fn name_str(n: &[u8]) -> String {
    let end = n.iter().position(|&b| b == 0).unwrap_or(n.len());
    String::from_utf8_lossy(&n[..end]).into_owned()
}
