//! Motion planning: requests, outcomes, and the planner pipeline.
//!
//! - [`sampler`]: the `Sampler` plug-in point and uniform sampling, from the planner's random
//!   numbers ([`PlannerRng`]);
//! - [`rrt_connect`]: bidirectional RRT over the planning group;
//! - [`simplify`]: redundant-vertex removal and corner cutting;
//! - [`nearest`]: nearest-neighbour index over tree nodes;
//! - [`ik`]: damped-least-squares inverse kinematics with restarts, collision-aware;
//! - [`validity`]: the sphere model with an exact fallback near terminal states.
//!
//! [`plan`] runs the whole pipeline: decide start and goal on the exact geometry, solve IK for
//! pose goals, search and simplify on the sphere model, validate the path on the exact geometry
//! (the states the sphere lanes cannot clear decided by the exact checker).

pub mod certify;
pub mod ik;
pub mod nearest;
mod retreat;
mod rng;
pub mod rrt_connect;
pub mod sampler;
pub mod simplify;
mod timing;
pub mod validity;

pub use ik::IkParams;
pub use sampler::{PlannerRng, Sampler, UniformSampler};

use crate::collision::checker::{Contact, DEFAULT_RESOLUTION};
use crate::collision::exact::ExactChecker;
use crate::robot::{ConfigError, Robot};
use crate::trajectory::{TimingParams, Trajectory, TrajectoryError};
use crate::world::Environment;
use crate::Pose;
use rand::SeedableRng;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use thiserror::Error;
use validity::Validity;

/// An end-effector pose goal.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseGoal {
    /// Link that must reach the pose; `None` means the robot's tip link.
    pub link: Option<String>,
    /// Target pose of the link, robot base frame.
    pub pose: Pose,
    /// Allowed position error, metres.
    pub position_tolerance: f64,
    /// Allowed rotation error, radians (infinite: position only).
    pub orientation_tolerance: f64,
}

/// What the plan must reach.
#[derive(Debug, Clone, PartialEq)]
pub enum Goal {
    /// Any one of these configurations.
    Joints(Vec<Vec<f64>>),
    /// A pose of a link, solved by inverse kinematics.
    Pose(PoseGoal),
}

/// Planner settings.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannerParams {
    /// Longest tree extension, configuration-space distance.
    pub range: f64,
    /// Edge-check resolution, configuration-space distance.
    pub resolution: f64,
    /// The returned path is validated on the exact geometry at `resolution` divided by this
    /// (at least 1): a hand's corner moves centimetres between two states the resolution
    /// apart and can graze an object between them on the approach to a grasp (see [`plan`]).
    pub validation_refine: f64,
    /// Certify the returned path between its validated states too: clear all the way, not
    /// only at the states a resolution apart (see [`certify`]).
    pub certify: bool,
    /// Wall-clock limit for the search.
    pub time_limit: Duration,
    /// Iteration limit for the search: none by default, so that the time limit ends it (a
    /// search stuck at a goal in a narrow shelf rejects most samples and runs tens of millions
    /// of iterations a second; the 5M cap it had gave up on MotionBenchMaker problems it solves
    /// in 0.2–3.2 s). Set one to end a search at the same point on every machine.
    pub max_iterations: u64,
    /// Seed of every random choice: same inputs and seed, same path.
    pub seed: u64,
    /// Shortcut and prune the path after the search.
    pub simplify: bool,
    /// Inverse kinematics settings for pose goals.
    pub ik: IkParams,
    /// Dynamic-domain sampling (`None`: plain RRT-Connect).
    pub dynamic_domain: Option<rrt_connect::DynamicDomain>,
    /// Within this configuration-space distance of a start or goal that is free in the exact
    /// geometry but touched by the spheres, the exact checker decides.
    pub exact_radius: f64,
    /// Time the returned path under the robot's joint limits (`None`: the path only).
    pub timing: Option<TimingParams>,
    /// Set from elsewhere to stop the search (it ends with [`PlanError::Cancelled`]).
    pub cancel: Cancel,
}

/// A flag another thread sets to cancel plans in flight; the search looks at it as often as at
/// its clock. The default is never set.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Option<Arc<AtomicBool>>);

impl Cancel {
    /// A token that reads `flag`.
    pub fn new(flag: Arc<AtomicBool>) -> Self {
        Cancel(Some(flag))
    }

    /// True once the flag is set.
    #[inline]
    pub fn is_set(&self) -> bool {
        self.0.as_ref().is_some_and(|f| f.load(Ordering::Relaxed))
    }
}

