//! What the `experience` and `paper` benchmarks share: sensed maps of problem scenes, training
//! SPARK and FLAME from solved problems, and planning a test set with one sampling method.
//!
//! Planning time includes retrieval (SPARK's primitive extraction and tree search, FLAME's
//! octobox extraction and lookups); the FLAME map itself is rendered from the test scene
//! beforehand, as the daemon keeps it up to date incrementally. A failure counts as the time
//! limit, as in the paper.

use ember_engine::experience::flame::octoboxes;
use ember_engine::experience::spark::spark_pairs;
use ember_engine::experience::{
    self as experience, Database, Experience, GlobalSampler, LocalSampler, Retrieval,
};
use ember_engine::planning::{self, PlanRequest, PlannerParams};
use ember_engine::problems::Problem;
use ember_engine::robot::Robot;
use ember_engine::scene::Scene;
use ember_engine::world::map::{MapParams, OccupancyMap};
use ember_engine::world::Environment;
use ember_sdk::stats::summary;
use ember_sensors::{quarter_vga, sensed_map};
use std::borrow::Cow;
use std::time::{Duration, Instant};

/// A sampling method under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Uniform sampling (the baseline).
    Uniform,
    /// SPARK: retrieval by the scene's box pairs.
    Spark,
    /// FLAME: retrieval by the sensed map's octoboxes.
    Flame,
    /// A diagnostic, not a method: the test problem's own stored solution as the only local
    /// sampler (its waypoints as components), the best experience any retrieval could give.
    Oracle,
}

impl Method {
    /// Every method, baseline first.
    pub const ALL: [Method; 3] = [Method::Uniform, Method::Spark, Method::Flame];

    /// Lower-case name, as in `RESULT` lines.
    pub fn name(self) -> &'static str {
        match self {
            Method::Uniform => "uniform",
            Method::Spark => "spark",
            Method::Flame => "flame",
            Method::Oracle => "oracle",
        }
    }
}

/// Where the sensed views look: the centre of the scene's objects other than the floor.
fn look_target(scene: &Scene) -> [f64; 3] {
    let pts: Vec<_> = scene
        .objects
        .iter()
        .filter(|o| o.name != "floor")
        .map(|o| o.pose.translation.vector)
        .collect();
    let n = pts.len().max(1) as f64;
    let c = pts.iter().fold(nalgebra::Vector3::zeros(), |a, p| a + p) / n;
    [c.x, c.y, c.z]
}

/// The scene as the head camera sees it (a few 320×240 views), as FLAME's input.
pub fn map_of(scene: &Scene) -> anyhow::Result<OccupancyMap> {
    Ok(sensed_map(
        &scene.environment()?,
        look_target(scene),
        &quarter_vga(),
        MapParams::default(),
    ))
}

/// Learns one solved problem into both databases (problems without a path are skipped).
pub fn train_one(
    robot: &Robot,
    problem: &Problem,
    interpolate: Option<f64>,
    experience: &mut Experience,
) -> anyhow::Result<()> {
    let Some(path) = &problem.path else {
        return Ok(());
    };
    let robot = problem
        .scene
        .robot_with(robot, &problem.request.start_joints)?;
    let map = map_of(&problem.scene)?;
    let boxes = octoboxes(&map);
    experience.learn(
        &robot,
        &problem.scene,
        Some((&map, &boxes)),
        path,
        interpolate,
    );
    Ok(())
}

/// A test problem with what planning it needs prepared once: its robot (carrying what the
/// scene attaches), environment and sensed map.
pub struct TestCase<'a> {
    /// The problem.
    pub problem: &'a Problem,
    /// The robot as the problem's scene has it.
    pub robot: Cow<'a, Robot>,
    /// Its scene as collision geometry.
    pub env: Environment,
    /// Its sensed map (FLAME's input).
    pub map: OccupancyMap,
}

/// Prepares test problems for [`plan_sets`].
pub fn prepare<'a>(robot: &'a Robot, problems: &'a [Problem]) -> anyhow::Result<Vec<TestCase<'a>>> {
    problems
        .iter()
        .map(|p| {
            Ok(TestCase {
                problem: p,
                robot: p.scene.robot_with(robot, &p.request.start_joints)?,
                env: p.scene.environment()?,
                map: map_of(&p.scene)?,
            })
        })
        .collect()
}

/// Planner settings of a benchmark run.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    /// Time limit per plan, seconds.
    pub time_limit: f64,
    /// Base seed (each problem uses seed + its index).
    pub seed: u64,
    /// RRT-Connect range.
    pub range: f64,
}

/// How one method did on one test set.
#[derive(Debug, Clone, Default)]
pub struct Outcome {
    /// Problems planned.
    pub n: usize,
    /// Problems solved within the time limit.
    pub solved: usize,
    /// Mean planning time including retrieval (a failure counts as the limit), ms.
    pub mean_ms: f64,
    /// Median of the same, ms.
    pub median_ms: f64,
    /// Mean retrieval time, µs.
    pub retrieval_us: f64,
    /// Mean database entries retrieved.
    pub entries: f64,
    /// Mean unique local samplers retrieved.
    pub samplers: f64,
}

