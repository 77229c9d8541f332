//! The object service: object updates (add, move, remove, attach, detach) from clients,
//! decoded into world changes.

use super::drops::Gaps;
use super::rejection::Rejection;
use ember_engine::collision::Shape;
use ember_engine::scene::pose_from_xyz_xyzw;
use ember_engine::world::model::ObjectChange;
use ember_engine::world::Object;
use ember_sdk::client::now_ns;
use ember_sdk::services::{self, Limits, Open};
use ember_sdk::wire::{self, ShapeKind, PROTOCOL_VERSION};
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

/// The object updates port.
pub struct ObjectsPort(Subscriber<ipc::Service, wire::ObjectUpdate, ()>);

impl ObjectsPort {
    /// Subscribes to the instance's object updates.
    pub fn open(node: &Node<ipc::Service>, instance: &str, limits: Limits) -> anyhow::Result<Self> {
        let sub = services::objects(node, instance, Open::Serve(limits))
            .map_err(anyhow::Error::msg)?
            .subscriber_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("object subscriber: {e:?}"))?;
        Ok(ObjectsPort(sub))
    }

    /// The next waiting update as received (for the recording) and decoded (objects reaching
    /// farther than `max_extent` metres refused); None when none waits. `gaps` counts the
    /// updates its publisher sent that never arrived.
    pub fn receive(
        &self,
        max_extent: f64,
        gaps: &mut Gaps,
    ) -> Option<(u64, wire::ObjectUpdate, Result<ObjectChange, Rejection>)> {
        let s = self.0.receive().ok().flatten()?;
        let u = *s.payload();
        let dropped = gaps.saw(s.header().publisher_id().value(), u.seq);
        Some((dropped, u, decode(&u, max_extent)))
    }
}

/// Decodes an update; an object larger than `max_extent`, or a world object centred farther
/// than it from the base, is refused.
pub fn decode(u: &wire::ObjectUpdate, max_extent: f64) -> Result<ObjectChange, Rejection> {
    Rejection::check_version("object update", u.version)?;
    let change = change_of(u)?;
    let (id, shape, pose) = match &change {
        ObjectChange::Upsert(o) => (&o.name, Some(o.shape), Some(&o.pose)),
        ObjectChange::Attach { id, shape, .. } => (id, *shape, None),
        ObjectChange::Detach { id, pose } => (id, None, Some(pose)),
        ObjectChange::Remove(_) => return Ok(change),
    };
    let far = pose.map_or(0.0, |p| p.translation.vector.norm());
    let large = shape.is_some() && u.dims.iter().any(|d| d.abs() > max_extent);
    if large || far > max_extent {
        return Err(Rejection::ObjectExtent {
            id: id.clone(),
            limit: max_extent,
        });
    }
    Ok(change)
}

/// The world change an update asks for, or why it is refused (limits aside).
pub fn change_of(u: &wire::ObjectUpdate) -> Result<ObjectChange, Rejection> {
    let id = wire::name_str(&u.id);
    if id.is_empty() {
        return Err(Rejection::ObjectWithoutId);
    }
    if !u.dims.iter().chain(u.pose.iter()).all(|v| v.is_finite()) {
        return Err(Rejection::ObjectNotFinite(id));
    }
    let d = u.dims;
    let shape = match u.shape {
        s if s == ShapeKind::Remove as u32 => return Ok(ObjectChange::Remove(id)),
        s if s == ShapeKind::Tracked as u32 => None,
        s if s == ShapeKind::Box as u32 => Some(Shape::cuboid(d)),
        s if s == ShapeKind::Cylinder as u32 => Some(Shape::Cylinder {
            radius: d[0],
            half_length: d[1] / 2.0,
        }),
        s if s == ShapeKind::Sphere as u32 => Some(Shape::Sphere { radius: d[0] }),
        s if s == ShapeKind::Capsule as u32 => Some(Shape::Capsule {
            radius: d[0],
            half_length: d[1] / 2.0,
        }),
        code => return Err(Rejection::UnknownShape { id, code }),
    };
    if shape.is_some_and(|s| !s.is_valid()) {
        return Err(Rejection::ObjectDimensions { id, dims: d });
    }
    let p = u.pose;
    let pose = pose_from_xyz_xyzw([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]])
        .ok_or_else(|| Rejection::ObjectQuaternion(id.clone()))?;
    let link = wire::name_str(&u.link);
    Ok(match (link.is_empty(), shape) {
        (true, Some(shape)) => ObjectChange::Upsert(Object {
            name: id,
            shape,
            pose,
        }),
        (true, None) => ObjectChange::Detach { id, pose },
        (false, shape) => ObjectChange::Attach {
            link,
            id,
            shape,
            grasp: pose,
        },
    })
}

/// The wire update that adds or moves `object` (the inverse of [`object_of`]).
pub fn update_of(object: &Object) -> wire::ObjectUpdate {
    let (shape, dims) = match object.shape {
        Shape::Box { half_extents: h } => (ShapeKind::Box, [2.0 * h[0], 2.0 * h[1], 2.0 * h[2]]),
        Shape::Cylinder {
            radius,
            half_length,
        } => (ShapeKind::Cylinder, [radius, 2.0 * half_length, 0.0]),
        Shape::Sphere { radius } => (ShapeKind::Sphere, [radius, 0.0, 0.0]),
        Shape::Capsule {
            radius,
            half_length,
        } => (ShapeKind::Capsule, [radius, 2.0 * half_length, 0.0]),
    };
    let (t, q) = ember_engine::scene::pose_to_xyz_xyzw(&object.pose);
    wire::ObjectUpdate {
        version: PROTOCOL_VERSION,
        shape: shape as u32,
        stamp_ns: now_ns(),
        id: wire::name(&object.name),
        dims,
        pose: [t[0], t[1], t[2], q[0], q[1], q[2], q[3]],
        seq: 0,
        link: [0; 32],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_updates_round_trip_every_shape() {
        let pose =
            pose_from_xyz_xyzw([0.5, -0.2, 0.8], [0.0, 0.0, 0.38268343, 0.92387953]).unwrap();
        for shape in [
            Shape::cuboid([0.4, 1.0, 0.04]),
            Shape::Cylinder {
                radius: 0.035,
                half_length: 0.06,
            },
            Shape::Sphere { radius: 0.1 },
            Shape::Capsule {
                radius: 0.05,
                half_length: 0.2,
            },
        ] {
            let o = Object {
                name: "thing".into(),
                shape,
                pose,
            };
            let ObjectChange::Upsert(back) = change_of(&update_of(&o)).unwrap() else {
                panic!("a world object's update is an upsert");
            };
            assert_eq!((back.name.as_str(), back.shape), ("thing", shape));
            assert!((back.pose.translation.vector - pose.translation.vector).norm() < 1e-12);
            assert!(back.pose.rotation.angle_to(&pose.rotation) < 1e-9);
        }
    }
}