impl PartialEq for Cancel {
    /// Tokens are equal when they read the same flag (or none).
    fn eq(&self, other: &Cancel) -> bool {
        match (&self.0, &other.0) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        }
    }
}

impl Default for PlannerParams {
    fn default() -> Self {
        PlannerParams {
            range: 1.0,
            resolution: DEFAULT_RESOLUTION,
            validation_refine: 1.0,
            certify: false,
            time_limit: Duration::from_secs(10),
            max_iterations: u64::MAX,
            seed: 0,
            simplify: true,
            ik: IkParams::default(),
            exact_radius: 0.75,
            dynamic_domain: Some(rrt_connect::DynamicDomain::default()),
            timing: None,
            cancel: Cancel::default(),
        }
    }
}

/// A planning request.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanRequest {
    /// Start configuration (group order).
    pub start: Vec<f64>,
    /// Goal.
    pub goal: Goal,
    /// Settings.
    pub params: PlannerParams,
}

/// Why no plan was returned. Each case is distinct so callers can react (and the wire maps each
/// to its own status code).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PlanError {
    /// The start configuration is malformed or outside the limits.
    #[error("invalid start: {0}")]
    InvalidStart(ConfigError),
    /// The start configuration collides.
    #[error("start is in collision: {0}")]
    StartInCollision(Contact),
    /// A goal configuration is malformed or outside the limits.
    #[error("invalid goal: {0}")]
    InvalidGoal(ConfigError),
    /// Every goal configuration collides.
    #[error("goal is in collision: {0}")]
    GoalInCollision(Contact),
    /// The goal names a link the robot does not have.
    #[error("goal link '{0}' is not a link of the robot")]
    UnknownLink(String),
    /// Inverse kinematics found no collision-free configuration for the pose goal.
    #[error("pose goal unreachable: no collision-free IK solution within {attempts} attempts")]
    UnreachablePose {
        /// Restarts tried.
        attempts: usize,
    },
    /// The path failed the final validation on the exact geometry, also when searched again
    /// at the validation's resolution (the sphere model does not cover the geometry it was
    /// fitted to: a bug or a corrupt sphere cache).
    #[error("the path failed exact validation: {0}")]
    InvalidPath(Contact),
    /// The timing parameters are out of range.
    #[error("invalid timing: {0}")]
    InvalidTiming(TrajectoryError),
    /// The search was cancelled (see [`Cancel`]).
    #[error("cancelled after {iterations} iterations")]
    Cancelled {
        /// Iterations run.
        iterations: u64,
    },
    /// The search ran out of time or iterations.
    #[error("no path found within {iterations} iterations and {elapsed_ms:.1} ms")]
    Timeout {
        /// Iterations run.
        iterations: u64,
        /// Time spent, milliseconds.
        elapsed_ms: f64,
    },
}

impl PlanError {
    /// A stable snake_case name for the outcome (command-line output and logs).
    pub fn kind(&self) -> &'static str {
        match self {
            PlanError::InvalidStart(_) => "invalid_start",
            PlanError::StartInCollision(_) => "start_in_collision",
            PlanError::InvalidGoal(_) => "invalid_goal",
            PlanError::GoalInCollision(_) => "goal_in_collision",
            PlanError::UnknownLink(_) => "unknown_link",
            PlanError::UnreachablePose { .. } => "unreachable_pose",
            PlanError::InvalidPath(_) => "invalid_path",
            PlanError::InvalidTiming(_) => "invalid_timing",
            PlanError::Timeout { .. } => "timeout",
            PlanError::Cancelled { .. } => "cancelled",
        }
    }
}

/// Counters and timings of one plan.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PlanStats {
    /// Search iterations.
    pub iterations: u64,
    /// Nodes in both trees at the end.
    pub tree_nodes: u64,
    /// Configurations checked (including edge states).
    pub config_checks: u64,
    /// Edges checked.
    pub motion_checks: u64,
    /// Batches of eight states checked in lanes.
    pub batches: u64,
    /// Of those, the batches a remembered contact ended.
    pub remembered_batches: u64,
    /// Time drawing samples, seconds.
    pub sample_s: f64,
    /// Time checking collisions during the search, seconds.
    pub check_s: f64,
    /// Time in nearest-neighbour queries during the search, seconds.
    pub neighbour_s: f64,
    /// Whole search time, seconds (sampling + checking + neighbours + the rest).
    pub search_s: f64,
    /// Inverse kinematics time, seconds.
    pub ik_s: f64,
    /// Simplification time, seconds.
    pub simplify_s: f64,
    /// Exact validation of start, goals and the returned path, seconds.
    pub validate_s: f64,
    /// Configurations the exact checker decided near anchors during the search.
    pub exact_fallbacks: u64,
    /// States the search added by retreating from stuck starts or goals (see
    /// [`rrt_connect`]'s module docs).
    pub retreat_states: u64,
    /// Extensions whose end states were screened together while the search was stuck.
    pub screened: u64,
    /// Of those, the ones the screen refused (a contact found) without a check of their own.
    pub screened_out: u64,
    /// Path length before simplification.
    pub length_before: f64,
    /// Path length after simplification.
    pub length_after: f64,
    /// Timing the path (blends checked on the exact geometry), seconds.
    pub timing_s: f64,
    /// The validation refused the path found at the planner's resolution and this one was
    /// searched again at the validation's, finer (see [`plan`]).
    pub refined: bool,
    /// Segments of the returned path (and of the fallbacks validated before it) that
    /// certification left uncertified, checked at 1/32 of its resolution instead (see
    /// [`certify`]).
    pub uncertified: u64,
}

