//! The geometric path a trajectory follows: straight segments between the waypoints, each
//! corner replaced by a circular arc tangent to both segments (Kunz & Stilman 2012), so the
//! path is C¹ in arc length and the robot need not stop at every waypoint.
//!
//! A corner's arc starts and ends at most half of either segment away from the waypoint and
//! passes within `max_deviation` (configuration-space distance) of it. A corner with no room
//! (deviation 0, or a reversal) stays sharp: the trajectory stops there.

/// One piece of the path.
#[derive(Debug, Clone, PartialEq)]
enum Piece {
    /// `start + s · dir` (unit `dir`).
    Line { start: Vec<f64>, dir: Vec<f64> },
    /// `center + radius (x cos(s/r) + y sin(s/r))` (orthonormal `x`, `y`).
    Arc {
        center: Vec<f64>,
        x: Vec<f64>,
        y: Vec<f64>,
        radius: f64,
        /// The corner blended (corner `i` is waypoint `i + 1`).
        corner: usize,
    },
}

/// A path through waypoints with blended corners (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct BlendedPath {
    /// Pieces with their start arc length and length.
    pieces: Vec<(f64, f64, Piece)>,
    length: f64,
    /// Arc length at which each waypoint is passed (the middle of its arc when blended).
    waypoint_s: Vec<f64>,
    /// Arc lengths where the path turns sharply (velocity must be zero), besides the ends.
    stops: Vec<f64>,
}

