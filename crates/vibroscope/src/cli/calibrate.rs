//! `vibroscope calibrate` and `listen --calibration` (issue 6): the
//! recovery comes from the listen pipeline (the same graph `listen` runs),
//! the math from [`crate::math::calibrate`].

use super::{cfg_error, listen_pipeline, read_wav_mono, run_decl, DenoiseArg, PyramidArg};
use crate::math::calibrate::{self as cal, Calibration, Correction, Options};
use anyhow::Context;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `vibroscope calibrate`.
#[derive(clap::Args, Debug, Clone)]
pub struct CalibrateArgs {
    /// The recording of the object while the reference sound played
    /// (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    pub video: PathBuf,
    /// The sound that was played (WAV, first channel): a chirp or ramp, or
    /// speech. It must cover the video's duration and be sampled at least
    /// at the video's frame rate.
    #[arg(long, value_name = "REF.wav")]
    pub reference: PathBuf,
    /// Where to write the report: errors on the held-out part before and
    /// after, the effects kept (name, parameters, uncertainty, SNR gain) and
    /// the residual no effect explains.
    #[arg(long, value_name = "REPORT.json")]
    pub json: PathBuf,
    /// Also write the corrected recovery, aligned and scaled to the
    /// reference, at the reference's sample rate (band-limited to half the
    /// frame rate, and still high-passed like every recovery).
    #[arg(short, long, value_name = "CORRECTED.wav")]
    pub output: Option<PathBuf>,
    /// Capture frame rate in Hz (containers often state the playback rate).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    pub fps: Option<f64>,
    /// The effects to try, comma-separated, in the catalog's order
    /// whatever the order given (default: all of time_base,
    /// dropped_frames, exposure, interference, transfer_function,
    /// soft_clip).
    #[arg(long, value_name = "LIST")]
    pub effects: Option<String>,
}

/// `--effects a,b,c` as catalog entries (in catalog order).
pub fn parse_effects(list: &str) -> anyhow::Result<Vec<cal::EffectKind>> {
    let names: Vec<&str> = list
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    for n in &names {
        if !cal::CATALOG.iter().any(|k| k.name() == *n) {
            let all: Vec<&str> = cal::CATALOG.iter().map(|k| k.name()).collect();
            return Err(cfg_error(
                "--effects",
                format!("unknown effect `{n}` (known: {})", all.join(", ")),
            )
            .into());
        }
    }
    Ok(cal::CATALOG
        .iter()
        .copied()
        .filter(|k| names.contains(&k.name()))
        .collect())
}

fn path_str(p: &Path) -> String {
    p.display().to_string()
}

/// Reads a WAV as a usage error when it is missing or unreadable.
fn read_input_wav(p: &Path) -> anyhow::Result<(f64, Vec<f64>)> {
    if !p.exists() {
        return Err(cfg_error(&path_str(p), "no such file".into()).into());
    }
    let (rate, x) = read_wav_mono(p).map_err(|e| cfg_error(&path_str(p), format!("{e:#}")))?;
    if x.is_empty() {
        return Err(cfg_error(&path_str(p), "the WAV file holds no samples".into()).into());
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(cfg_error(&path_str(p), "the WAV file holds non-finite samples".into()).into());
    }
    Ok((rate as f64, x))
}

/// The frame rate of `video`: `--fps`, else the file's.
fn frame_rate(video: &Path, fps: Option<f64>) -> anyhow::Result<f64> {
    if let Some(f) = fps {
        crate::stages::sources::check_fps(f).map_err(|m| cfg_error("--fps", m))?;
        return Ok(f);
    }
    if !video.exists() {
        return Err(cfg_error(&path_str(video), "no such file".into()).into());
    }
    let r = crate::io::open(video, crate::io::Format::Auto)
        .map_err(|e| cfg_error(&path_str(video), format!("{e}")))?;
    r.info().fps.ok_or_else(|| {
        cfg_error(
            &path_str(video),
            "the file states no frame rate; pass --fps".into(),
        )
        .into()
    })
}

