//! The world model: objects, what the robot holds, the occupancy map and their decompositions
//! (SPARK pairs, FLAME octoboxes), kept up to date one input at a time, and the immutable
//! snapshots planning works on. The daemon's ingest thread owns one; `ember train` rebuilds one
//! from a recording.

use super::map::{BlockKey, CloudMask, InsertReport, MapParams, OccupancyMap};
use super::{Environment, Object};
use crate::collision::checker::Contact;
use crate::collision::exact::ExactChecker;
use crate::collision::Shape;
use crate::experience::flame::{octoboxes, octoboxes_updated, Octobox};
use crate::experience::spark::{PairSet, PairsSnapshot};
use crate::experience::ExperienceParams;
use crate::robot::spheres::PlacedSpheres;
use crate::robot::Robot;
use crate::scene::{AttachedObject, Scene};
use crate::Pose;
use std::sync::Arc;
use thiserror::Error;

/// One change to the objects of a world, as motion capture or a client reports it.
#[derive(Debug, Clone, PartialEq)]
pub enum ObjectChange {
    /// Add or move a world object.
    Upsert(Object),
    /// Remove an object, from the world or from the robot's hand.
    Remove(String),
    /// The robot now holds object `id` on `link`, posed at `grasp` in the link's frame:
    /// `shape` given, or (None) the shape of the tracked object of that name, which leaves the
    /// world.
    Attach {
        /// The robot link holding it.
        link: String,
        /// Object name.
        id: String,
        /// Its shape; None: the tracked object's.
        shape: Option<Shape>,
        /// Its pose in the link's frame.
        grasp: Pose,
    },
    /// The robot lets go of `id`: it becomes a world object at `pose` (base frame).
    Detach {
        /// Object name.
        id: String,
        /// Where it now stands.
        pose: Pose,
    },
}

/// Why a change was refused; the world is left as it was.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ChangeError {
    /// No object of this name, in the world or held.
    #[error("unknown object '{0}'")]
    UnknownObject(String),
    /// The robot has no link of this name.
    #[error("attach to unknown link '{0}'")]
    UnknownLink(String),
    /// The robot already holds an object of this name.
    #[error("object '{0}' is already attached")]
    AlreadyAttached(String),
    /// Detach of an object the robot does not hold.
    #[error("detach of '{0}', which is not attached")]
    NotAttached(String),
    /// Held at the latest joint state, the object would touch the robot (outside the link
    /// holding it).
    #[error("attached object '{object}' would touch link '{link}' at the current joint state")]
    AttachCollides {
        /// Object name.
        object: String,
        /// The link it touches.
        link: String,
    },
}

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
    /// A box (base frame, metres: min and max corners) in which space never observed is an
    /// obstacle for planning, as occupied voxels are (with `use_map`); `None`: unknown space is
    /// free everywhere (OctoMap's and MoveIt's convention). The robot's own volume there, with
    /// what it holds, is observed free at each joint state (see [`World::set_joints`]) and
    /// when it takes hold of an object.
    pub unknown_obstacles: Option<([f64; 3], [f64; 3])>,
}

/// How far (radians or metres, per joint) a joint state may be from the last one whose volume
/// [`World::set_joints`] observed and not be looked at again: a milliradian moves a point a
/// metre out by a millimetre, far inside the self-filter's padding.
const LOOKED_TOLERANCE: f64 = 1e-3;

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
    /// Objects (+ map when configured, with the unknown space of
    /// [`WorldParams::unknown_obstacles`] occupied) for collision checking.
    pub env: Environment,
    /// Counts object changes: equal versions, equal objects.
    pub objects_version: u64,
    /// The robot with what it holds (`scene.attached`); None: it holds nothing.
    pub holding: Option<Arc<Robot>>,
}

impl Snapshot {
    /// The robot as planning sees it in this snapshot: `robot` with what it holds.
    pub fn robot<'r>(&'r self, robot: &'r Robot) -> &'r Robot {
        self.holding.as_deref().unwrap_or(robot)
    }
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
    /// The robot with the attached objects (None: it holds nothing).
    holding: Option<Arc<Robot>>,
    use_map: bool,
    padding: f64,
    carve: Option<f64>,
    /// See [`WorldParams::unknown_obstacles`]; `None` without `use_map` (planning ignores
    /// the map then).
    unknown: Option<([f64; 3], [f64; 3])>,
    /// With `unknown`: the map with the unknown space in that box occupied (what planning
    /// avoids; FLAME and monitoring see the map itself), made by the first snapshot after a
    /// change of the map, so that a burst of changes (joint states) remakes it once.
    planned_map: std::cell::OnceCell<Arc<OccupancyMap>>,
    /// With `unknown`: the last joint state whose volume was observed (see
    /// [`World::set_joints`]).
    looked: Option<Vec<f64>>,
    objects_version: u64,
}

/// Objects larger than this many voxels (within the map's bounds) are voxelised by whole
/// blocks: a client's 10 m box costs the ingest thread milliseconds, not seconds.
const VOXELISE_MAX: i64 = 1 << 20;

