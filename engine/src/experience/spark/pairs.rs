//! The SPARK pairs of a changing set of objects, kept up to date one object at a time: an
//! update recomputes the pairs of the object that changed, found through a uniform grid over
//! the objects' padded bounding balls (a broad phase), so it costs what the object's
//! neighbourhood holds, not the whole scene. Snapshots share the pairs of unchanged objects.

use super::primitive::{box_of, pair_if_close, BoxPrimitive, SparkPair};
use crate::collision::Shape;
use crate::experience::ExperienceParams;
use crate::world::Object;
use std::collections::HashMap;
use std::sync::{Arc, OnceLock};

/// Grid cells an object may cover before it is kept aside and paired by a scan instead.
const MAX_CELLS: i64 = 512;

type Cell = [i32; 3];

/// One object and where it sits in the grid.
#[derive(Debug, Clone)]
struct Slot {
    object: Object,
    bounds: (BoxPrimitive, Shape),
    /// Grid cells covered, or None for an object too large for the grid.
    cells: Option<Vec<Cell>>,
}

/// The objects and their pairs (each pair closer than `d_pairs`, as SPARK defines them).
#[derive(Debug, Clone)]
pub struct PairSet {
    params: ExperienceParams,
    cell: f64,
    slots: Vec<Option<Slot>>,
    free: Vec<usize>,
    by_name: HashMap<String, usize>,
    grid: HashMap<Cell, Vec<usize>>,
    /// Objects too large for the grid.
    large: Vec<usize>,
    /// Per slot, the pairs it forms with lower slots (each pair stored once, shared by
    /// snapshots until that slot's pairs change).
    chunks: Vec<Arc<Vec<SparkPair>>>,
    count: usize,
}

impl PairSet {
    /// An empty set pairing objects closer than `params.d_pairs`.
    pub fn new(params: &ExperienceParams) -> PairSet {
        PairSet {
            params: params.clone(),
            cell: params.d_pairs.max(0.25),
            slots: Vec::new(),
            free: Vec::new(),
            by_name: HashMap::new(),
            grid: HashMap::new(),
            large: Vec::new(),
            chunks: Vec::new(),
            count: 0,
        }
    }

    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.count
    }

    /// True when no two objects are close.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Adds an object, or moves (or reshapes) the one of that name.
    pub fn upsert(&mut self, object: &Object) {
        let slot = match self.by_name.get(&object.name) {
            Some(&s) => {
                self.unlink(s);
                s
            }
            None => {
                let s = self.free.pop().unwrap_or_else(|| {
                    self.slots.push(None);
                    self.chunks.push(Arc::default());
                    self.slots.len() - 1
                });
                self.by_name.insert(object.name.clone(), s);
                s
            }
        };
        let bounds = box_of(object);
        let cells = self.cells_of(&bounds);
        match &cells {
            Some(cells) => {
                for c in cells {
                    self.grid.entry(*c).or_default().push(slot);
                }
            }
            None => self.large.push(slot),
        }
        self.slots[slot] = Some(Slot {
            object: object.clone(),
            bounds,
            cells,
        });
        // Its pairs: with lower slots into its own chunk, with higher ones into theirs.
        let mut own = Vec::new();
        for other in self.candidates(slot) {
            let (a, b) = (self.slot(slot), self.slot(other));
            let Some(pair) =
                pair_if_close((&a.object, &a.bounds), (&b.object, &b.bounds), &self.params)
            else {
                continue;
            };
            self.count += 1;
            match other < slot {
                true => own.push(pair),
                false => Arc::make_mut(&mut self.chunks[other]).push(pair),
            }
        }
        self.chunks[slot] = Arc::new(own);
    }

    /// Removes the object of this name and its pairs; false when unknown.
    pub fn remove(&mut self, name: &str) -> bool {
        let Some(slot) = self.by_name.remove(name) else {
            return false;
        };
        self.unlink(slot);
        self.slots[slot] = None;
        self.free.push(slot);
        true
    }

    /// The pairs now, sharing every unchanged chunk with this set.
    pub fn snapshot(&self) -> PairsSnapshot {
        PairsSnapshot {
            chunks: self
                .chunks
                .iter()
                .filter(|c| !c.is_empty())
                .cloned()
                .collect(),
            flat: OnceLock::new(),
        }
    }

    fn slot(&self, s: usize) -> &Slot {
        self.slots[s].as_ref().expect("a live slot")
    }

    /// Takes slot `s` out of the grid and drops every pair it is part of.
    fn unlink(&mut self, s: usize) {
        let neighbours = self.candidates(s);
        let name = self.slot(s).object.name.clone();
        for other in neighbours.into_iter().filter(|&o| o > s) {
            let chunk = &self.chunks[other];
            let before = chunk.len();
            if chunk.iter().any(|p| p.names.contains(&name)) {
                let chunk = Arc::make_mut(&mut self.chunks[other]);
                chunk.retain(|p| !p.names.contains(&name));
                self.count -= before - chunk.len();
            }
        }
        self.count -= self.chunks[s].len();
        self.chunks[s] = Arc::default();
        match self.slot(s).cells.clone() {
            Some(cells) => {
                for c in cells {
                    if let Some(v) = self.grid.get_mut(&c) {
                        v.retain(|&x| x != s);
                        if v.is_empty() {
                            self.grid.remove(&c);
                        }
                    }
                }
            }
            None => self.large.retain(|&x| x != s),
        }
    }

    /// The other live slots that may be within `d_pairs` of slot `s`, ascending.
    fn candidates(&self, s: usize) -> Vec<usize> {
        let mut out: Vec<usize> = match &self.slot(s).cells {
            // A large object meets everything.
            None => (0..self.slots.len())
                .filter(|&o| self.slots[o].is_some())
                .collect(),
            Some(cells) => cells
                .iter()
                .filter_map(|c| self.grid.get(c))
                .flatten()
                .copied()
                .chain(self.large.iter().copied())
                .collect(),
        };
        out.sort_unstable();
        out.dedup();
        out.retain(|&o| o != s);
        out
    }

    /// The cells the object's bounding ball, grown by half of `d_pairs`, covers (two objects
    /// closer than `d_pairs` then share a cell); None beyond [`MAX_CELLS`].
    fn cells_of(&self, (b, shape): &(BoxPrimitive, Shape)) -> Option<Vec<Cell>> {
        let c = b.pose.translation.vector;
        let r = shape.bounding_radius() + self.params.d_pairs / 2.0;
        let lo = [c.x - r, c.y - r, c.z - r].map(|v| (v / self.cell).floor() as i64);
        let hi = [c.x + r, c.y + r, c.z + r].map(|v| (v / self.cell).floor() as i64);
        let n = (0..3).map(|k| hi[k] - lo[k] + 1).product::<i64>();
        if !(1..=MAX_CELLS).contains(&n) {
            return None;
        }
        let mut cells = Vec::with_capacity(n as usize);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    cells.push([x as i32, y as i32, z as i32]);
                }
            }
        }
        Some(cells)
    }
}

