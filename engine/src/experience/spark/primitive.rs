//! SPARK's local primitive: a pair of boxes (pose + size each; non-box objects enter as their
//! bounding boxes) whose objects are closer than `d_pairs`, and the pair metric.

use crate::collision::parry::shape_distance;
use crate::collision::Shape;
use crate::experience::ExperienceParams;
use crate::scene::Scene;
use crate::world::Object;
use crate::Pose;

/// A box: pose in the base frame and full size (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxPrimitive {
    /// Pose of the box centre.
    pub pose: Pose,
    /// Full size along the box's x, y, z.
    pub size: [f64; 3],
}

impl BoxPrimitive {
    /// The bounding box of an object's shape, in the object's frame.
    pub fn of(shape: &Shape, pose: &Pose) -> Self {
        let h = shape.local_half_extents();
        BoxPrimitive {
            pose: *pose,
            size: [2.0 * h[0], 2.0 * h[1], 2.0 * h[2]],
        }
    }

    /// Box distance: `w_s·(w_T·‖Δt‖ + (1−w_T)·angle) + (1−w_s)·‖Δsize‖`, a metric.
    pub fn distance(&self, other: &BoxPrimitive, p: &ExperienceParams) -> f64 {
        raw_distance(&self.raw(), &other.raw(), p)
    }

    /// The box as plain numbers (the form batched distance computations use).
    pub(crate) fn raw(&self) -> RawBox {
        let t = self.pose.translation.vector;
        let q = self.pose.rotation.coords;
        RawBox {
            t: [t.x, t.y, t.z],
            q: [q.x, q.y, q.z, q.w],
            s: self.size,
        }
    }
}

/// A box as plain numbers: translation, unit quaternion (x, y, z, w) and size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RawBox {
    pub t: [f64; 3],
    pub q: [f64; 4],
    pub s: [f64; 3],
}

/// The box distance on raw boxes: the single formula behind [`BoxPrimitive::distance`] and the
/// retrieval's batched distances, so both give the same bits.
#[inline(always)]
pub(crate) fn raw_distance(a: &RawBox, b: &RawBox, p: &ExperienceParams) -> f64 {
    let sq = |x: f64| x * x;
    let dt = (sq(a.t[0] - b.t[0]) + sq(a.t[1] - b.t[1]) + sq(a.t[2] - b.t[2])).sqrt();
    // Rotation angle between the orientations, 2·acos(|q₁·q₂|); below ~3 mrad from the chord
    // ‖q₁ − s·q₂‖ (s the sign of q₁·q₂), where acos loses its accuracy.
    let dot = a.q[0] * b.q[0] + a.q[1] * b.q[1] + a.q[2] * b.q[2] + a.q[3] * b.q[3];
    let angle = if dot.abs() > 1.0 - 1e-6 {
        let s = if dot < 0.0 { -1.0 } else { 1.0 };
        let chord = (sq(a.q[0] - s * b.q[0])
            + sq(a.q[1] - s * b.q[1])
            + sq(a.q[2] - s * b.q[2])
            + sq(a.q[3] - s * b.q[3]))
        .sqrt();
        2.0 * chord + chord * chord * chord / 12.0
    } else {
        2.0 * acos_unit(dot.abs())
    };
    let ds = (sq(a.s[0] - b.s[0]) + sq(a.s[1] - b.s[1]) + sq(a.s[2] - b.s[2])).sqrt();
    p.w_s * (p.w_t * dt + (1.0 - p.w_t) * angle) + (1.0 - p.w_s) * ds
}

/// `acos(x)` for `x` in [0, 1] (clamped) to within 2e-8 rad (Abramowitz & Stegun 4.4.46): the
/// retrieval's hot spot, several times cheaper than libm's. The metric tree prunes with a slack
/// far above this error, so tree and linear scan stay identical.
#[inline(always)]
fn acos_unit(x: f64) -> f64 {
    const A: [f64; 8] = [
        1.570_796_305_0,
        -0.214_598_801_6,
        0.088_978_987_4,
        -0.050_174_304_6,
        0.030_891_881_0,
        -0.017_088_125_6,
        0.006_670_090_1,
        -0.001_262_491_1,
    ];
    let x = x.clamp(0.0, 1.0);
    let p = A.iter().rev().fold(0.0, |acc, a| acc * x + a);
    (1.0 - x).sqrt() * p
}

