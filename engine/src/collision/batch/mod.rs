//! The batch checker: eight configurations at once in `f32` lanes (the states along an edge),
//! for the planner's edge checks.
//!
//! Forward kinematics runs across the eight lanes (sine and cosine included); sphere centres
//! are placed as lanes only where needed, down the same hierarchy as the scalar
//! [`SphereChecker`](super::SphereChecker): a link's bounding sphere, then its clusters, then
//! its spheres, against the objects whose world boxes the link's eight bounds reach, and over
//! the self-collision pairs (where a long or flat link's box around its spheres, tighter than
//! its ball, clears most pairs a torso or a base would otherwise pass down to the clusters).
//! The first lane in contact ends the check, and the spheres and obstacles of the last few
//! contacts are tried before the hierarchy (but on the batches after a motion's free first
//! batch, which nearly never collide). Links that never move
//! are not checked against the environment: the scalar checker decides that once, exactly
//! ([`SphereChecker::blocked`](super::SphereChecker::blocked)), and the planner does not use
//! this checker when it is so.
//!
//! Radii are enlarged by [`MARGIN`] (0.1 mm, far above `f32` rounding at robot scale), so a
//! batch found free is free for the scalar checker too, and a flagged batch is taken as a
//! collision; near the exact fallback's anchors each state of a flagged batch is checked
//! again alone, and only a state still flagged, whose balls inside the geometry
//! ([`BatchChecker::state_surely_collides`]) touch nothing, goes to the exact checker
//! ([`Validity`](crate::planning::validity::Validity) does). Where every state's verdict is
//! wanted (certification), [`BatchChecker::lane_flags`] gives each lane's flags, and the links
//! and pairs that raised them, from one placement of the eight and one walk that does not end
//! at a contact (the same tests, compiled a second time through their `E` parameter, so that
//! the early-ending walk keeps its source). An occupancy map is one more
//! obstacle down the same hierarchy: its [`Clearance`] grid clears most balls in one read per
//! lane, and a sphere it cannot clear is decided by the map's voxels, lane by lane.
//!
//! Any model and scene fit: objects go down the hierarchy in groups of 64 (one bit each in a
//! mask), and a link's clusters meet another link's 64 at a time.
//!
//! Compiled twice: for AVX2 with FMA (chosen at run time when the CPU has them) and for the
//! baseline target; the arithmetic is the same (products are summed by fused multiply-adds
//! on both, see [`lanes`]).

mod flags;
use flags::{map_counted, objects_counted, overlap_counted};
pub use flags::{LaneFlags, StateFlags};
mod hiding;
pub use hiding::prepare_validation;
mod kinematics;
pub mod lanes;
mod objects;

use crate::collision::checker::{bisection_order, steps_over};
use crate::robot::fk::JointFrames;
use crate::robot::Robot;
use crate::world::map::{Clearance, OccupancyMap};
use crate::world::Environment;
use hiding::Hiding;
use kinematics::Joint8;
use lanes::{boxes_overlapping, edge_fractions, edge_lanes, has_avx2, Pose8, ALL_LANES, F8, LANES};
use objects::{penetrated, penetrates, penetrating_lanes, Object8, ObjectKind};
use std::sync::Arc;

/// Environment contacts remembered and tried first in the next batch (see
/// [`BatchChecker::env_contact_with`]). Eight end 43–91% of the batches on the
/// MotionBenchMaker Fetch sets at seed 0 (`ember-bench plan`'s `remembered_pct`; four ended
/// 40–80%, and took 1.6–5.8% more search instructions on every Fetch set); twelve or sixteen
/// find more but cost the short table searches more when they miss.
const RECENT: usize = 8;

/// Distinct sphere–object contacts kept for [`BatchChecker::surely_colliding`], which
/// screens the end states of several tree extensions at once.
const SCREEN: usize = 32;

/// Added to the offsets of clusters and spheres from the balls holding them (metres): far above
/// the lanes' rounding of their placements at robot scale.
const OFFSET_SLACK: f32 = 1e-5;

/// Stamp of placements that never change (links that do not move).
const STATIC: u32 = u32::MAX;

/// Added to every radius (metres): the batch checker errs towards contact.
pub const MARGIN: f32 = 1e-4;

/// A self-collision pair: links `a` and `b`, their bound radii, and the square of their sum
/// (the bounds overlap where their centres are nearer than that; `f32`, as [`overlap`]).
#[derive(Clone, Copy)]
struct SelfPair {
    a: usize,
    b: usize,
    ra: f32,
    rb: f32,
    reach2: f32,
    /// Added to the sum of two spheres' radii in the pair's final test: the pair's own
    /// margin less the sum of the links' ([`BatchChecker::inflate`]); zero otherwise.
    adjust: f32,
}

/// Items one `u64` mask holds: objects go down the hierarchy in groups of this many, and a
/// link's clusters meet another link's this many at a time.
const MASK_BITS: usize = 64;

/// Slack of the clusters' eight-at-a-time test in their link's frame, metres: far above the
/// `f32` rounding between it and the lanes' test in the world frame.
const BLOCK_SLACK: f32 = 1e-4;

/// A link's clusters eight at a time, in the frame the link rides in: centres and radii (lanes
/// past the link's last cluster far away, radius zero).
#[derive(Clone, Copy, Default)]
struct ClusterBlock {
    centre: [F8; 3],
    radius: F8,
}

/// The decision [`BatchChecker::motion_free`] is given when it has none.
type NoDecision = fn(&mut BatchChecker, usize, usize) -> bool;

/// What a remembered contact's sphere touched.
#[derive(Clone, Copy)]
enum Touched {
    /// An object, by number.
    Object(usize),
    /// The occupancy map.
    Map,
}

/// Eight-lane collision checks for one robot in one environment (see the module docs).
#[derive(Clone)]
pub struct BatchChecker {
    dof: usize,
    /// Per link: the frame its pose is computed in (its own for a joint or the root, else its
    /// nearest such ancestor's).
    frame: Vec<usize>,
    /// Per link: what its pose is computed from (one record, read once per link and batch).
    joints: Vec<Joint8>,
    /// Links whose pose a batch computes (moving, in their own frame), parents first.
    posed: Vec<usize>,
    /// Links with spheres that move.
    moving: Vec<usize>,
    /// Per link: bound centre (link frame) and radius (+ margin), if it has spheres.
    bound: Vec<Option<([f32; 3], f32)>>,
    /// Per link: the box (lower and upper corners, in the frame it rides in) around its
    /// spheres, margin included, when it is smaller than the bound ball (a long or flat
    /// link: a torso, a base; not a one-sphere link, whose box holds its ball).
    /// Self-collision pairs test the other link's ball against it.
    bound_box: Vec<Option<([f32; 3], [f32; 3])>>,
    /// Per link: its clusters.
    link_clusters: Vec<std::ops::Range<usize>>,
    /// Per link: the range of its spheres (its clusters' together).
    link_spheres: Vec<std::ops::Range<usize>>,
    /// Per link: its clusters' blocks in `cluster_blocks` (the first holds its first eight).
    link_blocks: Vec<std::ops::Range<usize>>,
    /// The links' clusters eight to a block, link by link, for the self pairs' first test.
    cluster_blocks: Vec<ClusterBlock>,
    /// Per cluster: centre, radius (+ margin), spheres.
    cluster: Vec<([f32; 3], f32, std::ops::Range<usize>)>,
    /// Per sphere: centre (link frame), radius (+ margin).
    sphere: Vec<([f32; 3], f32)>,
    /// Per cluster: the distance from its link's bound's centre to its centre, and per
    /// sphere from its cluster's centre to its centre (each plus a hair for the lanes'
    /// rounding): how far a ball inside reaches from the outer ball's centre.
    cluster_offset: Vec<f32>,
    sphere_offset: Vec<f32>,
    /// Per sphere: centre and the radius of its ball inside the geometry (less the margin):
    /// swapped with `sphere` for [`BatchChecker::state_surely_collides`].
    sphere_inner: Vec<([f32; 3], f32)>,
    objects: Vec<Object8>,
    /// Object world boxes eight objects per vector (`[lo; 3]`, `[hi; 3]`); padding objects
    /// have empty boxes.
    object_boxes: Vec<([F8; 3], [F8; 3])>,
    /// The occupancy map to avoid, if any.
    map: Option<Arc<OccupancyMap>>,
    /// Self-collision pairs with a moving link, both with spheres (their links index
    /// `bounds`: the pair loop reads them unchecked).
    pairs: Vec<SelfPair>,
    /// Per-batch state.
    poses: Vec<Pose8>,
    bounds: Vec<[F8; 3]>,
    cluster_at: Vec<[F8; 3]>,
    cluster_stamp: Vec<u32>,
    sphere_at: Vec<[F8; 3]>,
    sphere_stamp: Vec<u32>,
    epoch: u32,
    lanes: Vec<F8>,
    /// Per variable: the start of the motion being checked, and its difference (end minus
    /// start).
    start: Vec<f64>,
    delta: Vec<f64>,
    /// States checked so far.
    states: u64,
    /// The last environment contacts, most recent first: link, sphere, what it touched.
    recent: [Option<(usize, usize, Touched)>; RECENT],
    /// The last distinct contacts of spheres with objects the hierarchy found, most recent
    /// first (link, sphere, object): what [`BatchChecker::surely_colliding`] tries.
    screen: Vec<(usize, usize, usize)>,
    /// True while a batch after a motion's free first batch is checked: the remembered
    /// contacts are not tried (see [`BatchChecker::states_free`]).
    skip_recent: bool,
    /// True while a returned path is validated: a batch is also flagged where an obstacle
    /// could lie inside a link without touching its spheres ([`hiding`]).
    validating: bool,
    /// What validation asks of the robot's parts and the links' pockets.
    hiding: Hiding,
    /// Batches checked, and those a remembered contact ended.
    batches: u64,
    remembered: u64,
    /// The lanes that hold distinct states: all of them, but the first alone while one state
    /// fills every lane (the map's voxels are then walked once, not eight times). In
    /// [`BatchChecker::lane_flags`]'s walks, the lanes not yet found in contact.
    live: u32,
    /// In [`BatchChecker::lane_flags`]'s walk (its tests' `E`): the lanes holding distinct
    /// states, the lanes found so far for the link or pair being walked, and per link and per
    /// pair the lanes where it may touch the obstacles or its partner.
    distinct: u32,
    hit: u32,
    link_hits: Vec<u32>,
    pair_hits: Vec<u32>,
    /// The radii as built, while [`BatchChecker::inflate`] has grown them.
    uninflated: Option<Box<Radii>>,
    avx2: bool,
}

