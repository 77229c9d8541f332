//! The sphere model: spheres per link, in the link frame, fitted to the link's collision
//! geometry (primitives and mesh hulls alike), plus one bounding sphere per link and clusters of
//! at most [`CLUSTER_SIZE`] neighbouring spheres for the checker's hierarchy.
//!
//! - [`fit`]: the fitter (bounded protrusion, greedy cover of the surface);
//! - [`cache`]: fitted spheres cached by content hash, in memory and on disk;
//! - [`pockets`]: whether an obstacle could hide inside a link clear of its spheres.
//!
//! [`measure`] reports a model's protrusion and coverage against any geometry; [`placed`] puts
//! a model at one configuration.

pub mod cache;
pub mod fit;
pub mod placed;
pub mod pockets;

pub use placed::PlacedSpheres;

use super::{Link, LinkShape};
use cache::{Source, SphereCache};
use fit::{Part, Sphere};
use nalgebra::Vector3;
use pockets::LinkPockets;
use rand::{Rng, SeedableRng};
use serde::Deserialize;
use std::sync::Arc;

/// Parameters of sphere fitting (the `[spheres]` table of the robot file).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpherizeParams {
    /// How far a sphere may stick out of the link's geometry, metres.
    #[serde(alias = "max_growth")]
    pub protrusion: f64,
    /// Per-link overrides of `protrusion` (coarser spheres for large static body parts).
    #[serde(default)]
    pub links: std::collections::BTreeMap<String, f64>,
    /// Protrusion on the hand: the group's tip link and every link below it (the gripper and
    /// its fingers), which reach into shelves and between objects; `None` (the default): as
    /// the rest. A link named in `links` keeps its own, and the hand is never looser than
    /// `protrusion`.
    #[serde(default)]
    pub hand: Option<f64>,
}

/// Default protrusion: 1 cm.
pub const DEFAULT_PROTRUSION: f64 = 0.01;

impl Default for SpherizeParams {
    fn default() -> Self {
        Self {
            protrusion: DEFAULT_PROTRUSION,
            links: Default::default(),
            hand: None,
        }
    }
}

impl SpherizeParams {
    /// The protrusion used for `link`.
    pub fn protrusion_of(&self, link: &str) -> f64 {
        self.links.get(link).copied().unwrap_or(self.protrusion)
    }

    /// These parameters with the hand's protrusion written out per link for `hand_links`
    /// (see [`SpherizeParams::hand`]).
    pub fn with_hand<'a>(&self, hand_links: impl IntoIterator<Item = &'a str>) -> SpherizeParams {
        let mut out = self.clone();
        if let Some(h) = self.hand {
            for name in hand_links {
                out.links
                    .entry(name.to_string())
                    .or_insert(h.min(self.protrusion));
            }
        }
        out
    }

    /// Checks every protrusion is within 2 mm – 10 cm; the message names the offending key.
    pub fn validate(&self) -> Result<(), String> {
        let ok = |v: f64| v.is_finite() && (0.002..=0.1).contains(&v);
        if !ok(self.protrusion) {
            return Err(format!(
                "sphere protrusion must be between 0.002 and 0.1 m, got {}",
                self.protrusion
            ));
        }
        if let Some(h) = self.hand.filter(|&h| !ok(h)) {
            return Err(format!(
                "sphere protrusion of the hand must be between 0.002 and 0.1 m, got {h}"
            ));
        }
        for (link, v) in &self.links {
            if !ok(*v) {
                return Err(format!(
                    "sphere protrusion of link '{link}' must be between 0.002 and 0.1 m, got {v}"
                ));
            }
        }
        Ok(())
    }
}

