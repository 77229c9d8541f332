//! `ember/<instance>/cloud`: depth clouds, publish-subscribe. The payload is a shared-memory
//! slice of [`Point`]s in the sensor frame; the user header [`CloudHeader`] says where the sensor
//! was. A publisher loans the slice and writes the points straight into shared memory.

use iceoryx2::prelude::*;

/// Largest cloud the service is sized for (a 640×480 image).
pub const MAX_CLOUD_POINTS: usize = 640 * 480;

/// One point, sensor frame, metres.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("EmberPoint")]
#[repr(C)]
pub struct Point {
    /// x, metres.
    pub x: f32,
    /// y, metres.
    pub y: f32,
    /// z, metres.
    pub z: f32,
}

/// The user header of a cloud sample.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("EmberCloudHeader")]
#[repr(C)]
pub struct CloudHeader {
    /// [`super::PROTOCOL_VERSION`].
    pub version: u32,
    /// Number of points in the payload.
    pub point_count: u32,
    /// Capture time, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// Sensor frame name (informational; the pose below places the cloud).
    pub frame_id: super::Name,
    /// Sensor pose in the robot base frame: x, y, z, qx, qy, qz, qw.
    pub sensor_pose: [f64; 7],
    /// The publisher's message number, counting from 1 (0: not numbered); the daemon counts
    /// the numbers it never saw as dropped.
    pub seq: u64,
}

impl Point {
    /// Views points as `[x, y, z]` arrays without copying (same `repr(C)` layout).
    pub fn as_arrays(points: &[Point]) -> &[[f32; 3]] {
        // SAFETY: `Point` is `repr(C)` with exactly three `f32` fields, so it has the size,
        // alignment and layout of `[f32; 3]`; the lifetime is carried over.
        unsafe { std::slice::from_raw_parts(points.as_ptr().cast::<[f32; 3]>(), points.len()) }
    }
}

const _: () = assert!(std::mem::size_of::<Point>() == 12 && std::mem::align_of::<Point>() == 4);
