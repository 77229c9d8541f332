//! RRT-Connect (Kuffner & LaValle 2000): two trees, one from the start and one from the goals,
//! grown towards random samples and towards each other.
//!
//! Trees are flat arrays (`dof` values per node, a parent index per node). Nearest neighbours
//! come from a [`NearestIndex`] built incrementally over the same nodes, so a query visits a
//! few buckets instead of scanning the tree. Nothing is allocated per iteration beyond the
//! arrays' amortised growth.
//!
//! A start or goal that no full step leaves (a gripper deep in a shelf) takes steps of
//! [`ROOT_STEP`] of the range once an extension from it has failed: the search grows the
//! smaller tree, so a one-node goal tree that cannot leave would otherwise take every
//! iteration (what stalled the bookshelves at ranges of 1.0 and more before). And when a tree
//! is still stuck at its roots after a few hundred iterations ([`RETREAT_AFTER`]), the search
//! backs its tip out of them in straight lines ([`Retreat`]) and grows on from there.
//!
//! The dynamic domain ([`DynamicDomain`]) is set aside while the search is stalled
//! ([`DOMAIN_STALLED_AFTER`]): once every node near the way out has failed, it lets through one
//! sample in thousands, and the search then waits seconds for the few extensions that find the
//! gap.

use super::nearest::NearestIndex;
use super::retreat::Retreat;
use super::validity::Validity;
use super::{PlanError, PlanStats, PlannerParams, PlannerRng, Sampler};
use crate::robot::Robot;
use std::time::Instant;

const ROOT: u32 = u32::MAX;

/// A start's or goal's step once an extension from it has failed, as a fraction of the range
/// (0.25–0.75 and shrinking by steps measured no better on the MotionBenchMaker Fetch sets).
const ROOT_STEP: f64 = 0.5;

/// A tree of configurations stored flat, with a nearest-neighbour index over its nodes.
struct Tree {
    dof: usize,
    q: Vec<f64>,
    parent: Vec<u32>,
    index: NearestIndex,
    /// Per node: its dynamic-domain radius (infinite until an extension from it fails).
    domain: Vec<f64>,
    /// Per root (the tree's first nodes: the start, or the goals): true once an extension
    /// from it has failed (see the module docs).
    root_failed: Vec<bool>,
    /// True once the search has retreated from the roots (see [`Retreat`]).
    retreated: bool,
}

impl Tree {
    fn new(dof: usize, continuous: &[bool]) -> Self {
        Tree {
            dof,
            q: Vec::with_capacity(dof * 256),
            parent: Vec::with_capacity(256),
            index: NearestIndex::new(continuous),
            domain: Vec::with_capacity(256),
            root_failed: Vec::new(),
            retreated: false,
        }
    }

    /// Empties the tree, keeping its buffers.
    fn clear(&mut self) {
        self.q.clear();
        self.parent.clear();
        self.index.clear();
        self.domain.clear();
        self.root_failed.clear();
        self.retreated = false;
    }

    fn len(&self) -> usize {
        self.parent.len()
    }

    /// Roots: the start, or the goals (the tree's first nodes).
    fn roots(&self) -> usize {
        self.root_failed.len()
    }

    fn node(&self, i: usize) -> &[f64] {
        &self.q[i * self.dof..(i + 1) * self.dof]
    }

    fn add(&mut self, q: &[f64], parent: u32) -> usize {
        let i = self.parent.len();
        self.q.extend_from_slice(q);
        self.parent.push(parent);
        self.domain.push(f64::INFINITY);
        self.index.insert(q, i as u32);
        i
    }

    /// Adds a root: a start or goal.
    fn add_root(&mut self, q: &[f64]) {
        self.add(q, ROOT);
        self.root_failed.push(false);
    }

    /// Index of the node nearest to `target`, and its distance.
    #[inline]
    fn nearest(&mut self, target: &[f64]) -> (usize, f64) {
        self.index
            .nearest(target)
            .map_or((0, f64::INFINITY), |(i, d2)| (i as usize, d2.sqrt()))
    }

    /// [`Tree::nearest`], or `None` when that node's dynamic-domain radius surely excludes
    /// `target` (then no exact distance is computed).
    #[inline]
    fn nearest_in_domain(&mut self, target: &[f64]) -> Option<(usize, f64)> {
        match self.index.nearest_unless_beyond(target, &self.domain) {
            None => Some((0, f64::INFINITY)),
            Some((_, None)) => None,
            Some((i, Some(d2))) => Some((i as usize, d2.sqrt())),
        }
    }

