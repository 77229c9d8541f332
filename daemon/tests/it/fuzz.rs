//! Fuzzing the recording reader `ember replay` and `ember train` go through: the committed
//! session, mutated at random (and at its chunk bytes), read with CRC checks on and off; every
//! input must read or be refused with a `SessionError`, never panic. Cases:
//! `EMBER_FUZZ_CASES`, seed `EMBER_FUZZ_SEED` (see `tests/fixtures/fuzzing.rs`).

include!("../../../tests/fixtures/fuzzing.rs");

use ember_sdk::session::{Session, SessionError, TopicMap};
use fuzzing::{cases, fuzz_bytes};

#[test]
fn fuzz_the_recording_reader() {
    let seed = std::fs::read(crate::fixtures().join("sessions/table_session.mcap")).unwrap();
    let read = |bytes: &[u8], lenient: bool| {
        let Ok(session) = Session::from_bytes("fuzz", bytes.to_vec()) else {
            return;
        };
        let _ = session.message_count();
        let _ = session.for_each(
            lenient,
            &TopicMap::default(),
            |_, _| -> Result<(), SessionError> { Ok(()) },
        );
    };
    fuzz_bytes("recording (strict)", &seed, cases(2000), |b| read(b, false));
    fuzz_bytes("recording (--allow-truncated)", &seed, cases(2000), |b| {
        read(b, true)
    });
    // The same through a ROS 2 bag's topic map (foreign-bag decoding paths).
    let map = TopicMap::parse(&[
        "/ember/cloud=cloud".into(),
        "/ember/cloud_pose=cloud_pose".into(),
        "/ember/joints=joints".into(),
    ])
    .unwrap();
    fuzz_bytes("recording (topic map)", &seed, cases(1000), |b| {
        if let Ok(s) = Session::from_bytes("fuzz", b.to_vec()) {
            let _ = s.for_each(true, &map, |_, _| -> Result<(), SessionError> { Ok(()) });
        }
    });
}

#[test]
fn a_shifted_chunk_is_refused_not_allocated() {
    // Found by fuzzing (seed 11): one byte of the first chunk's compressed data moved 21 KB
    // further decompresses into a record claiming 1.4e17 bytes; mcap's own stream reserved
    // them and the process aborted. The reader bounds record lengths and refuses it.
    let a = std::fs::read(crate::fixtures().join("sessions/table_session.mcap")).unwrap();
    let bytes = [&a[..21363], &a[21364..42361], &[0xb9], &a[42361..]].concat();
    let session = Session::from_bytes("shifted", bytes).unwrap();
    for lenient in [false, true] {
        let read = session.for_each(
            lenient,
            &TopicMap::default(),
            |_, _| -> Result<(), SessionError> { Ok(()) },
        );
        match lenient {
            false => assert!(
                matches!(read, Err(SessionError::Damaged { .. })),
                "{read:?}"
            ),
            true => assert!(read.is_ok()),
        }
    }
}
