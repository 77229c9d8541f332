//! Fitting spheres to one link's collision geometry with a bounded protrusion.
//!
//! Every sphere is centred inside some convex part of the link and has radius `depth + p`,
//! where `depth` is the centre's distance to that part's boundary and `p` the allowed
//! protrusion. For a convex part this bounds the protrusion exactly: the ball's support
//! function is then at most the part's plus `p` in every direction, so every point of the ball
//! lies within `p` of the part. Which spheres to keep is a set cover: the link's surface is
//! sampled on a grid of spacing `s` (samples inside another part are skipped), every candidate
//! centre (a grid inside the parts) covers the samples within its radius less the grid's
//! covering radius `s/√3` (so the whole surface is covered, not only the samples), and a lazy
//! greedy picks the candidate covering most uncovered samples until none is left. Samples no
//! candidate reaches get a sphere of their own, centred on the surface.

use crate::collision::convex::ConvexHull;
use crate::collision::distance::distance_point_shape;
use crate::collision::Shape;
use crate::robot::{Geometry, LinkShape};
use crate::Pose;
use nalgebra::{Point3, Vector3};
use rustc_hash::FxHashMap;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A sphere: centre in the link frame and radius, metres.
pub type Sphere = ([f64; 3], f64);

/// Most surface samples per link: large links get a coarser sample grid.
const MAX_SAMPLES: f64 = 40_000.0;
/// Candidate grid cells along a part's longest side.
const GRID_CELLS: f64 = 24.0;
/// Depths below the surface (in protrusions) of the candidates placed under surface samples.
const OFFSET_DEPTHS: [f64; 5] = [0.25, 0.6, 1.2, 2.5, 5.0];

/// One convex part of a link, posed in the link frame.
pub(crate) struct Part {
    /// Link frame → part frame.
    to_local: Pose,
    kind: PartKind,
    /// Surface triangles in the link frame.
    triangles: Vec<[[f64; 3]; 3]>,
}

enum PartKind {
    Primitive(Shape),
    Convex(std::sync::Arc<ConvexHull>),
}

impl Part {
    pub(crate) fn new(ls: &LinkShape) -> Part {
        let (kind, local) = match &ls.geometry {
            Geometry::Primitive(s) => (PartKind::Primitive(*s), tessellate(s)),
            Geometry::Convex(h) => (
                PartKind::Convex(h.clone()),
                h.triangles
                    .iter()
                    .map(|t| t.map(|i| h.points[i as usize]))
                    .collect(),
            ),
        };
        let triangles = local
            .into_iter()
            .map(|t| t.map(|p| (ls.origin * Point3::from(p)).coords.into()))
            .collect();
        Part {
            to_local: ls.origin.inverse(),
            kind,
            triangles,
        }
    }

    /// Distance from `p` (link frame) to the part's boundary, positive inside.
    #[inline]
    pub(crate) fn depth(&self, p: [f64; 3]) -> f64 {
        let l: [f64; 3] = (self.to_local * Point3::from(p)).coords.into();
        match &self.kind {
            PartKind::Primitive(s) => -distance_point_shape(l, s),
            PartKind::Convex(h) => h.depth(l),
        }
    }

    /// Distance from `p` (link frame) to the part, 0 inside.
    pub(crate) fn distance(&self, p: [f64; 3]) -> f64 {
        let l: [f64; 3] = (self.to_local * Point3::from(p)).coords.into();
        match &self.kind {
            PartKind::Primitive(s) => distance_point_shape(l, s).max(0.0),
            PartKind::Convex(h) => h.distance(l),
        }
    }

    /// Surface triangles in the link frame.
    pub(crate) fn triangles(&self) -> &[[[f64; 3]; 3]] {
        &self.triangles
    }

    /// The box (lower and upper corners, link frame) around `parts`.
    pub(crate) fn bounds_of(parts: &[Part]) -> ([f64; 3], [f64; 3]) {
        bounds(parts.iter().flat_map(|p| p.triangles.iter().flatten()))
    }
}

