//! Distance between two convex shapes by GJK (Gilbert, Johnson, Keerthi), in `f64`, over the
//! shapes' support functions. The exact checker's distances and contact decisions come from
//! here: parry3d 0.31's own GJK (`f32`) reports some separated pairs as touching (a 59×13×25 mm
//! box 4.8 mm from a 35 mm cylinder: distance 0, "intersecting").
//!
//! The simplex is reduced to the feature nearest the origin each step (segment, triangle and
//! tetrahedron cases as in Ericson, *Real-Time Collision Detection*, 5.1); iteration stops when
//! the distance is known to within 0.1 µm (curved shapes converge slowly, and nothing here
//! needs more), and the returned value is the lower bound `v·w / |v|`: a distance is never
//! overstated.

use crate::Pose;
use nalgebra::Vector3;
use parry3d::shape::Shape as ParryShape;

type V = Vector3<f64>;

/// A convex shape in its own frame, as the exact model holds them.
#[derive(Debug, Clone)]
pub enum Convex {
    /// Ball of this radius.
    Ball(f64),
    /// Box of these half extents.
    Cuboid(V),
    /// A segment swept by a ball.
    Capsule {
        /// One end.
        a: V,
        /// The other end.
        b: V,
        /// Radius.
        r: f64,
    },
    /// Cylinder along local Y (parry3d's convention).
    Cylinder {
        /// Half height.
        h: f64,
        /// Radius.
        r: f64,
    },
    /// Convex hull of these points (coordinates in three arrays of equal length, a multiple
    /// of [`HULL_LANES`], scanned four at a time; [`Convex::hull`] pads them by repeating the
    /// first point).
    Hull {
        /// x of each point.
        x: Vec<f64>,
        /// y of each point.
        y: Vec<f64>,
        /// z of each point.
        z: Vec<f64>,
        /// Its edges, when known: the support then climbs from a hint instead of scanning.
        edges: HullEdges,
    },
}

/// A hull's edges as each point's neighbours (the points' graph): `next[first[i]..first[i +
/// 1]]` lists point `i`'s. Empty when the edges are not known.
#[derive(Debug, Clone, Default)]
pub struct HullEdges {
    first: Vec<u32>,
    next: Vec<u32>,
}

impl HullEdges {
    /// The graph of `points` points and these `edges` (pairs of point numbers); empty (not
    /// known) when an edge names no point or a point has no edge.
    fn new(points: usize, edges: &[[u32; 2]]) -> HullEdges {
        let mut degree = vec![0u32; points];
        for e in edges {
            for &v in e {
                match degree.get_mut(v as usize) {
                    Some(d) => *d += 1,
                    None => return HullEdges::default(),
                }
            }
        }
        if points < 2 || degree.contains(&0) {
            return HullEdges::default();
        }
        let mut first = Vec::with_capacity(points + 1);
        first.push(0);
        for d in &degree {
            first.push(first.last().expect("starts at 0") + d);
        }
        let mut fill = first[..points].to_vec();
        let mut next = vec![0; *first.last().expect("one per point and one") as usize];
        for &[a, b] in edges {
            for (from, to) in [(a, b), (b, a)] {
                next[fill[from as usize] as usize] = to;
                fill[from as usize] += 1;
            }
        }
        HullEdges { first, next }
    }
}

/// Where a pair's support points were last found: one hint per shape (a point of each hull,
/// see [`Convex::support_from`]), with the pair's last separating direction (see
/// [`separated_along`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Witness {
    /// The last direction (zero: none yet).
    pub axis: V,
    /// The last support point of each shape (its number in a hull; 0 for other shapes).
    pub hints: [u32; 2],
}

