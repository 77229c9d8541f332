//! The environment: named primitives posed in the robot base frame.

use super::map::OccupancyMap;
use crate::collision::distance::distance_point_shape;
use crate::collision::Shape;
use crate::Pose;
use nalgebra::Matrix3;
use std::sync::Arc;
use thiserror::Error;

/// A named object in the world.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// Unique name.
    pub name: String,
    /// Geometry in the object's frame.
    pub shape: Shape,
    /// Pose of the object's frame in the robot base frame.
    pub pose: Pose,
}

/// An object that cannot be added or changed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum WorldError {
    /// Another object already has this name.
    #[error("object '{0}' already exists")]
    DuplicateName(String),
    /// No object has this name.
    #[error("no object named '{0}'")]
    UnknownObject(String),
    /// A dimension is zero, negative, NaN or infinite.
    #[error("object '{name}' has an invalid shape {shape:?}")]
    InvalidShape {
        /// Object name.
        name: String,
        /// The shape given.
        shape: Shape,
    },
    /// The pose has a NaN or infinite component.
    #[error("object '{0}' has a non-finite pose")]
    InvalidPose(String),
}

/// Precomputed world → object transform and broad-phase radius of one object.
#[derive(Debug, Clone, Copy)]
struct ObjectFrame {
    /// Rows of the inverse rotation.
    rot_t: [[f64; 3]; 3],
    /// World position of the object's origin.
    t: [f64; 3],
    /// World axis-aligned bounding box of the shape: the broad phase.
    lo: [f64; 3],
    hi: [f64; 3],
}

impl ObjectFrame {
    fn new(object: &Object) -> Self {
        let r: Matrix3<f64> = object.pose.rotation.to_rotation_matrix().into_inner();
        let rt = r.transpose();
        let t = object.pose.translation.vector;
        // World half extents of the rotated local box: |R| * h.
        let h = object.shape.local_half_extents();
        let extent = [0, 1, 2].map(|i| (0..3).map(|j| r[(i, j)].abs() * h[j]).sum::<f64>());
        ObjectFrame {
            rot_t: [
                [rt[(0, 0)], rt[(0, 1)], rt[(0, 2)]],
                [rt[(1, 0)], rt[(1, 1)], rt[(1, 2)]],
                [rt[(2, 0)], rt[(2, 1)], rt[(2, 2)]],
            ],
            t: [t.x, t.y, t.z],
            lo: [0, 1, 2].map(|i| t[i] - extent[i]),
            hi: [0, 1, 2].map(|i| t[i] + extent[i]),
        }
    }

    #[inline]
    fn to_local(self, p: [f64; 3]) -> [f64; 3] {
        let d = [p[0] - self.t[0], p[1] - self.t[1], p[2] - self.t[2]];
        let m = &self.rot_t;
        [
            m[0][0] * d[0] + m[0][1] * d[1] + m[0][2] * d[2],
            m[1][0] * d[0] + m[1][1] * d[1] + m[1][2] * d[2],
            m[2][0] * d[0] + m[2][1] * d[1] + m[2][2] * d[2],
        ]
    }
}

/// An object as the checkers see it (see [`Environment::placed`]).
pub(crate) struct PlacedObject<'a> {
    pub rot_t: [[f64; 3]; 3],
    pub t: [f64; 3],
    pub lo: [f64; 3],
    pub hi: [f64; 3],
    pub shape: &'a crate::collision::Shape,
}

/// Everything the robot must not touch, in the robot base frame.
#[derive(Debug, Clone, Default)]
pub struct Environment {
    objects: Vec<Object>,
    frames: Vec<ObjectFrame>,
    map: Option<Arc<OccupancyMap>>,
}

impl Environment {
    /// An empty environment.
    pub fn new() -> Self {
        Self::default()
    }

    /// An environment holding `objects`.
    pub fn from_objects(objects: impl IntoIterator<Item = Object>) -> Result<Self, WorldError> {
        let mut env = Self::new();
        for o in objects {
            env.add(o)?;
        }
        Ok(env)
    }

    /// Sets (or clears) the occupancy map the robot must also avoid.
    pub fn set_map(&mut self, map: Option<Arc<OccupancyMap>>) {
        self.map = map;
    }

    /// The occupancy map, if any.
    pub fn map(&self) -> Option<&OccupancyMap> {
        self.map.as_deref()
    }

    /// The occupancy map, shared.
    pub(crate) fn shared_map(&self) -> Option<Arc<OccupancyMap>> {
        self.map.clone()
    }

    /// The objects, in insertion order.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// The object named `name`.
    pub fn object(&self, name: &str) -> Option<&Object> {
        self.objects.iter().find(|o| o.name == name)
    }

