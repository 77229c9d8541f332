//! Problem sets for the paper's experiments: sampling scene variations, goals by inverse
//! kinematics, keeping only solvable problems, and MoveIt-style YAML folders that other tools
//! read (`config.yaml`, `sceneNNNN.yaml`, `requestNNNN.yaml`, `pathNNNN.yaml`).

pub mod datasets;

pub use datasets::{dataset, DatasetSpec, Variation, DATASETS};

use crate::collision::exact::ExactChecker;
use crate::planning::{self, ik, Goal, PlannerParams, PlannerRng, PoseGoal, UniformSampler};
use crate::robot::Robot;
use crate::scene::moveit::{self, MotionRequest};
use crate::scene::{read_text, write_text, AttachedObject, Scene, SceneError};
use crate::world::{Environment, Object};
use crate::Pose;
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::Duration;
use thiserror::Error;

/// A problem set that cannot be read or written.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ProblemError {
    /// A scene, request or path file is unusable.
    #[error(transparent)]
    File(#[from] SceneError),
    /// The folder holds no `sceneNNNN.yaml` + `requestNNNN.yaml` pair.
    #[error("{0}: no problems (expected sceneNNNN.yaml and requestNNNN.yaml files)")]
    Empty(String),
    /// The dataset name is unknown.
    #[error("unknown dataset '{0}' (known: {known})", known = DATASETS.join(", "))]
    UnknownDataset(String),
    /// The dataset defines no place task.
    #[error("dataset '{0}' has no place task")]
    NoPlaceTask(String),
    /// The robot has no named start state for this dataset.
    #[error("robot has no named state '{0}' to start from")]
    NoStartState(String),
}

/// One planning problem: scene, request and (when known) a solution path.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// Index in the set (the `NNNN` of the file names).
    pub index: usize,
    /// The scene.
    pub scene: Scene,
    /// The request.
    pub request: MotionRequest,
    /// A known solution.
    pub path: Option<Vec<Vec<f64>>>,
}

/// A folder of problems.
#[derive(Debug, Clone, PartialEq)]
pub struct ProblemSet {
    /// Folder name.
    pub name: String,
    /// Robot named in `config.yaml` (Ember's `robot` key), if any.
    pub robot: Option<String>,
    /// Problems in index order.
    pub problems: Vec<Problem>,
}

fn index_of(file: &str, prefix: &str) -> Option<usize> {
    file.strip_prefix(prefix)?
        .strip_suffix(".yaml")?
        .parse()
        .ok()
}

impl ProblemSet {
    /// The robot named in `dir/config.yaml`, if any.
    pub fn robot_of(dir: &Path) -> Option<String> {
        let text = std::fs::read_to_string(dir.join("config.yaml")).ok()?;
        let v: serde_yaml_ng::Value = serde_yaml_ng::from_str(&text).ok()?;
        v.get("robot")?.as_str().map(str::to_string)
    }

    /// Reads every `sceneNNNN.yaml` / `requestNNNN.yaml` (and `pathNNNN.yaml`) in `dir`.
    pub fn load(dir: impl AsRef<Path>, robot: &Robot) -> Result<ProblemSet, ProblemError> {
        let dir = dir.as_ref();
        let entries = std::fs::read_dir(dir).map_err(|e| SceneError::Io {
            path: dir.display().to_string(),
            message: e.to_string(),
        })?;
        let mut indices: Vec<(usize, String)> = entries
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().to_string();
                index_of(&name, "scene").map(|i| (i, name))
            })
            .collect();
        indices.sort();
        let mut problems = Vec::new();
        for (index, scene_file) in indices {
            let digits = scene_file.len() - "scene".len() - ".yaml".len();
            let request_path = dir.join(format!("request{index:0digits$}.yaml"));
            if !request_path.exists() {
                continue;
            }
            let scene = Scene::load(dir.join(&scene_file))?;
            let request = moveit::request_from_yaml(
                &read_text(&request_path)?,
                &request_path.display().to_string(),
                robot,
            )?;
            let path_path = dir.join(format!("path{index:0digits$}.yaml"));
            let path = if path_path.exists() {
                Some(moveit::path_from_yaml(
                    &read_text(&path_path)?,
                    &path_path.display().to_string(),
                    robot,
                )?)
            } else {
                None
            };
            problems.push(Problem {
                index,
                scene,
                request,
                path,
            });
        }
        if problems.is_empty() {
            return Err(ProblemError::Empty(dir.display().to_string()));
        }
        Ok(ProblemSet {
            name: dir
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default(),
            robot: Self::robot_of(dir),
            problems,
        })
    }
}

