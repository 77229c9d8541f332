//! Path simplification: redundant-vertex removal and random shortcutting. Every motion the
//! result is made of has been checked at the resolution, including the pieces of the old
//! segments a shortcut leaves (their states differ from the old segment's), so no full
//! re-validation is needed.

use super::validity::Validity;
use super::{path_length, PlannerRng};
use rand::Rng;

/// Shortcut attempts per path (OMPL's default budget is similar).
const SHORTCUT_ATTEMPTS: usize = 60;

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
