//! What the sphere lanes flag, state by state or lane by lane: which tests find a state (or
//! each of eight) in possible contact, so that the exact geometry is asked only about that.
//!
//! [`BatchChecker::lane_flags`] walks the batch checker's tests once for eight states without
//! ending at the first contact: a contact sets the lanes it is in aside (`counted`, at each
//! kind of contact in the walk, compiled in only where the tests' `E` parameter is set), and
//! the walk is made again for the others, until it finds none. The early-ending check keeps
//! its source: its tests are the same functions with `E` unset.

use super::lanes::{ALL_LANES, F8};
use super::objects::{penetrating_lanes_of, Object8};
use super::{lanes_touch_map, overlap_lanes, BatchChecker};
use crate::world::map::{Clearance, OccupancyMap};

/// What the sphere lanes find of one configuration ([`BatchChecker::state_flags`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateFlags {
    /// Some link may touch an object or the map.
    pub env: bool,
    /// Some pair of links may touch each other (or was not asked, as `env` was set).
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
    /// The lanes where some pair of links may touch each other (or that were not asked, as
    /// `env` was set there).
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

/// The tests [`BatchChecker::lane_flags`] walks lane by lane.
#[derive(Clone, Copy)]
enum Test {
    Environment,
    SelfPairs,
    Hiding,
}

impl BatchChecker {
    /// Which tests flag configuration `q`: the environment (objects, the map and, when
    /// validating, obstacles that could hide inside a link), and the self pairs (asked only
    /// when the environment's test clears; flagged otherwise). A part not flagged is clear:
    /// every link of the environment, or every pair of links of each other.
    pub fn state_flags(&mut self, q: &[f64]) -> StateFlags {
        for (lane, &v) in self.lanes.iter_mut().zip(q) {
            *lane = F8::splat(v as f32);
        }
        self.flags_of_lanes(1).lane(0)
    }

    /// Which tests flag each of eight configurations given per variable (`lanes[j]` holds
    /// variable `j` of each): lane by lane what [`BatchChecker::state_flags`] finds of each
    /// alone, from one placement of the eight. A walk does not end at its first contact: the
    /// lanes that contact is in are set aside and the walk is made again for the others,
    /// until it finds none.
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
    /// the self pairs and the hiding test asked in the lanes the environment's test clears.
    #[inline(always)]
    fn flags(&mut self, distinct: u32) -> LaneFlags {
        self.begin(None);
        let env = self.flagged(distinct, Test::Environment);
        let pairs = env | self.flagged(distinct & !env, Test::SelfPairs);
        let hide = match self.validating {
            true => self.flagged(distinct & !env, Test::Hiding),
            false => 0,
        };
        self.live = ALL_LANES;
        LaneFlags {
            env: env | hide,
            pairs,
        }
    }

    /// The lanes of `live` where `test` finds a contact: walked again with the lanes found
    /// set aside until it finds none. (A contact found without its lanes, as the hiding test's
    /// "nothing ruled out", flags every lane left.)
    #[inline(always)]
    fn flagged(&mut self, live: u32, test: Test) -> u32 {
        let mut found = 0;
        self.live = live;
        while self.live != 0 {
            self.hit = 0;
            let contact = match test {
                Test::Environment => self.env_contact::<true>(),
                Test::SelfPairs => self.self_contact::<true>(),
                Test::Hiding => self.may_hide::<true>(),
            };
            if !contact {
                break;
            }
            let hit = match self.hit {
                0 => self.live,
                hit => hit,
            };
            found |= hit;
            self.live &= !hit;
        }
        found
    }
}

/// In [`BatchChecker::lane_flags`]'s walks, whether a contact found in `lanes` counts: true
/// when some of them are still `live`; those are added to `hit`.
#[inline(always)]
pub(super) fn counted(hit: &mut u32, live: u32, lanes: u32) -> bool {
    let lanes = lanes & live;
    *hit |= lanes;
    lanes != 0
}

/// [`counted`] for balls `a` and `b` that [`overlap`].
#[inline(always)]
pub(super) fn overlap_counted(
    hit: &mut u32,
    live: u32,
    (a, ra): ([F8; 3], f32),
    (b, rb): ([F8; 3], f32),
) -> bool {
    counted(hit, live, overlap_lanes(a, ra, b, rb))
}

/// [`counted`] for the ball at `p` with radius `r` where it penetrates the objects `mask`
/// of `objects`.
#[inline(always)]
pub(super) fn objects_counted(
    hit: &mut u32,
    live: u32,
    objects: &[Object8],
    mask: u64,
    p: [F8; 3],
    r: f32,
) -> bool {
    counted(hit, live, penetrating_lanes_of(objects, mask, p, r))
}

/// [`counted`] for the ball at `p` with radius `r` in the lanes of `lanes` (bits) where
/// [`lanes_touch_map`] finds it touching an occupied voxel, each asked alone.
#[inline(always)]
pub(super) fn map_counted(
    hit: &mut u32,
    live: u32,
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
    counted(hit, live, touching)
}