/// Largest depth of `p` in any part (positive: inside the union).
fn union_depth(parts: &[Part], p: [f64; 3]) -> f64 {
    parts
        .iter()
        .map(|q| q.depth(p))
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Most surface samples a link may need at its protrusion (`area / protrusion²`): beyond
/// this the link is refused rather than fitted (a metre-sized link at 1 cm needs ~10⁵; a mesh
/// in millimetres read as metres, ~10⁹ and tens of GB).
pub const MAX_FIT_SAMPLES: f64 = 4.0e6;

/// Surface area of a link's collision geometry (link frame), m².
pub fn surface_area(shapes: &[LinkShape]) -> f64 {
    shapes
        .iter()
        .map(Part::new)
        .flat_map(|p| p.triangles)
        .map(|t| triangle_area(&t))
        .sum()
}

/// The balls `shapes` (one link, link frame) consist of, when they are balls alone (and not
/// none): such a link is its own sphere model.
pub fn balls(shapes: &[LinkShape]) -> Option<Vec<Sphere>> {
    let balls: Option<Vec<Sphere>> = shapes
        .iter()
        .map(|s| match s.geometry {
            Geometry::Primitive(Shape::Sphere { radius }) => {
                let c = s.origin.translation.vector;
                Some(([c.x, c.y, c.z], radius))
            }
            _ => None,
        })
        .collect();
    balls.filter(|b| !b.is_empty())
}

/// Spheres covering the surface of `shapes` (one link, link frame) with protrusion at most
/// `protrusion`. Deterministic.
pub fn fit(shapes: &[LinkShape], protrusion: f64) -> Vec<Sphere> {
    // Balls are their own best model: a link described by spheres alone (a spherized URDF, as
    // VAMP's and cuRobo's robots are) keeps them exactly, with no protrusion.
    if let Some(balls) = balls(shapes) {
        return balls;
    }
    let parts: Vec<Part> = shapes.iter().map(Part::new).collect();
    if parts.is_empty() {
        return Vec::new();
    }
    let area: f64 = parts
        .iter()
        .flat_map(|p| p.triangles.iter())
        .map(triangle_area)
        .sum();
    // Sample spacing: fine enough that the covering slack stays well inside the protrusion,
    // and never more than MAX_SAMPLES samples: parts of more than MAX_SAMPLES·protrusion² of
    // surface (4 m² at 1 cm; no real link) get a coarser cover rather than unbounded work (a
    // fuzzed URDF with a 10 m box took minutes and gigabytes).
    let spacing = (protrusion / 4.0).max((area / MAX_SAMPLES).sqrt());
    // Such parts are covered by spheres as proud as the samples are apart (no change below).
    let protrusion = protrusion.max(spacing);
    let slack = spacing / 3f64.sqrt() + 1e-6;

    // Surface samples of the union.
    let mut samples: Vec<[f64; 3]> = Vec::new();
    for (k, part) in parts.iter().enumerate() {
        for t in &part.triangles {
            grid_on_triangle(t, spacing, &mut |p| {
                let inside_other = parts
                    .iter()
                    .enumerate()
                    .any(|(j, q)| j != k && q.depth(p) > 1e-6);
                if !inside_other {
                    samples.push(p);
                }
            });
        }
    }
    dedup_points(&mut samples, spacing * 0.25);

    // Candidate centres: a grid inside each part, and points below the surface samples at a
    // few depths (where spheres covering edges and corners sit); radius from the union depth.
    let mut candidates: Vec<Sphere> = Vec::new();
    let push = |c: [f64; 3], candidates: &mut Vec<Sphere>| {
        let d = union_depth(&parts, c);
        if d > 0.0 {
            candidates.push((c, d + protrusion));
        }
    };
    for part in &parts {
        let (lo, hi) = bounds(part.triangles.iter().flatten());
        let longest = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        let shortest = (0..3).map(|k| hi[k] - lo[k]).fold(f64::INFINITY, f64::min);
        let g = (longest / GRID_CELLS).min(shortest / 4.0).max(5e-4);
        let n = [0, 1, 2].map(|k| ((hi[k] - lo[k]) / g).floor() as usize + 1);
        for i in 0..n[0] {
            for j in 0..n[1] {
                for l in 0..n[2] {
                    let c = [
                        lo[0] + (hi[0] - lo[0]) * (i as f64 + 0.5) / n[0] as f64,
                        lo[1] + (hi[1] - lo[1]) * (j as f64 + 0.5) / n[1] as f64,
                        lo[2] + (hi[2] - lo[2]) * (l as f64 + 0.5) / n[2] as f64,
                    ];
                    push(c, &mut candidates);
                }
            }
        }
        // Below the surface: every few samples of each triangle, along its inward normal.
        for t in &part.triangles {
            let [a, b, c] = t.map(Vector3::from);
            let normal = (b - a).cross(&(c - a));
            let Some(inward) = normal.try_normalize(1e-12).map(|n| -n) else {
                continue;
            };
            grid_on_triangle(t, (4.0 * spacing).max(protrusion), &mut |p| {
                for depth in OFFSET_DEPTHS {
                    let q = Vector3::from(p) + inward * (depth * protrusion);
                    push([q.x, q.y, q.z], &mut candidates);
                }
            });
        }
    }
    dedup_spheres(&mut candidates, spacing * 0.25);

    let mut cover = Coverage::new(&samples, protrusion + slack);
    let mut chosen = cover.greedy(&candidates, slack);
    // Whatever no candidate reached gets a sphere centred on the surface.
    for s in cover.uncovered() {
        chosen.push((s, protrusion));
        cover.mark(s, protrusion - slack);
    }
    drop_redundant(&mut chosen, &samples, slack);
    shrink_to_fit(&mut chosen, &samples, slack);
    chosen
}

/// Shrinks each sphere to what its samples need: every sample is assigned to the sphere that
/// covers it with the most room, and a sphere keeps the radius reaching its farthest sample
/// (plus the slack). Protrusion only falls; coverage is unchanged.
fn shrink_to_fit(chosen: &mut [Sphere], samples: &[[f64; 3]], slack: f64) {
    let mut need = vec![0.0f64; chosen.len()];
    for s in samples {
        let best = chosen
            .iter()
            .enumerate()
            .map(|(i, (c, r))| (i, r - slack - dist2(*c, *s).sqrt()))
            .filter(|(_, room)| *room >= 0.0)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, _)) = best {
            need[i] = need[i].max(dist2(chosen[i].0, *s).sqrt() + slack);
        }
    }
    for (sphere, n) in chosen.iter_mut().zip(need) {
        if n > 0.0 {
            sphere.1 = sphere.1.min(n);
        }
    }
}

