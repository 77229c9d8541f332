//! `collision`: forward kinematics, sphere checks and exact checks (self + environment) per
//! configuration in the nominal small-shelf scene (10 objects), over random configurations;
//! and the time to build the sphere model: fitted, from the disk cache, from the process memo.
//!
//! Flags: the robot options (`--robot`, `--srdf`, ..., default the built-in Fetch), `--configs
//! N` configurations per batch (default 1000), `--batches N` (default 200; the exact checks get
//! a tenth). Prints per-call medians over batches; ends with `RESULT collision fk_ns=<median>
//! check_ns=<median> exact_ns=<median> spheres=<n> moving_spheres=<n> build_fit_ms=<f>
//! build_disk_ms=<f> build_memory_ms=<f> batch_ns=<f> free_ns=<f> edge_batch_ns=<f>
//! edge_scalar_ns=<f> states_per_edge=<f>`: the last five on collision-free work (the eight-lane
//! checker and the scalar one per free configuration, and per free edge of length 0.5 at the
//! planner's resolution).

use ember_engine::collision::exact::ExactChecker;
use ember_engine::collision::SphereChecker;
use ember_engine::planning::PlannerRng;
use ember_engine::problems;
use ember_engine::robot::spheres::cache::{self, SphereCache};
use ember_engine::robot::{RobotArgs, RobotSpec};
use ember_engine::Pose;
use ember_sdk::stats::summary;
use rand::SeedableRng;
use std::hint::black_box;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// The robot.
    #[command(flatten)]
    robot: RobotArgs,
    /// Configurations per timed batch.
    #[arg(long, default_value_t = 1000)]
    configs: usize,
    /// Timed batches (the median batch is reported).
    #[arg(long, default_value_t = 200)]
    batches: usize,
}