impl Convex {
    /// The shape of a parry3d convex shape; `None` for kinds the exact model never holds.
    pub fn from_parry(shape: &dyn ParryShape) -> Option<Convex> {
        let v = |p: parry3d::math::Vector| V::new(p.x as f64, p.y as f64, p.z as f64);
        if let Some(b) = shape.as_ball() {
            return Some(Convex::Ball(b.radius as f64));
        }
        if let Some(c) = shape.as_cuboid() {
            return Some(Convex::Cuboid(v(c.half_extents)));
        }
        if let Some(c) = shape.as_capsule() {
            return Some(Convex::Capsule {
                a: v(c.segment.a),
                b: v(c.segment.b),
                r: c.radius as f64,
            });
        }
        if let Some(c) = shape.as_cylinder() {
            return Some(Convex::Cylinder {
                h: c.half_height as f64,
                r: c.radius as f64,
            });
        }
        if let Some(c) = shape.as_convex_polyhedron() {
            let edges: Vec<[u32; 2]> = c.edges().iter().map(|e| e.vertices).collect();
            return Some(Convex::hull_with_edges(
                c.points().iter().map(|&p| v(p)),
                &edges,
            ));
        }
        None
    }

    /// The convex hull of `points` (not empty), their coordinates padded to a multiple of
    /// [`HULL_LANES`] by repeating the first point (the first at a maximum wins, so the
    /// repeats are never chosen).
    pub fn hull(points: impl IntoIterator<Item = V>) -> Convex {
        Convex::hull_with_edges(points, &[])
    }

    /// [`Convex::hull`] of points that are the hull's vertices, with the hull's edges
    /// (pairs of point numbers; all of them, or none): its supports then climb along the
    /// edges ([`Convex::support_from`]).
    pub fn hull_with_edges(points: impl IntoIterator<Item = V>, edges: &[[u32; 2]]) -> Convex {
        let (mut x, mut y, mut z) = (Vec::new(), Vec::new(), Vec::new());
        for p in points {
            x.push(p.x);
            y.push(p.y);
            z.push(p.z);
        }
        assert!(!x.is_empty(), "a hull has points");
        let edges = HullEdges::new(x.len(), edges);
        while x.len() % HULL_LANES != 0 {
            x.push(x[0]);
            y.push(y[0]);
            z.push(z[0]);
        }
        Convex::Hull { x, y, z, edges }
    }

    /// [`Convex::support`], from a hint: on a hull whose edges are known, the climb from
    /// point `*hint` along the edges to a point no neighbour of which lies farther along `d`
    /// (on a convex polytope, a farthest point), left in `*hint`; a nearby direction's last
    /// answer makes it a few steps. Other shapes leave the hint alone.
    pub fn support_from(&self, d: &V, hint: &mut u32) -> V {
        match self {
            Convex::Hull { x, y, z, edges } if !edges.first.is_empty() => {
                let at = climb(x, y, z, edges, d, hint);
                V::new(x[at], y[at], z[at])
            }
            _ => self.support(d),
        }
    }

    /// Distance from `p` (in the shape's frame) to the shape, 0 inside it, in closed form;
    /// `None` for a hull (GJK's case). A ball of radius `r` at `p` touches the shape when it
    /// is within `r` (plus the contact tolerance): what GJK finds, without its iterations.
    pub fn point_gap(&self, p: &V) -> Option<f64> {
        Some(match self {
            Convex::Ball(r) => (p.norm() - r).max(0.0),
            Convex::Cuboid(h) => V::new(
                (p.x.abs() - h.x).max(0.0),
                (p.y.abs() - h.y).max(0.0),
                (p.z.abs() - h.z).max(0.0),
            )
            .norm(),
            Convex::Capsule { a, b, r } => {
                let ab = b - a;
                let len2 = ab.norm_squared();
                let t = match len2 > 0.0 {
                    true => ((p - a).dot(&ab) / len2).clamp(0.0, 1.0),
                    false => 0.0,
                };
                ((p - (a + ab * t)).norm() - r).max(0.0)
            }
            Convex::Cylinder { h, r } => {
                let radial = ((p.x * p.x + p.z * p.z).sqrt() - r).max(0.0);
                let axial = (p.y.abs() - h).max(0.0);
                (radial * radial + axial * axial).sqrt()
            }
            Convex::Hull { .. } => return None,
        })
    }

