//! The world model: objects, the occupancy map and their decompositions (SPARK pairs, FLAME
//! octoboxes), kept up to date one input at a time, and the immutable snapshots planning works
//! on. The daemon's ingest thread owns one; `ember train` rebuilds one from a recording.

use super::map::{InsertReport, MapParams, OccupancyMap};
use super::{Environment, Object};
use crate::experience::flame::{octoboxes, Octobox};
use crate::experience::spark::{PairSet, PairsSnapshot};
use crate::experience::ExperienceParams;
use crate::robot::spheres::PlacedSpheres;
use crate::robot::Robot;
use crate::scene::Scene;
use std::sync::Arc;

/// How a world is kept.
#[derive(Debug, Clone)]
pub struct WorldParams {
    /// The occupancy map's settings.
    pub map: MapParams,
    /// Whether planning avoids the map as well as the objects.
    pub use_map: bool,
    /// Cloud points within this of the robot's spheres are dropped (the self-filter), metres.
    pub self_filter_padding: f64,
}

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
    pub fn new(params: &WorldParams) -> Self {
        World {
            scene: Scene::default(),
            pairs: PairSet::new(&ExperienceParams::default()),
            env: Environment::new(),
            map: Arc::new(OccupancyMap::new(params.map.clone())),
            octoboxes: Arc::default(),
            joints: None,
            use_map: params.use_map,
            padding: params.self_filter_padding,
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

    /// True when no object of this name exists and the world already holds `max` objects.
    pub fn would_exceed(&self, name: &str, max: usize) -> bool {
        self.scene.objects.len() >= max && !self.scene.objects.iter().any(|o| o.name == name)
    }

    /// Removes an object and its pairs; false when unknown.
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
        sensor_pose: &crate::Pose,
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
