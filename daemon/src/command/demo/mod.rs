//! `ember demo`: the whole product on embedded defaults. Starts emberd (a real `ember run`
//! process), streams a shelf world to it from a simulated depth camera, motion capture and joint
//! encoders over iceoryx2, and runs pick episodes as a client would: each episode moves the
//! shelf and cans, waits until the daemon has seen the change, and plans the same pick with
//! FLAME, SPARK and uniform sampling. After every third pick comes a place episode: the robot
//! holds a can (the daemon is told: attach), every method plans putting it down on the lower
//! shelf, and the can is put down (detach) and taken away. Only the uniform plan is learned
//! from (the others carry `FLAG_NO_LEARN`), so the learned methods are always tested on scenes
//! they have not seen.

mod rig;
mod unseen;

use crate::cli::DemoArgs;
use ember_engine::planning::PlannerRng;
use ember_engine::problems::{self, DatasetSpec};
use ember_engine::robot::Robot;
use ember_engine::world::Environment;
use ember_sdk::launch::launch;
use ember_sdk::wire::{self, Method, ShapeKind, FLAG_NO_LEARN};
use ember_sdk::{Client, PlanCall, Status};
use indicatif::{ProgressBar, ProgressStyle};
use rand::{Rng, SeedableRng};
use rig::{Rig, Truth};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

/// The methods compared, in the order each episode plans them (the learning one last).
const METHODS: [(Method, &str); 3] = [
    (Method::Flame, "flame"),
    (Method::Spark, "spark"),
    (Method::Uniform, "uniform"),
];

/// Frames the sensors must deliver after a scene change before the episode plans. A new
/// obstacle in space the map has seen free many times needs 3 hits to turn occupied (OctoMap's
/// defaults: log-odds clamped at 0.12, a hit 0.7), and the frame under way when the scene
/// changes may still show the old one.
const SETTLE_FRAMES: u64 = 4;

/// The demo's daemon process; stopped with SIGTERM (databases saved, recording closed).
struct DemoDaemon {
    child: Child,
    recording: String,
}

impl DemoDaemon {
    fn start(args: &DemoArgs, dir: &Path) -> anyhow::Result<DemoDaemon> {
        let config = dir.join("emberd-demo.toml");
        // Paths become absolute: the daemon reads them from its own config file.
        let spec = args.robot.spec("fetch");
        let absolute = |p: &Path| -> std::io::Result<String> {
            Ok(match p.exists() {
                true => std::fs::canonicalize(p)?.display().to_string(),
                false => p.display().to_string(),
            })
        };
        let mut table = toml::Table::new();
        table.insert("robot".into(), absolute(Path::new(&spec.robot))?.into());
        if let Some(s) = &spec.srdf {
            table.insert("srdf".into(), absolute(s)?.into());
        }
        if let Some(g) = &spec.group {
            table.insert("group".into(), g.clone().into());
        }
        let packages = spec
            .package_paths
            .iter()
            .map(|p| absolute(p).map(toml::Value::from))
            .collect::<std::io::Result<Vec<_>>>()?;
        table.insert("package_path".into(), packages.into());
        if let Some(p) = spec.protrusion {
            table.insert("sphere_protrusion".into(), p.into());
        }
        if let Some(h) = spec.hand_protrusion {
            table.insert("sphere_protrusion_hand".into(), h.into());
        }
        if args.no_certify {
            let planner = toml::Table::from_iter([("certify".to_string(), false.into())]);
            table.insert("planner".into(), planner.into());
        }
        std::fs::write(&config, toml::to_string(&table)?)?;
        let mut cmd = Command::new(std::env::current_exe()?);
        cmd.args(["run", "--instance", &args.instance, "--config"])
            .arg(&config)
            .arg("--db-dir")
            .arg(&args.db);
        if args.no_record {
            cmd.arg("--no-record");
        } else {
            cmd.arg("--record-dir").arg(&args.record);
        }
        let (child, ready) = launch(cmd.stderr(Stdio::inherit()))
            .map_err(|e| anyhow::anyhow!("{e} (see its message above)"))?;
        println!("{ready}");
        let recording = ready
            .recording
            .map_or("off".to_string(), |p| p.display().to_string());
        Ok(DemoDaemon { child, recording })
    }

