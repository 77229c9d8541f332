//! The planner's validity checks: the sphere model everywhere, and the exact geometry near the
//! terminal states that only the spheres touch.
//!
//! The sphere model covers the robot's geometry with up to a centimetre to spare, so a start
//! or goal can be free in the real geometry yet touched by the spheres (a gripper closing
//! around a can, an arm resting close to the body). [`plan`](super::plan) decides start and goals
//! on the exact geometry and registers such states as *anchors*; within `exact_radius`
//! (configuration-space distance) of an anchor, a configuration the spheres reject is asked
//! again of the exact checker. Everywhere else the sphere verdict stands, so the inner loop
//! stays on the fast path.

use super::certify::Certified;
use super::exact_path_contact;
use crate::collision::batch::BatchChecker;
use crate::collision::checker::{bisect_motion, steps_over, CheckStats, Contact};
use crate::collision::exact::ExactChecker;
use crate::collision::{ConfigCheck, SphereChecker};
use crate::robot::Robot;
use crate::world::Environment;

/// Sphere checks with an exact fallback near anchors.
pub struct Validity<'a> {
    robot: &'a Robot,
    spheres: SphereChecker<'a>,
    /// Edge states eight at a time; `None` when the robot is blocked where it never moves.
    batch: Option<BatchChecker>,
    exact: ExactChecker<'a>,
    anchors: Vec<Vec<f64>>,
    exact_radius: f64,
    resolution: f64,
    /// Resolution of [`Validity::path_contact`]'s walk.
    validation_resolution: f64,
    scratch: Vec<f64>,
    state: Vec<f64>,
    motions: u64,
    fallbacks: u64,
    /// Certifies returned paths between their states ([`Validity::certifying`]).
    certified: Option<Certified>,
}

impl<'a> Validity<'a> {
    /// Checks for `robot` in `env` with edge resolution `resolution`.
    pub fn new(robot: &'a Robot, env: &'a Environment, resolution: f64, exact_radius: f64) -> Self {
        let exact = ExactChecker::new(robot, env);
        let spheres = SphereChecker::beside(&exact).with_resolution(resolution);
        let batch = if spheres.blocked() {
            None
        } else {
            Some(BatchChecker::new(robot, env))
        };
        Validity {
            robot,
            spheres,
            batch,
            exact,
            anchors: Vec::new(),
            exact_radius,
            resolution: resolution.max(1e-6),
            validation_resolution: resolution.max(1e-6),
            scratch: vec![0.0; robot.dof()],
            state: vec![0.0; robot.dof()],
            motions: 0,
            fallbacks: 0,
            certified: None,
        }
    }

    /// Certifies returned paths between their states too ([`Validity::path_contact`]; see
    /// [`certify`](super::certify)). It works in the sphere lanes: a robot they cannot stand
    /// for (a link with exact geometry but no spheres, where validation walks the exact
    /// geometry alone) is validated without it.
    pub fn certifying(mut self, on: bool) -> Self {
        self.certified = on.then(|| Certified::new(self.robot));
        self
    }

    /// Segments of returned paths left uncertified so far, checked at 1/32 of the validation's
    /// resolution instead (see [`certify`](super::certify)).
    pub fn uncertified(&self) -> u64 {
        self.certified.as_ref().map_or(0, Certified::uncertified)
    }

    /// Validates returned paths ([`Validity::path_contact`]) at `resolution` (by default
    /// the checks' own).
    pub fn validating_at(mut self, resolution: f64) -> Self {
        self.validation_resolution = resolution.max(1e-6);
        self
    }

