//! The batch checker's kinematics: each link's pose for the eight lanes' configurations,
//! from its parent's and its joint, the common joints (turns about a coordinate axis, slides
//! along one, behind origins that only shift or permute axes) recognised once so that a batch
//! takes no decision but which columns turn.

use super::lanes::{Pose8, F8};
use super::BatchChecker;
use crate::robot::fk::JointFrames;
use crate::robot::{Motion, Robot};

/// How a link moves with its joint's variable.
#[derive(Clone, Copy)]
pub(super) enum Kind {
    Fixed,
    /// About a coordinate axis, with its sign: the common case, a quarter of the work. Holds
    /// the two other axes (the columns that turn).
    RevoluteAxis([usize; 2], f32),
    Revolute([f32; 3]),
    Prismatic([f32; 3]),
}

/// How a link's pose follows from its parent's: the joint origin (row-major rotation,
/// translation) in the parent's frame, the parent's frame, the motion and its variable.
#[derive(Clone, Copy)]
pub(super) struct Joint8 {
    origin: Origin,
    parent: Option<usize>,
    kind: Kind,
    variable: usize,
    /// The same, when it is the common joint (see [`AxisTurn`]).
    turn: Option<AxisTurn>,
    /// The same, when it is a slide along a coordinate axis (see [`AxisSlide`]).
    pub(super) slide: Option<AxisSlide>,
}

/// The common joint, recognised once: a turn about a coordinate axis, behind an origin whose
/// rotation is none or a signed permutation of the axes (quarter turns), below a parent. Its
/// pose is the parent's translated along at most one of the parent's axes (or by the origin's
/// general shift), its rotation the parent's columns, permuted, two of them turned: no
/// decisions left per batch but which shift and which columns.
#[derive(Clone, Copy)]
pub(super) struct AxisTurn {
    parent: usize,
    shift: Shift,
    /// Per column of the origin's rotation: the parent's column it takes, and its sign
    /// (`None`: the origin does not rotate).
    columns: Option<[(usize, f32); 3]>,
    /// The columns that turn.
    axes: [usize; 2],
    sign: f32,
    variable: usize,
}

/// A slide along a coordinate axis behind an origin that only shifts (a torso lift): the
/// parent's rotation, copied (or written once, when no turn lies above it), and the parent's
/// translation shifted along one of its axes by the variable.
#[derive(Clone, Copy)]
pub(super) struct AxisSlide {
    pub(super) parent: usize,
    shift: Shift,
    /// The parent's axis it slides along (below 3), and its sign.
    axis: usize,
    sign: f32,
    variable: usize,
    /// True when no turn lies above it: its rotation never changes.
    pub(super) fixed_rotation: bool,
}

/// An origin's translation, sorted by the work it takes.
#[derive(Clone, Copy)]
pub(super) enum Shift {
    None,
    /// Along the parent's axis `k` by `v` (the other components zero).
    Along(usize, f32),
    /// Along two of the parent's axes (`k` first, the lower), the third component zero.
    AlongTwo([(usize, f32); 2]),
    General,
}

/// Per link, what its pose in a batch is computed from (see [`Joint8`]), its frames as
/// `frames` gives them.
pub(super) fn joints(robot: &Robot, frames: &JointFrames) -> Vec<Joint8> {
    let links = robot.links();
    let f = |v: f64| v as f32;
    let mut joints8 = Vec::new();
    for (i, link) in links.iter().enumerate() {
        let o = frames.origin[i];
        let m = o.rotation.matrix();
        let r = std::array::from_fn(|k| f(m[(k / 3, k % 3)]));
        let t = o.translation.vector;
        let origin = Origin::new(r, [f(t.x), f(t.y), f(t.z)]);
        let axis = |a: &nalgebra::Unit<nalgebra::Vector3<f64>>| [f(a.x), f(a.y), f(a.z)];
        let (k, v) = match &link.motion {
            Motion::Fixed => (Kind::Fixed, 0),
            Motion::Revolute { axis: a, variable } => {
                let a = axis(a);
                match coordinate_axis(a) {
                    Some(k) => (
                        Kind::RevoluteAxis([(k + 1) % 3, (k + 2) % 3], a[k].signum()),
                        *variable,
                    ),
                    None => (Kind::Revolute(a), *variable),
                }
            }
            Motion::Prismatic { axis: a, variable } => (Kind::Prismatic(axis(a)), *variable),
        };
        let parent = link.parent.map(|p| frames.frame[p]);
        let columns = match origin.turn {
            Turn::Identity => Some(None),
            Turn::Axes(columns) => Some(Some(columns)),
            Turn::General => None,
        };
        let nonzero: Vec<usize> = (0..3).filter(|&k| origin.t[k] != 0.0).collect();
        let shift = match nonzero[..] {
            [] => Shift::None,
            [k] => Shift::Along(k, origin.t[k]),
            [k, l] => Shift::AlongTwo([(k, origin.t[k]), (l, origin.t[l])]),
            _ => Shift::General,
        };
        let turn = match (k, parent, columns) {
            (Kind::RevoluteAxis(axes, sign), Some(parent), Some(columns)) => Some(AxisTurn {
                parent,
                shift,
                columns,
                axes,
                sign,
                variable: v,
            }),
            _ => None,
        };
        let slide = match (k, parent, origin.turn) {
            (Kind::Prismatic(a), Some(parent), Turn::Identity) => {
                coordinate_axis(a).map(|axis| {
                    // Parents come first: a parent's rotation is fixed when it does not move
                    // or is itself a slide with a fixed rotation.
                    let fixed_rotation = !robot.link_moves(parent)
                        || joints8
                            .get(parent)
                            .and_then(|j: &Joint8| j.slide)
                            .is_some_and(|s| s.fixed_rotation);
                    AxisSlide {
                        parent,
                        shift,
                        axis,
                        sign: a[axis],
                        variable: v,
                        fixed_rotation,
                    }
                })
            }
            _ => None,
        };
        joints8.push(Joint8 {
            origin,
            parent,
            kind: k,
            variable: v,
            turn,
            slide,
        });
    }
    joints8
}

