//! `retrieval`: SPARK and FLAME retrieval time against database size, against linear scans.
//! Databases are filled with the SPARK pairs of random `shelf_height_rot` scenes (4 random
//! configurations each: retrieval cost does not depend on what the configurations are), then
//! queried with the pairs of fresh scenes of the same dataset — the paper's situation, where
//! most of a low-variation database lies within the radius.
//!
//! FLAME's databases hold the octoboxes above the floor of the sensed maps of random scenes of
//! the same dataset (a superset of the critical ones training would keep: more entries per
//! scene, so longer match lists than real training gives), queried with every octobox of
//! fresh scenes' sensed maps, as planning does.
//!
//! Flags: `--sizes N,...` (default 1000,4000,17000), `--queries N` (default 50), `--dataset D`
//! (default shelf_height_rot), `--no-flame`, `--warm` (time the fast paths with their index
//! cached). Ends with one
//! `RESULT retrieval size=<entries> tree_us=<median> linear_us=<median> entries=<mean retrieved>
//! samplers=<mean unique>` per size, then one `RESULT retrieval_flame size=<entries>
//! lookup_us=<median> linear_us=<median> entries=<mean retrieved> samplers=<mean unique>` per
//! size.

use crate::learning::map_of;
use ember_engine::experience::flame::octoboxes;
use ember_engine::experience::spark::spark_pairs;
use ember_engine::experience::{
    Database, ExperienceParams, FlameDb, Octobox, Retrieval, SparkDb, SparkPair,
};
use ember_engine::planning::PlannerRng;
use ember_engine::problems;
use ember_engine::robot::Robot;
use ember_engine::world::map::MapParams;
use ember_sdk::stats::summary;
use rand::SeedableRng;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Database sizes (entries), comma separated.
    #[arg(long, value_delimiter = ',', default_value = "1000,4000,17000")]
    sizes: Vec<usize>,
    /// The generated dataset whose scenes fill and query the databases.
    #[arg(long, default_value = "shelf_height_rot")]
    dataset: String,
    /// Query scenes per size (FLAME renders at most 20 of them).
    #[arg(long, default_value_t = 50)]
    queries: usize,
    /// Skip FLAME (its maps take ~0.2 s per scene to render).
    #[arg(long)]
    no_flame: bool,
    /// Time each fast query with its index already cached (run once untimed first). By default
    /// each query is timed once, right after its linear scan, as a daemon meets it: cold.
    #[arg(long)]
    warm: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = Robot::builtin("fetch")?;
    let spec = problems::dataset(&args.dataset)
        .ok_or_else(|| anyhow::anyhow!("unknown dataset {:?}", args.dataset))?;
    let params = ExperienceParams::default();
    let mut rng = PlannerRng::seed_from_u64(5);
    let queries: Vec<Vec<SparkPair>> = (0..args.queries)
        .map(|_| spark_pairs(&problems::sample_scene(&spec, &mut rng), &params))
        .collect();
    let mut db = SparkDb::new(params.clone());
    let mut sizes = args.sizes.clone();
    sizes.sort_unstable();
    println!(
        "{:>8} {:>10} {:>10} {:>9} {:>9}",
        "entries", "tree_us", "linear_us", "retrieved", "samplers"
    );
    let mut results = Vec::new();
    for size in sizes {
        while db.len() < size {
            let scene = problems::sample_scene(&spec, &mut rng);
            for pair in spark_pairs(&scene, &params) {
                db.insert(pair, random_configs(&robot, &mut rng));
            }
        }
        let timing = time_queries(
            &queries,
            args.warm,
            |q| counts(&db.retrieve(q)),
            |q| counts(&db.retrieve_linear(q)),
        )?;
        results.push(timing.report("retrieval", db.len(), "tree_us"));
    }
    if !args.no_flame {
        results.extend(flame(&args, &spec, &robot, &mut rng)?);
    }
    for r in results {
        println!("{r}");
    }
    Ok(())
}

