//! Remote monitoring over Zenoh: the daemon's status, plan summaries, objects and a decimated
//! map, published under `ember/<instance>/` (keys and documents: [`ember_sdk::monitor`]), a
//! liveliness token, and queryables answering on demand. Read-only: nothing received over Zenoh
//! changes the daemon. Publishing runs on its own thread; the planner only hands over a summary
//! through a bounded queue after each reply.

pub mod docs;
pub mod session;

use crate::config::MonitorConfig;
use docs::Sources;
use ember_sdk::monitor::{key, PlanSummary};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tracing::{info, warn};
use zenoh::bytes::Encoding;
use zenoh::query::Query;
use zenoh::{Session, Wait};

/// The handle the planner hands summaries to; dropping it stops the publisher (the liveliness
/// token goes with it, so watchers see the daemon leave).
pub struct Monitor {
    tx: SyncSender<PlanSummary>,
    sources: Arc<Sources>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Monitor {
    /// Opens the Zenoh session, declares the token and queryables, starts the publisher thread.
    pub fn start(config: &MonitorConfig, sources: Arc<Sources>) -> anyhow::Result<Monitor> {
        let options = session::SessionOptions {
            mode: &config.mode,
            listen: &config.listen,
            connect: &config.connect,
            multicast_scouting: config.multicast_scouting,
            base: (!config.zenoh_config.as_os_str().is_empty())
                .then_some(config.zenoh_config.as_path()),
        };
        let zenoh = match session::open(&options) {
            Ok(s) => s,
            // Another daemon on this machine holds the port: join it as a peer on a free
            // loopback port; watchers connected to it learn about this one by gossip.
            Err(e) if config.connect.is_empty() && e.to_string().contains("in use") => {
                let ephemeral = ["tcp/127.0.0.1:0".to_string()];
                let joined = session::open(&session::SessionOptions {
                    listen: &ephemeral,
                    connect: &config.listen,
                    ..options
                })?;
                info!(
                    "{:?} in use: joined the daemon there as a peer",
                    config.listen
                );
                joined
            }
            Err(e) => return Err(e),
        };
        let (tx, rx) = sync_channel(config.queue);
        let mut publisher = Publisher::declare(zenoh, sources.clone(), config)?;
        let thread = std::thread::Builder::new()
            .name("monitor".into())
            .spawn(move || publisher.run(rx))?;
        info!(
            "monitoring over Zenoh under ember/{}/ (listen {:?}, connect {:?})",
            sources.instance, config.listen, config.connect
        );
        Ok(Monitor {
            tx,
            sources,
            thread: Some(thread),
        })
    }

    /// Queues a plan summary; drops (and counts) it when the publisher is behind.
    pub fn plan(&self, summary: PlanSummary) {
        if let Err(TrySendError::Full(_)) = self.tx.try_send(summary) {
            self.sources.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl Drop for Monitor {
    fn drop(&mut self) {
        // Closing the queue ends the thread, which closes the session.
        let (dead, _) = sync_channel(1);
        drop(std::mem::replace(&mut self.tx, dead));
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The publisher thread's state.
struct Publisher {
    session: Session,
    sources: Arc<Sources>,
    status: zenoh::pubsub::Publisher<'static>,
    plans: zenoh::pubsub::Publisher<'static>,
    objects: zenoh::pubsub::Publisher<'static>,
    map: zenoh::pubsub::Publisher<'static>,
    _alive: zenoh::liveliness::LivelinessToken,
    _queryables: Vec<zenoh::query::Queryable<()>>,
    status_period: Duration,
    objects_period: Duration,
    map_period: Duration,
}

fn reply(query: &Query, key: &str, payload: Vec<u8>, encoding: Encoding) {
    if let Err(e) = query.reply(key, payload).encoding(encoding).wait() {
        warn!("answering a Zenoh query on {key} failed: {e}");
    }
}

impl Publisher {
    fn declare(
        session: Session,
        sources: Arc<Sources>,
        config: &MonitorConfig,
    ) -> anyhow::Result<Publisher> {
        let instance = sources.instance.clone();
        let z = |e: zenoh::Error| anyhow::anyhow!("zenoh: {e}");
        let publisher = |leaf: &str, encoding: Encoding| {
            session
                .declare_publisher(key(&instance, leaf))
                .encoding(encoding)
                .wait()
                .map_err(z)
        };
        let json = Encoding::APPLICATION_JSON;
        let binary = Encoding::APPLICATION_OCTET_STREAM;
        let status = publisher("status", json.clone())?;
        let plans = publisher("plans", json.clone())?;
        let objects = publisher("objects", json.clone())?;
        let map = publisher("map", binary.clone())?;
        let alive = session
            .liveliness()
            .declare_token(key(&instance, "alive"))
            .wait()
            .map_err(z)?;
        type Answer = fn(&Sources) -> (Vec<u8>, Encoding);
        let answers: [(&str, Answer); 4] = [
            ("status", |s| {
                (
                    serde_json::to_vec(&s.status(false)).expect("JSON"),
                    Encoding::APPLICATION_JSON,
                )
            }),
            ("database", |s| {
                (
                    serde_json::to_vec(&s.database()).expect("JSON"),
                    Encoding::APPLICATION_JSON,
                )
            }),
            ("objects", |s| {
                (s.objects().1.into_bytes(), Encoding::APPLICATION_JSON)
            }),
            ("map", |s| (s.map().1, Encoding::APPLICATION_OCTET_STREAM)),
        ];
        let mut queryables = Vec::new();
        for (leaf, answer) in answers {
            let k = key(&instance, leaf);
            let src = sources.clone();
            let q = session
                .declare_queryable(k.clone())
                .callback(move |query| {
                    let (payload, encoding) = answer(&src);
                    reply(&query, &k, payload, encoding);
                })
                .wait()
                .map_err(z)?;
            queryables.push(q);
        }
        Ok(Publisher {
            session,
            sources,
            status,
            plans,
            objects,
            map,
            _alive: alive,
            _queryables: queryables,
            status_period: Duration::from_secs_f64(1.0 / config.status_hz),
            objects_period: Duration::from_secs_f64(config.objects_period_s),
            map_period: Duration::from_secs_f64(config.map_period_s),
        })
    }

    fn put(publisher: &zenoh::pubsub::Publisher<'static>, payload: Vec<u8>) {
        if let Err(e) = publisher.put(payload).wait() {
            warn!("publishing on {} failed: {e}", publisher.key_expr());
        }
    }

    fn run(&mut self, rx: Receiver<PlanSummary>) {
        let now = Instant::now();
        let (mut next_status, mut next_objects, mut next_map) = (now, now, now);
        let (mut objects_version, mut map_version) = (None, None);
        loop {
            let wait = next_status.min(next_objects).min(next_map);
            match rx.recv_timeout(wait.saturating_duration_since(Instant::now())) {
                Ok(summary) => {
                    Self::put(&self.plans, serde_json::to_vec(&summary).expect("JSON"));
                    continue;
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            let now = Instant::now();
            if now >= next_status {
                let doc = self.sources.status(true);
                Self::put(&self.status, serde_json::to_vec(&doc).expect("JSON"));
                next_status = now + self.status_period;
            }
            // Objects: on change (seen within a status period), and periodically for late joiners.
            if now >= next_objects || Some(self.sources.objects_version()) != objects_version {
                let (version, json) = self.sources.objects();
                Self::put(&self.objects, json.into_bytes());
                objects_version = Some(version);
                next_objects = now + self.objects_period;
            }
            if now >= next_map {
                let (version, bytes) = self.sources.map();
                if Some(version) != map_version {
                    Self::put(&self.map, bytes);
                    map_version = Some(version);
                }
                next_map = now + self.map_period;
            }
        }
        // Token and queryables go with the session.
        if let Err(e) = self.session.close().wait() {
            warn!("closing the Zenoh session: {e}");
        }
    }
}
