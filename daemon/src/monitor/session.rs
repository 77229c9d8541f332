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

/// How a session authenticates, as its Zenoh config file (`base`) sets it.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Authentication {
    /// It admits only peers whose user and password are in its dictionary file.
    pub requires_usrpwd: bool,
    /// The user it authenticates as.
    pub user: Option<String>,
}

impl Authentication {
    /// What the config file at `base` (none: Zenoh's defaults) sets.
    pub fn of(base: Option<&Path>) -> anyhow::Result<Authentication> {
        let Some(p) = base else {
            return Ok(Authentication::default());
        };
        let config = Config::from_file(p)
            .map_err(|e| anyhow::anyhow!("zenoh config {}: {e}", p.display()))?;
        let value = |key: &str| -> Option<String> {
            let v = config.get_json(key).ok()?;
            serde_json::from_str::<Option<String>>(&v).ok().flatten()
        };
        Ok(Authentication {
            requires_usrpwd: value("transport/auth/usrpwd/dictionary_file").is_some(),
            user: value("transport/auth/usrpwd/user"),
        })
    }

    /// `usrpwd` when peers must authenticate, else `none`.
    pub fn required(&self) -> &'static str {
        match self.requires_usrpwd {
            true => "usrpwd",
            false => "none",
        }
    }
}