impl PlanStats {
    /// Search time spent neither sampling, checking nor finding neighbours, seconds.
    pub fn other_s(&self) -> f64 {
        (self.search_s - self.sample_s - self.check_s - self.neighbour_s).max(0.0)
    }
}

/// A solved plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanResult {
    /// Waypoints from start to goal, group order; consecutive waypoints are joined by straight
    /// (shortest-way for continuous joints) motions checked at `params.resolution`.
    pub path: Vec<Vec<f64>>,
    /// Counters and timings.
    pub stats: PlanStats,
    /// The path timed under the robot's limits, when `params.timing` asked for it (`Err`: the
    /// robot's limits do not allow it, e.g. a joint without a velocity limit).
    pub trajectory: Option<Result<Trajectory, TrajectoryError>>,
}

/// Length of a path in configuration space.
pub fn path_length(robot: &Robot, path: &[Vec<f64>]) -> f64 {
    path.windows(2).map(|w| robot.distance(&w[0], &w[1])).sum()
}

/// Plans from the request's start to its goal in `env`, drawing samples from `sampler`.
///
/// ```
/// use ember_engine::planning::{plan, Goal, PlanRequest, PlannerParams, UniformSampler};
/// use ember_engine::{robot::Robot, world::Environment};
/// let fetch = Robot::builtin("fetch").unwrap();
/// let start = fetch.named_state("stow").unwrap().to_vec();
/// let goal = vec![0.2, 0.5, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0];
/// let req = PlanRequest { start, goal: Goal::Joints(vec![goal.clone()]), params: PlannerParams::default() };
/// let res = plan(&fetch, &Environment::new(), &req, &mut UniformSampler).unwrap();
/// assert_eq!(res.path.last().unwrap(), &goal);
/// ```
///
/// The returned path is validated on the exact geometry, its edges walked
/// `params.validation_refine` times finer than the search's resolution. Should that walk find
/// a contact the search's own checks passed between two of their states (a graze), the plan is
/// searched once more at the validation's resolution, within what is left of the time limit
/// (`stats.refined` is then set).
pub fn plan(
    robot: &Robot,
    env: &Environment,
    request: &PlanRequest,
    sampler: &mut dyn Sampler,
) -> Result<PlanResult, PlanError> {
    let t = Instant::now();
    match plan_once(robot, env, request, sampler) {
        Err(PlanError::InvalidPath(_))
            if request.params.validation_refine > 1.0 || request.params.certify =>
        {
            // Searched and validated at the first validation's resolution (a certified one
            // found a graze between the states: four times finer).
            let refine = match request.params.validation_refine {
                r if r > 1.0 => r,
                _ => CERTIFIED_RESEARCH,
            };
            let mut finer = request.clone();
            finer.params.resolution /= refine;
            finer.params.validation_refine = 1.0;
            finer.params.time_limit = finer.params.time_limit.saturating_sub(t.elapsed());
            let mut res = plan_once(robot, env, &finer, sampler)?;
            res.stats.refined = true;
            Ok(res)
        }
        other => other,
    }
}

/// How much finer [`plan`] searches again when a certified validation found a graze between
/// the states of both the simplified path and the search's own.
const CERTIFIED_RESEARCH: f64 = 4.0;

