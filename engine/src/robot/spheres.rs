//! The sphere model: spheres per link, in the link frame, that cover the link's collision
//! primitives, plus one bounding sphere per link for the broad phase.
//!
//! Spheres are generated from the primitives (not hand-placed), so they cover them by
//! construction: capsules and cylinders get a row of spheres along their axis, boxes a grid of
//! cell-circumscribing spheres. `max_growth` bounds how far a sphere may stick out of its
//! primitive (metres); smaller means tighter and more spheres.

use super::{Link, LinkShape};
use crate::collision::Shape;
use nalgebra::{Point3, Vector3};
use serde::Deserialize;

/// Parameters of sphere generation (the `[spheres]` table of the robot file).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpherizeParams {
    /// How far a sphere may stick out of its primitive, metres.
    pub max_growth: f64,
    /// Per-link overrides of `max_growth` (coarser spheres for large body parts).
    #[serde(default)]
    pub links: std::collections::BTreeMap<String, f64>,
}

impl Default for SpherizeParams {
    fn default() -> Self {
        Self {
            max_growth: 0.03,
            links: Default::default(),
        }
    }
}

/// Largest number of spheres in one cluster (one SIMD register of f32 lanes).
pub const CLUSTER_SIZE: usize = 8;

/// A group of at most [`CLUSTER_SIZE`] neighbouring spheres of one link, with a bounding sphere:
/// the middle level of the checker's hierarchy (link → cluster → sphere).
#[derive(Debug, Clone, PartialEq)]
pub struct Cluster {
    /// Range of the cluster's spheres in the model's arrays.
    pub range: std::ops::Range<usize>,
    /// Centre of the bounding sphere, link frame.
    pub center: [f64; 3],
    /// Radius of the bounding sphere.
    pub radius: f64,
}

/// Flat arrays of spheres grouped by link: centre in the link frame and radius.
#[derive(Debug, Clone, Default)]
pub struct SphereModel {
    /// Owning link of each sphere.
    pub link: Vec<u32>,
    /// Centre in the owning link's frame, metres.
    pub center: Vec<[f64; 3]>,
    /// Radius, metres.
    pub radius: Vec<f64>,
    /// Per link (indexed like `Robot::links`): the range of its spheres.
    pub ranges: Vec<std::ops::Range<usize>>,
    /// Per link: a sphere (centre in the link frame, radius) containing all its spheres.
    pub bounds: Vec<Option<([f64; 3], f64)>>,
    /// Clusters of neighbouring spheres, grouped by link.
    pub clusters: Vec<Cluster>,
    /// Per link: the range of its clusters.
    pub link_clusters: Vec<std::ops::Range<usize>>,
}

impl SphereModel {
    /// Number of spheres.
    pub fn len(&self) -> usize {
        self.radius.len()
    }

    /// True when no link has collision geometry.
    pub fn is_empty(&self) -> bool {
        self.radius.is_empty()
    }

    /// Generates spheres covering every collision primitive of every link, grouped into
    /// clusters of neighbours.
    pub fn generate(links: &[Link], params: &SpherizeParams) -> Self {
        let mut model = SphereModel::default();
        for (i, link) in links.iter().enumerate() {
            let growth = params
                .links
                .get(&link.name)
                .copied()
                .unwrap_or(params.max_growth);
            model.push_link(i, link, growth);
        }
        model
    }

