//! A vantage-point tree: exact radius queries under any metric, built in bulk, with a small
//! linear buffer for incremental inserts that is folded in by rebuilding when it grows.

/// Indices of items organised for radius queries under `dist`.
#[derive(Debug, Clone, Default)]
pub struct VpTree {
    nodes: Vec<Node>,
    root: Option<usize>,
    /// Built items in subtree order: every node's subtree is one contiguous range.
    order: Vec<usize>,
    /// Items inserted since the last build, scanned linearly.
    pending: Vec<usize>,
    built: usize,
}

#[derive(Debug, Clone)]
struct Node {
    item: usize,
    /// Median distance from `item`: the inside subtree holds the items at or below it.
    radius: f64,
    /// Largest distance from `item` to any item of its subtrees.
    cover: f64,
    inside: Option<usize>,
    outside: Option<usize>,
    /// The node's subtree (itself first) is `order[lo..hi]`.
    lo: usize,
    hi: usize,
}

impl VpTree {
    /// Number of indexed items.
    pub fn len(&self) -> usize {
        self.built + self.pending.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Adds item `i`; rebuilds (with `dist`) when the linear buffer has grown past a quarter.
    pub fn insert(&mut self, i: usize, dist: &dyn Fn(usize, usize) -> f64) {
        self.pending.push(i);
        if self.pending.len() > 64.max(self.built / 4) {
            let mut all = std::mem::take(&mut self.order);
            all.append(&mut self.pending);
            self.build(all, dist);
        }
    }

    /// Builds the tree over `items`.
    pub fn build(&mut self, mut items: Vec<usize>, dist: &dyn Fn(usize, usize) -> f64) {
        self.nodes.clear();
        self.pending.clear();
        self.built = items.len();
        self.root = self.build_rec(&mut items, 0, dist);
        self.order = items;
    }

    fn build_rec(
        &mut self,
        items: &mut [usize],
        lo: usize,
        dist: &dyn Fn(usize, usize) -> f64,
    ) -> Option<usize> {
        let (&mut vp, rest) = items.split_first_mut()?;
        let node = self.nodes.len();
        self.nodes.push(Node {
            item: vp,
            radius: 0.0,
            cover: 0.0,
            inside: None,
            outside: None,
            lo,
            hi: lo + 1 + rest.len(),
        });
        if rest.is_empty() {
            return Some(node);
        }
        let mut d: Vec<(f64, usize)> = rest.iter().map(|&i| (dist(vp, i), i)).collect();
        let mid = d.len() / 2;
        d.select_nth_unstable_by(mid, |a, b| a.0.total_cmp(&b.0));
        let radius = d[mid].0;
        let cover = d.iter().map(|x| x.0).fold(0.0, f64::max);
        for (k, (_, i)) in d.iter().enumerate() {
            rest[k] = *i;
        }
        let (inside, outside) = rest.split_at_mut(mid);
        self.nodes[node].radius = radius;
        self.nodes[node].cover = cover;
        let inside_node = self.build_rec(inside, lo + 1, dist);
        let outside_node = self.build_rec(outside, lo + 1 + mid, dist);
        self.nodes[node].inside = inside_node;
        self.nodes[node].outside = outside_node;
        Some(node)
    }

    /// Every item within `r` of the query, given `d(item)` = distance from the query to it.
    /// A subtree that lies wholly within `r` (by the triangle inequality) is reported without
    /// computing its distances.
    pub fn within(&self, r: f64, d: &dyn Fn(usize) -> f64, out: &mut Vec<usize>) {
        // Pruning and wholesale reporting rely on the triangle inequality; a metric computed in
        // floating point may break it by rounding, so both are decided with this slack.
        const SLACK: f64 = 1e-6;
        let mut stack: Vec<usize> = self.root.into_iter().collect();
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n];
            let dv = d(node.item);
            if dv + node.cover <= r - SLACK {
                out.extend_from_slice(&self.order[node.lo..node.hi]);
                continue;
            }
            if dv <= r {
                out.push(node.item);
            }
            // Inside holds items at distance <= radius from the vantage point.
            if let Some(i) = node.inside {
                if dv + node.radius <= r - SLACK {
                    let c = &self.nodes[i];
                    out.extend_from_slice(&self.order[c.lo..c.hi]);
                } else if dv - r <= node.radius + SLACK {
                    stack.push(i);
                }
            }
            if let Some(o) = node.outside {
                if dv + r >= node.radius - SLACK {
                    stack.push(o);
                }
            }
        }
        out.extend(self.pending.iter().copied().filter(|&i| d(i) <= r));
    }
}
