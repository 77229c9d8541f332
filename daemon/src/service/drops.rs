//! Counting the inputs that never reached the daemon: every publisher numbers its messages
//! (`seq`, from 1), and a number skipped was dropped on the way (the subscriber's buffer was
//! full). Unnumbered messages (`seq` 0, e.g. from a foreign client) are not counted.

use std::collections::HashMap;

/// The last number seen per publisher of one input kind.
#[derive(Debug, Default)]
pub struct Gaps {
    /// Per publisher: its last number, and when it was last heard from (a message count).
    last: HashMap<u128, (u64, u64)>,
    heard: u64,
}

/// Publishers remembered at most (clients come and go; the longest silent is forgotten).
const REMEMBERED: usize = 4096;

impl Gaps {
    /// Notes message `seq` from `publisher`; returns how many of its messages were skipped
    /// since the last one seen (since its first, for a publisher not seen before: it numbers
    /// from 1 on connecting). A number at or below the last (a restarted publisher) starts
    /// over.
    pub fn saw(&mut self, publisher: u128, seq: u64) -> u64 {
        if seq == 0 {
            return 0;
        }
        self.heard += 1;
        if self.last.len() >= REMEMBERED && !self.last.contains_key(&publisher) {
            // Forget the publisher silent longest (forgetting all would count every live
            // publisher's numbers so far as dropped).
            if let Some(&oldest) = self
                .last
                .iter()
                .min_by_key(|(_, (_, at))| *at)
                .map(|(p, _)| p)
            {
                self.last.remove(&oldest);
            }
        }
        match self.last.insert(publisher, (seq, self.heard)) {
            Some((last, _)) if seq > last => seq - last - 1,
            Some(_) => 0,
            None => seq - 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Gaps;

    #[test]
    fn counts_skipped_numbers_per_publisher() {
        let mut sut = Gaps::default();
        assert_eq!(sut.saw(1, 1), 0);
        assert_eq!(sut.saw(1, 2), 0);
        assert_eq!(sut.saw(1, 5), 2, "3 and 4 were dropped");
        assert_eq!(sut.saw(2, 3), 2, "first seen at 3: 1 and 2 were dropped");
        assert_eq!(sut.saw(2, 4), 0);
        assert_eq!(sut.saw(1, 1), 0, "restarted: starts over");
        assert_eq!(sut.saw(1, 3), 1);
        assert_eq!(sut.saw(3, 0), 0, "unnumbered");
        assert_eq!(sut.saw(3, 0), 0);
    }

    #[test]
    fn many_publishers_forget_the_silent_one_not_the_live_ones() {
        let mut sut = Gaps::default();
        assert_eq!(sut.saw(0, 1), 0);
        for p in 1..super::REMEMBERED as u128 {
            assert_eq!(sut.saw(p, 1), 0);
        }
        // Publisher 1 keeps publishing; a new one makes room by forgetting 0, the oldest.
        assert_eq!(sut.saw(1, 2), 0);
        assert_eq!(sut.saw(99_999, 1), 0);
        assert_eq!(
            sut.saw(1, 3),
            0,
            "a live publisher is still known: nothing dropped"
        );
        assert_eq!(
            sut.saw(0, 7),
            6,
            "the forgotten one counts from its first number again"
        );
    }
}
