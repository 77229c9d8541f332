//! Path simplification: redundant-vertex removal, then rounds of corner cutting, each followed
//! by a local pruning. Every motion the result is made of has been checked at the resolution,
//! including the pieces of the old segments a cut leaves (their states differ from the old
//! segment's), so no full re-validation is needed.
//!
//! No random shortcuts: on the MotionBenchMaker sets, pruning the search's path and three
//! rounds of corner cutting return shorter paths than forty shortcuts and one round did, for
//! −8% to +21% of the instructions on the Fetch (table_pick, box, cage) and about half the
//! time on the Panda (`docs/history.md`, session 45).

use super::validity::Validity;

/// Rounds of corner cutting at most (the path's corners round off a little more each time).
const CUT_ROUNDS: usize = 3;

/// A cut corner's new ends lie this fraction of the way from the corner to its neighbours;
/// where the motion between them is not free, the second fraction is tried (a corner beside an
/// obstacle is cut closer).
const CUTS: [f64; 2] = [0.5, 0.25];

/// After a round of cutting, pruning looks at most this many waypoints ahead of each kept
/// one: a cut leaves nearly straight runs, and longer jumps, tried from every waypoint, mostly
/// fail at the cost of a check each (two or four ahead: longer paths on the MotionBenchMaker
/// Fetch sets, or more checks for about the same).
const PRUNE_AFTER_CUT: usize = 3;

/// Shortens `path` in place; endpoints are kept.
pub fn simplify(checker: &mut Validity<'_>, path: &mut Vec<Vec<f64>>) {
    remove_redundant(checker, path, usize::MAX);
    for _ in 0..CUT_ROUNDS {
        if !cut_corners(checker, path) {
            break;
        }
        remove_redundant(checker, path, PRUNE_AFTER_CUT);
    }
}

/// Corner cutting (Chaikin's step): each interior waypoint gives way to the points a fraction
/// of the way to its neighbours ([`CUTS`], the first whose motion between them is free).
/// Returns whether a corner was cut. A piece of an old segment left between two kept points is
/// checked as it is finalised; should one fail (its states differ from the segment's), the
/// path is kept as it was.
fn cut_corners(checker: &mut Validity<'_>, path: &mut Vec<Vec<f64>>) -> bool {
    let robot = checker.robot();
    if path.len() < 3 {
        return false;
    }
    let dof = robot.dof();
    let mut out = vec![path[0].clone()];
    // Whether the last point of `out` was made by a cut (so the piece from it onwards lies
    // inside an old segment and is checked when its other end is known).
    let mut after_cut = false;
    let (mut a, mut b) = (vec![0.0; dof], vec![0.0; dof]);
    for i in 1..path.len() - 1 {
        let prev = out.last().expect("starts with the first waypoint");
        // The new edge first (where collisions are), then the piece before it.
        let cut = CUTS.iter().any(|&f| {
            robot.interpolate(&path[i], prev, f, &mut a);
            robot.interpolate(&path[i], &path[i + 1], f, &mut b);
            checker.reach_valid(&a, &b) && checker.reach_valid(prev, &a)
        });
        if cut {
            out.extend([a.clone(), b.clone()]);
            after_cut = true;
            continue;
        }
        if after_cut && !checker.motion_valid(prev, &path[i]) {
            return false;
        }
        out.push(path[i].clone());
        after_cut = false;
    }
    let last = path.last().expect("three waypoints or more");
    if after_cut && !checker.motion_valid(out.last().expect("non-empty"), last) {
        return false;
    }
    out.push(last.clone());
    let cut = out.len() > path.len();
    *path = out;
    cut
}

/// Greedy pruning: from each kept vertex, jump to the farthest vertex it sees directly, at
/// most `reach` vertices ahead.
fn remove_redundant(checker: &mut Validity<'_>, path: &mut Vec<Vec<f64>>, reach: usize) {
    if path.len() < 3 {
        return;
    }
    let mut kept = vec![path[0].clone()];
    let mut i = 0;
    while i < path.len() - 1 {
        let mut j = (path.len() - 1).min(i.saturating_add(reach));
        while j > i + 1 && !checker.motion_valid(&path[i], &path[j]) {
            j -= 1;
        }
        kept.push(path[j].clone());
        i = j;
    }
    *path = kept;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::path_length;
    use crate::robot::Robot;
    use crate::world::environment::random_boxes;
    use rand::{Rng, SeedableRng};

    /// Corner cutting keeps the ends, never lengthens a path, and leaves only motions the
    /// checker finds free; among boxes most corners are cut at the midpoints, some closer to
    /// the corner (where the midpoints' motion is not free), and a few kept.
    #[test]
    fn cut_corners_shorten_paths_through_free_motions_only() {
        let robot = Robot::builtin("panda").unwrap();
        let n = robot.dof();
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        // Corners cut at each fraction of `CUTS`, and corners kept.
        let (mut cut, mut kept) = ([0; CUTS.len()], 0);
        for _ in 0..ENVS {
            let env = random_boxes(
                &mut rng,
                BOXES,
                [0.25, 0.25, 0.2],
                [0.2..0.8, -0.5..0.5, 0.1..1.0],
            );
            let mut checker = Validity::new(&robot, &env, 1.0 / 32.0, 0.0);
            let mut tried = 0;
            for _ in 0..4000 {
                if tried == 30 {
                    break;
                }
                // Four waypoints, each motion free.
                let mut path = vec![vec![0.0; n]; 4];
                for q in &mut path {
                    robot.sample_uniform(&mut rng, q);
                    for v in q.iter_mut() {
                        *v *= rng.random_range(0.5..1.0);
                    }
                }
                if !path.iter().all(|q| checker.is_valid(q))
                    || !path.windows(2).all(|w| checker.motion_valid(&w[0], &w[1]))
                {
                    continue;
                }
                tried += 1;
                let before = path.clone();
                let changed = cut_corners(&mut checker, &mut path);
                assert_eq!(changed, path.len() > before.len());
                assert_eq!((&path[0], path.last()), (&before[0], before.last()));
                assert!(path_length(&robot, &path) <= path_length(&robot, &before) + 1e-9);
                for w in path.windows(2) {
                    assert!(checker.motion_valid(&w[0], &w[1]), "{path:?}");
                }
                // Each corner kept is in the new path; a cut one left a point the fraction
                // of the way to the waypoint after it.
                for i in 1..3 {
                    if path.contains(&before[i]) {
                        kept += 1;
                        continue;
                    }
                    let mut q = vec![0.0; n];
                    let k = CUTS.iter().position(|&f| {
                        robot.interpolate(&before[i], &before[i + 1], f, &mut q);
                        path.iter().any(|p| robot.distance(p, &q) < 1e-9)
                    });
                    cut[k.expect("a cut point at one of the fractions")] += 1;
                }
            }
        }
        assert!(
            cut[0] > 100 && cut[1] > 3 && kept > 0,
            "corners cut at each fraction {cut:?}, kept {kept}"
        );
    }

    /// Scenes of the corner-cutting test, and boxes in each.
    const ENVS: usize = 12;
    const BOXES: usize = 30;
}
