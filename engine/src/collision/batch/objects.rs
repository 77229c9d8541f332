//! The scene's objects as the batch checker tests them: their shapes in `f32`, placed once
//! per environment, and the tests of a ball in eight lanes against them (the scalar checker's
//! signed distances, compared squared).

use super::lanes::F8;
use crate::collision::Shape;
use crate::world::environment::PlacedObject;

/// An object's shape, in `f32`.
#[derive(Clone, Copy)]
pub(super) enum ObjectKind {
    Sphere { r: f32 },
    Box { h: [f32; 3] },
    Cylinder { r: f32, hl: f32 },
    Capsule { r: f32, hl: f32 },
}

/// An object as the lanes test it: rows of its inverse rotation, its origin, its world box
/// and its shape.
#[derive(Clone, Copy)]
pub(super) struct Object8 {
    pub(super) rot_t: [f32; 9],
    /// True when the rotation keeps the z axis on the world's z axis (a turn about the
    /// vertical, as of objects standing on a floor or a table, or such a turn upside down):
    /// five products place a point in its frame, not nine.
    pub(super) upright: bool,
    pub(super) t: [f32; 3],
    pub(super) lo: [f32; 3],
    pub(super) hi: [f32; 3],
    pub(super) kind: ObjectKind,
}

impl Object8 {
    /// An object of the environment, as the checkers place it.
    pub(super) fn of(o: PlacedObject<'_>) -> Self {
        let f = |v: f64| v as f32;
        Object8 {
            rot_t: std::array::from_fn(|k| f(o.rot_t[k / 3][k % 3])),
            upright: [o.rot_t[0][2], o.rot_t[1][2], o.rot_t[2][0], o.rot_t[2][1]] == [0.0; 4],
            t: o.t.map(f),
            lo: o.lo.map(f),
            hi: o.hi.map(f),
            kind: match *o.shape {
                Shape::Sphere { radius } => ObjectKind::Sphere { r: f(radius) },
                Shape::Box { half_extents } => ObjectKind::Box {
                    h: half_extents.map(f),
                },
                Shape::Cylinder {
                    radius,
                    half_length,
                } => ObjectKind::Cylinder {
                    r: f(radius),
                    hl: f(half_length),
                },
                Shape::Capsule {
                    radius,
                    half_length,
                } => ObjectKind::Capsule {
                    r: f(radius),
                    hl: f(half_length),
                },
            },
        }
    }
}

/// The objects of `mask` that the ball at `p` with radius `r` penetrates in some lane.
#[inline(always)]
pub(super) fn penetrated(objects: &[Object8], mask: u64, p: [F8; 3], r: f32) -> u64 {
    let mut out = 0u64;
    let mut m = mask;
    while m != 0 {
        let j = m.trailing_zeros() as usize;
        m &= m - 1;
        if penetrates(&objects[j], p, r) {
            out |= 1 << j;
        }
    }
    out
}

/// The lanes (bits) where the ball at `p` with radius `r` penetrates one of the objects of
/// `mask`: those behind [`penetrated`]'s verdict.
#[inline(always)]
pub(super) fn penetrating_lanes_of(objects: &[Object8], mask: u64, p: [F8; 3], r: f32) -> u32 {
    let mut lanes = 0;
    let mut m = mask;
    while m != 0 {
        let j = m.trailing_zeros() as usize;
        m &= m - 1;
        lanes |= penetrating_lanes(&objects[j], p, r);
    }
    lanes
}

/// The lanes (bits) where the ball at `p` with radius `r` penetrates object `o`
/// ([`penetrates`] lane by lane).
#[inline(always)]
pub(super) fn penetrating_lanes(o: &Object8, p: [F8; 3], r: f32) -> u32 {
    let (gap2, reach2) = penetration(o, p, r);
    gap2.lt_mask(reach2).bits()
}

/// True when the ball at `p` with radius `r` penetrates object `o` in some lane (the scalar checker's
/// test: signed distance below `r`).
#[inline(always)]
pub(super) fn penetrates(o: &Object8, p: [F8; 3], r: f32) -> bool {
    let (gap2, reach2) = penetration(o, p, r);
    gap2.any_lt(reach2)
}

