//! `map`: our occupancy map against real OctoMap on the same simulated 640×480 frames.
//!
//! Renders `--frames` views of the small-shelf scene with the simulated depth camera, inserts
//! them into our map and, through `bench/octomap_peer.py` in a throwaway virtualenv with the
//! `octomap-python` package from PyPI (single-threaded: `OMP_NUM_THREADS=1`), into OctoMap.
//! Prints ms per frame for both, the speed ratio, and the share of voxels (known to either map)
//! whose occupied/free/unknown state agrees; ends with
//! `RESULT map res=<m> ours_ms=<f> octomap_ms=<f> speedup=<f> agreement=<f> snapshot_ms=<f>
//! map_copy_ms=<f> blocks=<n>` (`snapshot_ms`: the same frames again into the grown map with the
//! previous state held by a snapshot, as the daemon inserts; `map_copy_ms`: a whole copy).
//! Flags: `--res` (0.02), `--max-range` (3.0), `--frames` (5), `--discretize` (OctoMap's option),
//! `--no-peer` (ours only).

use ember_engine::planning::PlannerRng;
use ember_engine::problems;
use ember_engine::world::map::{MapParams, Occupancy, OccupancyMap, VoxelKey};
use ember_sdk::stats::summary;
use ember_sensors::{look_at, CameraModel, DepthCamera, NoiseModel};
use nalgebra::Point3;
use rand::SeedableRng;
use std::collections::HashMap;
use std::io::Write;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Leaf size, metres.
    #[arg(long, default_value_t = 0.02)]
    res: f64,
    /// Maximum ray length, metres.
    #[arg(long, default_value_t = 3.0)]
    max_range: f64,
    /// Frames (viewpoints) to insert.
    #[arg(long, default_value_t = 5)]
    frames: usize,
    /// Let OctoMap discretize endpoints (its faster, approximate mode).
    #[arg(long)]
    discretize: bool,
    /// Skip the OctoMap side.
    #[arg(long)]
    no_peer: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let spec = problems::dataset("shelf_zero").expect("built in");
    let scene = problems::sample_scene(&spec, &mut PlannerRng::seed_from_u64(3));
    let env = scene.environment()?;
    let mut camera = DepthCamera::new(CameraModel::default(), NoiseModel::default(), 5);
    let frames: Vec<_> = (0..args.frames)
        .map(|i| {
            let a = (i as f64 - (args.frames as f64 - 1.0) / 2.0) * 0.15;
            let eye = [0.1 - 0.3 * a.abs(), 0.6 * a, 1.4 + 0.1 * (i % 2) as f64];
            camera.render(&env, &look_at(eye, [1.05, 0.0, 0.75]))
        })
        .collect();
    let points: usize = frames.iter().map(|f| f.points.len()).sum();
    println!(
        "{} frames of 640x480 ({} points on average), res {} m, max range {} m",
        frames.len(),
        points / frames.len().max(1),
        args.res,
        args.max_range
    );

    let params = MapParams {
        resolution: args.res,
        max_range: args.max_range,
        discretize: args.discretize,
        ..Default::default()
    };
    let mut ours = OccupancyMap::new(params);
    let mut ours_ms = Vec::new();
    for f in &frames {
        let t = Instant::now();
        ours.insert_cloud(&f.points, &f.sensor_pose, None);
        ours_ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let (ours_med, _, _) = summary(&mut ours_ms.clone());
    println!(
        "ours:    {:8.2} ms/frame median ({} blocks, {:.1} MB)",
        ours_med,
        ours.block_count(),
        ours.memory_bytes() as f64 / 1e6
    );
    // As the daemon inserts: the last snapshot still holds the map while the next frame goes
    // in, so the insert must not copy what it does not change. The same frames again into the
    // grown map, each with the previous state held.
    let mut shared = std::sync::Arc::new(ours.clone());
    let mut held_ms = Vec::new();
    for f in &frames {
        let held = shared.clone();
        let t = Instant::now();
        std::sync::Arc::make_mut(&mut shared).insert_cloud(&f.points, &f.sensor_pose, None);
        held_ms.push(t.elapsed().as_secs_f64() * 1e3);
        drop(held);
    }
    let (held_med, _, _) = summary(&mut held_ms);
    let t = Instant::now();
    let copy = ours.clone();
    let copy_ms = t.elapsed().as_secs_f64() * 1e3;
    drop(copy);
    println!(
        "ours with the previous snapshot held: {held_med:8.2} ms/frame median (a whole copy of this {}-block map: {copy_ms:.2} ms)",
        ours.block_count()
    );
    let snapshot_keys = format!(
        "snapshot_ms={held_med:.3} map_copy_ms={copy_ms:.3} blocks={}",
        ours.block_count()
    );
    if args.no_peer {
        println!(
            "RESULT map res={} ours_ms={ours_med:.3} octomap_ms=nan speedup=nan agreement=nan {snapshot_keys}",
            args.res
        );
        return Ok(());
    }

    let python = match crate::python::venv(
        "octomap-venv",
        &["octomap-python", "numpy"],
        "import octomap, numpy",
    ) {
        Ok(p) => p,
        Err(e) => {
            println!("OctoMap peer unavailable ({e}); run with --no-peer for our side only");
            println!(
                "RESULT map res={} ours_ms={ours_med:.3} octomap_ms=nan speedup=nan agreement=nan {snapshot_keys}",
                args.res
            );
            return Ok(());
        }
    };
    let dir = std::env::temp_dir().join(format!("ember-map-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let frames_path = dir.join("frames.bin");
    let mut out = std::io::BufWriter::new(std::fs::File::create(&frames_path)?);
    for f in &frames {
        let o = f.sensor_pose.translation.vector;
        out.write_all(&(f.points.len() as u32).to_le_bytes())?;
        for v in [o.x, o.y, o.z] {
            out.write_all(&v.to_le_bytes())?;
        }
        for p in &f.points {
            let w = f.sensor_pose * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            for v in [w.x as f32, w.y as f32, w.z as f32] {
                out.write_all(&v.to_le_bytes())?;
            }
        }
    }
    drop(out);
    let leaves_path = dir.join("leaves.txt");
    let mut cmd = Command::new(&python);
    cmd.arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("octomap_peer.py"))
        .arg(&frames_path)
        .arg(args.res.to_string())
        .arg(args.max_range.to_string())
        .arg(&leaves_path)
        .env("OMP_NUM_THREADS", "1");
    if args.discretize {
        cmd.arg("--discretize");
    }
    let output = cmd.output()?;
    anyhow::ensure!(
        output.status.success(),
        "octomap peer failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let mut peer_ms: Vec<f64> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix("ms ")?.parse().ok())
        .collect();
    let (peer_med, _, _) = summary(&mut peer_ms);

    let mut peer: HashMap<VoxelKey, Occupancy> = HashMap::new();
    for line in std::fs::read_to_string(&leaves_path)?.lines() {
        let v: Vec<i32> = line.split(' ').filter_map(|x| x.parse().ok()).collect();
        if v.len() == 4 {
            peer.insert(
                [v[0], v[1], v[2]],
                if v[3] == 1 {
                    Occupancy::Occupied
                } else {
                    Occupancy::Free
                },
            );
        }
    }
    let mine: HashMap<VoxelKey, Occupancy> = ours.known_voxels().collect();
    let mut union = 0usize;
    let mut agree = 0usize;
    let mut occ_both = 0usize;
    let mut occ_either = 0usize;
    for (k, s) in &mine {
        union += 1;
        let p = peer.get(k).copied().unwrap_or(Occupancy::Unknown);
        agree += (p == *s) as usize;
        occ_either += (p == Occupancy::Occupied || *s == Occupancy::Occupied) as usize;
        occ_both += (p == Occupancy::Occupied && *s == Occupancy::Occupied) as usize;
    }
    for (k, p) in &peer {
        if !mine.contains_key(k) {
            union += 1;
            occ_either += (*p == Occupancy::Occupied) as usize;
        }
    }
    let mut confusion: HashMap<(Occupancy, Occupancy), usize> = HashMap::new();
    for (k, s) in &mine {
        let p = peer.get(k).copied().unwrap_or(Occupancy::Unknown);
        if p != *s {
            *confusion.entry((*s, p)).or_default() += 1;
        }
    }
    for (k, p) in &peer {
        if !mine.contains_key(k) {
            *confusion.entry((Occupancy::Unknown, *p)).or_default() += 1;
        }
    }
    let mut confusion: Vec<_> = confusion.into_iter().collect();
    confusion.sort_by_key(|c| std::cmp::Reverse(c.1));
    for ((a, b), n) in &confusion {
        println!("  ours {a:?} / octomap {b:?}: {n} voxels");
    }
    let agreement = agree as f64 / union.max(1) as f64;
    let speedup = peer_med / ours_med;
    println!(
        "octomap: {:8.2} ms/frame median ({}single thread)",
        peer_med,
        if args.discretize { "discretize, " } else { "" }
    );
    println!("speedup: {speedup:.1}x");
    println!(
        "agreement: {:.4} of {} voxels known to either map; occupied voxels: {:.4} shared",
        agreement,
        union,
        occ_both as f64 / occ_either.max(1) as f64
    );
    std::fs::remove_dir_all(&dir).ok();
    println!(
        "RESULT map res={} ours_ms={ours_med:.3} octomap_ms={peer_med:.3} speedup={speedup:.2} agreement={agreement:.4} {snapshot_keys}",
        args.res
    );
    Ok(())
}
