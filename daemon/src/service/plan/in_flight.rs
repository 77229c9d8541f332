//! The plans taken off the port and not yet answered: their age (for the status, so a watchdog
//! can see a stuck planner) and their cancel flags (a cancel request by id, or the daemon
//! stopping).

use ember_engine::planning::Cancel;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// One plan in flight.
#[derive(Debug)]
struct Entry {
    /// The client's request id (0: none given).
    request_id: u64,
    received: Instant,
    cancel: Arc<AtomicBool>,
}

/// The registry of plans in flight, keyed by the daemon's job number.
#[derive(Debug, Default)]
pub struct InFlight {
    jobs: Mutex<HashMap<u64, Entry>>,
}

/// Plans in flight at one moment.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct InFlightSummary {
    /// How many.
    pub count: u64,
    /// Age of the oldest (zero when none).
    pub oldest: Duration,
}

impl InFlight {
    /// Registers job `job` (client id `request_id`), received at `received`; returns the token
    /// its plan reads.
    pub fn start(&self, job: u64, request_id: u64, received: Instant) -> Cancel {
        let cancel = Arc::new(AtomicBool::new(false));
        self.lock().insert(
            job,
            Entry {
                request_id,
                received,
                cancel: cancel.clone(),
            },
        );
        Cancel::new(cancel)
    }

    /// Removes job `job` (answered).
    pub fn finish(&self, job: u64) {
        self.lock().remove(&job);
    }

    /// Cancels the plans in flight with client id `request_id` (never 0); returns how many.
    pub fn cancel_request(&self, request_id: u64) -> usize {
        if request_id == 0 {
            return 0;
        }
        let jobs = self.lock();
        let mut n = 0;
        for e in jobs.values().filter(|e| e.request_id == request_id) {
            e.cancel.store(true, Ordering::Relaxed);
            n += 1;
        }
        n
    }

    /// Cancels every plan in flight (the daemon is stopping).
    pub fn cancel_all(&self) {
        for e in self.lock().values() {
            e.cancel.store(true, Ordering::Relaxed);
        }
    }

    /// How many plans are in flight and the oldest one's age.
    pub fn summary(&self) -> InFlightSummary {
        let jobs = self.lock();
        InFlightSummary {
            count: jobs.len() as u64,
            oldest: jobs
                .values()
                .map(|e| e.received.elapsed())
                .max()
                .unwrap_or_default(),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<u64, Entry>> {
        self.jobs.lock().expect("in-flight lock")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cancels_by_request_id_and_reports_the_oldest() {
        let sut = InFlight::default();
        let t0 = Instant::now() - Duration::from_millis(500);
        let a = sut.start(1, 42, t0);
        let b = sut.start(2, 7, Instant::now());
        let none = sut.start(3, 0, Instant::now());
        let s = sut.summary();
        assert_eq!(s.count, 3);
        assert!(s.oldest >= Duration::from_millis(500));

        assert_eq!(sut.cancel_request(42), 1);
        assert_eq!(sut.cancel_request(0), 0, "id 0 names no request");
        assert_eq!(sut.cancel_request(99), 0);
        assert!(a.is_set() && !b.is_set() && !none.is_set());

        sut.finish(1);
        assert_eq!(sut.summary().count, 2);
        assert!(sut.summary().oldest < Duration::from_millis(500));
        sut.cancel_all();
        assert!(b.is_set() && none.is_set());
        sut.finish(2);
        sut.finish(3);
        assert_eq!(sut.summary(), InFlightSummary::default());
    }
}
