//! `wav`: writes an audio stream to a WAV file (hound).
//!
//! The file's sample rate is the signal's (the camera's frame rate for a
//! per-frame signal); put a `resample` stage before it for a standard audio
//! rate. f32 files are `WAVE_FORMAT_IEEE_FLOAT` with a `fact` chunk, i16
//! files plain PCM: headers sox, Python's `wave` (PCM) and
//! `scipy.io.wavfile` read without a warning ([`vibroscope_io::wav::Encoding`]).
//! The file is written under a unique temporary sibling
//! (`.NAME.PID-N.partial`, [`vibroscope_io::atomic::Pending`]) and renamed
//! to its path on finish, which the runner calls on end of stream, on a
//! signal (SIGINT, SIGTERM, SIGHUP) and on an error anywhere: two runs
//! writing one path cannot splice, and the path holds a whole WAV (the
//! header is rewritten to match the data first; after a write error, such
//! as a full disk, to match the whole samples on disk).

use crate::*;
use serde::{Deserialize, Serialize};
use std::io::BufWriter;
use std::path::PathBuf;
use vibroscope_io::atomic::Pending;
use vibroscope_io::wav::{Encoding, MonoWavWriter};

#[derive(Deserialize, Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// 32-bit float, values as the signal has them (pixels of motion, say).
    F32,
    /// 16-bit PCM of `gain * value`, clipped to [-1, 1].
    I16,
}

params! {
    /// `wav`'s parameters.
    pub struct WavParams for "wav" {
        path: PathBuf = ParamSpec::of(ParamType::Path, Def::Required).doc("the WAV file"),
        format: Format = ParamSpec::of(ParamType::Choice(&["f32", "i16"]), Def::Str("f32"))
            .doc("f32: values as the signal has them; i16: PCM of gain * value, clipped to [-1, 1]"),
        gain: f64 = ParamSpec::of(ParamType::Float, Def::Float(1.0))
            .doc("factor applied before writing (i16 clips at ±1)"),
    }
}

type P = WavParams;

pub const KIND: KindSpec = KindSpec {
    name: "wav",
    summary:
        "writes audio to a WAV file (f32 or i16), valid even after Ctrl-C or an upstream error",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        if v.path.as_os_str().is_empty() {
            return Err(p.error("path", "must not be empty"));
        }
        Ok(Box::new(Wav {
            path: v.path,
            format: v.format,
            gain: v.gain as f32,
            writer: None,
            pending: None,
            rate: 0,
            since_flush: 0,
        }))
    },
};

struct Wav {
    path: PathBuf,
    format: Format,
    gain: f32,
    writer: Option<MonoWavWriter<BufWriter<std::fs::File>>>,
    /// The temporary file the writer writes, renamed on finish.
    pending: Option<Pending>,
    rate: u32,
    since_flush: u32,
}

impl Plan for Wav {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(self))
    }
}

impl Wav {
    fn err(&self, e: std::io::Error) -> StageError {
        StageError::file("write", &self.path, e)
    }
}

impl Stage for Wav {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let Item::Audio(a) = item else {
            return Err(StageError::expected("audio"));
        };
        let rate = a.rate_hz.round();
        if !(1.0..=u32::MAX as f64).contains(&rate) {
            return Err(StageError::format(format!(
                "{}: sample rate {} Hz cannot be written to WAV",
                self.path.display(),
                a.rate_hz
            )));
        }
        let rate = rate as u32;
        if self.writer.is_none() {
            if (a.rate_hz - rate as f64).abs() > 1e-6 {
                tracing::warn!(path = %self.path.display(), rate_hz = a.rate_hz, written_hz = rate, "WAV sample rates are integers; rounding");
            }
            let enc = match self.format {
                Format::F32 => Encoding::F32,
                Format::I16 => Encoding::I16,
            };
            let (pending, file) = super::create_pending(&self.path)?;
            self.pending = Some(pending);
            let w = MonoWavWriter::new(BufWriter::new(file), rate, enc).map_err(|e| self.err(e))?;
            self.writer = Some(w);
            self.rate = rate;
        } else if rate != self.rate {
            return Err(StageError::format(format!(
                "{}: the sample rate changed from {} to {} Hz mid-stream",
                self.path.display(),
                self.rate,
                rate
            )));
        }
        let gain = self.gain;
        let Some(w) = self.writer.as_mut() else {
            return Ok(());
        };
        if let Err(e) = w.write(&a.samples, gain) {
            return Err(self.err(e));
        }
        self.since_flush += a.samples.len() as u32;
        if self.since_flush >= self.rate {
            self.since_flush = 0;
            if let Some(w) = self.writer.as_mut() {
                if let Err(e) = w.flush() {
                    return Err(self.err(e));
                }
            }
        }
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        match (self.writer.take(), self.pending.take()) {
            // A failed finalise (a full disk) still leaves a header that
            // matches the whole samples on disk; then the rename.
            (Some(w), Some(pending)) => {
                let done = w.finalize().map(drop).map_err(|e| {
                    let _ = vibroscope_io::wav::repair_header(pending.temp_path());
                    self.err(e)
                });
                let renamed = pending.commit().map_err(|e| self.err(e));
                done.and(renamed)
            }
            _ => {
                tracing::warn!(path = %self.path.display(), "no audio reached the WAV sink; no file written");
                Ok(())
            }
        }
    }
}
