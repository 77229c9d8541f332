//! Command-line definitions. One subcommand per file under `command/`.

use clap::{Args, Parser, Subcommand};
use ember_engine::robot::RobotArgs;
use std::path::PathBuf;

/// Ember: a sensing-to-plan service for robot manipulators.
#[derive(Debug, Parser)]
#[command(name = "ember", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the daemon (emberd): serve clouds, objects, joint states and plan requests over iceoryx2.
    Run(RunArgs),
    /// Plan once for a scene and a request (MoveIt YAML or Ember's scene file) and print the result.
    Plan(PlanArgs),
    /// Generate the paper's problem sets as MoveIt-style YAML folders.
    Problems(ProblemsArgs),
    /// The sensing-to-plan demo: a daemon, simulated sensors and a client running pick episodes.
    Demo(DemoArgs),
    /// Feed recorded sessions (MCAP) into a running daemon; with --check, compare the plans.
    Replay(ReplayArgs),
    /// Extend the experience databases from the solved plans of recorded sessions.
    Train(TrainArgs),
    /// Watch daemons over Zenoh: a live view, or --once --json for scripts.
    Monitor(MonitorArgs),
    /// Inspect a robot description: links, group, spheres and their fit, self-collision pairs.
    #[command(subcommand)]
    Robot(RobotCommand),
}

#[derive(Debug, Subcommand)]
pub enum RobotCommand {
    /// Load a robot and report what Ember made of it: links, joints, group, spheres per link
    /// with measured protrusion and coverage, self-collision pairs; optionally a picture of the
    /// spheres over the geometry and an SRDF of the computed disabled pairs.
    Check(RobotCheckArgs),
    /// Print tight primitives (boxes, capsules, cylinders) around each collision mesh as URDF
    /// collision elements, with their protrusion.
    Primitives(RobotPrimitivesArgs),
}

#[derive(Debug, Args)]
pub struct RobotCheckArgs {
    /// The robot (same as --robot).
    pub robot_positional: Option<String>,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Also measure the robot's spheres and primitives against this description (a URDF with
    /// meshes), link by link: how far they stick out of it and how much of it they cover.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Folder for package:// URIs of the reference (repeat).
    #[arg(long = "reference-package-path")]
    pub reference_package_path: Vec<PathBuf>,
    /// Write a picture of the spheres over the geometry (.svg or .png).
    #[arg(long)]
    pub picture: Option<PathBuf>,
    /// Configuration of the picture: a named state [default: the first one, else the middle of
    /// the limits].
    #[arg(long)]
    pub state: Option<String>,
    /// Compute the pairs to skip the way MoveIt's setup assistant does and write an SRDF with
    /// them (and the group and named states) to this file.
    #[arg(long)]
    pub write_srdf: Option<PathBuf>,
    /// Random configurations sampled for --write-srdf.
    #[arg(long, default_value_t = 10_000)]
    pub samples: usize,
    /// Surface points per link drawn to measure coverage.
    #[arg(long, default_value_t = 4000)]
    pub coverage_samples: usize,
}

#[derive(Debug, Args)]
pub struct RobotPrimitivesArgs {
    /// The robot (same as --robot).
    pub robot_positional: Option<String>,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Most primitives per mesh part (slabs along its longest axis).
    #[arg(long, default_value_t = 3)]
    pub max_parts: usize,
}

#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Scene file: MoveIt PlanningScene YAML or Ember scene YAML.
    #[arg(long)]
    pub scene: PathBuf,
    /// MoveIt MotionPlanRequest YAML.
    #[arg(long)]
    pub request: PathBuf,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Seed of the planner.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Time limit in seconds (default: the request's allowed_planning_time, else 10).
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// End the search after this many iterations too (default: none, the time limit ends it),
    /// at the same point on every machine.
    #[arg(long)]
    pub max_iterations: Option<u64>,
    /// Keep the raw path (no simplification).
    #[arg(long)]
    pub no_simplify: bool,
    /// Print the result as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Fraction of the joint velocity limits the trajectory uses, (0, 1] (default: the
    /// request's max_velocity_scaling_factor, else 1).
    #[arg(long)]
    pub velocity_scaling: Option<f64>,
    /// Fraction of the joint acceleration limits, (0, 1] (default: the request's
    /// max_acceleration_scaling_factor, else 1).
    #[arg(long)]
    pub acceleration_scaling: Option<f64>,
    /// How far blended corners may pass from their waypoints (configuration-space distance;
    /// 0 stops at every waypoint).
    #[arg(long, default_value_t = 0.05)]
    pub max_deviation: f64,
    /// Trajectory sampling period, seconds.
    #[arg(long, default_value_t = 0.1)]
    pub sample_period: f64,
    /// Acceleration limit of joints the description gives none.
    #[arg(long, default_value_t = 1.0)]
    pub default_acceleration: f64,
    /// Return the path only (no timed trajectory).
    #[arg(long)]
    pub no_trajectory: bool,
    /// Write the timed trajectory as a MoveIt RobotTrajectory YAML.
    #[arg(long)]
    pub trajectory_out: Option<PathBuf>,
    /// Check the returned path at its states only, not certify it clear between them (as
    /// the daemon's `planner.certify = false`).
    #[arg(long)]
    pub no_certify: bool,
}