/// How the model was built: links fitted now, read from disk, or reused from memory.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BuildInfo {
    /// Links fitted by this build.
    pub fitted: usize,
    /// Links read from the disk cache.
    pub from_disk: usize,
    /// Links reused from this process.
    pub from_memory: usize,
    /// Wall time of the build, seconds.
    pub seconds: f64,
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
    /// Per sphere: the radius of a ball at the same centre that lies inside the link's
    /// geometry (the fitter centres each sphere in a convex part, at most the protrusion
    /// farther out than the part's boundary; a link given as balls is its own geometry).
    /// Such a ball touching something means the geometry does.
    pub inner: Vec<f64>,
    /// Per link (indexed like `Robot::links`): the range of its spheres.
    pub ranges: Vec<std::ops::Range<usize>>,
    /// Per link: a sphere (centre in the link frame, radius) containing all its spheres.
    pub bounds: Vec<Option<([f64; 3], f64)>>,
    /// Clusters of neighbouring spheres, grouped by link.
    pub clusters: Vec<Cluster>,
    /// Per link: the range of its clusters.
    pub link_clusters: Vec<std::ops::Range<usize>>,
    /// Per link: where an obstacle could hide inside it clear of its spheres (worked out
    /// when asked; shared by the robot's copies).
    pub pockets: Vec<Arc<LinkPockets>>,
    /// How the model was built.
    pub build: BuildInfo,
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

    /// Fits spheres to every link's collision geometry (through `cache`), grouped into
    /// clusters of neighbours.
    pub fn generate(links: &[Link], params: &SpherizeParams, cache: &SphereCache) -> Self {
        let t = std::time::Instant::now();
        let mut model = SphereModel::default();
        for (i, link) in links.iter().enumerate() {
            model.push_link(i, link, params.protrusion_of(&link.name), cache);
        }
        model.build.seconds = t.elapsed().as_secs_f64();
        model
    }

    /// Appends the spheres of link `index` (the next link: links are added in order).
    pub(crate) fn push_link(
        &mut self,
        index: usize,
        link: &Link,
        protrusion: f64,
        cache: &SphereCache,
    ) {
        debug_assert_eq!(index, self.ranges.len(), "links are added in order");
        let mut spheres: Vec<Sphere> = if link.collision.is_empty() {
            Vec::new()
        } else {
            let (s, source) = cache::fitted(&link.collision, protrusion, cache);
            match source {
                Source::Fitted => self.build.fitted += 1,
                Source::Disk => self.build.from_disk += 1,
                Source::Memory => self.build.from_memory += 1,
            }
            s.to_vec()
        };
        let balls_only = fit::balls(&link.collision).is_some();
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
                self.inner.push(if balls_only {
                    r
                } else {
                    (r - protrusion).max(0.0)
                });
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
        let spheres: Vec<Sphere> = self.link_spheres_in(range.clone()).collect();
        self.pockets.push(Arc::new(LinkPockets::new(
            &link.collision,
            &spheres,
            cache.dir(),
        )));
        self.ranges.push(range);
        self.link_clusters.push(cluster_start..self.clusters.len());
    }

    fn link_spheres_in(&self, range: std::ops::Range<usize>) -> impl Iterator<Item = Sphere> + '_ {
        range.map(move |s| (self.center[s], self.radius[s]))
    }

    /// The spheres of link `link`.
    pub fn link_spheres(&self, link: usize) -> impl Iterator<Item = Sphere> + '_ {
        self.link_spheres_in(self.ranges[link].clone())
    }
}

/// How well spheres fit a link's geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitQuality {
    /// Largest distance from a point of the spheres to the geometry, metres (sampled).
    pub protrusion: f64,
    /// Share of random surface points of the geometry inside some sphere.
    pub coverage: f64,
    /// Largest distance of a surface point of the geometry outside the spheres, metres (0
    /// when they cover it all).
    pub gap: f64,
    /// Surface points drawn.
    pub samples: usize,
}

/// Measures `spheres` (link frame) against the geometry `shapes`: protrusion over 200
/// directions per sphere, coverage over `samples` area-weighted random surface points drawn
/// with `seed`.
pub fn measure(shapes: &[LinkShape], spheres: &[Sphere], samples: usize, seed: u64) -> FitQuality {
    let parts: Vec<Part> = shapes.iter().map(Part::new).collect();
    let outside = |p: [f64; 3]| {
        let p = Vector3::from(p);
        spheres
            .iter()
            .map(|(c, r)| (Vector3::from(*c) - p).norm() - r)
            .fold(f64::INFINITY, f64::min)
    };
    coverage(
        &parts,
        samples,
        seed,
        outside,
        sphere_protrusion(&parts, spheres),
    )
}

/// Largest distance from a point of the spheres (200 directions each) to the parts.
pub(crate) fn sphere_protrusion(parts: &[Part], spheres: &[Sphere]) -> f64 {
    let dirs = fibonacci_directions(200);
    let mut worst: f64 = 0.0;
    for (c, r) in spheres {
        for d in &dirs {
            let p = [c[0] + r * d[0], c[1] + r * d[1], c[2] + r * d[2]];
            let dist = parts
                .iter()
                .map(|q| q.distance(p))
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(dist);
        }
    }
    worst
}

