//! The fast collision checker the planner calls in its inner loop: the robot's sphere model
//! against the environment, self-collision over the configured link pairs, and motion (edge)
//! checks at a fixed resolution.
//!
//! Per link, the link's bounding sphere is tested first (broad phase); only the objects it
//! touches are tested against the link's spheres. Nothing here allocates after construction.

use crate::robot::fk::{Frame, JointFrames};
use crate::robot::Robot;
use crate::world::Environment;
use nalgebra::Point3;

/// Default edge-check resolution in configuration-space distance (1/32, as VAMP uses).
pub const DEFAULT_RESOLUTION: f64 = 1.0 / 32.0;

/// What a colliding configuration touches first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Contact {
    /// A robot link touches an environment object.
    Object {
        /// Link name.
        link: String,
        /// Object name.
        object: String,
    },
    /// Two robot links touch.
    SelfCollision {
        /// First link name.
        link_a: String,
        /// Second link name.
        link_b: String,
    },
}

impl std::fmt::Display for Contact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Contact::Object { link, object } => write!(f, "link {link} touches object {object}"),
            Contact::SelfCollision { link_a, link_b } => {
                write!(f, "link {link_a} touches link {link_b}")
            }
        }
    }
}

/// Counters of checker work.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CheckStats {
    /// Configurations checked.
    pub configs: u64,
    /// Motions checked.
    pub motions: u64,
    /// Batches of eight states the lanes checked.
    pub batches: u64,
    /// Of those, the batches a remembered contact ended (see `collision::batch`).
    pub remembered: u64,
}

/// A configuration and motion validity checker over a robot and an environment.
///
/// ```
/// use ember_engine::{collision::SphereChecker, robot::Robot, world::Environment};
/// let fetch = Robot::builtin("fetch").unwrap();
/// let env = Environment::new();
/// let mut sut = SphereChecker::new(&fetch, &env);
/// assert!(sut.is_valid(fetch.named_state("stow").unwrap()));
/// ```
pub struct SphereChecker<'a> {
    robot: &'a Robot,
    env: &'a Environment,
    resolution: f64,
    stats: CheckStats,
    /// Contact among links that never move (base against the world): blocks every configuration.
    static_contact: Option<Contact>,
    /// Where the sphere model is, as of the last configuration.
    at: Placement,
}

/// The sphere model placed in the world, and what says which placements are current. It
/// starts from the robot alone (links that never move placed once), built once per robot
/// ([`Robot::prepared`]); each checker takes a copy, or a spare an earlier plan gave back.
#[derive(Clone, Default)]
pub(crate) struct Placement {
    /// Frames of joint links (others ride in them) and the sphere model placed in them.
    joints: JointFrames,
    bound_at: Vec<[f64; 3]>,
    cluster_at: Vec<[f64; 3]>,
    sphere_at: Vec<[f64; 3]>,
    poses: Vec<Frame>,
    /// World positions, computed lazily per configuration: link bounds eagerly, a link's
    /// cluster centres when first needed (`link_stamp`), a cluster's spheres likewise
    /// (`cluster_stamp`). A stamp equal to `epoch` means current; `STATIC` means placed once.
    bounds: Vec<[f64; 3]>,
    cluster_centers: Vec<[f64; 3]>,
    /// Sphere centres and radii, structure of arrays (lanes for the overlap kernel).
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
    rs: Vec<f64>,
    link_stamp: Vec<u32>,
    cluster_stamp: Vec<u32>,
    epoch: u32,
    scratch: Vec<f64>,
    /// Links with spheres that move with the group: the only ones checked per configuration.
    moving_links: Vec<usize>,
    /// Self-collision pairs with at least one moving link.
    moving_pairs: Vec<(usize, usize)>,
}

impl<'a> SphereChecker<'a> {
    /// A checker with the default edge resolution.
    pub fn new(robot: &'a Robot, env: &'a Environment) -> Self {
        Self::beside(&super::exact::ExactChecker::new(robot, env))
    }

    /// A checker for the robot and environment of `exact`, taking from it what it decided once
    /// about the parts that never move (so a planner holding both decides that once).
    pub fn beside(exact: &super::exact::ExactChecker<'a>) -> Self {
        SphereChecker {
            robot: exact.robot(),
            env: exact.environment(),
            resolution: DEFAULT_RESOLUTION,
            stats: CheckStats::default(),
            // What never moves is checked once, on the exact geometry (the base resting on
            // the floor is not in contact, whatever its spheres say).
            static_contact: exact.static_contact().cloned(),
            at: exact.robot().prepared().take_spheres(),
        }
    }