/// The batch checker's radii: per link its bound ball and box, per cluster and sphere its
/// radius, and the self pairs' reaches.
#[derive(Clone)]
struct Radii {
    bound: Vec<Option<([f32; 3], f32)>>,
    bound_box: Vec<Option<([f32; 3], [f32; 3])>>,
    cluster: Vec<f32>,
    sphere: Vec<f32>,
    pairs: Vec<SelfPair>,
    /// Per link: how much its balls are grown now (0: as built).
    grown: Vec<f32>,
}

impl BatchChecker {
    /// A batch checker for `robot` in `env`.
    pub fn new(robot: &Robot, env: &Environment) -> Self {
        robot.prepared().take_batch().in_environment(env)
    }

    /// The batch checker for `robot` in an empty environment: what depends on the robot
    /// alone, built once per robot ([`Robot::prepared`]).
    pub(crate) fn for_robot(robot: &Robot) -> Self {
        let links = robot.links();
        let model = robot.spheres();
        let f = |v: f64| v as f32;
        // Links on fixed joints ride in the frame of their nearest moving ancestor (or the
        // root): their spheres are placed in that frame once, so FK runs over joints only.
        let joints = JointFrames::new(robot);
        let frame = joints.frame.clone();
        let joints8 = kinematics::joints(robot, &joints);
        // Sphere-model points in the frame their link rides in.
        let place = |l: usize, c: [f64; 3]| -> [f32; 3] { joints.place(l, c).map(f) };
        let moves: Vec<bool> = (0..links.len()).map(|l| robot.link_moves(l)).collect();
        let bound: Vec<_> = model
            .bounds
            .iter()
            .enumerate()
            .map(|(l, b)| b.map(|(c, r)| (place(l, c), f(r) + MARGIN)))
            .collect();
        let mut owner = vec![0usize; model.clusters.len()];
        for (l, range) in model.link_clusters.iter().enumerate() {
            for ci in range.clone() {
                owner[ci] = l;
            }
        }
        // Tip first, as the scalar checker.
        let moving = (0..links.len())
            .rev()
            .filter(|&l| moves[l] && bound[l].is_some())
            .collect();
        let cluster: Vec<_> = model
            .clusters
            .iter()
            .enumerate()
            .map(|(ci, c)| {
                let l = owner[ci];
                (place(l, c.center), f(c.radius) + MARGIN, c.range.clone())
            })
            .collect();
        let sphere: Vec<_> = (0..model.len())
            .map(|s| {
                let l = model.link[s] as usize;
                (place(l, model.center[s]), f(model.radius[s]) + MARGIN)
            })
            .collect();
        let apart = |a: [f32; 3], b: [f32; 3]| {
            let d2: f32 = (0..3).map(|i| (a[i] - b[i]) * (a[i] - b[i])).sum();
            d2.sqrt() + OFFSET_SLACK
        };
        let cluster_offset = cluster
            .iter()
            .enumerate()
            .map(|(ci, c)| bound[owner[ci]].map_or(f32::INFINITY, |(b, _)| apart(b, c.0)))
            .collect();
        let mut sphere_offset = vec![f32::INFINITY; sphere.len()];
        for (c, _, range) in &cluster {
            for s in range.clone() {
                sphere_offset[s] = apart(*c, sphere[s].0);
            }
        }
        let sphere_inner: Vec<_> = (0..model.len())
            .map(|s| {
                let l = model.link[s] as usize;
                (
                    place(l, model.center[s]),
                    (f(model.inner[s]) - MARGIN).max(0.0),
                )
            })
            .collect();
        let bound_box = model
            .link_clusters
            .iter()
            .zip(&bound)
            .map(|(clusters, b)| {
                let (_, r) = (*b)?;
                let mut lo = [f32::INFINITY; 3];
                let mut hi = [f32::NEG_INFINITY; 3];
                let spheres = clusters.clone().flat_map(|ci| cluster[ci].2.clone());
                for (c, rs) in spheres.map(|s| sphere[s]) {
                    for i in 0..3 {
                        lo[i] = lo[i].min(c[i] - rs);
                        hi[i] = hi[i].max(c[i] + rs);
                    }
                }
                let volume: f32 = (0..3).map(|i| hi[i] - lo[i]).product();
                (volume < 4.0 / 3.0 * std::f32::consts::PI * r * r * r).then_some((lo, hi))
            })
            .collect();
        let (moving_pairs, _) = robot.partition_pairs();
        let pairs: Vec<SelfPair> = moving_pairs
            .into_iter()
            .filter_map(|(a, b)| {
                let (ra, rb) = (bound[a]?.1, bound[b]?.1);
                let r = ra + rb;
                Some(SelfPair {
                    a,
                    b,
                    ra,
                    rb,
                    reach2: r * r,
                    adjust: 0.0,
                })
            })
            .collect();
        let n_pairs = pairs.len();
        let n_links = links.len();
        assert!(pairs.iter().all(|p| p.a.max(p.b) < n_links));
        debug_assert!((0..n_links).all(|l| {
            let (clusters, spheres) = (&model.link_clusters[l], &model.ranges[l]);
            clusters.is_empty()
                || (cluster[clusters.start].2.start == spheres.start
                    && cluster[clusters.end - 1].2.end == spheres.end
                    && clusters
                        .clone()
                        .skip(1)
                        .all(|c| cluster[c - 1].2.end == cluster[c].2.start))
        }));
        let hiding = Hiding::for_robot(robot, &bound, place);
        // Links come parents first (`Robot::links`), so a pose is computed after its parent's.
        debug_assert!((0..n_links).all(|l| links[l].parent.is_none_or(|p| frame[p] < l)));
        let posed = (0..n_links)
            .filter(|&l| moves[l] && frame[l] == l)
            .collect();
        let mut sut = BatchChecker {
            dof: robot.dof(),
            frame,
            joints: joints8,
            posed,
            moving,
            bound,
            bound_box,
            link_clusters: model.link_clusters.clone(),
            link_spheres: model.ranges.clone(),
            link_blocks: Vec::new(),
            cluster_blocks: Vec::new(),
            cluster,
            sphere,
            cluster_offset,
            sphere_offset,
            sphere_inner,
            objects: Vec::new(),
            object_boxes: Vec::new(),
            map: None,
            pairs,
            poses: vec![Pose8::default(); n_links],
            bounds: vec![[F8::default(); 3]; n_links],
            cluster_at: vec![[F8::default(); 3]; model.clusters.len()],
            cluster_stamp: vec![0; model.clusters.len()],
            sphere_at: vec![[F8::default(); 3]; model.len()],
            sphere_stamp: vec![0; model.clusters.len()],
            epoch: 0,
            states: 0,
            recent: [None; RECENT],
            screen: Vec::with_capacity(SCREEN),
            validating: false,
            hiding,
            batches: 0,
            remembered: 0,
            live: ALL_LANES,
            distinct: ALL_LANES,
            hit: 0,
            link_hits: vec![0; n_links],
            pair_hits: vec![0; n_pairs],
            skip_recent: false,
            uninflated: None,
            lanes: vec![F8::default(); robot.dof()],
            start: vec![0.0; robot.dof()],
            delta: vec![0.0; robot.dof()],
            avx2: has_avx2(),
        };
        // Links that never move have the same pose, bound, clusters and spheres in every
        // batch: placed once, stamped as always valid.
        for (l, &m) in moves.iter().enumerate() {
            if !m && sut.frame[l] == l {
                sut.fk_link(l);
            }
        }
        // The slides' fixed rotations, their parents' (parents first): batches leave them.
        for k in 0..sut.posed.len() {
            let l = sut.posed[k];
            if let Some(slide) = sut.joints[l].slide.filter(|s| s.fixed_rotation) {
                sut.poses[l].r = sut.poses[slide.parent].r;
            }
        }
        for l in 0..n_links {
            let first = sut.cluster_blocks.len();
            let blocks = sut.link_clusters[l].len().div_ceil(LANES);
            sut.cluster_blocks
                .resize(first + blocks, ClusterBlock::default());
            sut.link_blocks.push(first..first + blocks);
            sut.write_cluster_blocks(l);
        }
        sut.epoch = STATIC;
        for l in (0..n_links).filter(|&l| !moves[l]) {
            if let Some((c, _)) = sut.bound[l] {
                sut.bounds[l] = sut.poses[sut.frame[l]].apply_const(c);
            }
            for ci in sut.link_clusters[l].clone() {
                sut.place_cluster(l, ci);
                sut.place_spheres(l, ci);
            }
        }
        sut.epoch = 0;
        sut
    }