/// How well geometry `ours` matches `reference` (both link frame): the protrusion is the
/// largest distance of a sampled point of `ours`'s surface from `reference`, the coverage the
/// share of `reference`'s surface points inside `ours`.
pub fn compare(
    ours: &[LinkShape],
    reference: &[LinkShape],
    samples: usize,
    seed: u64,
) -> FitQuality {
    let ours_parts: Vec<Part> = ours.iter().map(Part::new).collect();
    let ref_parts: Vec<Part> = reference.iter().map(Part::new).collect();
    let distance = |parts: &[Part], p: [f64; 3]| {
        parts
            .iter()
            .map(|q| q.distance(p))
            .fold(f64::INFINITY, f64::min)
    };
    let mut protrusion: f64 = 0.0;
    surface_samples(&ours_parts, samples, seed, |p| {
        protrusion = protrusion.max(distance(&ref_parts, p));
    });
    coverage(
        &ref_parts,
        samples,
        seed + 1,
        |p| distance(&ours_parts, p),
        protrusion,
    )
}

/// Coverage and gap of `parts`' surface (`samples` random points drawn with `seed`) under a
/// model given by the distance `outside` from a point to it (0 or less: covered).
fn coverage(
    parts: &[Part],
    samples: usize,
    seed: u64,
    outside: impl Fn([f64; 3]) -> f64,
    protrusion: f64,
) -> FitQuality {
    let (mut drawn, mut inside, mut gap) = (0usize, 0usize, 0.0f64);
    surface_samples(parts, samples, seed, |p| {
        let d = outside(p);
        drawn += 1;
        inside += (d <= 1e-6) as usize;
        gap = gap.max(d);
    });
    FitQuality {
        protrusion,
        coverage: if drawn == 0 {
            1.0
        } else {
            inside as f64 / drawn as f64
        },
        gap: gap.max(0.0),
        samples: drawn,
    }
}

/// Calls `f` with `n` area-weighted random points of the parts' union surface (points inside
/// another part are skipped and redrawn).
fn surface_samples(parts: &[Part], n: usize, seed: u64, mut f: impl FnMut([f64; 3])) {
    let triangles: Vec<&[[f64; 3]; 3]> = parts.iter().flat_map(|p| p.triangles()).collect();
    let mut cumulative = Vec::with_capacity(triangles.len());
    let mut total = 0.0;
    for t in &triangles {
        total += fit::triangle_area(t);
        cumulative.push(total);
    }
    if total <= 0.0 {
        return;
    }
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut drawn = 0;
    let mut tries = 0;
    while drawn < n && tries < 20 * n {
        tries += 1;
        let pick = rng.random::<f64>() * total;
        let k = cumulative
            .partition_point(|&c| c < pick)
            .min(triangles.len() - 1);
        let (mut u, mut v): (f64, f64) = (rng.random(), rng.random());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let [a, b, c] = triangles[k].map(Vector3::from);
        let p = a + (b - a) * u + (c - a) * v;
        let p = [p.x, p.y, p.z];
        if parts.iter().any(|q| q.depth(p) > 1e-6) {
            continue;
        }
        drawn += 1;
        f(p);
    }
}

/// Surface triangles of a collision part, in the link frame (primitives tessellated).
pub fn surface_triangles(part: &LinkShape) -> Vec<[[f64; 3]; 3]> {
    Part::new(part).triangles().to_vec()
}

