//! emberd's configuration: TOML with embedded defaults (`config/emberd.toml`); a user file
//! overrides any subset of keys. Unknown keys and bad values are errors naming the key.

use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The most ports of one kind a service may admit (each costs shared memory).
const MAX_PORTS: usize = 256;

/// The longest queue (records, plan summaries) the config may ask for: each entry can hold a
/// cloud, so more would let one key exhaust memory.
const MAX_QUEUE: usize = 100_000;

/// The most objects the config may allow (SPARK pairs are kept per object pair).
const MAX_OBJECTS: usize = 10_000;

/// The most planning threads the config may ask for.
const MAX_WORKERS: usize = 64;

/// The fastest status publication the config may ask for, Hz.
const MAX_STATUS_HZ: f64 = 100.0;

/// Parses `file_mode`: octal, owner read-write, not writable by others.
fn parse_file_mode(text: &str) -> Result<u32, String> {
    let mode = u32::from_str_radix(text, 8)
        .ok()
        .filter(|m| *m <= 0o777)
        .ok_or_else(|| {
            format!("key file_mode must be an octal mode such as \"0600\", got \"{text}\"")
        })?;
    if mode & 0o600 != 0o600 || mode & 0o002 != 0 {
        return Err(format!(
            "key file_mode must let the owner read and write and others not write, got \"{text}\""
        ));
    }
    Ok(mode)
}

/// The embedded default configuration.
pub const DEFAULT_TOML: &str = include_str!("../../config/emberd.toml");

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub instance: String,
    /// Built-in name, robot file (.toml) or URDF (.urdf).
    pub robot: String,
    /// SRDF of a URDF robot; empty for none.
    pub srdf: PathBuf,
    /// Planning group of the SRDF; empty for the default.
    pub group: String,
    /// Folders searched first for `package://` mesh URIs.
    pub package_path: Vec<PathBuf>,
    /// Sphere protrusion, metres; 0 keeps the description's.
    pub sphere_protrusion: f64,
    /// Sphere protrusion on the hand (the tip link and the links below it), metres; 0 keeps
    /// the description's.
    pub sphere_protrusion_hand: f64,
    /// MoveIt joint_limits.yaml over the description's limits; empty for none.
    pub joint_limits: PathBuf,
    /// Mode of the files emberd creates, octal text (see [`Config::file_mode`]).
    pub file_mode: String,
    pub map: MapConfig,
    pub planner: PlannerConfig,
    pub trajectory: TrajectoryConfig,
    pub experience: ExperienceConfig,
    pub record: RecordConfig,
    pub monitor: MonitorConfig,
    pub limits: LimitsConfig,
    pub ingest: IngestConfig,
}

/// `[ingest]`: how the ingest thread waits for inputs.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IngestConfig {
    /// Busy-look for the next input this long after each one, µs (0: sleep at once).
    pub spin_us: u64,
}

/// `[limits]`: how many clients, publishers and subscribers the services admit.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsConfig {
    pub clients: usize,
    pub publishers: usize,
    pub subscribers: usize,
    /// Objects the world holds at most (new ones beyond are rejected).
    pub objects: usize,
}

impl LimitsConfig {
    /// The services' limits.
    pub fn get(&self) -> ember_sdk::services::Limits {
        ember_sdk::services::Limits {
            clients: self.clients,
            publishers: self.publishers,
            subscribers: self.subscribers,
        }
    }
}

