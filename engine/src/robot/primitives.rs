//! Approximating convex mesh parts by primitives. [`fit_primitive`]: the smallest of a box,
//! three capsules and three cylinders (one per principal axis) that contains the hull;
//! containing every hull vertex means containing the hull, so the primitive covers the mesh,
//! and [`protrusion`] measures how far it sticks out. [`fit_primitives`]: the hull cut into
//! slabs along a principal axis, one primitive per slab, so long or tapering parts fit
//! tighter. `ember robot primitives` prints them as URDF collision elements: that is how our
//! built-in descriptions were tightened against the official meshes.

use crate::collision::convex::ConvexHull;
use crate::collision::Shape;
use crate::Pose;
use nalgebra::{Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector2, Vector3};

/// The smallest enclosing primitive found and its pose in the hull's frame.
pub fn fit_primitive(hull: &ConvexHull) -> (Shape, Pose) {
    let pts: Vec<Vector3<f64>> = hull.points.iter().map(|p| Vector3::from(*p)).collect();
    let frame = principal_frame(&pts);
    let mut best: Option<(f64, Shape, Pose)> = None;
    let mut consider = |volume: f64, shape: Shape, pose: Pose| {
        if best.as_ref().is_none_or(|(v, _, _)| volume < *v) {
            best = Some((volume, shape, pose));
        }
    };
    // Box in the principal frame.
    let local: Vec<Vector3<f64>> = pts.iter().map(|p| frame.transpose() * p).collect();
    let (lo, hi) = extent(&local);
    let half = (hi - lo) / 2.0;
    let mid = frame * ((hi + lo) / 2.0);
    consider(
        8.0 * half.x * half.y * half.z,
        Shape::Box {
            half_extents: [half.x, half.y, half.z],
        },
        pose_of(mid, frame),
    );
    // Capsules and cylinders along each principal axis (local z after a permutation).
    for axis in 0..3 {
        let (u, v, w) = match axis {
            0 => (1, 2, 0),
            1 => (2, 0, 1),
            _ => (0, 1, 2),
        };
        let rot = Matrix3::from_columns(&[frame.column(u), frame.column(v), frame.column(w)]);
        let rot = if rot.determinant() < 0.0 {
            Matrix3::from_columns(&[frame.column(v), frame.column(u), frame.column(w)])
        } else {
            rot
        };
        let q: Vec<Vector3<f64>> = pts.iter().map(|p| rot.transpose() * p).collect();
        let (c2, r) =
            enclosing_circle(&q.iter().map(|p| Vector2::new(p.x, p.y)).collect::<Vec<_>>());
        let r = r * (1.0 + 1e-9) + 1e-9;
        let t: Vec<f64> = q.iter().map(|p| p.z).collect();
        // Cylinder: the axial extent.
        let (tmin, tmax) = t
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let cyl_center = rot * Vector3::new(c2.x, c2.y, (tmin + tmax) / 2.0);
        let h = (tmax - tmin) / 2.0;
        consider(
            std::f64::consts::PI * r * r * 2.0 * h,
            Shape::Cylinder {
                radius: r,
                half_length: h,
            },
            pose_of(cyl_center, rot),
        );
        // Capsule: the shortest segment every point lies within r of.
        let (mut s0, mut s1) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in &q {
            let rho2 = (p.x - c2.x).powi(2) + (p.y - c2.y).powi(2);
            let wdt = (r * r - rho2).max(0.0).sqrt();
            s0 = s0.min(p.z + wdt);
            s1 = s1.max(p.z - wdt);
        }
        let (a, b) = if s1 < s0 {
            let m = (s0 + s1) / 2.0;
            (m, m)
        } else {
            (s0, s1)
        };
        let hl = (b - a) / 2.0;
        let cap_center = rot * Vector3::new(c2.x, c2.y, (a + b) / 2.0);
        consider(
            std::f64::consts::PI * r * r * (2.0 * hl + 4.0 / 3.0 * r),
            Shape::Capsule {
                radius: r,
                half_length: hl,
            },
            pose_of(cap_center, rot),
        );
    }
    let (_, shape, pose) = best.expect("candidates were considered");
    (shape, pose)
}