    /// SIGTERM, then wait: the daemon saves its databases and closes the recording.
    fn stop(mut self) -> anyhow::Result<()> {
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
        let status = self.child.wait()?;
        anyhow::ensure!(status.success(), "the daemon stopped with {status}");
        Ok(())
    }
}

impl Drop for DemoDaemon {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            // SAFETY: as in `stop`.
            unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
            let _ = self.child.wait();
        }
    }
}

/// Results of one method.
#[derive(Default)]
struct Tally {
    episodes: usize,
    latencies_ms: Vec<f64>,
    retrieval_us: Vec<f64>,
    /// Executed durations of the timed trajectories, seconds.
    durations_s: Vec<f64>,
    /// Returned paths that touch the true world (the unseen box included) at the planner's
    /// resolution, and those touching only between its states.
    unsafe_paths: usize,
    grazes: usize,
}

impl Tally {
    fn median(v: &[f64]) -> f64 {
        ember_sdk::stats::median(&mut v.to_vec())
    }

    fn mean(v: &[f64]) -> f64 {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn wait_until(
    client: &Client,
    rig: &Rig,
    what: &str,
    done: impl Fn(&ember_sdk::wire::StatusReply) -> bool,
) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let s = client.status(Duration::from_secs(5))?;
        if done(&s) {
            return Ok(());
        }
        anyhow::ensure!(
            rig.running(),
            "the sensor rig stopped while waiting for {what}"
        );
        anyhow::ensure!(
            Instant::now() < deadline,
            "the daemon did not take {what} within 60 s"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Plans `start → goal` with every method (the uniform plan learned from, the others not),
/// judging each returned path exactly against `truth` for `robot` (with what it holds): one
/// progress note per method. With `redraw_refused`, a task whose start or goal the daemon
/// refuses as in collision (with what its map shows: voxels stand up to a voxel proud of the
/// surfaces the task was drawn against) is counted nowhere and `None` is returned, for the task
/// layer to draw another.
fn plan_all(
    client: &Client,
    robot: &Robot,
    truth: &Environment,
    (start, goal): (&[f64], &[f64]),
    seed: u64,
    tallies: &mut [Tally],
    redraw_refused: bool,
) -> anyhow::Result<Option<Vec<String>>> {
    let mut line = Vec::new();
    for (k, ((method, name), tally)) in METHODS.iter().zip(tallies).enumerate() {
        let call = PlanCall {
            start: start.to_vec(),
            goals: vec![goal.to_vec()],
            pose: None,
            method: *method,
            time_limit_s: 5.0,
            seed,
            // Timed under the robot's limits at the daemon's scaling.
            trajectory: Some((0.0, 0.0)),
        };
        let flags = if *method == Method::Uniform {
            0
        } else {
            FLAG_NO_LEARN
        };
        let t0 = Instant::now();
        let reply = client.plan_with_flags(&call, flags, Duration::from_secs(30))?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let ends_refused = matches!(
            reply.status,
            Status::StartInCollision | Status::GoalInCollision
        );
        if redraw_refused && k == 0 && ends_refused {
            return Ok(None);
        }
        tally.episodes += 1;
        if reply.status == Status::Ok {
            match unseen::judge(robot, truth, &reply.path) {
                unseen::Verdict::Unsafe => tally.unsafe_paths += 1,
                unseen::Verdict::Grazes => tally.grazes += 1,
                unseen::Verdict::Free => {}
            }
            tally.latencies_ms.push(ms);
            tally.retrieval_us.push(reply.header.retrieval_us);
            let executes = reply.trajectory.as_ref().filter(|t| !t.times.is_empty());
            if let Some(t) = executes {
                tally.durations_s.push(t.duration);
                line.push(format!("{name} {ms:.1} ms → runs {:.1} s", t.duration));
            } else {
                line.push(format!("{name} {ms:.1} ms (not timed)"));
            }
        } else {
            line.push(format!("{name} {:?}", reply.status));
        }
    }
    Ok(Some(line))
}

/// Placements drawn per place episode before it is given up, when the daemon refuses their
/// ends.
const PLACE_DRAWS: usize = 4;

/// One place episode: a fresh shelf scene without the can, the robot at the grasp where the
/// can stood; the daemon is told the hand holds it (attach), every method plans putting it
/// down, then it is put down where the plan ends (detach) and taken away. A placement whose
/// ends the daemon refuses is drawn again (up to [`PLACE_DRAWS`], counted in `refused`). None
/// when no reachable placement was drawn.
fn place_episode(
    client: &Client,
    rig: &Rig,
    robot: &Robot,
    spec: &DatasetSpec,
    rng: &mut PlannerRng,
    tallies: &mut [Tally],
    refused: &mut usize,
) -> anyhow::Result<Option<Vec<String>>> {
    for _ in 0..PLACE_DRAWS {
        let drawn = (0..20)
            .find_map(|_| problems::sample_place(robot, spec, rng).transpose())
            .transpose()?;
        let Some(task) = drawn else {
            return Ok(None);
        };
        match place_once(client, rig, robot, task, rng, tallies)? {
            Some(line) => return Ok(Some(line)),
            None => *refused += 1,
        }
    }
    Ok(Some(vec![format!(
        "place: the daemon refused the ends of {PLACE_DRAWS} placements drawn"
    )]))
}

/// [`place_episode`] for one drawn task; `None` when the daemon refused its ends (nothing
/// counted; the can is put down and taken away all the same).
fn place_once(
    client: &Client,
    rig: &Rig,
    robot: &Robot,
    task: problems::PlaceTask,
    rng: &mut PlannerRng,
    tallies: &mut [Tally],
) -> anyhow::Result<Option<Vec<String>>> {
    let problems::PlaceTask {
        scene,
        held,
        start,
        goal,
    } = task;
    let o = &held.object;
    let holding = robot.with_attached(robot.tip(), &o.name, o.shape, o.pose);
    let truth = scene.environment()?;
    let before = client.status(Duration::from_secs(5))?;
    let frames = rig.frames.load(std::sync::atomic::Ordering::Relaxed);
    rig.set_joints(start.clone());
    rig.set_scene(scene.clone(), Vec::new());
    let n = scene.objects.len() as u64;
    wait_until(client, rig, "the place scene", |s| {
        s.objects >= before.objects + 2 * n
            && s.joint_states >= before.joint_states + 2
            && s.clouds >= before.clouds + SETTLE_FRAMES
            && rig.frames.load(std::sync::atomic::Ordering::Relaxed) >= frames + SETTLE_FRAMES
    })?;
    // The task layer tells the daemon what the hand holds.
    let mut attach = crate::service::objects::update_of(o);
    attach.link = wire::name(&held.link);
    let rejected = client.status(Duration::from_secs(5))?.rejected;
    client.publish_object_raw(attach)?;
    wait_until(client, rig, "the attach", |s| {
        s.world_attached == 1 || s.rejected > rejected
    })?;
    let s = client.status(Duration::from_secs(5))?;
    anyhow::ensure!(
        s.world_attached == 1,
        "the daemon refused to attach the can: {}",
        wire::name_str(&s.last_rejection)
    );
    let seed: u64 = rng.random();
    let line = plan_all(
        client,
        &holding,
        &truth,
        (&start, &goal),
        seed,
        tallies,
        true,
    )?;
    // Put down where the place ends, then taken away.
    let mut poses = vec![ember_engine::Pose::identity(); robot.links().len()];
    robot.forward_kinematics(&goal, &mut poses);
    let (t, q) = ember_engine::scene::pose_to_xyz_xyzw(&(poses[robot.tip()] * o.pose));
    client.detach(&o.name, [t[0], t[1], t[2], q[0], q[1], q[2], q[3]])?;
    wait_until(client, rig, "the detach", |s| s.world_attached == 0)?;
    client.publish_object(
        &o.name,
        ShapeKind::Remove,
        [0.0; 3],
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
    )?;
    wait_until(client, rig, "the removal", |s| s.world_objects == n)?;
    Ok(line.map(|line| line.into_iter().map(|l| format!("place: {l}")).collect()))
}

/// Prints the table of `tallies` and returns their `RESULT` lines (`prefix method=...`,
/// `extra` appended).
fn report(tallies: &[Tally], prefix: &str, extra: &str) -> Vec<String> {
    println!(
        "{:<8} {:>8} {:>7} {:>10} {:>9} {:>13} {:>11} {:>7} {:>7}",
        "method",
        "episodes",
        "solved",
        "median_ms",
        "mean_ms",
        "retrieval_us",
        "executes_s",
        "unsafe",
        "grazes"
    );
    let mut results = Vec::new();
    for ((_, name), t) in METHODS.iter().zip(tallies).rev() {
        let (median, mean) = (Tally::median(&t.latencies_ms), Tally::mean(&t.latencies_ms));
        let retrieval = Tally::mean(&t.retrieval_us);
        let executes = Tally::median(&t.durations_s);
        println!(
            "{name:<8} {:>8} {:>7} {median:>10.2} {mean:>9.2} {retrieval:>13.1} {executes:>11.2} {:>7} {:>7}",
            t.episodes,
            t.latencies_ms.len(),
            t.unsafe_paths,
            t.grazes
        );
        results.push(format!(
            "{prefix} method={name} episodes={} solved={} median_ms={median:.3} mean_ms={mean:.3} retrieval_us={retrieval:.1} median_duration_s={executes:.3} timed={} unsafe={} grazes={}{extra}",
            t.episodes,
            t.latencies_ms.len(),
            t.durations_s.len(),
            t.unsafe_paths,
            t.grazes
        ));
    }
    results
}

pub fn run(args: DemoArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(args.episodes > 0, "--episodes must be at least 1");
    anyhow::ensure!(
        ember_sdk::names::valid_instance(&args.instance),
        "invalid instance name '{}'",
        args.instance
    );
    let robot = super::load_robot(&args.robot.spec("fetch"))?;
    let spec = problems::dataset("shelf_height_rot").expect("built-in dataset");
    let start = robot
        .named_state(spec.start_state)
        .ok_or_else(|| {
            anyhow::anyhow!(
                "robot '{}' has no named state '{}' to start the picks from",
                robot.name(),
                spec.start_state
            )
        })?
        .to_vec();
    // A fresh database unless asked to continue: the learned methods start from nothing.
    std::fs::create_dir_all(&args.db)?;
    if !args.keep_db {
        for f in ember_engine::experience::Experience::files(&args.db) {
            let _ = std::fs::remove_file(f);
        }
    }
    let work = args
        .db
        .parent()
        .map_or(PathBuf::from("."), Path::to_path_buf);
    let daemon = DemoDaemon::start(&args, &work)?;
    let started = Instant::now();
    let client = {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            match Client::connect(&args.instance) {
                Ok(c) => break c,
                Err(e) if Instant::now() > deadline => return Err(e.into()),
                Err(_) => std::thread::sleep(Duration::from_millis(20)),
            }
        }
    };
    let mut rng = PlannerRng::seed_from_u64(args.seed);
    let first = problems::sample_scene(&spec, &mut rng);
    // The camera looks at the middle of the shelf's front (the scene's board0 pose anchors it).
    let anchor = first
        .objects
        .iter()
        .find(|o| o.name == "board1")
        .map_or([1.0, 0.0, 0.7], |o| {
            let t = o.pose.translation.vector;
            [t.x, t.y, t.z]
        });
    let camera = rig::head_camera(anchor);
    let rig = Rig::start(
        &args.instance,
        Truth {
            scene: first.clone(),
            unseen: Vec::new(),
            joints: start.clone(),
        },
        camera,
        args.seed,
    )?;
    println!(
        "sensors streaming at {} Hz: depth camera 320x240, motion capture of {} objects, joint states; `ember monitor` shows the daemon live",
        rig::RATE_HZ,
        first.objects.len()
    );

    let bar = ProgressBar::new(args.episodes as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} episodes  {msg}")
            .expect("valid template"),
    );
    let mut tallies: Vec<Tally> = METHODS.iter().map(|_| Tally::default()).collect();
    let mut placing: Vec<Tally> = METHODS.iter().map(|_| Tally::default()).collect();
    let mut scene = first;
    let mut draws = 0;
    let mut episode = 0;
    let mut with_unseen = 0;
    let mut placements_refused = 0;
    while episode < args.episodes {
        if draws > 0 {
            scene = problems::sample_scene(&spec, &mut rng);
        }
        draws += 1;
        anyhow::ensure!(
            draws <= 50 * args.episodes,
            "robot '{}' reached the target in none of {} shelf scenes drawn: it cannot do this task",
            robot.name(),
            draws - 1
        );
        // The task layer picks a grasp configuration for a can (IK on the known scene).
        let env = scene.environment()?;
        let Some(goal) = problems::sample_goal(&robot, &spec, &scene, &env, &mut rng) else {
            continue;
        };
        // A box only the camera sees, where a plan blind to it would pass.
        let (obstacle, truth) =
            match unseen::place(&robot, &env, &camera, (&start, &goal), rng.random()) {
                Some((o, truth)) => (Some(o), truth),
                None => (None, env.clone()),
            };
        with_unseen += obstacle.is_some() as usize;
        // Show the sensors the new scene; plan once the daemon has its objects and fresh frames
        // (enough for the rays to clear where the last box stood).
        let before = client.status(Duration::from_secs(5))?;
        let frames = rig.frames.load(std::sync::atomic::Ordering::Relaxed);
        rig.set_scene(scene.clone(), obstacle.into_iter().collect());
        let n = scene.objects.len() as u64;
        wait_until(&client, &rig, "the new scene", |s| {
            s.objects >= before.objects + 2 * n
                && s.clouds >= before.clouds + SETTLE_FRAMES
                && rig.frames.load(std::sync::atomic::Ordering::Relaxed) >= frames + SETTLE_FRAMES
        })?;
        episode += 1;
        let seed: u64 = rng.random();
        let mut line = plan_all(
            &client,
            &robot,
            &truth,
            (&start, &goal),
            seed,
            &mut tallies,
            false,
        )?
        .expect("counted whatever the daemon answers");
        if episode % 3 == 1 {
            let placed = place_episode(
                &client,
                &rig,
                &robot,
                &spec,
                &mut rng,
                &mut placing,
                &mut placements_refused,
            )?;
            match placed {
                Some(placed) => line.extend(placed),
                None => line.push("place: no reachable placement drawn".into()),
            }
            rig.set_joints(start.clone());
        }
        bar.set_message(line.join(", "));
        bar.inc(1);
    }
    bar.finish_and_clear();
    rig.stop()?;
    let recording = daemon.recording.clone();
    daemon.stop()?;
    let seconds = started.elapsed().as_secs_f64();

    println!("\nplace episodes (holding a can, attached through the daemon):");
    let refused = format!(" placements_refused={placements_refused}");
    let place_results = report(&placing, "RESULT demo_place", &refused);
    println!("\npick episodes:");
    let unseen = format!(" unseen_obstacles={with_unseen}");
    let results = report(&tallies, "RESULT demo", &unseen);
    println!(
        "\nplan latency is end to end (client request to reply over iceoryx2), retrieval and \
         trajectory timing included; executes_s: how long the timed trajectory runs on the robot; \
         unsafe: returned paths that touch the true world, checked exactly at the planner's edge \
         resolution; grazes: paths that touch it only between those states, found at a 3x finer \
         resolution ({with_unseen} of the episodes hold a box only the camera sees, on the path \
         a planner blind to it takes)"
    );
    match std::fs::metadata(&recording) {
        Ok(m) => println!(
            "recording: {recording} ({:.1} MB, {:.1} MB per second of demo)",
            m.len() as f64 / 1e6,
            m.len() as f64 / 1e6 / seconds
        ),
        Err(_) => println!("recording: {recording}"),
    }
    println!("experience database: {}", args.db.display());
    for r in place_results.into_iter().chain(results) {
        println!("{r}");
    }
    println!(
        "RESULT demo recording={recording} database={}",
        args.db.display()
    );
    Ok(ExitCode::SUCCESS)
}
