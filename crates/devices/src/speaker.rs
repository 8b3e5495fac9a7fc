//! `speaker`: plays an audio stream on a sound card (cpal), resampled from
//! the signal's rate (the camera's frame rate for the visual microphone) to
//! the device's rate.
//!
//! The stage thread resamples with a band-limited sinc interpolator
//! (rubato's asynchronous resampler) into a lock-free ring that the
//! device's callback drains. The camera and the sound card have separate
//! clocks, so in live runs the ratio is nudged (at most ±1%) to hold the
//! ring near `latency_ms`; if the ring still overfills, new audio is
//! discarded and counted, and an empty ring plays silence (counted as
//! underruns once sound has started). In replays the stage waits for room
//! instead, so a file plays at its real speed and nothing is lost.
//!
//! `gain = "auto"` (the default) scales a peak-following envelope to
//! -6 dBFS: recovered motion is in pixels or radians, far below full scale.
//!
//! `device = "null"` is a virtual output that consumes samples at its rate
//! on the wall clock and discards them: for machines without a sound card,
//! and for tests of the pacing and resampling path.

use ringbuf::traits::{Consumer, Observer, Producer, Split};
use ringbuf::{HeapCons, HeapProd, HeapRb};
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use vibroscope_core::*;
use vibroscope_engine::stages::transform::resample::Feed;

/// `gain`: a fixed factor or `"auto"`.
#[derive(Deserialize, Serialize, Clone, Debug, PartialEq)]
#[serde(untagged)]
pub enum Gain {
    Fixed(f64),
    Named(String),
}

params! {
    /// `speaker`'s parameters.
    pub struct SpeakerParams for "speaker" {
        device: String = ParamSpec::of(ParamType::Str, Def::Str("default"))
            .doc("\"default\", \"null\" (no sound card), or part of a device's name or id"),
        rate_hz: Option<u32> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(4000, 384_000)
            .unit("Hz")
            .doc("device sample rate; default: the device's own"),
        gain: Gain = ParamSpec::of(ParamType::NumOr(&["auto"]), Def::Str("auto"))
            .above(0.0)
            .doc("\"auto\" (peak-following envelope to -6 dBFS) or a fixed factor"),
        latency_ms: f64 = ParamSpec::of(ParamType::Float, Def::Float(40.0))
            .floats(5.0, 2000.0)
            .unit("ms")
            .doc("audio kept queued for the device in live runs"),
    }
}

type P = SpeakerParams;

pub const KIND: KindSpec = KindSpec {
    name: "speaker",
    summary: "plays audio on a sound card (cpal), resampled to the device rate; `device = \"null\"` for none",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        if v.device.trim().is_empty() {
            return Err(p.error("device", "must not be empty (use \"default\")"));
        }
        Ok(Box::new(SpeakerPlan(v, p.stage.id.clone())))
    },
};

struct SpeakerPlan(P, String);

impl Plan for SpeakerPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let (p, id) = (self.0, self.1);
        let shared = Arc::new(Shared::default());
        let out = Device::open(&p.device, p.rate_hz, Arc::clone(&shared)).map_err(|e| {
            e.with_hint(format!(
                "to run without a sound card: --set {id}.device=null, or device = \"null\""
            ))
        })?;
        let gain = match p.gain {
            Gain::Fixed(g) => Agc::fixed(g as f32),
            Gain::Named(_) => Agc::auto(out.rate),
        };
        Ok(Node::Stage(Box::new(Speaker {
            feed: None,
            gain,
            latency_s: p.latency_ms * 1e-3,
            live: ctx.live,
            shared,
            out: Some(out),
            rate_in: 0.0,
        })))
    }
}

/// Counters shared with the device callback.
#[derive(Default)]
struct Shared {
    /// Samples played from the ring.
    played: AtomicU64,
    /// Samples of silence played because the ring ran dry after sound began.
    underrun: AtomicU64,
    /// Samples discarded in live runs because the ring was full.
    discarded: AtomicU64,
    /// Errors the device reported (xruns and the like).
    device_errors: AtomicU64,
    started: AtomicBool,
}

