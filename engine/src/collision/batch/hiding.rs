//! What the batch checker adds when it validates a returned path
//! ([`crate::planning::validity::Validity::path_contact`]): the spheres cover each link's
//! surface, so a state they clear is free in the exact geometry unless an obstacle (an object,
//! a map's voxel, a part of another link) lies wholly inside a link, where the spheres need
//! not reach. Such an obstacle holds a ball of its inradius clear of the link's spheres, which
//! only a link with room for that ball can give ([`LinkPockets`]); and every point of it is
//! inside the link's bound ball and box. So validation also flags a batch where, in some lane,
//! the centre of an object, an occupied voxel, or a point of a part of the other link of a
//! self pair whose bounds meet, lies within the bound of a link with room for it. (A link
//! wholly inside an obstacle touches spheres: they are centred inside the link.)

use super::lanes::F8;
use super::{overlap, overlap_lanes, unclear_lanes, BatchChecker, ObjectKind, SelfPair, MARGIN};
use crate::collision::Shape;
use crate::robot::spheres::pockets::LinkPockets;
use crate::robot::{Geometry, LinkShape, Robot};
use std::ops::Range;
use std::sync::Arc;

/// The radii room is asked for: an obstacle's inradius counts as the largest of them not
/// above it (room for a larger ball implies room for a smaller one), so a robot's pockets are
/// worked out for a few radii only. Below the smallest, room is assumed.
const LADDER: [f64; 5] = [0.0005, 0.001, 0.002, 0.004, 0.008];

/// The robot's parts as validation needs them, and what may hide where in the environment
/// being validated.
#[derive(Clone)]
pub(super) struct Hiding {
    /// Per link: its exact parts' numbers; per part, a point of it (in the frame its link
    /// rides in) and the radius of a ball inside it.
    part_points: Vec<Range<usize>>,
    points: Vec<([f32; 3], f64)>,
    /// False when a link has exact geometry but no spheres: the lanes do not cover the robot,
    /// and validation is left to the exact checker.
    pub(super) covers: bool,
    /// Per link: its pockets (the sphere model's).
    pockets: Vec<Arc<LinkPockets>>,
    /// Per link and radius of [`LADDER`]: its pockets' answer, once asked (they answer under
    /// a lock; a spare checker keeps these from plan to plan).
    rooms: Vec<[Option<bool>; LADDER.len()]>,
    /// Self pairs (their index) with a part (its point) of link `x` that could hide in link
    /// `y`: `(pair, x, y, point)`; worked out on the first validation.
    parts: Option<Vec<(usize, usize, usize, usize)>>,
    /// In the environment checked (worked out on its first validation): the moving links and
    /// the objects that could hide in them, and with a map, per link whether a voxel could.
    in_env: Option<InEnvironment>,
}

/// What may hide where in one environment (see [`Hiding`]).
#[derive(Clone)]
struct InEnvironment {
    objects: Vec<(usize, usize)>,
    voxels: Option<Vec<bool>>,
}

impl Hiding {
    /// The parts of `robot`, their points placed by `place` (link, point in the link frame) in
    /// the frame the link rides in; `bound` per link, the sphere bound if it has spheres.
    pub(super) fn for_robot(
        robot: &Robot,
        bound: &[Option<([f32; 3], f32)>],
        place: impl Fn(usize, [f64; 3]) -> [f32; 3],
    ) -> Self {
        let exact = robot.exact_model();
        let links = robot.links();
        let (mut part_points, mut points) = (Vec::with_capacity(links.len()), Vec::new());
        for (l, link) in links.iter().enumerate() {
            let start = points.len();
            for (part, shape) in exact.link_parts(l).iter().zip(&link.collision) {
                // Its support point along x (on the part, wherever its box's centre lies), and
                // the radius of a ball inside it.
                let local = part.convex.support(&nalgebra::Vector3::x());
                let c = part.origin * nalgebra::Point3::from(local);
                points.push((place(l, [c.x, c.y, c.z]), part_inradius(shape)));
            }
            part_points.push(start..points.len());
        }
        let covers = (0..links.len()).all(|l| exact.link_parts(l).is_empty() || bound[l].is_some());
        Hiding {
            part_points,
            points,
            covers,
            pockets: robot.spheres().pockets.clone(),
            rooms: vec![[None; LADDER.len()]; links.len()],
            parts: None,
            in_env: None,
        }
    }

    /// Forgets what was worked out for the last environment (its objects or map changed).
    pub(super) fn new_environment(&mut self) {
        self.in_env = None;
    }

    /// Whether an obstacle with inradius `rho` could hide in link `l`.
    fn room(&mut self, rho: f64, l: usize) -> bool {
        match LADDER.iter().rposition(|&t| t <= rho) {
            Some(k) => {
                *self.rooms[l][k].get_or_insert_with(|| self.pockets[l].has_room_for(LADDER[k]))
            }
            None => true,
        }
    }
}