/// `n` unit vectors spread evenly over the sphere (Fibonacci lattice).
pub fn fibonacci_directions(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

/// Splits spheres into spatially coherent groups of at most [`CLUSTER_SIZE`] (median split
/// along the longest axis of the centres' extent).
fn split_clusters(spheres: &mut [Sphere], out: &mut Vec<Vec<Sphere>>) {
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

/// A ball holding the balls `(centers, radii)`, near the smallest such: the bound of a
/// cluster or a link, which the checkers test before what it holds, so a tighter one lets
/// fewer tests through (the verdicts are the same whatever the bound).
fn bounding_sphere(centers: &[[f64; 3]], radii: &[f64]) -> Option<([f64; 3], f64)> {
    if centers.is_empty() {
        return None;
    }
    let balls: Vec<(Vector3<f64>, f64)> = centers
        .iter()
        .zip(radii)
        .map(|(c, &r)| (Vector3::from(*c), r))
        .collect();
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for &(c, r) in &balls {
        lo = lo.inf(&(c - Vector3::repeat(r)));
        hi = hi.sup(&(c + Vector3::repeat(r)));
    }
    // The farthest ball from a centre (the last of equals) and its far side's distance: the
    // radius about that centre.
    let farthest = |m: &Vector3<f64>| {
        balls
            .iter()
            .map(|&(c, r)| ((c, r), (c - m).norm() + r))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .expect("not empty")
    };
    // From the box's middle, shrinking steps towards the farthest ball's far point
    // (Bădoiu–Clarkson), keeping the best centre seen. Whatever the centre, the radius is
    // measured from it, so the ball holds every ball.
    let mut m = (lo + hi) / 2.0;
    const STEPS: usize = 100;
    let mut best = (m, f64::INFINITY);
    for k in 1..=STEPS + 1 {
        let ((c, r), here) = farthest(&m);
        if here < best.1 {
            best = (m, here);
        }
        if k > STEPS {
            break;
        }
        let far = match (c - m).try_normalize(1e-12) {
            Some(u) => c + u * r,
            None => c,
        };
        m += (far - m) / (k as f64 + 1.0);
    }
    let (m, radius) = best;
    Some(([m.x, m.y, m.z], radius))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The hand's bound goes to the hand's links only; a link named on its own keeps its
    /// value, and the hand is never looser than the rest; out-of-range values are refused.
    #[test]
    fn the_hand_bound_applies_to_the_hand_links() {
        let params = SpherizeParams {
            protrusion: 0.01,
            links: [("finger_b".to_string(), 0.003)].into(),
            hand: Some(0.004),
        };
        let p = params.with_hand(["palm", "finger_b"]);
        assert_eq!(p.protrusion_of("palm"), 0.004);
        assert_eq!(p.protrusion_of("finger_b"), 0.003);
        assert_eq!(p.protrusion_of("forearm"), 0.01);
        let tight = SpherizeParams {
            protrusion: 0.003,
            ..params.clone()
        };
        assert_eq!(tight.with_hand(["palm"]).protrusion_of("palm"), 0.003);
        let none = SpherizeParams {
            hand: None,
            ..params.clone()
        };
        assert_eq!(none.with_hand(["palm"]).protrusion_of("palm"), 0.01);
        let bad = SpherizeParams {
            hand: Some(0.0005),
            ..params
        };
        assert!(bad.validate().unwrap_err().contains("hand"));
    }

    proptest! {
        /// The bound holds every ball, is no larger than the ball about the box's middle, and
        /// for two balls is within 1% of the smallest (half their span).
        #[test]
        fn bounds_hold_their_balls_and_are_tight(
            balls in prop::collection::vec(
                (prop::array::uniform3(-0.5f64..0.5), 0.0f64..0.1), 1..40),
        ) {
            let (c, r): (Vec<[f64; 3]>, Vec<f64>) = balls.iter().copied().unzip();
            let (m, radius) = bounding_sphere(&c, &r).unwrap();
            let m = Vector3::from(m);
            let mut lo = Vector3::repeat(f64::INFINITY);
            let mut hi = Vector3::repeat(f64::NEG_INFINITY);
            for (c, r) in &balls {
                let c = Vector3::from(*c);
                prop_assert!((c - m).norm() + r <= radius + 1e-12);
                lo = lo.inf(&(c - Vector3::repeat(*r)));
                hi = hi.sup(&(c + Vector3::repeat(*r)));
            }
            let mid = (lo + hi) / 2.0;
            let boxed = balls
                .iter()
                .map(|(c, r)| (Vector3::from(*c) - mid).norm() + r)
                .fold(0.0, f64::max);
            prop_assert!(radius <= boxed + 1e-12);
            if let [(a, ra), (b, rb)] = balls[..] {
                let span = ((Vector3::from(a) - Vector3::from(b)).norm() + ra + rb) / 2.0;
                let smallest = span.max(ra).max(rb);
                prop_assert!(radius <= smallest * 1.01 + 1e-9, "{radius} against {smallest}");
            }
        }
    }

    #[test]
    fn three_corners_get_their_circle_not_the_box() {
        // The box's middle is 0.866 from each corner; the three far corners' circle (0.816)
        // holds the origin too.
        let c = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let (m, radius) = bounding_sphere(&c, &[0.0; 4]).unwrap();
        let circle = (2.0f64 / 3.0).sqrt();
        assert!(radius <= circle * 1.01, "{radius} about {m:?}");
    }
}