impl BatchChecker {
    /// Writes the pose of every moving link for the eight lanes' configurations.
    #[inline(always)]
    pub(super) fn pose_links(&mut self) {
        // Moved out while the poses are written: the loop then keeps its place in registers
        // instead of reloading the list and checking the index per link.
        let posed = std::mem::take(&mut self.posed);
        for &l in &posed {
            self.fk_link(l);
        }
        self.posed = posed;
    }

    #[inline(always)]
    pub(super) fn fk_link(&mut self, l: usize) {
        // The parent's pose times the constant joint origin, then the joint's own motion,
        // written in place: a pose is 384 bytes, and copies cost as much as the arithmetic.
        let joint = &self.joints[l];
        let origin = &joint.origin;
        let (done, rest) = self.poses.split_at_mut(l);
        let at = &mut rest[0];
        if let Some(slide) = &joint.slide {
            let parent = &done[slide.parent];
            if !slide.fixed_rotation {
                // Row by row: a copy of the 288-byte rotation was a call to `memcpy`.
                for (to, from) in at.r.iter_mut().zip(&parent.r) {
                    *to = *from;
                }
            }
            shift(origin, slide.shift, parent, at);
            let v = self.lanes[slide.variable] * F8::splat(slide.sign);
            let k = slide.axis.min(2);
            for row in 0..3 {
                at.t[row] = parent.r[row * 3 + k].mul_add(v, at.t[row]);
            }
            return;
        }
        if let Some(turn) = &joint.turn {
            let parent = &done[turn.parent];
            shift(origin, turn.shift, parent, at);
            let (s, c) = self.lanes[turn.variable].sin_cos();
            let s = s * F8::splat(turn.sign);
            match turn.columns {
                None => turn_columns(Some(&parent.r), &mut at.r, turn.axes, (s, c)),
                // The parent's columns permuted by the quarter turns and turned, in one pass.
                Some(columns) => turn_permuted(&parent.r, &mut at.r, columns, turn.axes, (s, c)),
            }
            return;
        }
        let parent = match joint.parent {
            None => {
                *at = Pose8::splat(origin.r, origin.t);
                None
            }
            Some(p) => {
                origin.translate(&done[p], at);
                Some(&done[p].r)
            }
        };
        if let Kind::RevoluteAxis(axes, sign) = joint.kind {
            let (s, c) = self.lanes[joint.variable].sin_cos();
            let s = s * F8::splat(sign);
            match (parent, origin.turn) {
                // The common case: the parent's rotation turned straight into place.
                (Some(r), Turn::Identity) => turn_columns(Some(r), &mut at.r, axes, (s, c)),
                // Turned in place: a copy of the 288-byte rotation was a call to `memcpy`.
                (Some(r), _) => {
                    origin.rotate(r, &mut at.r);
                    turn_columns(None, &mut at.r, axes, (s, c));
                }
                (None, _) => turn_columns(None, &mut at.r, axes, (s, c)),
            }
            return;
        }
        if let Some(r) = parent {
            origin.rotate(r, &mut at.r);
        }
        match joint.kind {
            Kind::Fixed | Kind::RevoluteAxis(..) => {}
            Kind::Revolute(axis) => {
                at.r = rotation(axis, self.lanes[joint.variable]).r_after(&at.r);
            }
            Kind::Prismatic(axis) => {
                let v = self.lanes[joint.variable];
                at.t = at.apply(axis.map(|a| F8::splat(a) * v));
            }
        }
    }
}

