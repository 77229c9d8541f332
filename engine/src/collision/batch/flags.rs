//! What the sphere lanes flag, state by state or lane by lane: which links may touch the
//! obstacles and which pairs of links each other, so that the exact geometry is asked only
//! about those.
//!
//! [`BatchChecker::lane_flags`] walks the batch checker's tests once for eight states without
//! ending at a contact: each moving link and each pair is walked until its contacts are found
//! in every lane or its spheres run out, a contact setting the lanes it is in aside for that
//! part (`counted`, at each kind of contact in the walk, compiled in only where the tests' `E`
//! parameter is set). The early-ending check keeps its source: its tests are the same
//! functions with `E` unset.

use super::lanes::{ALL_LANES, F8};
use super::objects::{penetrating_lanes_of, Object8};
use super::{lanes_touch_map, overlap_lanes, BatchChecker};
use crate::world::map::{Clearance, OccupancyMap};

/// What the sphere lanes find of one configuration ([`BatchChecker::state_flags`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateFlags {
    /// Some link may touch an object or the map.
    pub env: bool,
    /// Some pair of links may touch each other.
    pub pairs: bool,
}

impl StateFlags {
    /// Either test flagged it.
    pub fn any(self) -> bool {
        self.env || self.pairs
    }
}

/// What the sphere lanes find of eight configurations, lane by lane
/// ([`BatchChecker::lane_flags`]): bit `i` of each mask is lane `i`'s [`StateFlags`] field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LaneFlags {
    /// The lanes where some link may touch an object or the map.
    pub env: u32,
    /// The lanes where some pair of links may touch each other.
    pub pairs: u32,
}

impl LaneFlags {
    /// Lane `i`'s flags.
    pub fn lane(self, i: usize) -> StateFlags {
        StateFlags {
            env: self.env >> i & 1 == 1,
            pairs: self.pairs >> i & 1 == 1,
        }
    }

    /// Some lane is flagged.
    pub fn any(self) -> bool {
        self.env | self.pairs != 0
    }
}

impl BatchChecker {
    /// Which tests flag configuration `q`: the environment (objects, the map and, when
    /// validating, obstacles that could hide inside a link), and the self pairs; which links
    /// and pairs they flag, [`BatchChecker::flagged_links`] and
    /// [`BatchChecker::flagged_pairs`] (lane 0). A part not flagged is clear: a link of the
    /// obstacles, a pair of links of each other.
    pub fn state_flags(&mut self, q: &[f64]) -> StateFlags {
        for (lane, &v) in self.lanes.iter_mut().zip(q) {
            *lane = F8::splat(v as f32);
        }
        self.flags_of_lanes(1).lane(0)
    }

    /// Which tests flag each of eight configurations given per variable (`lanes[j]` holds
    /// variable `j` of each): lane by lane what [`BatchChecker::state_flags`] finds of each
    /// alone, and the parts each lane flags ([`BatchChecker::flagged_links`],
    /// [`BatchChecker::flagged_pairs`]), from one placement of the eight and one walk.
    pub fn lane_flags(&mut self, lanes: &[F8]) -> LaneFlags {
        self.lanes[..self.dof].copy_from_slice(&lanes[..self.dof]);
        self.flags_of_lanes(ALL_LANES)
    }

