//! A sensor publisher to copy into a robot stack: streams a depth cloud (written straight into
//! shared memory), the robot's joint state and one motion-capture object to a running `emberd`,
//! then checks the daemon took them.
//!
//! Run: `ember run --instance demo` in one terminal, then
//! `cargo run -p ember-sdk --example sensor_publisher -- demo`.

use ember_sdk::wire::{Point, ShapeKind};
use ember_sdk::Client;
use std::time::Duration;

fn main() -> anyhow::Result<()> {
    let instance = std::env::args().nth(1).unwrap_or_else(|| "default".into());
    let client = Client::connect(&instance)?;
    // The robot's joint state (Fetch tuck), so the daemon removes the robot's own points.
    client.publish_joints(&[0.1, 1.32, 1.40, -0.2, 1.72, 0.0, 1.66, 0.0])?;
    // A table seen by motion capture: a box, pose x y z qx qy qz qw in the robot base frame.
    client.publish_object(
        "table",
        ShapeKind::Box,
        [0.8, 1.2, 0.04],
        [1.1, 0.0, 0.7, 0.0, 0.0, 0.0, 1.0],
    )?;
    // A 640×480 cloud from a camera 1 m up looking along x (optical frame: z forward), written
    // point by point into the loaned shared-memory slice: no copy on the way in.
    let camera_pose = [0.0, 0.0, 1.0, -0.5, 0.5, -0.5, 0.5];
    let (w, h) = (640usize, 480usize);
    for frame in 0..10 {
        client.publish_cloud(
            "head_camera_depth_optical_frame",
            camera_pose,
            0,
            w * h,
            |i| {
                let (u, v) = ((i % w) as f32, (i / w) as f32);
                let z = 1.5f32; // a wall 1.5 m ahead
                Point {
                    x: (u - 320.0) / 550.0 * z,
                    y: (v - 240.0) / 550.0 * z,
                    z,
                }
            },
        )?;
        std::thread::sleep(Duration::from_millis(33));
        let s = client.status(Duration::from_secs(1))?;
        println!(
            "frame {frame}: daemon has {} clouds, {} objects, {} map blocks",
            s.clouds, s.world_objects, s.map_blocks
        );
    }
    // A daemon busy with a cloud skips to the newest one (the stream keeps only the latest two):
    // wait until it has folded at least one in.
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    let s = loop {
        let s = client.status(Duration::from_secs(1))?;
        if s.clouds >= 1 || std::time::Instant::now() > deadline {
            break s;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    anyhow::ensure!(
        s.clouds >= 1 && s.world_objects >= 1,
        "the daemon did not take the data: {s:?}"
    );
    println!(
        "cloud hand-off p50 {:.1} us, {} map blocks",
        s.cloud_latency_p50_us, s.map_blocks
    );
    println!("ok");
    Ok(())
}