/// Works out each link's room for the balls validation asks about (the ladder's radii, and
/// half of each voxel edge in `voxel_edges`), so that no plan pays for it: what a daemon does
/// before it serves. Left alone, each is worked out the first time a validation asks.
pub fn prepare_validation(robot: &Robot, voxel_edges: &[f64]) {
    let radii: Vec<f64> = LADDER
        .iter()
        .copied()
        .chain(voxel_edges.iter().map(|e| e / 2.0))
        .collect();
    for pockets in &robot.spheres().pockets {
        for &t in &radii {
            pockets.has_room_for(t);
        }
    }
}

impl BatchChecker {
    /// Validation mode on or off: a batch is also flagged where an obstacle could hide
    /// inside a link ([`BatchChecker::may_hide`]). Returns false, and stays off, when the
    /// lanes cannot stand for the exact geometry (a link with exact parts but no spheres).
    /// A link's room for a ball is worked out the first time it is asked ([`LinkPockets`]);
    /// what may hide where, on the first validation in an environment.
    pub(crate) fn validate(&mut self, on: bool) -> bool {
        self.validating = on && self.hiding.covers;
        if !self.validating {
            return self.hiding.covers;
        }
        let h = &mut self.hiding;
        if h.parts.is_none() {
            let mut parts = Vec::new();
            for (k, &SelfPair { a, b, .. }) in self.pairs.iter().enumerate() {
                for (x, y) in [(a, b), (b, a)] {
                    for i in h.part_points[x].clone() {
                        if h.room(h.points[i].1, y) {
                            parts.push((k, x, y, i));
                        }
                    }
                }
            }
            self.hiding.parts = Some(parts);
        }
        if self.hiding.in_env.is_none() {
            let mut objects = Vec::new();
            for (o, object) in self.objects.iter().enumerate() {
                let rho = f64::from(inradius(object.kind));
                for &l in &self.moving {
                    if self.hiding.room(rho, l) {
                        objects.push((l, o));
                    }
                }
            }
            // A voxel holds a ball of half its edge, asked of each moving link as it is (the
            // links that never move are checked against the map on the exact geometry).
            let voxels = self.map.as_ref().map(|m| {
                let t = m.resolution() / 2.0;
                let mut room = vec![false; self.hiding.pockets.len()];
                for &l in &self.moving {
                    room[l] = self.hiding.pockets[l].has_room_for(t);
                }
                room
            });
            self.hiding.in_env = Some(InEnvironment { objects, voxels });
        }
        true
    }

    /// True when, in some lane, an obstacle may lie wholly inside a link without touching its
    /// spheres (see the module docs). Asked only of batches the spheres clear, every moving
    /// link's bound placed.
    #[inline(never)]
    pub(super) fn may_hide<const E: bool>(&mut self) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            return unsafe { self.may_hide_avx2::<E>() };
        }
        self.may_hide_lanes::<E>()
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn may_hide_avx2<const E: bool>(&mut self) -> bool {
        self.may_hide_lanes::<E>()
    }

    #[inline(always)]
    fn may_hide_lanes<const E: bool>(&mut self) -> bool {
        let h = &self.hiding;
        // Set whenever validating (by `validate(true)`); without it, nothing is ruled out.
        let Some(env) = &h.in_env else {
            return true;
        };
        for &(l, o) in &env.objects {
            let p = self.objects[o].t.map(F8::splat);
            if self.within_bound(l, p)
                && (!E || {
                    // The lanes it may hide in, and the walk goes on.
                    let lanes = self.within_lanes(l, p) & self.distinct;
                    self.link_hits[l] |= lanes;
                    false
                })
            {
                return true;
            }
        }
        // A voxel holds a ball of half its edge: any occupied voxel within the bound of a link
        // with room for that ball may be one.
        if let (Some(map), Some(room)) = (&self.map, &env.voxels) {
            for &l in &self.moving {
                let (_, r) = self.bound[l].unwrap_or_default();
                if room[l] {
                    let lanes = unclear_lanes(map.clearance(), self.bounds[l], r, self.live);
                    if lanes != 0
                        && (!E || {
                            self.link_hits[l] |= lanes & self.distinct;
                            false
                        })
                    {
                        return true;
                    }
                }
            }
        }
        for &(k, x, y, i) in h.parts.as_deref().unwrap_or_default() {
            let SelfPair { a, b, ra, rb, .. } = self.pairs[k];
            if !overlap(self.bounds[a], ra, self.bounds[b], rb) {
                continue;
            }
            let p = self.poses[self.frame[x]].apply_const_on(h.points[i].0, self.avx2);
            if self.within_bound(y, p)
                && (!E || {
                    let lanes = self.within_lanes(y, p) & self.distinct;
                    self.pair_hits[k] |= lanes;
                    false
                })
            {
                return true;
            }
        }
        false
    }

    /// True when the point `p` (eight lanes) is within link `l`'s bound ball and box in some
    /// lane (a hair of slack: its rounding).
    #[inline(always)]
    fn within_bound(&self, l: usize, p: [F8; 3]) -> bool {
        let (_, r) = self.bound[l].unwrap_or_default();
        overlap(p, MARGIN, self.bounds[l], r) && self.box_reached(l, p, MARGIN)
    }

    /// The lanes (bits) where [`BatchChecker::within_bound`] finds the point within both the
    /// bound ball and the box.
    #[inline(always)]
    fn within_lanes(&self, l: usize, p: [F8; 3]) -> u32 {
        let (_, r) = self.bound[l].unwrap_or_default();
        overlap_lanes(p, MARGIN, self.bounds[l], r) & self.box_lanes(l, p, MARGIN)
    }
}

