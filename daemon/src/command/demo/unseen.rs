//! The obstacle only the camera sees: a box put where a planner blind to it would pass, and
//! the check of every returned path against the true world.

use ember_engine::collision::checker::DEFAULT_RESOLUTION;
use ember_engine::collision::exact::ExactChecker;
use ember_engine::collision::Shape;
use ember_engine::planning::{self, Goal, PlanRequest, PlannerParams, UniformSampler};
use ember_engine::robot::Robot;
use ember_engine::world::{Environment, Object};
use ember_engine::Pose;
use std::time::Duration;

/// Edge of the unseen box, metres.
const SIDE: f64 = 0.1;

/// Resolution of the finer truth check along each edge (configuration distance).
const FINE_RESOLUTION: f64 = 0.01;

/// A box that the path planned from `start` to `goal` in `env` (the tracked objects only)
/// runs through: centred on the arm's last moving link at the middle of that path (or near
/// it), in view of the camera at `camera` and not hidden behind an object, where start and
/// goal stay free; with the true world (`env` and the box). `None` when no such place is
/// found.
pub fn place(
    robot: &Robot,
    env: &Environment,
    camera: &Pose,
    (start, goal): (&[f64], &[f64]),
    seed: u64,
) -> Option<(Object, Environment)> {
    let request = PlanRequest {
        start: start.to_vec(),
        goal: Goal::Joints(vec![goal.to_vec()]),
        params: PlannerParams {
            seed,
            time_limit: Duration::from_secs(2),
            ..Default::default()
        },
    };
    let path = planning::plan(robot, env, &request, &mut UniformSampler)
        .ok()?
        .path;
    let states = dense(robot, &path, 0.05);
    let tip = (0..robot.links().len())
        .rev()
        .find(|&l| robot.link_moves(l) && robot.spheres().bounds[l].is_some())?;
    let mut poses = vec![Pose::identity(); robot.links().len()];
    for fraction in [0.5, 0.4, 0.6, 0.3, 0.7] {
        let q = &states[(fraction * (states.len() - 1) as f64) as usize];
        robot.forward_kinematics(q, &mut poses);
        let c = poses[tip].translation.vector;
        if !in_view(env, camera, [c.x, c.y, c.z]) {
            continue;
        }
        let obstacle = Object {
            name: "unseen_box".into(),
            shape: Shape::cuboid([SIDE; 3]),
            pose: Pose::translation(c.x, c.y, c.z),
        };
        let mut truth = env.clone();
        truth.add(obstacle.clone()).ok()?;
        let mut exact = ExactChecker::new(robot, &truth);
        if exact.is_valid(start) && exact.is_valid(goal) {
            return Some((obstacle, truth));
        }
    }
    None
}

/// True when the camera at `camera` (optical frame: z forward) sees the point `c`: inside the
/// middle of its field of view, with no object in between.
fn in_view(env: &Environment, camera: &Pose, c: [f64; 3]) -> bool {
    let local = camera.inverse_transform_point(&nalgebra::Point3::from(c));
    if local.z <= 0.0 || (local.x / local.z).abs() > 0.45 || (local.y / local.z).abs() > 0.35 {
        return false;
    }
    let o = camera.translation.vector;
    let d = [c[0] - o.x, c[1] - o.y, c[2] - o.z];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let dir = d.map(|v| v / len);
    env.ray_cast([o.x, o.y, o.z], dir, len - SIDE).is_none()
}

/// How a returned path fares in the true world (the exact geometry).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Free at the planner's edge resolution and at the finer one.
    Free,
    /// Free at the planner's resolution, touching between its states (a graze the planner's
    /// discretisation cannot see, as in VAMP and OMPL).
    Grazes,
    /// Touching at the planner's own resolution: the plan is unsafe.
    Unsafe,
}

/// Checks `path` against `truth`: every edge at the planner's resolution, then finer.
pub fn judge(robot: &Robot, truth: &Environment, path: &[Vec<f64>]) -> Verdict {
    let mut exact = ExactChecker::new(robot, truth);
    let touches = |exact: &mut ExactChecker, resolution: f64| {
        path.windows(2)
            .any(|w| exact.motion_contact(&w[0], &w[1], resolution).is_some())
    };
    if touches(&mut exact, DEFAULT_RESOLUTION) {
        Verdict::Unsafe
    } else if touches(&mut exact, FINE_RESOLUTION) {
        Verdict::Grazes
    } else {
        Verdict::Free
    }
}

/// The path's states every `step` (configuration distance) along its edges.
fn dense(robot: &Robot, path: &[Vec<f64>], step: f64) -> Vec<Vec<f64>> {
    let mut out = vec![path[0].clone()];
    let mut q = vec![0.0; robot.dof()];
    for w in path.windows(2) {
        let n = (robot.distance(&w[0], &w[1]) / step).ceil().max(1.0) as usize;
        for k in 1..=n {
            robot.interpolate(&w[0], &w[1], k as f64 / n as f64, &mut q);
            out.push(q.clone());
        }
    }
    out
}
