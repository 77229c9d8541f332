//! The session recorder: everything the daemon receives and answers, with receive time, into MCAP
//! files (zstd chunks, indexes, summary) that ROS 2 tools, Foxglove and the Python `mcap` readers
//! open.
//!
//! Recording never slows the daemon: records go through a bounded queue to a writer thread; when
//! the queue is full the record is dropped and counted (visible in the status service and logged).
//! Files rotate by size or duration. The writer finishes a chunk at least every second, so a
//! daemon killed mid-recording leaves a file whose complete chunks are all readable; a clean stop
//! writes the summary and index.
//!
//! Topics: `/ember/cloud` (`sensor_msgs/msg/PointCloud2`), `/ember/cloud_pose` (the sensor pose,
//! `geometry_msgs/msg/PoseStamped`, same stamp), `/ember/joints` (`sensor_msgs/msg/JointState`),
//! `/ember/objects` (`ember_msgs/msg/ObjectUpdate`), `/ember/plan_request` and
//! `/ember/plan_response` (`ember_msgs/msg/PlanRequest`, `.../PlanResponse`). Log time is the
//! daemon's receive (or reply) time; header stamps are the sender's.

mod tail;

use ember_sdk::recording::{self as messages, Event};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tail::TailFile;
use tracing::{error, info, warn};

/// One thing to record: an event and the daemon's receive (or reply) time, ns.
pub type Record = (u64, Event);

/// Recorder settings.
#[derive(Debug, Clone)]
pub struct RecorderOptions {
    /// Folder of the session files.
    pub dir: PathBuf,
    /// Start a new file past this size, bytes.
    pub max_file_bytes: u64,
    /// Start a new file past this duration.
    pub max_file_duration: Duration,
    /// Records the queue holds before dropping.
    pub queue: usize,
    /// Mode of the session files.
    pub file_mode: u32,
    /// Target uncompressed chunk size, bytes.
    pub chunk_bytes: u64,
}

/// Counters of the recorder.
#[derive(Debug, Default)]
pub struct RecorderStats {
    pub written: AtomicU64,
    pub dropped: AtomicU64,
    /// Times writing failed (a full disk, an I/O error) and recording paused.
    pub failures: AtomicU64,
    /// Paused by a failure now, retrying.
    pub failing: std::sync::atomic::AtomicBool,
    pub bytes: AtomicU64,
    /// The file being written.
    pub current: std::sync::Mutex<PathBuf>,
}

/// The handle the daemon's threads send records to.
#[derive(Clone)]
pub struct Recorder {
    tx: SyncSender<Record>,
    stats: Arc<RecorderStats>,
}

impl Recorder {
    /// Queues `event`, received (or sent) at `recv_ns`; drops (and counts) it when the writer
    /// is behind.
    pub fn record(&self, recv_ns: u64, event: Event) {
        match self.tx.try_send((recv_ns, event)) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                let n = self.stats.dropped.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_power_of_two() {
                    warn!("recording queue full: {n} records dropped so far");
                }
            }
        }
    }

    /// The counters.
    pub fn stats(&self) -> &Arc<RecorderStats> {
        &self.stats
    }
}

/// Starts the writer thread; returns the handle and the thread (joined after the last handle is
/// dropped, which closes the files cleanly).
pub fn start(
    options: RecorderOptions,
) -> anyhow::Result<(Recorder, std::thread::JoinHandle<()>, PathBuf)> {
    std::fs::create_dir_all(&options.dir).map_err(|e| {
        anyhow::anyhow!(
            "cannot create recording folder {}: {e}",
            options.dir.display()
        )
    })?;
    let (tx, rx) = sync_channel(options.queue.max(1));
    let first = file_name(&options.dir, 0);
    let stats = Arc::new(RecorderStats {
        current: std::sync::Mutex::new(first.clone()),
        ..Default::default()
    });
    let writer = SessionWriter::open(&first, &options)?;
    let st = stats.clone();
    let thread = std::thread::Builder::new()
        .name("recorder".into())
        .spawn(move || run(rx, writer, options, st))?;
    Ok((Recorder { tx, stats }, thread, first))
}

fn file_name(dir: &Path, index: usize) -> PathBuf {
    let ns = ember_sdk::client::now_ns();
    dir.join(format!("session-{}-{index:03}.mcap", ns / 1_000_000))
}