    /// The farthest point along `d` (local frame).
    pub(crate) fn support(&self, d: &V) -> V {
        let unit = |d: &V| {
            let n = d.norm();
            if n > 0.0 {
                d / n
            } else {
                V::zeros()
            }
        };
        match self {
            Convex::Ball(r) => unit(d) * *r,
            Convex::Cuboid(h) => V::new(h.x.copysign(d.x), h.y.copysign(d.y), h.z.copysign(d.z)),
            Convex::Capsule { a, b, r } => {
                let end = if d.dot(a) >= d.dot(b) { a } else { b };
                end + unit(d) * *r
            }
            Convex::Cylinder { h, r } => {
                let radial = (d.x * d.x + d.z * d.z).sqrt();
                let (x, z) = if radial > 0.0 {
                    (d.x / radial * r, d.z / radial * r)
                } else {
                    (0.0, 0.0)
                };
                V::new(x, h.copysign(d.y), z)
            }
            Convex::Hull { x, y, z, .. } => {
                let at = farthest(x, y, z, d);
                V::new(x[at], y[at], z[at])
            }
        }
    }
}

/// [`Convex::support_from`]'s climb on a hull's points along its edges.
fn climb(x: &[f64], y: &[f64], z: &[f64], edges: &HullEdges, d: &V, hint: &mut u32) -> usize {
    let along = |i: usize| x[i] * d.x + y[i] * d.y + z[i] * d.z;
    let points = edges.first.len() - 1;
    let mut at = (*hint as usize).min(points - 1);
    let mut best = along(at);
    loop {
        let from = at;
        let (start, end) = (edges.first[from] as usize, edges.first[from + 1] as usize);
        for &j in &edges.next[start..end] {
            let v = along(j as usize);
            if v > best {
                (best, at) = (v, j as usize);
            }
        }
        if at == from {
            break;
        }
    }
    *hint = at as u32;
    at
}

/// Points a hull's support scans at once (`f64` lanes of an AVX2 register).
pub const HULL_LANES: usize = 4;

/// The index of the point of `(x, y, z)` farthest along `d`: the first at the maximum of
/// `x·d.x + y·d.y + z·d.z` (each product rounded, then summed left to right). Four points at
/// a time where AVX2 is available, with the same roundings and the same choice as
/// [`farthest_scalar`].
#[inline]
fn farthest(x: &[f64], y: &[f64], z: &[f64], d: &V) -> usize {
    #[cfg(target_arch = "x86_64")]
    if x.len() >= HULL_LANES && std::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 was detected just now.
        return unsafe { farthest_avx2(x, y, z, d) };
    }
    farthest_scalar(x, y, z, d)
}

/// [`farthest`], one point at a time (the fallback and the lanes' test oracle).
fn farthest_scalar(x: &[f64], y: &[f64], z: &[f64], d: &V) -> usize {
    let n = x.len();
    let (x, y, z) = (&x[..n], &y[..n], &z[..n]);
    let (mut best, mut at) = (f64::NEG_INFINITY, 0);
    for i in 0..n {
        let v = x[i] * d.x + y[i] * d.y + z[i] * d.z;
        if v > best {
            best = v;
            at = i;
        }
    }
    at
}

/// [`farthest`] in AVX2 lanes: each lane keeps its first maximum over the points `i ≡ lane
/// (mod 4)`; the lanes' greatest wins, the lowest index among equals. Points past the last
/// whole group of four are scanned one at a time.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn farthest_avx2(x: &[f64], y: &[f64], z: &[f64], d: &V) -> usize {
    use std::arch::x86_64::*;
    let n = x.len().min(y.len()).min(z.len());
    let whole = n - n % HULL_LANES;
    let (dx, dy, dz) = (
        _mm256_set1_pd(d.x),
        _mm256_set1_pd(d.y),
        _mm256_set1_pd(d.z),
    );
    let mut best = _mm256_set1_pd(f64::NEG_INFINITY);
    let mut best_at = _mm256_setzero_pd();
    let mut at = _mm256_setr_pd(0.0, 1.0, 2.0, 3.0);
    let step = _mm256_set1_pd(HULL_LANES as f64);
    let mut i = 0;
    while i < whole {
        // SAFETY: i + 4 <= whole <= the length of each array.
        let (px, py, pz) = unsafe {
            (
                _mm256_loadu_pd(x.as_ptr().add(i)),
                _mm256_loadu_pd(y.as_ptr().add(i)),
                _mm256_loadu_pd(z.as_ptr().add(i)),
            )
        };
        let v = _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(px, dx), _mm256_mul_pd(py, dy)),
            _mm256_mul_pd(pz, dz),
        );
        let more = _mm256_cmp_pd::<_CMP_GT_OQ>(v, best);
        best = _mm256_blendv_pd(best, v, more);
        best_at = _mm256_blendv_pd(best_at, at, more);
        at = _mm256_add_pd(at, step);
        i += HULL_LANES;
    }
    let (mut values, mut indices) = ([0.0; HULL_LANES], [0.0; HULL_LANES]);
    // SAFETY: both arrays hold four f64.
    unsafe {
        _mm256_storeu_pd(values.as_mut_ptr(), best);
        _mm256_storeu_pd(indices.as_mut_ptr(), best_at);
    }
    let (mut top, mut top_at) = (f64::NEG_INFINITY, 0);
    for k in 0..HULL_LANES {
        let index = indices[k] as usize;
        if values[k] > top || (values[k] == top && index < top_at) {
            (top, top_at) = (values[k], index);
        }
    }
    for j in whole..n {
        let v = x[j] * d.x + y[j] * d.y + z[j] * d.z;
        if v > top {
            (top, top_at) = (v, j);
        }
    }
    top_at
}