/// A primitive, its pose and its protrusion, metres.
pub type FittedPart = (Shape, Pose, f64);

/// Up to `max_parts` primitives that together contain the hull: it is cut into 1..=max_parts
/// equal slabs along one of its principal axes and each slab gets [`fit_primitive`]; the cut
/// with the least protrusion wins, fewer parts when within 3 mm. Returns (shape, pose,
/// protrusion) per part.
pub fn fit_primitives(hull: &ConvexHull, max_parts: usize) -> Vec<FittedPart> {
    let pts: Vec<Vector3<f64>> = hull.points.iter().map(|p| Vector3::from(*p)).collect();
    let frame = principal_frame(&pts);
    let local: Vec<Vector3<f64>> = pts.iter().map(|p| frame.transpose() * p).collect();
    let (lo, hi) = extent(&local);
    let mut best: Option<(f64, Vec<FittedPart>)> = None;
    for k in 1..=max_parts.max(1) {
        for axis_k in 0..if k == 1 { 1 } else { 3 } {
            let axis: Vector3<f64> = frame.column(axis_k).into_owned();
            let mut parts = Vec::new();
            for i in 0..k {
                let a = lo[axis_k] + (hi[axis_k] - lo[axis_k]) * i as f64 / k as f64;
                let b = lo[axis_k] + (hi[axis_k] - lo[axis_k]) * (i + 1) as f64 / k as f64;
                let Some(piece) = slab(hull, &axis, a, b) else {
                    continue;
                };
                let (shape, pose) = fit_primitive(&piece);
                let stick = protrusion(hull, &shape, &pose);
                parts.push((shape, pose, stick));
            }
            let worst = parts.iter().map(|p| p.2).fold(0.0, f64::max);
            if best.as_ref().is_none_or(|(w, _)| worst < w - 0.003) {
                best = Some((worst, parts));
            }
        }
    }
    best.map(|(_, p)| p).unwrap_or_default()
}

/// The part of the hull with `a <= axis·p <= b`.
fn slab(hull: &ConvexHull, axis: &Vector3<f64>, a: f64, b: f64) -> Option<ConvexHull> {
    let level = |p: &[f64; 3]| axis.dot(&Vector3::from(*p));
    let mut pts: Vec<[f64; 3]> = hull
        .points
        .iter()
        .filter(|p| (a - 1e-12..=b + 1e-12).contains(&level(p)))
        .copied()
        .collect();
    for t in &hull.triangles {
        for e in 0..3 {
            let (p, q) = (
                hull.points[t[e] as usize],
                hull.points[t[(e + 1) % 3] as usize],
            );
            let (lp, lq) = (level(&p), level(&q));
            for cut in [a, b] {
                if (lp - cut) * (lq - cut) < 0.0 {
                    let s = (cut - lp) / (lq - lp);
                    pts.push([0, 1, 2].map(|k| p[k] + (q[k] - p[k]) * s));
                }
            }
        }
    }
    ConvexHull::of_points(&pts).ok()
}

/// Largest distance from the primitive's surface to the hull, sampled on `samples` surface
/// points per primitive (the primitive contains the hull, so this is its protrusion).
pub fn protrusion(hull: &ConvexHull, shape: &Shape, pose: &Pose) -> f64 {
    let dirs = super::spheres::fibonacci_directions(2000);
    let e = shape.local_half_extents();
    let scale = Vector3::from(e).norm() * 2.0;
    dirs.iter()
        .map(|d| {
            // Surface point along d: bisect the signed distance from the centre outwards.
            let dir = Vector3::from(*d);
            let (mut lo, mut hi) = (0.0, scale);
            for _ in 0..40 {
                let mid = (lo + hi) / 2.0;
                let p = dir * mid;
                if crate::collision::distance::distance_point_shape([p.x, p.y, p.z], shape) < 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let p = pose * Point3::from(dir * lo);
            hull.distance([p.x, p.y, p.z])
        })
        .fold(0.0, f64::max)
}

fn pose_of(center: Vector3<f64>, rot: Matrix3<f64>) -> Pose {
    Pose::from_parts(
        Translation3::from(center),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rot)),
    )
}