    /// Configurations from the root to node `i`.
    fn branch(&self, mut i: usize) -> Vec<Vec<f64>> {
        let mut out = Vec::new();
        loop {
            out.push(self.node(i).to_vec());
            match self.parent[i] {
                ROOT => break,
                p => i = p as usize,
            }
        }
        out.reverse();
        out
    }
}

/// The extensions of one gathering (see [`GATHER`]): their end states and steps, `dof`
/// values each, and per extension its node, range, whether it reaches its sample, and
/// whether its iteration is timed.
struct Gathered {
    ends: Vec<f64>,
    steps: Vec<f64>,
    meta: [(usize, f64, bool, bool); GATHER],
}

impl Gathered {
    fn new(dof: usize) -> Self {
        Gathered {
            ends: vec![0.0; GATHER * dof],
            steps: vec![0.0; GATHER * dof],
            meta: [(0, 0.0, false, false); GATHER],
        }
    }
}

enum Extend {
    Trapped,
    Advanced(usize),
    Reached(usize),
}

struct Search<'c, 'a, 's> {
    checker: &'c mut Validity<'a>,
    robot: &'a Robot,
    range: f64,
    domain: Option<DynamicDomain>,
    scratch: Vec<f64>,
    /// The last extension's step per joint (see [`Robot::step_towards`]).
    step: Vec<f64>,
    stats: &'s mut PlanStats,
    phases: Phases,
    /// True on the iterations whose sampling, neighbour queries and checks are timed (see
    /// [`SPLIT_EVERY`]).
    timed: bool,
    /// The retreats' working state, made on the search's first retreat.
    retreat: Option<Retreat>,
    /// Samples drawn since an extension last advanced (see [`DOMAIN_STALLED_AFTER`]).
    stalled: u64,
}

/// The search retreats from the roots of the tree it grows (see [`Retreat`]) once it has
/// taken this many iterations, this many extensions in a row have failed, and the tree holds
/// fewer than this many nodes per root: its start or goals are confined. (Chosen on the
/// MotionBenchMaker Fetch sets: bookshelf_thin's trees hold 1–3 nodes when it fires, and its
/// median iterations fall from 14,433 to 1,609 at seed 0; box's have grown to 4–18 nodes by
/// then, and retreating there cost a sixth more instructions for no fewer iterations; at 512
/// or 1024 iterations bookshelf_thin took 29% and 56% more instructions than at 256.)
const RETREAT_AFTER: (u64, u64, usize) = (256, 16, 4);

/// Samples drawn in a row without an extension advancing, after which the dynamic domain is
/// set aside (every sample extends from its nearest node) until one advances. A tree whose
/// nodes have all failed has radii at their floor, and a node's radius takes in one uniform
/// Fetch sample in ~5,000: a goal deep in a narrow shelf then took 0.2–3.5 s, or the whole
/// 10 s limit, on the official Fetch's bookshelf_small 91 and bookshelf_thin 5, 19 and 23
/// (seeds 0 and 1), and seconds against the point clouds of bookshelf_thin 19 and 67, where
/// every sample extending found the way out in 3–640 ms. Searches that advance at least once in
/// this many samples, most of them, are unchanged (4,096 took the same medians; 1,024 slowed
/// the official Fetch's bookshelf_thin median search by 39%).
const DOMAIN_STALLED_AFTER: u64 = 16_384;

/// Sampling, neighbour queries and checks are timed on one iteration in this many and scaled
/// up: they take a few hundred nanoseconds, and reading the clock around each would add a
/// tenth. (At one in eight, the six readings of a ~10 ns time-stamp counter were still ~4% of
/// a bookshelf_thin iteration on an AMD EPYC.)
const SPLIT_EVERY: u64 = 32;

/// The search looks at the wall clock (its time limit) and at its cancel flag once in this
/// many iterations (the clock costs ~25 ns, an iteration that rejects its sample ~100).
const LOOK_EVERY: u64 = 32;

/// While the search is stuck (see [`STUCK_AFTER`]), the smaller tree's extensions are gathered
/// this many at a time, their end states screened in one batch against the contacts the
/// checks found last, and only the unflagged ones checked in full: where nearly every
/// extension fails at its end (a gripper in a narrow shelf), most are refused for a share of
/// one batch instead of a batch each.
const GATHER: usize = 8;