    /// This checker in `env` (its counters reset).
    fn in_environment(mut self, env: &Environment) -> Self {
        // An empty map is no obstacle; the grid of a non-empty one is built here, not mid-check.
        let map = env.shared_map().filter(|m| {
            m.clearance();
            m.has_occupied()
        });
        self.objects.clear();
        self.objects.extend(env.placed().map(Object8::of));
        self.object_boxes.clear();
        self.object_boxes
            .extend(self.objects.chunks(LANES).map(|chunk| {
                let lane = |k: usize, hi: bool, i: usize| match chunk.get(k) {
                    Some(o) if hi => o.hi[i],
                    Some(o) => o.lo[i],
                    None if hi => f32::NEG_INFINITY,
                    None => f32::INFINITY,
                };
                (
                    std::array::from_fn(|i| F8(std::array::from_fn(|k| lane(k, false, i)))),
                    std::array::from_fn(|i| F8(std::array::from_fn(|k| lane(k, true, i)))),
                )
            }));
        self.map = map;
        self.hiding.new_environment();
        self.states = 0;
        self.batches = 0;
        self.remembered = 0;
        self.recent = [None; RECENT];
        self.screen.clear();
        self
    }

    /// This checker with its map let go (it may be large), to be kept for another environment
    /// ([`BatchChecker::new`] replaces the objects).
    pub(crate) fn without_map(mut self) -> Self {
        self.map = None;
        self.hiding.new_environment();
        self
    }

    /// True when any of the states strictly between `a` and `b` (at `resolution`, the
    /// planner's discretisation), and `b` itself when `with_end` (first: a tree extension in
    /// one pass), may touch something. `false` means every state is free. The states are
    /// checked eight at a time, coarse to fine.
    pub fn motion_may_collide(
        &mut self,
        robot: &Robot,
        resolution: f64,
        (a, b): (&[f64], &[f64]),
        with_end: bool,
    ) -> bool {
        !self.motion_free(robot, resolution, (a, b), with_end, None::<NoDecision>)
    }

    /// True when every state strictly between `a` and `b` (at `resolution`; and `b` itself
    /// when `with_end`, first) is free: the states go eight at a time, coarse to fine
    /// (bisection order). Without `decide`, a batch the lanes flag is a collision. With it,
    /// each state of a flagged batch is checked again alone, and one the lanes still flag is
    /// handed to `decide` with this checker (its number `k` of `n` steps: `a + k/n (b − a)`),
    /// which says whether it is free after all; the first it does not clear ends the check.
    pub fn motion_free(
        &mut self,
        robot: &Robot,
        resolution: f64,
        (a, b): (&[f64], &[f64]),
        with_end: bool,
        decide: Option<impl FnMut(&mut BatchChecker, usize, usize) -> bool>,
    ) -> bool {
        // The states are a + (k / n) · delta; continuous joints need no wrapping here (the
        // kinematics only takes their sine and cosine).
        let n = steps_over(robot.deltas(a, b, &mut self.delta), resolution).max(1);
        if n < 2 && !with_end {
            return true;
        }
        self.start.copy_from_slice(a);
        self.states_free(n, with_end, decide)
    }

    /// [`BatchChecker::motion_may_collide`] of a tree extension given as its start `a`, its
    /// step per joint (`b − a` the short way round, as [`Robot::step_towards`] writes it) and
    /// its number of steps `n` at the resolution: the end state and the edge's states, from
    /// what the extension computed already.
    pub fn step_may_collide(&mut self, a: &[f64], step: &[f64], n: usize) -> bool {
        self.start.copy_from_slice(a);
        self.delta.copy_from_slice(step);
        !self.states_free(n.max(1), true, None::<NoDecision>)
    }

    /// True when configuration `q` may touch something: one state in every lane.
    pub fn state_may_collide(&mut self, q: &[f64]) -> bool {
        for (lane, &v) in self.lanes.iter_mut().zip(q) {
            *lane = F8::splat(v as f32);
        }
        self.alone(|sut| sut.lanes_may_collide(None))
    }

    /// True when configuration `q` surely touches something: the balls inside the geometry
    /// ([`SphereModel::inner`](crate::robot::spheres::SphereModel::inner), less the margin),
    /// down the same hierarchy, touch an object, the map or each other.
    pub fn state_surely_collides(&mut self, q: &[f64]) -> bool {
        std::mem::swap(&mut self.sphere, &mut self.sphere_inner);
        let hit = self.state_may_collide(q);
        std::mem::swap(&mut self.sphere, &mut self.sphere_inner);
        hit
    }

    /// Grows every ball of each link `l` by `by[l]` metres (links beyond `by` not at all),
    /// and its bound box likewise, from the radii as built: the checks then find a state in
    /// contact wherever a link comes within `by[l]` of an object or the map, and two links
    /// `a` and `b` within the sum of theirs of each other, or within `pairs[a * links + b]`
    /// where that is less (the spheres' final test; `pairs` empty: the sum).
    /// [`BatchChecker::deflate`] undoes it. Links that never move are placed once, so they are
    /// not grown; a link grown by as much already is left as it is.
    pub fn inflate(&mut self, by: &[f32], pairs: &[f32]) {
        // Taken out while the radii are written, and put back.
        let mut base = self.uninflated.take().unwrap_or_else(|| {
            Box::new(Radii {
                bound: self.bound.clone(),
                bound_box: self.bound_box.clone(),
                cluster: self.cluster.iter().map(|c| c.1).collect(),
                sphere: self.sphere.iter().map(|s| s.1).collect(),
                pairs: self.pairs.clone(),
                grown: vec![0.0; self.bound.len()],
            })
        });
        let grow = |l: usize| by.get(l).copied().unwrap_or(0.0).max(0.0);
        for k in 0..self.moving.len() {
            let l = self.moving[k];
            let m = grow(l);
            if base.grown[l] == m {
                continue;
            }
            base.grown[l] = m;
            if let (Some(b), Some(base)) = (&mut self.bound[l], base.bound[l]) {
                b.1 = base.1 + m;
            }
            if let (Some(b), Some((lo, hi))) = (&mut self.bound_box[l], base.bound_box[l]) {
                *b = (lo.map(|v| v - m), hi.map(|v| v + m));
            }
            // A link's clusters, and its spheres, are consecutive.
            let (clusters, spheres) = (self.link_clusters[l].clone(), self.link_spheres[l].clone());
            for (c, &r) in self.cluster[clusters.clone()]
                .iter_mut()
                .zip(&base.cluster[clusters])
            {
                c.1 = r + m;
            }
            for (s, &r) in self.sphere[spheres.clone()]
                .iter_mut()
                .zip(&base.sphere[spheres])
            {
                s.1 = r + m;
            }
            self.write_cluster_blocks(l);
        }
        let links = self.bound.len();
        for (pair, base) in self.pairs.iter_mut().zip(&base.pairs) {
            let (ga, gb) = (grow(pair.a), grow(pair.b));
            pair.ra = base.ra + ga;
            pair.rb = base.rb + gb;
            let r = pair.ra + pair.rb;
            pair.reach2 = r * r;
            let cap = pairs.get(pair.a * links + pair.b).copied();
            pair.adjust = cap.map_or(0.0, |cap| cap.max(0.0).min(ga + gb) - (ga + gb));
        }
        self.uninflated = Some(base);
    }

    /// The radii as built again, after [`BatchChecker::inflate`].
    pub fn deflate(&mut self) {
        let Some(base) = self.uninflated.as_deref_mut() else {
            return;
        };
        base.grown.fill(0.0);
        self.bound.clone_from(&base.bound);
        self.bound_box.clone_from(&base.bound_box);
        for (c, r) in self.cluster.iter_mut().zip(&base.cluster) {
            c.1 = *r;
        }
        for (s, r) in self.sphere.iter_mut().zip(&base.sphere) {
            s.1 = *r;
        }
        self.pairs.clone_from(&base.pairs);
        for l in 0..self.link_blocks.len() {
            self.write_cluster_blocks(l);
        }
    }