/// Uniform in `[-b, b]` (0 when `b` is 0).
fn sym(rng: &mut PlannerRng, b: f64) -> f64 {
    if b > 0.0 {
        rng.random_range(-b..=b)
    } else {
        0.0
    }
}

fn variation_transform(rng: &mut PlannerRng, v: &Variation) -> Pose {
    Pose::from_parts(
        Translation3::new(
            sym(rng, v.position[0]),
            sym(rng, v.position[1]),
            sym(rng, v.position[2]),
        ),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), sym(rng, v.yaw)),
    )
}

/// One random scene of the dataset.
pub fn sample_scene(spec: &DatasetSpec, rng: &mut PlannerRng) -> Scene {
    sample_scene_and_world(spec, rng).0
}

/// One random scene of the dataset, and the world variation that moved it.
fn sample_scene_and_world(spec: &DatasetSpec, rng: &mut PlannerRng) -> (Scene, Pose) {
    let world = variation_transform(rng, &spec.world);
    let mut objects: Vec<Object> = spec
        .objects
        .iter()
        .map(|(name, shape, pose)| Object {
            name: name.clone(),
            shape: *shape,
            pose: if spec.fixed.contains(name) {
                *pose
            } else {
                world * pose
            },
        })
        .collect();
    for (names, v) in &spec.object_variations {
        for name in names {
            let local = variation_transform(rng, v);
            if let Some(o) = objects.iter_mut().find(|o| &o.name == name) {
                o.pose *= local;
            }
        }
    }
    let scene = Scene {
        name: spec.name.to_string(),
        objects,
        attached: Vec::new(),
    };
    (scene, world)
}

/// A collision-free goal configuration reaching a random target of `scene` as `spec` defines
/// it (goal pose jittered within the dataset's tolerances), or `None` when IK finds none.
pub fn sample_goal(
    robot: &Robot,
    spec: &DatasetSpec,
    scene: &Scene,
    env: &crate::world::Environment,
    rng: &mut PlannerRng,
) -> Option<Vec<f64>> {
    let target = &spec.targets[rng.random_range(0..spec.targets.len())];
    let target_pose = scene.objects.iter().find(|o| &o.name == target)?.pose;
    let (pt, ot) = spec.goal_tolerance;
    let jitter = Pose::from_parts(
        Translation3::new(sym(rng, pt), sym(rng, pt), sym(rng, pt)),
        UnitQuaternion::from_euler_angles(sym(rng, ot), sym(rng, ot), sym(rng, ot)),
    );
    tip_ik(robot, env, target_pose * spec.goal_offset * jitter, rng)
}

/// A collision-free configuration putting the tip at `pose`, or `None` when IK finds none.
fn tip_ik(
    robot: &Robot,
    env: &crate::world::Environment,
    pose: Pose,
    rng: &mut PlannerRng,
) -> Option<Vec<f64>> {
    let pose_goal = PoseGoal {
        link: None,
        pose,
        position_tolerance: 0.002,
        orientation_tolerance: 0.01,
    };
    let ik_params = ik::IkParams {
        solutions: 1,
        ..Default::default()
    };
    // Decided on the exact geometry, as the planner decides goals: a grasp leaves the fingers
    // closer to the can than the spheres' protrusion.
    let mut checker = ExactChecker::new(robot, env);
    ik::solve(&mut checker, &pose_goal, None, &ik_params, rng)
        .ok()?
        .into_iter()
        .next()
}

/// What the robot holds in a place problem: `spec`'s first target object where a pick grasps
/// it (the tip at the dataset's goal offset from the object), attached to the tip link.
pub fn held_object(robot: &Robot, spec: &DatasetSpec) -> Result<AttachedObject, ProblemError> {
    let no_place = || ProblemError::NoPlaceTask(spec.name.to_string());
    spec.place.ok_or_else(no_place)?;
    let target = spec.targets.first().ok_or_else(no_place)?;
    let (_, shape, _) = spec
        .objects
        .iter()
        .find(|(n, ..)| n == target)
        .ok_or_else(no_place)?;
    Ok(AttachedObject {
        link: robot.links()[robot.tip()].name.clone(),
        object: Object {
            name: format!("held_{target}"),
            shape: *shape,
            pose: spec.goal_offset.inverse(),
        },
    })
}

/// A place task as a client poses it.
pub struct PlaceTask {
    /// The scene, without the held object.
    pub scene: Scene,
    /// The object (`spec`'s first target) as the tip holds it.
    pub held: AttachedObject,
    /// Where the robot holds it: the grasp where it stood.
    pub start: Vec<f64>,
    /// Where it puts it down.
    pub goal: Vec<f64>,
}

