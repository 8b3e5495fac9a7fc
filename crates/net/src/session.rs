//! Network edges on zenoh (issue 21): what the `zenoh_pub` sink, the
//! `zenoh_sub` source and `vibroscope monitor` share.
//!
//! Each item crosses as one zenoh sample: the payload is the item in the
//! versioned [`crate::wire`] encoding, the attachment the publisher's
//! sequence number (8 bytes, little-endian), so a receiver counts what it
//! lost. A publisher ends its stream with a *delete* on its key whose
//! attachment is the number of items it sent: a replay receiver finishes
//! there, and knows whether it got them all.
//!
//! Sessions are zenoh peers on TCP with multicast scouting off: a process
//! reaches exactly the endpoints it is given (`connect`) and is reached on
//! the ones it listens on (`listen`), so two test runs on one machine never
//! find each other by accident.

use std::time::Duration;
use vibroscope_core::config::{ConfigError, Params};
use vibroscope_core::stage::StageError;
pub use zenoh;
use zenoh::Wait;

/// The attachment of an item: its sequence number.
pub fn seq_attachment(seq: u64) -> [u8; 8] {
    seq.to_le_bytes()
}

/// Reads a sequence number attachment (`None` when absent or not 8 bytes).
pub fn read_seq(att: Option<&zenoh::bytes::ZBytes>) -> Option<u64> {
    let b = att?.to_bytes();
    let a: [u8; 8] = b.as_ref().try_into().ok()?;
    Some(u64::from_le_bytes(a))
}

/// Where a session connects and listens.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Endpoints {
    pub connect: Vec<String>,
    pub listen: Vec<String>,
}

/// Splits a comma-separated endpoint list and checks each endpoint
/// parses (`tcp/127.0.0.1:7447`).
pub fn parse_endpoints(text: &str) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    for e in text.split(',').map(str::trim).filter(|e| !e.is_empty()) {
        e.parse::<zenoh::config::EndPoint>().map_err(|why| {
            format!("endpoint {e:?} does not parse ({why}); expected e.g. \"tcp/127.0.0.1:7447\"")
        })?;
        out.push(e.to_string());
    }
    Ok(out)
}

/// Reads `connect` and `listen` (each a comma-separated endpoint list)
/// for a stage's parameters, naming the field that is wrong.
pub fn endpoints(p: &Params<'_>, connect: &str, listen: &str) -> Result<Endpoints, ConfigError> {
    Ok(Endpoints {
        connect: parse_endpoints(connect).map_err(|m| p.error("connect", m))?,
        listen: parse_endpoints(listen).map_err(|m| p.error("listen", m))?,
    })
}

/// Checks a key expression: the zenoh grammar, without `$*` wildcards
/// inside a chunk unless `allow_wild`. The message says what is wrong.
pub fn check_key(key: &str, allow_wild: bool) -> Result<(), String> {
    let ke = zenoh::key_expr::KeyExpr::try_from(key)
        .map_err(|why| format!("key expression {key:?} does not parse: {why}"))?;
    if !allow_wild && key.split('/').any(|c| c.contains('*')) {
        return Err(format!(
            "key expression {ke} has a wildcard: a publisher needs one exact key"
        ));
    }
    Ok(())
}

/// Opens a zenoh peer session on the given endpoints.
pub fn open_session(ep: &Endpoints) -> Result<zenoh::Session, StageError> {
    open_session_plain(ep).map_err(|why| StageError::device("zenoh", why))
}

/// [`open_session`] for callers outside a pipeline: the error as text.
pub fn open_session_plain(ep: &Endpoints) -> Result<zenoh::Session, String> {
    let mut c = zenoh::Config::default();
    let json = |v: &[String]| serde_json::to_string(v).unwrap_or_else(|_| "[]".into());
    let set = |c: &mut zenoh::Config, k: &str, v: &str| {
        c.insert_json5(k, v)
            .map_err(|e| format!("zenoh configuration {k} = {v}: {e}"))
    };
    set(&mut c, "mode", "\"peer\"")?;
    set(&mut c, "scouting/multicast/enabled", "false")?;
    set(&mut c, "connect/endpoints", &json(&ep.connect))?;
    set(&mut c, "listen/endpoints", &json(&ep.listen))?;
    // Keep retrying a connect endpoint that is not up yet (a monitor
    // started after its cameras, or restarted): every second, for ever.
    set(&mut c, "connect/timeout_ms", "-1")?;
    set(&mut c, "connect/exit_on_failure", "false")?;
    set(
        &mut c,
        "connect/retry",
        "{period_init_ms: 250, period_max_ms: 1000, period_increase_factor: 2}",
    )?;
    set(&mut c, "listen/exit_on_failure", "true")?;
    // Return at once rather than wait for a peer that is not up yet (a
    // replay publisher waits for its subscriber itself).
    set(&mut c, "open/return_conditions/connect_scouted", "false")?;
    zenoh::open(c).wait().map_err(|e| {
        format!(
            "cannot open a zenoh session (connect {:?}, listen {:?}): {e}",
            ep.connect, ep.listen
        )
    })
}

/// How long a replay publisher waits for its first subscriber by default.
pub const DEFAULT_WAIT_S: f64 = 30.0;

/// Polling period of blocking receives (so a stop request is seen).
pub const POLL: Duration = Duration::from_millis(50);