    /// Adds an object; its name must be new.
    pub fn add(&mut self, object: Object) -> Result<(), WorldError> {
        check(&object)?;
        if self.object(&object.name).is_some() {
            return Err(WorldError::DuplicateName(object.name));
        }
        self.frames.push(ObjectFrame::new(&object));
        self.objects.push(object);
        Ok(())
    }

    /// Adds the object or replaces the one with the same name.
    pub fn upsert(&mut self, object: Object) -> Result<(), WorldError> {
        check(&object)?;
        match self.objects.iter().position(|o| o.name == object.name) {
            Some(i) => {
                self.frames[i] = ObjectFrame::new(&object);
                self.objects[i] = object;
            }
            None => {
                self.frames.push(ObjectFrame::new(&object));
                self.objects.push(object);
            }
        }
        Ok(())
    }

    /// Removes the object named `name` and returns it.
    pub fn remove(&mut self, name: &str) -> Result<Object, WorldError> {
        let i = self
            .objects
            .iter()
            .position(|o| o.name == name)
            .ok_or_else(|| WorldError::UnknownObject(name.to_string()))?;
        self.frames.remove(i);
        Ok(self.objects.remove(i))
    }

    /// True when a ball at `center` (base frame) with `radius` penetrates any object.
    #[inline]
    pub fn sphere_collides(&self, center: [f64; 3], radius: f64) -> bool {
        self.sphere_contact(center, radius).is_some()
    }

    /// Distance along the ray `origin + t·dir` (unit `dir`, base frame) to the first object it
    /// hits within `max_t`. The map is not ray cast.
    pub fn ray_cast(&self, origin: [f64; 3], dir: [f64; 3], max_t: f64) -> Option<f64> {
        let mut best = max_t;
        let mut hit = false;
        for (f, o) in self.frames.iter().zip(&self.objects) {
            // AABB slab test first.
            let c = [0, 1, 2].map(|a| (f.lo[a] + f.hi[a]) / 2.0);
            let h = [0, 1, 2].map(|a| (f.hi[a] - f.lo[a]) / 2.0);
            let rel = [origin[0] - c[0], origin[1] - c[1], origin[2] - c[2]];
            match crate::collision::ray::ray_box(rel, dir, h) {
                Some(t) if t < best => {}
                _ => continue,
            }
            let lo = f.to_local(origin);
            let m = &f.rot_t;
            let ld = [0, 1, 2].map(|i| m[i][0] * dir[0] + m[i][1] * dir[1] + m[i][2] * dir[2]);
            if let Some(t) = crate::collision::ray::ray_shape(lo, ld, &o.shape) {
                if t < best {
                    best = t;
                    hit = true;
                }
            }
        }
        hit.then_some(best)
    }

    /// True when a ball overlaps an occupied voxel of the map (false without a map).
    #[inline]
    pub(crate) fn sphere_hits_map(&self, center: [f64; 3], radius: f64) -> bool {
        self.map
            .as_ref()
            .is_some_and(|m| m.sphere_collides(center, radius))
    }

    /// Name of the first object a ball at `center` with `radius` penetrates (`occupancy map` for
    /// an occupied voxel).
    pub fn sphere_contact(&self, center: [f64; 3], radius: f64) -> Option<&str> {
        if let Some(j) = (0..self.objects.len()).find(|&j| self.penetrates(j, center, radius)) {
            return Some(&self.objects[j].name);
        }
        match &self.map {
            Some(m) if m.sphere_collides(center, radius) => Some("occupancy map"),
            _ => None,
        }
    }

    /// Bit set of the objects a ball penetrates: bit `i` for object `i`, bit 63 for object 63
    /// and every object after it. The broad phase of the checker.
    #[inline]
    pub(crate) fn sphere_candidates(&self, center: [f64; 3], radius: f64) -> u64 {
        self.candidates_masked(center, radius, self.all_mask())
    }

    /// The mask selecting every object.
    #[inline]
    fn all_mask(&self) -> u64 {
        match self.objects.len() {
            n if n >= 64 => u64::MAX,
            n => (1u64 << n) - 1,
        }
    }

    /// Like [`Environment::sphere_candidates`], looking only at the objects in `mask`.
    #[inline]
    pub(crate) fn candidates_masked(&self, center: [f64; 3], radius: f64, mask: u64) -> u64 {
        let mut out = 0u64;
        self.scan_masked(mask, |j| {
            if self.penetrates(j, center, radius) {
                out |= 1u64 << j.min(63);
            }
            false
        });
        out
    }

    /// True when a ball penetrates one of the objects in `mask`.
    #[inline]
    pub(crate) fn sphere_collides_masked(&self, center: [f64; 3], radius: f64, mask: u64) -> bool {
        self.scan_masked(mask, |j| self.penetrates(j, center, radius))
    }