/// Samples a gathering draws at most (the dynamic domain rejects many).
const GATHER_DRAWS: usize = 16;

/// Extensions are gathered once the search has taken this many iterations and this many
/// extensions in a row have failed (until one advances): short searches, where extensions
/// advance often, are left as they are.
const STUCK_AFTER: (u64, u64) = (1024, 32);

/// Search time by phase, in clock ticks (see [`ticks`]), estimated from every
/// [`SPLIT_EVERY`]th iteration.
#[derive(Default)]
struct Phases {
    start: u64,
    sample: u64,
    neighbour: u64,
    check: u64,
}

impl Phases {
    /// Writes the search time and its split into `stats`, the ticks scaled by the wall clock.
    fn finish(&self, t0: Instant, stats: &mut PlanStats) {
        let elapsed = t0.elapsed().as_secs_f64();
        let total = ticks().wrapping_sub(self.start).max(1) as f64;
        let seconds = |t: u64| (t as f64 / total * elapsed).min(elapsed);
        stats.search_s = elapsed;
        stats.sample_s = seconds(self.sample);
        stats.neighbour_s = seconds(self.neighbour);
        stats.check_s = seconds(self.check);
    }
}

/// Runs `f`; when `on` (an iteration of the split's sample), adds its ticks, less the clock's
/// own ([`tick_overhead`]), scaled by [`SPLIT_EVERY`], to `phase`.
#[inline(always)]
fn timed<T>(on: bool, phase: &mut u64, f: impl FnOnce() -> T) -> T {
    if !on {
        return f();
    }
    timed_scaled(SPLIT_EVERY, phase, f)
}

/// Runs `f` and adds its ticks, less the clock's own, to `phase` (unscaled: for work done
/// once per gathering, not per iteration).
#[inline(always)]
fn timed_each<T>(phase: &mut u64, f: impl FnOnce() -> T) -> T {
    timed_scaled(1, phase, f)
}

/// Runs `f` and adds `scale` times its ticks, less the clock's own, to `phase`.
#[inline(always)]
fn timed_scaled<T>(scale: u64, phase: &mut u64, f: impl FnOnce() -> T) -> T {
    let t = ticks();
    let out = f();
    *phase += scale * ticks().wrapping_sub(t).saturating_sub(tick_overhead());
    out
}

/// Ticks two back-to-back readings of [`ticks`] take (the least of a few tries), measured
/// once: on an iteration that only draws a sample and rejects it, a phase takes a few dozen
/// nanoseconds, and the readings would otherwise be counted in it.
fn tick_overhead() -> u64 {
    static OVERHEAD: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *OVERHEAD.get_or_init(|| {
        (0..64)
            .map(|_| {
                let t = ticks();
                ticks().wrapping_sub(t)
            })
            .min()
            .unwrap_or(0)
    })
}

/// A cheap monotonic tick count for the time split: the CPU's time-stamp counter on x86-64
/// (a few nanoseconds to read, against ~25 ns for the system clock, which the split's four
/// readings per iteration made a tenth of the search), else nanoseconds of the system clock.
#[inline]
fn ticks() -> u64 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: RDTSC exists on every x86-64 CPU.
        #[allow(unused_unsafe)]
        unsafe {
            std::arch::x86_64::_rdtsc()
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        static ORIGIN: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
        ORIGIN.get_or_init(Instant::now).elapsed().as_nanos() as u64
    }
}

/// Dynamic-domain sampling (Yershova et al. 2005; VAMP's defaults): a node whose extension
/// failed only accepts samples within its radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DynamicDomain {
    /// Radius a node gets when an extension from it first fails.
    pub radius: f64,
    /// Smallest radius.
    pub min_radius: f64,
    /// Relative growth on success and shrinkage on failure.
    pub alpha: f64,
}

impl Default for DynamicDomain {
    fn default() -> Self {
        DynamicDomain {
            radius: 4.0,
            min_radius: 1.0,
            alpha: 1e-4,
        }
    }
}