/// A sampled place task, its ends collision-free for the robot holding the object; None when
/// IK found no ends in the scene drawn.
pub fn sample_place(
    robot: &Robot,
    spec: &DatasetSpec,
    rng: &mut PlannerRng,
) -> Result<Option<PlaceTask>, ProblemError> {
    let held = held_object(robot, spec)?;
    let o = &held.object;
    let holding = robot.with_attached(robot.tip(), &o.name, o.shape, o.pose);
    let (scene, _, ends) = place_candidate(&holding, spec, rng);
    Ok(ends.map(|(start, goal)| PlaceTask {
        scene,
        held,
        start,
        goal,
    }))
}

/// A place candidate: a sampled scene without the held object, and collision-free ends for
/// `holding` (the robot with [`held_object`] attached): the grasp where the object stood, and
/// the dataset's place pose. Both ends hold the object a little above its support: resting on it
/// would count as a collision of the robot's (padded) geometry.
fn place_candidate(holding: &Robot, spec: &DatasetSpec, rng: &mut PlannerRng) -> Candidate {
    let (place, place_variation) = spec.place.expect("checked by held_object");
    let (mut scene, world) = sample_scene_and_world(spec, rng);
    let target = &spec.targets[0];
    let held = scene.objects.iter().position(|o| &o.name == target);
    let held = scene.objects.remove(held.expect("checked by held_object"));
    let goal_pose = world * place * variation_transform(rng, &place_variation);
    let env = scene.environment().expect("generated scenes are valid");
    let lift = Pose::translation(0.0, 0.0, HOLD_LIFT);
    let ends = tip_ik(holding, &env, lift * held.pose * spec.goal_offset, rng).and_then(|s| {
        tip_ik(holding, &env, lift * goal_pose * spec.goal_offset, rng).map(|g| (s, g))
    });
    (scene, env, ends)
}

/// A sampled scene, its environment and, when IK found collision-free ends, (start, goal).
type Candidate = (Scene, Environment, Option<(Vec<f64>, Vec<f64>)>);

/// The candidate loop shared by the generators: `candidate` samples a scene and, when IK
/// finds collision-free ends, (start, goal); candidates the uniform planner solves in time go
/// to `keep(number from 1, scene, start, goal, path)` until `options.count` are kept.
fn solvable_candidates(
    robot: &Robot,
    options: &GenerateOptions,
    progress: &mut dyn FnMut(usize, usize),
    mut candidate: impl FnMut(&mut PlannerRng) -> Candidate,
    mut keep: impl FnMut(usize, Scene, Vec<f64>, Vec<f64>, Vec<Vec<f64>>) -> Result<(), SceneError>,
) -> Result<GenerateReport, ProblemError> {
    let mut rng = PlannerRng::seed_from_u64(options.seed);
    let mut report = GenerateReport {
        written: 0,
        attempts: 0,
        no_ik: 0,
        unsolved: 0,
    };
    while report.written < options.count
        && report.attempts < options.count * options.max_attempts_factor
    {
        report.attempts += 1;
        let (scene, env, ends) = candidate(&mut rng);
        let Some((start, goal)) = ends else {
            report.no_ik += 1;
            progress(report.written, report.attempts);
            continue;
        };
        let request = planning::PlanRequest {
            start: start.clone(),
            goal: Goal::Joints(vec![goal.clone()]),
            params: PlannerParams {
                time_limit: options.solve_time,
                max_iterations: CANDIDATE_ITERATIONS,
                seed: rng.random(),
                ..Default::default()
            },
        };
        match planning::plan(robot, &env, &request, &mut UniformSampler) {
            Ok(result) => {
                report.written += 1;
                keep(report.written, scene, start, goal, result.path)?;
            }
            Err(_) => report.unsolved += 1,
        }
        progress(report.written, report.attempts);
    }
    Ok(report)
}

/// Height above its support at which a place problem holds the object, metres.
pub const HOLD_LIFT: f64 = 0.03;

/// The two tasks a dataset's problems can pose.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Task {
    /// From the start state to a grasp of a target object.
    #[default]
    Pick,
    /// Holding the first target object from its grasp to the dataset's place pose.
    Place,
}

impl Task {
    /// Folder name of a dataset's set for this task: `<dataset>[_place][_test]`.
    pub fn set_name(self, dataset: &str, test: bool) -> String {
        let task = if self == Task::Place { "_place" } else { "" };
        let test = if test { "_test" } else { "" };
        format!("{dataset}{task}{test}")
    }