/// Removes spheres (latest first) whose samples the other spheres all cover.
fn drop_redundant(chosen: &mut Vec<Sphere>, samples: &[[f64; 3]], slack: f64) {
    let reach = |(c, r): &Sphere, s: [f64; 3]| dist2(*c, s) <= (r - slack).max(0.0).powi(2);
    let mut count: Vec<u32> = samples
        .iter()
        .map(|s| chosen.iter().filter(|sp| reach(sp, *s)).count() as u32)
        .collect();
    let mut k = chosen.len();
    while k > 0 {
        k -= 1;
        let mine: Vec<usize> = (0..samples.len())
            .filter(|&i| reach(&chosen[k], samples[i]))
            .collect();
        if mine.iter().all(|&i| count[i] >= 2) {
            for i in mine {
                count[i] -= 1;
            }
            chosen.remove(k);
        }
    }
}

/// Uncovered surface samples in a spatial hash, removed as they are covered.
struct Coverage {
    cell: f64,
    cells: FxHashMap<[i32; 3], Vec<[f64; 3]>>,
}

impl Coverage {
    fn new(samples: &[[f64; 3]], typical_radius: f64) -> Self {
        let cell = typical_radius.max(1e-3);
        let mut cells: FxHashMap<[i32; 3], Vec<[f64; 3]>> = FxHashMap::default();
        for s in samples {
            cells.entry(key(*s, cell)).or_default().push(*s);
        }
        Coverage { cell, cells }
    }

