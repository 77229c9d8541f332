//! The world model: objects, the occupancy map and their decompositions (SPARK pairs, FLAME
//! octoboxes), kept up to date one input at a time, and the immutable snapshots planning works
//! on. The daemon's ingest thread owns one; `ember train` rebuilds one from a recording.

use super::map::{BlockKey, CloudMask, InsertReport, MapParams, OccupancyMap};
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
    /// Tracked objects carved out of the map: cloud points within this distance (metres) of
    /// one are dropped, and the voxels an object fills are cleared when it arrives or moves;
    /// FLAME then sees the objects voxelised into its octoboxes. `None`: the map keeps them.
    pub carve_padding: Option<f64>,
}

/// What the planner sees: a consistent copy of the world at one instant.
pub struct Snapshot {
    /// Objects as a scene (SPARK's input).
    pub scene: Scene,
    /// SPARK pairs of the objects.
    pub pairs: PairsSnapshot,
    /// The occupancy map (FLAME's input; an obstacle too when configured).
    pub map: Arc<OccupancyMap>,
    /// The non-empty octoboxes (FLAME's primitives): the map's, and the carved objects'
    /// voxels, extracted once per change.
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
    /// The map's octoboxes and the union with the objects' (when carving).
    map_octoboxes: Arc<Vec<Octobox>>,
    octoboxes: Arc<Vec<Octobox>>,
    /// Per carved object: the blocks its voxels fill, with their masks.
    object_blocks: rustc_hash::FxHashMap<String, Vec<Octobox>>,
    joints: Option<Vec<f64>>,
    use_map: bool,
    padding: f64,
    carve: Option<f64>,
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
            map_octoboxes: Arc::default(),
            octoboxes: Arc::default(),
            object_blocks: Default::default(),
            joints: None,
            use_map: params.use_map,
            padding: params.self_filter_padding,
            carve: params.carve_padding,
            objects_version: 0,
        }
    }

    /// Adds or moves an object; only its SPARK pairs are recomputed. When carving, the voxels
    /// it now fills are cleared at once.
    pub fn upsert_object(&mut self, object: Object) {
        let moved = self.env.object(&object.name) != Some(&object);
        self.objects_version += 1;
        self.pairs.upsert(&object);
        self.env
            .upsert(object.clone())
            .expect("objects were validated on arrival");
        match self.carve {
            Some(padding) if moved => self.carve_object(&object, padding),
            _ => {}
        }
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
        if self.object_blocks.remove(name).is_some() {
            self.merge_octoboxes();
        }
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
        let mask = CloudMask {
            robot: filter.as_ref(),
            objects: self.carve.map(|padding| (&self.env, padding)),
        };
        let map = Arc::make_mut(&mut self.map);
        let report = map.insert_cloud_masked(points, sensor_pose, &mask);
        if !report.changed.is_empty() {
            self.map_octoboxes = Arc::new(octoboxes(map));
            self.merge_octoboxes();
        }
        report
    }

    /// Clears the voxels `object` fills (grown by `padding`) and voxelises it for FLAME.
    fn carve_object(&mut self, object: &Object, padding: f64) {
        let alone = Environment::from_objects([object.clone()]).expect("validated on arrival");
        let placed = alone.placed().next().expect("one object");
        let half = self.map.resolution() / 2.0;
        let reach = padding + half;
        let (lo, hi) = (placed.lo.map(|v| v - reach), placed.hi.map(|v| v + reach));
        let inside = |c: [f64; 3]| alone.sphere_collides(c, reach);
        if self.map.any_occupied_in(lo, hi, inside) {
            let map = Arc::make_mut(&mut self.map);
            map.clear_occupied(lo, hi, inside);
            self.map_octoboxes = Arc::new(octoboxes(map));
        }
        // The object's own voxels (centres inside it), block by block.
        let map = &self.map;
        let (klo, khi) = (map.key_of(placed.lo), map.key_of(placed.hi));
        let mut blocks: rustc_hash::FxHashMap<BlockKey, u64> = Default::default();
        for x in klo[0]..=khi[0] {
            for y in klo[1]..=khi[1] {
                for z in klo[2]..=khi[2] {
                    if alone.sphere_collides(map.voxel_center([x, y, z]), half) {
                        let (b, bit) = OccupancyMap::split([x, y, z]);
                        *blocks.entry(b).or_default() |= 1 << bit;
                    }
                }
            }
        }
        let blocks = blocks
            .into_iter()
            .map(|(key, mask)| Octobox { key, mask })
            .collect();
        self.object_blocks.insert(object.name.clone(), blocks);
        self.merge_octoboxes();
    }

    /// FLAME's octoboxes: the map's, with the carved objects' voxels added.
    fn merge_octoboxes(&mut self) {
        if self.object_blocks.is_empty() {
            self.octoboxes = self.map_octoboxes.clone();
            return;
        }
        let mut all: rustc_hash::FxHashMap<BlockKey, u64> =
            self.map_octoboxes.iter().map(|o| (o.key, o.mask)).collect();
        for o in self.object_blocks.values().flatten() {
            *all.entry(o.key).or_default() |= o.mask;
        }
        let mut v: Vec<Octobox> = all
            .into_iter()
            .map(|(key, mask)| Octobox { key, mask })
            .collect();
        v.sort_by_key(|o| o.key);
        self.octoboxes = Arc::new(v);
    }

    /// A snapshot of the current state.
    pub fn snapshot(&self) -> Snapshot {
        let mut env = self.env.clone();
        if self.use_map {
            // The planner's grids, built here (the ingest thread) once per map state rather
            // than by the first plan.
            self.map.clearance();
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
