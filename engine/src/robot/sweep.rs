//! How far a motion can move the robot's geometry: per planning variable and link, a bound on
//! how far a point of the link moves per unit of the variable.
//!
//! A revolute joint turned by `δ` moves a point at most `δ` times its distance from the axis,
//! and that distance is at most the chain's length from the joint to the link (the joint
//! origins' offsets, a prismatic joint's travel added) plus the link's reach from its own
//! origin (the bound balls of its sphere model and of its exact geometry). A prismatic joint
//! moves every point after it by exactly `δ`. Moving the joints one after another, a
//! straight motion of differences `Δ` moves no point of link `l` by more than
//! `Σ_j |Δ_j| · reach[j][l]` ([`Sweep::link_motion`]), for any configuration.
//!
//! Between two known states the bound is tighter ([`Step::half_motion`]). With the end
//! states' poses the centre `c` of each link's bound ball is known at both ends, and along the
//! motion it leaves the chord between them by at most `K / 8`, `K` bounding its acceleration
//! (the joints' rates are constant along a straight motion): `K ≤ 3 · S · M`, with `S = Σ_j |Δ_j|`
//! and `M` the structural bound above (each joint's turn of the axes before it, and of the
//! offsets after it, is at most `S` times the structural reach). A point within `ρ` of the
//! centre turns about it by at most `ρ · Θ`, `Θ` the sum of the revolute joints' turns that
//! move the link. So up to the motion's midpoint every point of the link stays within
//! `½ (|c₁ − c₀| + ρ · Θ) + K / 8` of where it is at the start, and from the midpoint on within
//! as much of where it is at the end: what certifies that a motion between two states clear
//! by that much is clear all the way (see [`crate::planning::Validity::path_contact`]).
//! The chord is what a motion actually moves the link, where the structural bound adds up
//! every joint's turn at the chain's full length.

use super::{Motion, Robot};
use crate::Pose;
use nalgebra::{Point3, Vector3};

/// Slack of the chords, metres: the centres may come from `f32` poses (the batch checker's
/// lanes), rounded far less than this at robot scale.
pub(crate) const CENTRE_SLACK: f64 = 1e-5;

/// Per planning variable and link, how far a point of the link moves per unit of the variable
/// at most (see the module docs).
#[derive(Debug, Clone)]
pub struct Sweep {
    links: usize,
    /// `reach[j * links + l]`, zero where variable `j` does not move link `l`.
    reach: Vec<f64>,
    /// Per link with a sphere model: a ball holding its geometry, centred on the sphere
    /// model's bound (centre in the link's frame, radius).
    ball: Vec<Option<([f64; 3], f64)>>,
    /// Per variable: it turns revolute joints only (a prismatic joint turns nothing).
    revolute: Vec<bool>,
    /// `moves[j * links + l]`: variable `j` moves link `l` (drives a joint on its chain).
    moves: Vec<bool>,
    /// Per variable: the links it moves, and those it does not.
    split: Vec<(Vec<usize>, Vec<usize>)>,
}