fn extent(pts: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    pts.iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}

/// Principal axes of the points (a right-handed rotation), snapped to the coordinate axes
/// when within 2° of them (mesh frames are usually aligned with their link).
fn principal_frame(pts: &[Vector3<f64>]) -> Matrix3<f64> {
    let n = pts.len() as f64;
    let mean = pts.iter().sum::<Vector3<f64>>() / n;
    let cov = pts
        .iter()
        .map(|p| (p - mean) * (p - mean).transpose())
        .sum::<Matrix3<f64>>()
        / n;
    let eig = cov.symmetric_eigen();
    let mut m = eig.eigenvectors;
    for k in 0..3 {
        let c = m.column(k).into_owned();
        let (i, v) = c.iter().enumerate().fold((0, 0.0f64), |(bi, bv), (i, v)| {
            if v.abs() > bv.abs() {
                (i, *v)
            } else {
                (bi, bv)
            }
        });
        if v.abs() > (2f64.to_radians()).cos() {
            let mut e = Vector3::zeros();
            e[i] = v.signum();
            m.set_column(k, &e);
        }
    }
    if m.determinant() < 0.0 {
        let c = -m.column(2).into_owned();
        m.set_column(2, &c);
    }
    m
}

/// Smallest circle containing the points (Welzl's algorithm, iterative form).
fn enclosing_circle(p: &[Vector2<f64>]) -> (Vector2<f64>, f64) {
    let inside =
        |c: &Vector2<f64>, r: f64, q: &Vector2<f64>| (q - c).norm() <= r * (1.0 + 1e-12) + 1e-12;
    let mut c = p[0];
    let mut r = 0.0;
    for i in 1..p.len() {
        if inside(&c, r, &p[i]) {
            continue;
        }
        c = p[i];
        r = 0.0;
        for j in 0..i {
            if inside(&c, r, &p[j]) {
                continue;
            }
            c = (p[i] + p[j]) / 2.0;
            r = (p[i] - c).norm();
            for k in 0..j {
                if inside(&c, r, &p[k]) {
                    continue;
                }
                if let Some((cc, rr)) = circumcircle(p[i], p[j], p[k]) {
                    c = cc;
                    r = rr;
                }
            }
        }
    }
    (c, r)
}

fn circumcircle(a: Vector2<f64>, b: Vector2<f64>, c: Vector2<f64>) -> Option<(Vector2<f64>, f64)> {
    let d = 2.0 * (a.x * (b.y - c.y) + b.x * (c.y - a.y) + c.x * (a.y - b.y));
    if d.abs() < 1e-18 {
        return None;
    }
    let (a2, b2, c2) = (a.norm_squared(), b.norm_squared(), c.norm_squared());
    let ux = (a2 * (b.y - c.y) + b2 * (c.y - a.y) + c2 * (a.y - b.y)) / d;
    let uy = (a2 * (c.x - b.x) + b2 * (a.x - c.x) + c2 * (b.x - a.x)) / d;
    let center = Vector2::new(ux, uy);
    Some((center, (a - center).norm()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rod_becomes_a_thin_primitive_that_contains_it() {
        // Points of a capsule-like rod along x.
        let mut pts = Vec::new();
        for i in 0..=20 {
            for k in 0..12 {
                let a = std::f64::consts::TAU * k as f64 / 12.0;
                pts.push([0.01 * i as f64, 0.03 * a.cos(), 0.03 * a.sin()]);
            }
        }
        let hull = ConvexHull::of_points(&pts).unwrap();
        let (shape, pose) = fit_primitive(&hull);
        for p in &hull.points {
            let local = pose.inverse() * Point3::from(*p);
            let d = crate::collision::distance::distance_point_shape(local.coords.into(), &shape);
            assert!(d <= 1e-6, "{shape:?} misses {p:?} by {d}");
        }
        let e = shape.local_half_extents();
        assert!(e.iter().cloned().fold(0.0, f64::max) < 0.15, "{shape:?}");
        assert!(protrusion(&hull, &shape, &pose) < 0.01, "{shape:?}");
    }
}
