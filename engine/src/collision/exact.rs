//! The exact checker: the robot's collision geometry itself (primitives as they are, meshes as
//! their convex hulls or decompositions) against the environment and against itself, with our
//! `f64` GJK ([`super::gjk`]) over the shapes. It decides what must not depend on the sphere
//! model's conservatism: start and goal validity (naming the contact), the states of a returned
//! path the sphere lanes cannot clear ([`crate::planning::validity::Validity::path_contact`]),
//! and the planner's checks near terminal states that only the spheres touch.
//!
//! Per configuration: forward kinematics, then each moving link's bounding sphere picks the
//! objects it reaches, and each of its parts' bounding spheres those of them GJK is asked
//! about; occupied map voxels are tested as cubes, only where the clearance grid cannot clear
//! the part's ball. Then the moving link pairs, screened by their links' bounding spheres, then
//! by their parts'. Every GJK test first tries the direction that separated the same two shapes
//! last time (a part–object or part–part pair), which along an edge usually settles it. Pairs
//! of links that never move relative to each other are checked once, at construction.

use super::checker::Contact;
use super::gjk::{extent_along, Convex, Placed, Witness};
use super::parry::{convex_within_along, exact_shape, shared_geometry, TOUCH};
use crate::robot::{Link, Robot};
use crate::world::Environment;
use crate::Pose;
use nalgebra::{Point3, Vector3};
use parry3d::shape::SharedShape;
use std::ops::Range;

/// One collision part of a link as a parry3d shape.
#[derive(Clone)]
pub struct ExactPart {
    /// Pose of the parry shape in the link frame.
    pub origin: Pose,
    /// The shape.
    pub shape: SharedShape,
    /// The same for the `f64` GJK ([`super::gjk`]), which decides contacts.
    pub convex: Convex,
    /// Bounding sphere centre in the link frame.
    pub center: [f64; 3],
    /// Bounding sphere radius.
    pub radius: f64,
}

impl std::fmt::Debug for ExactPart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ExactPart")
            .field("center", &self.center)
            .field("radius", &self.radius)
            .finish()
    }
}

/// The robot's exact collision geometry, built once per robot: parts grouped by link.
#[derive(Debug, Clone, Default)]
pub struct ExactModel {
    parts: Vec<ExactPart>,
    link_parts: Vec<Range<usize>>,
    link_bounds: Vec<Option<([f64; 3], f64)>>,
}

impl ExactModel {
    /// Converts every link's collision geometry.
    pub fn build(links: &[Link]) -> ExactModel {
        let mut model = ExactModel::default();
        for link in links {
            let start = model.parts.len();
            for ls in &link.collision {
                let (shape, adjust) = shared_geometry(&ls.geometry);
                let origin = ls.origin * adjust;
                let aabb = shape.compute_local_aabb();
                let (lo, hi) = (aabb.mins, aabb.maxs);
                let mid = Vector3::new(
                    ((lo.x + hi.x) / 2.0) as f64,
                    ((lo.y + hi.y) / 2.0) as f64,
                    ((lo.z + hi.z) / 2.0) as f64,
                );
                let half = Vector3::new(
                    ((hi.x - lo.x) / 2.0) as f64,
                    ((hi.y - lo.y) / 2.0) as f64,
                    ((hi.z - lo.z) / 2.0) as f64,
                );
                let c = origin * Point3::from(mid);
                let convex = Convex::from_parry(&*shape).expect("exact parts are convex");
                model.parts.push(ExactPart {
                    origin,
                    convex,
                    shape,
                    center: [c.x, c.y, c.z],
                    radius: half.norm() + 1e-6,
                });
            }
            let range = start..model.parts.len();
            model.link_bounds.push(bound(&model.parts[range.clone()]));
            model.link_parts.push(range);
        }
        model
    }

    /// The parts of link `link`.
    pub fn link_parts(&self, link: usize) -> &[ExactPart] {
        &self.parts[self.link_parts[link].clone()]
    }

    /// The numbers of link `link`'s parts among all parts.
    fn part_numbers(&self, link: usize) -> Range<usize> {
        self.link_parts[link].clone()
    }

    /// Parts of all links.
    fn part_count(&self) -> usize {
        self.parts.len()
    }

    /// A sphere (link frame) containing link `link`'s geometry, if it has any.
    pub fn link_bound(&self, link: usize) -> Option<([f64; 3], f64)> {
        self.link_bounds[link]
    }
}

fn bound(parts: &[ExactPart]) -> Option<([f64; 3], f64)> {
    if parts.is_empty() {
        return None;
    }
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for p in parts {
        let c = Vector3::from(p.center);
        lo = lo.inf(&(c - Vector3::repeat(p.radius)));
        hi = hi.sup(&(c + Vector3::repeat(p.radius)));
    }
    let mid = (lo + hi) / 2.0;
    let r = parts
        .iter()
        .map(|p| (Vector3::from(p.center) - mid).norm() + p.radius)
        .fold(0.0, f64::max);
    Some(([mid.x, mid.y, mid.z], r))
}