/// [`plan`] at the request's resolution.
fn plan_once(
    robot: &Robot,
    env: &Environment,
    request: &PlanRequest,
    sampler: &mut dyn Sampler,
) -> Result<PlanResult, PlanError> {
    let params = &request.params;
    if let Some(timing) = &params.timing {
        timing.validate().map_err(PlanError::InvalidTiming)?;
    }
    let mut checker = Validity::new(robot, env, params.resolution, params.exact_radius)
        .validating_at(params.resolution / params.validation_refine.max(1.0))
        .certifying(params.certify);
    let mut rng = PlannerRng::seed_from_u64(params.seed);
    let mut stats = PlanStats::default();
    robot
        .validate(&request.start)
        .map_err(PlanError::InvalidStart)?;
    let t = Instant::now();
    if let Some(c) = checker.state_contact(&request.start) {
        return Err(PlanError::StartInCollision(c));
    }
    checker.anchor_if_touched(&request.start);
    stats.validate_s = t.elapsed().as_secs_f64();
    let goals = match &request.goal {
        Goal::Joints(goals) => {
            let t = Instant::now();
            let mut free = Vec::new();
            let mut first_contact = None;
            for g in goals {
                robot.validate(g).map_err(PlanError::InvalidGoal)?;
                match checker.state_contact(g) {
                    None => {
                        checker.anchor_if_touched(g);
                        free.push(g.clone())
                    }
                    Some(c) => {
                        first_contact.get_or_insert(c);
                    }
                }
            }
            stats.validate_s += t.elapsed().as_secs_f64();
            if free.is_empty() {
                return Err(match first_contact {
                    Some(c) => PlanError::GoalInCollision(c),
                    None => PlanError::InvalidGoal(ConfigError::WrongLength {
                        expected: robot.dof(),
                        got: 0,
                    }),
                });
            }
            free
        }
        Goal::Pose(pg) => {
            let t = Instant::now();
            // IK solutions are decided on the exact geometry, like joint goals.
            let sols = ik::solve(
                checker.exact(),
                pg,
                Some(&request.start),
                &params.ik,
                &mut rng,
            )?;
            for q in &sols {
                checker.anchor_if_touched(q);
            }
            stats.ik_s = t.elapsed().as_secs_f64();
            if sols.is_empty() {
                return Err(PlanError::UnreachablePose {
                    attempts: params.ik.attempts,
                });
            }
            sols
        }
    };
    let (before, _) = checker.stats();
    let mut path = rrt_connect::search(
        &mut checker,
        &request.start,
        &goals,
        params,
        sampler,
        &mut rng,
        &mut stats,
    )?;
    stats.length_before = path_length(robot, &path);
    let raw = params.simplify.then(|| path.clone());
    if params.simplify {
        let t = Instant::now();
        simplify::simplify(&mut checker, &mut path);
        stats.simplify_s = t.elapsed().as_secs_f64();
    }
    let (after, fallbacks) = checker.stats();
    stats.config_checks = after.configs - before.configs;
    stats.motion_checks = after.motions - before.motions;
    stats.batches = after.batches - before.batches;
    stats.remembered_batches = after.remembered - before.remembered;
    stats.exact_fallbacks = fallbacks;
    // The returned path is validated on the exact geometry; should the simplified one fail,
    // the search's own path is the fallback.
    let t = Instant::now();
    let mut verdict = checker.path_contact(&path);
    if let (Some(_), Some(raw)) = (&verdict, raw) {
        if checker.path_contact(&raw).is_none() {
            path = raw;
            verdict = None;
        }
    }
    stats.validate_s += t.elapsed().as_secs_f64();
    stats.uncertified = checker.uncertified();
    if let Some(c) = verdict {
        return Err(PlanError::InvalidPath(c));
    }
    stats.length_after = path_length(robot, &path);
    let trajectory = params.timing.map(|timing| {
        let t = Instant::now();
        let out = timing::timed(&mut checker, &path, &timing, params.resolution);
        stats.timing_s = t.elapsed().as_secs_f64();
        out
    });
    Ok(PlanResult {
        path,
        stats,
        trajectory,
    })
}

/// The first contact along `path` in the exact geometry, waypoints and edges at `resolution`,
/// every state asked of the exact checker (what [`Validity::path_contact`] answers as).
pub(crate) fn exact_path_contact(
    exact: &mut ExactChecker<'_>,
    path: &[Vec<f64>],
    resolution: f64,
) -> Option<Contact> {
    if let [only] = path {
        return exact.contact(only);
    }
    path.windows(2)
        .find_map(|w| exact.motion_contact(&w[0], &w[1], resolution))
        .map(|(_, c)| c)
}

/// True when every waypoint and every edge of `path` is within the limits and collision free
/// in the exact geometry, edges checked at `resolution`.
pub fn path_is_valid(robot: &Robot, env: &Environment, path: &[Vec<f64>], resolution: f64) -> bool {
    let mut exact = ExactChecker::new(robot, env);
    path.iter().all(|q| robot.validate(q).is_ok())
        && exact_path_contact(&mut exact, path, resolution).is_none()
}