    /// Takes the placement out (the checker is not used after), to be given back to the
    /// robot for another checker ([`Robot::prepared`]).
    pub(crate) fn take_placement(&mut self) -> Placement {
        std::mem::take(&mut self.at)
    }

    /// The sphere model of `robot` at rest, the links that never move placed once: what
    /// every checker for the robot starts from ([`Robot::prepared`]).
    pub(crate) fn placement(robot: &Robot) -> Placement {
        let n_links = robot.links().len();
        let model = robot.spheres();
        let joints = JointFrames::new(robot);
        let bound_at = (0..n_links)
            .map(|l| model.bounds[l].map_or([0.0; 3], |(c, _)| joints.place(l, c)))
            .collect();
        let mut cluster_at = vec![[0.0; 3]; model.clusters.len()];
        let mut sphere_at = vec![[0.0; 3]; model.len()];
        for l in 0..n_links {
            for ci in model.link_clusters[l].clone() {
                cluster_at[ci] = joints.place(l, model.clusters[ci].center);
                for s in model.clusters[ci].range.clone() {
                    sphere_at[s] = joints.place(l, model.center[s]);
                }
            }
        }
        let (moving, fixed): (Vec<usize>, Vec<usize>) = (0..n_links)
            .filter(|&l| model.bounds[l].is_some())
            .partition(|&l| robot.link_moves(l));
        let (moving_pairs, _) = robot.partition_pairs();
        let mut sut = SphereChecker {
            robot,
            env: super::prepared::nothing(),
            resolution: DEFAULT_RESOLUTION,
            stats: CheckStats::default(),
            static_contact: None,
            at: Placement {
                joints,
                bound_at,
                cluster_at,
                sphere_at,
                poses: vec![Frame::identity(); n_links],
                bounds: vec![[0.0; 3]; n_links],
                cluster_centers: vec![[0.0; 3]; model.clusters.len()],
                xs: vec![0.0; model.len()],
                ys: vec![0.0; model.len()],
                zs: vec![0.0; model.len()],
                rs: model.radius.clone(),
                link_stamp: vec![0; n_links],
                cluster_stamp: vec![0; model.clusters.len()],
                epoch: 0,
                scratch: vec![0.0; robot.dof()],
                // Tip first: in clutter the hand and forearm touch things first, so a
                // colliding state is found after fewer links.
                moving_links: moving.into_iter().rev().collect(),
                moving_pairs,
            },
        };
        sut.at
            .joints
            .compute(robot, &robot.middle(), &mut sut.at.poses);
        sut.at.epoch = 1;
        for &l in &fixed {
            sut.place_bound(l);
            sut.place_clusters(l);
            for ci in model.link_clusters[l].clone() {
                sut.place_spheres(ci, l);
                sut.at.cluster_stamp[ci] = STATIC;
            }
            sut.at.link_stamp[l] = STATIC;
        }
        sut.at
    }

    /// Sets the edge-check resolution (configuration-space distance between checked states).
    pub fn with_resolution(mut self, resolution: f64) -> Self {
        self.resolution = resolution.max(1e-6);
        self
    }