/// SPARK's local primitive: two nearby boxes, plus the names of the objects they came from.
#[derive(Debug, Clone, PartialEq)]
pub struct SparkPair {
    /// First box.
    pub a: BoxPrimitive,
    /// Second box.
    pub b: BoxPrimitive,
    /// Object names (not part of the distance).
    pub names: [String; 2],
}

impl SparkPair {
    /// Pair distance: the smaller of the two pairings' summed box distances (a metric).
    ///
    /// ```
    /// use ember_engine::experience::{BoxPrimitive, ExperienceParams, SparkPair};
    /// use ember_engine::Pose;
    /// let b = |x: f64| BoxPrimitive { pose: Pose::translation(x, 0.0, 0.0), size: [0.1; 3] };
    /// let p = SparkPair { a: b(0.0), b: b(1.0), names: ["a".into(), "b".into()] };
    /// let swapped = SparkPair { a: b(1.0), b: b(0.0), names: ["b".into(), "a".into()] };
    /// assert_eq!(p.distance(&swapped, &ExperienceParams::default()), 0.0);
    /// ```
    pub fn distance(&self, other: &SparkPair, p: &ExperienceParams) -> f64 {
        let straight = self.a.distance(&other.a, p) + self.b.distance(&other.b, p);
        let crossed = self.a.distance(&other.b, p) + self.b.distance(&other.a, p);
        straight.min(crossed)
    }

    /// A key that is equal for pairs equal up to 1 cm, 0.01 in quaternion components and
    /// ordering: the deduplication key of the database.
    pub fn dedup_key(&self) -> Vec<i64> {
        let q = |b: &BoxPrimitive| {
            let t = b.pose.translation.vector;
            let mut r = b.pose.rotation.coords;
            if r.w < 0.0 {
                r = -r;
            }
            let mut k: Vec<i64> = [t.x, t.y, t.z]
                .iter()
                .map(|v| (v * 100.0).round() as i64)
                .collect();
            k.extend(
                [r.x, r.y, r.z, r.w]
                    .iter()
                    .map(|v| (v * 100.0).round() as i64),
            );
            k.extend(b.size.iter().map(|v| (v * 100.0).round() as i64));
            k
        };
        let (ka, kb) = (q(&self.a), q(&self.b));
        if ka <= kb {
            [ka, kb].concat()
        } else {
            [kb, ka].concat()
        }
    }
}

/// An object's bounding box, as a primitive and as a shape.
pub(crate) fn box_of(o: &Object) -> (BoxPrimitive, Shape) {
    let b = BoxPrimitive::of(&o.shape, &o.pose);
    (b, Shape::cuboid(b.size))
}

/// The pair of `a` and `b` when their boxes are closer than `d_pairs`.
pub(crate) fn pair_if_close(
    (oa, (ba, sa)): (&Object, &(BoxPrimitive, Shape)),
    (ob, (bb, sb)): (&Object, &(BoxPrimitive, Shape)),
    params: &ExperienceParams,
) -> Option<SparkPair> {
    // Cheap reject before GJK.
    let reach = sa.bounding_radius() + sb.bounding_radius() + params.d_pairs;
    if (ba.pose.translation.vector - bb.pose.translation.vector).norm() > reach {
        return None;
    }
    (shape_distance(sa, &ba.pose, sb, &bb.pose) < params.d_pairs).then(|| SparkPair {
        a: *ba,
        b: *bb,
        names: [oa.name.clone(), ob.name.clone()],
    })
}

/// Every pair of scene objects closer than `d_pairs` (exact distance between their bounding
/// boxes), as SPARK primitives.
pub fn spark_pairs(scene: &Scene, params: &ExperienceParams) -> Vec<SparkPair> {
    let boxes: Vec<_> = scene.objects.iter().map(box_of).collect();
    let mut out = Vec::new();
    for i in 0..boxes.len() {
        for j in i + 1..boxes.len() {
            let (a, b) = (&scene.objects[i], &scene.objects[j]);
            out.extend(pair_if_close((a, &boxes[i]), (b, &boxes[j]), params));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_acos_matches_libm() {
        for i in 0..=10_000 {
            let x = i as f64 / 10_000.0;
            assert!((acos_unit(x) - x.acos()).abs() < 3e-8, "x = {x}");
        }
    }
}