    /// Calls `f` on the cells a ball may reach.
    fn for_cells(&self, c: [f64; 3], r: f64, mut f: impl FnMut([i32; 3])) {
        let lo = key([c[0] - r, c[1] - r, c[2] - r], self.cell);
        let hi = key([c[0] + r, c[1] + r, c[2] + r], self.cell);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    f([x, y, z]);
                }
            }
        }
    }

    fn count(&self, c: [f64; 3], r: f64) -> usize {
        if r <= 0.0 {
            return 0;
        }
        let r2 = r * r;
        let mut n = 0;
        self.for_cells(c, r, |k| {
            if let Some(v) = self.cells.get(&k) {
                n += v.iter().filter(|s| dist2(**s, c) <= r2).count();
            }
        });
        n
    }

    fn mark(&mut self, c: [f64; 3], r: f64) {
        let r2 = r.max(0.0).powi(2);
        let mut keys = Vec::new();
        self.for_cells(c, r.max(0.0), |k| keys.push(k));
        for k in keys {
            if let Some(v) = self.cells.get_mut(&k) {
                v.retain(|s| dist2(*s, c) > r2);
                if v.is_empty() {
                    self.cells.remove(&k);
                }
            }
        }
    }

    fn uncovered(&self) -> Vec<[f64; 3]> {
        let mut keys: Vec<&[i32; 3]> = self.cells.keys().collect();
        keys.sort();
        keys.into_iter()
            .flat_map(|k| self.cells[k].iter().copied())
            .collect()
    }

    /// Lazy greedy set cover: candidate counts only shrink, so a popped candidate whose fresh
    /// count still beats the next stale one is the best.
    fn greedy(&mut self, candidates: &[Sphere], slack: f64) -> Vec<Sphere> {
        let mut heap: BinaryHeap<(usize, Reverse<usize>)> = candidates
            .iter()
            .enumerate()
            .map(|(i, (c, r))| (self.count(*c, r - slack), Reverse(i)))
            .filter(|(n, _)| *n > 0)
            .collect();
        let mut out = Vec::new();
        while let Some((stale, Reverse(i))) = heap.pop() {
            let (c, r) = candidates[i];
            let fresh = if stale == 0 {
                0
            } else {
                self.count(c, r - slack)
            };
            if fresh == 0 {
                continue;
            }
            if heap.peek().is_some_and(|&(next, _)| fresh < next) {
                heap.push((fresh, Reverse(i)));
                continue;
            }
            out.push((c, r));
            self.mark(c, r - slack);
        }
        out
    }
}

#[inline]
fn key(p: [f64; 3], cell: f64) -> [i32; 3] {
    p.map(|v| (v / cell).floor() as i32)
}

#[inline]
fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

fn dedup_points(points: &mut Vec<[f64; 3]>, tolerance: f64) {
    let mut seen: FxHashMap<[i64; 3], ()> = FxHashMap::default();
    points.retain(|p| {
        seen.insert(p.map(|v| (v / tolerance).round() as i64), ())
            .is_none()
    });
}

fn dedup_spheres(spheres: &mut Vec<Sphere>, tolerance: f64) {
    let mut seen: FxHashMap<[i64; 3], ()> = FxHashMap::default();
    spheres.retain(|(p, _)| {
        seen.insert(p.map(|v| (v / tolerance).round() as i64), ())
            .is_none()
    });
}