    /// The edge-check resolution.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// The robot checked.
    pub fn robot(&self) -> &'a Robot {
        self.robot
    }

    /// The environment checked against.
    pub fn environment(&self) -> &'a Environment {
        self.env
    }

    /// True when links that never move touch something: every configuration is in collision.
    pub fn blocked(&self) -> bool {
        self.static_contact.is_some()
    }

    /// Work done so far.
    pub fn stats(&self) -> CheckStats {
        self.stats
    }

    /// True when `q` is free of environment and self-collision. `q` must have the robot's DOF
    /// (validate inputs with [`Robot::validate`] first).
    #[inline]
    pub fn is_valid(&mut self, q: &[f64]) -> bool {
        self.stats.configs += 1;
        if self.static_contact.is_some() {
            return false;
        }
        self.update(q);
        if self.env_contact_any() {
            return false;
        }
        let pairs = std::mem::take(&mut self.at.moving_pairs);
        let free = self.self_contact(&pairs).is_none();
        self.at.moving_pairs = pairs;
        free
    }

    /// What `q` touches first, or `None` when it is collision free.
    pub fn contact(&mut self, q: &[f64]) -> Option<Contact> {
        if let Some(c) = &self.static_contact {
            return Some(c.clone());
        }
        self.update(q);
        let links = std::mem::take(&mut self.at.moving_links);
        let pairs = std::mem::take(&mut self.at.moving_pairs);
        let contact = self.first_contact(&links, &pairs);
        self.at.moving_links = links;
        self.at.moving_pairs = pairs;
        contact
    }

    fn first_contact(&mut self, links: &[usize], pairs: &[(usize, usize)]) -> Option<Contact> {
        let robot = self.robot;
        let model = robot.spheres();
        let names = robot.links();
        for &li in links {
            self.place_clusters(li);
            for ci in model.link_clusters[li].clone() {
                self.place_spheres(ci, li);
                for s in model.clusters[ci].range.clone() {
                    if let Some(o) = self.env.sphere_contact(self.center(s), model.radius[s]) {
                        return Some(Contact::Object {
                            link: names[li].name.clone(),
                            object: o.to_string(),
                        });
                    }
                }
            }
        }
        self.self_contact(pairs)
            .map(|(a, b)| Contact::SelfCollision {
                link_a: names[a].name.clone(),
                link_b: names[b].name.clone(),
            })
    }

    /// True when the straight motion from `a` to `b` is free at the checker's resolution.
    /// Both ends are assumed valid; interior states are checked coarse to fine (bisection
    /// order), so collisions in the middle are found early.
    pub fn motion_valid(&mut self, a: &[f64], b: &[f64]) -> bool {
        self.stats.motions += 1;
        let robot = self.robot;
        let resolution = self.resolution;
        let mut q = std::mem::take(&mut self.at.scratch);
        let ok = bisect_motion(robot, resolution, a, b, &mut q, |q| self.is_valid(q));
        self.at.scratch = q;
        ok
    }

    /// FK and world bounds of the moving links; clusters and spheres are placed on demand.
    #[inline]
    fn update(&mut self, q: &[f64]) {
        self.at.joints.compute(self.robot, q, &mut self.at.poses);
        self.at.epoch += 1;
        if self.at.epoch == STATIC {
            // Wrapped: forget every stamp of the moving links.
            for &l in &self.at.moving_links {
                self.at.link_stamp[l] = 0;
                for ci in self.robot.spheres().link_clusters[l].clone() {
                    self.at.cluster_stamp[ci] = 0;
                }
            }
            self.at.epoch = 1;
        }
        for k in 0..self.at.moving_links.len() {
            self.place_bound(self.at.moving_links[k]);
        }
    }

    #[inline]
    fn place_bound(&mut self, li: usize) {
        if self.robot.spheres().bounds[li].is_some() {
            let w = self.at.poses[self.at.joints.frame[li]] * Point3::from(self.at.bound_at[li]);
            self.at.bounds[li] = [w.x, w.y, w.z];
        }
    }

    /// Places link `li`'s cluster centres unless current.
    #[inline]
    fn place_clusters(&mut self, li: usize) {
        let stamp = self.at.link_stamp[li];
        if stamp == self.at.epoch || stamp == STATIC {
            return;
        }
        self.at.link_stamp[li] = self.at.epoch;
        let model = self.robot.spheres();
        let pose = &self.at.poses[self.at.joints.frame[li]];
        for ci in model.link_clusters[li].clone() {
            let w = pose * Point3::from(self.at.cluster_at[ci]);
            self.at.cluster_centers[ci] = [w.x, w.y, w.z];
        }
    }

    /// Places cluster `ci`'s spheres (of link `li`) unless current.
    #[inline]
    fn place_spheres(&mut self, ci: usize, li: usize) {
        let stamp = self.at.cluster_stamp[ci];
        if stamp == self.at.epoch || stamp == STATIC {
            return;
        }
        self.at.cluster_stamp[ci] = self.at.epoch;
        let model = self.robot.spheres();
        let pose = &self.at.poses[self.at.joints.frame[li]];
        for s in model.clusters[ci].range.clone() {
            let w = pose * Point3::from(self.at.sphere_at[s]);
            (self.at.xs[s], self.at.ys[s], self.at.zs[s]) = (w.x, w.y, w.z);
        }
    }

    #[inline]
    fn center(&self, s: usize) -> [f64; 3] {
        [self.at.xs[s], self.at.ys[s], self.at.zs[s]]
    }

    fn env_contact_any(&mut self) -> bool {
        let model = self.robot.spheres();
        let env = self.env;
        for k in 0..self.at.moving_links.len() {
            let li = self.at.moving_links[k];
            let Some((_, bound_r)) = model.bounds[li] else {
                continue;
            };
            let mask = env.sphere_candidates(self.at.bounds[li], bound_r);
            let map = env.sphere_hits_map(self.at.bounds[li], bound_r);
            if mask == 0 && !map {
                continue;
            }
            self.place_clusters(li);
            for ci in model.link_clusters[li].clone() {
                let cluster = &model.clusters[ci];
                let c = self.at.cluster_centers[ci];
                let cmask = if mask == 0 {
                    0
                } else {
                    env.candidates_masked(c, cluster.radius, mask)
                };
                let cmap = map && env.sphere_hits_map(c, cluster.radius);
                if cmask == 0 && !cmap {
                    continue;
                }
                self.place_spheres(ci, li);
                for s in cluster.range.clone() {
                    let (p, r) = (self.center(s), model.radius[s]);
                    if (cmask != 0 && env.sphere_collides_masked(p, r, cmask))
                        || (cmap && env.sphere_hits_map(p, r))
                    {
                        return true;
                    }
                }
            }
        }
        false
    }

    fn self_contact(&mut self, pairs: &[(usize, usize)]) -> Option<(usize, usize)> {
        let model = self.robot.spheres();
        for &(a, b) in pairs {
            let (Some((_, ra)), Some((_, rb))) = (model.bounds[a], model.bounds[b]) else {
                continue;
            };
            if !overlap(self.at.bounds[a], ra, self.at.bounds[b], rb) {
                continue;
            }
            self.place_clusters(a);
            self.place_clusters(b);
            for ca in model.link_clusters[a].clone() {
                let cla = &model.clusters[ca];
                let pa = self.at.cluster_centers[ca];
                if !overlap(pa, cla.radius, self.at.bounds[b], rb) {
                    continue;
                }
                for cb in model.link_clusters[b].clone() {
                    let clb = &model.clusters[cb];
                    if !overlap(pa, cla.radius, self.at.cluster_centers[cb], clb.radius) {
                        continue;
                    }
                    self.place_spheres(ca, a);
                    self.place_spheres(cb, b);
                    let r = clb.range.clone();
                    let lanes = [
                        &self.at.xs[r.clone()],
                        &self.at.ys[r.clone()],
                        &self.at.zs[r.clone()],
                        &self.at.rs[r],
                    ];
                    for i in cla.range.clone() {
                        let sphere = [self.at.xs[i], self.at.ys[i], self.at.zs[i], self.at.rs[i]];
                        if any_overlap(sphere, lanes) {
                            return Some((a, b));
                        }
                    }
                }
            }
        }
        None
    }
}