/// The device side: the ring's consumer lives in its callback.
struct Device {
    rate: u32,
    prod: HeapProd<f32>,
    stop: crossbeam_channel::Sender<()>,
    thread: Option<std::thread::JoinHandle<()>>,
    name: String,
}

/// Ring size: two seconds of device audio.
const RING_S: f64 = 2.0;

impl Device {
    /// Opens `device` ("null" for the virtual one) on its own thread and
    /// starts it; a device that cannot be opened is an error here, before
    /// the run starts. ALSA's own diagnostics, which it prints on standard
    /// error while probing devices, are silenced: the error says what failed.
    fn open(device: &str, rate: Option<u32>, shared: Arc<Shared>) -> Result<Device, StageError> {
        type Ready = Result<(u32, String, HeapProd<f32>), String>;
        let (ready_tx, ready_rx) = crossbeam_channel::bounded::<Ready>(1);
        let (stop_tx, stop_rx) = crossbeam_channel::bounded::<()>(1);
        let dev = device.to_string();
        let ring = |rate: u32| HeapRb::<f32>::new((rate as f64 * RING_S) as usize).split();
        // cpal streams are not `Send` on every platform: one thread opens,
        // owns and closes the stream.
        let thread = std::thread::Builder::new()
            .name("speaker-device".into())
            .spawn(move || {
                if dev == "null" {
                    let rate = rate.unwrap_or(48_000);
                    let (prod, cons) = ring(rate);
                    let name = "null (virtual, discards audio)".to_string();
                    let _ = ready_tx.send(Ok((rate, name, prod)));
                    null_device(cons, rate, 1, &shared, &stop_rx);
                    return;
                }
                let started = quiet_stderr(|| {
                    let d = cpal_device::open(&dev, rate)?;
                    let (prod, cons) = ring(d.rate);
                    let (rate, name) = (d.rate, d.name.clone());
                    let stream = d.start(cons, &shared)?;
                    Ok::<_, String>((rate, name, prod, stream))
                });
                match started {
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                    }
                    Ok((rate, name, prod, stream)) => {
                        let _ = ready_tx.send(Ok((rate, name, prod)));
                        let _ = stop_rx.recv();
                        drop(stream);
                    }
                }
            })
            .map_err(|e| StageError::thread("the audio thread", e))?;
        let who = format!("audio device \"{device}\"");
        let (rate, name, prod) = match ready_rx.recv() {
            Ok(Ok(v)) => v,
            Ok(Err(e)) => {
                let _ = thread.join();
                return Err(StageError::device(who, e));
            }
            Err(_) => {
                let _ = thread.join();
                return Err(StageError::device(
                    who,
                    "the audio thread ended before opening the device",
                ));
            }
        };
        tracing::info!(device = %name, rate, "speaker opened");
        Ok(Device {
            rate,
            prod,
            stop: stop_tx,
            thread: Some(thread),
            name,
        })
    }

    fn close(&mut self) {
        let _ = self.stop.send(());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        self.close();
    }
}

/// Fills a device buffer from the ring: mono to every channel, silence
/// when the ring is dry.
fn fill<T: Copy>(
    data: &mut [T],
    channels: usize,
    cons: &mut HeapCons<f32>,
    shared: &Shared,
    conv: impl Fn(f32) -> T,
) {
    let mut played = 0u64;
    let mut dry = 0u64;
    for frame in data.chunks_mut(channels.max(1)) {
        let v = match cons.try_pop() {
            Some(v) => {
                played += 1;
                v
            }
            None => {
                dry += 1;
                0.0
            }
        };
        frame.iter_mut().for_each(|s| *s = conv(v));
    }
    if played > 0 {
        shared.started.store(true, Ordering::Relaxed);
    }
    shared.played.fetch_add(played, Ordering::Relaxed);
    if shared.started.load(Ordering::Relaxed) {
        shared.underrun.fetch_add(dry, Ordering::Relaxed);
    }
}

