//! A vantage-point tree: exact radius queries under any metric, built in bulk, with a small
//! linear buffer for incremental inserts that is folded in by rebuilding when it grows.
//!
//! Items are stored in the tree itself, in depth-first order, so every subtree is one contiguous
//! run of items and a query walks memory mostly forwards.

/// Items of type `T` organised for radius queries under a metric on `T`.
#[derive(Debug, Clone)]
pub struct VpTree<T> {
    /// Per built item, in depth-first order: node `i` holds `items[i]`, its inside subtree
    /// starts at `i + 1` and its outside subtree right after the inside one.
    nodes: Vec<Node>,
    items: Vec<T>,
    /// Items inserted since the last build, scanned linearly.
    pending: Vec<T>,
}

impl<T> Default for VpTree<T> {
    fn default() -> Self {
        VpTree {
            nodes: Vec::new(),
            items: Vec::new(),
            pending: Vec::new(),
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
    /// Adds `item`; rebuilds (with `dist`) when the linear buffer has grown past a quarter.
    pub fn insert(&mut self, item: T, dist: impl Fn(&T, &T) -> f64) {
        self.pending.push(item);
        if self.pending.len() > 64.max(self.items.len() / 4) {
            let mut all = std::mem::take(&mut self.items);
            all.append(&mut self.pending);
            self.build(all, dist);
        }
    }

    /// Builds the tree over `items`.
    pub fn build(&mut self, mut items: Vec<T>, dist: impl Fn(&T, &T) -> f64) {
        self.pending.clear();
        self.nodes.clear();
        self.nodes.resize(
            items.len(),
            Node {
                radius: 0.0,
                cover: 0.0,
                inside: 0,
                size: 1,
            },
        );
        let mut scratch = Vec::new();
        build_rec(&mut items, &mut self.nodes, &dist, &mut scratch);
        self.items = items;
    }

    /// Calls `found` with every item within `r` of the query and its distance, given `d(item)` =
    /// distance from the query to it. A subtree that lies wholly within `r` (by the triangle
    /// inequality) is reported without computing its distances (`None`).
    pub fn within(&self, r: f64, d: impl Fn(&T) -> f64, mut found: impl FnMut(&T, Option<f64>)) {
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
        for item in &self.pending {
            let dv = d(item);
            if dv <= r {
                found(item, Some(dv));
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
