//! RRT-Connect (Kuffner & LaValle 2000): two trees, one from the start and one from the goals,
//! grown towards random samples and towards each other.
//!
//! Trees are flat arrays (`dof` values per node, a parent index per node); nearest neighbours
//! are found by a linear scan with early exit, which beats tree structures at the sizes
//! RRT-Connect reaches. Nothing is allocated per iteration.

use super::{PlanError, PlanStats, PlannerParams, PlannerRng, Sampler};
use crate::collision::SphereChecker;
use crate::robot::Robot;
use std::time::Instant;

const ROOT: u32 = u32::MAX;

/// A tree of configurations stored flat.
struct Tree {
    dof: usize,
    q: Vec<f64>,
    parent: Vec<u32>,
}

impl Tree {
    fn new(dof: usize) -> Self {
        Tree {
            dof,
            q: Vec::with_capacity(dof * 4096),
            parent: Vec::with_capacity(4096),
        }
    }

    fn len(&self) -> usize {
        self.parent.len()
    }

    fn node(&self, i: usize) -> &[f64] {
        &self.q[i * self.dof..(i + 1) * self.dof]
    }

    fn add(&mut self, q: &[f64], parent: u32) -> usize {
        self.q.extend_from_slice(q);
        self.parent.push(parent);
        self.parent.len() - 1
    }

    /// Index of the node nearest to `target`.
    #[inline]
    fn nearest(&self, continuous: &[bool], target: &[f64]) -> usize {
        let mut best = f64::INFINITY;
        let mut best_i = 0;
        for (i, node) in self.q.chunks_exact(self.dof).enumerate() {
            let mut d2 = 0.0;
            for j in 0..self.dof {
                let mut d = target[j] - node[j];
                if continuous[j] {
                    d = crate::robot::config_space::wrap_angle(d);
                }
                d2 += d * d;
                if d2 >= best {
                    break;
                }
            }
            if d2 < best {
                best = d2;
                best_i = i;
            }
        }
        best_i
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
    checker: &'c mut SphereChecker<'a>,
    robot: &'a Robot,
    continuous: Vec<bool>,
    range: f64,
    scratch: Vec<f64>,
    stats: &'s mut PlanStats,
}

impl Search<'_, '_, '_> {
    fn extend(&mut self, tree: &mut Tree, target: &[f64]) -> Extend {
        let near = tree.nearest(&self.continuous, target);
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

    fn connect(&mut self, tree: &mut Tree, target: &[f64]) -> Extend {
        loop {
            match self.extend(tree, target) {
                Extend::Advanced(_) => continue,
                other => return other,
            }
        }
    }
}

/// Searches for a path from `start` to any of `goals` (all valid and collision free).
pub(crate) fn search(
    checker: &mut SphereChecker<'_>,
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
    let mut start_tree = Tree::new(dof);
    start_tree.add(start, ROOT);
    let mut goal_tree = Tree::new(dof);
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
        continuous: robot.variables().iter().map(|v| v.continuous).collect(),
        range: params.range,
        scratch: vec![0.0; dof],
        checker,
        stats,
    };
    let mut sample = vec![0.0; dof];
    let mut target = vec![0.0; dof];
    let mut from_start = true;
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

        let (a, b) = if from_start {
            (&mut start_tree, &mut goal_tree)
        } else {
            (&mut goal_tree, &mut start_tree)
        };
        let new = match search.extend(a, &sample) {
            Extend::Trapped => None,
            Extend::Advanced(i) | Extend::Reached(i) => Some(i),
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
        from_start = !from_start;
    }
}