/// Runs `f` with standard error sent to /dev/null: ALSA prints a line on
/// stderr for every PCM it fails to probe ("unable to open slave", "Unknown
/// PCM cards.pcm.rear", ...), which would bury the one error that matters.
/// Only the device thread runs meanwhile (the runner is waiting for it).
#[cfg(target_os = "linux")]
fn quiet_stderr<T>(f: impl FnOnce() -> T) -> T {
    use std::io::Write;
    let _ = std::io::stderr().flush();
    // SAFETY: plain descriptor calls on descriptors this function opens and
    // closes itself; descriptor 2 is restored before returning.
    let saved = unsafe { libc::dup(2) };
    if saved < 0 {
        return f();
    }
    // SAFETY: as above; the path is a NUL-terminated C string.
    let null = unsafe { libc::open(c"/dev/null".as_ptr(), libc::O_WRONLY | libc::O_CLOEXEC) };
    if null < 0 {
        // SAFETY: `saved` is ours.
        unsafe { libc::close(saved) };
        return f();
    }
    // SAFETY: both descriptors are valid and ours.
    unsafe {
        libc::dup2(null, 2);
        libc::close(null);
    }
    let r = f();
    // SAFETY: `saved` is a valid descriptor we own.
    unsafe {
        libc::dup2(saved, 2);
        libc::close(saved);
    }
    r
}

#[cfg(not(target_os = "linux"))]
fn quiet_stderr<T>(f: impl FnOnce() -> T) -> T {
    f()
}

/// The virtual device: drains `rate` samples per second of wall clock, in
/// 5 ms periods, like a sound card's callback.
fn null_device(
    mut cons: HeapCons<f32>,
    rate: u32,
    channels: usize,
    shared: &Shared,
    stop: &crossbeam_channel::Receiver<()>,
) {
    let period = Duration::from_millis(5);
    let mut buf = vec![0.0f32; (rate as usize / 200).max(1) * channels];
    let start = Instant::now();
    let mut done = 0u64;
    loop {
        match stop.recv_timeout(period) {
            Ok(()) | Err(crossbeam_channel::RecvTimeoutError::Disconnected) => return,
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => {}
        }
        let due = (start.elapsed().as_secs_f64() * rate as f64) as u64;
        while done + (buf.len() / channels) as u64 <= due {
            fill(&mut buf, channels, &mut cons, shared, |v| v);
            done += (buf.len() / channels) as u64;
        }
    }
}

mod cpal_device {
    use super::{fill, Shared};
    use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
    use ringbuf::HeapCons;

    pub struct Opened {
        device: cpal::Device,
        config: cpal::SupportedStreamConfig,
        pub rate: u32,
        pub name: String,
    }

    fn describe(d: &cpal::Device) -> String {
        match (d.description(), d.id()) {
            (Ok(desc), Ok(id)) => format!("{desc} [{id}]"),
            (Ok(desc), Err(_)) => desc.to_string(),
            (Err(_), Ok(id)) => id.to_string(),
            (Err(_), Err(_)) => "(unnamed device)".into(),
        }
    }

    pub fn open(want: &str, rate: Option<u32>) -> Result<Opened, String> {
        let host = cpal::default_host();
        let hostname = format!("{:?}", host.id());
        let device = if want == "default" {
            host.default_output_device()
                .ok_or_else(|| format!("no audio output device found (cpal host {hostname})"))?
        } else {
            let devices: Vec<cpal::Device> = host
                .output_devices()
                .map_err(|e| format!("cannot list audio output devices: {e}"))?
                .collect();
            let names: Vec<String> = devices.iter().map(describe).collect();
            match devices
                .into_iter()
                .zip(&names)
                .find(|(_, n)| n.contains(want))
            {
                Some((d, _)) => d,
                None => {
                    return Err(format!(
                        "no audio output device matches \"{want}\"; devices: {}",
                        if names.is_empty() {
                            "none".to_string()
                        } else {
                            names.join(", ")
                        }
                    ))
                }
            }
        };
        let name = describe(&device);
        let config = match rate {
            None => device
                .default_output_config()
                .map_err(|e| format!("audio device {name}: no usable output format: {e}"))?,
            Some(r) => {
                let ranges: Vec<_> = device
                    .supported_output_configs()
                    .map_err(|e| format!("audio device {name}: cannot list formats: {e}"))?
                    .collect();
                let found = ranges
                    .iter()
                    .find(|c| c.min_sample_rate() <= r && r <= c.max_sample_rate())
                    .map(|c| c.with_sample_rate(r));
                found.ok_or_else(|| {
                    let have: Vec<String> = ranges
                        .iter()
                        .map(|c| format!("{}-{} Hz", c.min_sample_rate(), c.max_sample_rate()))
                        .collect();
                    format!(
                        "audio device {name} does not play at {r} Hz; it supports {}",
                        have.join(", ")
                    )
                })?
            }
        };
        Ok(Opened {
            rate: config.sample_rate(),
            device,
            config,
            name,
        })
    }

