//! A recording file that ends with a valid MCAP end (data end, footer, magic) after every
//! flush, so a daemon killed at any moment (or stopped by a full disk) leaves a file the
//! standard readers read to its last flushed chunk without an error.
//!
//! Writes are held in memory; a flush writes them, followed by a provisional end, in one write
//! at the end of what was written before, and the next flush writes over that provisional end.
//! The MCAP writer builds each chunk in memory (`disable_seeking`), so it only ever asks this
//! file for its position.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::os::unix::fs::FileExt;

/// DataEnd (opcode 0x0F, CRC 0: not computed), Footer (opcode 0x02, no summary), magic.
const PROVISIONAL_END: [u8; 13 + 29 + 8] = {
    let mut b = [0u8; 50];
    b[0] = 0x0F;
    b[1] = 4; // record length, u64 LE; the CRC (4 zero bytes) follows
    b[13] = 0x02;
    b[14] = 20; // summary start, summary offset start (u64), summary CRC (u32): all zero
    let magic = *b"\x89MCAP0\r\n";
    let mut i = 0;
    while i < 8 {
        b[42 + i] = magic[i];
        i += 1;
    }
    b
};

/// See the module documentation.
pub struct TailFile {
    file: File,
    /// Bytes on disk that stay (everything before the provisional end).
    written: u64,
    pending: Vec<u8>,
}

impl TailFile {
    /// Wraps a new, empty file.
    pub fn new(file: File) -> Self {
        TailFile {
            file,
            written: 0,
            pending: Vec::new(),
        }
    }

    /// Gives the file up after a failed write (a full disk): cuts whatever the failed write
    /// left after the last complete chunk and ends the file there, so it reads to that chunk.
    /// Cutting frees the space the end needs.
    pub fn abandon(self) -> io::Result<()> {
        self.file.set_len(self.written)?;
        self.file.write_all_at(&PROVISIONAL_END, self.written)?;
        self.file.sync_all()
    }

    /// Writes what is pending without a provisional end (the writer has written the real one)
    /// and cuts the file there.
    pub fn finish(mut self) -> io::Result<()> {
        self.file.write_all_at(&self.pending, self.written)?;
        self.written += self.pending.len() as u64;
        self.file.set_len(self.written)?;
        self.file.sync_all()
    }
}

impl Write for TailFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.pending.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        let kept = self.pending.len() as u64;
        self.pending.extend_from_slice(&PROVISIONAL_END);
        // One write: a regular file's write is not cut short by a signal.
        let result = self.file.write_all_at(&self.pending, self.written);
        self.pending.truncate(kept as usize);
        result?;
        self.written += kept;
        self.pending.clear();
        Ok(())
    }
}

impl Seek for TailFile {
    /// Only reports the position (what the MCAP writer asks when it does not seek).
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let here = self.written + self.pending.len() as u64;
        match to {
            SeekFrom::Current(0) | SeekFrom::End(0) => Ok(here),
            SeekFrom::Start(p) if p == here => Ok(here),
            _ => Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "the recording file is append-only",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_file_always_ends_with_a_valid_end() {
        let path = std::env::temp_dir().join(format!("ember-tail-{}.mcap", std::process::id()));
        let mut w = mcap::WriteOptions::new()
            .disable_seeking(true)
            .create(TailFile::new(File::create(&path).unwrap()))
            .unwrap();
        let schema = w.add_schema("s", "jsonschema", b"{}").unwrap();
        let channel = w
            .add_channel(schema, "/t", "json", &Default::default())
            .unwrap();
        for k in 0..3u32 {
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: k,
                log_time: k as u64,
                publish_time: k as u64,
            };
            w.write_to_known_channel(&header, b"{}").unwrap();
            w.flush().unwrap();
            // As a kill would leave it: every message so far, then a clean end.
            let bytes = std::fs::read(&path).unwrap();
            let read: Vec<_> = mcap::MessageStream::new(&bytes)
                .unwrap()
                .collect::<Result<_, _>>()
                .unwrap();
            assert_eq!(read.len(), k as usize + 1);
            assert!(bytes.ends_with(b"\x89MCAP0\r\n"));
        }
        w.finish().unwrap();
        w.into_inner().finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert_eq!(summary.stats.unwrap().message_count, 3);
        std::fs::remove_file(&path).ok();
    }
}
