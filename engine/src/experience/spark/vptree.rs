//! A vantage-point tree: exact radius queries under any metric, built in bulk, with incremental
//! inserts folded in by rebuilding a small tree often and the large one rarely.
//!
//! Items are stored in the tree itself, in depth-first order, so every subtree is one contiguous
//! run of items and a query walks memory mostly forwards.

/// Items of type `T` organised for radius queries under a metric on `T`.
///
/// Inserts go to a short linear buffer; when it fills, it is folded into a smaller `recent`
/// tree, which is folded into the `main` tree when it reaches a quarter of its size. A query
/// thus scans at most [`PENDING`] items linearly, and an insert costs amortised O(log² n)
/// distances.
#[derive(Debug, Clone)]
pub struct VpTree<T> {
    main: Built<T>,
    recent: Built<T>,
    /// Items inserted since `recent` was last built, scanned linearly.
    pending: Vec<T>,
}

/// Most items a query scans linearly.
const PENDING: usize = 32;

impl<T> Default for VpTree<T> {
    fn default() -> Self {
        VpTree {
            main: Built::default(),
            recent: Built::default(),
            pending: Vec::new(),
        }
    }
}

/// One built tree.
#[derive(Debug, Clone)]
struct Built<T> {
    /// Per item, in depth-first order: node `i` holds `items[i]`, its inside subtree starts at
    /// `i + 1` and its outside subtree right after the inside one.
    nodes: Vec<Node>,
    items: Vec<T>,
}

impl<T> Default for Built<T> {
    fn default() -> Self {
        Built {
            nodes: Vec::new(),
            items: Vec::new(),
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Node {
    /// Median distance from the node's item: the inside subtree holds the items at or below it.
    radius: f64,
    /// Largest distance from the node's item to any item of its subtrees.
    cover: f64,
    /// Items in the inside subtree.
    inside: u32,
    /// Items in the node's subtree, itself included.
    size: u32,
}

/// Pruning and wholesale reporting rely on the triangle inequality; a metric computed in
/// floating point may break it by rounding, so both are decided with this slack.
const SLACK: f64 = 1e-6;

impl<T: Copy> VpTree<T> {
    /// Adds `item`, folding the buffer and trees (with `dist`) as they fill.
    pub fn insert(&mut self, item: T, dist: impl Fn(&T, &T) -> f64) {
        self.pending.push(item);
        if self.pending.len() < PENDING {
            return;
        }
        let mut recent = std::mem::take(&mut self.recent.items);
        recent.append(&mut self.pending);
        if recent.len() * 4 >= self.main.items.len() {
            let mut all = std::mem::take(&mut self.main.items);
            all.append(&mut recent);
            self.main = Built::new(all, &dist);
            self.recent = Built::default();
        } else {
            self.recent = Built::new(recent, &dist);
        }
    }

    /// Calls `found` with every item within `r` of the query and its distance, given `d(item)` =
    /// distance from the query to it. A subtree that lies wholly within `r` (by the triangle
    /// inequality) is reported without computing its distances (`None`).
    pub fn within(&self, r: f64, d: impl Fn(&T) -> f64, mut found: impl FnMut(&T, Option<f64>)) {
        self.main.within(r, &d, &mut found);
        self.recent.within(r, &d, &mut found);
        for item in &self.pending {
            let dv = d(item);
            if dv <= r {
                found(item, Some(dv));
            }
        }
    }
}

impl<T: Copy> Built<T> {
    /// The tree over `items`.
    fn new(mut items: Vec<T>, dist: &impl Fn(&T, &T) -> f64) -> Self {
        let mut nodes = vec![
            Node {
                radius: 0.0,
                cover: 0.0,
                inside: 0,
                size: 1,
            };
            items.len()
        ];
        build_rec(&mut items, &mut nodes, dist, &mut Vec::new());
        Built { nodes, items }
    }

    fn within(&self, r: f64, d: &impl Fn(&T) -> f64, found: &mut impl FnMut(&T, Option<f64>)) {
        let mut stack: Vec<usize> = Vec::with_capacity(64);
        if !self.items.is_empty() {
            stack.push(0);
        }
        while let Some(i) = stack.pop() {
            let node = self.nodes[i];
            let dv = d(&self.items[i]);
            let end = i + node.size as usize;
            if dv + node.cover <= r - SLACK {
                self.items[i..end].iter().for_each(|x| found(x, None));
                continue;
            }
            if dv <= r {
                found(&self.items[i], Some(dv));
            }
            let split = i + 1 + node.inside as usize;
            // Inside holds items at distance <= radius from the vantage point.
            if node.inside > 0 {
                if dv + node.radius <= r - SLACK {
                    self.items[i + 1..split].iter().for_each(|x| found(x, None));
                } else if dv - r <= node.radius + SLACK {
                    stack.push(i + 1);
                }
            }
            if split < end && dv + r >= node.radius - SLACK {
                stack.push(split);
            }
        }
    }
}

/// Arranges `items` in depth-first order (vantage point, inside, outside) and fills their nodes.
fn build_rec<T: Copy>(
    items: &mut [T],
    nodes: &mut [Node],
    dist: &impl Fn(&T, &T) -> f64,
    scratch: &mut Vec<(f64, T)>,
) {
    let Some((vp, rest)) = items.split_first_mut() else {
        return;
    };
    nodes[0].size = 1 + rest.len() as u32;
    if rest.is_empty() {
        return;
    }
    scratch.clear();
    scratch.extend(rest.iter().map(|x| (dist(vp, x), *x)));
    let mid = scratch.len() / 2;
    scratch.select_nth_unstable_by(mid, |a, b| a.0.total_cmp(&b.0));
    nodes[0].radius = scratch[mid].0;
    nodes[0].cover = scratch.iter().map(|x| x.0).fold(0.0, f64::max);
    nodes[0].inside = mid as u32;
    for (slot, (_, x)) in rest.iter_mut().zip(scratch.iter()) {
        *slot = *x;
    }
    let (inside, outside) = rest.split_at_mut(mid);
    let (inside_nodes, outside_nodes) = nodes[1..].split_at_mut(mid);
    build_rec(inside, inside_nodes, dist, scratch);
    build_rec(outside, outside_nodes, dist, scratch);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points in the plane, queried after every insert: the answers go through the buffer, the
    /// recent tree and the main tree in all their fill states.
    #[test]
    fn radius_queries_equal_the_linear_scan_through_every_fold() {
        let dist = |a: &(f64, f64), b: &(f64, f64)| (a.0 - b.0).hypot(a.1 - b.1);
        let mut state = 7u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut tree, mut all, mut saw_recent) = (VpTree::default(), Vec::new(), false);
        for n in 0..600 {
            let p = (next(), next());
            tree.insert(p, dist);
            all.push(p);
            if n % 7 != 0 {
                continue;
            }
            saw_recent |= !tree.recent.items.is_empty();
            let (q, r) = ((next(), next()), 0.3 * next());
            let mut found = Vec::new();
            tree.within(r, |x| dist(&q, x), |x, _| found.push(*x));
            let mut expected: Vec<_> = all.iter().copied().filter(|x| dist(&q, x) <= r).collect();
            let key = |a: &(f64, f64), b: &(f64, f64)| a.partial_cmp(b).unwrap();
            found.sort_by(key);
            expected.sort_by(key);
            assert_eq!(found, expected, "after {} inserts", n + 1);
        }
        assert!(saw_recent && !tree.main.items.is_empty() && tree.pending.len() < PENDING);
    }
}
