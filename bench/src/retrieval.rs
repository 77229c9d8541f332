//! `retrieval`: SPARK retrieval time against database size, metric tree against linear scan.
//! Databases are filled with the SPARK pairs of random `shelf_height_rot` scenes (4 random
//! configurations each: retrieval cost does not depend on what the configurations are), then
//! queried with the pairs of fresh scenes of the same dataset — the paper's situation, where
//! most of a low-variation database lies within the radius.
//!
//! Flags: `--sizes N,...` (default 1000,4000,17000), `--queries N` (default 50), `--dataset D`
//! (default shelf_height_rot). Ends with one
//! `RESULT retrieval size=<entries> tree_us=<median> linear_us=<median> entries=<mean retrieved>
//! samplers=<mean unique>` per size.

use crate::stats::summary;
use ember_engine::experience::primitive::spark_pairs;
use ember_engine::experience::{ExperienceParams, SparkDb, SparkPair};
use ember_engine::planning::PlannerRng;
use ember_engine::problems;
use ember_engine::robot::Robot;
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
    /// Query scenes per size.
    #[arg(long, default_value_t = 50)]
    queries: usize,
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
                let configs = (0..4)
                    .map(|_| {
                        let mut q = vec![0.0; robot.dof()];
                        robot.sample_uniform(&mut rng, &mut q);
                        q
                    })
                    .collect();
                db.insert(pair, configs);
            }
        }
        let (mut tree, mut linear, mut entries, mut samplers) = (Vec::new(), Vec::new(), 0.0, 0.0);
        for q in &queries {
            let t = Instant::now();
            let r = db.retrieve(q);
            tree.push(t.elapsed().as_secs_f64() * 1e6);
            let t = Instant::now();
            let l = db.retrieve_linear(q);
            linear.push(t.elapsed().as_secs_f64() * 1e6);
            anyhow::ensure!(
                r.entries == l.entries && r.samplers.len() == l.samplers.len(),
                "tree and linear scan disagree"
            );
            entries += r.entries as f64 / queries.len() as f64;
            samplers += r.samplers.len() as f64 / queries.len() as f64;
        }
        let (tree_us, _, _) = summary(&mut tree);
        let (linear_us, _, _) = summary(&mut linear);
        println!(
            "{:>8} {tree_us:>10.1} {linear_us:>10.1} {entries:>9.0} {samplers:>9.0}",
            db.len()
        );
        results.push(format!(
            "RESULT retrieval size={} tree_us={tree_us:.1} linear_us={linear_us:.1} entries={entries:.0} samplers={samplers:.0}",
            db.len()
        ));
    }
    for r in results {
        println!("{r}");
    }
    Ok(())
}