/// An environment object as a parry shape with a bounding sphere.
struct ExactObject {
    convex: Convex,
    pose: Pose,
    /// World axis-aligned bounds: the broad phase against parts' bounding spheres.
    lo: Vector3<f64>,
    hi: Vector3<f64>,
}

/// Added to a part's bounding radius where its ball alone clears it of an object (metres):
/// above the rounding of the ball's placement and the contact tolerance.
const BALL_SLACK: f64 = 1e-6;

/// The world boxes of the first 64 objects, each corner coordinate in an array padded to a
/// multiple of four with empty boxes: the links' broad phase, four objects per AVX2
/// instruction when the CPU has it.
struct ObjectBoxes {
    lo: [Vec<f64>; 3],
    hi: [Vec<f64>; 3],
    /// Read only where the AVX2 paths are compiled (x86-64).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    avx2: bool,
}

impl ObjectBoxes {
    fn new(objects: &[ExactObject]) -> Self {
        let n = objects.len().min(64);
        let corner = |k: usize, of: fn(&ExactObject) -> &Vector3<f64>, empty: f64| {
            let mut v: Vec<f64> = objects[..n].iter().map(|o| of(o)[k]).collect();
            v.resize(n.div_ceil(4) * 4, empty);
            v
        };
        ObjectBoxes {
            lo: [0, 1, 2].map(|k| corner(k, |o| &o.lo, f64::INFINITY)),
            hi: [0, 1, 2].map(|k| corner(k, |o| &o.hi, f64::NEG_INFINITY)),
            avx2: crate::collision::batch::lanes::has_avx2(),
        }
    }

    /// The objects (bit `o` for object `o`) whose box is within `reach2` (squared) of `c`.
    fn near(&self, c: &Vector3<f64>, reach2: f64) -> u64 {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            return unsafe { self.near_avx2(c, reach2) };
        }
        let mut near = 0u64;
        for o in 0..self.lo[0].len() {
            near |= u64::from(self.gap2(o, c) <= reach2) << o;
        }
        near
    }

    /// Squared distance from `c` to box `o` ([`box_gap2`], whose operations the vector path
    /// repeats one for one).
    fn gap2(&self, o: usize, c: &Vector3<f64>) -> f64 {
        box_gap2(|k| (self.lo[k][o], self.hi[k][o]), c)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn near_avx2(&self, c: &Vector3<f64>, reach2: f64) -> u64 {
        use std::arch::x86_64::*;
        let (zero, reach2) = (_mm256_setzero_pd(), _mm256_set1_pd(reach2));
        let mut near = 0u64;
        for o in (0..self.lo[0].len()).step_by(4) {
            let mut sum = zero;
            for k in 0..3 {
                let ck = _mm256_set1_pd(c[k]);
                // SAFETY: the arrays' lengths are multiples of four, and o + 4 within them.
                let (lo, hi) = unsafe {
                    (
                        _mm256_loadu_pd(self.lo[k].as_ptr().add(o)),
                        _mm256_loadu_pd(self.hi[k].as_ptr().add(o)),
                    )
                };
                // `max(a, b)` is `a > b ? a : b`, as `gap2` writes it.
                let d = _mm256_max_pd(_mm256_sub_pd(lo, ck), _mm256_sub_pd(ck, hi));
                let d = _mm256_max_pd(d, zero);
                let d2 = _mm256_mul_pd(d, d);
                sum = if k == 0 { d2 } else { _mm256_add_pd(sum, d2) };
            }
            let within = _mm256_cmp_pd::<_CMP_LE_OQ>(sum, reach2);
            near |= (_mm256_movemask_pd(within) as u64) << o;
        }
        near
    }
}

/// Squared distance from `c` to the box whose bounds along axis `k` are `bounds(k)`, in plain
/// comparisons (nalgebra's generic `sup` took several instructions per component).
#[inline(always)]
fn box_gap2(bounds: impl Fn(usize) -> (f64, f64), c: &Vector3<f64>) -> f64 {
    let max = |a: f64, b: f64| if a > b { a } else { b };
    let d = |k: usize| {
        let (lo, hi) = bounds(k);
        max(max(lo - c[k], c[k] - hi), 0.0)
    };
    let (x, y, z) = (d(0), d(1), d(2));
    x * x + y * y + z * z
}

/// Exact validity of configurations of one robot in one environment.
///
/// ```
/// use ember_engine::{collision::exact::ExactChecker, robot::Robot, world::Environment};
/// let fetch = Robot::builtin("fetch").unwrap();
/// let env = Environment::new();
/// let mut sut = ExactChecker::new(&fetch, &env);
/// assert_eq!(sut.contact(fetch.named_state("stow").unwrap()), None);
/// ```
pub struct ExactChecker<'a> {
    robot: &'a Robot,
    env: &'a Environment,
    poses: Vec<Pose>,
    /// Per link: its bounding sphere's centre in the world, as of the last configuration
    /// (placed once per check: a link meets several others).
    bounds: Vec<Vector3<f64>>,
    /// Per pair of a part and an object (part-major), then per pair of parts: the last
    /// direction that separated them or GJK ended on, and their last support points, tried
    /// first the next time (see [`gjk::separated_along`](super::gjk::separated_along)).
    witnesses: Vec<Witness>,
    /// Per link, whether a check needs its pose; the links posed, in order (scratch).
    needed: Vec<bool>,
    chain: Vec<usize>,
    objects: Vec<ExactObject>,
    /// The first 64 objects' boxes, for the links' broad phase.
    boxes: ObjectBoxes,
    /// The robot-only part: which links and pairs move.
    rest: &'a Rest,
    static_contact: Option<Contact>,
    checks: u64,
    /// Per link, metres: a link within this of an object or the map, or two links within the
    /// sum of theirs, count as touching ([`ExactChecker::set_margins`]); empty for none.
    margins: Vec<f64>,
    /// Per pair of links (`links × links`), at most this of the sum; empty for no cap.
    pair_margins: Vec<f64>,
}

