//! How far a motion can move the robot's geometry: per planning variable and link, a bound on
//! how far a point of the link moves per unit of the variable, for any configuration.
//!
//! A revolute joint turned by `δ` moves a point at most `δ` times its distance from the axis,
//! and that distance is at most the chain's length from the joint to the link (the joint
//! origins' offsets, a prismatic joint's travel added) plus the link's reach from its own
//! origin (the bound balls of its sphere model and of its exact geometry). A prismatic joint
//! moves every point after it by exactly `δ`. Moving the joints one after another, a
//! straight motion of differences `Δ` moves no point of link `l` by more than
//! `Σ_j |Δ_j| · reach[j][l]` ([`Sweep::link_motion`]): what certifies that a motion between
//! two states clear by that much is clear all the way (see
//! [`Validity::path_contact`](crate::planning::Validity::path_contact)).

use super::{Motion, Robot};

/// Per planning variable and link, how far a point of the link moves per unit of the variable
/// at most (see the module docs).
#[derive(Debug, Clone)]
pub struct Sweep {
    links: usize,
    /// `reach[j * links + l]`, zero where variable `j` does not move link `l`.
    reach: Vec<f64>,
}

impl Sweep {
    /// The bounds of `robot`.
    pub fn new(robot: &Robot) -> Self {
        let links = robot.links();
        let n = links.len();
        let mut reach = vec![0.0; robot.dof() * n];
        for l in 0..n {
            let spheres = robot.spheres().bounds.get(l).copied().flatten();
            let exact = robot.exact_model().link_bound(l);
            let own = |b: Option<([f64; 3], f64)>| {
                b.map_or(0.0, |(c, r)| {
                    (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() + r
                })
            };
            // From the current link's origin to any point of link `l`, at most.
            let mut along = own(spheres).max(own(exact));
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
                    }
                    Motion::Prismatic { variable, .. } => {
                        reach[variable * n + l] = 1.0;
                        let v = &robot.variables()[*variable];
                        offset += v.lower.abs().max(v.upper.abs());
                    }
                }
                along += offset;
                at = parent;
            }
        }
        Sweep { links: n, reach }
    }

    /// Writes into `out` (one per link) how far the straight motion whose per-variable
    /// differences are `delta` ([`Robot::deltas`]) moves any point of each link, at most.
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Pose;
    use nalgebra::Point3;
    use rand::{Rng, SeedableRng};

    /// On Fetch and the Panda, random short motions move no sphere centre and no corner of
    /// an exact part's bounding box (points of the geometry or around it) farther than the
    /// bound, measured at many states along each motion; and the bound is not vacuous.
    #[test]
    fn no_point_moves_farther_than_the_bound() {
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let sweep = Sweep::new(&robot);
            let mut rng = rand::rngs::StdRng::seed_from_u64(8);
            let n = robot.dof();
            let (mut a, mut target, mut b, mut step) =
                (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            let (mut delta, mut bound) = (vec![0.0; n], vec![0.0; robot.links().len()]);
            let mut q = vec![0.0; n];
            let mut tightest: f64 = 0.0;
            for _ in 0..300 {
                robot.sample_uniform(&mut rng, &mut a);
                robot.sample_uniform(&mut rng, &mut target);
                let t = rng.random_range(0.01..0.3) / robot.distance(&a, &target).max(1e-9);
                robot.step_towards(&a, &target, t.min(1.0), &mut b, &mut step);
                robot.deltas(&a, &b, &mut delta);
                sweep.link_motion(&delta, &mut bound);
                let points = |q: &[f64]| -> Vec<(usize, Point3<f64>)> {
                    let poses: Vec<Pose> = robot.link_poses(q).unwrap();
                    let mut out = Vec::new();
                    for (l, pose) in poses.iter().enumerate() {
                        for (c, _) in robot.spheres().link_spheres(l) {
                            out.push((l, pose * Point3::from(c)));
                        }
                    }
                    out
                };
                let start = points(&a);
                for k in 1..=16 {
                    robot.interpolate(&a, &b, k as f64 / 16.0, &mut q);
                    for ((l, p0), (_, p)) in start.iter().zip(points(&q)) {
                        let moved = (p - p0).norm();
                        assert!(
                            moved <= bound[*l] + 1e-9,
                            "{name}: link {l} moved {moved} m, bound {}",
                            bound[*l]
                        );
                        if moved > 1e-3 {
                            tightest = tightest.max(moved / bound[*l]);
                        }
                    }
                }
            }
            assert!(tightest > 0.3, "{name}: the bound is loose ({tightest})");
        }
    }
}