    /// [`BatchChecker::lane_flags`] of the configurations in `self.lanes`, of which those in
    /// `distinct` (bits) are distinct (one lane, while one state fills them all).
    fn flags_of_lanes(&mut self, distinct: u32) -> LaneFlags {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            return unsafe { self.flags_avx2(distinct) };
        }
        self.flags(distinct)
    }

    /// [`BatchChecker::flags`] compiled for AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn flags_avx2(&mut self, distinct: u32) -> LaneFlags {
        self.flags(distinct)
    }

    /// The checks of [`BatchChecker::check`] lane by lane, in the lanes `distinct` (bits):
    /// every moving link against the obstacles and every pair, each walked until its
    /// contacts are found in every lane or its spheres run out.
    #[inline(always)]
    fn flags(&mut self, distinct: u32) -> LaneFlags {
        self.begin(None);
        self.distinct = distinct;
        self.link_hits.fill(0);
        self.pair_hits.fill(0);
        self.env_contact::<true>();
        self.self_contact::<true>();
        self.live = distinct;
        if self.validating && self.may_hide::<true>() {
            // Nothing ruled out: every part may touch.
            for k in 0..self.moving.len() {
                self.link_hits[self.moving[k]] = distinct;
            }
            self.pair_hits.fill(distinct);
        }
        self.live = ALL_LANES;
        let env = self.moving.iter().fold(0, |m, &l| m | self.link_hits[l]);
        let pairs = self.pair_hits.iter().fold(0, |m, &h| m | h);
        LaneFlags { env, pairs }
    }

    /// The moving links the last [`BatchChecker::lane_flags`] (or
    /// [`BatchChecker::state_flags`]) flagged against the obstacles in lane `lane`: the
    /// others are clear of them there.
    pub fn flagged_links(&self, lane: usize) -> impl Iterator<Item = usize> + '_ {
        self.moving
            .iter()
            .copied()
            .filter(move |&l| self.link_hits[l] >> lane & 1 == 1)
    }

    /// The pairs of links (the batch checker's own: a moving link and another, both with
    /// spheres) the last [`BatchChecker::lane_flags`] flagged in lane `lane`: the others are
    /// clear of each other there.
    pub fn flagged_pairs(&self, lane: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.pairs
            .iter()
            .zip(&self.pair_hits)
            .filter(move |(_, &h)| h >> lane & 1 == 1)
            .map(|(p, _)| (p.a, p.b))
    }

    /// True when the links and pairs these flags name cover `links` and `pairs` (the exact
    /// checker's moving links with geometry and moving pairs): only then is a part not
    /// flagged known clear.
    pub fn flags_cover(&self, links: &[usize], pairs: &[(usize, usize)]) -> bool {
        let key = |(a, b): (usize, usize)| (a.min(b), a.max(b));
        let ours: std::collections::HashSet<_> =
            self.pairs.iter().map(|p| key((p.a, p.b))).collect();
        links.iter().all(|l| self.moving.contains(l))
            && pairs.iter().all(|&p| ours.contains(&key(p)))
    }
}

/// In [`BatchChecker::lane_flags`]'s walk, a contact of the part being walked found in
/// `lanes`: those of them still `live` are added to `hit` and set aside; true (the part is
/// done) when none is left.
#[inline(always)]
pub(super) fn counted((hit, live): (&mut u32, &mut u32), lanes: u32) -> bool {
    let lanes = lanes & *live;
    *hit |= lanes;
    *live &= !lanes;
    *live == 0
}

/// [`counted`] for balls `a` and `b` that [`overlap`].
#[inline(always)]
pub(super) fn overlap_counted(
    found: (&mut u32, &mut u32),
    (a, ra): ([F8; 3], f32),
    (b, rb): ([F8; 3], f32),
) -> bool {
    counted(found, overlap_lanes(a, ra, b, rb))
}

/// [`counted`] for the ball at `p` with radius `r` where it penetrates the objects `mask`
/// of `objects`.
#[inline(always)]
pub(super) fn objects_counted(
    found: (&mut u32, &mut u32),
    objects: &[Object8],
    mask: u64,
    p: [F8; 3],
    r: f32,
) -> bool {
    counted(found, penetrating_lanes_of(objects, mask, p, r))
}

/// [`counted`] for the ball at `p` with radius `r` in the lanes of `lanes` (bits) where
/// [`lanes_touch_map`] finds it touching an occupied voxel, each asked alone.
#[inline(always)]
pub(super) fn map_counted(
    found: (&mut u32, &mut u32),
    (map, grid): (Option<&OccupancyMap>, Option<&Clearance>),
    p: [F8; 3],
    r: f32,
    lanes: u32,
) -> bool {
    let mut touching = 0;
    let mut m = lanes;
    while m != 0 {
        let lane = 1 << m.trailing_zeros();
        m &= m - 1;
        if lanes_touch_map(map, grid, p, r, lane) {
            touching |= lane;
        }
    }
    counted(found, touching)
}