    /// Writes link `l`'s cluster blocks from its clusters' centres and radii.
    fn write_cluster_blocks(&mut self, l: usize) {
        let clusters = &self.cluster[self.link_clusters[l].clone()];
        write_blocks(
            &mut self.cluster_blocks[self.link_blocks[l].clone()],
            clusters,
        );
    }

    /// `check` with the first lane marked as the only distinct one.
    #[inline]
    fn alone(&mut self, check: impl FnOnce(&mut Self) -> bool) -> bool {
        self.live = 1;
        let hit = check(self);
        self.live = ALL_LANES;
        hit
    }

    /// The checks of [`BatchChecker::motion_free`] once `start` and `delta` hold the motion.
    fn states_free(
        &mut self,
        n: usize,
        with_end: bool,
        mut decide: Option<impl FnMut(&mut BatchChecker, usize, usize) -> bool>,
    ) -> bool {
        let mut batch = [0usize; LANES];
        let mut filled = 0;
        if with_end {
            batch[0] = n;
            filled = 1;
        }
        // A motion's first batch (the end state and states spread over it) mostly settles
        // it; those after a free first batch are nearly always free (on the MotionBenchMaker
        // Fetch sets under 2% of second batches collide), so they skip the remembered contacts
        // and go straight down the hierarchy.
        let mut first = true;
        for k in bisection_order(n) {
            batch[filled] = k;
            filled += 1;
            if filled == LANES {
                let may_collide = self.states_may_collide(n, &batch, !first);
                if may_collide && !self.decided_free(n, &batch, &mut decide) {
                    return false;
                }
                first = false;
                filled = 0;
            }
        }
        if filled > 0 {
            for i in filled..LANES {
                batch[i] = batch[filled - 1];
            }
            let may_collide = self.states_may_collide(n, &batch, !first);
            // Only the distinct states count (the filler repeats the last).
            self.states -= (LANES - filled) as u64;
            if may_collide && !self.decided_free(n, &batch[..filled], &mut decide) {
                return false;
            }
        }
        true
    }

    /// True when each of the states `ks` (of `n` steps) of a flagged batch is free: the lanes
    /// clear it alone, or `decide` does. False without `decide`.
    fn decided_free(
        &mut self,
        n: usize,
        ks: &[usize],
        decide: &mut Option<impl FnMut(&mut BatchChecker, usize, usize) -> bool>,
    ) -> bool {
        let Some(decide) = decide else {
            return false;
        };
        ks.iter().all(|&k| {
            let alone = [k; LANES];
            !self.alone(|sut| sut.lanes_may_collide(Some((&alone, n)))) || decide(self, k, n)
        })
    }

    /// True when any of the states `start + (k / n) · delta` for the eight `ks` may touch
    /// something; `after_free` for a batch after a motion's free first batch, which skips the
    /// remembered contacts (see [`BatchChecker::states_free`]).
    fn states_may_collide(&mut self, n: usize, ks: &[usize; LANES], after_free: bool) -> bool {
        self.states += LANES as u64;
        self.skip_recent = after_free;
        let hit = self.lanes_may_collide(Some((ks, n)));
        self.skip_recent = false;
        hit
    }