impl<'a> super::ConfigCheck<'a> for SphereChecker<'a> {
    fn robot(&self) -> &'a Robot {
        self.robot
    }

    fn is_valid(&mut self, q: &[f64]) -> bool {
        SphereChecker::is_valid(self, q)
    }
}

/// Segments of the motion from `a` to `b` at `resolution`: `ceil(distance / resolution)`, the
/// same in both directions (an edge of exactly a multiple of the resolution is not split one
/// step finer one way by rounding), so every check of an edge samples the same states.
#[inline]
pub fn motion_steps(robot: &Robot, a: &[f64], b: &[f64], resolution: f64) -> usize {
    steps_over(robot.distance(a, b), resolution)
}

/// [`motion_steps`] of a motion `distance` long.
#[inline]
pub fn steps_over(distance: f64, resolution: f64) -> usize {
    // `ceil` without its library call (the baseline x86-64 has no rounding instruction): the
    // saturating conversion truncates, and a fraction left over adds one. Not finite or not
    // positive gives 0, as `ceil().max(0.0)` did.
    let x = distance / resolution - 1e-9;
    let n = x as usize;
    n.saturating_add(usize::from((n as f64) < x))
}

/// Checks the states strictly between `a` and `b` at `resolution` with `valid`, coarse to
/// fine (bisection order, so collisions in the middle are found early); `scratch` holds one
/// configuration. The ends are not checked.
#[inline]
pub fn bisect_motion(
    robot: &Robot,
    resolution: f64,
    a: &[f64],
    b: &[f64],
    scratch: &mut [f64],
    mut valid: impl FnMut(&[f64]) -> bool,
) -> bool {
    let n = motion_steps(robot, a, b, resolution);
    bisection_order(n).all(|k| {
        robot.interpolate(a, b, k as f64 / n as f64, scratch);
        valid(scratch)
    })
}