fn sub(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

fn norm(a: &[f64]) -> f64 {
    a.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn scaled(a: &[f64], k: f64) -> Vec<f64> {
    a.iter().map(|v| v * k).collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Turning angles below this are straight (no blend).
const STRAIGHT: f64 = 1e-9;

impl BlendedPath {
    /// The path through `waypoints` (equal lengths, unwrapped: continuous joints as plain
    /// numbers), corner `i` (waypoint `i + 1`) blended within `max_deviation[i]`. Repeated
    /// waypoints are dropped.
    pub fn new(waypoints: &[Vec<f64>], max_deviation: &[f64]) -> Self {
        // Keep each waypoint's number, dropping exact repeats.
        let mut pts: Vec<(usize, &Vec<f64>)> = Vec::new();
        for (i, w) in waypoints.iter().enumerate() {
            if pts.last().is_none_or(|(_, p)| norm(&sub(w, p)) > 1e-12) {
                pts.push((i, w));
            }
        }
        let mut path = BlendedPath {
            pieces: Vec::new(),
            length: 0.0,
            waypoint_s: vec![0.0; waypoints.len()],
            stops: Vec::new(),
        };
        if pts.len() < 2 {
            return path;
        }
        // Per corner (interior point): the distance along each segment its arc takes.
        let n = pts.len();
        let seg_len: Vec<f64> = (0..n - 1)
            .map(|k| norm(&sub(pts[k + 1].1, pts[k].1)))
            .collect();
        let dirs: Vec<Vec<f64>> = (0..n - 1)
            .map(|k| scaled(&sub(pts[k + 1].1, pts[k].1), 1.0 / seg_len[k]))
            .collect();
        let mut blend = vec![0.0; n];
        let mut angle = vec![0.0; n];
        for k in 1..n - 1 {
            let cos = dot(&dirs[k - 1], &dirs[k]).clamp(-1.0, 1.0);
            let alpha = cos.acos();
            angle[k] = alpha;
            let deviation = max_deviation
                .get(pts[k].0.saturating_sub(1))
                .copied()
                .unwrap_or(0.0);
            if !(STRAIGHT..=std::f64::consts::PI - 1e-6).contains(&alpha) || deviation <= 0.0 {
                continue;
            }
            let half = alpha / 2.0;
            let by_deviation = deviation * half.sin() / (1.0 - half.cos());
            blend[k] = by_deviation.min(seg_len[k - 1] / 2.0).min(seg_len[k] / 2.0);
        }
        for k in 0..n - 1 {
            let (a, b) = (pts[k].1, pts[k + 1].1);
            let dir = &dirs[k];
            // The straight part between the arcs of its two corners.
            let start = a
                .iter()
                .zip(dir)
                .map(|(v, d)| v + d * blend[k])
                .collect::<Vec<_>>();
            let len = seg_len[k] - blend[k] - blend[k + 1];
            if k == 0 {
                path.waypoint_s[pts[0].0] = 0.0;
            }
            path.push(
                len.max(0.0),
                Piece::Line {
                    start,
                    dir: dir.clone(),
                },
            );
            // The corner at b.
            if k + 1 == n - 1 {
                path.waypoint_s[pts[k + 1].0] = path.length;
                break;
            }
            let l = blend[k + 1];
            if l <= 0.0 {
                path.waypoint_s[pts[k + 1].0] = path.length;
                if angle[k + 1] >= STRAIGHT {
                    path.stops.push(path.length);
                }
                continue;
            }
            let alpha = angle[k + 1];
            let radius = l / (alpha / 2.0).tan();
            let next = &dirs[k + 1];
            let inward = sub(next, dir);
            let inward = scaled(&inward, 1.0 / norm(&inward));
            let to_center = radius / (alpha / 2.0).cos();
            let center: Vec<f64> = b
                .iter()
                .zip(&inward)
                .map(|(v, i)| v + i * to_center)
                .collect();
            let arc_start: Vec<f64> = b.iter().zip(dir).map(|(v, d)| v - d * l).collect();
            let x = scaled(&sub(&arc_start, &center), 1.0 / radius);
            path.waypoint_s[pts[k + 1].0] = path.length + radius * alpha / 2.0;
            path.push(
                radius * alpha,
                Piece::Arc {
                    center,
                    x,
                    y: dir.clone(),
                    radius,
                    corner: pts[k + 1].0 - 1,
                },
            );
        }
        // Waypoints dropped as repeats are passed where their twin is.
        for i in 1..waypoints.len() {
            if !pts.iter().any(|(k, _)| *k == i) {
                path.waypoint_s[i] = path.waypoint_s[i - 1];
            }
        }
        path
    }

    /// Appends a piece of length `len` (none when empty).
    fn push(&mut self, len: f64, piece: Piece) {
        if len > 0.0 {
            self.pieces.push((self.length, len, piece));
            self.length += len;
        }
    }

    /// Total arc length.
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Arc length at which waypoint `i` is passed (nearest point of its arc when blended).
    pub fn waypoint_s(&self) -> &[f64] {
        &self.waypoint_s
    }

    /// Arc lengths of sharp corners, where the trajectory must stop.
    pub fn stops(&self) -> &[f64] {
        &self.stops
    }

    /// Pieces `(start, length, angle turned)` in order (angle 0 for straight ones).
    pub fn pieces(&self) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        self.pieces.iter().map(|(s, l, p)| match p {
            Piece::Arc { radius, .. } => (*s, *l, l / radius),
            Piece::Line { .. } => (*s, *l, 0.0),
        })
    }

    /// The blend arcs: `(corner, start, length)`.
    pub fn arcs(&self) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        self.pieces.iter().filter_map(|(s, l, p)| match p {
            Piece::Arc { corner, .. } => Some((*corner, *s, *l)),
            Piece::Line { .. } => None,
        })
    }

    /// Position, first and second derivative in arc length at `s`, on the piece holding arc
    /// length `on` (the later one at a boundary): `s` is clamped to that piece, so the ends
    /// of a grid interval are evaluated on the interval's own piece whatever the rounding.
    pub fn eval(&self, s: f64, on: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]) {
        let k = self
            .pieces
            .partition_point(|(s0, _, _)| *s0 <= on)
            .saturating_sub(1)
            .min(self.pieces.len() - 1);
        let (s0, len, piece) = &self.pieces[k];
        let u = (s - s0).clamp(0.0, *len);
        match piece {
            Piece::Line { start, dir } => {
                for j in 0..q.len() {
                    q[j] = start[j] + dir[j] * u;
                    dq[j] = dir[j];
                    ddq[j] = 0.0;
                }
            }
            Piece::Arc {
                center,
                x,
                y,
                radius,
                ..
            } => {
                let (sin, cos) = (u / radius).sin_cos();
                for j in 0..q.len() {
                    q[j] = center[j] + radius * (x[j] * cos + y[j] * sin);
                    dq[j] = -x[j] * sin + y[j] * cos;
                    ddq[j] = -(x[j] * cos + y[j] * sin) / radius;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_right_angle_is_blended_within_the_deviation_and_tangent() {
        let w = vec![vec![0.0, 0.0], vec![1.0, 0.0], vec![1.0, 1.0]];
        let path = BlendedPath::new(&w, &[0.05]);
        assert!(path.stops().is_empty());
        let (mut q, mut dq, mut ddq) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        // Closest approach to the corner: the arc's middle, within the deviation.
        path.eval(
            path.waypoint_s()[1],
            path.waypoint_s()[1],
            &mut q,
            &mut dq,
            &mut ddq,
        );
        let d = ((q[0] - 1.0).powi(2) + q[1].powi(2)).sqrt();
        assert!((d - 0.05).abs() < 1e-9, "deviation {d}");
        // Tangent directions continuous at the piece boundaries.
        for (s0, _, _) in path.pieces() {
            let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
            path.eval(s0, s0 - 1e-9, &mut q, &mut a, &mut ddq);
            path.eval(s0, s0, &mut q, &mut b, &mut ddq);
            assert!((a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9);
        }
        path.eval(path.length(), path.length(), &mut q, &mut dq, &mut ddq);
        assert!((q[0] - 1.0).abs() < 1e-12 && (q[1] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_reversal_is_a_stop() {
        let w = vec![vec![0.0], vec![1.0], vec![0.5]];
        let path = BlendedPath::new(&w, &[0.1]);
        assert_eq!(path.stops(), &[1.0]);
        assert!((path.length() - 1.5).abs() < 1e-12);
    }
}
