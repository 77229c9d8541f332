//! Nearest-neighbour query time of the planner's index against a linear scan, on trees grown
//! the way RRT trees grow (short random steps from random nodes) in a robot's joint space,
//! queried with uniform samples (what RRT-Connect asks). Ends with one
//! `RESULT nearest nodes=<n> index_ns=<f> scan_ns=<f> ratio=<scan/index>` line per size.

use ember_engine::planning::nearest::NearestIndex;
use ember_engine::robot::RobotArgs;
use rand::{Rng, SeedableRng};
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Tree sizes to measure.
    #[arg(long, num_args = 1.., default_values_t = [1000usize, 4000, 10000, 40000])]
    nodes: Vec<usize>,
    /// Queries per size.
    #[arg(long, default_value_t = 20000)]
    queries: usize,
    /// The robot whose joint space is used.
    #[command(flatten)]
    robot: RobotArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = args.robot.spec("fetch").load()?;
    let dof = robot.dof();
    let continuous: Vec<bool> = robot.variables().iter().map(|v| v.continuous).collect();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(1);
    let mut results = Vec::new();
    println!(
        "{:>8} {:>12} {:>12} {:>8}",
        "nodes", "index_ns", "scan_ns", "ratio"
    );
    for &n in &args.nodes {
        let mut points: Vec<f64> = Vec::with_capacity(n * dof);
        let mut index = NearestIndex::new(&continuous);
        let mut q = robot.middle();
        let mut step = vec![0.0; dof];
        for i in 0..n {
            if i > 0 {
                let from = rng.random_range(0..i);
                robot.sample_uniform(&mut rng, &mut step);
                let base = points[from * dof..(from + 1) * dof].to_vec();
                let d = robot.distance(&base, &step).max(1e-9);
                robot.interpolate(&base, &step, (0.5 / d).min(1.0), &mut q);
            }
            points.extend_from_slice(&q);
            index.insert(&q, i as u32);
        }
        let queries: Vec<Vec<f64>> = (0..args.queries)
            .map(|_| {
                let mut s = vec![0.0; dof];
                robot.sample_uniform(&mut rng, &mut s);
                s
            })
            .collect();
        let t = Instant::now();
        let mut found = Vec::with_capacity(queries.len());
        for s in &queries {
            found.push(index.nearest(s).map(|(_, d2)| d2));
        }
        let index_ns = t.elapsed().as_secs_f64() * 1e9 / queries.len() as f64;
        // The scan answers a subset (it is slow at large sizes): every query up to 2000.
        let m = queries.len().min(2000);
        let t = Instant::now();
        for (s, got) in queries[..m].iter().zip(&found) {
            let best = points
                .chunks_exact(dof)
                .map(|p| robot.distance(p, s))
                .fold(f64::INFINITY, f64::min);
            let got = got.map_or(f64::NAN, f64::sqrt);
            anyhow::ensure!(
                (best - got).abs() < 1e-9,
                "the index disagrees with the scan: {got} vs {best}"
            );
        }
        let scan_ns = t.elapsed().as_secs_f64() * 1e9 / m as f64;
        println!(
            "{n:>8} {index_ns:>12.0} {scan_ns:>12.0} {:>8.1}",
            scan_ns / index_ns
        );
        results.push(format!(
            "RESULT nearest nodes={n} index_ns={index_ns:.0} scan_ns={scan_ns:.0} ratio={:.1}",
            scan_ns / index_ns
        ));
    }
    for r in results {
        println!("{r}");
    }
    Ok(())
}