/// FLAME lookups against database size, against the linear scan: the `RESULT` lines.
fn flame(
    args: &Args,
    spec: &problems::DatasetSpec,
    robot: &Robot,
    rng: &mut PlannerRng,
) -> anyhow::Result<Vec<String>> {
    let params = ExperienceParams::default();
    let map_params = MapParams::default();
    let n_queries = args.queries.min(20);
    let queries: Vec<Vec<Octobox>> = (0..n_queries)
        .map(|_| Ok(octoboxes(&map_of(&problems::sample_scene(spec, rng))?)))
        .collect::<anyhow::Result<_>>()?;
    let mut db = FlameDb::new(params, map_params.resolution);
    let mut sizes = args.sizes.clone();
    sizes.sort_unstable();
    println!(
        "{:>8} {:>10} {:>10} {:>9} {:>9}  (FLAME, {n_queries} query maps of ~{} octoboxes)",
        "entries",
        "lookup_us",
        "linear_us",
        "retrieved",
        "samplers",
        queries.iter().map(Vec::len).sum::<usize>() / n_queries.max(1)
    );
    let mut results = Vec::new();
    for size in sizes {
        while db.len() < size {
            let map = map_of(&problems::sample_scene(spec, rng))?;
            for o in octoboxes(&map) {
                if map.block_center(o.key)[2] > 0.05 && db.len() < size {
                    db.insert(o, random_configs(robot, rng));
                }
            }
        }
        let timing = time_queries(
            &queries,
            args.warm,
            |q| counts(&db.retrieve(q)),
            |q| {
                let mut found: Vec<usize> = q.iter().flat_map(|o| db.matches_linear(o)).collect();
                let entries = found.len();
                found.sort_unstable();
                found.dedup();
                (entries, found.len())
            },
        )?;
        results.push(timing.report("retrieval_flame", db.len(), "lookup_us"));
    }
    Ok(results)
}

/// What a retrieval found: (entries, distinct samplers).
fn counts(r: &Retrieval) -> (usize, usize) {
    (r.entries, r.samplers.len())
}

/// Median query times of the fast path and the linear scan, and mean sizes of what they found.
struct Timing {
    fast_us: f64,
    linear_us: f64,
    entries: f64,
    samplers: f64,
}

/// Times `fast` and `linear` on every query. Each gives (entries found, distinct samplers), and
/// the two must agree. With `warm`, `fast` runs once untimed before it is timed.
fn time_queries<Q>(
    queries: &[Q],
    warm: bool,
    fast: impl Fn(&Q) -> (usize, usize),
    linear: impl Fn(&Q) -> (usize, usize),
) -> anyhow::Result<Timing> {
    let (mut fast_us, mut linear_us) = (Vec::new(), Vec::new());
    let (mut entries, mut samplers) = (0.0, 0.0);
    for q in queries {
        if warm {
            std::hint::black_box(fast(q));
        }
        let t = Instant::now();
        let found = fast(q);
        fast_us.push(t.elapsed().as_secs_f64() * 1e6);
        let t = Instant::now();
        let expected = linear(q);
        linear_us.push(t.elapsed().as_secs_f64() * 1e6);
        anyhow::ensure!(
            found == expected,
            "fast path {found:?} and linear scan {expected:?} disagree"
        );
        entries += found.0 as f64 / queries.len() as f64;
        samplers += found.1 as f64 / queries.len() as f64;
    }
    Ok(Timing {
        fast_us: summary(&mut fast_us).0,
        linear_us: summary(&mut linear_us).0,
        entries,
        samplers,
    })
}

impl Timing {
    /// Prints the table row and returns the `RESULT <name>` line (`fast_key` names the fast time).
    fn report(&self, name: &str, size: usize, fast_key: &str) -> String {
        let Timing {
            fast_us,
            linear_us,
            entries,
            samplers,
        } = self;
        println!("{size:>8} {fast_us:>10.1} {linear_us:>10.1} {entries:>9.0} {samplers:>9.0}");
        format!(
            "RESULT {name} size={size} {fast_key}={fast_us:.1} linear_us={linear_us:.1} entries={entries:.0} samplers={samplers:.0}"
        )
    }
}

/// Four random configurations: retrieval cost does not depend on what they are.
fn random_configs(robot: &Robot, rng: &mut PlannerRng) -> Vec<Vec<f64>> {
    (0..4)
        .map(|_| {
            let mut q = vec![0.0; robot.dof()];
            robot.sample_uniform(rng, &mut q);
            q
        })
        .collect()
}
