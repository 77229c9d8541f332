//! `plan --problems DIR...`: the uniform planner over MoveIt-style problem folders.
//!
//! Flags: `--robot` (default: the folder's `config.yaml`, else fetch) with `--srdf`, `--group`,
//! `--package-path`, `--sphere-protrusion`; `--time-limit S` per problem (default 10),
//! `--seed N`, `--max-iterations N` (default none), `--no-simplify`, `--range R`, `--validation-refine K`. With `--clouds DIR` the obstacles are not the
//! scene's objects but the point cloud `DIR/<set>/cloudNNNN.pcd` (ASCII PCD, x y z in the base
//! frame, as the VAMP peer writes them), its points marked occupied in an occupancy map at
//! `--cloud-resolution` (default 0.01 m); problems without a cloud are skipped (VAMP found
//! them invalid). `--map-compare` (with `--clouds`) plans each problem three times on the same
//! scene: against its objects alone (map off), against the objects with the cloud's map (map on,
//! uncarved: as emberd plans with `planner.use_map` and `map.carve_objects = false`) and against
//! the cloud's map alone (below); the `RESULT plan` line is then the map-on run (key
//! `objects=1`), followed by `RESULT plan_map set= n= solved_off= solved_on= off_median_ms=
//! on_median_ms= ratio= off_check_ns_per_config= on_check_ns_per_config= off_median_iterations=
//! on_median_iterations= solved_voxels= voxels_median_ms= voxels_check_ns_per_config=
//! voxels_check_ratio= voxels_median_iterations=` (the check cost apart from how much harder the
//! voxels make a problem; the `voxels_` keys plan a third time against the cloud's map alone,
//! and `voxels_check_ratio` is its check cost over the objects': voxels against primitives for
//! the same obstacles). For each folder prints success, refusals and
//! planning-time statistics (planning = IK + search; simplification and the exact validation
//! reported apart) and ends with `RESULT plan set=<folder> n=<problems> solved=<count>
//! median_ms=<f> mean_ms=<f> p95_ms=<f> start_refused=<k> goal_refused=<k>
//! simplify_ms=<median> validate_ms=<median> total_median_ms=<median> median_iterations=
//! median_nodes= raw_length_median= length_median= solved_sum_ms= refined= uncertified=` (configuration-space path
//! length, the search's and the returned path's; the solved problems' planning times summed,
//! steadier than the median when two builds are compared) and the time split; a failure counts as the time limit in the mean, as in
//! the paper. `total_median_ms` is over the solved problems: planning, simplification and
//! validation, what a caller waits for. `--per-problem` also prints, as each problem ends,
//! `PROBLEM set= index= solved=1 ms= total_ms= search_ms= iterations= nodes= exact_fallbacks=
//! raw_length= length= waypoints= retreat_states= refined= uncertified=` (or
//! `solved=0 outcome=start_in_collision|goal_in_collision|timeout|failed`).

