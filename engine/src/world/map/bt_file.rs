//! OctoMap's binary `.bt` format (read and write), so octovis and OctoMap users open our maps.
//!
//! The format holds a depth-16 octree in pre-order: per inner node two bytes with two bits per
//! child (`00` unknown, `01` occupied leaf, `10` free leaf, `11` inner node; children 0–3 then
//! 4–7, child index = x | y<<1 | z<<2 of the key bit at that depth), keys being
//! `floor(coordinate / resolution) + 32768`. It is binary: reading sets leaves to the clamping
//! bounds. Writing prunes full subtrees whose leaves agree, as OctoMap does.

use super::{MapParams, Occupancy, OccupancyMap, VoxelKey};
use std::io::{BufRead, Write};
use thiserror::Error;

const HEADER: &str = "# Octomap OcTree binary file";
const TREE_DEPTH: u32 = 16;
const KEY_OFFSET: i32 = 32768;
/// Largest pruned node expanded on reading (voxels); larger ones are refused, not truncated.
const MAX_EXPAND: u64 = 1 << 24;

/// A `.bt` file that cannot be read or written.
#[derive(Debug, Error)]
pub enum BtError {
    /// Reading or writing failed.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The header is not an OctoMap binary header.
    #[error("not an OctoMap binary file: {0}")]
    BadHeader(String),
    /// The tree is not an `OcTree`.
    #[error("unsupported tree type '{0}' (only OcTree)")]
    UnsupportedTree(String),
    /// The data ends before the tree does.
    #[error("truncated data after {0} nodes")]
    Truncated(usize),
    /// A voxel lies outside OctoMap's key range.
    #[error("voxel {0:?} lies outside OctoMap's key range")]
    OutOfRange(VoxelKey),
    /// A pruned node covers too many voxels to expand.
    #[error("a pruned node covers {0} voxels, more than this map expands")]
    TooLarge(u64),
}

fn morton(k: [u16; 3]) -> u64 {
    let mut code = 0u64;
    for b in (0..TREE_DEPTH).rev() {
        let child = ((k[0] >> b) & 1) | (((k[1] >> b) & 1) << 1) | (((k[2] >> b) & 1) << 2);
        code = (code << 3) | child as u64;
    }
    code
}

impl OccupancyMap {
    /// Writes the map as an OctoMap `.bt` stream.
    pub fn write_bt(&self, out: &mut impl Write) -> Result<(), BtError> {
        let mut leaves: Vec<(u64, bool)> = Vec::new();
        for (k, state) in self.known_voxels() {
            let mut key = [0u16; 3];
            for a in 0..3 {
                let v = k[a] + KEY_OFFSET;
                if !(0..=u16::MAX as i32).contains(&v) {
                    return Err(BtError::OutOfRange(k));
                }
                key[a] = v as u16;
            }
            leaves.push((morton(key), state == Occupancy::Occupied));
        }
        leaves.sort_unstable_by_key(|l| l.0);
        let mut body = Vec::new();
        let mut nodes = 1usize; // the root
        if !leaves.is_empty() {
            write_node(&leaves, 0, &mut body, &mut nodes);
        }
        write!(
            out,
            "{HEADER}\n# (written by Ember)\nid OcTree\nsize {}\nres {}\ndata\n",
            if leaves.is_empty() { 0 } else { nodes },
            self.resolution()
        )?;
        out.write_all(&body)?;
        Ok(())
    }