impl Outcome {
    /// Header of [`Outcome::csv`] columns.
    pub const CSV_HEADER: &'static str =
        "n_test,solved,mean_ms,median_ms,retrieval_us,entries,samplers";

    /// The outcome as CSV columns (see [`Outcome::CSV_HEADER`]).
    pub fn csv(&self) -> String {
        format!(
            "{},{},{:.3},{:.3},{:.1},{:.1},{:.1}",
            self.n,
            self.solved,
            self.mean_ms,
            self.median_ms,
            self.retrieval_us,
            self.entries,
            self.samplers
        )
    }

    /// The `RESULT` keys after the problem count: `solved=… mean_ms=… median_ms=…
    /// retrieval_us=…`.
    pub fn result_keys(&self) -> String {
        format!(
            "solved={} mean_ms={:.3} median_ms={:.3} retrieval_us={:.1}",
            self.solved, self.mean_ms, self.median_ms, self.retrieval_us
        )
    }
}

/// The sampler for `case` with `method`: what `experience` retrieves for it (the scene's
/// primitives are extracted here, as part of the retrieval's time), or the oracle's.
fn sampler<'a>(
    method: Method,
    case: &'a TestCase,
    experience: &'a Experience,
) -> GlobalSampler<'a> {
    let m = match method {
        Method::Uniform => experience::Method::Uniform,
        Method::Spark => experience::Method::Spark,
        Method::Flame => experience::Method::Flame,
        Method::Oracle => {
            let path = case.problem.path.as_deref().unwrap_or_default();
            let r = Retrieval::from_samplers(vec![LocalSampler::from_means(path)]);
            let p = experience.spark.params();
            return GlobalSampler::new(r, p.sigma, p.lambda);
        }
    };
    let pairs = match m {
        experience::Method::Spark => spark_pairs(&case.problem.scene, experience.spark.params()),
        _ => Vec::new(),
    };
    let boxes = match m {
        experience::Method::Flame => octoboxes(&case.map),
        _ => Vec::new(),
    };
    experience.sampler_for(m, &pairs, &boxes)
}

/// One method to evaluate: the method and the experience it retrieves from.
pub type Run<'d> = (Method, &'d Experience);

/// Plans every case with each of `runs`, interleaved: each case is planned by every run in turn
/// before the next case, so a slow spell of a shared machine slows all of them alike and their
/// ratios stay fair. One outcome per run, in order.
pub fn plan_sets(cases: &[TestCase], runs: &[Run], options: &EvalOptions) -> Vec<Outcome> {
    let mut samples = vec![Samples::default(); runs.len()];
    for case in cases {
        for (&(method, experience), samples) in runs.iter().zip(&mut samples) {
            samples.plan(case, method, experience, options);
        }
    }
    samples
        .into_iter()
        .map(|s| s.outcome(cases.len()))
        .collect()
}

/// What one method's plans measured so far.
#[derive(Debug, Clone, Default)]
struct Samples {
    times: Vec<f64>,
    retrieval: Vec<f64>,
    entries: Vec<f64>,
    samplers: Vec<f64>,
    solved: usize,
}

impl Samples {
    /// Plans `case` with `method` and records the time (retrieval included).
    fn plan(
        &mut self,
        case: &TestCase,
        method: Method,
        experience: &Experience,
        options: &EvalOptions,
    ) {
        let t = Instant::now();
        let mut sampler = sampler(method, case, experience);
        self.entries.push(sampler.retrieved_entries() as f64);
        self.samplers.push(sampler.local_samplers() as f64);
        let retrieval_s = t.elapsed().as_secs_f64();
        let p = case.problem;
        let req = PlanRequest {
            start: p.request.start.clone(),
            goal: p.request.goal.clone(),
            params: PlannerParams {
                seed: options.seed + p.index as u64,
                time_limit: Duration::from_secs_f64(options.time_limit),
                simplify: false,
                range: options.range,
                ..Default::default()
            },
        };
        match planning::plan(&case.robot, &case.env, &req, &mut sampler) {
            Ok(_) => {
                self.solved += 1;
                self.times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            Err(e) => {
                // Which problems fail, and how, is worth seeing beside the means.
                eprintln!("{method:?}: problem {:04} not solved: {e}", p.index);
                self.times.push((options.time_limit + retrieval_s) * 1e3)
            }
        }
        self.retrieval.push(retrieval_s * 1e6);
    }

    /// The outcome over the `n` cases planned.
    fn outcome(mut self, n: usize) -> Outcome {
        let (median_ms, mean_ms, _) = summary(&mut self.times);
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        Outcome {
            n,
            solved: self.solved,
            mean_ms,
            median_ms,
            retrieval_us: mean(&self.retrieval),
            entries: mean(&self.entries),
            samplers: mean(&self.samplers),
        }
    }
}