use ember_engine::planning::PlanError;
use ember_engine::planning::{self, PlanRequest, PlannerParams, UniformSampler};
use ember_engine::problems::ProblemSet;
use ember_engine::robot::{Robot, RobotArgs};
use ember_engine::scene::AttachedObject;
use ember_engine::world::map::{MapParams, OccupancyMap};
use ember_engine::world::Environment;
use ember_sdk::stats::summary;
use std::borrow::Cow;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct Args {
    /// Problem folders (sceneNNNN.yaml + requestNNNN.yaml each).
    #[arg(long, num_args = 1.., required = true)]
    problems: Vec<PathBuf>,
    /// The robot; default from the folder's config.yaml, else fetch.
    #[command(flatten)]
    robot: RobotArgs,
    /// Time limit per problem, seconds.
    #[arg(long, default_value_t = 10.0)]
    time_limit: f64,
    /// Planner seed (each problem uses seed + index).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// End each search after this many iterations too (default: none, the time limit ends
    /// it), at the same point on every machine.
    #[arg(long)]
    max_iterations: Option<u64>,
    /// Skip path simplification.
    #[arg(long)]
    no_simplify: bool,
    /// RRT-Connect range (longest extension); default: the planner's.
    #[arg(long)]
    range: Option<f64>,
    /// Validate returned paths this many times finer than the search checks edges.
    #[arg(long, default_value_t = 1.0)]
    validation_refine: f64,
    /// Certify returned paths between their validated states (the engine's `certify`).
    #[arg(long)]
    certify: bool,
    /// Plan against point clouds instead of the scenes' objects: `DIR/<set>/cloudNNNN.pcd`.
    #[arg(long)]
    clouds: Option<PathBuf>,
    /// Voxel size of the map built from each cloud, metres.
    #[arg(long, default_value_t = 0.01)]
    cloud_resolution: f64,
    /// With `--clouds`: plan each problem against the scene's objects alone (map off), against
    /// the objects with the cloud's map, uncarved (map on), and against the map alone.
    #[arg(long)]
    map_compare: bool,
    /// Also print one `PROBLEM` line per problem (time, iterations, nodes, exact fallbacks).
    #[arg(long)]
    per_problem: bool,
    /// Plan each problem once untimed before the timed plan (the same seed, so the same
    /// search): the caches then hold what that search reads, as for a daemon planning again
    /// against a map it holds; without it, the first plan after the map was built is timed.
    #[arg(long)]
    warm: bool,
    /// Write each solved problem's returned path to this file, one JSON object a line:
    /// `{"set", "index", "joints", "continuous", "path"}` (joint names in the path's order;
    /// the continuous ones, whose edges go the short way round), for checkers outside Ember
    /// (`bench/path_truth.py`).
    #[arg(long)]
    paths_out: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        !args.map_compare || args.clouds.is_some(),
        "--map-compare needs --clouds"
    );
    let mut results = Vec::new();
    println!(
        "{:<24} {:>4} {:>6} {:>6} {:>6} {:>10} {:>10} {:>10} {:>11} {:>11}",
        "set",
        "n",
        "solved",
        "start!",
        "goal!",
        "median_ms",
        "mean_ms",
        "p95_ms",
        "simplify_ms",
        "validate_ms"
    );
    let mut paths_out = match &args.paths_out {
        Some(f) => Some(std::io::BufWriter::new(
            std::fs::File::create(f)
                .map_err(|e| anyhow::anyhow!("--paths-out {}: {e}", f.display()))?,
        )),
        None => None,
    };
    let mut loaded: Option<(String, ember_engine::robot::Robot)> = None;
    for dir in &args.problems {
        let default = ProblemSet::robot_of(dir).unwrap_or_else(|| "fetch".into());
        let spec = args.robot.spec(&default);
        let robot = match loaded.take() {
            Some((name, r)) if name == spec.robot => r,
            _ => spec.load()?,
        };
        let set = ProblemSet::load(dir, &robot)?;
        // With --map-compare: the scene's objects alone, and with the cloud's map added.
        let fresh = || Tally {
            warm: args.warm,
            ..Tally::default()
        };
        let (mut tally, mut objects_only, mut voxels_only) = (fresh(), fresh(), fresh());
        let mut voxels = None;
        let mut map_ms = Vec::new();
        // The robot with the joints outside the group (fingers, head) as a problem's start
        // state sets them, kept while the next problem sets them alike: a daemon keeps its
        // robot between requests, and a copy derives its checkers' robot data on first use.
        let mut copy: Option<RobotCopy> = None;
        for p in &set.problems {
            let env = match &args.clouds {
                None => p.scene.environment()?,
                Some(dir) => {
                    let file = dir.join(&set.name).join(format!("cloud{:04}.pcd", p.index));
                    if !file.exists() {
                        continue;
                    }
                    let t = Instant::now();
                    let map = cloud_map(&file, args.cloud_resolution)?;
                    map_ms.push(t.elapsed().as_secs_f64() * 1e3);
                    let mut env = if args.map_compare {
                        voxels = Some(file);
                        p.scene.environment()?
                    } else {
                        Environment::new()
                    };
                    env.set_map(Some(map));
                    env
                }
            };
            // Only the joints outside the group shape the copy (the group's are the start).
            let joints: Vec<(String, f64)> = p
                .request
                .start_joints
                .iter()
                .filter(|(name, _)| !robot.variables().iter().any(|v| &v.name == name))
                .cloned()
                .collect();
            let attached = &p.scene.attached[..];
            let robot = match &copy {
                Some((j, a, r)) if *j == joints && *a == attached => r,
                _ => match p.scene.robot_with(&robot, &joints)? {
                    Cow::Borrowed(r) => r,
                    Cow::Owned(r) => &copy.insert((joints, attached, r)).2,
                },
            };
            let req = PlanRequest {
                start: p.request.start.clone(),
                goal: p.request.goal.clone(),
                params: PlannerParams {
                    seed: args.seed + p.index as u64,
                    time_limit: Duration::from_secs_f64(args.time_limit),
                    max_iterations: args
                        .max_iterations
                        .unwrap_or(PlannerParams::default().max_iterations),
                    simplify: !args.no_simplify,
                    range: args.range.unwrap_or(PlannerParams::default().range),
                    validation_refine: args.validation_refine,
                    certify: args.certify,
                    ..Default::default()
                },
            };
            if args.map_compare {
                objects_only.plan(robot, &p.scene.environment()?, &req, args.time_limit);
            }
            let (outcome, path) = tally.plan(robot, &env, &req, args.time_limit);
            if let (Some(out), Some(path)) = (&mut paths_out, path) {
                let vars = robot.variables();
                let joints: Vec<&str> = vars.iter().map(|v| &v.name[..]).collect();
                let wraps = vars.iter().filter(|v| v.continuous).map(|v| &v.name[..]);
                let line = serde_json::json!({
                    "set": set.name, "index": p.index, "joints": joints,
                    "continuous": wraps.collect::<Vec<_>>(), "path": path,
                });
                writeln!(out, "{line}")?;
            }
            // The map alone, built anew just before as for the other runs (not warmed by them).
            if let Some(file) = voxels.take() {
                let mut alone = Environment::new();
                alone.set_map(Some(cloud_map(&file, args.cloud_resolution)?));
                voxels_only.plan(robot, &alone, &req, args.time_limit);
            }
            if args.per_problem {
                println!("PROBLEM set={} index={} {outcome}", set.name, p.index);
            }
        }
        let cloud_keys = if args.clouds.is_some() {
            let (map_median, _, _) = summary(&mut map_ms);
            format!(
                " clouds=1 cloud_resolution={} map_build_ms={map_median:.3}{}",
                args.cloud_resolution,
                if args.map_compare { " objects=1" } else { "" }
            )
        } else {
            String::new()
        };
        let warm_key = if args.warm { " warm=1" } else { "" };
        results.push(tally.result(&set.name, &format!("{cloud_keys}{warm_key}")));
        if args.map_compare {
            let (off, _, _) = summary(&mut objects_only.times.clone());
            let (on, _, _) = summary(&mut tally.times.clone());
            let (alone, _, _) = summary(&mut voxels_only.times.clone());
            let (off_it, _, _) = summary(&mut objects_only.iterations.clone());
            let (on_it, _, _) = summary(&mut tally.iterations.clone());
            let (alone_it, _, _) = summary(&mut voxels_only.iterations.clone());
            let off_ns = objects_only.split.check_ns_per_config();
            let voxels_ns = voxels_only.split.check_ns_per_config();
            results.push(format!(
                "RESULT plan_map set={} n={} solved_off={} solved_on={} off_median_ms={off:.3} \
                 on_median_ms={on:.3} ratio={:.3} off_check_ns_per_config={off_ns:.1} \
                 on_check_ns_per_config={:.1} off_median_iterations={off_it:.0} \
                 on_median_iterations={on_it:.0} solved_voxels={} voxels_median_ms={alone:.3} \
                 voxels_check_ns_per_config={voxels_ns:.1} voxels_check_ratio={:.3} \
                 voxels_median_iterations={alone_it:.0}",
                set.name,
                tally.times.len(),
                objects_only.solved,
                tally.solved,
                on / off.max(1e-9),
                tally.split.check_ns_per_config(),
                voxels_only.solved,
                voxels_ns / off_ns.max(1e-9),
            ));
        }
        loaded = Some((spec.robot.clone(), robot));
    }
    if let Some(out) = &mut paths_out {
        out.flush()?;
    }
    for line in results {
        println!("{line}");
    }
    Ok(())
}

