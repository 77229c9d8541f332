//! `world`: the world model under many tracked objects, as the daemon's ingest keeps it. Adds
//! `--objects` spheres on a 15 × 15 grid of layers 0.1 m apart (close enough to pair with their
//! neighbours), then moves `--updates` of them by 1 cm, each move followed by a snapshot (what
//! ingest does per batch). Ends with
//! `RESULT world objects=<n> pairs=<n> add_ms=<f> update_snapshot_ms=<f>` (the last: all the
//! updates with their snapshots).

use ember_engine::collision::Shape;
use ember_engine::world::map::MapParams;
use ember_engine::world::model::{World, WorldParams};
use ember_engine::world::Object;
use ember_engine::Pose;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Objects to add.
    #[arg(long, default_value_t = 3000)]
    objects: usize,
    /// Moves, each followed by a snapshot.
    #[arg(long, default_value_t = 100)]
    updates: usize,
}

fn object(k: usize, dx: f64) -> Object {
    Object {
        name: format!("o{k}"),
        shape: Shape::Sphere { radius: 0.03 },
        pose: Pose::translation(
            0.5 + (k % 15) as f64 * 0.1 + dx,
            -0.7 + ((k / 15) % 15) as f64 * 0.1,
            0.2 + (k / 225) as f64 * 0.1,
        ),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut world = World::new(&WorldParams {
        map: MapParams::default(),
        use_map: false,
        carve_padding: None,
        self_filter_padding: 0.03,
    });
    let t = Instant::now();
    for k in 0..args.objects {
        world.upsert_object(object(k, 0.0));
    }
    let add_ms = t.elapsed().as_secs_f64() * 1e3;
    let pairs = world.snapshot().pairs.len();
    let t = Instant::now();
    for u in 0..args.updates {
        world.upsert_object(object((u * 29) % args.objects.max(1), 0.01));
        std::hint::black_box(world.snapshot());
    }
    let update_ms = t.elapsed().as_secs_f64() * 1e3;
    println!(
        "{} objects, {pairs} SPARK pairs: added in {add_ms:.1} ms; {} moves, each with a snapshot, in {update_ms:.1} ms",
        args.objects, args.updates
    );
    println!(
        "RESULT world objects={} pairs={pairs} add_ms={add_ms:.2} update_snapshot_ms={update_ms:.2}",
        args.objects
    );
    Ok(())
}