    impl Opened {
        /// Starts playing from `cons`; the stream plays until dropped.
        pub fn start(
            self,
            mut cons: HeapCons<f32>,
            shared: &std::sync::Arc<Shared>,
        ) -> Result<cpal::Stream, String> {
            let channels = self.config.channels() as usize;
            let fmt = self.config.sample_format();
            let config: cpal::StreamConfig = self.config.into();
            // The first device error is logged; the rest are counted (an
            // xrun every period would flood the log) and summed at close.
            let errs = std::sync::Arc::clone(shared);
            let err = move |e: cpal::Error| {
                if errs
                    .device_errors
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
                    == 0
                {
                    tracing::warn!(
                        "audio device: {e} (further device errors are counted, not logged)"
                    );
                }
            };
            let sh = std::sync::Arc::clone(shared);
            macro_rules! build {
                ($t:ty, $conv:expr) => {
                    self.device.build_output_stream(
                        config,
                        move |data: &mut [$t], _: &cpal::OutputCallbackInfo| {
                            fill(data, channels, &mut cons, &sh, $conv)
                        },
                        err,
                        None,
                    )
                };
            }
            let stream = match fmt {
                cpal::SampleFormat::F32 => build!(f32, |v: f32| v),
                cpal::SampleFormat::I16 => {
                    build!(i16, |v: f32| (v.clamp(-1.0, 1.0) * i16::MAX as f32) as i16)
                }
                cpal::SampleFormat::I32 => {
                    build!(i32, |v: f32| (v.clamp(-1.0, 1.0) as f64 * i32::MAX as f64)
                        as i32)
                }
                cpal::SampleFormat::U16 => {
                    build!(u16, |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 32767.5) as u16)
                }
                cpal::SampleFormat::U8 => {
                    build!(u8, |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 127.5) as u8)
                }
                other => {
                    return Err(format!(
                        "audio device {}: sample format {other:?} is not supported",
                        self.name
                    ))
                }
            }
            .map_err(|e| format!("audio device {}: cannot open a stream: {e}", self.name))?;
            stream
                .play()
                .map_err(|e| format!("audio device {}: cannot start: {e}", self.name))?;
            Ok(stream)
        }
    }
}

/// Gain: fixed, or a peak follower (instant attack, ~2 s release) that
/// maps the envelope to -6 dBFS.
struct Agc {
    fixed: Option<f32>,
    env: f32,
    release: f32,
}

impl Agc {
    fn fixed(g: f32) -> Self {
        Self {
            fixed: Some(g),
            env: 0.0,
            release: 1.0,
        }
    }
    fn auto(rate: u32) -> Self {
        Self {
            fixed: None,
            env: 0.0,
            release: (-1.0 / (2.0 * rate as f32)).exp(),
        }
    }
    fn apply(&mut self, x: &mut [f32]) {
        if let Some(g) = self.fixed {
            x.iter_mut().for_each(|v| *v *= g);
            return;
        }
        for v in x.iter_mut() {
            self.env = (self.env * self.release).max(v.abs());
            *v = if self.env > 0.0 {
                (*v * 0.5 / self.env).clamp(-1.0, 1.0)
            } else {
                0.0
            };
        }
    }
}

struct Speaker {
    feed: Option<Feed>,
    gain: Agc,
    latency_s: f64,
    live: bool,
    shared: Arc<Shared>,
    out: Option<Device>,
    rate_in: f64,
}

/// How long a replay waits for the device to take audio before giving up.
const STALL: Duration = Duration::from_secs(5);