/// The outcomes of one set's problems.
#[derive(Default)]
struct Tally {
    /// Plan each request once untimed before timing it (`--warm`).
    warm: bool,
    times: Vec<f64>,
    /// Summed planning time of the solved problems, ms.
    solved_sum: f64,
    simplify: Vec<f64>,
    validate: Vec<f64>,
    /// Per solved problem: planning, simplification and validation, what a caller waits for.
    total: Vec<f64>,
    solved: usize,
    start_refused: usize,
    goal_refused: usize,
    split: Split,
    iterations: Vec<f64>,
    nodes: Vec<f64>,
    /// Per solved problem: the search's path length, and the returned path's.
    raw_length: Vec<f64>,
    length: Vec<f64>,
    /// Solved problems searched again at the validation's resolution.
    refined: usize,
    /// Segments certification left uncertified, over the solved problems.
    uncertified: u64,
}

impl Tally {
    /// Plans one request and counts the outcome (a failure as the time limit); returns the
    /// outcome as `--per-problem` prints it, and the path when solved.
    fn plan(
        &mut self,
        robot: &Robot,
        env: &Environment,
        req: &PlanRequest,
        time_limit: f64,
    ) -> (String, Option<Vec<Vec<f64>>>) {
        if self.warm {
            let _ = planning::plan(robot, env, req, &mut UniformSampler);
        }
        let t = Instant::now();
        match planning::plan(robot, env, req, &mut UniformSampler) {
            Ok(res) => {
                let total = t.elapsed().as_secs_f64();
                let ms = (total - res.stats.simplify_s - res.stats.validate_s) * 1e3;
                self.solved += 1;
                self.times.push(ms);
                self.solved_sum += ms;
                self.simplify.push(res.stats.simplify_s * 1e3);
                self.validate.push(res.stats.validate_s * 1e3);
                self.total.push(total * 1e3);
                self.split.add(&res.stats);
                self.iterations.push(res.stats.iterations as f64);
                self.nodes.push(res.stats.tree_nodes as f64);
                self.raw_length.push(res.stats.length_before);
                self.length.push(res.stats.length_after);
                self.refined += usize::from(res.stats.refined);
                self.uncertified += res.stats.uncertified;
                let line = format!(
                    "solved=1 ms={ms:.3} total_ms={:.3} search_ms={:.3} iterations={} nodes={} exact_fallbacks={} \
                     raw_length={:.4} length={:.4} waypoints={} retreat_states={} refined={} \
                     uncertified={}",
                    total * 1e3,
                    res.stats.search_s * 1e3,
                    res.stats.iterations,
                    res.stats.tree_nodes,
                    res.stats.exact_fallbacks,
                    res.stats.length_before,
                    res.stats.length_after,
                    res.path.len(),
                    res.stats.retreat_states,
                    u8::from(res.stats.refined),
                    res.stats.uncertified
                );
                (line, Some(res.path))
            }
            Err(e) => {
                let outcome = match e {
                    PlanError::StartInCollision(_) => {
                        self.start_refused += 1;
                        "start_in_collision"
                    }
                    PlanError::GoalInCollision(_) => {
                        self.goal_refused += 1;
                        "goal_in_collision"
                    }
                    PlanError::Timeout { .. } => "timeout",
                    _ => "failed",
                };
                self.times.push(time_limit * 1e3);
                (format!("solved=0 outcome={outcome}"), None)
            }
        }
    }