impl Sweep {
    /// The bounds of `robot`.
    pub fn new(robot: &Robot) -> Self {
        let links = robot.links();
        let (n, dof) = (links.len(), robot.dof());
        let mut reach = vec![0.0; dof * n];
        let mut moves = vec![false; dof * n];
        let mut ball = vec![None; n];
        for l in 0..n {
            let spheres = robot.spheres().bounds.get(l).copied().flatten();
            let exact = robot.exact_model().link_bound(l);
            // Centred where the sphere model's bound is (the point the batch checker places).
            ball[l] = spheres.map(|s| exact.map_or(s, |e| enclosing(s, e)));
            // From the current link's origin to any point of link `l`, at most.
            let own =
                |b: Option<([f64; 3], f64)>| b.map_or(0.0, |(c, r)| Vector3::from(c).norm() + r);
            let mut along = own(ball[l]).max(own(exact));
            let mut at = l;
            loop {
                let link = &links[at];
                let Some(parent) = link.parent else { break };
                let mut offset = link.origin.translation.vector.norm();
                match &link.motion {
                    Motion::Fixed => {}
                    Motion::Revolute { variable, .. } => {
                        // The axis passes through the link's origin.
                        let r: &mut f64 = &mut reach[variable * n + l];
                        *r = r.max(along);
                        moves[variable * n + l] = true;
                    }
                    Motion::Prismatic { variable, .. } => {
                        reach[variable * n + l] = 1.0;
                        moves[variable * n + l] = true;
                        let v = &robot.variables()[*variable];
                        offset += v.lower.abs().max(v.upper.abs());
                    }
                }
                along += offset;
                at = parent;
            }
        }
        let mut revolute = vec![true; dof];
        for link in links {
            if let Motion::Prismatic { variable, .. } = link.motion {
                revolute[variable] = false;
            }
        }
        let split = (0..dof)
            .map(|j| (0..n).partition(|&l| moves[j * n + l]))
            .collect();
        Sweep {
            links: n,
            reach,
            ball,
            revolute,
            moves,
            split,
        }
    }

    /// Writes into `out` (one per link) how far the straight motion whose per-variable
    /// differences are `delta` ([`Robot::deltas`]) moves any point of each link, at most, from
    /// any state.
    pub fn link_motion(&self, delta: &[f64], out: &mut [f64]) {
        let out = &mut out[..self.links];
        out.fill(0.0);
        for (d, row) in delta.iter().zip(self.reach.chunks_exact(self.links)) {
            let d = d.abs();
            for (o, r) in out.iter_mut().zip(row) {
                *o += d * r;
            }
        }
    }

    /// Writes into `out` (one per link) the centre of each link's bound ball at the state
    /// whose link poses are `poses` ([`Robot::forward_kinematics`]): the sphere model's bound
    /// centre, where the batch checker places it too
    /// ([`BatchChecker::bound_centres`](crate::collision::batch::BatchChecker::bound_centres));
    /// the link's origin where it has no sphere model.
    pub fn centres(&self, poses: &[Pose], out: &mut [[f64; 3]]) {
        for ((o, pose), ball) in out.iter_mut().zip(poses).zip(&self.ball) {
            let c = ball.map_or([0.0; 3], |(c, _)| c);
            *o = (pose * Point3::from(c)).coords.into();
        }
    }

    /// Writes into `out` what the straight motion of differences `delta` bounds alone, for
    /// [`Step::half_motion`] between two states that far apart.
    pub fn step(&self, delta: &[f64], out: &mut Step) {
        let n = self.links;
        out.half_structural.resize(n, 0.0);
        out.rest.resize(n, 0.0);
        self.link_motion(delta, &mut out.half_structural);
        let s: f64 = delta.iter().map(|d| d.abs()).sum();
        for (l, (h, rest)) in out
            .half_structural
            .iter_mut()
            .zip(&mut out.rest)
            .enumerate()
        {
            let structural = *h;
            *h *= 0.5;
            // The revolute turns that move the link, its radius, and the chord's bend.
            let turn: f64 = (0..delta.len())
                .filter(|&j| self.revolute[j] && self.moves[j * n + l])
                .map(|j| delta[j].abs())
                .sum();
            *rest = match self.ball[l] {
                Some((_, radius)) => 0.5 * radius * turn + 3.0 * s * structural / 8.0,
                None => f64::INFINITY,
            };
        }
    }

    /// Writes into `out` (`links × links`, symmetric) how far the straight motion of
    /// differences `delta` changes the distance between any point of one link and any point
    /// of another from what it is at the nearer end: half the structural bound of their motion
    /// relative to each other, which only the joints between them make (those before both
    /// carry both alike). Two links with no joint between them keep their distances.
    pub fn pair_half_motion(&self, delta: &[f64], out: &mut [f64]) {
        let n = self.links;
        let out = &mut out[..n * n];
        out.fill(0.0);
        for (j, d) in delta.iter().enumerate() {
            let d = 0.5 * d.abs();
            if d == 0.0 {
                continue;
            }
            let reach = &self.reach[j * n..][..n];
            let (moved, still) = &self.split[j];
            for &a in moved {
                let r = d * reach[a];
                for &b in still {
                    out[a * n + b] += r;
                    out[b * n + a] += r;
                }
            }
        }
    }
}