/// One open MCAP file with its channels.
struct SessionWriter {
    writer: mcap::Writer<TailFile>,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
    opened: Instant,
    bytes: u64,
    /// Message bytes in the chunk not yet closed, and the size that closes it.
    unflushed: u64,
    chunk_bytes: u64,
    path: PathBuf,
}

impl SessionWriter {
    fn open(path: &Path, options: &RecorderOptions) -> anyhow::Result<Self> {
        // Owner-only, as the databases: recordings hold the robot's surroundings.
        let file = ember_engine::experience::file::private_file(path)
            .and_then(|f| {
                use std::os::unix::fs::PermissionsExt;
                f.set_permissions(std::fs::Permissions::from_mode(options.file_mode))?;
                Ok(f)
            })
            .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", path.display()))?;
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            // Chunks are closed here (`write`), each on disk as soon as it is complete; the
            // writer's own limit is set above ours so it never holds two.
            .chunk_size(Some(options.chunk_bytes.saturating_mul(2)))
            .profile("ros2")
            .library("ember")
            // Each chunk is built in memory and written whole, followed by a provisional end
            // (`tail`): a file cut by a kill or a full disk reads to its last flushed chunk
            // with every standard reader (a chunk streamed in place left a length of 2^64-1).
            .disable_seeking(true)
            .create(TailFile::new(file))
            .map_err(|e| anyhow::anyhow!("cannot start {}: {e}", path.display()))?;
        let schemas: BTreeMap<&str, String> = messages::schemas().into_iter().collect();
        let mut channels = BTreeMap::new();
        for (name, ty) in messages::TOPICS {
            let schema = writer.add_schema(ty, "ros2msg", schemas[ty].as_bytes())?;
            channels.insert(
                name,
                writer.add_channel(schema, name, "cdr", &BTreeMap::new())?,
            );
        }
        // On disk at once, readable from the start.
        writer.flush()?;
        info!("recording to {}", path.display());
        Ok(SessionWriter {
            writer,
            channels,
            sequence: 0,
            opened: Instant::now(),
            bytes: 0,
            unflushed: 0,
            chunk_bytes: options.chunk_bytes,
            path: path.to_path_buf(),
        })
    }

    fn write(
        &mut self,
        topic: &'static str,
        log_ns: u64,
        publish_ns: u64,
        data: &[u8],
    ) -> anyhow::Result<()> {
        self.sequence += 1;
        let header = mcap::records::MessageHeader {
            channel_id: self.channels[topic],
            sequence: self.sequence,
            log_time: log_ns,
            publish_time: publish_ns,
        };
        self.writer.write_to_known_channel(&header, data)?;
        self.bytes += data.len() as u64;
        self.unflushed += data.len() as u64;
        if self.unflushed >= self.chunk_bytes {
            self.flush()?;
        }
        Ok(())
    }

    /// Closes the current chunk and puts it on disk (followed by a provisional end).
    fn flush(&mut self) -> anyhow::Result<()> {
        self.unflushed = 0;
        self.writer.flush()?;
        Ok(())
    }

    /// Gives the file up after a failed write: it ends after its last complete chunk.
    fn abandon(self) {
        if let Err(e) = self.writer.into_inner().abandon() {
            error!(
                "cutting {} after the failure failed: {e}",
                self.path.display()
            );
        }
    }

    fn finish(mut self) {
        let done = self
            .writer
            .finish()
            .map_err(anyhow::Error::from)
            .and_then(|_| Ok(self.writer.into_inner().finish()?));
        if let Err(e) = done {
            error!("closing {} failed: {e}", self.path.display());
        }
    }
}

/// Writes one record; returns the bytes written.
fn write_record(w: &mut SessionWriter, (recv_ns, event): Record) -> anyhow::Result<u64> {
    let mut n = 0;
    for (topic, publish_ns, data) in event.messages(recv_ns) {
        w.write(topic, recv_ns, publish_ns, &data)?;
        n += data.len() as u64;
    }
    Ok(n)
}

/// Where records go: a file, or nowhere while a failure (a full disk) lasts.
enum Output {
    Writing(Box<SessionWriter>),
    /// Records are dropped (counted) until a new file opens, tried at `retry_at`.
    Paused {
        retry_at: Instant,
        backoff: Duration,
    },
}