    /// Reads an OctoMap `.bt` stream into a new map with default parameters at its resolution.
    pub fn read_bt(input: &mut impl BufRead) -> Result<OccupancyMap, BtError> {
        let mut first = String::new();
        input.read_line(&mut first)?;
        if !first.starts_with(HEADER) {
            return Err(BtError::BadHeader(first.trim().to_string()));
        }
        let (mut id, mut size, mut res) = (String::new(), None::<usize>, None::<f64>);
        loop {
            let mut line = String::new();
            if input.read_line(&mut line)? == 0 {
                return Err(BtError::BadHeader("missing 'data' line".into()));
            }
            let line = line.trim();
            if line.starts_with('#') || line.is_empty() {
                continue;
            }
            let mut it = line.split_whitespace();
            match (it.next(), it.next()) {
                (Some("data"), _) => break,
                (Some("id"), Some(v)) => id = v.to_string(),
                (Some("size"), Some(v)) => {
                    size = Some(
                        v.parse()
                            .map_err(|_| BtError::BadHeader(format!("size '{v}'")))?,
                    )
                }
                (Some("res"), Some(v)) => {
                    res = Some(
                        v.parse()
                            .map_err(|_| BtError::BadHeader(format!("res '{v}'")))?,
                    )
                }
                _ => return Err(BtError::BadHeader(format!("unexpected line '{line}'"))),
            }
        }
        if id != "OcTree" {
            return Err(BtError::UnsupportedTree(id));
        }
        let res = res
            .filter(|r| r.is_finite() && *r > 0.0)
            .ok_or_else(|| BtError::BadHeader("missing or invalid 'res'".into()))?;
        let mut map = OccupancyMap::new(MapParams {
            resolution: res,
            ..Default::default()
        });
        if size.unwrap_or(0) > 0 {
            let mut data = Vec::new();
            input.read_to_end(&mut data)?;
            let mut reader = NodeReader {
                data: &data,
                pos: 0,
                nodes: 1,
            };
            reader.read_node(0, [0; 3], &mut map)?;
        }
        map.compact();
        Ok(map)
    }
}

/// Writes the node at `depth` whose leaves (sorted Morton codes) are `leaves`.
fn write_node(leaves: &[(u64, bool)], depth: u32, out: &mut Vec<u8>, nodes: &mut usize) {
    let shift = 3 * (TREE_DEPTH - 1 - depth);
    let child_span = 8u64.pow(TREE_DEPTH - 1 - depth);
    let mut bits = 0u16;
    let mut inner: Vec<&[(u64, bool)]> = Vec::new();
    let mut start = 0;
    while start < leaves.len() {
        let c = (leaves[start].0 >> shift) & 7;
        let end = start + leaves[start..].partition_point(|l| (l.0 >> shift) & 7 == c);
        let group = &leaves[start..end];
        let uniform = group.iter().all(|l| l.1 == group[0].1);
        let code = if depth + 1 == TREE_DEPTH || (group.len() as u64 == child_span && uniform) {
            if group[0].1 {
                0b10 // bit 2i+1 set: occupied
            } else {
                0b01 // bit 2i set: free
            }
        } else {
            inner.push(group);
            0b11
        };
        bits |= code << (2 * c);
        *nodes += 1;
        start = end;
    }
    out.push((bits & 0xff) as u8);
    out.push((bits >> 8) as u8);
    for group in inner {
        write_node(group, depth + 1, out, nodes);
    }
}

struct NodeReader<'d> {
    data: &'d [u8],
    pos: usize,
    nodes: usize,
}

impl NodeReader<'_> {
    fn read_node(
        &mut self,
        depth: u32,
        prefix: [u32; 3],
        map: &mut OccupancyMap,
    ) -> Result<(), BtError> {
        if self.pos + 2 > self.data.len() {
            return Err(BtError::Truncated(self.nodes));
        }
        let bits = self.data[self.pos] as u16 | (self.data[self.pos + 1] as u16) << 8;
        self.pos += 2;
        let level = TREE_DEPTH - 1 - depth;
        for c in 0..8u32 {
            let code = (bits >> (2 * c)) & 3;
            if code == 0 {
                continue;
            }
            self.nodes += 1;
            let key = [
                prefix[0] | ((c & 1) << level),
                prefix[1] | (((c >> 1) & 1) << level),
                prefix[2] | (((c >> 2) & 1) << level),
            ];
            match code {
                0b11 if depth + 1 < TREE_DEPTH => self.read_node(depth + 1, key, map)?,
                0b11 => return Err(BtError::BadHeader("inner node below the leaf level".into())),
                leaf => {
                    let occupied = leaf == 0b10;
                    let span = 1u32 << level;
                    let count = (span as u64).pow(3);
                    if count > MAX_EXPAND {
                        return Err(BtError::TooLarge(count));
                    }
                    for x in 0..span {
                        for y in 0..span {
                            for z in 0..span {
                                let k = [key[0] + x, key[1] + y, key[2] + z]
                                    .map(|v| v as i32 - KEY_OFFSET);
                                map.set_voxel(k, occupied);
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }
}