/// What the exact checker derives from the robot alone (built once per robot,
/// [`Robot::prepared`]): link poses at the middle of the limits, and which links and pairs
/// move.
#[derive(Clone)]
pub(crate) struct Rest {
    poses: Vec<Pose>,
    moving_links: Vec<usize>,
    /// Links with geometry that never move.
    fixed_links: Vec<usize>,
    moving_pairs: Vec<(usize, usize)>,
    /// Pairs that keep their relative pose.
    fixed_pairs: Vec<(usize, usize)>,
}

impl Rest {
    pub(crate) fn new(robot: &Robot) -> Self {
        let n = robot.links().len();
        let (moving_links, fixed_links): (Vec<usize>, Vec<usize>) = (0..n)
            .filter(|&l| robot.exact_model().link_bound(l).is_some())
            .partition(|&l| robot.link_moves(l));
        let (moving_pairs, fixed_pairs) = robot.partition_pairs();
        let mut poses = vec![Pose::identity(); n];
        robot.forward_kinematics(&robot.middle(), &mut poses);
        Rest {
            poses,
            moving_links,
            fixed_links,
            moving_pairs,
            fixed_pairs,
        }
    }
}

impl<'a> ExactChecker<'a> {
    /// A checker for `robot` in `env` (object shapes are converted once here).
    pub fn new(robot: &'a Robot, env: &'a Environment) -> Self {
        let prepared = robot.prepared();
        let mut sut = Self::at_rest(robot, env, &prepared.exact);
        // The links that never move against the world here; against each other once per robot.
        sut.static_contact = sut
            .first_contact(&prepared.exact.fixed_links, &[])
            .or_else(|| prepared.fixed_self_contact.clone());
        sut
    }

    /// The contact between links that never move apart, if any (see
    /// [`ExactChecker::static_contact`]): the same in every environment.
    pub(crate) fn fixed_self_contact(robot: &Robot, rest: &Rest) -> Option<Contact> {
        let mut sut = ExactChecker::at_rest(robot, super::prepared::nothing(), rest);
        sut.first_contact(&[], &rest.fixed_pairs)
    }

    /// A checker with the robot at the middle of its limits, static contact not yet decided.
    fn at_rest(robot: &'a Robot, env: &'a Environment, rest: &'a Rest) -> Self {
        let objects = env
            .objects()
            .iter()
            .zip(env.placed())
            .map(|(o, placed)| {
                let (convex, adjust) = exact_shape(&o.shape);
                ExactObject {
                    convex,
                    pose: o.pose * adjust,
                    lo: Vector3::from(placed.lo) - Vector3::repeat(1e-6),
                    hi: Vector3::from(placed.hi) + Vector3::repeat(1e-6),
                }
            })
            .collect::<Vec<_>>();
        let parts = robot.exact_model().part_count();
        let mut sut = ExactChecker {
            robot,
            env,
            poses: rest.poses.clone(),
            bounds: vec![Vector3::zeros(); rest.poses.len()],
            witnesses: vec![Witness::default(); parts * (objects.len() + parts)],
            needed: vec![false; rest.poses.len()],
            chain: Vec::with_capacity(rest.poses.len()),
            boxes: ObjectBoxes::new(&objects),
            objects,
            rest,
            static_contact: None,
            checks: 0,
            margins: Vec::new(),
            pair_margins: Vec::new(),
        };
        sut.place_bounds(0..rest.poses.len());
        sut
    }