    /// The robot checked.
    pub fn robot(&self) -> &'a Robot {
        self.robot
    }

    /// The exact checker.
    pub fn exact(&mut self) -> &mut ExactChecker<'a> {
        &mut self.exact
    }

    /// Registers a state free in the exact geometry but touched by the spheres.
    pub fn add_anchor(&mut self, q: &[f64]) {
        self.anchors.push(q.to_vec());
    }

    /// Anchors registered.
    pub fn anchors(&self) -> usize {
        self.anchors.len()
    }

    /// Sphere-model work so far (configurations, scalar and in lanes, and motions), and exact
    /// fallbacks.
    pub fn stats(&self) -> (CheckStats, u64) {
        let mut s = self.spheres.stats();
        if let Some(b) = &self.batch {
            s.configs += b.states();
            (s.batches, s.remembered) = b.batches();
        }
        s.motions = self.motions;
        (s, self.fallbacks)
    }

    /// True when the sphere model, as the search checks states (the batch checker's lanes
    /// when there is one), finds `q` free.
    #[inline]
    fn spheres_free(&mut self, q: &[f64]) -> bool {
        match self.batch.as_mut() {
            Some(batch) => !batch.state_may_collide(q),
            None => self.spheres.is_valid(q),
        }
    }

    /// Registers `q`, a start or goal free in the exact geometry, as an anchor when the sphere
    /// model touches it (see the module docs); true when it did.
    pub fn anchor_if_touched(&mut self, q: &[f64]) -> bool {
        let touched = !self.spheres_free(q);
        if touched {
            self.add_anchor(q);
        }
        touched
    }

    /// True when `q` is free: the spheres say so, or `q` is near an anchor and the exact
    /// geometry says so.
    #[inline]
    pub fn is_valid(&mut self, q: &[f64]) -> bool {
        if self.spheres_free(q) {
            return true;
        }
        // Moved out only for a flagged state (the checker is large).
        let mut batch = self.batch.take();
        let free = self.exact_clears(batch.as_mut(), q);
        self.batch = batch;
        free
    }

    /// True when `q`, touched by the spheres, is near an anchor and free in the exact
    /// geometry. With the lanes of `batch`, a state whose balls inside the geometry already
    /// touch something is refused without the exact checker (most states near an anchor the
    /// spheres flag are in real contact).
    fn exact_clears(&mut self, batch: Option<&mut BatchChecker>, q: &[f64]) -> bool {
        if self.anchors.is_empty() || !self.near_anchor(q) {
            return false;
        }
        if batch.is_some_and(|b| b.state_surely_collides(q)) {
            return false;
        }
        self.fallbacks += 1;
        self.exact.is_valid(q)
    }

    /// Of up to eight states, those (bits) the sphere model surely finds in contact, from the
    /// contacts its checks found last ([`BatchChecker::surely_colliding`]); never a state near
    /// an anchor, where the spheres' verdict is not final. Lanes not flagged may collide too.
    pub fn surely_colliding(&mut self, states: &[&[f64]]) -> u32 {
        let Some(batch) = self.batch.as_mut() else {
            return 0;
        };
        let mut flagged = batch.surely_colliding(states);
        if flagged != 0 && !self.anchors.is_empty() {
            for (i, q) in states.iter().enumerate() {
                if flagged & (1 << i) != 0 && self.near_anchor(q) {
                    flagged &= !(1 << i);
                }
            }
        }
        flagged
    }

    fn near_anchor(&self, q: &[f64]) -> bool {
        self.anchors
            .iter()
            .any(|a| self.robot.distance(a, q) <= self.exact_radius)
    }

    /// True when `b` is free and the straight motion from `a` (assumed valid) to it is free
    /// at the resolution: a tree extension. Away from anchors, `b` and the edge's states go
    /// through the batch checker in one pass, and a flag is a collision (the lanes err towards
    /// contact by 0.1 mm at most); near anchors, state by state as [`Validity::is_valid`].
    pub fn reach_valid(&mut self, a: &[f64], b: &[f64]) -> bool {
        let (robot, resolution) = (self.robot, self.resolution);
        self.reach_valid_by(a, b, |batch| {
            !batch.motion_may_collide(robot, resolution, (a, b), true)
        })
    }

    /// [`Validity::reach_valid`] of the extension from `a` to `b` that took `step` per joint
    /// ([`Robot::step_towards`]) over a configuration-space length `length`: away from anchors,
    /// the batch checker takes the step as it is (no differences computed again).
    pub fn step_valid(&mut self, a: &[f64], b: &[f64], step: &[f64], length: f64) -> bool {
        let n = steps_over(length, self.resolution);
        self.reach_valid_by(a, b, |batch| !batch.step_may_collide(a, step, n))
    }

    /// [`Validity::reach_valid`], the batch checker's part asked of `in_batch`.
    #[inline(always)]
    fn reach_valid_by(
        &mut self,
        a: &[f64],
        b: &[f64],
        in_batch: impl FnOnce(&mut BatchChecker) -> bool,
    ) -> bool {
        let far = self.far_from_anchors(a, b);
        if let (Some(batch), true) = (self.batch.as_mut(), far) {
            self.motions += 1;
            return in_batch(batch);
        }
        self.is_valid(b) && self.motion_valid(a, b)
    }

    /// True when the straight motion from `a` to `b` is free at the resolution (ends assumed
    /// valid). The states go eight at a time through the batch checker. Away from anchors a
    /// flagged batch is a collision (within the lanes' 0.1 mm margin); near them each state
    /// of a flagged batch is checked alone in the lanes, and one still flagged near an anchor
    /// goes to the exact checker.
    pub fn motion_valid(&mut self, a: &[f64], b: &[f64]) -> bool {
        self.motions += 1;
        let (robot, resolution) = (self.robot, self.resolution);
        let far = self.far_from_anchors(a, b);
        match self.batch.take() {
            Some(mut batch) if far => {
                let ok = !batch.motion_may_collide(robot, resolution, (a, b), false);
                self.batch = Some(batch);
                ok
            }
            Some(mut batch) => {
                let mut state = std::mem::take(&mut self.state);
                let decide = |batch: &mut BatchChecker, k, n| {
                    robot.interpolate(a, b, k as f64 / n as f64, &mut state);
                    self.exact_clears(Some(batch), &state)
                };
                let ok = batch.motion_free(robot, resolution, (a, b), false, Some(decide));
                self.state = state;
                self.batch = Some(batch);
                ok
            }
            None => {
                let mut q = std::mem::take(&mut self.scratch);
                let ok = bisect_motion(robot, resolution, a, b, &mut q, |q| self.is_valid(q));
                self.scratch = q;
                ok
            }
        }
    }

    /// The first contact of `q` in the exact geometry, as [`ExactChecker::contact`] names it,
    /// or `None` when `q` is free: the check of a start or goal. As in
    /// [`Validity::path_contact`], the state goes through the sphere lanes in validation mode
    /// first, and only when they flag it through the exact checker.
    pub fn state_contact(&mut self, q: &[f64]) -> Option<Contact> {
        if let Some(c) = self.exact.static_contact() {
            return Some(c.clone());
        }
        if let Some(batch) = self.batch.as_mut() {
            if batch.validate(true) {
                let flagged = batch.state_may_collide(q);
                batch.validate(false);
                if !flagged {
                    return None;
                }
            }
        }
        self.exact.contact(q)
    }

    /// The first contact along `path` (waypoints, and the states of each edge at the
    /// validation's resolution, see [`Validity::validating_at`]) in the exact geometry, as
    /// [`ExactChecker::motion_contact`] walks it, or `None` when every state is free: the
    /// validation of a returned path.
    ///
    /// The states go eight at a time through the batch checker in validation mode first. Its
    /// spheres cover every link's geometry, so a state they clear is free in the exact
    /// geometry, unless an obstacle could lie wholly inside a link, where spheres need not
    /// reach (the batch checker flags that possibility too). Only the states flagged go to
    /// the exact checker; an edge with a state it finds in contact is walked again in order
    /// by the exact checker, to name its first contact.
    ///
    /// When [`Validity::certifying`], a path found free so is then certified between those
    /// states ([`certify`](super::certify)), and the first contact found there is returned.
    pub fn path_contact(&mut self, path: &[Vec<f64>]) -> Option<Contact> {
        let (robot, resolution) = (self.robot, self.validation_resolution);
        if let Some(c) = self.exact.static_contact() {
            return Some(c.clone());
        }
        let mut batch = match self.batch.take() {
            Some(b) if path.len() >= 2 => b,
            other => {
                self.batch = other;
                return exact_path_contact(&mut self.exact, path, resolution);
            }
        };
        if !batch.validate(true) {
            self.batch = Some(batch);
            return exact_path_contact(&mut self.exact, path, resolution);
        }
        let mut state = std::mem::take(&mut self.state);
        let exact = &mut self.exact;
        let mut found = None;
        if batch.state_may_collide(&path[0]) {
            found = exact.contact(&path[0]);
        }
        for w in path.windows(2) {
            if found.is_some() {
                break;
            }
            let (a, b) = (&w[0][..], &w[1][..]);
            let decide = |_: &mut BatchChecker, k, n| {
                robot.interpolate(a, b, k as f64 / n as f64, &mut state);
                exact.is_valid(&state)
            };
            if !batch.motion_free(robot, resolution, (a, b), true, Some(decide)) {
                found = exact.motion_contact(a, b, resolution).map(|(_, c)| c);
            }
        }
        if let (None, Some(certified)) = (&found, self.certified.as_mut()) {
            found = certified.path_contact(robot, (&mut batch, exact), resolution, path);
        }
        batch.validate(false);
        self.state = state;
        self.batch = Some(batch);
        found
    }

    /// True when no state of the motion from `a` to `b` can be within `exact_radius` of an
    /// anchor (each is at most the motion's length from `a`).
    fn far_from_anchors(&self, a: &[f64], b: &[f64]) -> bool {
        if self.anchors.is_empty() {
            return true;
        }
        let length = self.robot.distance(a, b);
        self.anchors
            .iter()
            .all(|x| self.robot.distance(a, x) - length > self.exact_radius)
    }
}

