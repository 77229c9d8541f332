//! RRT-Connect (Kuffner & LaValle 2000): two trees, one from the start and one from the goals,
//! grown towards random samples and towards each other.
//!
//! Trees are flat arrays (`dof` values per node, a parent index per node). Nearest neighbours
//! come from a k-d tree built incrementally over the same nodes (split on the bounded joints,
//! cycling through them by depth; continuous joints wrap, so they are never split on), so a
//! query costs about the logarithm of the tree's size instead of a scan of it. Nothing is
//! allocated per iteration beyond the arrays' amortised growth.

use super::validity::Validity;
use super::{PlanError, PlanStats, PlannerParams, PlannerRng, Sampler};
use crate::robot::Robot;
use std::time::Instant;

const ROOT: u32 = u32::MAX;

/// A tree of configurations stored flat, with a k-d tree over its nodes.
struct Tree {
    dof: usize,
    q: Vec<f64>,
    parent: Vec<u32>,
    /// Per node: its two k-d children (`NONE` when absent).
    kd: Vec<[u32; 2]>,
    /// Joints split on, cycled by depth (the bounded ones).
    split_dims: Vec<usize>,
    /// Per node: the joint it splits on.
    split: Vec<u8>,
    /// Search stack, kept between queries.
    stack: Vec<(u32, f64)>,
    /// Per node: its dynamic-domain radius (infinite until an extension from it fails).
    domain: Vec<f64>,
}

const NONE: u32 = u32::MAX;

impl Tree {
    fn new(dof: usize, continuous: &[bool]) -> Self {
        Tree {
            dof,
            q: Vec::with_capacity(dof * 4096),
            parent: Vec::with_capacity(4096),
            kd: Vec::with_capacity(4096),
            split_dims: (0..dof).filter(|&j| !continuous[j]).collect(),
            split: Vec::with_capacity(4096),
            stack: Vec::with_capacity(256),
            domain: Vec::with_capacity(4096),
        }
    }

    fn len(&self) -> usize {
        self.parent.len()
    }

    fn node(&self, i: usize) -> &[f64] {
        &self.q[i * self.dof..(i + 1) * self.dof]
    }

    fn add(&mut self, q: &[f64], parent: u32) -> usize {
        let i = self.parent.len();
        self.q.extend_from_slice(q);
        self.parent.push(parent);
        self.kd.push([NONE, NONE]);
        self.domain.push(f64::INFINITY);
        let mut depth = 0;
        if i > 0 && !self.split_dims.is_empty() {
            let mut at = 0usize;
            loop {
                let dim = self.split[at] as usize;
                let side = (q[dim] >= self.q[at * self.dof + dim]) as usize;
                depth += 1;
                match self.kd[at][side] {
                    NONE => {
                        self.kd[at][side] = i as u32;
                        break;
                    }
                    next => at = next as usize,
                }
            }
        }
        let dim = if self.split_dims.is_empty() {
            0
        } else {
            self.split_dims[depth % self.split_dims.len()]
        };
        self.split.push(dim as u8);
        i
    }

    /// Squared distance (continuous joints wrapped) from `target` to node `i`, or more than
    /// `bound` when it exceeds it (early exit).
    #[inline]
    fn dist2(&self, continuous: &[bool], target: &[f64], i: usize, bound: f64) -> f64 {
        let node = &self.q[i * self.dof..(i + 1) * self.dof];
        let mut d2 = 0.0;
        for j in 0..self.dof {
            let mut d = target[j] - node[j];
            if continuous[j] {
                d = crate::robot::config_space::wrap_angle(d);
            }
            d2 += d * d;
            if d2 >= bound {
                break;
            }
        }
        d2
    }