    /// The robot checked.
    pub fn robot(&self) -> &'a Robot {
        self.robot
    }

    /// The environment checked against.
    pub fn environment(&self) -> &'a Environment {
        self.env
    }

    /// The contact among the parts that never move (links fixed to the root against the
    /// world, and link pairs that keep their relative pose), if any: it blocks every
    /// configuration.
    pub fn static_contact(&self) -> Option<&Contact> {
        self.static_contact.as_ref()
    }

    /// From now on, link `l` counts as touching an object or the map within `margins[l]`
    /// metres of it (links past the slice's end: none), and links `a` and `b` each other
    /// within the sum of theirs or `pairs[a * links + b]`, whichever is less (`pairs` empty:
    /// the sum); empty slices restore plain contact. Links that never move are decided once
    /// ([`ExactChecker::static_contact`]), without a margin.
    pub fn set_margins(&mut self, margins: &[f64], pairs: &[f64]) {
        self.set_link_margins(margins);
        self.pair_margins.clear();
        self.pair_margins.extend(pairs.iter().map(|m| m.max(0.0)));
    }

    /// [`ExactChecker::set_margins`] of the links alone, the pairs' caps kept (a caller
    /// whose caps change less often than its links' margins).
    pub fn set_link_margins(&mut self, margins: &[f64]) {
        self.margins.clear();
        self.margins.extend(margins.iter().map(|m| m.max(0.0)));
    }

    /// Configurations checked so far.
    pub fn checks(&self) -> u64 {
        self.checks
    }

    /// What `q` touches first (an object, the map, or another link), or `None` when it is
    /// free. `q` must have the robot's DOF.
    pub fn contact(&mut self, q: &[f64]) -> Option<Contact> {
        self.contact_of(q, true, true)
    }

    /// [`ExactChecker::contact`] of some parts only: the links against the objects and the
    /// map when `env`, the links against each other when `pairs` (for a caller that knows
    /// the rest clear: the sphere lanes' [`StateFlags`](super::batch::StateFlags)).
    pub fn contact_of(&mut self, q: &[f64], env: bool, pairs: bool) -> Option<Contact> {
        let rest = self.rest;
        let links: &[usize] = if env { &rest.moving_links } else { &[] };
        let pairs: &[(usize, usize)] = if pairs { &rest.moving_pairs } else { &[] };
        self.contact_of_parts(q, links, pairs)
    }

    /// [`ExactChecker::contact`] of the moving `links` against the objects and the map, and
    /// of the `pairs` of links against each other, only (for a caller that knows the other
    /// parts clear: the sphere lanes'
    /// [`BatchChecker::flagged_links`](super::batch::BatchChecker::flagged_links) and
    /// [`BatchChecker::flagged_pairs`](super::batch::BatchChecker::flagged_pairs)).
    pub fn contact_of_parts(
        &mut self,
        q: &[f64],
        links: &[usize],
        pairs: &[(usize, usize)],
    ) -> Option<Contact> {
        self.checks += 1;
        if let Some(c) = &self.static_contact {
            return Some(c.clone());
        }
        // Only the links asked about and those they hang from are posed (in order, parents
        // first), and only the links asked about have their bounds placed.
        let tree = self.robot.links();
        self.needed.fill(false);
        for &l in links.iter().chain(pairs.iter().flat_map(|(a, b)| [a, b])) {
            let mut at = Some(l);
            while let Some(i) = at.filter(|&i| !self.needed[i]) {
                self.needed[i] = true;
                at = tree[i].parent;
            }
        }
        let mut chain = std::mem::take(&mut self.chain);
        chain.clear();
        chain.extend((0..tree.len()).filter(|&i| self.needed[i]));
        self.robot.forward_kinematics_of(&chain, q, &mut self.poses);
        self.chain = chain;
        let pair_links = pairs.iter().flat_map(|&(a, b)| [a, b]);
        self.place_bounds(links.iter().copied().chain(pair_links));
        self.first_contact(links, pairs)
    }

    /// The links with geometry that move, and the pairs of links that move one relative to
    /// the other: what [`ExactChecker::contact`] tests.
    pub fn moving_parts(&self) -> (&[usize], &[(usize, usize)]) {
        (&self.rest.moving_links, &self.rest.moving_pairs)
    }

    /// True when `q` is free in the exact geometry.
    pub fn is_valid(&mut self, q: &[f64]) -> bool {
        self.contact(q).is_none()
    }

    /// The first contact along the straight motion from `a` to `b` at `resolution` (ends
    /// included), with the interpolation parameter where it occurs.
    pub fn motion_contact(
        &mut self,
        a: &[f64],
        b: &[f64],
        resolution: f64,
    ) -> Option<(f64, Contact)> {
        let n = super::checker::motion_steps(self.robot, a, b, resolution).max(1);
        let mut q = vec![0.0; a.len()];
        for k in 0..=n {
            let t = k as f64 / n as f64;
            self.robot.interpolate(a, b, t, &mut q);
            if let Some(c) = self.contact(&q) {
                return Some((t, c));
            }
        }
        None
    }

    /// Places the bounding spheres of `links` (those with geometry) at the link poses held.
    fn place_bounds(&mut self, links: impl IntoIterator<Item = usize>) {
        let model = self.robot.exact_model();
        for l in links {
            if let Some((c, _)) = model.link_bound(l) {
                self.bounds[l] = (self.poses[l] * Point3::from(c)).coords;
            }
        }
    }

    /// The first contact of `links` with the world, else of `pairs` with each other, at the
    /// link poses and bounds held.
    fn first_contact(&mut self, links: &[usize], pairs: &[(usize, usize)]) -> Option<Contact> {
        let mut witnesses = std::mem::take(&mut self.witnesses);
        let found = self.contact_among(links, pairs, &mut witnesses);
        self.witnesses = witnesses;
        found
    }

    /// [`ExactChecker::first_contact`] with the link bounds placed, trying and updating the
    /// pairs' `witnesses` (see [`ExactChecker::witnesses`]).
    fn contact_among(
        &self,
        links: &[usize],
        pairs: &[(usize, usize)],
        witnesses: &mut [Witness],
    ) -> Option<Contact> {
        let model = self.robot.exact_model();
        let names = self.robot.links();
        let n_objects = self.objects.len();
        let (object_witnesses, pair_witnesses) =
            witnesses.split_at_mut(model.part_count() * n_objects);
        let out2 = |obj: &ExactObject, c: &Vector3<f64>| box_gap2(|k| (obj.lo[k], obj.hi[k]), c);
        let margin = |l: usize| self.margins.get(l).copied().unwrap_or(0.0);
        for &li in links {
            let m = margin(li);
            // The objects the link's bounding sphere reaches (all past the 64th), which hold
            // every part's sphere (with a hair of slack).
            let near = model.link_bound(li).map_or(0, |(_, r)| {
                let reach = r + m + 1e-6;
                self.boxes.near(&self.bounds[li], reach * reach)
            });
            if near == 0 && n_objects <= 64 && self.env.map().is_none() {
                continue;
            }
            for (pi, part) in model.part_numbers(li).zip(model.link_parts(li)) {
                // The part's pose is composed only for the exact tests.
                let pose = || self.poses[li] * part.origin;
                let c = (self.poses[li] * Point3::from(part.center)).coords;
                let witnesses = &mut object_witnesses[pi * n_objects..][..n_objects];
                let r2 = (part.radius + m) * (part.radius + m);
                for ((o, obj), witness) in self.objects.iter().enumerate().zip(witnesses) {
                    if (o < 64 && near & (1 << o) == 0) || out2(obj, &c) > r2 {
                        continue;
                    }
                    // The part's ball against the object's own shape (a turned object's
                    // world box is loose): a ball clear of it by more than the margin holds
                    // a part clear of it too, without the GJK.
                    let local = obj.pose.inverse_transform_point(&Point3::from(c));
                    let clear = |gap: f64| gap > part.radius + m + BALL_SLACK;
                    if obj.convex.point_gap(&local.coords).is_some_and(clear) {
                        continue;
                    }
                    let (convex, at) = (&obj.convex, &obj.pose);
                    if convex_within_along(&part.convex, &pose(), convex, at, m, witness) {
                        return Some(Contact::Object {
                            link: names[li].name.clone(),
                            object: self.env.objects()[o].name.clone(),
                        });
                    }
                }
                if self.touches_map(part, pose, [c.x, c.y, c.z], m) {
                    return Some(Contact::Object {
                        link: names[li].name.clone(),
                        object: "occupancy map".into(),
                    });
                }
            }
        }
        let links = names.len();
        for &(a, b) in pairs {
            let (a_at, b_at) = ((a, self.bounds[a]), (b, self.bounds[b]));
            let gap = (margin(a) + margin(b)).min(
                self.pair_margins
                    .get(a * links + b)
                    .copied()
                    .unwrap_or(f64::INFINITY),
            );
            if bounds_meet(model, a_at, b_at, gap)
                && parts_touch(model, &self.poses, (a, b), gap, Some(&mut *pair_witnesses))
            {
                return Some(Contact::SelfCollision {
                    link_a: names[a].name.clone(),
                    link_b: names[b].name.clone(),
                });
            }
        }
        None
    }

    /// True when the part (its pose made by `pose`, its ball centred at `center`) comes
    /// within `gap` of an occupied voxel's cube.
    fn touches_map(
        &self,
        part: &ExactPart,
        pose: impl Fn() -> Pose,
        center: [f64; 3],
        gap: f64,
    ) -> bool {
        let Some(map) = self.env.map() else {
            return false;
        };
        // The clearance grid clears most parts in one read; the walk below finds the voxels
        // the part's ball holds itself (asking `sphere_collides` first walked them twice).
        let r = part.radius + gap;
        if map.clearance().is_some_and(|g| g.clear(center, r)) {
            return false;
        }
        let pose = &pose();
        let half = map.resolution() / 2.0;
        let voxel = Convex::Cuboid(Vector3::repeat(half));
        let aabb = part.shape.compute_aabb(&super::parry::to_parry_pose(pose));
        let lo = [aabb.mins.x, aabb.mins.y, aabb.mins.z].map(|v| v as f64 - half - gap);
        let hi = [aabb.maxs.x, aabb.maxs.y, aabb.maxs.z].map(|v| v as f64 + half + gap);
        // A voxel farther from the part's bounding sphere than a hair (well above the
        // contact tolerance) cannot touch the part.
        let reach2 = (r + 1e-6) * (r + 1e-6);
        // The last separating axis found, unit, with the part's extent along it and a voxel's
        // along it: neighbouring voxels (a shelf's face) mostly lie beyond the same plane,
        // which then settles each in a dot product instead of GJK.
        let mut witness = Witness::default();
        let mut slab: Option<(Vector3<f64>, (f64, f64), f64)> = None;
        map.any_occupied_in(lo, hi, |v| {
            if !(0..3).all(|k| v[k] >= lo[k] && v[k] <= hi[k]) || map.voxel_gap2(center, v) > reach2
            {
                return false;
            }
            if let Some((n, (least, most), e)) = &slab {
                let t = n.x * v[0] + n.y * v[1] + n.z * v[2];
                if least - (t + e) > TOUCH + gap || (t - e) - most > TOUCH + gap {
                    return false;
                }
            }
            let at = Pose::translation(v[0], v[1], v[2]);
            if convex_within_along(&part.convex, pose, &voxel, &at, gap, &mut witness) {
                return true;
            }
            let axis = witness.axis;
            let len = axis.norm();
            slab = (len > 0.0).then(|| {
                let n = axis / len;
                let placed = Placed {
                    shape: &part.convex,
                    pose,
                };
                (n, extent_along(&placed, &n), half * n.abs().sum())
            });
            false
        })
    }
}