/// Recovers sound from `video` with the default listen pipeline (CSP
/// pyramid, alignment, high-pass): `(frame rate, samples)`.
pub fn recover(video: &Path, fps: Option<f64>) -> anyhow::Result<(f64, Vec<f64>)> {
    if !video.exists() {
        return Err(cfg_error(&path_str(video), "no such file".into()).into());
    }
    let fs = frame_rate(video, fps)?;
    let tmp = std::env::temp_dir().join(format!(
        "vibroscope-calibrate-{}-{}.wav",
        std::process::id(),
        TMP.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    let decl = listen_pipeline(video, &tmp, fps, None, DenoiseArg::None, PyramidArg::Csp)?;
    let (code, _) = run_decl(&decl, false, false)?;
    let read = read_wav_mono(&tmp);
    let _ = std::fs::remove_file(&tmp);
    if code != ExitCode::SUCCESS {
        anyhow::bail!("{}: the recovery failed", video.display());
    }
    Ok((fs, read?.1))
}

static TMP: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Recovers `video` and calibrates it against `reference` (errors that are
/// the user's: exit 2 with the file or value named).
pub fn calibrate_video(
    video: &Path,
    reference: &Path,
    fps: Option<f64>,
    opts: Option<Options>,
) -> anyhow::Result<(f64, f64, Vec<f64>, Calibration)> {
    let (fr, r) = read_input_wav(reference)?;
    let fs = frame_rate(video, fps)?;
    if fr < fs {
        return Err(cfg_error(
            &path_str(reference),
            format!(
                "sampled at {fr} Hz, below the video's frame rate of {fs} Hz: the reference must hold every frequency the camera can see"
            ),
        )
        .into());
    }
    let (fs, y) = recover(video, fps)?;
    let (dv, dr) = (y.len() as f64 / fs, r.len() as f64 / fr);
    if dr + 0.5 / fs < dv {
        return Err(cfg_error(
            &path_str(reference),
            format!(
                "{dr:.3} s long, shorter than the video {} ({dv:.3} s at {fs} Hz)",
                video.display()
            ),
        )
        .into());
    }
    let opts = opts.unwrap_or_else(|| Options::for_rate(fs));
    let c = cal::calibrate(&y, fs, &r, fr, &opts)
        .map_err(|e| cfg_error(&path_str(video), e.to_string()))?;
    Ok((fs, fr, r, c))
}

fn write_wav(path: &Path, rate: u32, x: &[f64]) -> anyhow::Result<()> {
    Ok(crate::io::wav::write_mono_f32(path, rate, x)?)
}

fn fmt_db(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2}")
    } else {
        "n/a".into()
    }
}

/// `vibroscope calibrate`.
pub fn run(a: &CalibrateArgs) -> anyhow::Result<ExitCode> {
    let effects = a.effects.as_deref().map(parse_effects).transpose()?;
    let opts = match (effects, frame_rate(&a.video, a.fps)) {
        (Some(e), Ok(fs)) => Some(Options {
            effects: e,
            ..Options::for_rate(fs)
        }),
        _ => None,
    };
    let (fs, fr, r, c) = calibrate_video(&a.video, &a.reference, a.fps, opts)?;
    let text = serde_json::to_string_pretty(&c.report)?;
    crate::stages::sinks::write_atomic(&a.json, (text + "\n").as_bytes())
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let (b, af) = (&c.report.before, &c.report.after);
    eprintln!(
        "linear model: delay {:.3} ms, gain {:.4e}; held-out part (40%): SNR {} -> {} dB, segmental SNR {} -> {} dB, LSD {} -> {} dB",
        c.delay_s * 1e3,
        c.gain,
        fmt_db(b.snr_db),
        fmt_db(af.snr_db),
        fmt_db(b.ssnr_db),
        fmt_db(af.ssnr_db),
        fmt_db(b.lsd_db),
        fmt_db(af.lsd_db)
    );
    for e in &c.report.effects {
        eprintln!("kept {}: +{:.2} dB", e.name, e.snr_gain_db);
    }
    for e in &c.rejected {
        eprintln!(
            "tried {}: {} dB, not kept ({})",
            e.name,
            fmt_db(e.snr_gain_db),
            e.parameters
        );
    }
    for u in &c.report.unexplained {
        eprintln!("unexplained: {}", u.description());
    }
    if let Some(out) = &a.output {
        // Reference time of corrected sample n is n / fs - delay.
        let end = c.corrected.len() as f64 / fs - c.delay_s;
        let count = ((end * fr).floor().max(0.0) as usize).min(r.len());
        let x = cal::sample_at(
            &c.corrected,
            fs,
            (0..count).map(|k| k as f64 / fr + c.delay_s),
        );
        write_wav(out, fr as u32, &x)?;
        eprintln!("wrote {}", out.display());
    }
    eprintln!("wrote {}", a.json.display());
    Ok(ExitCode::SUCCESS)
}

/// The reusable corrections of a stored report (`listen --calibration`).
pub fn load_calibration(path: &Path) -> anyhow::Result<Vec<Correction>> {
    let name = path_str(path);
    let text =
        std::fs::read_to_string(path).map_err(|e| cfg_error(&name, format!("cannot read: {e}")))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| cfg_error(&name, format!("not JSON: {e}")))?;
    cal::reusable_from_report(&v).map_err(|m| cfg_error(&name, m.to_string()).into())
}

