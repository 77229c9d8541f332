//! Signed distances from a point to a primitive, in the primitive's own frame.
//!
//! One file per pair, named `distance_<a>_<b>.rs` as in parry. A robot sphere of radius `r`
//! centred at `p` is at distance `distance_point_shape(p, shape) - r` from the shape; negative
//! means penetration. [`distance_point_shape`] is the one dispatch point.

mod distance_point_box;
mod distance_point_capsule;
mod distance_point_cylinder;
mod distance_point_sphere;

pub use distance_point_box::distance_point_box;
pub use distance_point_capsule::distance_point_capsule;
pub use distance_point_cylinder::distance_point_cylinder;
pub use distance_point_sphere::distance_point_sphere;

use super::Shape;

/// Signed distance from `p` (in the shape's frame) to the surface of `shape`: positive outside,
/// negative inside.
///
/// ```
/// use ember_engine::collision::{distance::distance_point_shape, Shape};
/// let d = distance_point_shape([3.0, 0.0, 0.0], &Shape::Sphere { radius: 1.0 });
/// assert_eq!(d, 2.0);
/// ```
#[inline]
pub fn distance_point_shape(p: [f64; 3], shape: &Shape) -> f64 {
    match *shape {
        Shape::Sphere { radius } => distance_point_sphere(p, radius),
        Shape::Box { half_extents } => distance_point_box(p, half_extents),
        Shape::Cylinder {
            radius,
            half_length,
        } => distance_point_cylinder(p, radius, half_length),
        Shape::Capsule {
            radius,
            half_length,
        } => distance_point_capsule(p, radius, half_length),
    }
}
