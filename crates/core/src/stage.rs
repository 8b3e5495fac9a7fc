//! The seams between the runner and stage code: [`Source`], [`Stage`],
//! [`Emitter`] and the shared [`Control`] flags.

use super::edge::{EdgeTx, Sent};
use super::frame::{FrameMut, FramePool};
use super::item::Item;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

/// Run-wide flags. Raising `stop_sources` ends the stream gracefully:
/// sources stop, everything queued drains, sinks finalise. Raising
/// `hard_stop` also ends every wait at once (second Ctrl-C).
#[derive(Default, Debug)]
pub struct Control {
    pub stop_sources: AtomicBool,
    pub hard_stop: AtomicBool,
    /// The run's clock: live sources stamp capture times in ns since this
    /// instant, so a sink can tell how old a sample is (`now_ns() - t`).
    epoch: OnceLock<Instant>,
}

impl Control {
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }
    /// Graceful stop: sources end, queues drain, sinks finalise.
    pub fn stop(&self) {
        self.stop_sources.store(true, Ordering::Release);
    }
    /// Immediate stop: every wait ends now; sinks still finalise.
    pub fn abort(&self) {
        self.stop_sources.store(true, Ordering::Release);
        self.hard_stop.store(true, Ordering::Release);
    }
    pub fn sources_should_stop(&self) -> bool {
        self.stop_sources.load(Ordering::Acquire)
    }
    /// Starts the run clock (the runner calls this just before the stage
    /// threads start; later calls keep the first instant).
    pub fn start_clock(&self) -> Instant {
        *self.epoch.get_or_init(Instant::now)
    }
    /// The instant live capture times count from.
    pub fn epoch(&self) -> Instant {
        self.start_clock()
    }
    /// Nanoseconds on the run clock.
    pub fn now_ns(&self) -> i64 {
        self.epoch().elapsed().as_nanos() as i64
    }
}