    /// Appends the spheres of link `index` (the next link: links are added in order).
    pub(crate) fn push_link(&mut self, index: usize, link: &Link, max_growth: f64) {
        debug_assert_eq!(index, self.ranges.len(), "links are added in order");
        let mut spheres: Vec<([f64; 3], f64)> = link
            .collision
            .iter()
            .flat_map(|ls| spherize(ls, max_growth))
            .collect();
        let start = self.len();
        let cluster_start = self.clusters.len();
        let mut groups = Vec::new();
        split_clusters(&mut spheres, &mut groups);
        for group in groups {
            let first = self.len();
            for (c, r) in group {
                self.link.push(index as u32);
                self.center.push(c);
                self.radius.push(r);
            }
            let range = first..self.len();
            let (center, radius) =
                bounding_sphere(&self.center[range.clone()], &self.radius[range.clone()])
                    .expect("clusters are not empty");
            self.clusters.push(Cluster {
                range,
                center,
                radius,
            });
        }
        let range = start..self.len();
        self.bounds.push(bounding_sphere(
            &self.center[range.clone()],
            &self.radius[range.clone()],
        ));
        self.ranges.push(range);
        self.link_clusters.push(cluster_start..self.clusters.len());
    }
}

/// Splits spheres into spatially coherent groups of at most [`CLUSTER_SIZE`] (median split
/// along the longest axis of the centres' extent).
fn split_clusters(spheres: &mut [([f64; 3], f64)], out: &mut Vec<Vec<([f64; 3], f64)>>) {
    if spheres.is_empty() {
        return;
    }
    if spheres.len() <= CLUSTER_SIZE {
        out.push(spheres.to_vec());
        return;
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (c, _) in spheres.iter() {
        for k in 0..3 {
            lo[k] = lo[k].min(c[k]);
            hi[k] = hi[k].max(c[k]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    spheres.sort_by(|a, b| a.0[axis].total_cmp(&b.0[axis]));
    // Split at a multiple of the cluster size so clusters come out full.
    let half = spheres.len().div_ceil(2).div_ceil(CLUSTER_SIZE) * CLUSTER_SIZE;
    let (a, b) = spheres.split_at_mut(half.min(spheres.len() - 1));
    split_clusters(a, out);
    split_clusters(b, out);
}

/// Spheres (centre in the link frame, radius) covering one posed primitive.
pub fn spherize(ls: &LinkShape, max_growth: f64) -> Vec<([f64; 3], f64)> {
    let local: Vec<(Vector3<f64>, f64)> = match ls.shape {
        Shape::Sphere { radius } => vec![(Vector3::zeros(), radius)],
        Shape::Capsule {
            radius,
            half_length,
        } => axis_row(radius, half_length, 0.0, max_growth),
        Shape::Cylinder {
            radius,
            half_length,
        } => cylinder_spheres(radius, half_length, max_growth),
        Shape::Box { half_extents } => box_grid(half_extents, max_growth),
    };
    local
        .into_iter()
        .map(|(c, r)| {
            let w = ls.origin * Point3::from(c);
            ([w.x, w.y, w.z], r)
        })
        .collect()
}

/// Spheres along z from `-(h - inset)` to `h - inset` whose union covers a capsule of radius
/// `r` and half length `h` (inset 0), or a cylinder (inset > 0 keeps the rim covered while the
/// end spheres stick out of the flat faces by at most `max_growth`).
fn axis_row(r: f64, h: f64, inset: f64, max_growth: f64) -> Vec<(Vector3<f64>, f64)> {
    let end = (h - inset).max(0.0);
    let max_spacing = 2.0 * ((r + max_growth).powi(2) - r * r).sqrt();
    let n = (2.0 * end / max_spacing).ceil() as usize + 1;
    let spacing = if n > 1 {
        2.0 * end / (n - 1) as f64
    } else {
        0.0
    };
    let radius = (r * r + (spacing / 2.0).powi(2))
        .sqrt()
        .max((r * r + inset * inset).sqrt());
    (0..n)
        .map(|k| (Vector3::new(0.0, 0.0, -end + spacing * k as f64), radius))
        .collect()
}

/// Spheres covering a cylinder along z: a row of inset spheres when it is slender, else the
/// cells of a grid over its bounding box that meet it.
fn cylinder_spheres(r: f64, h: f64, max_growth: f64) -> Vec<(Vector3<f64>, f64)> {
    // A sphere centred `a` inside a flat face covers the rim with radius sqrt(r² + a²) and sticks
    // out of the face by sqrt(r² + a²) - a; that is at most `max_growth` when a >= inset.
    let inset = ((r * r - max_growth * max_growth) / (2.0 * max_growth)).max(0.0);
    if inset <= h {
        return axis_row(r, h, inset, max_growth);
    }
    box_grid([r, r, h], max_growth)
        .into_iter()
        .filter(|(c, radius)| {
            let radial = (c.x * c.x + c.y * c.y).sqrt();
            radial - radius < r
        })
        .collect()
}

/// A grid of spheres, each circumscribing one cell of a box with half extents `h`.
fn box_grid(h: [f64; 3], max_growth: f64) -> Vec<(Vector3<f64>, f64)> {
    let mut cell = 2.0 * h[0].min(h[1]).min(h[2]);
    loop {
        let n = h.map(|hi| ((2.0 * hi / cell).ceil() as usize).max(1));
        let c = [0, 1, 2].map(|i| h[i] / n[i] as f64);
        let radius = Vector3::from(c).norm();
        let growth = radius - c[0].min(c[1]).min(c[2]);
        if growth <= max_growth || cell < 0.005 {
            let mut out = Vec::with_capacity(n[0] * n[1] * n[2]);
            for i in 0..n[0] {
                for j in 0..n[1] {
                    for k in 0..n[2] {
                        let p = Vector3::new(
                            -h[0] + c[0] * (2 * i + 1) as f64,
                            -h[1] + c[1] * (2 * j + 1) as f64,
                            -h[2] + c[2] * (2 * k + 1) as f64,
                        );
                        out.push((p, radius));
                    }
                }
            }
            return out;
        }
        cell *= 0.8;
    }
}

fn bounding_sphere(centers: &[[f64; 3]], radii: &[f64]) -> Option<([f64; 3], f64)> {
    if centers.is_empty() {
        return None;
    }
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for (c, r) in centers.iter().zip(radii) {
        let c = Vector3::from(*c);
        lo = lo.inf(&(c - Vector3::repeat(*r)));
        hi = hi.sup(&(c + Vector3::repeat(*r)));
    }
    let mid = (lo + hi) / 2.0;
    let radius = centers
        .iter()
        .zip(radii)
        .map(|(c, r)| (Vector3::from(*c) - mid).norm() + r)
        .fold(0.0, f64::max);
    Some(([mid.x, mid.y, mid.z], radius))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::distance::distance_point_shape;
    use crate::Pose;
    use proptest::prelude::*;

    fn covered(shape: Shape, p: [f64; 3]) -> bool {
        let ls = LinkShape {
            origin: Pose::identity(),
            shape,
        };
        spherize(&ls, 0.02)
            .iter()
            .any(|(c, r)| (Vector3::from(*c) - Vector3::from(p)).norm() <= r + 1e-9)
    }

    proptest! {
        #[test]
        fn spheres_cover_every_point_of_the_primitive(
            kind in 0..4usize, a in 0.01..0.4f64, b in 0.01..0.4f64, c in 0.01..0.4f64,
            u in -1.0..1.0f64, v in -1.0..1.0f64, w in -1.0..1.0f64,
        ) {
            let shape = match kind {
                0 => Shape::Sphere { radius: a },
                1 => Shape::Box { half_extents: [a, b, c] },
                2 => Shape::Cylinder { radius: a, half_length: b },
                _ => Shape::Capsule { radius: a, half_length: b },
            };
            let e = shape.local_half_extents();
            let p = [u * e[0], v * e[1], w * e[2]];
            prop_assume!(distance_point_shape(p, &shape) <= 0.0);
            prop_assert!(covered(shape, p));
        }
    }

    #[test]
    fn growth_is_bounded_for_capsules() {
        let ls = LinkShape {
            origin: Pose::identity(),
            shape: Shape::Capsule {
                radius: 0.06,
                half_length: 0.2,
            },
        };
        for (_, r) in spherize(&ls, 0.02) {
            assert!(r <= 0.06 + 0.02 + 1e-12);
        }
    }
}