/// A joint origin (row-major rotation `r`, translation `t`), with its rotation sorted by the
/// work it takes: none, a signed permutation of the axes (quarter turns, common in robot
/// descriptions), or a general product.
#[derive(Clone, Copy)]
struct Origin {
    r: [f32; 9],
    t: [f32; 3],
    turn: Turn,
}

#[derive(Clone, Copy)]
enum Turn {
    Identity,
    /// Column `j` of the rotation is `sign · e[axis]`: `(axis, sign)` per column.
    Axes([(usize, f32); 3]),
    General,
}

impl Origin {
    fn new(r: [f32; 9], t: [f32; 3]) -> Self {
        let column = |j: usize| -> Option<(usize, f32)> {
            let c = [r[j], r[3 + j], r[6 + j]];
            let i = (0..3).find(|&i| (c[i].abs() - 1.0).abs() < 1e-6)?;
            let rest = (0..3).filter(|&k| k != i).all(|k| c[k].abs() < 1e-6);
            rest.then_some((i, c[i].signum()))
        };
        let turn = match [column(0), column(1), column(2)] {
            [Some(a), Some(b), Some(c)] if [a, b, c] == [(0, 1.0), (1, 1.0), (2, 1.0)] => {
                Turn::Identity
            }
            [Some(a), Some(b), Some(c)] => Turn::Axes([a, b, c]),
            _ => Turn::General,
        };
        Origin { r, t, turn }
    }

    /// `out.t` = the translation of `parent · self` (zero components skipped).
    #[inline(always)]
    fn translate(&self, parent: &Pose8, out: &mut Pose8) {
        let a = &parent.r;
        out.t = parent.t;
        for (k, &v) in self.t.iter().enumerate() {
            if v != 0.0 {
                let v = F8::splat(v);
                for row in 0..3 {
                    out.t[row] = a[row * 3 + k].mul_add(v, out.t[row]);
                }
            }
        }
    }

    /// `out` = the rotation `a · self.r`, permuting columns when it can.
    #[inline(always)]
    fn rotate(&self, a: &[F8; 9], out: &mut [F8; 9]) {
        match self.turn {
            // Row by row: a copy of the whole 288 bytes is a call to `memcpy`.
            Turn::Identity => {
                for row in 0..3 {
                    let r: [F8; 3] = [a[row * 3], a[row * 3 + 1], a[row * 3 + 2]];
                    out[row * 3..row * 3 + 3].copy_from_slice(&r);
                }
            }
            Turn::Axes(axes) => permute_columns(a, out, axes),
            Turn::General => *out = Pose8::splat(self.r, [0.0; 3]).r_after(a),
        }
    }
}

/// `at.t` = the translation of `parent · origin`, its kind `shift` recognised beforehand: the
/// same arithmetic as [`Origin::translate`] (zero components skipped).
#[inline(always)]
fn shift(origin: &Origin, shift: Shift, parent: &Pose8, at: &mut Pose8) {
    match shift {
        Shift::None => at.t = parent.t,
        // Loops, not `array::from_fn`: its closures were left uninlined (so without AVX2)
        // once the batch checker grew.
        Shift::Along(k, v) => {
            let (k, v) = (k.min(2), F8::splat(v));
            for row in 0..3 {
                at.t[row] = parent.r[row * 3 + k].mul_add(v, parent.t[row]);
            }
        }
        Shift::AlongTwo([(k, v), (l, w)]) => {
            let (k, l, v, w) = (k.min(2), l.min(2), F8::splat(v), F8::splat(w));
            for row in 0..3 {
                let t = parent.r[row * 3 + k].mul_add(v, parent.t[row]);
                at.t[row] = parent.r[row * 3 + l].mul_add(w, t);
            }
        }
        Shift::General => origin.translate(parent, at),
    }
}

/// `out` = the rotation `a` times a signed permutation: column `j` of `out` is column
/// `columns[j].0` of `a`, negated when `columns[j].1` is negative.
#[inline(always)]
fn permute_columns(a: &[F8; 9], out: &mut [F8; 9], columns: [(usize, f32); 3]) {
    for row in 0..3 {
        for (j, &(i, sign)) in columns.iter().enumerate() {
            let v = a[row * 3 + i];
            out[row * 3 + j] = if sign > 0.0 { v } else { F8::splat(0.0) - v };
        }
    }
}

