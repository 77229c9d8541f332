//! `ember-bench`: system benchmarks. Each ends with a machine-readable `RESULT <name> ...` line.
//!
//! - `collision`: FK and full configuration checks for Fetch in a shelf scene;
//! - `plan --problems DIR...`: the uniform planner over MoveIt-style problem folders;
//! - `map`: our occupancy map against OctoMap on the same simulated frames;
//! - `experience --train DIR --test DIR...`: the paper's experiment (uniform vs SPARK vs FLAME);
//! - `ipc`: cloud hand-off and plan round-trip overhead through a real daemon;
//! - `monitor`: plan latency with monitoring over Zenoh on against off;
//! - `nearest`: the planner's nearest-neighbour index against a linear scan;
//! - `retrieval`: SPARK and FLAME retrieval time against database size (against linear scans);
//! - `paper`: the paper's experiments (training-size sweep, retrieval scaling), tables and plots;
//! - `validity --problems DIR...`: start/goal verdicts against an exact FCL mesh checker;
//! - `paths --problems DIR... --paths FILE...`: returned paths (any planner's) checked on the exact geometry;
//! - `trajectory`: time-optimal parameterisation time and durations against `toppra`;
//! - `world`: the world model's upkeep (SPARK pairs, snapshots) under thousands of objects.

mod collision;
mod daemon;
mod experience;
mod ipc;
mod learning;
mod map;
mod monitor;
mod nearest;
mod paper;
mod paths;
mod plan;
mod plot;
mod python;
mod retrieval;

mod trajectory;
mod validity;
mod world;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "ember-bench", about = "Ember's system benchmarks")]
struct Cli {
    #[command(subcommand)]
    bench: Bench,
}

#[derive(Subcommand)]
enum Bench {
    /// FK time per configuration and full collision check time (Fetch, shelf scene).
    Collision(collision::Args),
    /// Plan every problem of each folder with the uniform planner.
    Plan(plan::Args),
    /// Occupancy map insertion against OctoMap (Python peer) on the same frames.
    Map(map::Args),
    /// The world model's upkeep under many tracked objects.
    World(world::Args),
    /// Learn SPARK and FLAME from a training set, compare them with uniform sampling on test sets.
    Experience(experience::Args),
    /// Cloud hand-off latency and plan round-trip overhead through a real daemon.
    Ipc(ipc::Args),
    /// Plan latency with monitoring over Zenoh on against off (two real daemons).
    Monitor(monitor::Args),
    /// Nearest-neighbour query time of the planner's index against a linear scan.
    Nearest(nearest::Args),
    /// SPARK and FLAME retrieval time against database size, against linear scans.
    Retrieval(retrieval::Args),
    /// The paper's experiments: training-size sweep on the shelf datasets, tables and plots.
    Paper(paper::Args),
    /// Start/goal verdicts against an exact mesh checker on FCL (MoveIt's), same problems.
    Validity(validity::Args),
    /// Returned paths (any planner's) checked on Ember's exact geometry at a fine step.
    Paths(paths::Args),
    /// Trajectory parameterisation time per path and durations against toppra (same paths).
    Trajectory(trajectory::Args),
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().bench {
        Bench::Collision(a) => collision::run(a),
        Bench::Plan(a) => plan::run(a),
        Bench::Map(a) => map::run(a),
        Bench::World(a) => world::run(a),
        Bench::Experience(a) => experience::run(a),
        Bench::Ipc(a) => ipc::run(a),
        Bench::Monitor(a) => monitor::run(a),
        Bench::Nearest(a) => nearest::run(a),
        Bench::Retrieval(a) => retrieval::run(a),
        Bench::Paper(a) => paper::run(a),
        Bench::Validity(a) => validity::run(a),
        Bench::Paths(a) => paths::run(a),
        Bench::Trajectory(a) => trajectory::run(a),
    }
}