impl Drop for Validity<'_> {
    /// Gives the checkers' working copies back to the robot, for its next plan.
    fn drop(&mut self) {
        let spheres = self.spheres.take_placement();
        let batch = self.batch.take().map(BatchChecker::without_map);
        self.robot.prepared().give_back(spheres, batch);
    }
}

impl<'a> ConfigCheck<'a> for Validity<'a> {
    fn robot(&self) -> &'a Robot {
        self.robot
    }

    fn is_valid(&mut self, q: &[f64]) -> bool {
        Validity::is_valid(self, q)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::collision::Shape;
    use crate::robot::spheres::fit::Part;
    use crate::world::map::{MapParams, OccupancyMap};
    use crate::world::Object;
    use crate::Pose;
    use nalgebra::Point3;
    use rand::{Rng, SeedableRng};

    /// Adds two waypoints to `path`, each a random step of 0.1 to `longest` (configuration
    /// space) from the last, towards a uniform sample.
    pub(crate) fn extend_randomly(
        robot: &Robot,
        rng: &mut impl Rng,
        path: &mut Vec<Vec<f64>>,
        longest: f64,
    ) {
        let n = robot.dof();
        for _ in 0..2 {
            let (mut target, mut next, mut step) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            robot.sample_uniform(rng, &mut target);
            let last = path.last().unwrap();
            let d = robot.distance(last, &target);
            let t = rng.random_range(0.1..longest).min(d) / d;
            robot.step_towards(last, &target, t, &mut next, &mut step);
            path.push(next);
        }
    }

    /// The validation of a path answers as the exact checker walking it does, the same
    /// contact named, on Fetch and the Panda among boxes small enough to fit inside a link,
    /// large ones, and a map's scattered voxels; and the check of a start or goal as the exact
    /// checker does, state by state.
    #[test]
    fn a_path_is_validated_as_the_exact_checker_walks_it() {
        let resolution = 1.0 / 32.0;
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let mut rng = rand::rngs::StdRng::seed_from_u64(5);
            let n = robot.dof();
            let (mut free, mut hit) = (0, 0);
            for scene in 0..9 {
                let size = if scene % 3 == 0 {
                    [0.03, 0.04, 0.05]
                } else {
                    [0.4, 0.3, 0.05]
                };
                let within = [0.1..0.9, -0.6..0.6, 0.1..1.2];
                let mut env =
                    crate::world::environment::random_boxes(&mut rng, 6, size, within.clone());
                if scene % 3 == 2 {
                    let mut map = OccupancyMap::new(MapParams::default());
                    for _ in 0..400 {
                        let p = within.clone().map(|r| rng.random_range(r));
                        map.set_voxel(map.key_of(p), true);
                    }
                    env = Environment::new();
                    env.set_map(Some(std::sync::Arc::new(map)));
                }
                let mut sut = Validity::new(&robot, &env, resolution, 0.0);
                let mut exact = ExactChecker::new(&robot, &env);
                for _ in 0..25 {
                    // Three waypoints, each a short step from the last.
                    let mut path = vec![vec![0.0; n]];
                    robot.sample_uniform(&mut rng, &mut path[0]);
                    extend_randomly(&robot, &mut rng, &mut path, 0.6);
                    let want = exact_path_contact(&mut exact, &path, resolution);
                    assert_eq!(sut.path_contact(&path), want, "{name}: {path:?}");
                    for q in &path {
                        assert_eq!(sut.state_contact(q), exact.contact(q), "{name}: {q:?}");
                    }
                    free += usize::from(want.is_none());
                    hit += usize::from(want.is_some());
                }
            }
            assert!(
                free > 20 && hit > 20,
                "{name}: {free} free, {hit} in contact"
            );
        }
    }

    /// A grain, and a voxel of a fine map, wholly inside a link where the link's spheres do
    /// not reach them, are found by the validation, though the spheres clear every state of
    /// the path.
    #[test]
    fn an_obstacle_hidden_inside_a_link_is_found() {
        let robot = Robot::builtin("fetch").unwrap();
        let (link, point, gap) = deepest_pocket(&robot);
        let radius = 0.3e-3;
        assert!(
            gap > radius + 2e-4,
            "no link leaves room inside its spheres for a grain: {gap} m at most"
        );
        let q = robot.named_state("stow").unwrap().to_vec();
        let at = robot.link_poses(&q).unwrap()[link] * Point3::from(point);
        let grain = Environment::from_objects(vec![Object {
            name: "grain".into(),
            shape: Shape::Sphere { radius },
            pose: Pose::translation(at.x, at.y, at.z),
        }])
        .unwrap();
        assert_hidden_is_found(&robot, &grain, link, &q);
        // A voxel holding the point, its cube (at most 0.87 of its edge from the point) clear
        // of the spheres.
        let mut map = OccupancyMap::new(MapParams {
            resolution: gap / 2.0,
            ..MapParams::default()
        });
        map.set_voxel(map.key_of([at.x, at.y, at.z]), true);
        let mut voxel = Environment::new();
        voxel.set_map(Some(std::sync::Arc::new(map)));
        assert_hidden_is_found(&robot, &voxel, link, &q);
    }

    /// The spheres clear `q` in `env`, the exact geometry does not, and the check of `q` as a
    /// start or goal, and the validation of paths to and from `q` turning the last joint
    /// (which leaves `link` in place), find the exact checker's contact, after a validation
    /// in an empty world with the same robot.
    fn assert_hidden_is_found(robot: &Robot, env: &Environment, link: usize, q: &[f64]) {
        assert!(
            !BatchChecker::new(robot, env).state_may_collide(q),
            "the spheres reach the obstacle"
        );
        // A validation in an empty world first: the checkers it gives back to the robot must
        // not carry what could hide there into `env`.
        let empty = Environment::new();
        assert_eq!(
            Validity::new(robot, &empty, 1.0 / 32.0, 0.0).state_contact(q),
            None
        );
        let mut sut = Validity::new(robot, env, 1.0 / 32.0, 0.0);
        let mut other = q.to_vec();
        *other.last_mut().unwrap() += 0.3;
        let moved = robot.link_poses(&other).unwrap()[link];
        assert_eq!(moved, robot.link_poses(q).unwrap()[link], "the link moves");
        let want = sut.exact().contact(q);
        assert!(want.is_some());
        assert_eq!(sut.state_contact(q), want);
        for path in [vec![q.to_vec(), other.clone()], vec![other, q.to_vec()]] {
            let want = exact_path_contact(sut.exact(), &path, 1.0 / 32.0);
            assert!(want.is_some());
            assert_eq!(sut.path_contact(&path), want);
        }
    }

    /// The point inside a link's geometry farthest from its spheres (among seeded samples):
    /// link, point in the link frame, and its distance to the nearest sphere.
    fn deepest_pocket(robot: &Robot) -> (usize, [f64; 3], f64) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let mut best = (0, [0.0; 3], f64::NEG_INFINITY);
        for (l, link) in robot.links().iter().enumerate() {
            let parts: Vec<Part> = link.collision.iter().map(Part::new).collect();
            if parts.is_empty() {
                continue;
            }
            let spheres: Vec<_> = robot.spheres().link_spheres(l).collect();
            let (lo, hi) = Part::bounds_of(&parts);
            for _ in 0..40_000 {
                let p: [f64; 3] = std::array::from_fn(|a| rng.random_range(lo[a]..=hi[a]));
                if parts.iter().all(|part| part.depth(p) <= 0.0) {
                    continue;
                }
                let gap = spheres
                    .iter()
                    .map(|(c, r)| (Point3::from(*c) - Point3::from(p)).norm() - r)
                    .fold(f64::INFINITY, f64::min);
                if gap > best.2 {
                    best = (l, p, gap);
                }
            }
        }
        best
    }

    /// An extension checked from the step it took answers as one checked from its two ends,
    /// on Fetch (continuous joints, stepped across ±π) among boxes, free and blocked alike.
    #[test]
    fn a_step_is_checked_as_its_two_ends() {
        let robot = Robot::builtin("fetch").unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(21);
        let env = crate::world::environment::random_boxes(
            &mut rng,
            5,
            [0.4, 0.3, 0.05],
            [0.4..1.0, -0.5..0.5, 0.3..1.3],
        );
        let mut sut = Validity::new(&robot, &env, 1.0 / 32.0, 0.0);
        let n = robot.dof();
        let (mut a, mut target) = (vec![0.0; n], vec![0.0; n]);
        let (mut b, mut step) = (vec![0.0; n], vec![0.0; n]);
        let (mut free, mut blocked) = (0, 0);
        for _ in 0..400 {
            robot.sample_uniform(&mut rng, &mut a);
            robot.sample_uniform(&mut rng, &mut target);
            let d = robot.distance(&a, &target);
            let range = 0.75_f64.min(d);
            robot.step_towards(&a, &target, range / d, &mut b, &mut step);
            let verdict = sut.reach_valid(&a, &b);
            assert_eq!(
                sut.step_valid(&a, &b, &step, range),
                verdict,
                "{a:?} -> {b:?}"
            );
            free += usize::from(verdict);
            blocked += usize::from(!verdict);
        }
        assert!(free > 0 && blocked > 0, "{free} free, {blocked} blocked");
    }
}
