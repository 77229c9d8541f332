//! Certified motions: a returned path clear between its checked states, not only at them.
//!
//! A discrete walk checks a motion's states a resolution apart, and a hand's corner moves
//! centimetres between two of them: it can graze an object there unseen. Between two states the
//! robot's [`Sweep`] bounds how far any point of each link strays from where it is at the
//! nearer of the two (from their poses: the chord its bound ball's centre moves, its turn and
//! the chord's bend, [`Step::half_motion`]). So a motion between two states is clear all the
//! way when, at each end, every link `l` is clear of the objects and the map by that bound
//! `m_l`, and each pair of links by the sum of theirs or, where that is less, by half of how
//! far the joints between them can move one relative to the other ([`Sweep::pair_half_motion`]:
//! a hand and its fingers, with no joint between them, need no margin from each other). Each
//! edge's states (at the validation's resolution) are checked so, the links grown by those
//! margins (a state's the larger of its two segments'): eight states at a time in the sphere
//! lanes first (grown by the eight states' largest; one walk gives each state's own flags,
//! [`BatchChecker::lane_flags`]), then the flagged states on the exact geometry with their own
//! margins (only the links and the pairs of links the lanes flag,
//! [`BatchChecker::flagged_links`]). A segment whose ends are not both clear is halved, and its
//! halves asked again with their own (smaller) margins, down to [`DEPTH`] halvings (segments 32
//! times shorter); there its states are checked without a margin, as a discrete walk would
//! check them, and a contact found between the validation's states is returned. Only what is
//! left at that depth (a state closer than a hair to something, where a motion could also just
//! touch it) is not certified; [`Certified::uncertified`] counts those segments.

use crate::collision::batch::lanes::{F8, LANES};
use crate::collision::batch::BatchChecker;
use crate::collision::checker::{steps_over, Contact};
use crate::collision::exact::ExactChecker;
use crate::robot::sweep::{Step, Sweep};
use crate::robot::Robot;
use rustc_hash::FxHashMap;

/// Halvings of a segment before its states are only checked (the finest segments are
/// `2^DEPTH` times shorter than the validation's resolution).
pub const DEPTH: u32 = 5;

/// A batch of states is checked with each link grown by as much as for the last batch where
/// that covers its margin and exceeds it by at most a quarter or this much (metres).
const REGROW_SLACK: f32 = 5e-4;

/// What each state of an edge is known to be, by its place on the finest grid.
#[derive(Clone, Copy)]
struct Known {
    /// The coarsest level at which it is clear by that level's margins (a state's margins
    /// shrink from level to level, so clear at one level is clear at every finer one).
    clear_at: Option<u32>,
    /// Free without a margin.
    free: bool,
    /// Where its links' bound-ball centres are kept (in links, in `Certified::centres`).
    slot: usize,
}

/// The certification's working state for one robot (kept by the validity checks).
pub(crate) struct Certified {
    sweep: Sweep,
    links: usize,
    delta: Vec<f64>,
    /// A segment's differences at the current level, and what they bound.
    step: Vec<f64>,
    bounds: Step,
    /// A segment's margins (one per link).
    half: Vec<f64>,
    known: FxHashMap<u64, Known>,
    /// Per known state, per link: its bound ball's centre, placed in the batch checker's lanes
    /// ([`BatchChecker::bound_centres`]).
    centres: Vec<[f64; 3]>,
    segments: Vec<(u64, u64)>,
    next: Vec<(u64, u64)>,
    /// The states asked at the current level, with where their margins are in `margins`.
    asked: Vec<(u64, usize)>,
    slots: FxHashMap<u64, usize>,
    /// Per asked state, per link: the margin it must be clear by.
    margins: Vec<f64>,
    margins32: Vec<f32>,
    /// The links' margins the batch checker is grown by (empty: not grown at this level).
    inflated: Vec<f32>,
    /// Per pair of links (`links × links`): the margin two links must be clear of each other
    /// by at the current level, from the joints between them ([`Sweep::pair_half_motion`]).
    pair_margins: Vec<f64>,
    pair_margins32: Vec<f32>,
    /// States to place, and their links' centres in eight lanes.
    missing: Vec<u64>,
    centres8: Vec<[F8; 3]>,
    q: Vec<f64>,
    lanes: Vec<F8>,
    /// Whether the lanes' flags name every part the exact checker tests (so that a flagged
    /// state is asked of the exact geometry only for its flagged links and pairs), once known.
    parts_named: Option<bool>,
    /// A flagged state's links and pairs.
    links_flagged: Vec<usize>,
    pairs_flagged: Vec<(usize, usize)>,
    uncertified: u64,
}

