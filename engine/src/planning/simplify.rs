//! Path simplification: redundant-vertex removal, random shortcutting and a round of corner
//! cutting. Every motion the result is made of has been checked at the resolution, including
//! the pieces of the old segments a shortcut or a cut leaves (their states differ from the old
//! segment's), so no full re-validation is needed.

use super::validity::Validity;
use super::{path_length, PlannerRng};
use rand::Rng;

/// Shortcut attempts per path (OMPL's default budget is similar).
const SHORTCUT_ATTEMPTS: usize = 40;

/// A cut corner's new ends lie this fraction of the way from the corner to its neighbours.
const CUT: f64 = 0.5;

/// Shortens `path` in place; endpoints are kept.
pub fn simplify(checker: &mut Validity<'_>, path: &mut Vec<Vec<f64>>, rng: &mut PlannerRng) {
    let robot = checker.robot();
    remove_redundant(checker, path);
    let dof = robot.dof();
    let mut pa = vec![0.0; dof];
    let mut pb = vec![0.0; dof];
    for _ in 0..SHORTCUT_ATTEMPTS {
        if path.len() < 3 {
            break;
        }
        // Two random points on two different segments.
        let segs = path.len() - 1;
        let mut i = rng.random_range(0..segs);
        let mut j = rng.random_range(0..segs);
        if i == j {
            continue;
        }
        if i > j {
            std::mem::swap(&mut i, &mut j);
        }
        let ti: f64 = rng.random();
        let tj: f64 = rng.random();
        robot.interpolate(&path[i], &path[i + 1], ti, &mut pa);
        robot.interpolate(&path[j], &path[j + 1], tj, &mut pb);
        let old = robot.distance(&pa, &path[i + 1])
            + path_length(robot, &path[i + 1..=j])
            + robot.distance(&path[j], &pb);
        if robot.distance(&pa, &pb) >= old - 1e-9 {
            continue;
        }
        // The shortcut first (where collisions are), then the pieces of the old segments the
        // shortcut keeps; each check takes its end state in the same pass.
        if !(checker.reach_valid(&pa, &pb)
            && checker.reach_valid(&path[i], &pa)
            && checker.motion_valid(&pb, &path[j + 1]))
        {
            continue;
        }
        path.splice(i + 1..=j, [pa.clone(), pb.clone()]);
    }
    remove_redundant(checker, path);
    if cut_corners(checker, path) {
        remove_redundant(checker, path);
    }
}

/// Corner cutting (Chaikin's step): each interior waypoint gives way to the points a fraction
/// [`CUT`] of the way to its neighbours when the motion between them is free. Returns whether
/// a corner was cut. A piece of an old segment left between two kept points is checked as it
/// is finalised; should one fail (its states differ from the segment's), the path is kept as
/// it was.
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
        robot.interpolate(&path[i], prev, CUT, &mut a);
        robot.interpolate(&path[i], &path[i + 1], CUT, &mut b);
        // The new edge first (where collisions are), then the piece before it.
        if checker.reach_valid(&a, &b) && checker.reach_valid(prev, &a) {
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

/// Greedy pruning: from each kept vertex, jump to the farthest vertex it sees directly.
fn remove_redundant(checker: &mut Validity<'_>, path: &mut Vec<Vec<f64>>) {
    if path.len() < 3 {
        return;
    }
    let mut kept = vec![path[0].clone()];
    let mut i = 0;
    while i < path.len() - 1 {
        let mut j = path.len() - 1;
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
    /// checker finds free; among boxes some corners are cut and some kept.
    #[test]
    fn cut_corners_shorten_paths_through_free_motions_only() {
        let robot = Robot::builtin("panda").unwrap();
        let n = robot.dof();
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let (mut cut, mut kept) = (0, 0);
        for _ in 0..6 {
            let env = random_boxes(
                &mut rng,
                10,
                [0.25, 0.25, 0.2],
                [0.2..0.8, -0.5..0.5, 0.1..1.0],
            );
            let mut checker = Validity::new(&robot, &env, 1.0 / 32.0, 0.0);
            let mut tried = 0;
            for _ in 0..2000 {
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
                cut += usize::from(path.len() > before.len());
                kept += before.len() + 2 - path.len();
            }
        }
        assert!(cut > 10 && kept > 3, "{cut} paths cut, {kept} corners kept");
    }
}