/// The radius of a ball inside a part of a link (0 for a hull whose vertices' centroid is
/// on its boundary).
fn part_inradius(shape: &LinkShape) -> f64 {
    match &shape.geometry {
        Geometry::Primitive(s) => match *s {
            Shape::Sphere { radius } | Shape::Capsule { radius, .. } => radius,
            Shape::Box { half_extents: h } => h[0].min(h[1]).min(h[2]),
            Shape::Cylinder {
                radius,
                half_length,
            } => radius.min(half_length),
        },
        Geometry::Convex(hull) => {
            let n = hull.points.len().max(1) as f64;
            let c = hull
                .points
                .iter()
                .fold([0.0; 3], |c, p| std::array::from_fn(|a| c[a] + p[a] / n));
            hull.depth(c).max(0.0)
        }
    }
}

/// The radius of a ball inside an object of this shape.
fn inradius(kind: ObjectKind) -> f32 {
    match kind {
        ObjectKind::Sphere { r } | ObjectKind::Capsule { r, .. } => r,
        ObjectKind::Box { h } => h[0].min(h[1]).min(h[2]),
        ObjectKind::Cylinder { r, hl } => r.min(hl),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::Environment;
    use rand::SeedableRng;

    /// Prepared, every link's room is known for every radius a validation of the built-in
    /// Fetch against a map of 1 cm voxels asks about.
    #[test]
    fn prepared_validation_asks_no_more() {
        let robot = Robot::builtin("fetch").unwrap();
        prepare_validation(&robot, &[0.01]);
        let asked = |r: &Robot| -> Vec<usize> {
            r.spheres().pockets.iter().map(|p| p.answered()).collect()
        };
        let before = asked(&robot);
        assert!(before.iter().any(|&n| n == LADDER.len() + 1), "{before:?}");
        use crate::world::map::{MapParams, OccupancyMap};
        let mut map = OccupancyMap::new(MapParams {
            resolution: 0.01,
            ..MapParams::default()
        });
        map.set_voxel(map.key_of([0.6, 0.0, 0.7]), true);
        let mut env = Environment::new();
        env.set_map(Some(Arc::new(map)));
        let mut sut = BatchChecker::new(&robot, &env);
        assert!(sut.validate(true));
        assert_eq!(asked(&robot), before);
    }

    /// No part of the built-in Fetch or Panda fits in another link's pockets; listed as if
    /// every part could, the Fetch's parts flag states the spheres clear, where one lies
    /// within the other link's bound.
    #[test]
    fn parts_that_could_hide_flag_states_where_they_lie_within_the_other_link() {
        let panda = Robot::builtin("panda").unwrap();
        let mut sut = BatchChecker::new(&panda, &Environment::new());
        assert!(sut.validate(true));
        assert_eq!(sut.hiding.parts.as_deref(), Some(&[][..]));
        let robot = Robot::builtin("fetch").unwrap();
        let mut none = BatchChecker::new(&robot, &Environment::new());
        assert!(none.validate(true));
        assert_eq!(none.hiding.parts.as_deref(), Some(&[][..]));
        let mut every = none.clone();
        let mut parts = Vec::new();
        for (k, &SelfPair { a, b, .. }) in every.pairs.iter().enumerate() {
            for (x, y) in [(a, b), (b, a)] {
                parts.extend(every.hiding.part_points[x].clone().map(|i| (k, x, y, i)));
            }
        }
        every.hiding.parts = Some(parts);
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        let mut q = vec![0.0; robot.dof()];
        let mut flagged = 0;
        for _ in 0..3000 {
            robot.sample_uniform(&mut rng, &mut q);
            flagged += usize::from(every.state_may_collide(&q) && !none.state_may_collide(&q));
        }
        assert!(flagged > 0);
    }

    #[test]
    fn objects_hold_balls_of_their_inradius() {
        assert_eq!(
            inradius(ObjectKind::Box {
                h: [0.3, 0.02, 0.5]
            }),
            0.02
        );
        assert_eq!(inradius(ObjectKind::Cylinder { r: 0.04, hl: 0.01 }), 0.01);
        assert_eq!(inradius(ObjectKind::Capsule { r: 0.03, hl: 0.2 }), 0.03);
    }
}
