//! `collision`: forward kinematics, sphere checks and exact checks (self + environment) per
//! configuration in the nominal small-shelf scene (10 objects), over random configurations;
//! and the time to build the sphere model: fitted, from the disk cache, from the process memo.
//!
//! Flags: the robot options (`--robot`, `--srdf`, ..., default the built-in Fetch), `--configs
//! N` configurations per batch (default 1000), `--batches N` (default 200; the exact checks get
//! a tenth). Prints per-call medians over batches; ends with `RESULT collision fk_ns=<median>
//! check_ns=<median> exact_ns=<median> spheres=<n> moving_spheres=<n> build_fit_ms=<f>
//! build_disk_ms=<f> build_memory_ms=<f>`.

use crate::stats::summary;
use ember_engine::collision::exact::ExactChecker;
use ember_engine::collision::SphereChecker;
use ember_engine::planning::PlannerRng;
use ember_engine::problems;
use ember_engine::robot::spheres::cache::{self, SphereCache};
use ember_engine::robot::{RobotArgs, RobotSpec};
use ember_engine::Pose;
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
        "sphere model: fitted in {fit_ms:.1} ms, read from the disk cache in {disk_ms:.1} ms, from the process memo in {memory_ms:.1} ms (whole robot load)"
    );
    println!(
        "RESULT collision fk_ns={fk_med:.1} check_ns={ck_med:.1} exact_ns={ex_med:.1} spheres={} moving_spheres={moving} build_fit_ms={fit_ms:.1} build_disk_ms={disk_ms:.1} build_memory_ms={memory_ms:.1}",
        robot.spheres().len()
    );
    Ok(())
}