    /// Every object as the checkers place it: rows of the inverse rotation, world position of
    /// its origin, world bounding box (low and high corners) and shape.
    pub(crate) fn placed(&self) -> impl Iterator<Item = PlacedObject<'_>> + '_ {
        self.frames
            .iter()
            .zip(&self.objects)
            .map(|(f, o)| PlacedObject {
                rot_t: f.rot_t,
                t: f.t,
                lo: f.lo,
                hi: f.hi,
                shape: &o.shape,
            })
    }

    /// Calls `f` for each object index in `mask` until it returns true; returns whether it did.
    #[inline]
    fn scan_masked(&self, mask: u64, mut f: impl FnMut(usize) -> bool) -> bool {
        let mut m = mask;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let end = if i == 63 {
                self.objects.len()
            } else {
                (i + 1).min(self.objects.len())
            };
            for j in i..end {
                if f(j) {
                    return true;
                }
            }
        }
        false
    }

    #[inline]
    fn penetrates(&self, j: usize, center: [f64; 3], radius: f64) -> bool {
        let f = &self.frames[j];
        if center[0] + radius < f.lo[0]
            || center[0] - radius > f.hi[0]
            || center[1] + radius < f.lo[1]
            || center[1] - radius > f.hi[1]
            || center[2] + radius < f.lo[2]
            || center[2] - radius > f.hi[2]
        {
            return false;
        }
        distance_point_shape(f.to_local(center), &self.objects[j].shape) < radius
    }
}

fn check(object: &Object) -> Result<(), WorldError> {
    if !object.shape.is_valid() {
        return Err(WorldError::InvalidShape {
            name: object.name.clone(),
            shape: object.shape,
        });
    }
    let t = object.pose.translation.vector;
    let q = object.pose.rotation.coords;
    if !(t.iter().all(|v| v.is_finite()) && q.iter().all(|v| v.is_finite())) {
        return Err(WorldError::InvalidPose(object.name.clone()));
    }
    Ok(())
}

/// `n` boxes of full size `size`, named `box0`, `box1`, …, each centred at a point drawn from
/// `within` (x, y, z in turn): the crowded scenes unit tests check against.
#[cfg(test)]
pub(crate) fn random_boxes(
    rng: &mut impl rand::Rng,
    n: usize,
    size: [f64; 3],
    within: [std::ops::Range<f64>; 3],
) -> Environment {
    let objects: Vec<Object> = (0..n)
        .map(|i| Object {
            name: format!("box{i}"),
            shape: Shape::cuboid(size),
            pose: Pose::translation(
                rng.random_range(within[0].clone()),
                rng.random_range(within[1].clone()),
                rng.random_range(within[2].clone()),
            ),
        })
        .collect();
    Environment::from_objects(objects).unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn wall() -> Object {
        Object {
            name: "wall".into(),
            shape: Shape::cuboid([0.1, 2.0, 2.0]),
            pose: Pose::from_parts(
                Translation3::new(1.0, 0.0, 1.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
            ),
        }
    }

    #[test]
    fn sphere_touching_rotated_box_collides() {
        let sut = Environment::from_objects([wall()]).unwrap();
        assert!(sut.sphere_collides([1.0, 0.0, 1.0], 0.01));
        assert!(!sut.sphere_collides([0.5, 0.0, 1.0], 0.1));
        assert!(sut.sphere_collides([0.5, 0.0, 1.0], 0.5));
    }

    #[test]
    fn duplicate_and_invalid_objects_are_rejected() {
        let mut sut = Environment::from_objects([wall()]).unwrap();
        assert_eq!(
            sut.add(wall()),
            Err(WorldError::DuplicateName("wall".into()))
        );
        let mut bad = wall();
        bad.name = "bad".into();
        bad.shape = Shape::Sphere { radius: f64::NAN };
        assert!(matches!(sut.add(bad), Err(WorldError::InvalidShape { .. })));
    }

    #[test]
    fn masked_check_agrees_with_full_check() {
        let mut objects = Vec::new();
        for i in 0..70 {
            objects.push(Object {
                name: format!("o{i}"),
                shape: Shape::Sphere { radius: 0.05 },
                pose: Pose::translation(0.2 * i as f64, 0.0, 0.0),
            });
        }
        let sut = Environment::from_objects(objects).unwrap();
        for i in 0..140 {
            let c = [0.1 * i as f64, 0.03, 0.0];
            let mask = sut.sphere_candidates(c, 0.04);
            assert_eq!(sut.sphere_collides(c, 0.04), mask != 0);
            assert_eq!(
                sut.sphere_collides(c, 0.04),
                sut.sphere_collides_masked(c, 0.04, mask)
            );
        }
    }
}
