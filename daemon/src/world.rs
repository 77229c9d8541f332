//! The daemon's world model, kept up to date incrementally by the ingest thread, and the
//! immutable snapshots the planner works on.

use crate::config::Config;
use ember_engine::experience::flame::{octoboxes, Octobox};
use ember_engine::experience::spark::{PairSet, PairsSnapshot};
use ember_engine::experience::ExperienceParams;
use ember_engine::robot::spheres::PlacedSpheres;
use ember_engine::robot::Robot;
use ember_engine::scene::Scene;
use ember_engine::world::map::{InsertReport, MapParams, OccupancyMap};
use ember_engine::world::{Environment, Object};
use std::sync::Arc;

/// What the planner sees: a consistent copy of the world at one instant.
pub struct Snapshot {
    /// Objects as a scene (SPARK's input).
    pub scene: Scene,
    /// SPARK pairs of the objects.
    pub pairs: PairsSnapshot,
    /// The occupancy map (FLAME's input; an obstacle too when configured).
    pub map: Arc<OccupancyMap>,
    /// The map's non-empty octoboxes (FLAME's primitives), extracted once per cloud.
    pub octoboxes: Arc<Vec<Octobox>>,
    /// Objects (+ map when configured) for collision checking.
    pub env: Environment,
    /// Counts object changes: equal versions, equal objects.
    pub objects_version: u64,
}

/// The mutable world (owned by the ingest thread).
pub struct World {
    scene: Scene,
    pairs: PairSet,
    /// The objects for collision checking (kept with the scene, not rebuilt per snapshot).
    env: Environment,
    map: Arc<OccupancyMap>,
    octoboxes: Arc<Vec<Octobox>>,
    joints: Option<Vec<f64>>,
    use_map: bool,
    padding: f64,
    objects_version: u64,
}

impl World {
    /// An empty world.
    pub fn new(config: &Config) -> Self {
        World {
            scene: Scene::default(),
            pairs: PairSet::new(&ExperienceParams::default()),
            env: Environment::new(),
            map: Arc::new(OccupancyMap::new(MapParams {
                resolution: config.map.resolution,
                max_range: config.map.max_range,
                bounds: Some((config.map.bounds_min, config.map.bounds_max)),
                discretize: config.map.discretize,
                ..Default::default()
            })),
            octoboxes: Arc::default(),
            joints: None,
            use_map: config.planner.use_map,
            padding: config.map.self_filter_padding,
            objects_version: 0,
        }
    }

    /// Adds or moves an object; only its SPARK pairs are recomputed.
    pub fn upsert_object(&mut self, object: Object) {
        self.objects_version += 1;
        self.pairs.upsert(&object);
        self.env
            .upsert(object.clone())
            .expect("objects were validated on arrival");
        match self
            .scene
            .objects
            .iter()
            .position(|o| o.name == object.name)
        {
            Some(i) => self.scene.objects[i] = object,
            None => self.scene.objects.push(object),
        }
    }

    /// Removes an object and its pairs; false when unknown.
    /// True when no object of this name exists and the world already holds `max` objects.
    pub fn would_exceed(&self, name: &str, max: usize) -> bool {
        self.scene.objects.len() >= max && !self.scene.objects.iter().any(|o| o.name == name)
    }

    pub fn remove_object(&mut self, name: &str) -> bool {
        let before = self.scene.objects.len();
        self.objects_version += 1;
        self.scene.objects.retain(|o| o.name != name);
        self.pairs.remove(name);
        let _ = self.env.remove(name);
        self.scene.objects.len() != before
    }

    /// Sets the joint state.
    pub fn set_joints(&mut self, q: Vec<f64>) {
        self.joints = Some(q);
    }

    /// Folds a cloud into the map, dropping the robot's own points at the latest joint state
    /// (and non-finite ones); says what was folded in.
    pub fn insert_cloud(
        &mut self,
        robot: &Robot,
        points: &[[f32; 3]],
        sensor_pose: &ember_engine::Pose,
    ) -> InsertReport {
        let filter = self
            .joints
            .as_ref()
            .filter(|q| robot.validate(q).is_ok())
            .map(|q| PlacedSpheres::at(robot, q, self.padding));
        let map = Arc::make_mut(&mut self.map);
        let report = map.insert_cloud(points, sensor_pose, filter.as_ref());
        if !report.changed.is_empty() {
            self.octoboxes = Arc::new(octoboxes(map));
        }
        report
    }

    /// A snapshot of the current state.
    pub fn snapshot(&self) -> Snapshot {
        let mut env = self.env.clone();
        if self.use_map {
            env.set_map(Some(self.map.clone()));
        }
        Snapshot {
            scene: self.scene.clone(),
            pairs: self.pairs.snapshot(),
            map: self.map.clone(),
            octoboxes: self.octoboxes.clone(),
            env,
            objects_version: self.objects_version,
        }
    }
}
