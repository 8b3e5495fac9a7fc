//! The monitor's events as another process sees them: a subscription to
//! the key `vibroscope monitor` publishes its events on, kept as the state
//! of each source (ok, alarm, stale, ended; its tracks) and the latest
//! events. The studio shows it (`vibroscope studio --monitor ENDPOINT`).

use serde_json::{json, Map, Value};
use std::collections::{BTreeMap, VecDeque};
use std::sync::{Arc, Mutex};
use vibroscope_net::session::{self as net, Endpoints};
use zenoh::Wait;

/// Events kept, newest last.
const KEEP: usize = 200;

#[derive(Default)]
struct State {
    sources: BTreeMap<String, Value>,
    events: VecDeque<Value>,
    received: u64,
    unreadable: u64,
}

/// A live view of a monitor's events.
pub struct Feed {
    pub endpoints: Endpoints,
    pub key: String,
    state: Arc<Mutex<State>>,
    _sub: zenoh::pubsub::Subscriber<()>,
    _session: zenoh::Session,
}

impl Feed {
    /// Subscribes to `key` (the monitor's `--events-key`) over `endpoints`.
    pub fn start(endpoints: Endpoints, key: &str) -> Result<Feed, String> {
        net::check_key(key, true)?;
        if endpoints.connect.is_empty() && endpoints.listen.is_empty() {
            return Err("give the monitor's endpoint (tcp/HOST:PORT)".into());
        }
        let session = net::open_session_plain(&endpoints)?;
        let state = Arc::new(Mutex::new(State::default()));
        let st = state.clone();
        let sub = session
            .declare_subscriber(key.to_string())
            .callback(move |sample| {
                let mut s = st.lock().unwrap_or_else(|e| e.into_inner());
                match serde_json::from_slice::<Value>(&sample.payload().to_bytes()) {
                    Ok(v) if v.is_object() => s.take(v),
                    _ => s.unreadable += 1,
                }
            })
            .wait()
            .map_err(|e| format!("cannot subscribe to {key}: {e}"))?;
        Ok(Feed {
            endpoints,
            key: key.to_string(),
            state,
            _sub: sub,
            _session: session,
        })
    }

    /// Each source's state and the latest events, newest first.
    pub fn snapshot(&self) -> Value {
        let s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        json!({
            "endpoints": self.endpoints.connect.iter().chain(&self.endpoints.listen).collect::<Vec<_>>(),
            "key": self.key,
            "received": s.received,
            "unreadable": s.unreadable,
            "sources": s.sources,
            "events": s.events.iter().rev().take(50).collect::<Vec<_>>(),
        })
    }
}

impl State {
    fn take(&mut self, v: Value) {
        self.received += 1;
        let kind = v["event"].as_str().unwrap_or("").to_string();
        let source = v["source"].as_str().unwrap_or("").to_string();
        if !source.is_empty() && kind != "summary" {
            let e = self
                .sources
                .entry(source)
                .or_insert_with(|| json!({"state": "ok", "tracks": {}}));
            let track = v["track"].as_u64().map(|t| t.to_string());
            if let (Some(t), Some(tracks)) = (&track, e["tracks"].as_object_mut()) {
                let entry = tracks
                    .entry(t.clone())
                    .or_insert_with(|| Value::Object(Map::new()));
                for k in ["frequency_hz", "sigma_hz", "damping_ratio", "power_db"] {
                    if !v[k].is_null() {
                        entry[k] = v[k].clone();
                    }
                }
                match kind.as_str() {
                    "alarm" | "lost" => entry["alarmed"] = json!(true),
                    "cleared" | "track" => entry["alarmed"] = json!(false),
                    _ => {}
                }
            }
            let alarmed = e["tracks"]
                .as_object()
                .is_some_and(|t| t.values().any(|x| x["alarmed"] == true));
            // An alarm stays the state shown until it clears, whatever
            // the source does after it.
            e["state"] = json!(match kind.as_str() {
                _ if alarmed => "alarm",
                "stale" => "stale",
                "ended" => "ended",
                _ => "ok",
            });
            e["last"] = v.clone();
        }
        self.events.push_back(v);
        while self.events.len() > KEEP {
            self.events.pop_front();
        }
    }
}
