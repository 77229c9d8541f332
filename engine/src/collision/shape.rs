//! Collision shapes as plain data. Queries on them live in [`super::distance`] and
//! [`super::parry`].

use nalgebra::Vector3;

/// A convex primitive in its own frame: boxes are centred, cylinders and capsules run along
/// local **z** (the URDF convention). Metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A ball of the given radius.
    Sphere {
        /// Radius, metres.
        radius: f64,
    },
    /// A box given by its half extents along x, y, z.
    Box {
        /// Half extents, metres.
        half_extents: [f64; 3],
    },
    /// A cylinder along z.
    Cylinder {
        /// Radius, metres.
        radius: f64,
        /// Half of the length along z, metres.
        half_length: f64,
    },
    /// A capsule along z: a segment of length `2 * half_length` swept by a ball of `radius`.
    Capsule {
        /// Radius, metres.
        radius: f64,
        /// Half of the segment length along z, metres.
        half_length: f64,
    },
}

impl Shape {
    /// A box from its full size along x, y, z.
    pub fn cuboid(size: [f64; 3]) -> Self {
        Shape::Box {
            half_extents: [size[0] / 2.0, size[1] / 2.0, size[2] / 2.0],
        }
    }

    /// Radius of the smallest ball about the shape's origin that contains it.
    ///
    /// ```
    /// use ember_engine::collision::Shape;
    /// assert_eq!(Shape::Capsule { radius: 1.0, half_length: 2.0 }.bounding_radius(), 3.0);
    /// ```
    pub fn bounding_radius(&self) -> f64 {
        match *self {
            Shape::Sphere { radius } => radius,
            Shape::Box { half_extents: h } => Vector3::from(h).norm(),
            Shape::Cylinder {
                radius,
                half_length,
            } => (radius * radius + half_length * half_length).sqrt(),
            Shape::Capsule {
                radius,
                half_length,
            } => radius + half_length,
        }
    }

    /// Half extents of the shape's local axis-aligned bounding box.
    pub fn local_half_extents(&self) -> [f64; 3] {
        match *self {
            Shape::Sphere { radius } => [radius; 3],
            Shape::Box { half_extents } => half_extents,
            Shape::Cylinder {
                radius,
                half_length,
            } => [radius, radius, half_length],
            Shape::Capsule {
                radius,
                half_length,
            } => [radius, radius, half_length + radius],
        }
    }

    /// True when every dimension is finite and positive (half lengths may be zero).
    pub fn is_valid(&self) -> bool {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        let ok0 = |v: f64| v.is_finite() && v >= 0.0;
        match *self {
            Shape::Sphere { radius } => ok(radius),
            Shape::Box { half_extents } => half_extents.iter().all(|&h| ok(h)),
            Shape::Cylinder {
                radius,
                half_length,
            } => ok(radius) && ok(half_length),
            Shape::Capsule {
                radius,
                half_length,
            } => ok(radius) && ok0(half_length),
        }
    }
}