impl<'a> super::ConfigCheck<'a> for ExactChecker<'a> {
    fn robot(&self) -> &'a Robot {
        self.robot
    }

    fn is_valid(&mut self, q: &[f64]) -> bool {
        ExactChecker::is_valid(self, q)
    }
}

/// True when links `a` and `b` (at link poses `poses`) touch in the exact geometry.
pub fn links_touch(model: &ExactModel, poses: &[Pose], a: usize, b: usize) -> bool {
    let placed = |l: usize| {
        model
            .link_bound(l)
            .map(|(c, _)| (poses[l] * Point3::from(c)).coords)
    };
    match (placed(a), placed(b)) {
        (Some(ba), Some(bb)) => {
            bounds_meet(model, (a, ba), (b, bb), 0.0)
                && parts_touch(model, poses, (a, b), 0.0, None)
        }
        _ => false,
    }
}

/// True when the bounding spheres of links `a` and `b`, centred at `ba` and `bb` in the
/// world, come within `gap` of each other: most pairs are far apart. They hold every part's
/// sphere, so (with a hair of slack for rounding) a pair they keep apart is one
/// [`parts_touch`] would find apart too.
#[inline]
fn bounds_meet(
    model: &ExactModel,
    (a, ba): (usize, Vector3<f64>),
    (b, bb): (usize, Vector3<f64>),
    gap: f64,
) -> bool {
    let (Some((_, ra)), Some((_, rb))) = (model.link_bound(a), model.link_bound(b)) else {
        return false;
    };
    let reach = ra + rb + gap + 1e-6;
    (ba - bb).norm_squared() <= reach * reach
}