/// The octoboxes of the one object in `alone` (its box `[lo, hi]`) in `map`'s grid: the voxels
/// whose centre ball touches it, within the map's bounds; whole blocks touched by the block's
/// ball past [`VOXELISE_MAX`] voxels.
fn voxelise(map: &OccupancyMap, alone: &Environment, lo: [f64; 3], hi: [f64; 3]) -> Vec<Octobox> {
    let Some((lo, hi)) = map.clip_to_bounds(lo, hi) else {
        return Vec::new();
    };
    let (klo, khi) = (map.key_of(lo), map.key_of(hi));
    let voxels: i64 = (0..3).map(|i| (khi[i] - klo[i] + 1) as i64).product();
    let mut blocks: rustc_hash::FxHashMap<BlockKey, u64> = Default::default();
    if voxels <= VOXELISE_MAX {
        let half = map.resolution() / 2.0;
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
    } else {
        let (blo, bhi) = (klo.map(|v| v >> 2), khi.map(|v| v >> 2));
        let reach = map.block_size() * 3f64.sqrt() / 2.0;
        for x in blo[0]..=bhi[0] {
            for y in blo[1]..=bhi[1] {
                for z in blo[2]..=bhi[2] {
                    if alone.sphere_collides(map.block_center([x, y, z]), reach) {
                        blocks.insert([x, y, z], u64::MAX);
                    }
                }
            }
        }
    }
    blocks
        .into_iter()
        .map(|(key, mask)| Octobox { key, mask })
        .collect()
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
            holding: None,
            use_map: params.use_map,
            padding: params.self_filter_padding,
            carve: params.carve_padding,
            unknown: params.unknown_obstacles.filter(|_| params.use_map),
            planned_map: std::cell::OnceCell::new(),
            looked: None,
            objects_version: 0,
        }
    }

    /// Marks what planning sees of the map out of date after the map changed (see
    /// [`World::planned_map`]).
    fn map_changed(&mut self) {
        self.planned_map = std::cell::OnceCell::new();
    }

    /// The map planning avoids: with [`WorldParams::unknown_obstacles`], the map with the
    /// unknown space in the box occupied (remade on first use after a change), else the map.
    fn planned_map(&self) -> &Arc<OccupancyMap> {
        match self.unknown {
            Some((lo, hi)) => self.planned_map.get_or_init(|| {
                let mut planned = self.map.with_unknown_occupied(lo, hi);
                planned.refresh_clearance();
                Arc::new(planned)
            }),
            None => &self.map,
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

    /// Applies one object change for `robot` (the robot without what it holds); a refused
    /// change leaves the world as it was.
    pub fn apply(&mut self, robot: &Robot, change: ObjectChange) -> Result<(), ChangeError> {
        match change {
            ObjectChange::Upsert(object) => {
                if self.held(&object.name).is_some() {
                    // A tracked object the robot holds is moved by the robot, not by reports.
                    return Err(ChangeError::AlreadyAttached(object.name));
                }
                self.upsert_object(object);
            }
            ObjectChange::Remove(id) => {
                if !self.remove_object(&id) && !self.release(robot, &id) {
                    return Err(ChangeError::UnknownObject(id));
                }
            }
            ObjectChange::Attach {
                link,
                id,
                shape,
                grasp,
            } => self.attach(robot, link, id, shape, grasp)?,
            ObjectChange::Detach { id, pose } => {
                let Some(i) = self.held(&id) else {
                    return Err(ChangeError::NotAttached(id));
                };
                let shape = self.scene.attached[i].object.shape;
                self.release(robot, &id);
                self.upsert_object(Object {
                    name: id,
                    shape,
                    pose,
                });
            }
        }
        Ok(())
    }

    /// Where `id` is in `scene.attached`, when held.
    fn held(&self, id: &str) -> Option<usize> {
        self.scene.attached.iter().position(|a| a.object.name == id)
    }

    /// Attaches (see [`ObjectChange::Attach`]), refusing what would touch the robot at once.
    fn attach(
        &mut self,
        robot: &Robot,
        link: String,
        id: String,
        shape: Option<Shape>,
        grasp: Pose,
    ) -> Result<(), ChangeError> {
        if self.held(&id).is_some() {
            return Err(ChangeError::AlreadyAttached(id));
        }
        if robot.link_index(&link).is_none() {
            return Err(ChangeError::UnknownLink(link));
        }
        let shape = match shape {
            Some(s) => s,
            None => match self.env.object(&id) {
                Some(o) => o.shape,
                None => return Err(ChangeError::UnknownObject(id)),
            },
        };
        let mut scene = Scene {
            attached: self.scene.attached.clone(),
            ..Scene::default()
        };
        scene.attached.push(AttachedObject {
            link,
            object: Object {
                name: id.clone(),
                shape,
                pose: grasp,
            },
        });
        let holding = scene
            .robot(robot)
            .expect("the link was checked")
            .into_owned();
        if let Some(q) = self.joints.as_ref().filter(|q| robot.validate(q).is_ok()) {
            let nothing = Environment::new();
            let touches = |r: &Robot| match ExactChecker::new(r, &nothing).contact(q) {
                Some(Contact::SelfCollision { link_a, link_b }) => Some((link_a, link_b)),
                _ => None,
            };
            if let Some((a, b)) = touches(&holding).filter(|c| touches(robot) != Some(c.clone())) {
                let link = if a == id { b } else { a };
                return Err(ChangeError::AttachCollides { object: id, link });
            }
        }
        self.remove_object(&id);
        self.objects_version += 1;
        self.scene.attached = scene.attached;
        self.holding = Some(Arc::new(holding));
        // What the robot holds is part of its volume, observed free at once where it sits
        // now in the unknown box.
        self.looked = None;
        self.look(robot);
        Ok(())
    }

    /// Drops the held object `id` (false when not held).
    fn release(&mut self, robot: &Robot, id: &str) -> bool {
        let Some(i) = self.held(id) else {
            return false;
        };
        self.objects_version += 1;
        self.scene.attached.remove(i);
        self.holding = match self.scene.attached.is_empty() {
            true => None,
            false => Some(Arc::new(
                self.scene
                    .robot(robot)
                    .expect("links were checked on attach")
                    .into_owned(),
            )),
        };
        true
    }

    /// Removes a world object and its pairs; false when unknown.
    pub fn remove_object(&mut self, name: &str) -> bool {
        if !self.scene.objects.iter().any(|o| o.name == name) {
            return false;
        }
        self.objects_version += 1;
        self.scene.objects.retain(|o| o.name != name);
        self.pairs.remove(name);
        let _ = self.env.remove(name);
        if self.object_blocks.remove(name).is_some() {
            self.merge_octoboxes();
        }
        true
    }

    /// Sets the joint state. With [`WorldParams::unknown_obstacles`], the unknown voxels in the
    /// box that `robot`'s padded spheres (the self-filter's) touch there are observed free:
    /// the robot is there, so nothing else is, and a plan starting where the robot stands is
    /// not refused for its own unseen volume, with or without a cloud taken there. True
    /// when that changed what planning sees (the next snapshot remakes planning's map once,
    /// however many joint states came before it).
    pub fn set_joints(&mut self, robot: &Robot, q: Vec<f64>) -> bool {
        self.joints = Some(q);
        self.look(robot)
    }

    /// With [`WorldParams::unknown_obstacles`]: observes the volume of `robot` (with what it
    /// holds) at the latest joint state free in the box (see [`World::set_joints`]); true
    /// when that changed what planning sees.
    fn look(&mut self, robot: &Robot) -> bool {
        let Some((lo, hi)) = self.unknown else {
            return false;
        };
        let robot = self.holding.as_deref().unwrap_or(robot);
        let Some(q) = self.joints.as_ref().filter(|q| robot.validate(q).is_ok()) else {
            return false;
        };
        // A robot standing still streams the same state (give or take its encoders' noise):
        // within `LOOKED_TOLERANCE` of the last state looked at, its spheres, padded by
        // centimetres, cover nothing new worth a look (~0.2 ms with the Fetch's).
        if self.looked.as_ref().is_some_and(|last| {
            last.iter()
                .zip(q)
                .all(|(a, b)| (a - b).abs() <= LOOKED_TOLERANCE)
        }) {
            return false;
        }
        self.looked = Some(q.clone());
        let placed = PlacedSpheres::at(robot, q, self.padding);
        let touched = self.map.unknown_touched(placed.balls(), lo, hi);
        if touched.is_empty() {
            return false;
        }
        Arc::make_mut(&mut self.map).observe_free(&touched);
        self.map_changed();
        true
    }

    /// Folds a cloud into the map, dropping the robot's own points at the latest joint state
    /// (and non-finite ones); says what was folded in.
    pub fn insert_cloud(
        &mut self,
        robot: &Robot,
        points: &[[f32; 3]],
        sensor_pose: &crate::Pose,
    ) -> InsertReport {
        // What the robot holds is part of it here: the self-filter drops its points too.
        let robot = self.holding.as_deref().unwrap_or(robot);
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
        if self.use_map {
            map.refresh_clearance();
        }
        if !report.changed.is_empty() {
            self.map_octoboxes =
                Arc::new(octoboxes_updated(&self.map_octoboxes, map, &report.changed));
            self.merge_octoboxes();
        }
        // Free space observed turns unknown space free too, whether or not any occupancy
        // changed.
        self.map_changed();
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
            if self.use_map {
                map.refresh_clearance();
            }
            self.map_octoboxes = Arc::new(octoboxes(map));
            self.map_changed();
        }
        let blocks = voxelise(&self.map, &alone, placed.lo, placed.hi);
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
            // The planner's grids, kept up to date by the changes above; built here (the
            // ingest thread) when they are not, rather than by the first plan.
            let planned = self.planned_map();
            planned.clearance();
            env.set_map(Some(planned.clone()));
        }
        Snapshot {
            scene: self.scene.clone(),
            pairs: self.pairs.snapshot(),
            map: self.map.clone(),
            octoboxes: self.octoboxes.clone(),
            env,
            objects_version: self.objects_version,
            holding: self.holding.clone(),
        }
    }
}