    /// Prints the set's row and returns its `RESULT plan` line.
    fn result(&self, set: &str, extra: &str) -> String {
        let n = self.times.len();
        let (median, mean, p95) = summary(&mut self.times.clone());
        let (simp, _, _) = summary(&mut self.simplify.clone());
        let (val, _, _) = summary(&mut self.validate.clone());
        let (total, _, _) = summary(&mut self.total.clone());
        let (median_iterations, _, _) = summary(&mut self.iterations.clone());
        let (median_nodes, _, _) = summary(&mut self.nodes.clone());
        let (raw_length, _, _) = summary(&mut self.raw_length.clone());
        let (length, _, _) = summary(&mut self.length.clone());
        let (solved, start_refused, goal_refused) =
            (self.solved, self.start_refused, self.goal_refused);
        println!(
            "{:<24} {:>4} {:>6} {:>6} {:>6} {:>10.3} {:>10.3} {:>10.3} {:>11.3} {:>11.3}",
            set, n, solved, start_refused, goal_refused, median, mean, p95, simp, val
        );
        format!(
            "RESULT plan set={set} n={n} solved={solved} median_ms={median:.3} mean_ms={mean:.3} \
             p95_ms={p95:.3} start_refused={start_refused} goal_refused={goal_refused} \
             simplify_ms={simp:.3} validate_ms={val:.3} total_median_ms={total:.3} \
             median_iterations={median_iterations:.0} median_nodes={median_nodes:.0} \
             raw_length_median={raw_length:.3} length_median={length:.3} \
             solved_sum_ms={:.3} refined={} uncertified={} {}{extra}",
            self.solved_sum,
            self.refined,
            self.uncertified,
            self.split.keys()
        )
    }
}