/// `[monitor]`: Zenoh publications for remote watchers (read-only).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MonitorConfig {
    pub enabled: bool,
    /// Zenoh mode: `peer` or `client` (a client needs a router in `connect`).
    pub mode: String,
    pub listen: Vec<String>,
    pub connect: Vec<String>,
    pub multicast_scouting: bool,
    /// A Zenoh JSON5 config file used as the base (access control, TLS, ...); empty for none.
    pub zenoh_config: PathBuf,
    pub status_hz: f64,
    pub objects_period_s: f64,
    pub map_period_s: f64,
    /// Plan summaries queued for the publisher before drops (counted in status).
    pub queue: usize,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordConfig {
    pub enabled: bool,
    pub dir: PathBuf,
    pub max_file_mb: f64,
    pub max_file_s: f64,
    pub queue: usize,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapConfig {
    pub resolution: f64,
    pub max_range: f64,
    pub self_filter_padding: f64,
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
    pub max_points: usize,
    pub discretize: bool,
    pub carve_objects: bool,
    pub carve_padding: f64,
}

impl MapConfig {
    /// The largest object dimension or distance from the base accepted: ten times the farthest
    /// bound of the map, metres.
    pub fn max_object_extent(&self) -> f64 {
        let far = self
            .bounds_min
            .iter()
            .chain(&self.bounds_max)
            .fold(0.0f64, |m, v| m.max(v.abs()));
        10.0 * far
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlannerConfig {
    pub default_time_limit_s: f64,
    /// Requests asking for more are refused (`bad_request` naming the cap).
    pub max_time_limit_s: f64,
    /// Planning threads (0: one per core).
    pub workers: usize,
    pub range: f64,
    pub simplify: bool,
    /// The returned path's validation walks its edges this many times finer than the search.
    pub validation_refine: f64,
    /// Certify returned paths clear between their validated states too (the engine's
    /// `PlannerParams::certify`); on unless configured off.
    #[serde(default = "certify_by_default")]
    pub certify: bool,
    pub use_map: bool,
    /// With `use_map`: space never observed inside this box (min and max corners, base frame,
    /// metres) is an obstacle; unset, unknown space is free.
    #[serde(default)]
    pub unknown_obstacle_min: Option<[f64; 3]>,
    #[serde(default)]
    pub unknown_obstacle_max: Option<[f64; 3]>,
}

/// `[trajectory]`: how solved paths are timed (requests may lower the scaling factors).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryConfig {
    pub velocity_scaling: f64,
    pub acceleration_scaling: f64,
    pub max_deviation: f64,
    pub sample_period_s: f64,
    pub default_acceleration: f64,
}

impl PlannerConfig {
    /// Planning threads: `workers`, or one per core when 0.
    pub fn worker_count(&self) -> usize {
        match self.workers {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get().min(MAX_WORKERS)),
            n => n,
        }
    }
}

impl TrajectoryConfig {
    /// The engine's timing parameters.
    pub fn params(&self) -> ember_engine::trajectory::TimingParams {
        ember_engine::trajectory::TimingParams {
            velocity_scaling: self.velocity_scaling,
            acceleration_scaling: self.acceleration_scaling,
            max_deviation: self.max_deviation,
            sample_period: self.sample_period_s,
            default_acceleration: self.default_acceleration,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperienceConfig {
    pub online_learning: bool,
    pub db_dir: PathBuf,
    pub save_every_s: f64,
}

/// Merges `over` into `base` table by table.
fn merge(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

impl Config {
    /// The robot the `robot`, `srdf`, `group`, `package_path` and `sphere_protrusion(_hand)`
    /// keys name.
    pub fn robot_spec(&self) -> ember_engine::robot::RobotSpec {
        ember_engine::robot::RobotSpec {
            robot: self.robot.clone(),
            srdf: (!self.srdf.as_os_str().is_empty()).then(|| self.srdf.clone()),
            group: (!self.group.is_empty()).then(|| self.group.clone()),
            package_paths: self.package_path.clone(),
            protrusion: (self.sphere_protrusion != 0.0).then_some(self.sphere_protrusion),
            hand_protrusion: (self.sphere_protrusion_hand != 0.0)
                .then_some(self.sphere_protrusion_hand),
            sphere_cache: Default::default(),
            joint_limits: (!self.joint_limits.as_os_str().is_empty())
                .then(|| self.joint_limits.clone()),
        }
    }

    /// The defaults, overridden by `file` when given.
    pub fn load(file: Option<&Path>) -> anyhow::Result<Config> {
        let mut table: toml::Table = DEFAULT_TOML.parse().expect("embedded defaults parse");
        if let Some(path) = file {
            let text = std::fs::read_to_string(path)
                .map_err(|e| anyhow::anyhow!("cannot read config {}: {e}", path.display()))?;
            let over: toml::Table = text
                .parse()
                .map_err(|e| anyhow::anyhow!("config {}: {e}", path.display()))?;
            merge(&mut table, over);
        }
        let name = file.map_or("<defaults>".to_string(), |p| p.display().to_string());
        let config: Config =
            toml::Value::Table(table)
                .try_into()
                .map_err(|e: toml::de::Error| {
                    anyhow::anyhow!("config {name}: {}", e.to_string().trim())
                })?;
        config
            .validate()
            .map_err(|e| anyhow::anyhow!("config {name}: {e}"))?;
        Ok(config)
    }

    /// How the world model is kept: the map's settings, whether planning avoids it, the
    /// self-filter's padding.
    pub fn world_params(&self) -> ember_engine::world::model::WorldParams {
        ember_engine::world::model::WorldParams {
            map: ember_engine::world::map::MapParams {
                resolution: self.map.resolution,
                max_range: self.map.max_range,
                bounds: Some((self.map.bounds_min, self.map.bounds_max)),
                discretize: self.map.discretize,
                ..Default::default()
            },
            use_map: self.planner.use_map,
            self_filter_padding: self.map.self_filter_padding,
            carve_padding: self.map.carve_objects.then_some(self.map.carve_padding),
            unknown_obstacles: self
                .planner
                .unknown_obstacle_min
                .zip(self.planner.unknown_obstacle_max),
        }
    }

    /// The mode of the files emberd creates (databases, recordings): `file_mode`, validated.
    pub fn file_mode(&self) -> u32 {
        parse_file_mode(&self.file_mode).expect("validated on load")
    }

    /// Gives `path` (a file emberd created) the configured mode.
    pub fn apply_file_mode(&self, path: &Path) -> std::io::Result<()> {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(self.file_mode()))
    }

    fn validate(&self) -> Result<(), String> {
        parse_file_mode(&self.file_mode)?;
        if self.ingest.spin_us > 1_000_000 {
            return Err(format!(
                "key ingest.spin_us must be at most 1000000 (one second), got {}",
                self.ingest.spin_us
            ));
        }
        let positive = |key: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("key {key} must be a positive number, got {v}"))
            }
        };
        if !ember_sdk::names::valid_instance(&self.instance) {
            return Err(format!(
                "key instance: '{}' is not a valid instance name",
                self.instance
            ));
        }
        positive("map.resolution", self.map.resolution)?;
        positive("map.max_range", self.map.max_range)?;
        positive(
            "planner.default_time_limit_s",
            self.planner.default_time_limit_s,
        )?;
        positive("planner.max_time_limit_s", self.planner.max_time_limit_s)?;
        if self.planner.default_time_limit_s > self.planner.max_time_limit_s {
            return Err(format!(
                "key planner.default_time_limit_s ({}) must not exceed planner.max_time_limit_s ({})",
                self.planner.default_time_limit_s, self.planner.max_time_limit_s
            ));
        }
        positive("planner.range", self.planner.range)?;
        // Finer than 64 times would walk a metre of path in ~2,000 exact checks per 1/32.
        let refine = self.planner.validation_refine;
        if !(1.0..=64.0).contains(&refine) {
            return Err(format!(
                "key planner.validation_refine must be within [1, 64], got {refine}"
            ));
        }
        if self.planner.workers > MAX_WORKERS {
            return Err(format!(
                "key planner.workers must be at most {MAX_WORKERS} (0 = one per core), got {}",
                self.planner.workers
            ));
        }
        positive("experience.save_every_s", self.experience.save_every_s)?;
        positive("record.max_file_mb", self.record.max_file_mb)?;
        positive("record.max_file_s", self.record.max_file_s)?;
        if self.monitor.enabled {
            positive("monitor.status_hz", self.monitor.status_hz)?;
            positive("monitor.objects_period_s", self.monitor.objects_period_s)?;
            positive("monitor.map_period_s", self.monitor.map_period_s)?;
            if !matches!(self.monitor.mode.as_str(), "peer" | "client") {
                return Err(format!(
                    "key monitor.mode must be \"peer\" or \"client\", got \"{}\"",
                    self.monitor.mode
                ));
            }
        }
        for (key, v, max) in [
            ("record.queue", self.record.queue, MAX_QUEUE),
            ("monitor.queue", self.monitor.queue, MAX_QUEUE),
        ] {
            if !(1..=max).contains(&v) {
                return Err(format!("key {key} must be 1 to {max}, got {v}"));
            }
        }
        if self.monitor.status_hz > MAX_STATUS_HZ {
            return Err(format!(
                "key monitor.status_hz must be at most {MAX_STATUS_HZ}, got {}",
                self.monitor.status_hz
            ));
        }
        if self.map.self_filter_padding.is_nan() || self.map.self_filter_padding < 0.0 {
            return Err("key map.self_filter_padding must be >= 0".into());
        }
        if !(0.0..=1.0).contains(&self.map.carve_padding) {
            return Err("key map.carve_padding must be within 0..=1 m".into());
        }
        if (0..3).any(|a| {
            self.map.bounds_min[a].partial_cmp(&self.map.bounds_max[a])
                != Some(std::cmp::Ordering::Less)
        }) {
            return Err(
                "keys map.bounds_min / map.bounds_max: min must be below max on every axis".into(),
            );
        }
        match (
            self.planner.unknown_obstacle_min,
            self.planner.unknown_obstacle_max,
        ) {
            (None, None) => {}
            (Some(lo), Some(hi)) => {
                if (0..3).any(|a| !(lo[a].is_finite() && hi[a].is_finite() && lo[a] < hi[a])) {
                    return Err(
                        "keys planner.unknown_obstacle_min / planner.unknown_obstacle_max: \
                         min must be below max on every axis, both finite"
                            .into(),
                    );
                }
            }
            _ => {
                return Err(
                    "keys planner.unknown_obstacle_min / planner.unknown_obstacle_max: \
                     give both or neither"
                        .into(),
                )
            }
        }
        for (key, v) in [
            ("limits.clients", self.limits.clients),
            ("limits.publishers", self.limits.publishers),
            // The daemon's own subscriber is one.
            ("limits.subscribers", self.limits.subscribers),
        ] {
            if !(1..=MAX_PORTS).contains(&v) {
                return Err(format!("key {key} must be 1 to {MAX_PORTS}, got {v}"));
            }
        }
        if !(1..=MAX_OBJECTS).contains(&self.limits.objects) {
            return Err(format!(
                "key limits.objects must be 1 to {MAX_OBJECTS}, got {}",
                self.limits.objects
            ));
        }
        if self.map.max_points == 0 {
            return Err("key map.max_points must be at least 1".into());
        }
        self.trajectory
            .params()
            .validate()
            .map_err(|e| format!("[trajectory]: {e}"))?;
        Ok(())
    }
}

/// `planner.certify` where a configuration leaves it out: a path for a real robot is
/// certified clear between its states.
fn certify_by_default() -> bool {
    true
}
