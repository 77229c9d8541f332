//! Convex hulls of mesh geometry: vertices, outward triangles and face planes, in the frame the
//! mesh was given in (a link frame). The exact checker turns them into parry3d polyhedra; the
//! sphere fitter reads their depth function.

use nalgebra::Vector3;

/// A closed convex polyhedron.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvexHull {
    /// Hull vertices, metres.
    pub points: Vec<[f64; 3]>,
    /// Triangles over `points`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Distinct face planes `(n, d)` with unit outward `n`: inside is `n·p <= d`.
    pub planes: Vec<([f64; 3], f64)>,
}

/// Why points have no usable hull.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HullError {
    /// Fewer than four points, or every point on one plane (a flat or empty mesh).
    #[error("is flat or degenerate (its points span no volume)")]
    Degenerate,
    /// A coordinate is NaN or infinite.
    #[error("has a non-finite vertex coordinate")]
    NonFinite,
}

impl ConvexHull {
    /// The convex hull of `points` (parry3d's quickhull, in f32).
    pub fn of_points(points: &[[f64; 3]]) -> Result<ConvexHull, HullError> {
        if points.iter().flatten().any(|v| !v.is_finite()) {
            return Err(HullError::NonFinite);
        }
        if points.len() < 4 {
            return Err(HullError::Degenerate);
        }
        let input: Vec<parry3d::math::Vector> = points
            .iter()
            .map(|p| parry3d::math::Vector::new(p[0] as f32, p[1] as f32, p[2] as f32))
            .collect();
        let (vertices, indices) =
            parry3d::transformation::try_convex_hull(&input).map_err(|_| HullError::Degenerate)?;
        let pts: Vec<[f64; 3]> = vertices
            .iter()
            .map(|v| [v.x as f64, v.y as f64, v.z as f64])
            .collect();
        if pts.len() < 4 || indices.len() < 4 {
            return Err(HullError::Degenerate);
        }
        let centroid = pts
            .iter()
            .fold(Vector3::zeros(), |s, p| s + Vector3::from(*p))
            / pts.len() as f64;
        let extent = pts
            .iter()
            .map(|p| (Vector3::from(*p) - centroid).norm())
            .fold(0.0, f64::max);
        let mut triangles = Vec::with_capacity(indices.len());
        let mut planes: Vec<([f64; 3], f64)> = Vec::new();
        for t in &indices {
            let [a, b, c] = t.map(|i| Vector3::from(pts[i as usize]));
            let mut n = (b - a).cross(&(c - a));
            let len = n.norm();
            if len <= 1e-12 * extent.max(1e-9).powi(2) {
                continue; // sliver
            }
            n /= len;
            let mut tri = *t;
            if n.dot(&(a - centroid)) < 0.0 {
                n = -n;
                tri.swap(1, 2);
            }
            triangles.push(tri);
            let d = n.dot(&a);
            let dup = planes.iter().any(|(m, e)| {
                (Vector3::from(*m) - n).norm() < 1e-6 && (e - d).abs() < 1e-7 * extent.max(1.0)
            });
            if !dup {
                planes.push(([n.x, n.y, n.z], d));
            }
        }
        let hull = ConvexHull {
            points: pts,
            triangles,
            planes,
        };
        if hull.planes.len() < 4 || hull.volume() <= 1e-12 * extent.max(1e-9).powi(3) {
            return Err(HullError::Degenerate);
        }
        // Planes must bound every vertex (f32 hulls are slightly inexact).
        Ok(Self::widened(hull))
    }

    fn widened(mut hull: ConvexHull) -> ConvexHull {
        for k in 0..hull.planes.len() {
            let n = Vector3::from(hull.planes[k].0);
            let worst = hull
                .points
                .iter()
                .map(|p| n.dot(&Vector3::from(*p)))
                .fold(f64::NEG_INFINITY, f64::max);
            hull.planes[k].1 = hull.planes[k].1.max(worst);
        }
        hull
    }

    /// Depth of `p` inside the hull: distance to the nearest face plane, positive inside,
    /// negative outside (then a lower bound on the distance's magnitude).
    #[inline]
    pub fn depth(&self, p: [f64; 3]) -> f64 {
        self.planes
            .iter()
            .map(|(n, d)| d - (n[0] * p[0] + n[1] * p[1] + n[2] * p[2]))
            .fold(f64::INFINITY, f64::min)
    }

    /// Euclidean distance from `p` to the hull, 0 inside.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        if self.depth(p) >= 0.0 {
            return 0.0;
        }
        let q = Vector3::from(p);
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| Vector3::from(self.points[i as usize]));
                (closest_on_triangle(q, a, b, c) - q).norm()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Enclosed volume, cubic metres.
    pub fn volume(&self) -> f64 {
        let o = Vector3::from(self.points[0]);
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| Vector3::from(self.points[i as usize]) - o);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Axis-aligned bounds `(lo, hi)`.
    pub fn aabb(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }
}

/// The point of triangle `abc` closest to `p` (Ericson, Real-Time Collision Detection, 5.1.5).
fn closest_on_triangle(
    p: Vector3<f64>,
    a: Vector3<f64>,
    b: Vector3<f64>,
    c: Vector3<f64>,
) -> Vector3<f64> {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> Vec<[f64; 3]> {
        let mut pts = Vec::new();
        for x in [-1.0, 1.0] {
            for y in [-1.0, 1.0] {
                for z in [-1.0, 1.0] {
                    pts.push([x * 0.1, y * 0.2, z * 0.3]);
                }
            }
        }
        pts.push([0.0, 0.0, 0.0]); // interior point, dropped
        pts
    }

    #[test]
    fn hull_of_a_box_has_six_planes_and_its_volume() {
        let sut = ConvexHull::of_points(&cube()).unwrap();
        assert_eq!(sut.points.len(), 8);
        assert_eq!(sut.planes.len(), 6);
        assert!((sut.volume() - 0.2 * 0.4 * 0.6).abs() < 1e-6);
        assert!((sut.depth([0.0, 0.0, 0.0]) - 0.1).abs() < 1e-6);
        assert!((sut.depth([0.0, 0.15, 0.0]) - 0.05).abs() < 1e-6);
        assert!(sut.depth([0.2, 0.0, 0.0]) < 0.0);
        assert_eq!(sut.distance([0.05, 0.0, 0.0]), 0.0);
        assert!((sut.distance([0.2, 0.0, 0.0]) - 0.1).abs() < 1e-6);
        let corner = sut.distance([0.2, 0.3, 0.3]);
        assert!((corner - (0.01f64 + 0.01).sqrt()).abs() < 1e-6, "{corner}");
    }

    #[test]
    fn flat_and_tiny_inputs_are_degenerate() {
        let flat = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        assert_eq!(ConvexHull::of_points(&flat), Err(HullError::Degenerate));
        assert_eq!(
            ConvexHull::of_points(&flat[..2]),
            Err(HullError::Degenerate)
        );
        let nan = [[f64::NAN, 0.0, 0.0]; 5];
        assert_eq!(ConvexHull::of_points(&nan), Err(HullError::NonFinite));
    }
}