/// A robot copy and the start-state joints outside the group and the attached objects it was
/// derived with.
type RobotCopy<'p> = (Vec<(String, f64)>, &'p [AttachedObject], Robot);

/// The points of an ASCII PCD file (x y z first) as occupied voxels of a map, with its
/// clearance grid built (map building is not planning time).
fn cloud_map(file: &Path, resolution: f64) -> anyhow::Result<Arc<OccupancyMap>> {
    let text = std::fs::read_to_string(file)?;
    let mut map = OccupancyMap::new(MapParams {
        resolution,
        ..Default::default()
    });
    let mut in_data = false;
    for line in text.lines() {
        if !in_data {
            in_data = line.starts_with("DATA");
            anyhow::ensure!(
                !in_data || line.trim() == "DATA ascii",
                "{}: only ASCII PCD is read",
                file.display()
            );
            continue;
        }
        let mut v = line.split_whitespace().map(str::parse::<f64>);
        match (v.next(), v.next(), v.next()) {
            (Some(Ok(x)), Some(Ok(y)), Some(Ok(z))) => map.set_voxel(map.key_of([x, y, z]), true),
            _ => anyhow::bail!("{}: bad point line {line:?}", file.display()),
        }
    }
    map.clearance();
    Ok(Arc::new(map))
}

/// Where the search time of the solved problems went, summed over the set.
#[derive(Default)]
struct Split {
    search_s: f64,
    sample_s: f64,
    check_s: f64,
    neighbour_s: f64,
    configs: u64,
    motions: u64,
    iterations: u64,
    fallbacks: u64,
    batches: u64,
    remembered: u64,
    screened: u64,
    screened_out: u64,
    retreat_states: u64,
}

impl Split {
    fn add(&mut self, s: &ember_engine::planning::PlanStats) {
        self.search_s += s.search_s;
        self.sample_s += s.sample_s;
        self.check_s += s.check_s;
        self.neighbour_s += s.neighbour_s;
        self.configs += s.config_checks;
        self.motions += s.motion_checks;
        self.iterations += s.iterations;
        self.fallbacks += s.exact_fallbacks;
        self.batches += s.batches;
        self.remembered += s.remembered_batches;
        self.screened += s.screened;
        self.screened_out += s.screened_out;
        self.retreat_states += s.retreat_states;
    }

    /// Collision-checking time per configuration checked, ns.
    fn check_ns_per_config(&self) -> f64 {
        self.check_s * 1e9 / self.configs.max(1) as f64
    }

    /// `sample_pct check_pct neighbour_pct other_pct` of the search time, ns per checked
    /// configuration, configurations per iteration, exact fallbacks, the share of batches a
    /// remembered contact ended, and the extensions screened while searches were stuck and
    /// the share of them the screen refused.
    fn keys(&self) -> String {
        let pct = |x: f64| 100.0 * x / self.search_s.max(1e-12);
        let other = self.search_s - self.sample_s - self.check_s - self.neighbour_s;
        format!(
            "sample_pct={:.1} check_pct={:.1} neighbour_pct={:.1} other_pct={:.1} \
             check_ns_per_config={:.1} configs_per_iteration={:.1} exact_fallbacks={} \
             remembered_pct={:.1} screened={} screened_out_pct={:.1} retreat_states={}",
            pct(self.sample_s),
            pct(self.check_s),
            pct(self.neighbour_s),
            pct(other.max(0.0)),
            self.check_ns_per_config(),
            self.configs as f64 / self.iterations.max(1) as f64,
            self.fallbacks,
            100.0 * self.remembered as f64 / self.batches.max(1) as f64,
            self.screened,
            100.0 * self.screened_out as f64 / self.screened.max(1) as f64,
            self.retreat_states
        )
    }
}