#[derive(Debug, Args)]
pub struct ProblemsArgs {
    /// Dataset: shelf_zero, shelf_height, shelf_height_rot, shelf_tall, table_pick, box.
    #[arg(long)]
    pub dataset: Vec<String>,
    /// Training problems per dataset (written to OUT/<dataset>).
    #[arg(long, default_value_t = 500)]
    pub train: usize,
    /// Test problems per dataset (written to OUT/<dataset>_test).
    #[arg(long, default_value_t = 100)]
    pub test: usize,
    /// Output folder.
    #[arg(long, default_value = "problems")]
    pub out: PathBuf,
    /// Seed (the test set uses seed + 1000, place sets seed + 1).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Place problems instead of picks (OUT/<dataset>_place[_test]): the robot starts holding
    /// the target can and puts it in the shelf's lower compartment (small shelf datasets,
    /// table_pick).
    #[arg(long)]
    pub place: bool,
    #[command(flatten)]
    pub robot: RobotArgs,
}

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Pick episodes to run (each in a new variation of the shelf scene).
    #[arg(long, default_value_t = 30)]
    pub episodes: usize,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Seed of scene variation, sensor noise and planning.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Folder of the session recording.
    #[arg(
        long,
        default_value = "ember-data/demo/recordings",
        conflicts_with = "no_record"
    )]
    pub record: PathBuf,
    /// Do not record the session.
    #[arg(long)]
    pub no_record: bool,
    /// Folder of the experience databases; emptied first unless --keep-db.
    #[arg(long, default_value = "ember-data/demo/db")]
    pub db: PathBuf,
    /// Start from the experience already in --db instead of an empty database.
    #[arg(long)]
    pub keep_db: bool,
    /// Instance name of the demo's daemon (what `ember monitor` shows).
    #[arg(long, default_value = "demo")]
    pub instance: String,
    /// Have the daemon check returned paths at their states only, not certify them between
    /// (`planner.certify = false`).
    #[arg(long)]
    pub no_certify: bool,
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Configuration file (TOML); overrides the embedded defaults key by key.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Instance name (services under ember/<instance>/); overrides the config.
    #[arg(long)]
    pub instance: Option<String>,
    /// Experience database folder; overrides the config.
    #[arg(long)]
    pub db_dir: Option<PathBuf>,
    /// Recording folder; overrides the config.
    #[arg(long)]
    pub record_dir: Option<PathBuf>,
    /// Do not record this session.
    #[arg(long)]
    pub no_record: bool,
    /// Do not publish over Zenoh.
    #[arg(long)]
    pub no_monitor: bool,
    /// Zenoh endpoint to listen on for watchers (repeat); overrides monitor.listen.
    #[arg(long = "monitor-listen")]
    pub monitor_listen: Vec<String>,
}

#[derive(Debug, Args)]
pub struct MonitorArgs {
    /// Instance to watch (default: every instance found).
    #[arg(long, default_value = "*")]
    pub instance: String,
    /// Zenoh endpoint of a daemon or router (repeat).
    #[arg(long, default_value = "tcp/127.0.0.1:7447")]
    pub connect: Vec<String>,
    /// Print the status of each instance as one JSON array and exit (1 if none answers).
    #[arg(long)]
    pub once: bool,
    /// With --once: JSON output (the only format of --once; accepted for clarity).
    #[arg(long)]
    pub json: bool,
    /// Seconds to wait for answers with --once.
    #[arg(long, default_value_t = 2.0)]
    pub timeout: f64,
    /// Zenoh mode of the watcher: peer or client.
    #[arg(long, default_value = "peer")]
    pub mode: String,
    /// Discover daemons by multicast scouting on the network.
    #[arg(long)]
    pub scout: bool,
    /// A Zenoh JSON5 config file used as the base, e.g. with the user and password to
    /// authenticate with (`transport.auth.usrpwd`).
    #[arg(long)]
    pub zenoh_config: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// Recording files, replayed in order.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Instance of the running daemon to feed.
    #[arg(long, default_value = "default")]
    pub instance: String,
    /// Replay at this multiple of real time (default: as fast as possible).
    #[arg(long)]
    pub speed: Option<f64>,
    /// Compare each plan reply with the recorded one; exit 1 on a difference.
    #[arg(long)]
    pub check: bool,
    /// Replay what is intact of a damaged file instead of refusing it.
    #[arg(long)]
    pub allow_truncated: bool,
    /// The robot the joint states belong to.
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Role of a foreign (ROS 2) bag topic: TOPIC=cloud|cloud_pose|joints|object:ID:SHAPE:D1,D2,D3 (repeat).
    #[arg(long = "topic-map")]
    pub topic_map: Vec<String>,
}

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Recording files.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Experience database folder (spark.emberdb, flame.emberdb), created or extended.
    #[arg(long)]
    pub db: PathBuf,
    /// Daemon configuration the sessions ran with (robot, map settings).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Also test path states every STEP for criticality.
    #[arg(long)]
    pub interpolate: Option<f64>,
    /// Role of a foreign (ROS 2) bag topic, as for `ember replay` (repeat).
    #[arg(long = "topic-map")]
    pub topic_map: Vec<String>,
    /// Learn from what is intact of a damaged file instead of refusing it.
    #[arg(long)]
    pub allow_truncated: bool,
}