impl Search<'_, '_, '_> {
    fn nearest(&mut self, tree: &mut Tree, target: &[f64]) -> (usize, f64) {
        timed(self.timed, &mut self.phases.neighbour, || {
            tree.nearest(target)
        })
    }

    /// One step from the nearest node towards a sample. With a dynamic domain, samples
    /// farther from their nearest node than its radius are rejected (`None`), and the radius
    /// shrinks where extensions fail and grows where they succeed (Yershova et al. 2005).
    fn extend(&mut self, tree: &mut Tree, target: &[f64]) -> Option<Extend> {
        let (near, d) = self.nearest_accepting(tree, target)?;
        let out = self.extend_from(tree, near, d, target, self.range_from(tree, near));
        self.record(tree, near, &out);
        Some(out)
    }

    /// The node nearest to `target` and its distance; `None` when a dynamic domain rejects
    /// the sample (its nearest node's radius does not reach it), unless the search is stalled
    /// (see [`DOMAIN_STALLED_AFTER`]).
    #[inline(always)]
    fn nearest_accepting(&mut self, tree: &mut Tree, target: &[f64]) -> Option<(usize, f64)> {
        self.stalled += 1;
        if self.domain.is_none() || self.stalled >= DOMAIN_STALLED_AFTER {
            return Some(self.nearest(tree, target));
        }
        let (near, d) = timed(self.timed, &mut self.phases.neighbour, || {
            tree.nearest_in_domain(target)
        })?;
        (d <= tree.domain[near]).then_some((near, d))
    }

    /// The longest step from node `near`: the range, or [`ROOT_STEP`] of it from a root an
    /// extension has failed from.
    #[inline(always)]
    fn range_from(&self, tree: &Tree, near: usize) -> f64 {
        match tree.root_failed.get(near) {
            Some(true) => self.range * ROOT_STEP,
            _ => self.range,
        }
    }

    /// Notes an extension's outcome from node `near`: a root that failed takes shorter steps
    /// from then on, the node's dynamic-domain radius shrinks on a failure and grows on a
    /// success, and a success ends a stall (see [`DOMAIN_STALLED_AFTER`]).
    #[inline(always)]
    fn record(&mut self, tree: &mut Tree, near: usize, out: &Extend) {
        let trapped = matches!(out, Extend::Trapped);
        if trapped {
            if let Some(failed) = tree.root_failed.get_mut(near) {
                *failed = true;
            }
        } else {
            self.stalled = 0;
        }
        if let Some(dd) = self.domain {
            let r = &mut tree.domain[near];
            if trapped {
                *r = if r.is_finite() {
                    (*r * (1.0 - dd.alpha)).max(dd.min_radius)
                } else {
                    dd.radius
                };
            } else if r.is_finite() {
                *r *= 1.0 + dd.alpha;
            }
        }
    }

    /// Adds the retreats from each root of `tree` to it (see [`Retreat`]), once per tree.
    #[cold]
    #[inline(never)]
    fn retreat(&mut self, tree: &mut Tree) {
        tree.retreated = true;
        let robot = self.robot;
        let retreat = self.retreat.get_or_insert_with(|| Retreat::new(robot));
        for root in 0..tree.roots() {
            let q = tree.node(root).to_vec();
            let mut parent = root as u32;
            retreat.run(self.checker, &q, self.range, |state, first| {
                if first {
                    parent = root as u32;
                }
                parent = tree.add(state, parent) as u32;
                self.stats.retreat_states += 1;
            });
        }
    }

    /// One step of at most `range` from node `near`, at distance `d`, towards `target`.
    fn extend_from(
        &mut self,
        tree: &mut Tree,
        near: usize,
        d: f64,
        target: &[f64],
        range: f64,
    ) -> Extend {
        let reached = step_end(
            self.robot,
            (tree.node(near), d, target, range),
            &mut self.scratch,
            &mut self.step,
        );
        let (checker, timed_now) = (&mut *self.checker, self.timed);
        let check = &mut self.phases.check;
        add_if_free(
            checker,
            (timed_now, check),
            tree,
            near,
            (&self.scratch, &self.step),
            (reached, range),
        )
    }

    /// One gathering (see [`GATHER`]) of extensions of `tree` towards samples drawn into
    /// `sample` (counted in `iterations`, below `limit`): the node the first that advances
    /// added (the rest are dropped: their nearest nodes may have changed), else `None`.
    /// `failures` counts the extensions that fail in a row.
    fn gathered_round(
        &mut self,
        tree: &mut Tree,
        (sampler, rng): (&mut dyn Sampler, &mut PlannerRng),
        sample: &mut [f64],
        (iterations, limit): (&mut u64, u64),
        failures: &mut u64,
        g: &mut Gathered,
    ) -> Option<usize> {
        let dof = tree.dof;
        let (mut k, mut draws) = (0, 0);
        while k < GATHER && draws < GATHER_DRAWS && *iterations < limit {
            *iterations += 1;
            draws += 1;
            self.timed = iterations.is_multiple_of(SPLIT_EVERY);
            timed(self.timed, &mut self.phases.sample, || {
                sampler.sample(self.robot, rng, sample)
            });
            let Some((near, d)) = self.nearest_accepting(tree, sample) else {
                continue;
            };
            let range = self.range_from(tree, near);
            let reached = step_end(
                self.robot,
                (tree.node(near), d, sample, range),
                &mut g.ends[k * dof..][..dof],
                &mut g.steps[k * dof..][..dof],
            );
            g.meta[k] = (near, range, reached, self.timed);
            k += 1;
        }
        if k == 0 {
            return None;
        }
        self.stats.screened += k as u64;
        let flagged = {
            let ends: [&[f64]; GATHER] =
                std::array::from_fn(|i| &g.ends[i.min(k - 1) * dof..][..dof]);
            let checker = &mut *self.checker;
            timed_each(&mut self.phases.check, || {
                checker.surely_colliding(&ends[..k])
            })
        };
        self.stats.screened_out += u64::from(flagged.count_ones());
        for i in 0..k {
            let (near, range, reached, on) = g.meta[i];
            let out = if flagged & (1 << i) != 0 {
                Extend::Trapped
            } else {
                add_if_free(
                    self.checker,
                    (on, &mut self.phases.check),
                    tree,
                    near,
                    (&g.ends[i * dof..][..dof], &g.steps[i * dof..][..dof]),
                    (reached, range),
                )
            };
            self.record(tree, near, &out);
            match out {
                Extend::Trapped => *failures += 1,
                Extend::Advanced(n) | Extend::Reached(n) => {
                    *failures = 0;
                    return Some(n);
                }
            }
        }
        None
    }

    /// Steps towards `target` until it is reached or blocked: from the nearest node first,
    /// then from each node just added (no further nearest-neighbour queries).
    fn connect(&mut self, tree: &mut Tree, target: &[f64]) -> Extend {
        let (mut from, mut d) = self.nearest(tree, target);
        loop {
            match self.extend_from(tree, from, d, target, self.range) {
                Extend::Advanced(i) => {
                    from = i;
                    d = self.robot.distance(tree.node(i), target);
                }
                other => return other,
            }
        }
    }
}