/// What [`penetrates`] compares, per lane: a squared gap and the squared reach it must be
/// below.
#[inline(always)]
pub(super) fn penetration(o: &Object8, p: [F8; 3], r: f32) -> (F8, F8) {
    let d = [
        p[0] - F8::splat(o.t[0]),
        p[1] - F8::splat(o.t[1]),
        p[2] - F8::splat(o.t[2]),
    ];
    let (x, y, z) = if o.upright {
        // The general products below without the zeros' terms: the same values.
        // (No closure: it would be compiled without the caller's AVX2.)
        let m = &o.rot_t;
        let x = F8::splat(m[0]).mul_add(d[0], F8::splat(m[1]) * d[1]);
        let y = F8::splat(m[3]).mul_add(d[0], F8::splat(m[4]) * d[1]);
        (x, y, F8::splat(m[8]) * d[2])
    } else {
        let m = o.rot_t.map(F8::splat);
        let x = m[0].mul_add(d[0], m[1].mul_add(d[1], m[2] * d[2]));
        let y = m[3].mul_add(d[0], m[4].mul_add(d[1], m[5] * d[2]));
        let z = m[6].mul_add(d[0], m[7].mul_add(d[1], m[8] * d[2]));
        (x, y, z)
    };
    let zero = F8::splat(0.0);
    match o.kind {
        ObjectKind::Sphere { r: big } => {
            let reach = big + r;
            (x.mul_add(x, y.mul_add(y, z * z)), F8::splat(reach * reach))
        }
        ObjectKind::Box { h } => {
            let qx = (x.abs() - F8::splat(h[0])).max(zero);
            let qy = (y.abs() - F8::splat(h[1])).max(zero);
            let qz = (z.abs() - F8::splat(h[2])).max(zero);
            (qx.mul_add(qx, qy.mul_add(qy, qz * qz)), F8::splat(r * r))
        }
        ObjectKind::Cylinder { r: big, hl } => {
            let radial = (x.mul_add(x, y * y).sqrt() - F8::splat(big)).max(zero);
            let axial = (z.abs() - F8::splat(hl)).max(zero);
            (radial.mul_add(radial, axial * axial), F8::splat(r * r))
        }
        ObjectKind::Capsule { r: big, hl } => {
            let zc = z - z.max(F8::splat(-hl)).min(F8::splat(hl));
            let reach = big + r;
            (
                x.mul_add(x, y.mul_add(y, zc * zc)),
                F8::splat(reach * reach),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::{Environment, Object};
    use crate::Pose;
    use rand::{Rng, SeedableRng};

    /// An object turned about z alone is placed in its frame by the shorter products, with
    /// the same values as the general ones, bit for bit, for every shape; a tilted one is not
    /// taken as upright.
    #[test]
    fn upright_objects_test_as_the_general_rotation() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let shapes = [
            Shape::cuboid([0.3, 0.2, 0.1]),
            Shape::Sphere { radius: 0.1 },
            Shape::Cylinder {
                radius: 0.1,
                half_length: 0.2,
            },
            Shape::Capsule {
                radius: 0.05,
                half_length: 0.15,
            },
        ];
        let objects = shapes.iter().enumerate().map(|(i, shape)| Object {
            name: format!("o{i}"),
            shape: *shape,
            pose: Pose::from_parts(
                nalgebra::Translation3::new(0.6, -0.2 + 0.1 * i as f64, 0.8),
                nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.4 + i as f64),
            ),
        });
        let tilted = Object {
            name: "tilted".into(),
            shape: Shape::cuboid([0.3, 0.2, 0.1]),
            pose: Pose::from_parts(
                nalgebra::Translation3::new(0.6, 0.0, 0.8),
                nalgebra::UnitQuaternion::from_euler_angles(0.3, 0.0, 0.4),
            ),
        };
        let env = Environment::from_objects(objects.chain([tilted])).unwrap();
        let placed: Vec<Object8> = env.placed().map(Object8::of).collect();
        let upright: Vec<bool> = placed.iter().map(|o| o.upright).collect();
        assert_eq!(upright, [true, true, true, true, false]);
        let bits = |(a, b): (F8, F8)| (a.0.map(f32::to_bits), b.0.map(f32::to_bits));
        for o in &placed[..4] {
            let general = Object8 {
                upright: false,
                ..*o
            };
            for _ in 0..200 {
                let p: [F8; 3] = std::array::from_fn(|_| {
                    F8(std::array::from_fn(|_| rng.random_range(0.0..1.5)))
                });
                let r = rng.random_range(0.01..0.3);
                assert_eq!(
                    bits(penetration(o, p, r)),
                    bits(penetration(&general, p, r))
                );
            }
        }
    }
}