/// What a straight motion's differences bound alone ([`Sweep::step`]); the states at its ends
/// give the rest ([`Step::half_motion`]).
#[derive(Debug, Clone, Default)]
pub struct Step {
    /// Per link: half the structural bound.
    half_structural: Vec<f64>,
    /// Per link: half the turn times the link's radius, plus the chord's bend (infinite for a
    /// link without geometry: the structural bound holds).
    rest: Vec<f64>,
}

impl Step {
    /// Writes into `out` (one per link) how far any point of each link strays along the
    /// motion from where it is at the nearer end (the start up to the midpoint, the end after
    /// it), `ends` the links' [`Sweep::centres`] at the motion's two states (or the batch
    /// checker's, in `f32`): see the module docs; at most half the structural bound.
    pub fn half_motion(&self, ends: (&[[f64; 3]], &[[f64; 3]]), out: &mut [f64]) {
        let chords = ends.0.iter().zip(ends.1);
        for (o, ((h, rest), (c0, c1))) in out
            .iter_mut()
            .zip(self.half_structural.iter().zip(&self.rest).zip(chords))
        {
            let chord = (Vector3::from(*c1) - Vector3::from(*c0)).norm() + CENTRE_SLACK;
            *o = h.min(0.5 * chord + rest);
        }
    }
}

