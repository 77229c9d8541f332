//! The demo's simulated sensor rig: a head-mounted depth camera rendering the true world, motion
//! capture reporting every object's pose, and the robot's joint encoders — all streamed to the
//! daemon over iceoryx2 through the SDK, as a robot's drivers would.

use crate::service::objects::update_of;
use ember_engine::scene::{pose_to_xyz_xyzw, Scene};
use ember_engine::world::Object;
use ember_engine::Pose;
use ember_sdk::wire::{self, ShapeKind};
use ember_sdk::Client;
use ember_sensors::{look_at, quarter_vga, DepthCamera, NoiseModel};
use std::collections::BTreeSet;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What the rig streams: the true scene (tracked by motion capture), objects only the
/// camera sees, and the robot's joint positions.
pub struct Truth {
    pub scene: Scene,
    pub unseen: Vec<Object>,
    pub joints: Vec<f64>,
}

/// The running rig.
pub struct Rig {
    truth: Arc<Mutex<Truth>>,
    stop: Arc<AtomicBool>,
    /// Frames published so far.
    pub frames: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<anyhow::Result<()>>>,
}

/// Frames per second of the rig (camera, motion capture and joints alike).
pub const RATE_HZ: f64 = 5.0;

impl Rig {
    /// Starts streaming `truth` to daemon `instance` from a camera at `camera_pose`.
    pub fn start(
        instance: &str,
        truth: Truth,
        camera_pose: Pose,
        seed: u64,
    ) -> anyhow::Result<Rig> {
        let instance = instance.to_string();
        let truth = Arc::new(Mutex::new(truth));
        let stop = Arc::new(AtomicBool::new(false));
        let frames = Arc::new(AtomicU64::new(0));
        let (t, s, f) = (truth.clone(), stop.clone(), frames.clone());
        let thread = std::thread::Builder::new()
            .name("sensor-rig".into())
            .spawn(move || {
                // iceoryx2 ports live on the thread that uses them.
                let client = Client::connect(&instance)?;
                stream(client, t, s, f, camera_pose, seed)
            })?;
        Ok(Rig {
            truth,
            stop,
            frames,
            thread: Some(thread),
        })
    }

    /// Changes the world the sensors see (from the next frame on): `scene` for motion capture
    /// and the camera, `unseen` for the camera only.
    pub fn set_scene(&self, scene: Scene, unseen: Vec<Object>) {
        let mut truth = self.truth.lock().expect("truth lock");
        truth.scene = scene;
        truth.unseen = unseen;
    }

    /// Changes the joint positions the encoders report (from the next frame on).
    pub fn set_joints(&self, joints: Vec<f64>) {
        self.truth.lock().expect("truth lock").joints = joints;
    }

    /// Stops streaming; an error of the rig thread (the daemon gone) comes back here.
    pub fn stop(mut self) -> anyhow::Result<()> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take().map(|t| t.join()) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(anyhow::anyhow!("the sensor rig panicked")),
            None => Ok(()),
        }
    }

    /// Whether the rig is still streaming.
    pub fn running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The head camera of the demo: above the robot's base, looking at `target`.
pub fn head_camera(target: [f64; 3]) -> Pose {
    look_at([0.15, 0.0, 1.45], target)
}

fn stream(
    client: Client,
    truth: Arc<Mutex<Truth>>,
    stop: Arc<AtomicBool>,
    frames: Arc<AtomicU64>,
    camera_pose: Pose,
    seed: u64,
) -> anyhow::Result<()> {
    let mut camera = DepthCamera::new(quarter_vga(), NoiseModel::default(), seed);
    let (t, q) = pose_to_xyz_xyzw(&camera_pose);
    let sensor_pose = [t[0], t[1], t[2], q[0], q[1], q[2], q[3]];
    let period = Duration::from_secs_f64(1.0 / RATE_HZ);
    let mut known: BTreeSet<String> = BTreeSet::new();
    while !stop.load(Ordering::Relaxed) {
        let tick = Instant::now();
        let (scene, unseen, joints) = {
            let t = truth.lock().expect("truth lock");
            (t.scene.clone(), t.unseen.clone(), t.joints.clone())
        };
        // Motion capture: every object's pose; objects that left the scene are removed.
        let names: BTreeSet<String> = scene.objects.iter().map(|o| o.name.clone()).collect();
        for gone in known.difference(&names) {
            let identity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
            client.publish_object(gone, ShapeKind::Remove, [0.0; 3], identity)?;
        }
        for o in &scene.objects {
            client.publish_object_raw(update_of(o))?;
        }
        known = names;
        client.publish_joints(&joints)?;
        // The depth camera: a 320×240 frame of the true scene, unseen objects included, with
        // noise and dropout.
        let mut env = scene.environment()?;
        for o in unseen {
            env.add(o)?;
        }
        let frame = camera.render(&env, &camera_pose);
        let points = &frame.points;
        client.publish_cloud("head_camera", sensor_pose, 0, points.len(), |i| {
            wire::Point {
                x: points[i][0],
                y: points[i][1],
                z: points[i][2],
            }
        })?;
        frames.fetch_add(1, Ordering::Relaxed);
        std::thread::sleep(period.saturating_sub(tick.elapsed()));
    }
    Ok(())
}
