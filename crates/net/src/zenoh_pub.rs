//! `zenoh_pub`: publishes every item it receives on a zenoh key, for a
//! `zenoh_sub` source or `vibroscope monitor` in another process or on
//! another host ([`crate::session`]: versioned wire encoding, capture times kept,
//! a sequence number on each item, an end-of-stream marker).
//!
//! The edge policy crosses the network. On a replay the publisher is
//! reliable and blocking: it waits (up to `wait_s`) for a subscriber before
//! the first item, and a slow subscriber holds it up, so nothing is lost.
//! When the graph has a live source it drops instead of holding up the
//! camera (zenoh's congestion control `drop`); the receiver counts the gaps.

use crate::session::{self as net, Endpoints};
use std::time::{Duration, Instant};
use vibroscope_core::wire::{self, WireRef};
use vibroscope_core::*;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

params! {
    /// `zenoh_pub`'s parameters.
    pub struct ZenohPubParams for "zenoh_pub" {
        key: Option<String> = ParamSpec::of(ParamType::Str, Def::Optional)
            .doc("zenoh key expression published on (no wildcards); default vibroscope/<site>/<camera>/<input stage id>"),
        site: String = ParamSpec::of(ParamType::Str, Def::Str("site"))
            .doc("site name in the default key"),
        camera: String = ParamSpec::of(ParamType::Str, Def::Str("camera"))
            .doc("camera name in the default key"),
        connect: String = ParamSpec::of(ParamType::Str, Def::Str(""))
            .doc("zenoh endpoints to connect to, comma-separated (\"tcp/10.0.0.2:7447\"); retried until they answer"),
        listen: String = ParamSpec::of(ParamType::Str, Def::Str(""))
            .doc("zenoh endpoints to listen on, comma-separated (\"tcp/0.0.0.0:7447\")"),
        wait_s: f64 = ParamSpec::of(ParamType::Float, Def::Float(net::DEFAULT_WAIT_S))
            .floats(0.0, 86_400.0)
            .unit("s")
            .doc("replay: longest wait for a subscriber before the first item (then an error); live runs never wait"),
    }
}

type P = ZenohPubParams;

const ACCEPTS: &[PortType] = &[
    PortType::Audio,
    PortType::Samples,
    PortType::Spectrum,
    PortType::Peaks,
    PortType::Frames,
];

pub const KIND: KindSpec = KindSpec {
    name: "zenoh_pub",
    summary: "publishes audio, samples, spectra, peak sets or frames on a zenoh key for another process or host (replay: reliable and blocking; live: drops)",
    inputs: &[InPort::one(ACCEPTS)],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        let ep = net::endpoints(p, &v.connect, &v.listen)?;
        let key = match &v.key {
            Some(k) => k.clone(),
            None => {
                let from = p.stage.inputs.first().map_or("out", |i| i.from.as_str());
                format!("vibroscope/{}/{}/{}", v.site, v.camera, from)
            }
        };
        let field = if v.key.is_some() { "key" } else { "camera" };
        net::check_key(&key, false).map_err(|m| p.error(field, m))?;
        Ok(Box::new(PubPlan {
            key,
            ep,
            wait: Duration::from_secs_f64(v.wait_s),
        }))
    },
};

struct PubPlan {
    key: String,
    ep: Endpoints,
    wait: Duration,
}

impl Plan for PubPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let session = net::open_session(&self.ep)?;
        let cc = if ctx.live {
            CongestionControl::Drop
        } else {
            CongestionControl::Block
        };
        let publisher = session
            .declare_publisher(self.key.clone())
            .congestion_control(cc)
            .wait()
            .map_err(|e| {
                StageError::device("zenoh", format!("cannot publish on {}: {e}", self.key))
            })?;
        Ok(Node::Stage(Box::new(Pub {
            key: self.key,
            wait: (!ctx.live).then_some(self.wait),
            publisher: Some(publisher),
            session,
            buf: Vec::new(),
            seq: 0,
            bytes: 0,
        })))
    }
}

struct Pub {
    key: String,
    /// Replay: wait this long for a subscriber before the first item.
    wait: Option<Duration>,
    publisher: Option<zenoh::pubsub::Publisher<'static>>,
    session: zenoh::Session,
    /// The encoding buffer, reused.
    buf: Vec<u8>,
    seq: u64,
    bytes: u64,
}

impl Pub {
    fn publisher(&self) -> Result<&zenoh::pubsub::Publisher<'static>, StageError> {
        self.publisher
            .as_ref()
            .ok_or_else(|| StageError::device("zenoh", format!("{}: publisher closed", self.key)))
    }

    /// Replay: blocks until a subscriber matches the key (or `wait` passes).
    fn wait_for_subscriber(&mut self) -> Result<(), StageError> {
        let Some(wait) = self.wait.take() else {
            return Ok(());
        };
        let deadline = Instant::now() + wait;
        let publisher = self.publisher()?;
        loop {
            let matching = publisher
                .matching_status()
                .wait()
                .map(|m| m.matching())
                .unwrap_or(false);
            if matching {
                return Ok(());
            }
            if Instant::now() >= deadline {
                return Err(StageError::device(
                    "zenoh",
                    format!(
                        "no subscriber for {} after {:.1} s (a replay publisher loses nothing, so it waits for one)",
                        self.key,
                        wait.as_secs_f64()
                    ),
                )
                .with_hint("start the receiving pipeline or monitor, check `connect`/`listen`, or raise `wait_s`"));
            }
            std::thread::sleep(net::POLL);
        }
    }
}

impl Stage for Pub {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        self.wait_for_subscriber()?;
        let r = match &item {
            Item::Audio(a) => WireRef::Audio(a),
            Item::Samples(s) => WireRef::Samples(s),
            Item::Spectrum(s) => WireRef::Spectrum(s),
            Item::Peaks(p) => WireRef::Peaks(p),
            Item::Frame(f) => WireRef::Frame(f),
            Item::Pyramid(_) => return Ok(()),
        };
        wire::encode_into(r, &mut self.buf)
            .map_err(|e| StageError::format(format!("{}: {e}", self.key)))?;
        let seq = self.seq;
        // zenoh takes the payload by value: one copy of the encoded bytes.
        self.publisher()?
            .put(self.buf.as_slice())
            .attachment(&net::seq_attachment(seq)[..])
            .wait()
            .map_err(|e| StageError::device("zenoh", format!("put on {}: {e}", self.key)))?;
        self.seq += 1;
        self.bytes += self.buf.len() as u64;
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        // A run that sent nothing still waits, so its subscriber sees the end.
        self.wait_for_subscriber()?;
        if let Some(p) = self.publisher.take() {
            p.delete()
                .attachment(&net::seq_attachment(self.seq)[..])
                .wait()
                .map_err(|e| {
                    StageError::device("zenoh", format!("end marker on {}: {e}", self.key))
                })?;
            let _ = p.undeclare().wait();
        }
        let _ = self.session.close().wait();
        Ok(())
    }

    fn summary(&self) -> Option<String> {
        Some(format!(
            "{}: {} items, {} bytes published",
            self.key, self.seq, self.bytes
        ))
    }
}