/// `to = from` (or `to` itself, `from` being `None`) turned by the lane angles whose sine
/// and cosine are `(s, c)` about the coordinate axis other than `[i, j]`: those two columns
/// turn, the third is copied.
#[inline(always)]
fn turn_columns(from: Option<&[F8; 9]>, to: &mut [F8; 9], axes: [usize; 2], sc: (F8, F8)) {
    // Column numbers known at compile time: no index arithmetic or bounds checks.
    match axes {
        [1, 2] => turn_columns_of::<1, 2, 0>(from, to, sc),
        [2, 0] => turn_columns_of::<2, 0, 1>(from, to, sc),
        _ => turn_columns_of::<0, 1, 2>(from, to, sc),
    }
}

#[inline(always)]
fn turn_columns_of<const I: usize, const J: usize, const K: usize>(
    from: Option<&[F8; 9]>,
    to: &mut [F8; 9],
    (s, c): (F8, F8),
) {
    for row in 0..3 {
        // A row's two entries are read before either is written: in place is safe.
        let (a, b) = match from {
            Some(f) => (f[row * 3 + I], f[row * 3 + J]),
            None => (to[row * 3 + I], to[row * 3 + J]),
        };
        to[row * 3 + I] = a.mul_add(c, b * s);
        to[row * 3 + J] = b.mul_sub(c, a * s);
        if let Some(f) = from {
            to[row * 3 + K] = f[row * 3 + K];
        }
    }
}

/// `to` = `from` with its columns permuted by `columns` (as [`permute_columns`]), then turned
/// as [`turn_columns`] turns them, in one pass: the permutation's signs go into the sine and
/// cosine (products by ±1, exact), and each column is read from `from` where it lies, so no
/// permuted copy is written and read back.
#[inline(always)]
fn turn_permuted(
    from: &[F8; 9],
    to: &mut [F8; 9],
    columns: [(usize, f32); 3],
    axes: [usize; 2],
    sc: (F8, F8),
) {
    match axes {
        [1, 2] => turn_permuted_of::<1, 2, 0>(from, to, columns, sc),
        [2, 0] => turn_permuted_of::<2, 0, 1>(from, to, columns, sc),
        _ => turn_permuted_of::<0, 1, 2>(from, to, columns, sc),
    }
}

#[inline(always)]
fn turn_permuted_of<const I: usize, const J: usize, const K: usize>(
    from: &[F8; 9],
    to: &mut [F8; 9],
    columns: [(usize, f32); 3],
    (s, c): (F8, F8),
) {
    let ((i, sign_i), (j, sign_j), (k, sign_k)) = (columns[I], columns[J], columns[K]);
    // Column numbers (below 3), said so: the reads below need no bounds checks.
    let (i, j, k) = (i.min(2), j.min(2), k.min(2));
    let (sign_i, sign_j) = (F8::splat(sign_i), F8::splat(sign_j));
    let (c_i, s_i, c_j, s_j) = (c * sign_i, s * sign_i, c * sign_j, s * sign_j);
    let sign_k = F8::splat(sign_k);
    for row in 0..3 {
        let (a, b) = (from[row * 3 + i], from[row * 3 + j]);
        to[row * 3 + I] = a.mul_add(c_i, b * s_j);
        to[row * 3 + J] = b.mul_sub(c_j, a * s_i);
        to[row * 3 + K] = from[row * 3 + k] * sign_k;
    }
}

/// Rotation by the lane angles `q` about the unit `axis` (Rodrigues).
#[inline(always)]
fn rotation(axis: [f32; 3], q: F8) -> Pose8 {
    let (s, c) = q.sin_cos();
    let one_c = F8::splat(1.0) - c;
    let [x, y, z] = axis.map(F8::splat);
    let (xs, ys, zs) = (x * s, y * s, z * s);
    let (xc, yc, zc) = (x * one_c, y * one_c, z * one_c);
    Pose8 {
        r: [
            x * xc + c,
            x * yc - zs,
            x * zc + ys,
            y * xc + zs,
            y * yc + c,
            y * zc - xs,
            z * xc - ys,
            z * yc + xs,
            z * zc + c,
        ],
        t: [F8::splat(0.0); 3],
    }
}

/// The coordinate axis that joint axis `a` lies along exactly (its other components zero, as
/// `f32` gives them), if any: such a turn or slide touches two columns or one (see [`Kind`]).
fn coordinate_axis(a: [f32; 3]) -> Option<usize> {
    (0..3).find(|&k| a[k].abs() == 1.0 && (0..3).all(|m| m == k || a[m] == 0.0))
}
