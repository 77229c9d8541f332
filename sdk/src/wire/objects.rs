//! `ember/<instance>/objects`: motion-capture object updates and what the robot holds,
//! publish-subscribe, one object per sample.
//!
//! - `link` empty: a world object in the base frame, added or moved ([`ShapeKind::Remove`]
//!   removes it, from the world or the robot's hand);
//! - `link` a robot link: the robot holds the object there (attach), `pose` in that link's
//!   frame; [`ShapeKind::Tracked`] attaches the tracked object of that id with its shape;
//! - `link` empty and [`ShapeKind::Tracked`]: the robot lets go of it (detach); it stays a
//!   world object at `pose`.

use iceoryx2::prelude::*;

/// Shape codes of [`ObjectUpdate::shape`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ShapeKind {
    /// Remove the object with this id.
    Remove = 0,
    /// Box: dims = full size x, y, z.
    Box = 1,
    /// Cylinder along local z: dims = radius, length, unused.
    Cylinder = 2,
    /// Sphere: dims = radius, unused, unused.
    Sphere = 3,
    /// Capsule along local z: dims = radius, length of the segment, unused.
    Capsule = 4,
    /// The shape the daemon tracks for this id (attach a tracked object, or detach a held
    /// one); dims unused.
    Tracked = 5,
}

/// One object's state.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("EmberObjectUpdate")]
#[repr(C)]
pub struct ObjectUpdate {
    /// [`super::PROTOCOL_VERSION`].
    pub version: u32,
    /// A [`ShapeKind`] code.
    pub shape: u32,
    /// Measurement time, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// Object id.
    pub id: super::Name,
    /// Dimensions, metres (meaning per shape).
    pub dims: [f64; 3],
    /// Pose in the robot base frame: x, y, z, qx, qy, qz, qw.
    pub pose: [f64; 7],
    /// The publisher's message number, counting from 1 (0: not numbered); the daemon counts
    /// the numbers it never saw as dropped.
    pub seq: u64,
    /// The robot link holding the object (attach; `pose` is then in that link's frame), or
    /// empty: a world object (see the module docs).
    pub link: super::Name,
}