/// Writes the end of a step of at most `range` from `from` (at distance `d`) towards
/// `target` into `end`, and the step per joint into `step` (see [`Robot::step_towards`]);
/// true when the step reaches `target`.
#[inline(always)]
fn step_end(
    robot: &Robot,
    (from, d, target, range): (&[f64], f64, &[f64], f64),
    end: &mut [f64],
    step: &mut [f64],
) -> bool {
    let reached = d <= range;
    if reached {
        end.copy_from_slice(target);
    } else {
        // The step is kept: the edge's states follow from it without taking the joints'
        // differences again.
        robot.step_towards(from, target, range / d, end, step);
    }
    reached
}

/// Adds `end` to `tree` below node `near` when the step to it (`step`, of length at most
/// `range`; to a sample when `reached`) is free, the check timed into `phase` when `on`.
#[inline(always)]
fn add_if_free(
    checker: &mut Validity<'_>,
    (on, phase): (bool, &mut u64),
    tree: &mut Tree,
    near: usize,
    (end, step): (&[f64], &[f64]),
    (reached, range): (bool, f64),
) -> Extend {
    let ok = timed(on, phase, || {
        if reached {
            checker.reach_valid(tree.node(near), end)
        } else {
            checker.step_valid(tree.node(near), end, step, range)
        }
    });
    if !ok {
        return Extend::Trapped;
    }
    let i = tree.add(end, near as u32);
    if reached {
        Extend::Reached(i)
    } else {
        Extend::Advanced(i)
    }
}

/// Trees kept over at most this many nodes are dropped rather than kept as spares (a tree of
/// 8 joints and 16k nodes holds ~2 MB).
const SPARE_NODES: usize = 1 << 14;

thread_local! {
    /// The last search's two trees on this thread, for the next search to empty and reuse:
    /// making and dropping them (the index's buffers, the first leaf's lanes) and growing them
    /// was ~5% of a short Panda search's instructions.
    static SPARE_TREES: std::cell::Cell<Option<Box<[Tree; 2]>>> =
        const { std::cell::Cell::new(None) };
}