/// A shape placed in the world.
pub struct Placed<'a> {
    /// The shape.
    pub shape: &'a Convex,
    /// Its pose.
    pub pose: &'a Pose,
}

/// A placed shape with its rotation as a matrix (support points are taken many times).
struct Frame<'a> {
    shape: &'a Convex,
    rotation: nalgebra::Matrix3<f64>,
    translation: V,
}

impl<'a> Frame<'a> {
    fn of(p: &Placed<'a>) -> Self {
        Frame {
            shape: p.shape,
            rotation: p.pose.rotation.to_rotation_matrix().into_inner(),
            translation: p.pose.translation.vector,
        }
    }

    /// The support point along `d`, climbing from `hint` where given ([`Convex::support_from`]),
    /// else scanning.
    fn support(&self, d: &V, hint: Option<&mut u32>) -> V {
        let local = self.rotation.tr_mul(d);
        let p = match hint {
            Some(hint) => self.shape.support_from(&local, hint),
            None => self.shape.support(&local),
        };
        self.rotation * p + self.translation
    }
}

/// Convergence: the distance known to within this (metres), or relative 1e-10 of it.
const TOLERANCE: f64 = 1e-7;
const EPS: f64 = 1e-10;

/// The distance between `a` and `b`; 0 when they touch or overlap.
pub fn distance(a: &Placed, b: &Placed) -> f64 {
    run(&Frame::of(a), &Frame::of(b), f64::INFINITY, &mut [0; 2]).0
}

/// The least and greatest of `n · x` over the points `x` of `a`.
pub fn extent_along(a: &Placed, n: &V) -> (f64, f64) {
    // Scanned: a climb from one end of the hull to the other crosses all of it.
    let f = Frame::of(a);
    (n.dot(&f.support(&-n, None)), n.dot(&f.support(n, None)))
}

/// True when `a` and `b` are more than `gap` apart (stops as soon as that is certain).
pub fn separated(a: &Placed, b: &Placed, gap: f64) -> bool {
    separated_along(a, b, gap, &mut Witness::default())
}

/// [`separated`], trying the witness's axis first: when the shapes' extents along it are more
/// than `gap` apart, that settles it with one support point each. Otherwise GJK decides, and
/// the axis is left holding its last direction. Any axis gives a true answer; the last one of
/// the same pair a small motion ago (the states along an edge) usually settles the next. The
/// supports climb from the witness's hints and leave theirs.
pub fn separated_along(a: &Placed, b: &Placed, gap: f64, witness: &mut Witness) -> bool {
    let (fa, fb) = (Frame::of(a), Frame::of(b));
    let Witness { axis, hints } = witness;
    let n2 = axis.norm_squared();
    if n2 > 0.0 {
        // The point of A − B least far along the axis bounds the distance from below.
        let [ha, hb] = hints;
        let w = fa.support(&-*axis, Some(ha)) - fb.support(axis, Some(hb));
        if axis.dot(&w) > gap * n2.sqrt() {
            return true;
        }
    }
    let (lower, v) = run(&fa, &fb, gap, hints);
    *axis = v;
    lower > gap
}

