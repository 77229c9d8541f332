//! Ray casting against primitives, in the primitive's frame: the simulated depth camera's
//! renderer. Each function returns the smallest `t >= 0` with `o + t·d` on the surface.

use super::Shape;

/// First hit of the ray `o + t·d` (`t >= 0`) with `shape`, if any.
///
/// ```
/// use ember_engine::collision::{ray::ray_shape, Shape};
/// let t = ray_shape([-5.0, 0.0, 0.0], [1.0, 0.0, 0.0], &Shape::Sphere { radius: 1.0 });
/// assert_eq!(t, Some(4.0));
/// ```
pub fn ray_shape(o: [f64; 3], d: [f64; 3], shape: &Shape) -> Option<f64> {
    match *shape {
        Shape::Sphere { radius } => ray_sphere(o, d, [0.0; 3], radius),
        Shape::Box { half_extents } => ray_box(o, d, half_extents),
        Shape::Cylinder {
            radius,
            half_length,
        } => ray_cylinder(o, d, radius, half_length),
        Shape::Capsule {
            radius,
            half_length,
        } => {
            let side = ray_cylinder_side(o, d, radius, half_length);
            let a = ray_sphere(o, d, [0.0, 0.0, half_length], radius);
            let b = ray_sphere(o, d, [0.0, 0.0, -half_length], radius);
            [side, a, b].into_iter().flatten().min_by(f64::total_cmp)
        }
    }
}

/// Ray against a ball at `c`.
pub fn ray_sphere(o: [f64; 3], d: [f64; 3], c: [f64; 3], r: f64) -> Option<f64> {
    let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
    let cc = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - r * r;
    let disc = b * b - a * cc;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let t0 = (-b - s) / a;
    let t1 = (-b + s) / a;
    if t0 >= 0.0 {
        Some(t0)
    } else if t1 >= 0.0 {
        Some(0.0)
    } else {
        None
    }
}

/// Ray against a centred box (slab method).
pub fn ray_box(o: [f64; 3], d: [f64; 3], h: [f64; 3]) -> Option<f64> {
    let mut t_near = f64::NEG_INFINITY;
    let mut t_far = f64::INFINITY;
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a].abs() > h[a] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (mut t0, mut t1) = ((-h[a] - o[a]) * inv, (h[a] - o[a]) * inv);
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        t_near = t_near.max(t0);
        t_far = t_far.min(t1);
        if t_near > t_far {
            return None;
        }
    }
    (t_far >= 0.0).then_some(t_near.max(0.0))
}

fn ray_cylinder_side(o: [f64; 3], d: [f64; 3], r: f64, h: f64) -> Option<f64> {
    let a = d[0] * d[0] + d[1] * d[1];
    if a == 0.0 {
        return None;
    }
    let b = o[0] * d[0] + o[1] * d[1];
    let c = o[0] * o[0] + o[1] * o[1] - r * r;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / a;
    (t >= 0.0 && (o[2] + t * d[2]).abs() <= h).then_some(t)
}

/// Ray against a cylinder along z.
pub fn ray_cylinder(o: [f64; 3], d: [f64; 3], r: f64, h: f64) -> Option<f64> {
    let side = ray_cylinder_side(o, d, r, h);
    let cap = |z: f64| {
        if d[2] == 0.0 {
            return None;
        }
        let t = (z - o[2]) / d[2];
        let x = o[0] + t * d[0];
        let y = o[1] + t * d[1];
        (t >= 0.0 && x * x + y * y <= r * r).then_some(t)
    };
    [side, cap(h), cap(-h)]
        .into_iter()
        .flatten()
        .min_by(f64::total_cmp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_hit_from_outside() {
        assert_eq!(
            ray_box([-3.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
            Some(2.0)
        );
        assert_eq!(
            ray_box([-3.0, 2.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
            None
        );
    }

    #[test]
    fn cylinder_cap_and_side() {
        let down = ray_cylinder([0.0, 0.0, 5.0], [0.0, 0.0, -1.0], 1.0, 1.0);
        assert_eq!(down, Some(4.0));
        let side = ray_cylinder([5.0, 0.0, 0.0], [-1.0, 0.0, 0.0], 1.0, 1.0);
        assert_eq!(side, Some(4.0));
    }

    #[test]
    fn capsule_end_cap() {
        let s = Shape::Capsule {
            radius: 0.5,
            half_length: 1.0,
        };
        assert_eq!(ray_shape([0.0, 0.0, 5.0], [0.0, 0.0, -1.0], &s), Some(3.5));
    }
}