impl Certified {
    pub(crate) fn new(robot: &Robot) -> Self {
        let (n, links) = (robot.dof(), robot.links().len());
        Certified {
            sweep: Sweep::new(robot),
            links,
            delta: vec![0.0; n],
            step: vec![0.0; n],
            bounds: Step::default(),
            half: vec![0.0; links],
            known: FxHashMap::default(),
            centres: Vec::new(),
            segments: Vec::new(),
            next: Vec::new(),
            asked: Vec::new(),
            slots: FxHashMap::default(),
            margins: Vec::new(),
            margins32: vec![0.0; links],
            inflated: Vec::new(),
            pair_margins: vec![0.0; links * links],
            pair_margins32: vec![0.0; links * links],
            missing: Vec::new(),
            centres8: vec![[F8::splat(0.0); 3]; links],
            q: vec![0.0; n],
            lanes: vec![F8::splat(0.0); n],
            parts_named: None,
            links_flagged: Vec::new(),
            pairs_flagged: Vec::new(),
            uncertified: 0,
        }
    }

    /// Segments of the finest length left uncertified so far (their states checked free).
    pub(crate) fn uncertified(&self) -> u64 {
        self.uncertified
    }

    /// The first contact between the states of `path`'s edges at `resolution` (each already
    /// found free, by the discrete walk): see the module docs. `batch` is in validation mode
    /// (obstacles that could hide inside a link flag its states, as they do there); it is
    /// left with its radii as built, and `exact` without margins. (Kept out of line: profiles
    /// name it.)
    #[inline(never)]
    pub(crate) fn path_contact(
        &mut self,
        robot: &Robot,
        (batch, exact): (&mut BatchChecker, &mut ExactChecker<'_>),
        resolution: f64,
        path: &[Vec<f64>],
    ) -> Option<Contact> {
        let found = path
            .windows(2)
            .find_map(|w| self.edge_contact(robot, (&mut *batch, &mut *exact), resolution, w));
        batch.deflate();
        exact.set_margins(&[], &[]);
        found
    }

    fn edge_contact(
        &mut self,
        robot: &Robot,
        (batch, exact): (&mut BatchChecker, &mut ExactChecker<'_>),
        resolution: f64,
        edge: &[Vec<f64>],
    ) -> Option<Contact> {
        let (a, b) = (&edge[0][..], &edge[1][..]);
        let n = steps_over(robot.deltas(a, b, &mut self.delta), resolution).max(1) as u64;
        let unit = 1u64 << DEPTH;
        let finest = n * unit;
        self.known.clear();
        self.centres.clear();
        self.segments.clear();
        for k in 0..n {
            self.segments.push((k * unit, (k + 1) * unit));
        }
        for level in 0..=DEPTH {
            if self.segments.is_empty() {
                break;
            }
            self.margins_at(robot, batch, (a, b), finest, n << level, level);
            if level == 0 {
                // The validation's own states were found free.
                for k in 0..=n {
                    self.known.get_mut(&(k * unit)).expect("an end").free = true;
                }
            }
            self.clear_states(robot, (&mut *batch, &mut *exact), (a, b), finest, level);
            self.next.clear();
            for i in 0..self.segments.len() {
                let (k0, k1) = self.segments[i];
                let clear = [k0, k1].map(|k| self.known[&k].clear_at.is_some_and(|at| at <= level));
                if clear == [true, true] {
                    continue;
                }
                if level < DEPTH {
                    let mid = (k0 + k1) / 2;
                    self.next.push((k0, mid));
                    self.next.push((mid, k1));
                    continue;
                }
                // As far as it is halved (the last level: the checkers stay plain for the
                // rest of it): its states checked as a discrete walk would.
                batch.deflate();
                exact.set_margins(&[], &[]);
                for k in [k0, k1] {
                    if self.known[&k].free {
                        continue;
                    }
                    robot.interpolate(a, b, k as f64 / finest as f64, &mut self.q);
                    if batch.state_may_collide(&self.q) {
                        if let Some(c) = exact.contact(&self.q) {
                            return Some(c);
                        }
                    }
                    self.known.get_mut(&k).expect("known").free = true;
                }
                self.uncertified += 1;
            }
            std::mem::swap(&mut self.segments, &mut self.next);
        }
        None
    }

    /// Makes the segments' ends not seen yet known, their links' centres placed eight states
    /// at a time in the batch checker's lanes ([`BatchChecker::bound_centres`]).
    fn know_ends(
        &mut self,
        robot: &Robot,
        batch: &mut BatchChecker,
        (a, b): (&[f64], &[f64]),
        finest: u64,
    ) {
        let links = self.links;
        self.missing.clear();
        for &(k0, k1) in &self.segments {
            self.missing
                .extend([k0, k1].into_iter().filter(|k| !self.known.contains_key(k)));
        }
        self.missing.sort_unstable();
        self.missing.dedup();
        for chunk in self.missing.chunks(LANES) {
            fill_lanes(
                robot,
                (a, b),
                finest,
                chunk.iter().copied(),
                &mut self.q,
                &mut self.lanes,
            );
            batch.bound_centres(&self.lanes, &mut self.centres8);
            for (i, &k) in chunk.iter().enumerate() {
                let slot = self.centres.len() / links;
                let at = self.centres8.iter().map(|c| c.map(|v| f64::from(v.0[i])));
                self.centres.extend(at);
                let known = Known {
                    clear_at: None,
                    free: false,
                    slot,
                };
                self.known.insert(k, known);
            }
        }
    }

    /// Gathers the states the current segments (each `1 / parts` of the edge) need clear at
    /// `level` and not yet known so, each with its margins: per link, the larger of its
    /// segments' [`Step::half_motion`].
    fn margins_at(
        &mut self,
        robot: &Robot,
        batch: &mut BatchChecker,
        (a, b): (&[f64], &[f64]),
        finest: u64,
        parts: u64,
        level: u32,
    ) {
        let links = self.links;
        for (s, d) in self.step.iter_mut().zip(&self.delta) {
            *s = d / parts as f64;
        }
        self.sweep.step(&self.step, &mut self.bounds);
        self.sweep
            .pair_half_motion(&self.step, &mut self.pair_margins);
        for (m32, m) in self.pair_margins32.iter_mut().zip(&self.pair_margins) {
            *m32 = *m as f32;
        }
        self.know_ends(robot, batch, (a, b), finest);
        self.asked.clear();
        self.slots.clear();
        self.margins.clear();
        for i in 0..self.segments.len() {
            let (k0, k1) = self.segments[i];
            let ends = [k0, k1].map(|k| self.known[&k].slot);
            let c = |slot: usize| &self.centres[slot * links..(slot + 1) * links];
            self.bounds
                .half_motion((c(ends[0]), c(ends[1])), &mut self.half);
            for k in [k0, k1] {
                if self.known[&k].clear_at.is_some_and(|at| at <= level) {
                    continue;
                }
                let slot = *self.slots.entry(k).or_insert_with(|| {
                    self.asked.push((k, self.margins.len() / links));
                    self.margins.resize(self.margins.len() + links, 0.0);
                    self.margins.len() / links - 1
                });
                let m = &mut self.margins[slot * links..(slot + 1) * links];
                for (m, h) in m.iter_mut().zip(&self.half) {
                    *m = m.max(*h);
                }
            }
        }
        self.asked.sort_unstable();
    }

    /// Decides the states `self.asked` (places on the finest grid of `finest` steps from `a`
    /// to `b`) at their margins: eight at a time in the lanes (grown by the eight's largest,
    /// each state's flags from one walk), and those the lanes flag on the exact geometry with
    /// their own.
    fn clear_states(
        &mut self,
        robot: &Robot,
        (batch, exact): (&mut BatchChecker, &mut ExactChecker<'_>),
        (a, b): (&[f64], &[f64]),
        finest: u64,
        level: u32,
    ) {
        let links = self.links;
        let parts_named = *self.parts_named.get_or_insert_with(|| {
            let (links, pairs) = exact.moving_parts();
            batch.flags_cover(links, pairs)
        });
        // The pairs' margins are new at each level.
        self.inflated.clear();
        exact.set_margins(&[], &self.pair_margins);
        for chunk in self.asked.chunks(LANES) {
            fill_lanes(
                robot,
                (a, b),
                finest,
                chunk.iter().map(|&(k, _)| k),
                &mut self.q,
                &mut self.lanes,
            );
            self.margins32.fill(0.0);
            for &(_, slot) in chunk {
                let m = &self.margins[slot * links..(slot + 1) * links];
                for (m32, &m) in self.margins32.iter_mut().zip(m) {
                    *m32 = m32.max(m as f32);
                }
            }
            // Each link grown again only where its last growth falls short or is much too
            // large: growing every sphere costs about as much as checking the batch.
            let mut changed = self.inflated.len() != links;
            if changed {
                self.inflated.clone_from(&self.margins32);
            }
            for (have, &need) in self.inflated.iter_mut().zip(&self.margins32) {
                if !(need <= *have && *have <= need + (0.25 * need).max(REGROW_SLACK)) {
                    *have = need;
                    changed = true;
                }
            }
            if changed {
                batch.inflate(&self.inflated, &self.pair_margins32);
            }
            // Each state's flags from one walk of the eight; the exact geometry is asked only
            // what the lanes flag.
            let flags = batch.lane_flags(&self.lanes);
            for (i, &(k, slot)) in chunk.iter().enumerate() {
                let flags = flags.lane(i);
                let clear = !flags.any() || {
                    robot.interpolate(a, b, k as f64 / finest as f64, &mut self.q);
                    let own = &self.margins[slot * links..(slot + 1) * links];
                    exact.set_link_margins(own);
                    if parts_named {
                        self.links_flagged.clear();
                        self.links_flagged.extend(batch.flagged_links(i));
                        self.pairs_flagged.clear();
                        self.pairs_flagged.extend(batch.flagged_pairs(i));
                        let (l, p) = (&self.links_flagged, &self.pairs_flagged);
                        exact.contact_of_parts(&self.q, l, p).is_none()
                    } else {
                        exact.contact_of(&self.q, flags.env, flags.pairs).is_none()
                    }
                };
                if clear {
                    let known = self.known.get_mut(&k).expect("known");
                    known.clear_at = Some(level);
                    known.free = true;
                }
            }
        }
    }
}

/// Writes the states `ks` (places on the finest grid of `finest` steps from `a` to `b`, at
/// most eight) into `lanes` (per variable), the last repeated in the lanes left over.
fn fill_lanes(
    robot: &Robot,
    (a, b): (&[f64], &[f64]),
    finest: u64,
    ks: impl IntoIterator<Item = u64>,
    q: &mut [f64],
    lanes: &mut [F8],
) {
    let mut last = None;
    let mut ks = ks.into_iter();
    for i in 0..LANES {
        if let Some(k) = ks.next().or(last) {
            if last != Some(k) || i == 0 {
                robot.interpolate(a, b, k as f64 / finest as f64, q);
            }
            last = Some(k);
        }
        for (lane, &v) in lanes.iter_mut().zip(q.iter()) {
            lane.0[i] = v as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::fill_lanes;
    use crate::collision::batch::lanes::{F8, LANES};
    use crate::collision::batch::BatchChecker;
    use crate::collision::checker::steps_over;
    use crate::collision::exact::ExactChecker;
    use crate::collision::Shape;
    use crate::planning::exact_path_contact;
    use crate::planning::validity::tests::extend_randomly;
    use crate::planning::validity::Validity;
    use crate::robot::sweep::{Sweep, CENTRE_SLACK};
    use crate::robot::Robot;
    use crate::world::{Environment, Object};
    use crate::Pose;
    use rand::{Rng, SeedableRng};

    /// The links' centres placed in the batch checker's `f32` lanes, from which certification
    /// takes its chords, are the scalar forward kinematics' within the chords' slack (a
    /// tenth of it), on random states of both robots.
    #[test]
    fn centres_in_the_lanes_are_the_scalar_ones() {
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let sweep = Sweep::new(&robot);
            let mut batch = BatchChecker::new(&robot, &Environment::default());
            let (n, links) = (robot.dof(), robot.links().len());
            let mut rng = rand::rngs::StdRng::seed_from_u64(5);
            let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
            robot.sample_uniform(&mut rng, &mut a);
            robot.sample_uniform(&mut rng, &mut b);
            let (mut q, mut lanes) = (vec![0.0; n], vec![F8::splat(0.0); n]);
            let mut centres8 = vec![[F8::splat(0.0); 3]; links];
            let mut scalar = vec![[0.0; 3]; links];
            let mut poses = vec![Pose::identity(); links];
            let ks: Vec<u64> = (0..LANES as u64).map(|i| i * 37 % 256).collect();
            fill_lanes(
                &robot,
                (&a, &b),
                256,
                ks.iter().copied(),
                &mut q,
                &mut lanes,
            );
            batch.bound_centres(&lanes, &mut centres8);
            let mut worst: f64 = 0.0;
            for (i, &k) in ks.iter().enumerate() {
                robot.interpolate(&a, &b, k as f64 / 256.0, &mut q);
                robot.forward_kinematics(&q, &mut poses);
                sweep.centres(&poses, &mut scalar);
                for l in (0..links).filter(|&l| robot.spheres().bounds[l].is_some()) {
                    let lane = centres8[l].map(|v| f64::from(v.0[i]));
                    let d = (0..3)
                        .map(|x| (lane[x] - scalar[l][x]).powi(2))
                        .sum::<f64>();
                    worst = worst.max(d.sqrt());
                }
            }
            assert!(worst < 0.1 * CENTRE_SLACK, "{name}: {worst} m apart");
        }
    }

    /// On Fetch and the Panda, random paths of two motions among shelves or scattered grains,
    /// most with one more grain planted on a part of the hand halfway between two of
    /// the validation's states: a certified validation finds every contact an exact walk 64
    /// times finer than the validation's resolution finds, grazes a walk at the resolution
    /// misses included, and calls a path free only where that walk does (or where it left a
    /// segment uncertified, checked 32 times finer); it leaves a segment of few free paths.
    #[test]
    fn certification_finds_what_a_much_finer_walk_finds() {
        let resolution = 1.0 / 32.0;
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            // The hand and fingers: thin parts that move most between two states.
            let hand: Vec<usize> = (0..robot.links().len())
                .filter(|&l| robot.link_moves(l) && !robot.links()[l].collision.is_empty())
                .rev()
                .take(3)
                .collect();
            let mut rng = rand::rngs::StdRng::seed_from_u64(13);
            let n = robot.dof();
            let (mut free, mut hit, mut grazes, mut left) = (0, 0, 0, 0);
            for scene in 0..16 {
                let (count, size) = match scene % 2 {
                    0 => (30, [0.005, 0.005, 0.005]),
                    _ => (4, [0.4, 0.3, 0.05]),
                };
                let within = [0.2..0.9, -0.5..0.5, 0.3..1.2];
                let scene: Environment =
                    crate::world::environment::random_boxes(&mut rng, count, size, within);
                let mut exact = ExactChecker::new(&robot, &scene);
                for _ in 0..30 {
                    // A free start (some scenes block the robot wherever it stands).
                    let mut path = vec![vec![0.0; n]];
                    let free_start = (0..200).any(|_| {
                        robot.sample_uniform(&mut rng, &mut path[0]);
                        exact.is_valid(&path[0])
                    });
                    if !free_start {
                        break;
                    }
                    extend_randomly(&robot, &mut rng, &mut path, 0.4);
                    // A 1 mm grain on a part of the hand, halfway between two states.
                    let mut objects = scene.objects().to_vec();
                    if rng.random_bool(0.7) {
                        let (a, b) = (&path[0], &path[1]);
                        let steps = steps_over(robot.distance(a, b), resolution).max(1);
                        let k = rng.random_range(0..steps);
                        let mut q = vec![0.0; n];
                        robot.interpolate(a, b, (k as f64 + 0.5) / steps as f64, &mut q);
                        // On the part's surface, in a random direction.
                        let l = hand[rng.random_range(0..hand.len())];
                        let part = &robot.exact_model().link_parts(l)[0];
                        let d = nalgebra::Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
                        let at = robot.link_poses(&q).unwrap()[l] * part.origin;
                        let p = at * nalgebra::Point3::from(part.convex.support(&d));
                        objects.push(Object {
                            name: "grain".into(),
                            shape: Shape::Sphere { radius: 1e-3 },
                            pose: Pose::translation(p.x, p.y, p.z),
                        });
                    }
                    let env = Environment::from_objects(objects).unwrap();
                    let mut plain = Validity::new(&robot, &env, resolution, 0.0);
                    let mut sut = Validity::new(&robot, &env, resolution, 0.0).certifying(true);
                    let found = sut.path_contact(&path);
                    let uncertified = sut.uncertified() > 0;
                    let mut exact = ExactChecker::new(&robot, &env);
                    let truth = exact_path_contact(&mut exact, &path, resolution / 64.0);
                    // Every contact is found, and none where the walk finds none (unless a
                    // segment was left uncertified, checked only 32 times finer).
                    assert!(truth.is_none() || found.is_some(), "{name}: {path:?}");
                    if !uncertified {
                        assert_eq!(found.is_some(), truth.is_some(), "{name}: {path:?}");
                    }
                    if found.is_some() && plain.path_contact(&path).is_none() {
                        grazes += 1;
                    }
                    free += usize::from(truth.is_none());
                    hit += usize::from(truth.is_some());
                    left += usize::from(uncertified && found.is_none());
                }
            }
            assert!(
                free > 40 && hit > 40 && grazes > 20 && left * 10 < free,
                "{name}: {free} free, {hit} in contact, {grazes} grazes, {left} left uncertified"
            );
        }
    }
}