/// Milliseconds to load `spec` (each source of spheres forced in turn).
fn build_times(spec: &RobotSpec) -> anyhow::Result<(f64, f64, f64)> {
    let dir = std::env::temp_dir().join(format!("ember-bench-cache-{}", std::process::id()));
    let time = |spec: &RobotSpec| -> anyhow::Result<f64> {
        let t = Instant::now();
        spec.load()?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    };
    cache::clear_memory();
    let fit = time(&RobotSpec {
        sphere_cache: SphereCache::Dir(dir.clone()),
        ..spec.clone()
    })?;
    cache::clear_memory();
    let disk = time(&RobotSpec {
        sphere_cache: SphereCache::Dir(dir.clone()),
        ..spec.clone()
    })?;
    let memory = time(spec)?;
    std::fs::remove_dir_all(&dir).ok();
    Ok((fit, disk, memory))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot_spec = args.robot.spec("fetch");
    let (fit_ms, disk_ms, memory_ms) = build_times(&robot_spec)?;
    let robot = robot_spec.load()?;
    let spec = problems::dataset("shelf_zero").expect("built in");
    let scene = problems::sample_scene(
        &problems::DatasetSpec {
            world: problems::Variation {
                position: [0.0; 3],
                yaw: 0.0,
            },
            object_variations: vec![],
            ..spec
        },
        &mut PlannerRng::seed_from_u64(0),
    );
    let env = scene.environment()?;
    let mut rng = PlannerRng::seed_from_u64(1);
    let configs: Vec<Vec<f64>> = (0..args.configs)
        .map(|_| {
            let mut q = vec![0.0; robot.dof()];
            robot.sample_uniform(&mut rng, &mut q);
            q
        })
        .collect();

    let mut poses = vec![Pose::identity(); robot.links().len()];
    let mut fk = Vec::with_capacity(args.batches);
    for _ in 0..args.batches {
        let t = Instant::now();
        for q in &configs {
            robot.forward_kinematics(black_box(q), &mut poses);
            black_box(&poses);
        }
        fk.push(t.elapsed().as_secs_f64() * 1e9 / configs.len() as f64);
    }

    let mut checker = SphereChecker::new(&robot, &env);
    let valid = configs.iter().filter(|q| checker.is_valid(q)).count();
    let mut check = Vec::with_capacity(args.batches);
    for _ in 0..args.batches {
        let t = Instant::now();
        for q in &configs {
            black_box(checker.is_valid(black_box(q)));
        }
        check.push(t.elapsed().as_secs_f64() * 1e9 / configs.len() as f64);
    }
    let lanes = lane_figures(&robot, &env, &configs, &mut checker, args.batches);
    let mut exact_checker = ExactChecker::new(&robot, &env);
    let exact_valid = configs.iter().filter(|q| exact_checker.is_valid(q)).count();
    let mut exact = Vec::with_capacity(args.batches / 10 + 1);
    for _ in 0..args.batches / 10 + 1 {
        let t = Instant::now();
        for q in &configs {
            black_box(exact_checker.is_valid(black_box(q)));
        }
        exact.push(t.elapsed().as_secs_f64() * 1e9 / configs.len() as f64);
    }
    let moving: usize = (0..robot.links().len())
        .filter(|&l| robot.link_moves(l))
        .map(|l| robot.spheres().ranges[l].len())
        .sum();
    let (fk_med, fk_mean, fk_p95) = summary(&mut fk);
    let (ck_med, ck_mean, ck_p95) = summary(&mut check);
    let (ex_med, ex_mean, ex_p95) = summary(&mut exact);
    println!(
        "{} ({}), {} objects, {} spheres ({moving} on moving links), {} self-collision pairs; {} random configurations ({:.0}% valid for the spheres, {:.0}% exactly)",
        robot.name(),
        robot_spec.robot,
        env.objects().len(),
        robot.spheres().len(),
        robot.self_collision_pairs().len(),
        configs.len(),
        100.0 * valid as f64 / configs.len() as f64,
        100.0 * exact_valid as f64 / configs.len() as f64
    );
    println!(
        "{:<28} {:>10} {:>10} {:>10}",
        "per call (ns)", "median", "mean", "p95"
    );
    println!(
        "{:<28} {:>10.1} {:>10.1} {:>10.1}",
        "forward kinematics", fk_med, fk_mean, fk_p95
    );
    println!(
        "{:<28} {:>10.1} {:>10.1} {:>10.1}",
        "full check (self + env)", ck_med, ck_mean, ck_p95
    );
    println!(
        "{:<28} {:>10.1} {:>10.1} {:>10.1}",
        "exact check (parry3d)", ex_med, ex_mean, ex_p95
    );
    println!(
        "{:<28} {:>10.1}   (free configurations: scalar {:.1})",
        "eight lanes, per config", lanes.batch_ns, lanes.free_ns
    );
    println!(
        "{:<28} {:>10.1}   (scalar {:.1}; {:.1} states per edge, eight-lane {:.1} / scalar {:.1} ns per state)",
        "free edge, eight lanes",
        lanes.edge_batch_ns,
        lanes.edge_scalar_ns,
        lanes.states_per_edge,
        lanes.edge_batch_ns / lanes.states_per_edge,
        lanes.edge_scalar_ns / lanes.states_per_edge
    );
    println!(
        "sphere model: fitted in {fit_ms:.1} ms, read from the disk cache in {disk_ms:.1} ms, from the process memo in {memory_ms:.1} ms (whole robot load)"
    );
    println!(
        "RESULT collision fk_ns={fk_med:.1} check_ns={ck_med:.1} exact_ns={ex_med:.1} spheres={} moving_spheres={moving} build_fit_ms={fit_ms:.1} build_disk_ms={disk_ms:.1} build_memory_ms={memory_ms:.1} batch_ns={:.1} free_ns={:.1} edge_batch_ns={:.1} edge_scalar_ns={:.1} states_per_edge={:.1}",
        robot.spheres().len(),
        lanes.batch_ns,
        lanes.free_ns,
        lanes.edge_batch_ns,
        lanes.edge_scalar_ns,
        lanes.states_per_edge
    );
    Ok(())
}