    /// Index of the node nearest to `target`.
    #[inline]
    fn nearest(&mut self, continuous: &[bool], target: &[f64]) -> usize {
        if self.split_dims.is_empty() {
            let mut best = (f64::INFINITY, 0);
            for i in 0..self.len() {
                let d2 = self.dist2(continuous, target, i, best.0);
                if d2 < best.0 {
                    best = (d2, i);
                }
            }
            return best.1;
        }
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        stack.push((0, 0.0));
        let mut best = (f64::INFINITY, 0usize);
        while let Some((at, bound)) = stack.pop() {
            if bound >= best.0 {
                continue;
            }
            let at = at as usize;
            let d2 = self.dist2(continuous, target, at, best.0);
            if d2 < best.0 {
                best = (d2, at);
            }
            let dim = self.split[at] as usize;
            let diff = target[dim] - self.q[at * self.dof + dim];
            let (near, far) = if diff >= 0.0 {
                (self.kd[at][1], self.kd[at][0])
            } else {
                (self.kd[at][0], self.kd[at][1])
            };
            // The far side is at least |diff| away along this joint.
            if far != NONE {
                stack.push((far, bound.max(diff * diff)));
            }
            if near != NONE {
                stack.push((near, bound));
            }
        }
        self.stack = stack;
        best.1
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

enum Extend {
    Trapped,
    Advanced(usize),
    Reached(usize),
}

struct Search<'c, 'a, 's> {
    checker: &'c mut Validity<'a>,
    robot: &'a Robot,
    continuous: Vec<bool>,
    range: f64,
    domain: Option<DynamicDomain>,
    scratch: Vec<f64>,
    stats: &'s mut PlanStats,
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
    /// One step from the nearest node towards a sample. With a dynamic domain, samples
    /// farther from their nearest node than its radius are rejected (`None`), and the radius
    /// shrinks where extensions fail and grows where they succeed (Yershova et al. 2005).
    fn extend(&mut self, tree: &mut Tree, target: &[f64]) -> Option<Extend> {
        let near = tree.nearest(&self.continuous, target);
        if let Some(dd) = self.domain {
            if self.robot.distance(tree.node(near), target) > tree.domain[near] {
                return None;
            }
            let out = self.extend_from(tree, near, target);
            let r = &mut tree.domain[near];
            match out {
                Extend::Trapped if r.is_finite() => *r = (*r * (1.0 - dd.alpha)).max(dd.min_radius),
                Extend::Trapped => *r = dd.radius,
                _ if r.is_finite() => *r *= 1.0 + dd.alpha,
                _ => {}
            }
            return Some(out);
        }
        Some(self.extend_from(tree, near, target))
    }

    /// One step of at most `range` from node `near` towards `target`.
    fn extend_from(&mut self, tree: &mut Tree, near: usize, target: &[f64]) -> Extend {
        let near_q = tree.node(near);
        let d = self.robot.distance(near_q, target);
        let reached = d <= self.range;
        if reached {
            self.scratch.copy_from_slice(target);
        } else {
            self.robot
                .interpolate(near_q, target, self.range / d, &mut self.scratch);
        }
        let t = Instant::now();
        let ok = self.checker.is_valid(&self.scratch)
            && self.checker.motion_valid(tree.node(near), &self.scratch);
        self.stats.check_s += t.elapsed().as_secs_f64();
        if !ok {
            return Extend::Trapped;
        }
        let i = tree.add(&self.scratch, near as u32);
        if reached {
            Extend::Reached(i)
        } else {
            Extend::Advanced(i)
        }
    }

    /// Steps towards `target` until it is reached or blocked: from the nearest node first,
    /// then from each node just added (no further nearest-neighbour queries).
    fn connect(&mut self, tree: &mut Tree, target: &[f64]) -> Extend {
        let mut from = tree.nearest(&self.continuous, target);
        loop {
            match self.extend_from(tree, from, target) {
                Extend::Advanced(i) => from = i,
                other => return other,
            }
        }
    }
}

/// Searches for a path from `start` to any of `goals` (all valid and collision free).
pub(crate) fn search(
    checker: &mut Validity<'_>,
    start: &[f64],
    goals: &[Vec<f64>],
    params: &PlannerParams,
    sampler: &mut dyn Sampler,
    rng: &mut PlannerRng,
    stats: &mut PlanStats,
) -> Result<Vec<Vec<f64>>, PlanError> {
    let robot = checker.robot();
    let dof = robot.dof();
    let t0 = Instant::now();
    let continuous: Vec<bool> = robot.variables().iter().map(|v| v.continuous).collect();
    let mut start_tree = Tree::new(dof, &continuous);
    start_tree.add(start, ROOT);
    let mut goal_tree = Tree::new(dof, &continuous);
    for g in goals {
        goal_tree.add(g, ROOT);
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
        continuous,
        range: params.range,
        domain: params.dynamic_domain,
        scratch: vec![0.0; dof],
        checker,
        stats,
    };
    let mut sample = vec![0.0; dof];
    let mut target = vec![0.0; dof];
    let mut iterations = 0u64;
    loop {
        if iterations >= params.max_iterations
            || (iterations.is_multiple_of(16) && t0.elapsed() >= params.time_limit)
        {
            let elapsed = t0.elapsed().as_secs_f64();
            search.stats.iterations = iterations;
            search.stats.search_s = elapsed;
            search.stats.tree_nodes = (start_tree.len() + goal_tree.len()) as u64;
            return Err(PlanError::Timeout {
                iterations,
                elapsed_ms: elapsed * 1e3,
            });
        }
        iterations += 1;
        let t = Instant::now();
        sampler.sample(robot, rng, &mut sample);
        search.stats.sample_s += t.elapsed().as_secs_f64();

        // Grow the smaller tree (balanced bidirectional search).
        let from_start = start_tree.len() <= goal_tree.len();
        let (a, b) = if from_start {
            (&mut start_tree, &mut goal_tree)
        } else {
            (&mut goal_tree, &mut start_tree)
        };
        let new = match search.extend(a, &sample) {
            None | Some(Extend::Trapped) => None,
            Some(Extend::Advanced(i) | Extend::Reached(i)) => Some(i),
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
                search.stats.search_s = t0.elapsed().as_secs_f64();
                search.stats.tree_nodes = (start_tree.len() + goal_tree.len()) as u64;
                return Ok(path);
            }
        }
    }
}