/// The pairs of a [`PairSet`] at one moment: cheap to take (the chunks are shared); the flat
/// list retrieval reads is made on first use.
#[derive(Debug, Default)]
pub struct PairsSnapshot {
    chunks: Vec<Arc<Vec<SparkPair>>>,
    flat: OnceLock<Vec<SparkPair>>,
}

impl PairsSnapshot {
    /// Every pair, as one slice (built once per snapshot).
    pub fn pairs(&self) -> &[SparkPair] {
        self.flat
            .get_or_init(|| self.chunks.iter().flat_map(|c| c.iter().cloned()).collect())
    }

    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.chunks.iter().map(|c| c.len()).sum()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experience::spark::spark_pairs;
    use crate::scene::Scene;
    use crate::Pose;
    use rand::{Rng, SeedableRng};

    /// The pairs as sorted name pairs, for comparing sets.
    fn names(pairs: &[SparkPair]) -> Vec<[String; 2]> {
        let mut v: Vec<_> = pairs
            .iter()
            .map(|p| {
                let mut n = p.names.clone();
                n.sort();
                n
            })
            .collect();
        v.sort();
        v
    }

    #[test]
    fn incremental_pairs_equal_the_full_computation() {
        let params = ExperienceParams::default();
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let mut sut = PairSet::new(&params);
        let mut scene = Scene::default();
        let shape = |rng: &mut rand::rngs::StdRng| match rng.random_range(0..4) {
            0 => Shape::Sphere {
                radius: rng.random_range(0.02..0.2),
            },
            1 => Shape::Box {
                half_extents: [0.05, rng.random_range(0.02..0.4), 0.1],
            },
            2 => Shape::Cylinder {
                radius: 0.04,
                half_length: rng.random_range(0.05..0.3),
            },
            // Larger than the grid takes: paired by a scan.
            _ => Shape::Box {
                half_extents: [2.5, 2.5, 0.02],
            },
        };
        for step in 0..400 {
            let name = format!("o{}", rng.random_range(0..40));
            if rng.random_bool(0.15) {
                let known = scene.objects.iter().any(|o| o.name == name);
                assert_eq!(sut.remove(&name), known);
                scene.objects.retain(|o| o.name != name);
            } else {
                let o = Object {
                    name: name.clone(),
                    shape: shape(&mut rng),
                    pose: Pose::translation(
                        rng.random_range(0.0..1.5),
                        rng.random_range(-0.8..0.8),
                        rng.random_range(0.0..1.2),
                    ),
                };
                sut.upsert(&o);
                match scene.objects.iter_mut().find(|x| x.name == name) {
                    Some(x) => *x = o,
                    None => scene.objects.push(o),
                }
            }
            let expected = spark_pairs(&scene, &params);
            let snap = sut.snapshot();
            assert_eq!(sut.len(), expected.len(), "step {step}");
            assert_eq!(snap.len(), expected.len());
            assert_eq!(names(snap.pairs()), names(&expected), "step {step}");
        }
    }

    #[test]
    fn a_snapshot_keeps_its_pairs_while_the_set_changes() {
        let params = ExperienceParams::default();
        let mut sut = PairSet::new(&params);
        let at = |name: &str, x: f64| Object {
            name: name.into(),
            shape: Shape::Sphere { radius: 0.05 },
            pose: Pose::translation(x, 0.0, 0.5),
        };
        sut.upsert(&at("a", 0.0));
        sut.upsert(&at("b", 0.15));
        let before = sut.snapshot();
        sut.upsert(&at("b", 3.0));
        assert_eq!((before.len(), sut.len(), sut.snapshot().len()), (1, 0, 0));
        assert!(sut.remove("a") && !sut.remove("a"));
    }
}