    /// Seed of that set from the base seed (pick training sets use the base seed itself).
    pub fn set_seed(self, seed: u64, test: bool) -> u64 {
        seed + (self == Task::Place) as u64 * PLACE_SEED_OFFSET + test as u64 * TEST_SEED_OFFSET
    }
}

/// Place sets are generated with the pick seed plus this offset (their scenes differ).
pub const PLACE_SEED_OFFSET: u64 = 1;

/// A dataset's test set lives beside its training set as `<name>_test`, generated with the
/// training seed plus this offset (so the two never share a scene).
pub const TEST_SEED_OFFSET: u64 = 1000;

/// Iterations a candidate's search may take (besides [`GenerateOptions::solve_time`]): a
/// candidate that needs more is a needle the sets are better without, and the cap keeps the
/// sets the same on every machine fast enough to reach it.
const CANDIDATE_ITERATIONS: u64 = 5_000_000;

/// Settings of [`generate`].
#[derive(Debug, Clone)]
pub struct GenerateOptions {
    /// Problems to keep.
    pub count: usize,
    /// Seed of the whole set.
    pub seed: u64,
    /// Time allowed to solve each candidate (unsolved candidates are dropped).
    pub solve_time: Duration,
    /// Give up after `count * max_attempts_factor` candidates.
    pub max_attempts_factor: usize,
    /// Pick or place problems.
    pub task: Task,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        GenerateOptions {
            count: 100,
            seed: 1,
            solve_time: Duration::from_secs(5),
            max_attempts_factor: 20,
            task: Task::Pick,
        }
    }
}

/// What [`generate`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GenerateReport {
    /// Problems written.
    pub written: usize,
    /// Candidates sampled.
    pub attempts: usize,
    /// Candidates dropped for lack of a collision-free IK solution.
    pub no_ik: usize,
    /// Candidates dropped because the planner did not solve them in time.
    pub unsolved: usize,
}

/// Samples problems of `spec` for `robot` until `count` solvable ones are written to `out`.
/// `progress(written, attempts)` is called after each candidate.
pub fn generate(
    robot: &Robot,
    spec: &DatasetSpec,
    options: &GenerateOptions,
    out: &Path,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<GenerateReport, ProblemError> {
    let start = robot
        .named_state(spec.start_state)
        .ok_or_else(|| ProblemError::NoStartState(spec.start_state.to_string()))?
        .to_vec();
    std::fs::create_dir_all(out).map_err(|e| SceneError::Io {
        path: out.display().to_string(),
        message: e.to_string(),
    })?;
    let width = 4.max(options.count.to_string().len());
    let held = match options.task {
        Task::Pick => None,
        Task::Place => Some(held_object(robot, spec)?),
    };
    let holding = match &held {
        Some(a) => Cow::Owned(robot.with_attached(
            robot.tip(),
            &a.object.name,
            a.object.shape,
            a.object.pose,
        )),
        None => Cow::Borrowed(robot),
    };
    let candidate = |rng: &mut PlannerRng| match &held {
        None => {
            let scene = sample_scene(spec, rng);
            let env = scene.environment().expect("generated scenes are valid");
            let goal = sample_goal(robot, spec, &scene, &env, rng);
            (scene, env, goal.map(|g| (start.clone(), g)))
        }
        Some(a) => {
            let (mut scene, env, ends) = place_candidate(&holding, spec, rng);
            scene.attached.push(a.clone());
            (scene, env, ends)
        }
    };
    let keep = |i: usize, scene: Scene, start: Vec<f64>, goal: Vec<f64>, path: Vec<Vec<f64>>| {
        let file = |kind: &str| -> PathBuf { out.join(format!("{kind}{i:0width$}.yaml")) };
        write_text(
            &file("scene"),
            &moveit::scene_to_yaml(&scene, robot, &start),
        )?;
        write_text(
            &file("request"),
            &moveit::request_to_yaml(robot, &start, &goal, 60.0),
        )?;
        write_text(&file("path"), &moveit::path_to_yaml(robot, &path))
    };
    let report = solvable_candidates(&holding, options, progress, candidate, keep)?;
    let config = format!(
        "# Written by Ember's problem generator.\nrobot: {}\nplanning_group: {}\ndataset: {}\ntask: {}\nsamples: {}\nseed: {}\n",
        robot.name(),
        robot.group_name(),
        spec.name,
        if options.task == Task::Place { "place" } else { "pick" },
        report.written,
        options.seed
    );
    write_text(&out.join("config.yaml"), &config)?;
    Ok(report)
}
