//! The pitch of a sound, or of the sound recovered from a video (thesis
//! 4.6, Fig. 4-11): YIN frame by frame ([`crate::math::pitch`]), written as
//! CSV and drawn over the sound's spectrogram.

use crate::error::{Error, Result};
use crate::io::atomic::TempPath;
use crate::io::plot::{spectrogram_with_track, TimedSpectrum, TrackPoint};
use crate::listen::{ListenOptions, OutputRate};
pub use crate::math::pitch::YinParams;
use crate::math::pitch::{self, PitchFrame};
use crate::pipeline::{Region, RunSettings};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What `pitch` is asked.
#[derive(Clone, Debug, Default)]
pub struct PitchOptions {
    /// A WAV (first channel), or a video whose sound is recovered first
    /// (the `listen` recipe at the frame rate, no output filters).
    pub input: PathBuf,
    /// For a video: its capture rate when the file states the wrong one.
    pub fps: Option<f64>,
    /// For a video: the region and pyramid.
    pub region: Region,
    pub params: YinParams,
    /// The track, as CSV.
    pub csv: PathBuf,
    /// The track over the spectrogram, as PNG.
    pub png: Option<PathBuf>,
    pub run: RunSettings,
}

/// What `pitch` found.
#[derive(Debug, Serialize)]
pub struct PitchReport {
    pub input: PathBuf,
    /// The rate of the sound tracked, Hz.
    pub sample_rate_hz: f64,
    pub frames: usize,
    pub voiced_frames: usize,
    /// Median, 10th and 90th percentile of the voiced frames' pitch, Hz
    /// (NaN when no frame is voiced).
    pub median_hz: f64,
    pub p10_hz: f64,
    pub p90_hz: f64,
    pub written: Vec<PathBuf>,
    #[serde(skip)]
    pub track: Vec<PitchFrame>,
}

/// Whether `path` is read as a WAV (by its extension).
pub fn is_wav(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("wav"))
}

/// Runs `pitch`.
pub fn pitch(o: &PitchOptions) -> Result<PitchReport> {
    let mut inputs = vec![o.input.as_path()];
    inputs.extend(o.region.mask.as_deref());
    let mut outputs = vec![o.csv.as_path()];
    outputs.extend(o.png.as_deref());
    crate::error::check_outputs(&inputs, &outputs)?;
    let (rate, x) = if is_wav(&o.input) {
        let (rate, x) = crate::io::wav::read_mono(&o.input)?;
        (f64::from(rate), x)
    } else {
        recover(o)?
    };
    let track = pitch::track(&x, rate, &o.params).map_err(|e| match e {
        pitch::PitchError::Invalid { field, message } => {
            Error::usage(format!("--{field}"), message)
        }
        other => Error::input(&o.input, other.to_string()),
    })?;
    let mut voiced: Vec<f64> = track.iter().filter(|f| f.voiced).map(|f| f.f0_hz).collect();
    voiced.sort_by(f64::total_cmp);
    let pct = |q: f64| {
        if voiced.is_empty() {
            f64::NAN
        } else {
            voiced[((voiced.len() - 1) as f64 * q).round() as usize]
        }
    };
    write_csv(&o.csv, &track)?;
    let mut written = vec![o.csv.clone()];
    if let Some(png) = &o.png {
        draw(png, &x, rate, &o.params, &track)?;
        written.push(png.clone());
    }
    Ok(PitchReport {
        input: o.input.clone(),
        sample_rate_hz: rate,
        frames: track.len(),
        voiced_frames: voiced.len(),
        median_hz: pct(0.5),
        p10_hz: pct(0.1),
        p90_hz: pct(0.9),
        written,
        track,
    })
}

/// The sound of a video, at the frame rate, in the signal's units.
fn recover(o: &PitchOptions) -> Result<(f64, Vec<f64>)> {
    let tmp = TempPath::new("pitch.wav");
    let l = ListenOptions {
        video: o.input.clone(),
        output: tmp.path().to_path_buf(),
        fps: o.fps,
        region: o.region.clone(),
        // A pyramid chosen is the phase method's; else the default.
        method: (o.region.pyramid != crate::pipeline::Pyramid::default())
            .then_some(crate::listen::Method::Phase),
        rate: OutputRate::Native,
        float: true,
        run: o.run,
        ..ListenOptions::default()
    };
    crate::listen::listen(&l)?;
    let (_, x) = crate::io::wav::read_mono(tmp.path())?;
    // The WAV's header holds an integer rate; the frame rate is exact.
    let rate = crate::calibrate::frame_rate(&o.input, o.fps)?;
    Ok((rate, x))
}

/// `time_s,f0_hz,confidence,voiced`, one row a frame.
fn write_csv(path: &Path, track: &[PitchFrame]) -> Result<()> {
    let mut s = String::from("time_s,f0_hz,confidence,voiced\n");
    for f in track {
        let _ = writeln!(
            s,
            "{:.4},{:.3},{:.4},{}",
            f.time_s,
            f.f0_hz,
            f.confidence,
            u8::from(f.voiced)
        );
    }
    crate::io::atomic::write_atomic(path, s.as_bytes())?;
    Ok(())
}

/// The track over the spectrogram, 0 Hz to twice the highest pitch searched
/// (or Nyquist).
fn draw(path: &Path, x: &[f64], rate: f64, p: &YinParams, track: &[PitchFrame]) -> Result<()> {
    let len = ((0.04 * rate) as usize).next_power_of_two().max(64);
    let hop = ((0.01 * rate) as usize).max(1);
    let spectra: Vec<TimedSpectrum> = pitch::spectrogram(x, rate, len, hop)
        .into_iter()
        .map(|(t_s, power)| TimedSpectrum { t_s, power })
        .collect();
    let points: Vec<TrackPoint> = track
        .iter()
        .map(|f| TrackPoint {
            t_s: f.time_s,
            f_hz: f.f0_hz,
            confident: f.voiced,
        })
        .collect();
    let top = (2.0 * p.fmax_hz).min(rate / 2.0);
    let caption = "pitch (YIN): voiced frames in cyan, over the spectrogram";
    let (img, _) = spectrogram_with_track(
        &spectra,
        0.0,
        rate / len as f64,
        (0.0, top),
        (1000, 500),
        caption,
        &points,
    )
    .map_err(crate::io::Error::from)?;
    let png = img.png().map_err(crate::io::Error::from)?;
    crate::io::atomic::write_atomic(path, &png)?;
    Ok(())
}
