//! Opening Zenoh sessions with safe defaults: no multicast scouting, loopback endpoints unless
//! configured otherwise. Used by the daemon and by `ember monitor`.

use std::path::Path;
use zenoh::{Config, Session, Wait};

/// What a session needs: mode, endpoints, scouting, and an optional base config file.
#[derive(Debug, Clone)]
pub struct SessionOptions<'a> {
    /// `peer` or `client`.
    pub mode: &'a str,
    /// Endpoints to listen on (`tcp/127.0.0.1:7447`).
    pub listen: &'a [String],
    /// Endpoints to connect to.
    pub connect: &'a [String],
    /// Multicast scouting on the network.
    pub multicast_scouting: bool,
    /// A Zenoh JSON5 config file used as the base.
    pub base: Option<&'a Path>,
}

fn json(v: impl serde::Serialize) -> String {
    serde_json::to_string(&v).expect("JSON of plain values")
}

/// Opens a session; errors name what was wrong (a bad endpoint, a port in use, a bad file).
pub fn open(o: &SessionOptions) -> anyhow::Result<Session> {
    let mut config = match o.base {
        Some(p) => Config::from_file(p)
            .map_err(|e| anyhow::anyhow!("zenoh config {}: {e}", p.display()))?,
        None => Config::default(),
    };
    let set = |c: &mut Config, key: &str, value: String| {
        c.insert_json5(key, &value)
            .map_err(|e| anyhow::anyhow!("zenoh setting {key} = {value}: {e}"))
    };
    set(&mut config, "mode", json(o.mode))?;
    set(&mut config, "listen/endpoints", json(o.listen))?;
    set(&mut config, "connect/endpoints", json(o.connect))?;
    set(
        &mut config,
        "scouting/multicast/enabled",
        json(o.multicast_scouting),
    )?;
    zenoh::open(config).wait().map_err(|e| {
        anyhow::anyhow!(
            "cannot open the Zenoh session (listen {:?}, connect {:?}): {e}",
            o.listen,
            o.connect
        )
    })
}