/// The box (lower and upper corners) around `points`.
pub(crate) fn bounds<'a>(points: impl Iterator<Item = &'a [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

pub(crate) fn triangle_area(t: &[[f64; 3]; 3]) -> f64 {
    let [a, b, c] = t.map(Vector3::from);
    (b - a).cross(&(c - a)).norm() / 2.0
}

/// Points of a regular grid on the triangle, no two neighbours farther apart than `spacing`.
fn grid_on_triangle(t: &[[f64; 3]; 3], spacing: f64, f: &mut impl FnMut([f64; 3])) {
    let [a, b, c] = t.map(Vector3::from);
    let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
    let n = ((longest / spacing).ceil() as usize).max(1);
    for i in 0..=n {
        for j in 0..=(n - i) {
            let p = a + (b - a) * (i as f64 / n as f64) + (c - a) * (j as f64 / n as f64);
            f([p.x, p.y, p.z]);
        }
    }
}

/// Triangles of a primitive in its own frame (circles as 48-gons, spheres as 24 × 48 grids).
fn tessellate(shape: &Shape) -> Vec<[[f64; 3]; 3]> {
    const SEG: usize = 48;
    let mut out = Vec::new();
    let ring = |r: f64, z: f64| -> Vec<[f64; 3]> {
        (0..SEG)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / SEG as f64;
                [r * a.cos(), r * a.sin(), z]
            })
            .collect()
    };
    let band = |out: &mut Vec<[[f64; 3]; 3]>, lo: &[[f64; 3]], hi: &[[f64; 3]]| {
        for k in 0..SEG {
            let k1 = (k + 1) % SEG;
            out.push([lo[k], lo[k1], hi[k1]]);
            out.push([lo[k], hi[k1], hi[k]]);
        }
    };
    // A sphere of radius r centred at z0 (only the half above/below when `half` says so).
    let dome = |out: &mut Vec<[[f64; 3]; 3]>, r: f64, z0: f64, lat: std::ops::Range<usize>| {
        const LAT: usize = 24;
        for i in lat {
            let (t0, t1) = (
                std::f64::consts::PI * i as f64 / LAT as f64,
                std::f64::consts::PI * (i + 1) as f64 / LAT as f64,
            );
            let lo = ring(r * t0.sin(), z0 + r * t0.cos());
            let hi = ring(r * t1.sin(), z0 + r * t1.cos());
            band(out, &hi, &lo);
        }
    };
    match *shape {
        Shape::Box { half_extents: h } => {
            let v = |x: f64, y: f64, z: f64| [x * h[0], y * h[1], z * h[2]];
            let quads = [
                [
                    v(-1., -1., -1.),
                    v(-1., 1., -1.),
                    v(1., 1., -1.),
                    v(1., -1., -1.),
                ],
                [
                    v(-1., -1., 1.),
                    v(1., -1., 1.),
                    v(1., 1., 1.),
                    v(-1., 1., 1.),
                ],
                [
                    v(-1., -1., -1.),
                    v(1., -1., -1.),
                    v(1., -1., 1.),
                    v(-1., -1., 1.),
                ],
                [
                    v(-1., 1., -1.),
                    v(-1., 1., 1.),
                    v(1., 1., 1.),
                    v(1., 1., -1.),
                ],
                [
                    v(-1., -1., -1.),
                    v(-1., -1., 1.),
                    v(-1., 1., 1.),
                    v(-1., 1., -1.),
                ],
                [
                    v(1., -1., -1.),
                    v(1., 1., -1.),
                    v(1., 1., 1.),
                    v(1., -1., 1.),
                ],
            ];
            for q in quads {
                out.push([q[0], q[1], q[2]]);
                out.push([q[0], q[2], q[3]]);
            }
        }
        Shape::Cylinder {
            radius,
            half_length,
        } => {
            let lo = ring(radius, -half_length);
            let hi = ring(radius, half_length);
            band(&mut out, &lo, &hi);
            for k in 0..SEG {
                let k1 = (k + 1) % SEG;
                out.push([[0.0, 0.0, -half_length], lo[k1], lo[k]]);
                out.push([[0.0, 0.0, half_length], hi[k], hi[k1]]);
            }
        }
        Shape::Sphere { radius } => dome(&mut out, radius, 0.0, 0..24),
        Shape::Capsule {
            radius,
            half_length,
        } => {
            dome(&mut out, radius, half_length, 0..12);
            dome(&mut out, radius, -half_length, 12..24);
            band(
                &mut out,
                &ring(radius, -half_length),
                &ring(radius, half_length),
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    fn shape(s: Shape) -> LinkShape {
        LinkShape {
            origin: Pose::translation(0.1, -0.2, 0.3),
            geometry: Geometry::Primitive(s),
        }
    }

    #[test]
    fn primitives_are_covered_within_the_protrusion() {
        for s in [
            Shape::cuboid([0.2, 0.1, 0.05]),
            Shape::Cylinder {
                radius: 0.05,
                half_length: 0.1,
            },
            Shape::Capsule {
                radius: 0.04,
                half_length: 0.08,
            },
            Shape::Sphere { radius: 0.07 },
        ] {
            let shapes = [shape(s)];
            let spheres = fit(&shapes, 0.01);
            assert!(!spheres.is_empty());
            let parts: Vec<Part> = shapes.iter().map(Part::new).collect();
            let worst = crate::robot::spheres::sphere_protrusion(&parts, &spheres);
            assert!(worst <= 0.01 + 1e-6, "{s:?}: protrusion {worst}");
            // Every surface point (fresh random samples) lies in some sphere.
            let quality = crate::robot::spheres::measure(&shapes, &spheres, 2000, 7);
            assert_eq!(quality.coverage, 1.0, "{s:?}");
        }
    }

    #[test]
    fn a_ball_is_one_sphere() {
        let spheres = fit(&[shape(Shape::Sphere { radius: 0.1 })], 0.01);
        assert_eq!(spheres.len(), 1, "{spheres:?}");
    }

    /// A spherized link (several balls, as VAMP's robots are described) keeps its balls exactly:
    /// refitting them had made every link up to the protrusion fatter.
    #[test]
    fn a_link_of_balls_keeps_them() {
        let balls = [
            ([0.0, 0.0, 0.1], 0.05),
            ([0.0, 0.04, 0.2], 0.03),
            ([0.0, 0.04, 0.2], 0.03),
        ];
        let shapes: Vec<LinkShape> = balls
            .iter()
            .map(|&(c, radius)| LinkShape {
                origin: Pose::translation(c[0], c[1], c[2]),
                geometry: Geometry::Primitive(Shape::Sphere { radius }),
            })
            .collect();
        assert_eq!(fit(&shapes, 0.01), balls.to_vec());
        // A ball beside another part is fitted with it.
        let mut mixed = shapes.clone();
        mixed.push(shape(Shape::cuboid([0.05, 0.05, 0.05])));
        let spheres = fit(&mixed, 0.01);
        assert!(spheres.len() > 3 && !balls.iter().all(|b| spheres.contains(b)));
    }

    #[test]
    fn convex_hull_parts_are_fitted() {
        let mut pts = Vec::new();
        for x in [-0.1, 0.1] {
            for y in [-0.03, 0.03] {
                for z in [-0.02, 0.02] {
                    pts.push([x, y, z]);
                }
            }
        }
        pts.push([0.15, 0.0, 0.0]);
        let hull = Arc::new(ConvexHull::of_points(&pts).unwrap());
        let shapes = [LinkShape {
            origin: Pose::identity(),
            geometry: Geometry::Convex(hull),
        }];
        let spheres = fit(&shapes, 0.01);
        let parts: Vec<Part> = shapes.iter().map(Part::new).collect();
        assert!(crate::robot::spheres::sphere_protrusion(&parts, &spheres) <= 0.01 + 1e-6);
        let quality = crate::robot::spheres::measure(&shapes, &spheres, 2000, 3);
        assert_eq!(quality.coverage, 1.0);
    }
}