/// The interior steps `1..n` of a motion cut into `n` segments, coarse to fine: the middle,
/// then the quarters, and so on (empty when `n < 2`).
#[inline]
pub fn bisection_order(n: usize) -> Bisection {
    let top = match n {
        0 | 1 => 0,
        _ => 1usize << (usize::BITS - 1 - (n - 1).leading_zeros()),
    };
    Bisection {
        n,
        step: top,
        k: top,
    }
}

/// The iterator of [`bisection_order`]: the steps `step, 3 step, 5 step, …` below `n`, for
/// `step` halving down to one. (A hand-written state machine: the adapter chain it replaces
/// cost ~200 instructions per motion, as much as the rest of the motion's set-up.)
#[derive(Debug, Clone)]
pub struct Bisection {
    n: usize,
    /// The current stride's first step, zero when done.
    step: usize,
    /// The next step to give at this stride.
    k: usize,
}

impl Iterator for Bisection {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        while self.step > 0 {
            if self.k < self.n {
                let k = self.k;
                self.k += 2 * self.step;
                return Some(k);
            }
            self.step /= 2;
            self.k = self.step;
        }
        None
    }
}

/// Stamp of positions that never change (links that do not move).
const STATIC: u32 = u32::MAX;

/// True when the ball `[x, y, z, r]` overlaps any ball of the lanes (x, y, z, r arrays of
/// equal length): branch-free over the lanes, so it runs in vector registers.
#[inline]
fn any_overlap(ball: [f64; 4], lanes: [&[f64]; 4]) -> bool {
    let [xs, ys, zs, rs] = lanes;
    let n = xs.len();
    let (ys, zs, rs) = (&ys[..n], &zs[..n], &rs[..n]);
    let mut hit = false;
    for k in 0..n {
        let (dx, dy, dz) = (ball[0] - xs[k], ball[1] - ys[k], ball[2] - zs[k]);
        let r = ball[3] + rs[k];
        hit |= dx * dx + dy * dy + dz * dz < r * r;
    }
    hit
}

#[inline]
fn overlap(a: [f64; 3], ra: f64, b: [f64; 3], rb: f64) -> bool {
    let r = ra + rb;
    dist2(a, b) < r * r
}

#[inline]
fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

#[cfg(test)]
mod tests {
    use super::{bisection_order, steps_over};

    #[test]
    fn steps_over_rounds_up_as_ceil_does() {
        let ceil = |d: f64, r: f64| (d / r - 1e-9).ceil().max(0.0) as usize;
        let cases = [0.0, 1e-12, 0.03125, 0.031250001, 0.75, 1.0, 3.7, 1e6, -2.0];
        for d in cases
            .into_iter()
            .chain((0..2000).map(|i| f64::from(i) * 0.013))
        {
            for r in [1.0 / 32.0, 0.05, 0.01, 1.0] {
                assert_eq!(steps_over(d, r), ceil(d, r), "{d} {r}");
            }
        }
        assert_eq!(steps_over(f64::NAN, 0.1), 0);
        assert_eq!(steps_over(f64::INFINITY, 0.1), usize::MAX);
    }

    #[test]
    fn bisection_order_visits_every_interior_step_once_coarse_to_fine() {
        assert_eq!(bisection_order(0).count(), 0);
        assert_eq!(bisection_order(1).count(), 0);
        assert_eq!(
            bisection_order(8).collect::<Vec<_>>(),
            [4, 2, 6, 1, 3, 5, 7]
        );
        assert_eq!(bisection_order(5).collect::<Vec<_>>(), [4, 2, 1, 3]);
        for n in 2..200 {
            let mut ks: Vec<usize> = bisection_order(n).collect();
            ks.sort();
            assert_eq!(ks, (1..n).collect::<Vec<_>>(), "n = {n}");
        }
    }
}