/// Errors a stage reports at run time. The runner adds the stage id.
#[derive(Debug, thiserror::Error)]
pub enum StageError {
    /// A recording could not be opened or read.
    #[error(transparent)]
    Video(#[from] vibroscope_io::VideoError),
    /// I/O on a named file.
    #[error("cannot {op} {}: {source}", path.display())]
    File {
        /// What was being done: "create", "write", "read".
        op: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// I/O on an unnamed stream (standard output, say).
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// A setting that proves wrong only once the stream is known (a
    /// region larger than the frame, a frequency above Nyquist): the field
    /// to change is named.
    #[error("{field}: {message}")]
    Config {
        field: &'static str,
        message: String,
    },
    /// The stream does not suit the stage: the wrong payload, an unusable
    /// size, rate or pixel format, or one that changed mid-stream.
    #[error("{0}")]
    Format(String),
    /// Signal processing failed (a filter or resampler that cannot be
    /// designed for this rate, a pyramid, too little data).
    #[error("{0}")]
    Dsp(String),
    /// A capture or playback device (camera, sound card), with what to do
    /// about it when there is something.
    #[error("{device}: {message}{}", hint.as_ref().map(|h| format!(" ({h})")).unwrap_or_default())]
    Device {
        device: String,
        message: String,
        hint: Option<String>,
    },
    /// A thread the stage needs could not be started (the system's limit
    /// on threads or memory).
    #[error("cannot start {what}: {message}")]
    Thread { what: String, message: String },
    /// The stage's thread panicked (a bug).
    #[error("the stage thread panicked")]
    Panicked,
    /// A broken invariant inside the stage (a bug).
    #[error("internal error: {0}")]
    Internal(&'static str),
}

impl StageError {
    /// A thread (`what`) that could not be started, and why.
    pub fn thread(what: impl Into<String>, why: impl std::fmt::Display) -> Self {
        StageError::Thread {
            what: what.into(),
            message: why.to_string(),
        }
    }
    /// I/O on `path` failed while doing `op` ("create", "write", "read").
    pub fn file(op: &'static str, path: &Path, source: std::io::Error) -> Self {
        StageError::File {
            op,
            path: path.to_path_buf(),
            source,
        }
    }
    pub fn config(field: &'static str, message: impl Into<String>) -> Self {
        StageError::Config {
            field,
            message: message.into(),
        }
    }
    pub fn format(message: impl Into<String>) -> Self {
        StageError::Format(message.into())
    }
    /// The item on an input is not of the payload the stage takes (the
    /// validator rules this out; a custom registry might not).
    pub fn expected(what: &str) -> Self {
        StageError::Format(format!("expected {what}"))
    }
    pub fn dsp(message: impl Into<String>) -> Self {
        StageError::Dsp(message.into())
    }
    pub fn device(device: impl Into<String>, message: impl Into<String>) -> Self {
        StageError::Device {
            device: device.into(),
            message: message.into(),
            hint: None,
        }
    }
    /// Adds what to do about a device error.
    pub fn with_hint(self, h: impl Into<String>) -> Self {
        match self {
            StageError::Device {
                device, message, ..
            } => StageError::Device {
                device,
                message,
                hint: Some(h.into()),
            },
            other => other,
        }
    }
}

/// Handed to sources on every call.
pub struct SourceCtx<'a> {
    pub control: &'a Control,
    /// Frames lost before they reached the source (a camera's sequence
    /// gaps); shown in the source's `dropped` column of `--stats`.
    pub dropped: &'a AtomicU64,
}

impl SourceCtx<'_> {
    pub fn should_stop(&self) -> bool {
        self.control.sources_should_stop()
    }

    /// Counts `n` frames the device dropped before delivering them.
    pub fn count_dropped(&self, n: u64) {
        self.dropped.fetch_add(n, Ordering::Relaxed);
    }

    /// Takes a frame buffer from `pool`, sleeping while all are in use
    /// downstream. `None` once the run is stopping.
    pub fn acquire(&self, pool: &FramePool) -> Option<FrameMut> {
        loop {
            if let Some(f) = pool.acquire_timeout(Duration::from_millis(50)) {
                return Some(f);
            }
            if self.should_stop() {
                return None;
            }
        }
    }
}

/// Something that produces items: a camera, a file, the simulator.
pub trait Source: Send {
    /// The next item, or `None` at the end of the stream (or when
    /// `ctx.should_stop()`). A live source paces itself here.
    fn next(&mut self, ctx: &SourceCtx<'_>) -> Result<Option<Item>, StageError>;
    /// Number of items when known (files), for progress display.
    fn total_hint(&self) -> Option<u64> {
        None
    }
    /// Live sources pace themselves in real time; their edges default to
    /// dropping the oldest item when downstream falls behind.
    fn is_live(&self) -> bool {
        false
    }
}

/// A processing stage or a sink.
pub trait Stage: Send {
    /// Handles one item that arrived on input `port`.
    fn process(&mut self, port: usize, item: Item, out: &mut Emitter) -> Result<(), StageError>;
    /// Called exactly once when the inputs end, the run stops, or an error
    /// occurs anywhere: flush buffered output and finalise files here.
    fn finish(&mut self, _out: &mut Emitter) -> Result<(), StageError> {
        Ok(())
    }
    /// One line on how the stage ran (a mode it chose, its latency), read
    /// after `finish` and printed by `--stats`; `None` says nothing.
    fn summary(&self) -> Option<String> {
        None
    }
    /// `Some(period)`: the stage is not woken per item; when its inputs are
    /// empty it sleeps `period` and looks again (a watcher that keeps the
    /// latest of a fast stream, so the producer never pays for waking it).
    fn poll_period(&self) -> Option<std::time::Duration> {
        None
    }
}

/// What a stage thread runs.
pub enum Node {
    Source(Box<dyn Source>),
    Stage(Box<dyn Stage>),
}

/// Why [`Emitter::emit`] could not deliver.
#[derive(Debug, PartialEq, Eq)]
pub enum EmitError {
    /// Every consumer has gone away.
    Disconnected,
    /// The run is being aborted.
    Stopped,
}

/// Sends a stage's output to every consumer (fan-out: one ring each; frames
/// are shared handles, so nothing is copied).
pub struct Emitter {
    outs: Vec<EdgeTx>,
    control: Arc<Control>,
    emitted: Arc<AtomicU64>,
}

impl Emitter {
    pub fn new(outs: Vec<EdgeTx>, control: Arc<Control>, emitted: Arc<AtomicU64>) -> Self {
        Self {
            outs,
            control,
            emitted,
        }
    }

    pub fn has_outputs(&self) -> bool {
        !self.outs.is_empty()
    }

    /// Takes a buffer from a stage's own output `pool` (a stage that makes
    /// frames), sleeping while every buffer is in use downstream. `None`
    /// once the run is aborted.
    pub fn acquire(&self, pool: &FramePool) -> Option<FrameMut> {
        loop {
            if let Some(f) = pool.acquire_timeout(Duration::from_millis(50)) {
                return Some(f);
            }
            if self.control.hard_stop.load(Ordering::Acquire) {
                return None;
            }
        }
    }

    pub fn emit(&mut self, item: Item) -> Result<(), EmitError> {
        if self.outs.is_empty() {
            return Ok(());
        }
        let stop = &self.control.hard_stop;
        let mut delivered = 0usize;
        let last = self.outs.len() - 1;
        let mut item = Some(item);
        for (i, tx) in self.outs.iter_mut().enumerate() {
            let it = if i == last { item.take() } else { item.clone() };
            let Some(it) = it else { break };
            match tx.send(it, stop) {
                Sent::Queued { .. } => delivered += 1,
                Sent::Gone => {}
                Sent::Stopped => return Err(EmitError::Stopped),
            }
        }
        if delivered == 0 {
            return Err(EmitError::Disconnected);
        }
        self.emitted.fetch_add(1, Ordering::Relaxed);
        Ok(())
    }
}