/// The first and the longest wait before opening a new file after a failure.
const RETRY_FIRST: Duration = Duration::from_millis(100);
const RETRY_MAX: Duration = Duration::from_secs(2);

/// Bytes free for an unprivileged writer on the file system holding `dir` (None: unknown).
fn free_bytes(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let path = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: `path` is a NUL-terminated string and `st` a valid statvfs to fill.
    match unsafe { libc::statvfs(path.as_ptr(), &mut st) } {
        0 => Some(st.f_bavail as u64 * st.f_frsize as u64),
        _ => None,
    }
}

impl Output {
    /// Gives the file up after `e` and pauses (one log line per pause).
    fn fail(&mut self, e: anyhow::Error, stats: &RecorderStats) {
        if let Output::Writing(_) = self {
            error!("recording paused: {e:#}; records are dropped (counted) until it resumes");
            stats.failures.fetch_add(1, Ordering::Relaxed);
            stats.failing.store(true, Ordering::Relaxed);
            let paused = Output::Paused {
                retry_at: Instant::now() + RETRY_FIRST,
                backoff: RETRY_FIRST,
            };
            if let Output::Writing(w) = std::mem::replace(self, paused) {
                w.abandon();
            }
        }
    }
}

fn run(
    rx: Receiver<Record>,
    first: SessionWriter,
    options: RecorderOptions,
    stats: Arc<RecorderStats>,
) {
    let mut output = Output::Writing(Box::new(first));
    let mut index = 0;
    let mut last_flush = Instant::now();
    loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(r) => match &mut output {
                Output::Writing(w) => match write_record(w, r) {
                    Ok(bytes) => {
                        stats.written.fetch_add(1, Ordering::Relaxed);
                        stats.bytes.fetch_add(bytes, Ordering::Relaxed);
                    }
                    Err(e) => {
                        stats.dropped.fetch_add(1, Ordering::Relaxed);
                        output.fail(e, &stats);
                    }
                },
                Output::Paused { .. } => {
                    stats.dropped.fetch_add(1, Ordering::Relaxed);
                }
            },
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
        }
        let rotate = match &mut output {
            Output::Writing(w) => {
                // Finish a chunk at least every second: what a crash leaves stays readable.
                if last_flush.elapsed() >= Duration::from_secs(1) {
                    last_flush = Instant::now();
                    if let Err(e) = w.flush() {
                        output.fail(e, &stats);
                        continue;
                    }
                }
                w.bytes >= options.max_file_bytes || w.opened.elapsed() >= options.max_file_duration
            }
            // Resume only with room for a chunk: a file opened on a disk still full would
            // fail again at its first chunk.
            Output::Paused { retry_at, backoff } if Instant::now() >= *retry_at => {
                let room = free_bytes(&options.dir).is_none_or(|b| b >= options.chunk_bytes);
                if !room {
                    *backoff = (*backoff * 2).min(RETRY_MAX);
                    *retry_at = Instant::now() + *backoff;
                }
                room
            }
            Output::Paused { .. } => false,
        };
        if !rotate {
            continue;
        }
        // A new file: rotation, or a retry after a failure.
        index += 1;
        let path = file_name(&options.dir, index);
        match SessionWriter::open(&path, &options) {
            Ok(next) => {
                if let Output::Writing(done) =
                    std::mem::replace(&mut output, Output::Writing(Box::new(next)))
                {
                    done.finish();
                } else {
                    info!("recording resumed in {}", path.display());
                    stats.failing.store(false, Ordering::Relaxed);
                }
                *stats.current.lock().expect("recorder path lock") = path;
            }
            Err(e) => {
                // The half-made file goes: it holds no message.
                std::fs::remove_file(&path).ok();
                match &mut output {
                    Output::Writing(_) => output.fail(e.context("cannot rotate"), &stats),
                    Output::Paused { retry_at, backoff } => {
                        *backoff = (*backoff * 2).min(RETRY_MAX);
                        *retry_at = Instant::now() + *backoff;
                    }
                }
            }
        }
    }
    if let Output::Writing(w) = output {
        w.finish();
    }
}