/// The simplex: up to four points of the Minkowski difference.
#[derive(Clone, Copy)]
struct Simplex {
    points: [V; 4],
    len: usize,
}

impl Simplex {
    fn of(points: &[V]) -> Self {
        let mut s = Simplex {
            points: [V::zeros(); 4],
            len: points.len(),
        };
        s.points[..points.len()].copy_from_slice(points);
        s
    }
}

/// GJK; returns a lower bound of the distance, or as soon as the bound exceeds `stop` or the
/// distance is known to be at most `stop`, with the last direction (the point of A − B
/// nearest the origin found). The supports climb from `hints` (one per shape) and leave
/// theirs.
fn run(fa: &Frame, fb: &Frame, stop: f64, hints: &mut [u32; 2]) -> (f64, V) {
    // A point of the Minkowski difference A − B in direction d.
    let [ha, hb] = hints;
    let mut support = |d: &V| fa.support(d, Some(&mut *ha)) - fb.support(&-d, Some(&mut *hb));
    let start = fa.translation - fb.translation;
    let mut v = support(&if start.norm() > 0.0 { -start } else { V::x() });
    let mut simplex = Simplex::of(&[v]);
    let mut lower: f64 = 0.0;
    for _ in 0..128 {
        let vv = v.norm_squared();
        if vv <= 1e-30 {
            return (0.0, v);
        }
        // |v| bounds the distance from above: within a finite `stop`, the bound below cannot
        // exceed it.
        if stop.is_finite() && vv <= stop * stop {
            return (lower.max(0.0), v);
        }
        let w = support(&-v);
        // v·w / |v| bounds the distance from below.
        lower = lower.max(v.dot(&w) / vv.sqrt());
        // |v| − lower ≤ (|v|² − v·w) / |v|: stop once that gap is within the tolerance.
        if lower > stop || vv - v.dot(&w) <= (EPS * vv).max(TOLERANCE * vv.sqrt()) {
            return (lower.max(0.0), v);
        }
        simplex.points[simplex.len] = w;
        simplex.len += 1;
        match closest_on_simplex(&simplex.points[..simplex.len]) {
            None => return (0.0, v),
            Some((p, reduced)) => {
                // No progress: the bound is as good as it gets.
                if p.norm_squared() >= vv * (1.0 - 1e-14) {
                    return (lower.max(0.0), v);
                }
                v = p;
                simplex = reduced;
            }
        }
    }
    (lower.max(0.0), v)
}

/// The point of the simplex nearest the origin and the vertices of the feature it lies on;
/// `None` when the origin is inside a tetrahedron.
fn closest_on_simplex(s: &[V]) -> Option<(V, Simplex)> {
    match s {
        [a] => Some((*a, Simplex::of(&[*a]))),
        [a, b] => Some(segment(a, b)),
        [a, b, c] => Some(triangle(a, b, c)),
        [a, b, c, d] => tetrahedron(a, b, c, d),
        _ => unreachable!("a simplex has at most four vertices"),
    }
}

fn segment(a: &V, b: &V) -> (V, Simplex) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    if len2 <= 0.0 {
        return (*a, Simplex::of(&[*a]));
    }
    let t = (-a.dot(&ab) / len2).clamp(0.0, 1.0);
    match t {
        t if t <= 0.0 => (*a, Simplex::of(&[*a])),
        t if t >= 1.0 => (*b, Simplex::of(&[*b])),
        t => (a + ab * t, Simplex::of(&[*a, *b])),
    }
}

/// Ericson's closest point on a triangle (to the origin), with its feature.
fn triangle(a: &V, b: &V, c: &V) -> (V, Simplex) {
    let (ab, ac, ap) = (b - a, c - a, -a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, Simplex::of(&[*a]));
    }
    let bp = -b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, Simplex::of(&[*b]));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let t = d1 / (d1 - d3);
        return (a + ab * t, Simplex::of(&[*a, *b]));
    }
    let cp = -c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, Simplex::of(&[*c]));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let t = d2 / (d2 - d6);
        return (a + ac * t, Simplex::of(&[*a, *c]));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * t, Simplex::of(&[*b, *c]));
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE {
        // Degenerate (collinear): the best of its edges.
        return [segment(a, b), segment(b, c), segment(a, c)]
            .into_iter()
            .min_by(|x, y| x.0.norm_squared().total_cmp(&y.0.norm_squared()))
            .expect("three edges");
    }
    let (v, w) = (vb / denom, vc / denom);
    (a + ab * v + ac * w, Simplex::of(&[*a, *b, *c]))
}

