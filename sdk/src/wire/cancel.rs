//! `ember/<instance>/cancel`: cancels plans in flight by the id their request carried
//! ([`super::PlanRequestHeader::request_id`]), request-response. A cancelled plan is answered
//! with status `cancelled` on its own request.

use iceoryx2::prelude::*;

/// Which plans to cancel.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("EmberCancelRequest")]
#[repr(C)]
pub struct CancelRequest {
    /// [`super::PROTOCOL_VERSION`].
    pub version: u32,
    /// Unused, 0.
    pub reserved: u32,
    /// The request id of the plans to cancel (0 names none).
    pub request_id: u64,
}

/// The daemon's answer.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("EmberCancelReply")]
#[repr(C)]
pub struct CancelReply {
    /// [`super::PROTOCOL_VERSION`].
    pub version: u32,
    /// A [`crate::Status`] code: `ok`, or `version_mismatch` (nothing cancelled).
    pub status: u32,
    /// Plans in flight with that id, now cancelled (0: none was in flight, e.g. already
    /// answered).
    pub cancelled: u32,
}