impl Speaker {
    fn push(&mut self, x: &[f32], flush: bool) -> Result<(), StageError> {
        let (Some(feed), Some(out)) = (self.feed.as_mut(), self.out.as_mut()) else {
            return Ok(());
        };
        let live = self.live;
        let gain = &mut self.gain;
        let target = (self.latency_s * out.rate as f64) as usize;
        let mut err: Option<String> = None;
        let mut discarded = 0u64;
        let prod = &mut out.prod;
        let mut deliver = |y: &mut [f32]| {
            gain.apply(y);
            if live {
                // Over twice the target: the device is slower than the
                // camera; discard rather than grow the delay.
                let room = (2 * target + y.len()).saturating_sub(prod.occupied_len());
                let n = prod.push_slice(&y[..y.len().min(room)]);
                discarded += (y.len() - n) as u64;
            } else {
                let mut done = 0;
                let mut since = Instant::now();
                while done < y.len() {
                    let n = prod.push_slice(&y[done..]);
                    done += n;
                    if n > 0 {
                        since = Instant::now();
                    } else if since.elapsed() > STALL {
                        err = Some(format!(
                            "the audio device took nothing for {} s",
                            STALL.as_secs()
                        ));
                        return;
                    } else {
                        std::thread::sleep(Duration::from_millis(2));
                    }
                }
            }
        };
        let r = if flush {
            feed.flush(&mut deliver)
        } else {
            feed.push(x, &mut deliver)
        };
        r.map_err(StageError::dsp)?;
        if let Some(e) = err {
            return Err(StageError::device(&out.name, e));
        }
        if discarded > 0 {
            tracing::debug!(discarded, "speaker: ring full, audio discarded");
            self.shared
                .discarded
                .fetch_add(discarded, Ordering::Relaxed);
        }
        if live {
            // Hold the ring near the target: a fuller ring plays slower
            // input (fewer output samples per input sample).
            let fill = out.prod.occupied_len() as f64;
            let err = (target as f64 - fill) / target.max(1) as f64;
            feed.adjust(1.0 + 0.01 * err.clamp(-1.0, 1.0));
        }
        Ok(())
    }
}

impl Stage for Speaker {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let Item::Audio(a) = item else {
            return Err(StageError::expected("audio"));
        };
        if self.feed.is_none() {
            let rate_out = self.out.as_ref().map_or(48_000, |o| o.rate) as f64;
            self.feed = Some(Feed::new(a.rate_hz, rate_out).map_err(StageError::dsp)?);
            self.rate_in = a.rate_hz;
        } else if (a.rate_hz - self.rate_in).abs() > 1e-9 * self.rate_in {
            return Err(StageError::format(format!(
                "the sample rate changed from {} Hz to {} Hz mid-stream",
                self.rate_in, a.rate_hz
            )));
        }
        self.push(&a.samples, false)
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        let r = self.push(&[], true);
        // Let the device play what is queued (bounded by the ring size).
        if let Some(out) = self.out.as_mut() {
            let rate = out.rate as f64;
            let deadline = Instant::now()
                + Duration::from_secs_f64(out.prod.occupied_len() as f64 / rate + 0.5);
            while out.prod.occupied_len() > 0 && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(5));
            }
            out.close();
            let (played, underrun, discarded, device_errors) = (
                self.shared.played.load(Ordering::Relaxed),
                self.shared.underrun.load(Ordering::Relaxed),
                self.shared.discarded.load(Ordering::Relaxed),
                self.shared.device_errors.load(Ordering::Relaxed),
            );
            if underrun + discarded + device_errors > 0 {
                tracing::warn!(device = %out.name, played, underrun, discarded, device_errors, "speaker: gaps in playback (samples) and device errors");
            } else {
                tracing::info!(device = %out.name, played, "speaker closed");
            }
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_gain_brings_a_tiny_signal_to_half_scale() {
        let mut agc = Agc::auto(48000);
        let mut x: Vec<f32> = (0..48000).map(|n| 1e-3 * (n as f32 * 0.05).sin()).collect();
        agc.apply(&mut x);
        let peak = x[24000..].iter().fold(0.0f32, |a, v| a.max(v.abs()));
        assert!((peak - 0.5).abs() < 0.01, "{peak}");
    }
}