/// The nearest point over the faces the origin lies outside of; `None` when it is inside.
fn tetrahedron(a: &V, b: &V, c: &V, d: &V) -> Option<(V, Simplex)> {
    // Outside the face (p, q, r) when the origin and the fourth vertex lie on opposite sides.
    let outside = |p: &V, q: &V, r: &V, s: &V| {
        let n = (q - p).cross(&(r - p));
        let origin_side = (-p).dot(&n);
        let vertex_side = (s - p).dot(&n);
        origin_side * vertex_side < 0.0
    };
    let faces = [(a, b, c, d), (a, c, d, b), (a, d, b, c), (b, d, c, a)];
    // A flat tetrahedron has no inside: its nearest face decides.
    let scale = (b - a).norm().max((c - a).norm()).max((d - a).norm());
    let volume = (b - a).dot(&(c - a).cross(&(d - a)));
    let flat = volume.abs() <= 1e-12 * scale * scale * scale;
    let mut best: Option<(V, Simplex)> = None;
    for (p, q, r, s) in faces {
        if flat || outside(p, q, r, s) {
            let candidate = triangle(p, q, r);
            if best
                .as_ref()
                .is_none_or(|b| candidate.0.norm_squared() < b.0.norm_squared())
            {
                best = Some(candidate);
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Translation3, UnitQuaternion};

    fn at(x: f64, y: f64, z: f64) -> Pose {
        Pose::from_parts(Translation3::new(x, y, z), UnitQuaternion::identity())
    }

    proptest::proptest! {
        /// The hull support's lanes choose the point the scalar scan chooses, ties (repeated
        /// and coplanar points) and lengths that are not a multiple of four included.
        #[test]
        fn farthest_in_lanes_is_the_scalar_choice(
            points in proptest::collection::vec((-3i8..=3, -3i8..=3, -3i8..=3), 1..40),
            d in (-2i8..=2, -2i8..=2, -2i8..=2),
            scale in 0.01f64..2.0,
        ) {
            let coord = |k: fn(&(i8, i8, i8)) -> i8| -> Vec<f64> {
                points.iter().map(|p| k(p) as f64 * scale).collect()
            };
            let (x, y, z) = (coord(|p| p.0), coord(|p| p.1), coord(|p| p.2));
            let d = V::new(d.0 as f64, d.1 as f64 * 0.5, d.2 as f64 * 0.25);
            let scalar = farthest_scalar(&x, &y, &z, &d);
            proptest::prop_assert_eq!(farthest(&x, &y, &z, &d), scalar);
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                proptest::prop_assert_eq!(unsafe { farthest_avx2(&x, &y, &z, &d) }, scalar);
            }
            // Padded as the exact model pads them, the same point.
            let hull = Convex::hull((0..x.len()).map(|i| V::new(x[i], y[i], z[i])));
            let i = scalar;
            proptest::prop_assert_eq!(hull.support(&d), V::new(x[i], y[i], z[i]));
        }
    }

    /// On hulls of random point clouds (parry's, with their edges), the climb from any hint
    /// ends at a point as far along the direction as the scan's, and the scan is kept where
    /// the edges are not known or leave a point out.
    #[test]
    fn climbs_reach_the_farthest_point() {
        use parry3d::shape::ConvexPolyhedron;
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(8);
        let mut climbed = 0;
        for _ in 0..60 {
            let n = rng.random_range(4..200);
            let points: Vec<parry3d::math::Vector> = (0..n)
                .map(|_| {
                    let mut v = || rng.random_range(-0.3f32..0.3);
                    parry3d::math::Vector::new(v(), v() * 0.2, v() * 2.0)
                })
                .collect();
            let Some(poly) = ConvexPolyhedron::from_convex_hull(&points) else {
                continue;
            };
            let hull = Convex::from_parry(&poly).expect("a hull");
            let Convex::Hull { x, y, z, edges } = &hull else {
                panic!("a hull");
            };
            assert!(
                !edges.first.is_empty(),
                "parry's hulls come with their edges"
            );
            let count = edges.first.len() - 1;
            for _ in 0..50 {
                let d = V::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let mut hint = rng.random_range(0..count as u32);
                let got = hull.support_from(&d, &mut hint);
                let best = farthest_scalar(x, y, z, &d);
                let top = V::new(x[best], y[best], z[best]).dot(&d);
                assert!(got.dot(&d) >= top - 1e-12, "{} against {top}", got.dot(&d));
                assert_eq!(
                    got,
                    V::new(x[hint as usize], y[hint as usize], z[hint as usize])
                );
                climbed += 1;
            }
        }
        assert!(climbed > 2000);
        // A point without an edge (or an edge past the points): no climbing, the scan.
        let pts = [V::zeros(), V::x(), V::y(), V::z()];
        let lonely = Convex::hull_with_edges(pts, &[[0, 1], [1, 2], [2, 0]]);
        let past = Convex::hull_with_edges(pts, &[[0, 1], [1, 2], [2, 3], [3, 9]]);
        for hull in [lonely, past] {
            let mut hint = 0;
            assert_eq!(hull.support_from(&V::z(), &mut hint), V::z());
        }
    }

    /// The closed-form distance from a point agrees with GJK's distance to a point-sized ball,
    /// for every kind but hulls, at random poses.
    #[test]
    fn point_gaps_are_gjk_distances() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let shapes = [
            Convex::Ball(0.2),
            Convex::Cuboid(V::new(0.3, 0.1, 0.2)),
            Convex::Capsule {
                a: V::new(-0.1, 0.05, 0.0),
                b: V::new(0.2, -0.1, 0.1),
                r: 0.07,
            },
            Convex::Cylinder { h: 0.25, r: 0.1 },
        ];
        let point = Convex::Ball(0.0);
        for shape in &shapes {
            for _ in 0..500 {
                let mut v = || rng.random_range(-0.6..0.6);
                let rotation = UnitQuaternion::from_euler_angles(v(), v(), v());
                let pose = Pose::from_parts(Translation3::new(v(), v(), v()), rotation);
                let p = V::new(v(), v(), v());
                let gap = shape
                    .point_gap(&pose.inverse_transform_vector(&(p - pose.translation.vector)))
                    .unwrap();
                let gjk = distance(
                    &Placed { shape, pose: &pose },
                    &Placed {
                        shape: &point,
                        pose: &at(p.x, p.y, p.z),
                    },
                );
                assert!((gap - gjk).abs() < 1e-6, "{shape:?}: {gap} against {gjk}");
            }
        }
        assert!(shapes[0].point_gap(&V::zeros()) == Some(0.0));
        let hull = Convex::hull([V::zeros(); 4]);
        assert!(hull.point_gap(&V::zeros()).is_none());
    }

    #[test]
    fn simple_pairs_have_their_distances() {
        let ball = Convex::Ball(0.5);
        let cube = Convex::Cuboid(V::new(0.5, 0.5, 0.5));
        let d = |s: &Convex, p: Pose, t: &Convex, q: Pose| {
            distance(
                &Placed { shape: s, pose: &p },
                &Placed { shape: t, pose: &q },
            )
        };
        assert!((d(&ball, at(0.0, 0.0, 0.0), &ball, at(3.0, 0.0, 0.0)) - 2.0).abs() < 1e-9);
        assert!((d(&cube, at(0.0, 0.0, 0.0), &cube, at(0.0, 2.5, 0.0)) - 1.5).abs() < 1e-9);
        assert_eq!(d(&cube, at(0.0, 0.0, 0.0), &ball, at(0.7, 0.2, 0.0)), 0.0);
        // Corner to corner along the diagonal.
        let diag = d(&cube, at(0.0, 0.0, 0.0), &cube, at(2.0, 2.0, 2.0));
        assert!((diag - 3f64.sqrt()).abs() < 1e-9, "{diag}");
        let cyl = Convex::Cylinder { h: 0.5, r: 0.2 };
        assert!((d(&cyl, at(0.0, 0.0, 0.0), &ball, at(1.0, 0.0, 0.0)) - 0.3).abs() < 1e-9);
        assert!((d(&cyl, at(0.0, 0.0, 0.0), &ball, at(0.0, 1.5, 0.0)) - 0.5).abs() < 1e-9);
    }

    /// The least signed distance from a box's surface, sampled `n` × `n` per face, to
    /// `shape` (analytic point distances): an upper bound of the true distance, within the
    /// grid's half diagonal of it.
    fn sampled(half: [f64; 3], pose: &Pose, shape: &crate::collision::Shape, at: &Pose) -> f64 {
        let [hx, hy, hz] = half;
        let n = 60;
        let mut best = f64::INFINITY;
        for i in 0..=n {
            for j in 0..=n {
                let (u, v) = (
                    -1.0 + 2.0 * i as f64 / n as f64,
                    -1.0 + 2.0 * j as f64 / n as f64,
                );
                for p in [
                    [hx, u * hy, v * hz],
                    [-hx, u * hy, v * hz],
                    [u * hx, hy, v * hz],
                    [u * hx, -hy, v * hz],
                    [u * hx, v * hy, hz],
                    [u * hx, v * hy, -hz],
                ] {
                    let l = at.inverse() * (pose * Point3::from(p));
                    best = best.min(crate::collision::distance::distance_point_shape(
                        [l.x, l.y, l.z],
                        shape,
                    ));
                }
            }
        }
        best
    }

    #[test]
    fn boxes_and_cylinders_agree_with_sampled_surfaces() {
        use crate::collision::parry::shape_distance;
        use crate::collision::Shape;
        use rand::{Rng, SeedableRng};
        // Where parry3d 0.31 reports contact: a Fetch finger box 4.8 mm from a can.
        let finger = Pose::from_parts(
            Translation3::new(0.8755042037992072, 0.11065355664291954, 0.7617272387046394),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                0.7767246503389604,
                -0.4764755759195849,
                0.09880159206870362,
                -0.39988509413656387,
            )),
        );
        let can_at = at(0.9346490881643363, 0.07645544744633315, 0.7);
        let can = Shape::Cylinder {
            radius: 0.035,
            half_length: 0.06,
        };
        let half = [0.0297, 0.0066, 0.0126];
        let box_shape = Shape::cuboid(half.map(|h| 2.0 * h));
        let gjk = shape_distance(&box_shape, &finger, &can, &can_at);
        let oracle = sampled(half, &finger, &can, &can_at);
        assert!(
            gjk > 0.004 && gjk <= oracle + 1e-8 && oracle - gjk < 1e-3,
            "{gjk} vs {oracle}"
        );
        // Random boxes against a cylinder: never farther than the surfaces (no contact
        // missed), never nearer than the sampling allows (no contact invented).
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
        let (mut apart, mut touching) = (0, 0);
        for _ in 0..300 {
            let half = [0.03, 0.007, 0.013];
            let pose = Pose::from_parts(
                Translation3::new(
                    rng.random_range(-0.08..0.08),
                    rng.random_range(-0.08..0.08),
                    rng.random_range(-0.1..0.1),
                ),
                UnitQuaternion::from_euler_angles(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                ),
            );
            let gjk = shape_distance(
                &Shape::cuboid(half.map(|h| 2.0 * h)),
                &pose,
                &can,
                &Pose::identity(),
            );
            let oracle = sampled(half, &pose, &can, &Pose::identity());
            // (Dimensions pass through parry3d's f32 shapes: 1e-8 m of slack.)
            assert!(
                gjk <= oracle.max(0.0) + 1e-8,
                "gjk {gjk} beyond the surfaces' {oracle}"
            );
            if oracle > 1e-3 {
                apart += 1;
                assert!(
                    oracle - gjk < 1e-3,
                    "gjk {gjk} nearer than sampled {oracle}"
                );
            }
            touching += (gjk == 0.0) as usize;
        }
        assert!(
            apart > 50 && touching > 50,
            "{apart} apart, {touching} touching"
        );
    }
}