/// Searches for a path from `start` to any of `goals` (all valid and collision free).
// Never inlined: called once per plan, and profiles (the README's callgrind commands) select
// the search by its name.
#[inline(never)]
pub(crate) fn search(
    checker: &mut Validity<'_>,
    start: &[f64],
    goals: &[Vec<f64>],
    params: &PlannerParams,
    sampler: &mut dyn Sampler,
    rng: &mut PlannerRng,
    stats: &mut PlanStats,
) -> Result<Vec<Vec<f64>>, PlanError> {
    let t0 = Instant::now();
    let continuous = || checker.robot().variables().iter().map(|v| v.continuous);
    let mut trees = match SPARE_TREES.take() {
        Some(mut spare) if spare[0].index.continuous().iter().copied().eq(continuous()) => {
            spare.iter_mut().for_each(Tree::clear);
            spare
        }
        _ => {
            let continuous: Vec<bool> = continuous().collect();
            let dof = continuous.len();
            Box::new([Tree::new(dof, &continuous), Tree::new(dof, &continuous)])
        }
    };
    let [start_tree, goal_tree] = &mut *trees;
    let result = search_with(
        (start_tree, goal_tree),
        t0,
        checker,
        (start, goals),
        params,
        (sampler, rng),
        stats,
    );
    if trees.iter().all(|t| t.parent.capacity() <= SPARE_NODES) {
        SPARE_TREES.set(Some(trees));
    }
    result
}