    /// True when any of the eight configurations in `self.lanes` (first written from the
    /// edge's states `ks` of `n`, if given) may touch something.
    fn lanes_may_collide(&mut self, edge: Option<(&[usize; LANES], usize)>) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            return unsafe { self.check_avx2(edge) };
        }
        self.check(edge)
    }

    /// Writes the lanes from the edge: variable `j` of lane `i` is `start[j] + t[i] · delta[j]`
    /// with `t[i] = ks[i] / n` (in `f64`, then rounded: the same values on every path).
    #[inline(always)]
    fn fill_lanes(&mut self, (ks, n): (&[usize; LANES], usize)) {
        let t = edge_fractions(ks, n, self.avx2);
        edge_lanes(&mut self.lanes, &self.start, &self.delta, &t, self.avx2);
    }

    /// States checked so far (edge states; padding not counted).
    pub fn states(&self) -> u64 {
        self.states
    }

    /// Batches checked so far, and how many of them a remembered contact ended.
    pub fn batches(&self) -> (u64, u64) {
        (self.batches, self.remembered)
    }

    /// Writes into `out` (one per link) each link's sphere-model bound centre at eight
    /// configurations given per variable (as [`BatchChecker::may_collide`] takes them); links
    /// without a sphere model are left as they are.
    pub fn bound_centres(&mut self, lanes: &[F8], out: &mut [[F8; 3]]) {
        self.lanes[..self.dof].copy_from_slice(&lanes[..self.dof]);
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            unsafe { self.pose_links_avx2() };
        } else {
            self.pose_links();
        }
        #[cfg(not(target_arch = "x86_64"))]
        self.pose_links();
        for (l, o) in out.iter_mut().enumerate().take(self.bound.len()) {
            if let Some((c, _)) = self.bound[l] {
                *o = self.poses[self.frame[l]].apply_const_on(c, self.avx2);
            }
        }
    }

    /// Checks eight configurations given per variable (`lanes[j]` holds variable `j` of each).
    pub fn may_collide(&mut self, lanes: &[F8]) -> bool {
        self.lanes[..self.dof].copy_from_slice(&lanes[..self.dof]);
        self.lanes_may_collide(None)
    }

    /// Of up to eight configurations (`states[i]` in lane `i`), those (bits) surely in
    /// contact with an object: a sphere of one of the last [`SCREEN`] distinct contacts the
    /// checks found touches its object there. Lanes without a contact found may still
    /// collide. The planner screens the end states of several extensions at once with it
    /// where nearly every extension fails (a flag is a contact, as in a full check). The
    /// states count among those checked ([`BatchChecker::states`]).
    pub fn surely_colliding(&mut self, states: &[&[f64]]) -> u32 {
        let n = states.len().min(LANES);
        if n == 0 || self.screen.is_empty() {
            return 0;
        }
        self.states += n as u64;
        for (j, lane) in self.lanes.iter_mut().enumerate() {
            *lane = F8(std::array::from_fn(|i| states[i.min(n - 1)][j] as f32));
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            return unsafe { self.screen_avx2(n) };
        }
        self.screen_lanes(n)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn screen_avx2(&mut self, n: usize) -> u32 {
        self.screen_lanes(n)
    }

    #[inline(always)]
    fn screen_lanes(&mut self, n: usize) -> u32 {
        self.pose_links();
        let wanted = ALL_LANES >> (LANES - n);
        let mut flagged = 0;
        for k in 0..self.screen.len() {
            let (l, s, j) = self.screen[k];
            let (c, r) = self.sphere[s];
            let p = self.poses[self.frame[l]].apply_const_on(c, self.avx2);
            flagged |= penetrating_lanes(&self.objects[j], p, r);
            if flagged & wanted == wanted {
                break;
            }
        }
        flagged & wanted
    }

    /// Puts a contact first among those kept for screening (dropping the oldest past
    /// [`SCREEN`]).
    #[inline(always)]
    fn keep_for_screening(&mut self, contact: (usize, usize, usize)) {
        match self.screen.iter().position(|&c| c == contact) {
            Some(k) => self.screen[..=k].rotate_right(1),
            None => {
                if self.screen.len() == SCREEN {
                    self.screen.pop();
                }
                self.screen.insert(0, contact);
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn check_avx2(&mut self, edge: Option<(&[usize; LANES], usize)>) -> bool {
        self.check(edge)
    }

    /// [`BatchChecker::pose_links`] compiled for AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn pose_links_avx2(&mut self) {
        self.pose_links();
    }

    #[inline(always)]
    fn check(&mut self, edge: Option<(&[usize; LANES], usize)>) -> bool {
        self.begin(edge);
        // The environment places each moving link's bound as it reaches it (most batches end
        // at the first link or two); the self pairs need them all, placed by then.
        self.env_contact::<false>()
            || self.self_contact::<false>()
            || (self.validating && self.may_hide::<false>())
    }

    /// A batch's kinematics, before its tests: the lanes from the edge, if given, a new
    /// epoch for the placements, the links posed.
    #[inline(always)]
    fn begin(&mut self, edge: Option<(&[usize; LANES], usize)>) {
        if let Some(edge) = edge {
            self.fill_lanes(edge);
        }
        self.epoch += 1;
        self.batches += 1;
        if self.epoch == STATIC {
            // Stamps start again (those of links that never move stay valid).
            for stamp in self.cluster_stamp.iter_mut().chain(&mut self.sphere_stamp) {
                if *stamp != STATIC {
                    *stamp = 0;
                }
            }
            self.epoch = 1;
        }
        self.pose_links();
    }

    #[inline(always)]
    fn remember(&mut self, contact: (usize, usize, Touched)) {
        self.bring_forward(RECENT - 1, Some(contact));
    }

    /// Moves the remembered contacts before `k` one place back and puts `contact` first.
    /// (A loop over the entries: `rotate_right` was a call costing as much as a test.)
    #[inline(always)]
    fn bring_forward(&mut self, k: usize, contact: Option<(usize, usize, Touched)>) {
        for i in (1..=k.min(RECENT - 1)).rev() {
            self.recent[i] = self.recent[i - 1];
        }
        self.recent[0] = contact;
    }

    #[inline(always)]
    fn place_bound(&mut self, l: usize) {
        let (c, _) = self.bound[l].unwrap_or_default();
        self.bounds[l] = self.poses[self.frame[l]].apply_const_on(c, self.avx2);
    }

    #[inline(always)]
    fn place_cluster(&mut self, l: usize, ci: usize) {
        if self.cluster_stamp[ci] < self.epoch {
            self.cluster_stamp[ci] = self.epoch;
            self.cluster_at[ci] =
                self.poses[self.frame[l]].apply_const_on(self.cluster[ci].0, self.avx2);
        }
    }

    #[inline(always)]
    fn place_spheres(&mut self, l: usize, ci: usize) {
        if self.sphere_stamp[ci] < self.epoch {
            self.sphere_stamp[ci] = self.epoch;
            let pose = &self.poses[self.frame[l]];
            for s in self.cluster[ci].2.clone() {
                self.sphere_at[s] = pose.apply_const_on(self.sphere[s].0, self.avx2);
            }
        }
    }

    #[inline(always)]
    fn env_contact<const E: bool>(&mut self) -> bool {
        if self.objects.is_empty() && self.map.is_none() {
            for k in 0..self.moving.len() {
                self.place_bound(self.moving[k]);
            }
            return false;
        }
        // Moved out while the placements are written, and back: no reference count per batch.
        let map = self.map.take();
        let hit = self.env_contact_with::<E>(map.as_deref());
        self.map = map;
        hit
    }

    /// True when a sphere may touch an object or the map in some lane. The spheres and
    /// obstacles of the last contacts are tried first: a search's neighbouring batches mostly
    /// hit the same obstacle with the same sphere, and such a batch then costs its kinematics
    /// and one test instead of the walk down the hierarchy. (Any sphere in contact is a
    /// contact: the order changes the cost, never the verdict.)
    #[inline(always)]
    fn env_contact_with<const E: bool>(&mut self, map: Option<&OccupancyMap>) -> bool {
        let grid = match map {
            Some(m) => m.clearance(),
            None => None,
        };
        for k in 0..if self.skip_recent || E { 0 } else { RECENT } {
            let Some((l, s, j)) = self.recent[k] else {
                break;
            };
            let (c, r) = self.sphere[s];
            // Written where the sphere's placement goes (correct for this batch; its stamp
            // is left alone): computed into a local, LLVM interleaved the three rows with
            // the shape test and took twice the instructions.
            self.sphere_at[s] = self.poses[self.frame[l]].apply_const_on(c, self.avx2);
            let p = self.sphere_at[s];
            let hit = match j {
                Touched::Object(j) => penetrates(&self.objects[j], p, r),
                Touched::Map => lanes_touch_map(map, grid, p, r, self.live),
            };
            if hit {
                self.remembered += 1;
                self.bring_forward(k, self.recent[k]);
                return true;
            }
        }
        // Objects go in groups of 64 (one bit each in the masks below), the map with the
        // first; all but crowded scenes have one group.
        for group in 0..self.objects.len().div_ceil(MASK_BITS).max(1) {
            let map = if group == 0 { map } else { None };
            if self.group_contact::<E>(group, map, grid) {
                return true;
            }
        }
        false
    }

    /// [`BatchChecker::env_contact_with`] down the hierarchy for the objects of one group
    /// and the map, if given.
    #[inline(always)]
    fn group_contact<const E: bool>(
        &mut self,
        group: usize,
        map: Option<&OccupancyMap>,
        grid: Option<&Clearance>,
    ) -> bool {
        let first = group * MASK_BITS;
        let end = self.objects.len().min(first + MASK_BITS);
        'links: for k in 0..self.moving.len() {
            let l = self.moving[k];
            self.place_bound(l);
            if E {
                // The lanes where this link's contacts are still to be found.
                self.live = self.distinct & !self.link_hits[l];
                self.hit = 0;
                if self.live == 0 {
                    continue;
                }
            }
            let (_, br) = self.bound[l].unwrap_or_default();
            let b = self.bounds[l];
            let link_mask = self.objects_reached(group, b, br);
            // The lanes where the map may reach the link (none when the link misses the map's
            // cover boxes), then each cluster, then its spheres: a ball inside one the grid
            // cleared in a lane is clear in that lane.
            // With each level's unclear lanes, a lower bound on the distance from its centre
            // to the voxels: a ball inside it that the bound clears in a lane needs no read.
            let (link_map, link_room) = match map {
                Some(_) => link_unclear(grid, &b, br, self.live, self.avx2),
                None => (0, F8::default()),
            };
            if link_mask == 0 && link_map == 0 {
                continue;
            }
            for ci in self.link_clusters[l].clone() {
                self.place_cluster(l, ci);
                let (c, cr) = (self.cluster_at[ci], self.cluster[ci].1);
                let cluster_mask = penetrated(&self.objects[first..end], link_mask, c, cr);
                let (cluster_map, cluster_room) = unclear_inside(
                    grid,
                    (c, cr),
                    link_map,
                    (link_room, self.cluster_offset[ci]),
                );
                if cluster_mask == 0 && cluster_map == 0 {
                    continue;
                }
                // Spheres not yet placed in this batch are placed one by one as they are
                // tested: most batches end at a link's first spheres in contact.
                let placed = self.sphere_stamp[ci] >= self.epoch;
                let avx2 = self.avx2;
                let pose = &self.poses[self.frame[l]];
                let range = self.cluster[ci].2.clone();
                for (s, (at, &(c, r))) in self.sphere_at[range.clone()]
                    .iter_mut()
                    .zip(&self.sphere[range.clone()])
                    .enumerate()
                    .map(|(k, x)| (range.start + k, x))
                {
                    if !placed {
                        *at = pose.apply_const_on(c, avx2);
                    }
                    let p = *at;
                    let hit = penetrated(&self.objects[first..end], cluster_mask, p, r);
                    if hit != 0
                        && (!E
                            || objects_counted(
                                (&mut self.hit, &mut self.live),
                                &self.objects[first..end],
                                hit,
                                p,
                                r,
                            ))
                    {
                        if E {
                            self.link_hits[l] |= self.hit;
                            continue 'links;
                        }
                        let j = first + hit.trailing_zeros() as usize;
                        self.remember((l, s, Touched::Object(j)));
                        self.keep_for_screening((l, s, j));
                        return true;
                    }
                    let asked = match cluster_map {
                        0 => 0,
                        m => m & !roomy(cluster_room, self.sphere_offset[s] + r),
                    };
                    if asked != 0
                        && lanes_touch_map(map, grid, p, r, asked)
                        && (!E
                            || map_counted(
                                (&mut self.hit, &mut self.live),
                                (map, grid),
                                p,
                                r,
                                asked,
                            ))
                    {
                        if E {
                            self.link_hits[l] |= self.hit;
                            continue 'links;
                        }
                        self.remember((l, s, Touched::Map));
                        return true;
                    }
                }
                // Every sphere of the cluster is placed now.
                self.sphere_stamp[ci] = self.sphere_stamp[ci].max(self.epoch);
            }
            if E {
                self.link_hits[l] |= self.hit;
            }
        }
        false
    }

    /// The objects of group `group` a link's bound (centres `b` in eight lanes, radius `br`)
    /// penetrates in some lane, as bits: world boxes first, then the shapes.
    #[inline(always)]
    fn objects_reached(&self, group: usize, b: [F8; 3], br: f32) -> u64 {
        let first = group * MASK_BITS;
        if self.objects.len() <= first {
            return 0;
        }
        let lo = b.map(|v| v.hmin() - br);
        let hi = b.map(|v| v.hmax() + br);
        let mut cand = 0u64;
        let boxes = &self.object_boxes[first / LANES..];
        for (block, (olo, ohi)) in boxes.iter().take(MASK_BITS / LANES).enumerate() {
            let reach = boxes_overlapping(olo, ohi, lo, hi, self.avx2);
            cand |= (reach as u64) << (block * LANES);
        }
        penetrated(&self.objects[first..], cand, b, br)
    }

    #[inline(always)]
    fn self_contact<const E: bool>(&mut self) -> bool {
        let mut next = 0;
        // Most pairs' bounds are apart in every lane: a tight loop finds those that are not.
        while let Some(k) = next_overlapping(&self.pairs, &self.bounds, next) {
            next = k + 1;
            let SelfPair {
                a,
                b,
                ra,
                rb,
                adjust,
                ..
            } = self.pairs[k];
            let (ba, bb) = (self.bounds[a], self.bounds[b]);
            if !self.box_reached(a, bb, rb) || !self.box_reached(b, ba, ra) {
                continue;
            }
            if E {
                // The lanes where this pair's contacts are still to be found.
                self.live = self.distinct & !self.pair_hits[k];
                self.hit = 0;
            }
            // `b`'s clusters go 64 at a time (one per bit); most links have one such group.
            let clusters_b = self.link_clusters[b].clone();
            for first in clusters_b.clone().step_by(MASK_BITS) {
                let group = first..clusters_b.end.min(first + MASK_BITS);
                if self.clusters_touch::<E>((a, ba, ra), (b, bb, rb), group, adjust) {
                    if E {
                        break;
                    }
                    return true;
                }
            }
            if E {
                self.pair_hits[k] |= self.hit;
            }
        }
        false
    }

    /// True when a sphere of link `a` (bound centres `ba`, radius `ra`) overlaps one of the
    /// clusters `clusters_b` (at most 64) of link `b` in some lane, the spheres' radii summed
    /// with `adjust` (the pair's [`SelfPair::adjust`]).
    #[inline(always)]
    fn clusters_touch<const E: bool>(
        &mut self,
        (a, ba, ra): (usize, [F8; 3], f32),
        (b, bb, rb): (usize, [F8; 3], f32),
        clusters_b: std::ops::Range<usize>,
        adjust: f32,
    ) -> bool {
        // The clusters of `b` within reach of `a`'s bound, as bits.
        let mut near_b = 0u64;
        for (bit, cb) in clusters_b.clone().enumerate() {
            self.place_cluster(b, cb);
            let (pb, crb) = (self.cluster_at[cb], self.cluster[cb].1);
            if overlap(pb, crb, ba, ra) && self.box_reached(a, pb, crb) {
                near_b |= 1 << bit;
            }
        }
        if near_b == 0 {
            return false;
        }
        // `a`'s clusters eight at a time against the box around `b`'s bound's centres, in the
        // frame `a` rides in; those it may reach, then lane by lane.
        let q = self.poses[self.frame[a]].apply_inverse(bb);
        let (lo, hi) = (
            q.map(|v| F8::splat(v.hmin())),
            q.map(|v| F8::splat(v.hmax())),
        );
        let zero = F8::splat(0.0);
        let first = self.link_clusters[a].start;
        for (k, blk) in self.link_blocks[a].clone().enumerate() {
            let ClusterBlock { centre, radius } = self.cluster_blocks[blk];
            let mut d2 = zero;
            for i in 0..3 {
                let gap = (lo[i] - centre[i]).max(centre[i] - hi[i]).max(zero);
                d2 = gap.mul_add(gap, d2);
            }
            let reach = radius + F8::splat(rb + BLOCK_SLACK);
            let mut near_a = d2.le(reach * reach).bits();
            while near_a != 0 {
                let ca = first + k * LANES + near_a.trailing_zeros() as usize;
                near_a &= near_a - 1;
                if self.cluster_pair_touch::<E>(
                    (a, ca),
                    (b, bb, rb),
                    clusters_b.start,
                    near_b,
                    adjust,
                ) {
                    return true;
                }
            }
        }
        false
    }

    /// [`BatchChecker::clusters_touch`] for cluster `ca` of link `a` against the clusters
    /// `near_b` (bits from `first_b`) of link `b` (bound centres `bb`, radius `rb`).
    #[inline(always)]
    fn cluster_pair_touch<const E: bool>(
        &mut self,
        (a, ca): (usize, usize),
        (b, bb, rb): (usize, [F8; 3], f32),
        first_b: usize,
        near_b: u64,
        adjust: f32,
    ) -> bool {
        self.place_cluster(a, ca);
        let (pa, cra) = (self.cluster_at[ca], self.cluster[ca].1);
        if !overlap(pa, cra, bb, rb) || !self.box_reached(b, pa, cra) {
            return false;
        }
        let mut m = near_b;
        while m != 0 {
            let cb = first_b + m.trailing_zeros() as usize;
            m &= m - 1;
            let (pb, crb) = (self.cluster_at[cb], self.cluster[cb].1);
            if !overlap(pa, cra, pb, crb) {
                continue;
            }
            self.place_spheres(a, ca);
            if self.spheres_touch::<E>(b, ca, cb, adjust) {
                return true;
            }
        }
        false
    }

    /// True when the ball (centres `p` in eight lanes, radius `r`) reaches link `l`'s box in
    /// some lane, or the link has no box.
    #[inline(always)]
    fn box_reached(&self, l: usize, p: [F8; 3], r: f32) -> bool {
        let Some((lo, hi)) = self.bound_box[l] else {
            return true;
        };
        let q = self.poses[self.frame[l]].apply_inverse(p);
        box_gap2((lo, hi), q).any_lt(F8::splat(r * r))
    }

    /// The lanes (bits) where [`BatchChecker::box_reached`] finds the ball reaching the box.
    #[inline(always)]
    fn box_lanes(&self, l: usize, p: [F8; 3], r: f32) -> u32 {
        let Some((lo, hi)) = self.bound_box[l] else {
            return ALL_LANES;
        };
        let q = self.poses[self.frame[l]].apply_inverse(p);
        box_gap2((lo, hi), q).lt_mask(F8::splat(r * r)).bits()
    }

    /// True when a sphere of cluster `ca` (placed) overlaps one of cluster `cb` of link `b`
    /// in some lane, their radii summed with `adjust`; `cb`'s spheres are placed only if a
    /// sphere of `ca` reaches its bound.
    #[inline(always)]
    fn spheres_touch<const E: bool>(
        &mut self,
        b: usize,
        ca: usize,
        cb: usize,
        adjust: f32,
    ) -> bool {
        let (pb, crb) = (self.cluster_at[cb], self.cluster[cb].1);
        let range_a = self.cluster[ca].2.clone();
        for i in range_a {
            let (pi, ri) = (self.sphere_at[i], self.sphere[i].1);
            // A sphere clear of the other cluster's bound is clear of its spheres.
            if !overlap(pi, ri, pb, crb) {
                continue;
            }
            // Stamped: placed once per batch however often it is asked.
            self.place_spheres(b, cb);
            let range_b = self.cluster[cb].2.clone();
            let (at_b, model_b) = (&self.sphere_at[range_b.clone()], &self.sphere[range_b]);
            for (&pj, &(_, rj)) in at_b.iter().zip(model_b) {
                if overlap(pi, ri + adjust, pj, rj)
                    && (!E
                        || overlap_counted(
                            (&mut self.hit, &mut self.live),
                            (pi, ri + adjust),
                            (pj, rj),
                        ))
                {
                    return true;
                }
            }
        }
        false
    }
}

/// Writes `clusters` (centres, radii) eight to a block into `blocks`, the lanes past the last
/// far away with radius zero.
fn write_blocks(blocks: &mut [ClusterBlock], clusters: &[([f32; 3], f32, std::ops::Range<usize>)]) {
    for (block, eight) in blocks.iter_mut().zip(clusters.chunks(LANES)) {
        *block = ClusterBlock {
            centre: [F8::splat(1e15); 3],
            radius: F8::splat(0.0),
        };
        for (i, (c, r, _)) in eight.iter().enumerate() {
            for (a, &v) in c.iter().enumerate() {
                block.centre[a].0[i] = v;
            }
            block.radius.0[i] = *r;
        }
    }
}

/// The first self-collision pair from `from` on whose link bounds overlap in some lane.
#[inline(always)]
fn next_overlapping(pairs: &[SelfPair], bounds: &[[F8; 3]], from: usize) -> Option<usize> {
    // A plain loop: closures would be compiled without the caller's AVX2.
    for (k, p) in pairs.iter().enumerate().skip(from) {
        // SAFETY: a pair's links are links of the robot, and `bounds` holds one per link
        // (both made, and checked, in `BatchChecker::for_robot`; neither changes after).
        let (a, b) = unsafe { (bounds.get_unchecked(p.a), bounds.get_unchecked(p.b)) };
        let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
        if dx
            .mul_add(dx, dy.mul_add(dy, dz * dz))
            .any_lt(F8::splat(p.reach2))
        {
            return Some(k);
        }
    }
    None
}

/// True when balls `(a, ra)` and `(b, rb)` overlap in some lane.
#[inline(always)]
fn overlap(a: [F8; 3], ra: f32, b: [F8; 3], rb: f32) -> bool {
    let r = ra + rb;
    gap2(a, b).any_lt(F8::splat(r * r))
}

/// The lanes (bits) where [`overlap`] finds the balls overlapping.
#[inline(always)]
fn overlap_lanes(a: [F8; 3], ra: f32, b: [F8; 3], rb: f32) -> u32 {
    let r = ra + rb;
    gap2(a, b).lt_mask(F8::splat(r * r)).bits()
}

/// The squared distances from the points `q` (eight lanes) to the box `[lo, hi]`.
#[inline(always)]
fn box_gap2((lo, hi): ([f32; 3], [f32; 3]), q: [F8; 3]) -> F8 {
    let zero = F8::splat(0.0);
    let mut d2 = zero;
    for i in 0..3 {
        let gap = (F8::splat(lo[i]) - q[i])
            .max(q[i] - F8::splat(hi[i]))
            .max(zero);
        d2 = gap.mul_add(gap, d2);
    }
    d2
}

/// The squared distances between the points `a` and `b`, lane by lane.
#[inline(always)]
fn gap2(a: [F8; 3], b: [F8; 3]) -> F8 {
    let (dx, dy, dz) = (a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    dx.mul_add(dx, dy.mul_add(dy, dz * dz))
}

/// Of the lanes in `lanes` (bits), those where the grid cannot clear the ball (centres `p`,
/// radius `r`); all of them without a grid.
#[inline(always)]
fn unclear_lanes(grid: Option<&Clearance>, p: [F8; 3], r: f32, lanes: u32) -> u32 {
    unclear_within(grid, p, r, lanes).0
}

/// [`unclear_lanes`], with each lane's lower bound on the distance from `p` to the voxels
/// ([`Clearance::unclear8_within`]; zero without a grid).
#[inline(always)]
fn unclear_within(grid: Option<&Clearance>, p: [F8; 3], r: f32, lanes: u32) -> (u32, F8) {
    // No closures on this path: they would be compiled without the caller's AVX2.
    match grid {
        Some(g) if lanes != 0 => g.unclear8_within(p, r, lanes),
        _ => (lanes, F8::default()),
    }
}

/// [`unclear_within`] for a link's bound (centres `p`, radius `r`), first against the map's
/// cover boxes ([`Clearance::missed8`]): a link that misses them in every lane needs no read.
/// Out of line, and compiled for AVX2 where the CPU has it (`avx2`): inlined, the test changed
/// the walk's register allocation and cost the checks against objects alone 4% more
/// instructions.
#[inline(always)]
fn link_unclear(
    grid: Option<&Clearance>,
    p: &[F8; 3],
    r: f32,
    lanes: u32,
    avx2: bool,
) -> (u32, F8) {
    let Some(g) = grid else {
        return (lanes, F8::default());
    };
    if lanes == 0 {
        return (0, F8::default());
    }
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: the CPU has AVX2 (the caller says so, from `has_avx2`).
        return unsafe { link_unclear_avx2(g, p, r, lanes) };
    }
    let _ = avx2;
    link_unclear_apart(g, p, r, lanes)
}

/// [`link_unclear`]'s test, out of line.
#[inline(never)]
fn link_unclear_apart(g: &Clearance, p: &[F8; 3], r: f32, lanes: u32) -> (u32, F8) {
    cover_then_grid(g, p, r, lanes)
}

/// [`link_unclear`]'s test, out of line, compiled for AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
unsafe fn link_unclear_avx2(g: &Clearance, p: &[F8; 3], r: f32, lanes: u32) -> (u32, F8) {
    cover_then_grid(g, p, r, lanes)
}

#[inline(always)]
fn cover_then_grid(g: &Clearance, p: &[F8; 3], r: f32, lanes: u32) -> (u32, F8) {
    if g.missed8(*p, r) {
        return (0, F8::default());
    }
    g.unclear8_within(*p, r, lanes)
}

/// [`unclear_within`] for a ball (centres `p`, radius `r`) inside an outer one left unclear in
/// `lanes`, whose read gave the lower bound `room` there: the lanes where the ball's `offset`
/// from the outer centre plus its radius stays within the bound are clear without a read.
#[inline(always)]
fn unclear_inside(
    grid: Option<&Clearance>,
    (p, r): ([F8; 3], f32),
    lanes: u32,
    (room, offset): (F8, f32),
) -> (u32, F8) {
    if lanes == 0 {
        return (0, F8::default());
    }
    unclear_within(grid, p, r, lanes & !roomy(room, offset + r))
}

/// The lanes (bits) whose lower bound `room` on the distance to the voxels reaches `reach`:
/// there a ball reaching that far from the bound's centre is clear.
#[inline(always)]
fn roomy(room: F8, reach: f32) -> u32 {
    F8::splat(reach).le(room).bits()
}

/// True when the ball touches an occupied voxel in one of `lanes` (bits): the grid clears
/// what it can and confirms the contacts it can, the map's voxels decide the rest.
#[inline(always)]
fn lanes_touch_map(
    map: Option<&OccupancyMap>,
    grid: Option<&Clearance>,
    p: [F8; 3],
    r: f32,
    lanes: u32,
) -> bool {
    let Some(m) = map else {
        return false;
    };
    if lanes.is_power_of_two() {
        // One lane (a fifth of the spheres' reads): the map's own test of that ball, whose
        // read of its cell in `f64` costs a sixth of the eight lanes' read.
        let i = lanes.trailing_zeros() as usize;
        let c = [p[0].0[i], p[1].0[i], p[2].0[i]].map(f64::from);
        return m.sphere_collides_in(grid, c, f64::from(r));
    }
    let mut unclear = match grid {
        Some(g) if lanes != 0 => match g.sphere8(p, r, lanes) {
            Some(unclear) => unclear,
            None => return true,
        },
        _ => lanes,
    };
    while unclear != 0 {
        let i = unclear.trailing_zeros() as usize;
        unclear &= unclear - 1;
        let c = [p[0].0[i], p[1].0[i], p[2].0[i]].map(f64::from);
        // The lane's own cell could not decide it: the cells around it, then the voxels.
        let rf = f64::from(r);
        let touches = match grid.and_then(|g| g.refine(c, rf)) {
            Some(touches) => touches,
            None => m.sphere_touches_voxels(c, rf),
        };
        if touches {
            return true;
        }
    }
    false
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::world::environment::random_boxes;
    use rand::SeedableRng;

    /// Six random boxes in front of the robot, where arms reach.
    fn six_boxes(rng: &mut rand::rngs::StdRng) -> Environment {
        random_boxes(rng, 6, [0.3, 0.2, 0.1], [0.2..1.0, -0.6..0.6, 0.2..1.4])
    }

    /// The AVX2 code (with fused multiply-adds) and the portable code (whose fused
    /// multiply-adds are library calls here) place every link at the same pose, bit for bit,
    /// and give the same verdicts, on Fetch (axis-aligned joints) and Panda (quarter-turn
    /// origins) among random boxes.
    #[test]
    fn avx2_poses_and_verdicts_equal_the_portable_ones() {
        if !has_avx2() {
            return;
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let env = six_boxes(&mut rng);
            let mut vector = BatchChecker::new(&robot, &env);
            let mut portable = vector.clone();
            portable.avx2 = false;
            let mut q = vec![0.0; robot.dof()];
            let (mut hits, mut runs) = (0, 0);
            for _ in 0..300 {
                let lanes: Vec<F8> = (0..robot.dof())
                    .map(|j| {
                        F8(std::array::from_fn(|_| {
                            robot.sample_uniform(&mut rng, &mut q);
                            q[j] as f32
                        }))
                    })
                    .collect();
                let verdict = vector.may_collide(&lanes);
                assert_eq!(verdict, portable.may_collide(&lanes), "{name}");
                for &l in &vector.posed {
                    let bits = |p: &Pose8| {
                        p.r.iter()
                            .chain(&p.t)
                            .map(|v| v.0.map(f32::to_bits))
                            .collect::<Vec<_>>()
                    };
                    assert_eq!(
                        bits(&vector.poses[l]),
                        bits(&portable.poses[l]),
                        "{name} link {l}"
                    );
                }
                hits += usize::from(verdict);
                runs += 1;
            }
            assert!(
                hits > 0 && hits < runs,
                "{name}: {hits} of {runs} in contact"
            );
        }
    }

    /// A checker under test, one to compare it with, and a copy running the portable code.
    fn three_checkers(
        robot: &Robot,
        env: &Environment,
    ) -> (BatchChecker, BatchChecker, BatchChecker) {
        let sut = BatchChecker::new(robot, env);
        let mut portable = sut.clone();
        portable.avx2 = false;
        (sut.clone(), sut, portable)
    }

    /// A state's flags agree with the full check (flagged exactly when it is), in AVX2 and
    /// portable code alike, and what they leave unflagged is clear on the exact geometry: the
    /// links not flagged touch no object, the pairs not flagged do not touch, and the flags
    /// name every part the exact checker tests; on random states of both robots among random
    /// boxes (where all four outcomes occur: nothing flagged, the pairs alone, the
    /// environment alone, both).
    #[test]
    fn unflagged_parts_are_clear_in_the_exact_geometry() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(13);
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let env = six_boxes(&mut rng);
            let (mut sut, mut full, mut portable) = three_checkers(&robot, &env);
            let mut exact = crate::collision::exact::ExactChecker::new(&robot, &env);
            let (links, pairs) = exact.moving_parts();
            let (links, pairs) = (links.to_vec(), pairs.to_vec());
            assert!(sut.flags_cover(&links, &pairs), "{name}");
            let key = |(a, b): (usize, usize)| (a.min(b), a.max(b));
            let mut q = vec![0.0; robot.dof()];
            let mut seen = std::collections::HashSet::new();
            for _ in 0..1500 {
                robot.sample_uniform(&mut rng, &mut q);
                let flags = sut.state_flags(&q);
                assert_eq!(flags, portable.state_flags(&q), "{name}");
                assert_eq!(flags.any(), full.state_may_collide(&q), "{name}");
                let flagged: Vec<_> = sut.flagged_links(0).collect();
                let clear: Vec<_> = links
                    .iter()
                    .copied()
                    .filter(|l| !flagged.contains(l))
                    .collect();
                assert!(
                    exact.contact_of_parts(&q, &clear, &[]).is_none(),
                    "{name}: {q:?}"
                );
                let flagged: Vec<_> = sut.flagged_pairs(0).map(key).collect();
                let apart: Vec<_> = pairs
                    .iter()
                    .copied()
                    .filter(|&p| !flagged.contains(&key(p)))
                    .collect();
                assert!(
                    exact.contact_of_parts(&q, &[], &apart).is_none(),
                    "{name}: {q:?}"
                );
                assert_eq!(flags.env, sut.flagged_links(0).next().is_some(), "{name}");
                assert_eq!(flags.pairs, sut.flagged_pairs(0).next().is_some(), "{name}");
                seen.insert((flags.env, flags.pairs));
            }
            assert_eq!(seen.len(), 4, "{name}: flags seen {seen:?}");
        }
    }

    /// The flags of a state alone by the early-ending tests (the environment's and the
    /// hiding test's when validating, the self pairs'): what each lane of
    /// [`BatchChecker::lane_flags`] must give (the built-in robots have no part that could
    /// hide in another link, so the hiding test flags only the environment).
    fn flags_alone(c: &mut BatchChecker, q: &[f64]) -> StateFlags {
        for (lane, &v) in c.lanes.iter_mut().zip(q) {
            *lane = F8::splat(v as f32);
        }
        c.live = 1;
        c.begin(None);
        let env = c.env_contact::<false>();
        // An environment contact ends that walk before every link's bound is placed.
        for k in 0..c.moving.len() {
            c.place_bound(c.moving[k]);
        }
        let pairs = c.self_contact::<false>();
        let env = env || (c.validating && c.may_hide::<false>());
        c.live = ALL_LANES;
        StateFlags { env, pairs }
    }

    /// Each lane's flags from one walk of eight states are the state's own (those of the
    /// early-ending tests on it alone, and of `state_flags`), in AVX2 and portable code
    /// alike: on eight states along short motions of both robots, among random boxes and a
    /// map's voxels and beads that fit inside links, with the balls as built, grown, and
    /// validating (so that a batch mixes states in contact with clear ones, and every kind of
    /// contact ends some walk).
    #[test]
    fn lane_flags_are_each_states_own() {
        use crate::world::map::{MapParams, OccupancyMap};
        use rand::Rng;
        let mut rng = rand::rngs::StdRng::seed_from_u64(21);
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let mut env = six_boxes(&mut rng);
            // Beads small enough to lie inside a link unseen by its spheres (the hiding test).
            for i in 0..30 {
                let at = [0.0..0.9, -0.6..0.6, 0.2..1.4].map(|r| rng.random_range(r));
                env.add(crate::world::Object {
                    name: format!("bead{i}"),
                    shape: crate::collision::Shape::cuboid([0.004; 3]),
                    pose: crate::Pose::translation(at[0], at[1], at[2]),
                })
                .unwrap();
            }
            let mut map = OccupancyMap::new(MapParams {
                resolution: 0.02,
                ..MapParams::default()
            });
            for _ in 0..300 {
                let p = [
                    rng.random_range(0.2..1.0),
                    rng.random_range(-0.6..0.6),
                    rng.random_range(0.2..1.3),
                ];
                map.set_voxel(map.key_of(p), true);
            }
            env.set_map(Some(Arc::new(map)));
            let (n, links) = (robot.dof(), robot.links().len());
            for mode in ["built", "grown", "validating"] {
                let (mut sut, mut alone, mut portable) = three_checkers(&robot, &env);
                for c in [&mut sut, &mut alone, &mut portable] {
                    match mode {
                        "grown" => c.inflate(&vec![0.01; links], &[]),
                        "validating" => assert!(c.validate(true)),
                        _ => {}
                    }
                }
                let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
                let mut qs = vec![vec![0.0; n]; LANES];
                let mut lanes = vec![F8::default(); n];
                let (mut mixed, mut kinds) = (0, std::collections::HashSet::new());
                for _ in 0..300 {
                    robot.sample_uniform(&mut rng, &mut a);
                    robot.sample_uniform(&mut rng, &mut b);
                    for (i, q) in qs.iter_mut().enumerate() {
                        robot.interpolate(&a, &b, 0.03 * i as f64, q);
                        for (lane, &v) in lanes.iter_mut().zip(q.iter()) {
                            lane.0[i] = v as f32;
                        }
                    }
                    let flags = sut.lane_flags(&lanes);
                    assert_eq!(flags, portable.lane_flags(&lanes), "{name} {mode}");
                    for (i, q) in qs.iter().enumerate() {
                        let own = flags_alone(&mut alone, q);
                        assert_eq!(flags.lane(i), own, "{name} {mode} lane {i}: {q:?}");
                        assert_eq!(alone.state_flags(q), own, "{name} {mode}");
                        // The same parts flagged as for the state alone.
                        let parts = |c: &BatchChecker, i| {
                            let links: Vec<_> = c.flagged_links(i).collect();
                            (links, c.flagged_pairs(i).collect::<Vec<_>>())
                        };
                        assert_eq!(parts(&sut, i), parts(&alone, 0), "{name} {mode} lane {i}");
                        assert_eq!(parts(&sut, i), parts(&portable, i), "{name} {mode}");
                        kinds.insert((own.env, own.pairs));
                    }
                    let flagged = flags.env | flags.pairs;
                    mixed += usize::from(flagged != 0 && flagged != ALL_LANES);
                }
                assert!(mixed >= 20, "{name} {mode}: {mixed} mixed batches");
                assert_eq!(kinds.len(), 4, "{name} {mode}: flags seen {kinds:?}");
            }
        }
    }

    /// Grown from an earlier growth (links grown by as much already left alone), the balls,
    /// boxes and pairs are those a growth from the radii as built gives, and deflating gives
    /// back the radii as built.
    #[test]
    fn growth_from_an_earlier_growth_is_a_fresh_growth() {
        let robot = Robot::builtin("fetch").unwrap();
        let env = six_boxes(&mut rand::rngs::StdRng::seed_from_u64(3));
        let built = BatchChecker::new(&robot, &env);
        let links = robot.links().len();
        let radii = |c: &BatchChecker| {
            let pairs: Vec<_> = c
                .pairs
                .iter()
                .map(|p| (p.ra, p.rb, p.reach2, p.adjust))
                .collect();
            let spheres: Vec<f32> = c.sphere.iter().map(|s| s.1).collect();
            let clusters: Vec<f32> = c.cluster.iter().map(|s| s.1).collect();
            (
                c.bound.clone(),
                c.bound_box.clone(),
                clusters,
                spheres,
                pairs,
            )
        };
        let first: Vec<f32> = (0..links).map(|l| 0.001 * l as f32).collect();
        let mut second = first.clone();
        second[links - 1] += 0.01;
        second[links / 2] = 0.0;
        let caps = vec![0.004; links * links];
        let mut sut = built.clone();
        sut.inflate(&first, &[]);
        sut.inflate(&second, &caps);
        let mut fresh = built.clone();
        fresh.inflate(&second, &caps);
        assert!(radii(&sut) == radii(&fresh));
        assert!(radii(&sut) != radii(&built));
        sut.deflate();
        assert!(radii(&sut) == radii(&built));
        sut.inflate(&second, &caps);
        assert!(radii(&sut) == radii(&fresh));
    }

    /// A state the screen flags is one the full check finds in contact, in AVX2 and
    /// portable code alike (the same flags), and after some checks have found contacts the
    /// screen flags many colliding states, none of the free ones.
    #[test]
    fn screened_states_are_in_contact() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let env = six_boxes(&mut rng);
            let (mut sut, mut full, mut portable) = three_checkers(&robot, &env);
            let state = |rng: &mut rand::rngs::StdRng| {
                let mut q = vec![0.0; robot.dof()];
                robot.sample_uniform(rng, &mut q);
                q
            };
            assert_eq!(
                sut.surely_colliding(&[&state(&mut rng)]),
                0,
                "nothing found yet"
            );
            let (mut flagged, mut colliding) = (0, 0);
            for round in 0..400 {
                // Checks find contacts (and teach both screens the same ones).
                let q = state(&mut rng);
                sut.state_may_collide(&q);
                portable.state_may_collide(&q);
                let n = 1 + round % LANES;
                let states: Vec<Vec<f64>> = (0..n).map(|_| state(&mut rng)).collect();
                let refs: Vec<&[f64]> = states.iter().map(|q| &q[..]).collect();
                let flags = sut.surely_colliding(&refs);
                assert_eq!(flags, portable.surely_colliding(&refs), "{name}");
                assert_eq!(flags >> n, 0, "{name}: a lane past the states");
                for (i, q) in states.iter().enumerate() {
                    let hit = full.state_may_collide(q);
                    colliding += usize::from(hit);
                    if flags & (1 << i) != 0 {
                        flagged += 1;
                        assert!(hit, "{name}: a free state flagged");
                    }
                }
            }
            assert!(
                flagged * 4 > colliding,
                "{name}: {flagged} of {colliding} colliding states flagged"
            );
        }
    }
}
