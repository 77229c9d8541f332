//! Counting the inputs that never reached the daemon: every publisher numbers its messages
//! (`seq`, from 1), and a number skipped was dropped on the way (the subscriber's buffer was
//! full). Unnumbered messages (`seq` 0, e.g. from a foreign client) are not counted.

use std::collections::HashMap;

/// The last number seen per publisher of one input kind.
#[derive(Debug, Default)]
pub struct Gaps {
    last: HashMap<u128, u64>,
}

impl Gaps {
    /// Notes message `seq` from `publisher`; returns how many of its messages were skipped
    /// since the last one seen (since its first, for a publisher not seen before: it numbers
    /// from 1 on connecting). A number at or below the last (a restarted publisher) starts
    /// over.
    pub fn saw(&mut self, publisher: u128, seq: u64) -> u64 {
        if seq == 0 {
            return 0;
        }
        // Publishers come and go: forget the oldest when too many are remembered.
        if self.last.len() >= 4096 && !self.last.contains_key(&publisher) {
            self.last.clear();
        }
        match self.last.insert(publisher, seq) {
            Some(last) if seq > last => seq - last - 1,
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
}
