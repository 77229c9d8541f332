//! A vantage-point tree: exact radius queries under any metric, built in bulk, with a small
//! linear buffer for incremental inserts that is folded in by rebuilding when it grows.

/// Indices of items organised for radius queries under `dist`.
#[derive(Debug, Clone, Default)]
pub struct VpTree {
    nodes: Vec<Node>,
    root: Option<usize>,
    /// Items inserted since the last build, scanned linearly.
    pending: Vec<usize>,
    built: usize,
}

#[derive(Debug, Clone)]
struct Node {
    item: usize,
    radius: f64,
    inside: Option<usize>,
    outside: Option<usize>,
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
            let mut all: Vec<usize> = self.nodes.iter().map(|n| n.item).collect();
            all.append(&mut self.pending);
            self.build(all, dist);
        }
    }

    /// Builds the tree over `items`.
    pub fn build(&mut self, mut items: Vec<usize>, dist: &dyn Fn(usize, usize) -> f64) {
        self.nodes.clear();
        self.pending.clear();
        self.built = items.len();
        self.root = self.build_rec(&mut items, dist);
    }

    fn build_rec(
        &mut self,
        items: &mut [usize],
        dist: &dyn Fn(usize, usize) -> f64,
    ) -> Option<usize> {
        let (&mut vp, rest) = items.split_first_mut()?;
        let node = self.nodes.len();
        self.nodes.push(Node {
            item: vp,
            radius: 0.0,
            inside: None,
            outside: None,
        });
        if rest.is_empty() {
            return Some(node);
        }
        let mut d: Vec<(f64, usize)> = rest.iter().map(|&i| (dist(vp, i), i)).collect();
        let mid = d.len() / 2;
        d.select_nth_unstable_by(mid, |a, b| a.0.total_cmp(&b.0));
        let radius = d[mid].0;
        for (k, (_, i)) in d.iter().enumerate() {
            rest[k] = *i;
        }
        let (inside, outside) = rest.split_at_mut(mid);
        self.nodes[node].radius = radius;
        let inside_node = self.build_rec(inside, dist);
        let outside_node = self.build_rec(outside, dist);
        self.nodes[node].inside = inside_node;
        self.nodes[node].outside = outside_node;
        Some(node)
    }

    /// Every item within `r` of the query, given `d(item)` = distance from the query to it.
    pub fn within(&self, r: f64, d: &dyn Fn(usize) -> f64, out: &mut Vec<usize>) {
        let mut stack: Vec<usize> = self.root.into_iter().collect();
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n];
            let dv = d(node.item);
            if dv <= r {
                out.push(node.item);
            }
            // Inside holds items at distance <= radius from the vantage point.
            if let Some(i) = node.inside {
                if dv - r <= node.radius {
                    stack.push(i);
                }
            }
            if let Some(o) = node.outside {
                if dv + r >= node.radius {
                    stack.push(o);
                }
            }
        }
        out.extend(self.pending.iter().copied().filter(|&i| d(i) <= r));
    }
}