/// Applies `corrections` to the WAV at `path` in place (at its own rate).
/// With `denoise` (the recovery was denoised), the same denoiser runs
/// again after the corrections, as in the thesis' Table 4.2: equalising
/// boosts the noise in the bands it lifts, and that noise is removed
/// again. Samples keep their times.
pub(crate) fn apply_to_wav(
    path: &Path,
    corrections: &[Correction],
    denoise: Option<DenoiseArg>,
) -> anyhow::Result<()> {
    let (rate, y) = read_wav_mono(path)?;
    let mut z = cal::apply_all(corrections, &y, rate as f64);
    if let Some(kind) = denoise {
        z = denoise_again(&z, rate as f64, kind)
            .with_context(|| format!("denoising {} after the calibration", path.display()))?;
    }
    let peak = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let ypeak = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // Keep the recovery's scale (the equaliser's level is arbitrary).
    let s = if peak > 0.0 { ypeak / peak } else { 1.0 };
    let z: Vec<f64> = z.iter().map(|v| v * s).collect();
    write_wav(path, rate, &z)
}

/// Runs the `--denoise` method (default settings, as the stage's) over `x`;
/// `x` itself for `none`. Output sample `k` is the estimate of input sample
/// `k` (the denoisers' latency is only in when a sample is released), so
/// the whole signal is fed and finished.
fn denoise_again(x: &[f64], rate: f64, kind: DenoiseArg) -> anyhow::Result<Vec<f64>> {
    use crate::math::denoise::{SpectralSubtraction, SpeechEnhance};
    let input: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    let mut out = Vec::with_capacity(input.len());
    match kind {
        DenoiseArg::None => return Ok(x.to_vec()),
        DenoiseArg::Subtract => {
            let mut d = SpectralSubtraction::with_defaults(rate)?;
            d.process(&input, &mut out);
            d.finish(&mut out);
        }
        DenoiseArg::Enhance => {
            let mut d = SpeechEnhance::with_defaults(rate)?;
            d.process(&input, &mut out);
            d.finish(&mut out);
        }
    }
    Ok(out.iter().map(|&v| v as f64).collect())
}

/// The names of the corrections a report holds, for messages.
pub fn describe(corrections: &[Correction]) -> String {
    if corrections.is_empty() {
        return "none (the report keeps no object or camera effect)".into();
    }
    corrections
        .iter()
        .map(|c| c.kind().name())
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// Denoising again after a calibration keeps every sample at its time:
    /// a chirp in noise comes out at lag 0, as long as it went in.
    #[test]
    fn denoising_again_keeps_sample_times() {
        let fs = 2200.0;
        let mut s = 12345u64;
        let x: Vec<f64> = (0..4400)
            .map(|i| {
                let t = i as f64 / fs;
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
                let noise = ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.05;
                (2.0 * std::f64::consts::PI * (100.0 * t + 100.0 * t * t)).sin() + noise
            })
            .collect();
        for kind in [DenoiseArg::Subtract, DenoiseArg::Enhance] {
            let y = denoise_again(&x, fs, kind).unwrap();
            assert_eq!(y.len(), x.len(), "{kind:?}");
            let (lag, _) = crate::math::metrics::best_lag_gain(&x, &y, 500);
            assert_eq!(lag, 0, "{kind:?}");
        }
    }
}