/// Parts of a link whose centres [`parts_touch`] places once on the stack (a link with more
/// places them per test).
const PLACED_PARTS: usize = 32;

/// True when a part of link `a` comes within `gap` of a part of link `b` (at link poses
/// `poses`), part pairs screened by their bounding spheres; `witnesses`, when given, holds the
/// part pairs' last separating directions and support points (part-major, one row per part)
/// to try first and update.
fn parts_touch(
    model: &ExactModel,
    poses: &[Pose],
    (a, b): (usize, usize),
    gap: f64,
    mut witnesses: Option<&mut [Witness]>,
) -> bool {
    let parts = model.part_count();
    // `b`'s part centres placed once (not once per part of `a`: a spherized link has dozens of
    // parts, and these products were a third of a path's validation), on the stack.
    let parts_b = model.link_parts(b);
    let mut centres_b = [Point3::origin(); PLACED_PARTS];
    let placed = parts_b.len() <= PLACED_PARTS;
    if placed {
        for (c, pb) in centres_b.iter_mut().zip(parts_b) {
            *c = poses[b] * Point3::from(pb.center);
        }
    }
    for (ia, pa) in model.part_numbers(a).zip(model.link_parts(a)) {
        let ca = poses[a] * Point3::from(pa.center);
        let mut pose_a = None;
        for (k, (ib, pb)) in model.part_numbers(b).zip(parts_b).enumerate() {
            let cb = match placed {
                true => centres_b[k],
                false => poses[b] * Point3::from(pb.center),
            };
            if (ca - cb).norm() > pa.radius + pb.radius + gap {
                continue;
            }
            let pose_a = pose_a.get_or_insert_with(|| poses[a] * pa.origin);
            let mut fresh = Witness::default();
            let witness = match witnesses.as_deref_mut() {
                Some(witnesses) => &mut witnesses[ia * parts + ib],
                None => &mut fresh,
            };
            if convex_within_along(
                &pa.convex,
                pose_a,
                &pb.convex,
                &(poses[b] * pb.origin),
                gap,
                witness,
            ) {
                return true;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::super::parry::convex_touch;
    use super::*;
    use crate::planning::PlannerRng;
    use crate::world::Object;
    use rand::SeedableRng;

    /// The first contact of moving links, tested with no prefilter and no remembered axis:
    /// links in order, each part against each object (in order), then the moving pairs.
    fn oracle(sut: &ExactChecker, q: &[f64]) -> Option<Contact> {
        let (robot, model) = (sut.robot, sut.robot.exact_model());
        let mut poses = vec![Pose::identity(); robot.links().len()];
        robot.forward_kinematics(q, &mut poses);
        let names = robot.links();
        let objects = sut.env.objects();
        for &l in &sut.rest.moving_links {
            for part in model.link_parts(l) {
                for o in objects {
                    let (convex, adjust) = exact_shape(&o.shape);
                    let at = poses[l] * part.origin;
                    if convex_touch(&part.convex, &at, &convex, &(o.pose * adjust)) {
                        let (link, object) = (names[l].name.clone(), o.name.clone());
                        return Some(Contact::Object { link, object });
                    }
                }
                // Every occupied voxel, as a cube.
                let Some(map) = sut.env.map() else {
                    continue;
                };
                let voxel = Convex::Cuboid(Vector3::repeat(map.resolution() / 2.0));
                let at = poses[l] * part.origin;
                if map.occupied_voxels().any(|v| {
                    convex_touch(
                        &part.convex,
                        &at,
                        &voxel,
                        &Pose::translation(v[0], v[1], v[2]),
                    )
                }) {
                    let link = names[l].name.clone();
                    return Some(Contact::Object {
                        link,
                        object: "occupancy map".into(),
                    });
                }
            }
        }
        sut.rest.moving_pairs.iter().find_map(|&(a, b)| {
            let touch = model.link_parts(a).iter().any(|pa| {
                model.link_parts(b).iter().any(|pb| {
                    let (ta, tb) = (poses[a] * pa.origin, poses[b] * pb.origin);
                    convex_touch(&pa.convex, &ta, &pb.convex, &tb)
                })
            });
            touch.then(|| Contact::SelfCollision {
                link_a: names[a].name.clone(),
                link_b: names[b].name.clone(),
            })
        })
    }

    /// Walks 30 straight motions of 20 steps between random configurations (where the
    /// remembered separating axes settle most tests) and checks that `sut` names the contact
    /// the oracle does at every step; returns how many steps were free, touched an object
    /// (or the map) and touched the robot itself.
    fn walk_against_oracle(
        sut: &mut ExactChecker,
        rng: &mut PlannerRng,
        label: &str,
    ) -> [usize; 3] {
        let robot = sut.robot;
        let (mut a, mut b, mut q) = (robot.middle(), robot.middle(), robot.middle());
        let mut seen = [0usize; 3];
        for step in 0..600 {
            if step % 20 == 0 {
                a.copy_from_slice(&b);
                robot.sample_uniform(rng, &mut b);
            }
            robot.interpolate(&a, &b, (step % 20) as f64 / 20.0, &mut q);
            let expected = oracle(sut, &q);
            assert_eq!(sut.contact(&q), expected, "{label} {q:?}");
            seen[match expected {
                None => 0,
                Some(Contact::Object { .. }) => 1,
                Some(Contact::SelfCollision { .. }) => 2,
            }] += 1;
        }
        seen
    }

    /// Along random walks of short steps (where the remembered separating axes settle most
    /// tests) and across jumps, among 12 or 70 objects (past the 64 the link screen tracks),
    /// the checker names the contact the oracle does.
    #[test]
    fn contact_answers_as_every_part_and_object_tested() {
        use crate::collision::Shape;
        use rand::Rng;
        // Robot, objects, and the nearest x and the middle z of where they are put.
        for (name, count, x, z) in [
            ("fetch", 12, 0.45, 0.9),
            ("fetch", 70, 0.45, 0.9),
            ("panda", 12, 0.25, 0.4),
        ] {
            let robot = Robot::builtin(name).unwrap();
            let mut rng = PlannerRng::seed_from_u64(3);
            let objects = (0..count).map(|i| {
                let c: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.9..0.9));
                let shape = match i % 3 {
                    0 => Shape::cuboid([0.08, 0.3, 0.05]),
                    1 => Shape::Cylinder {
                        radius: 0.04,
                        half_length: 0.15,
                    },
                    _ => Shape::Sphere { radius: 0.05 },
                };
                // In front of the robot, clear of the links that never move.
                let pose = Pose::translation(x + c[0].abs(), c[1], z + c[2]);
                Object {
                    name: format!("o{i}"),
                    shape,
                    pose,
                }
            });
            let env = Environment::from_objects(objects.collect::<Vec<_>>()).unwrap();
            let mut sut = ExactChecker::new(&robot, &env);
            assert_eq!(sut.static_contact(), None);
            let seen = walk_against_oracle(&mut sut, &mut rng, &format!("{name} {count}"));
            assert!(seen.iter().all(|&n| n > 0), "{name} {count}: {seen:?}");
        }
    }

    /// Among occupied voxels (a shelf's board, side and back, a voxel thick), along random
    /// walks of short steps and across jumps, the checker names the contact the oracle does,
    /// which tests every part against every voxel: the clearance grid, the voxel walk's
    /// filters and the separating planes it carries from voxel to voxel only skip voxels the
    /// part does not touch.
    #[test]
    fn map_contacts_answer_as_every_part_and_voxel_tested() {
        use crate::world::map::{MapParams, OccupancyMap};
        for (name, x, z) in [("fetch", 0.55, 0.75), ("panda", 0.35, 0.3)] {
            let robot = Robot::builtin(name).unwrap();
            let mut map = OccupancyMap::new(MapParams {
                resolution: 0.02,
                ..MapParams::default()
            });
            let cells = |lo: f64, hi: f64| {
                let n = ((hi - lo) / 0.02).round() as i32;
                (0..=n).map(move |i| lo + 0.02 * f64::from(i))
            };
            for u in cells(-0.4, 0.4) {
                for w in cells(0.0, 0.4) {
                    // Board, side wall, back wall.
                    for p in [
                        [x + w, u, z],
                        [x + w, 0.4, z + u.abs()],
                        [x + 0.4, u, z + w],
                    ] {
                        map.set_voxel(map.key_of(p), true);
                    }
                }
            }
            map.refresh_clearance();
            let mut env = Environment::new();
            env.set_map(Some(std::sync::Arc::new(map)));
            let mut sut = ExactChecker::new(&robot, &env);
            assert_eq!(sut.static_contact(), None);
            let mut rng = PlannerRng::seed_from_u64(9);
            let [free, touching, _] = walk_against_oracle(&mut sut, &mut rng, name);
            assert!(free > 0 && touching > 0, "{name}: {free} {touching}");
        }
    }

    /// The links' broad phase finds the boxes within reach, bit for bit the same in AVX2 as
    /// in plain code, for 1 to 70 objects (past the 64 it tracks) and points around them.
    #[test]
    fn object_boxes_near_a_point_are_the_ones_within_reach() {
        use rand::Rng;
        let mut rng = PlannerRng::seed_from_u64(4);
        for count in [1, 3, 4, 5, 13, 64, 70] {
            let objects: Vec<ExactObject> = (0..count)
                .map(|_| {
                    let lo = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
                    let size = Vector3::from_fn(|_, _| rng.random_range(0.0..0.5));
                    ExactObject {
                        convex: Convex::Ball(0.1),
                        pose: Pose::identity(),
                        lo,
                        hi: lo + size,
                    }
                })
                .collect();
            let mut boxes = ObjectBoxes::new(&objects);
            for _ in 0..300 {
                let c = Vector3::from_fn(|_, _| rng.random_range(-1.5..1.5));
                let reach2 = rng.random_range(0.0f64..0.6).powi(2);
                let truth = objects.iter().take(64).enumerate().fold(0u64, |m, (o, b)| {
                    let d = (b.lo - c).sup(&(c - b.hi)).sup(&Vector3::zeros());
                    m | u64::from(d.norm_squared() <= reach2) << o
                });
                let vector = boxes.near(&c, reach2);
                boxes.avx2 = false;
                assert_eq!(boxes.near(&c, reach2), truth, "{count} objects");
                boxes.avx2 = crate::collision::batch::lanes::has_avx2();
                assert_eq!(vector, truth, "{count} objects");
            }
        }
    }

    /// On random configurations in an empty world, the checker names the first moving pair
    /// any two parts of which touch (every part pair tested, no prefilter), else nothing.
    #[test]
    fn contact_names_the_first_touching_pair() {
        let env = Environment::new();
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let mut sut = ExactChecker::new(&robot, &env);
            let mut rng = PlannerRng::seed_from_u64(5);
            let mut q = vec![0.0; robot.dof()];
            let (mut free, mut touching) = (0, 0);
            for _ in 0..300 {
                robot.sample_uniform(&mut rng, &mut q);
                let expected = oracle(&sut, &q);
                assert_eq!(sut.contact(&q), expected, "{name} {q:?}");
                free += usize::from(expected.is_none());
                touching += usize::from(expected.is_some());
            }
            assert!(free > 0 && touching > 0, "{name}: {free} {touching}");
        }
    }

    /// The link-level sphere test only skips pairs no two parts of which touch: on random
    /// configurations, `links_touch` answers as every part pair tested with no prefilter.
    #[test]
    fn links_touch_answers_as_every_part_pair() {
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let model = robot.exact_model();
            let mut rng = PlannerRng::seed_from_u64(11);
            let mut q = vec![0.0; robot.dof()];
            let mut poses = vec![Pose::identity(); robot.links().len()];
            let (mut touching, mut bounds_met) = (0, 0);
            for _ in 0..300 {
                robot.sample_uniform(&mut rng, &mut q);
                robot.forward_kinematics(&q, &mut poses);
                for a in 0..poses.len() {
                    for b in a + 1..poses.len() {
                        let oracle = model.link_parts(a).iter().any(|pa| {
                            model.link_parts(b).iter().any(|pb| {
                                convex_touch(
                                    &pa.convex,
                                    &(poses[a] * pa.origin),
                                    &pb.convex,
                                    &(poses[b] * pb.origin),
                                )
                            })
                        });
                        assert_eq!(links_touch(model, &poses, a, b), oracle, "{name} {a} {b}");
                        touching += usize::from(oracle);
                        if let (Some((ca, ra)), Some((cb, rb))) =
                            (model.link_bound(a), model.link_bound(b))
                        {
                            let d =
                                (poses[a] * Point3::from(ca) - poses[b] * Point3::from(cb)).norm();
                            bounds_met += usize::from(d <= ra + rb && !oracle);
                        }
                    }
                }
            }
            // Both answers occur, and bounds that meet without a contact too.
            assert!(
                touching > 0 && bounds_met > 0,
                "{name}: {touching} {bounds_met}"
            );
        }
    }
}