/// Eight-lane figures on collision-free work (every state must be checked, so nothing exits
/// early): per configuration, and per edge of the planner's range (0.5) at its resolution.
struct LaneFigures {
    batch_ns: f64,
    free_ns: f64,
    edge_batch_ns: f64,
    edge_scalar_ns: f64,
    states_per_edge: f64,
}

impl LaneFigures {
    /// Nothing measured.
    fn none() -> Self {
        LaneFigures {
            batch_ns: f64::NAN,
            free_ns: f64::NAN,
            edge_batch_ns: f64::NAN,
            edge_scalar_ns: f64::NAN,
            states_per_edge: f64::NAN,
        }
    }
}

fn lane_figures(
    robot: &ember_engine::robot::Robot,
    env: &ember_engine::world::Environment,
    configs: &[Vec<f64>],
    scalar: &mut SphereChecker<'_>,
    batches: usize,
) -> LaneFigures {
    use ember_engine::collision::batch::{lanes::F8, BatchChecker};
    use ember_engine::collision::checker::{motion_steps, DEFAULT_RESOLUTION};
    let dof = robot.dof();
    let mut batch = BatchChecker::new(robot, env);
    let free: Vec<&Vec<f64>> = configs.iter().filter(|q| scalar.is_valid(q)).collect();
    let groups: Vec<Vec<F8>> = free
        .chunks_exact(8)
        .map(|g| {
            (0..dof)
                .map(|j| F8(std::array::from_fn(|k| g[k][j] as f32)))
                .collect()
        })
        .collect();
    let n_free = groups.len() * 8;
    if n_free == 0 {
        // Nothing free in this scene for this robot (its base in the shelf): nothing to time.
        return LaneFigures::none();
    }
    let time = |f: &mut dyn FnMut()| -> f64 {
        let mut v: Vec<f64> = (0..batches.max(1))
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e9
            })
            .collect();
        summary(&mut v).0
    };
    let batch_ns = time(&mut || {
        for g in &groups {
            black_box(batch.may_collide(black_box(g)));
        }
    }) / n_free.max(1) as f64;
    let free_ns = time(&mut || {
        for q in &free[..n_free] {
            black_box(scalar.is_valid(black_box(q)));
        }
    }) / n_free.max(1) as f64;
    // Free edges of length 0.5 from free configurations towards others.
    let mut edges = Vec::new();
    let mut b = vec![0.0; dof];
    for w in free.windows(2) {
        let d = robot.distance(w[0], w[1]);
        robot.interpolate(w[0], w[1], (0.5 / d).min(1.0), &mut b);
        if scalar.is_valid(&b) && scalar.motion_valid(w[0], &b) {
            edges.push((w[0].clone(), b.clone()));
        }
    }
    let states: usize = edges
        .iter()
        .map(|(a, b)| motion_steps(robot, a, b, DEFAULT_RESOLUTION).saturating_sub(1))
        .sum();
    if edges.is_empty() {
        return LaneFigures {
            batch_ns,
            free_ns,
            ..LaneFigures::none()
        };
    }
    let n_edges = edges.len() as f64;
    let edge_batch_ns = time(&mut || {
        for (a, b) in &edges {
            black_box(batch.motion_may_collide(robot, DEFAULT_RESOLUTION, (a, b), false));
        }
    }) / n_edges;
    let edge_scalar_ns = time(&mut || {
        for (a, b) in &edges {
            black_box(scalar.motion_valid(a, b));
        }
    }) / n_edges;
    LaneFigures {
        batch_ns,
        free_ns,
        edge_batch_ns,
        edge_scalar_ns,
        states_per_edge: states as f64 / n_edges,
    }
}