/// A ball centred on `a`'s centre holding balls `a` and `b` (centre, radius).
fn enclosing(a: ([f64; 3], f64), (e, re): ([f64; 3], f64)) -> ([f64; 3], f64) {
    let (c, r) = a;
    let gap = (Vector3::from(e) - Vector3::from(c)).norm();
    (c, r.max(gap + re))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// On Fetch and the Panda, random short motions (a few validation steps long, as
    /// certification asks) move no point of the geometry (sphere centres, and a point on
    /// each sphere's surface) farther than the structural bound, nor farther from its place
    /// at the nearer end than the bound between the two states, measured at many states along
    /// each motion; neither bound is vacuous, and the one between states is less than half the
    /// structural one on the hand. Nor does any two links' distance change by more than their
    /// pair's bound, which is zero for links with no joint between them.
    #[test]
    fn no_point_moves_farther_than_the_bounds() {
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let sweep = Sweep::new(&robot);
            let mut rng = rand::rngs::StdRng::seed_from_u64(8);
            let (n, links) = (robot.dof(), robot.links().len());
            let (mut a, mut target, mut b, mut step) =
                (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            let (mut delta, mut bound, mut half) =
                (vec![0.0; n], vec![0.0; links], vec![0.0; links]);
            let (mut c0, mut c1) = (vec![[0.0; 3]; links], vec![[0.0; 3]; links]);
            let (mut poses, mut end_poses) =
                (vec![Pose::identity(); links], vec![Pose::identity(); links]);
            let mut q = vec![0.0; n];
            let (mut tightest, mut half_tightest): (f64, f64) = (0.0, 0.0);
            let mut ratios = Vec::new();
            let mut pairs = vec![0.0; links * links];
            let mut step_bounds = Step::default();
            // Links with no joint between them were seen keeping their distance; the tightest
            // bound of the others.
            let (mut rigid_seen, mut pair_tightest): (bool, f64) = (false, 0.0);
            for _ in 0..300 {
                robot.sample_uniform(&mut rng, &mut a);
                robot.sample_uniform(&mut rng, &mut target);
                let t = rng.random_range(0.005..0.1) / robot.distance(&a, &target).max(1e-9);
                robot.step_towards(&a, &target, t.min(1.0), &mut b, &mut step);
                robot.deltas(&a, &b, &mut delta);
                sweep.link_motion(&delta, &mut bound);
                robot.forward_kinematics(&a, &mut poses);
                robot.forward_kinematics(&b, &mut end_poses);
                sweep.centres(&poses, &mut c0);
                sweep.centres(&end_poses, &mut c1);
                sweep.step(&delta, &mut step_bounds);
                step_bounds.half_motion((&c0, &c1), &mut half);
                // Per sphere: its centre and a point on its surface, in the link's frame.
                let points: Vec<(usize, Point3<f64>)> = (0..links)
                    .flat_map(|l| robot.spheres().link_spheres(l).map(move |s| (l, s)))
                    .flat_map(|(l, (c, r))| {
                        let u = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)).normalize();
                        [(l, Point3::from(c)), (l, Point3::from(c) + u * r)]
                    })
                    .collect();
                let firsts: Vec<usize> = (0..points.len())
                    .filter(|&i| i == 0 || points[i].0 != points[i - 1].0)
                    .collect();
                let at = |poses: &[Pose]| -> Vec<Point3<f64>> {
                    points.iter().map(|(l, p)| poses[*l] * p).collect()
                };
                let (start, end) = (at(&poses), at(&end_poses));
                sweep.pair_half_motion(&delta, &mut pairs);
                for k in 1..32 {
                    let t = k as f64 / 32.0;
                    robot.interpolate(&a, &b, t, &mut q);
                    robot.forward_kinematics(&q, &mut poses);
                    let now = at(&poses);
                    // Between links: the first point of each (a sphere centre) against the
                    // others' first points.
                    for (i, j) in firsts
                        .iter()
                        .flat_map(|&i| firsts.iter().map(move |&j| (i, j)))
                    {
                        let (la, lb) = (points[i].0, points[j].0);
                        let nearer = if t <= 0.5 { &start } else { &end };
                        let change =
                            ((now[i] - now[j]).norm() - (nearer[i] - nearer[j]).norm()).abs();
                        let cap = pairs[la * links + lb];
                        assert!(
                            la == lb || change <= cap + 1e-9,
                            "{name}: links {la} and {lb} came {change} m nearer or farther \
                             (bound {cap})"
                        );
                        rigid_seen |= la != lb && cap == 0.0 && change < 1e-9;
                        if change > 1e-3 {
                            pair_tightest = pair_tightest.max(change / cap);
                        }
                    }
                    for (i, ((l, _), p)) in points.iter().zip(now).enumerate() {
                        let moved = (p - start[i]).norm();
                        let strayed = (p - if t <= 0.5 { start[i] } else { end[i] }).norm();
                        assert!(
                            moved <= bound[*l] + 1e-9 && strayed <= half[*l] + 1e-9,
                            "{name}: link {l} moved {moved} m (bound {}), strayed {strayed} m \
                             (bound {})",
                            bound[*l],
                            half[*l]
                        );
                        if moved > 1e-3 {
                            tightest = tightest.max(moved / bound[*l]);
                        }
                        if strayed > 1e-3 {
                            half_tightest = half_tightest.max(strayed / half[*l]);
                        }
                    }
                }
                // The link with geometry that moves most (a hand's).
                let far = (0..links)
                    .filter(|&l| robot.spheres().link_spheres(l).next().is_some())
                    .max_by(|&i, &j| bound[i].total_cmp(&bound[j]))
                    .unwrap();
                ratios.push(half[far] / (0.5 * bound[far]));
            }
            assert!(
                rigid_seen && pair_tightest > 0.3,
                "{name}: no two links rigidly joined, or the pairs' bound loose ({pair_tightest})"
            );
            ratios.sort_by(f64::total_cmp);
            let median = ratios[ratios.len() / 2];
            assert!(tightest > 0.3, "{name}: the bound is loose ({tightest})");
            assert!(
                half_tightest > 0.3 && median < 0.6,
                "{name}: the bound between states is loose ({half_tightest}) or no tighter \
                 on the hand (median {median} of the structural one)"
            );
        }
    }
}