/// [`search`] in the trees given (empty).
fn search_with(
    (start_tree, goal_tree): (&mut Tree, &mut Tree),
    t0: Instant,
    checker: &mut Validity<'_>,
    (start, goals): (&[f64], &[Vec<f64>]),
    params: &PlannerParams,
    (sampler, rng): (&mut dyn Sampler, &mut PlannerRng),
    stats: &mut PlanStats,
) -> Result<Vec<Vec<f64>>, PlanError> {
    let robot = checker.robot();
    let dof = robot.dof();
    start_tree.add_root(start);
    for g in goals {
        goal_tree.add_root(g);
    }
    // Start and goal may see each other directly.
    for (gi, g) in goals.iter().enumerate() {
        if checker.motion_valid(start, g) {
            stats.search_s = t0.elapsed().as_secs_f64();
            stats.tree_nodes = 1 + goals.len() as u64;
            return Ok(vec![start.to_vec(), goal_tree.node(gi).to_vec()]);
        }
    }
    let mut search = Search {
        robot,
        range: params.range,
        domain: params.dynamic_domain,
        scratch: vec![0.0; dof],
        step: vec![0.0; dof],
        checker,
        stats,
        phases: Phases {
            start: ticks(),
            ..Phases::default()
        },
        timed: false,
        retreat: None,
        stalled: 0,
    };
    let mut sample = vec![0.0; dof];
    let mut target = vec![0.0; dof];
    let mut iterations = 0u64;
    // The next iteration at which the clock and the cancel flag are read.
    let mut next_look = 0u64;
    // Extensions of the smaller tree that failed in a row.
    let mut failures = 0u64;
    let mut gathered = Gathered::new(dof);
    loop {
        let look = iterations >= next_look;
        if look {
            next_look = iterations + LOOK_EVERY;
        }
        if look && params.cancel.is_set() {
            search.phases.finish(t0, search.stats);
            search.stats.iterations = iterations;
            search.stats.tree_nodes = (start_tree.len() + goal_tree.len()) as u64;
            return Err(PlanError::Cancelled { iterations });
        }
        if iterations >= params.max_iterations || (look && t0.elapsed() >= params.time_limit) {
            search.phases.finish(t0, search.stats);
            let elapsed = search.stats.search_s;
            search.stats.iterations = iterations;
            search.stats.tree_nodes = (start_tree.len() + goal_tree.len()) as u64;
            return Err(PlanError::Timeout {
                iterations,
                elapsed_ms: elapsed * 1e3,
            });
        }

        // Grow the smaller tree (balanced bidirectional search).
        let from_start = start_tree.len() <= goal_tree.len();
        let (a, b) = if from_start {
            (&mut *start_tree, &mut *goal_tree)
        } else {
            (&mut *goal_tree, &mut *start_tree)
        };
        if !a.retreated
            && iterations >= RETREAT_AFTER.0
            && failures >= RETREAT_AFTER.1
            && a.len() < RETREAT_AFTER.2 * a.roots()
        {
            search.retreat(a);
        }
        let new = if iterations >= STUCK_AFTER.0 && failures >= STUCK_AFTER.1 {
            search.gathered_round(
                a,
                (&mut *sampler, &mut *rng),
                &mut sample,
                (&mut iterations, params.max_iterations),
                &mut failures,
                &mut gathered,
            )
        } else {
            iterations += 1;
            search.timed = iterations.is_multiple_of(SPLIT_EVERY);
            timed(search.timed, &mut search.phases.sample, || {
                sampler.sample(robot, rng, &mut sample)
            });
            match search.extend(a, &sample) {
                None => None,
                Some(Extend::Trapped) => {
                    failures += 1;
                    None
                }
                Some(Extend::Advanced(i) | Extend::Reached(i)) => {
                    failures = 0;
                    Some(i)
                }
            }
        };
        if let Some(new) = new {
            target.copy_from_slice(a.node(new));
            if let Extend::Reached(other) = search.connect(b, &target) {
                let (si, gi) = if from_start {
                    (new, other)
                } else {
                    (other, new)
                };
                let mut path = start_tree.branch(si);
                let mut tail = goal_tree.branch(gi);
                tail.reverse();
                // The connecting node appears at the end of both branches.
                path.extend(tail.into_iter().skip(1));
                search.stats.iterations = iterations;
                search.phases.finish(t0, search.stats);
                search.stats.tree_nodes = (start_tree.len() + goal_tree.len()) as u64;
                return Ok(path);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::Shape;
    use crate::world::{Environment, Object};
    use crate::Pose;

    /// A search of range 1.0 with `checker`'s robot, writing into `stats`.
    fn test_search<'c, 'a, 's>(
        checker: &'c mut Validity<'a>,
        stats: &'s mut PlanStats,
        domain: Option<DynamicDomain>,
    ) -> Search<'c, 'a, 's> {
        let robot = checker.robot();
        Search {
            robot,
            range: 1.0,
            domain,
            scratch: vec![0.0; robot.dof()],
            step: vec![0.0; robot.dof()],
            checker,
            stats,
            phases: Phases::default(),
            timed: false,
            retreat: None,
            stalled: 0,
        }
    }

    /// A goal whose full-range steps towards a sample all hit a post takes half steps once
    /// one has failed, and so leaves; a node that is not a root keeps the full range.
    #[test]
    fn a_root_that_failed_takes_half_steps() {
        let robot = Robot::builtin("fetch").unwrap();
        // A post beside the arm, about 0.9 rad round the shoulder's pan from the arm at zero.
        let (r, angle) = (0.75_f64, 0.9_f64);
        let post = Object {
            name: "post".into(),
            shape: Shape::cuboid([0.06, 0.06, 1.0]),
            pose: Pose::translation(r * angle.cos(), r * angle.sin(), 1.0),
        };
        let env = Environment::from_objects([post]).unwrap();
        let mut checker = Validity::new(&robot, &env, 1.0 / 32.0, 0.0);
        let pan = robot
            .variables()
            .iter()
            .position(|v| v.name == "shoulder_pan_joint")
            .unwrap();
        let at = |a: f64| {
            let mut q = vec![0.0; robot.dof()];
            q[pan] = a;
            q
        };
        assert!(checker.is_valid(&at(0.0)) && checker.is_valid(&at(0.5)));
        assert!(
            !checker.is_valid(&at(angle)),
            "the post is not in the arm's way"
        );
        let continuous: Vec<bool> = robot.variables().iter().map(|v| v.continuous).collect();
        let mut stats = PlanStats::default();
        let mut search = test_search(&mut checker, &mut stats, None);
        let target = at(1.2);
        let mut tree = Tree::new(robot.dof(), &continuous);
        tree.add_root(&at(0.0));
        assert!(matches!(
            search.extend(&mut tree, &target),
            Some(Extend::Trapped)
        ));
        match search.extend(&mut tree, &target) {
            Some(Extend::Advanced(i)) => assert!((tree.node(i)[pan] - 0.5).abs() < 1e-9),
            _ => panic!("the root's half step was not taken"),
        }
        // The same state as a node that is not a root: full steps only, trapped every time.
        let mut tree = Tree::new(robot.dof(), &continuous);
        tree.add_root(&at(-1.5));
        tree.add(&at(0.0), 0);
        let near = 1;
        for _ in 0..2 {
            let d = robot.distance(tree.node(near), &target);
            let range = search.range_from(&tree, near);
            let out = search.extend_from(&mut tree, near, d, &target, range);
            search.record(&mut tree, near, &out);
            assert!(matches!(out, Extend::Trapped));
        }
    }

    /// A sample beyond its nearest node's dynamic-domain radius is rejected until the search
    /// has drawn [`DOMAIN_STALLED_AFTER`] samples without an extension advancing; from then on
    /// it is taken, until an extension advances.
    #[test]
    fn a_stalled_search_sets_the_domain_aside() {
        let robot = Robot::builtin("fetch").unwrap();
        let env = Environment::default();
        let mut checker = Validity::new(&robot, &env, 1.0 / 32.0, 0.0);
        let continuous: Vec<bool> = robot.variables().iter().map(|v| v.continuous).collect();
        let mut stats = PlanStats::default();
        let domain = DynamicDomain::default();
        let mut search = test_search(&mut checker, &mut stats, Some(domain));
        let mut tree = Tree::new(robot.dof(), &continuous);
        let root = robot.named_state("tuck").unwrap().to_vec();
        tree.add_root(&root);
        tree.domain[0] = domain.min_radius;
        let mut far = root.clone();
        far[2] += 2.0 * domain.min_radius;
        for k in 1..DOMAIN_STALLED_AFTER {
            assert!(
                search.nearest_accepting(&mut tree, &far).is_none(),
                "sample {k} taken"
            );
        }
        for _ in 0..3 {
            let (near, d) = search
                .nearest_accepting(&mut tree, &far)
                .expect("still rejected");
            assert_eq!(near, 0);
            assert!(d > tree.domain[0]);
        }
        // An extension that advances ends the stall.
        search.record(&mut tree, 0, &Extend::Advanced(0));
        assert!(search.nearest_accepting(&mut tree, &far).is_none());
    }

    /// Gathered extensions among crowded boxes: the screen refuses many without a check of
    /// their own, every node added is free and reached by a free motion from its parent, and
    /// the same seed grows the same tree.
    #[test]
    fn gathered_extensions_add_only_free_nodes() {
        use crate::planning::UniformSampler;
        use rand::SeedableRng;
        let robot = Robot::builtin("fetch").unwrap();
        let mut place = rand::rngs::StdRng::seed_from_u64(3);
        let env = crate::world::environment::random_boxes(
            &mut place,
            14,
            [0.25; 3],
            [0.3..1.1, -0.8..0.8, 0.3..1.5],
        );
        let continuous: Vec<bool> = robot.variables().iter().map(|v| v.continuous).collect();
        let grow = |seed: u64| {
            let mut checker = Validity::new(&robot, &env, 1.0 / 32.0, 0.0);
            let root = robot.named_state("tuck").unwrap().to_vec();
            assert!(checker.is_valid(&root));
            let mut stats = PlanStats::default();
            let domain = Some(DynamicDomain::default());
            let mut search = test_search(&mut checker, &mut stats, domain);
            let mut tree = Tree::new(robot.dof(), &continuous);
            tree.add_root(&root);
            let (mut rng, mut sampler) = (PlannerRng::seed_from_u64(seed), UniformSampler);
            let (mut sample, mut gathered) = (vec![0.0; robot.dof()], Gathered::new(robot.dof()));
            let (mut iterations, mut failures) = (0, 0);
            for _ in 0..300 {
                search.gathered_round(
                    &mut tree,
                    (&mut sampler, &mut rng),
                    &mut sample,
                    (&mut iterations, u64::MAX),
                    &mut failures,
                    &mut gathered,
                );
            }
            let (screened, refused) = (search.stats.screened, search.stats.screened_out);
            (tree.q.clone(), tree.parent.clone(), screened, refused)
        };
        let (q, parent, screened, refused) = grow(11);
        assert!(parent.len() > 10, "{} nodes", parent.len());
        assert!(
            refused * 5 > screened,
            "{refused} of {screened} refused by the screen"
        );
        let mut oracle = Validity::new(&robot, &env, 1.0 / 32.0, 0.0);
        let node = |i: usize| &q[i * robot.dof()..][..robot.dof()];
        for (i, &p) in parent.iter().enumerate().skip(1) {
            let p = p as usize;
            assert!(oracle.is_valid(node(i)) && oracle.motion_valid(node(p), node(i)));
        }
        assert_eq!((q, parent), {
            let (q, parent, ..) = grow(11);
            (q, parent)
        });
    }
}
