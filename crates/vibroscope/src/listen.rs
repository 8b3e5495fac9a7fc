//! Recover sound from a video: a shipped visual-microphone pipeline
//! replayed on a recording ([`Method::Gradient`], the default: per-tile
//! gradient motion on its principal component, at the Cramér-Rao bound;
//! [`Method::Phase`]: the thesis' pyramid local phase and band alignment),
//! high-passed, optionally denoised; or, for rolling-shutter cameras, one
//! sample per row. Optional band-pass and band-stop stages (`--band`,
//! `--notch`) follow, then a `resample` stage to a standard audio rate,
//! then the WAV: 16-bit PCM peak-normalised to -1 dBFS, or 32-bit float in
//! the signal's own units (relative units, or radians of A²-weighted local
//! phase, on the frame path; pixels along x for rows): a sound, not a
//! displacement with a length unit (that is `spectrum --waveform` with a
//! scale).

use crate::corrections;
use crate::engine::config::PipelineDecl;
use crate::engine::pipelines::stage::{rolling_shutter, tile_microphone, visual_microphone};
use crate::engine::spec::KindParams;
use crate::engine::RunReport;
use crate::error::{Error, Result};
use crate::math::calibrate::{self as cal, Correction};
use crate::math::exposure::Mode as ExposureMode;
use crate::microphone::listen_pipeline;
pub use crate::microphone::Method;
pub use crate::pipeline::BandFilter;
pub use crate::pipeline::Denoise;
use crate::pipeline::{self, by, PipelineOptions, Region, RunSettings};
use crate::stages::params::{
    AlignParams, ExposureParams, GapFillParams, PhaseParams, ResampleParams, RowsParams,
    SpeakerParams, WavParams,
};
use crate::stages::transform::gap_fill::FillMethod;
use crate::stages::transform::resample::{default_rate_hz, resample_all};
use serde::Serialize;
use std::path::PathBuf;

/// Filling of a rolling-shutter camera's frame-delay gaps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Fill {
    #[default]
    Ar,
    Linear,
}

/// Rolling-shutter timing (thesis ch. 4.5): one sample per image row.
#[derive(Clone, Debug, Default)]
pub struct RollingShutter {
    /// Time between consecutive rows, µs (required).
    pub line_delay_us: Option<f64>,
    /// Blind time between a frame's last row and the next frame's first, µs.
    pub frame_delay_us: Option<f64>,
    /// Exposure per row, µs.
    pub exposure_us: Option<f64>,
    /// Invert the exposure boxcar (needs `exposure_us`).
    pub compensate_exposure: bool,
    pub fill: Fill,
}

/// The rate of the WAV `listen` writes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum OutputRate {
    /// The signal's own rate when it is a standard audio rate, else 48 kHz.
    #[default]
    Standard,
    /// This rate, Hz (band-limited resampling).
    Hz(u32),
    /// The signal's own rate (the frame rate; 1/line delay for rows).
    Native,
}

/// Output rates `--rate` takes, Hz (the `resample` stage's range).
pub const RATE_RANGE: std::ops::RangeInclusive<u32> = 1000..=384_000;

/// Whether `listen --calibration` unfolds a readout across the rows
/// (issue 50, item 3: a timing effect across the rows makes `listen` use
/// the instants the rows were captured at, not one a frame).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Unfold {
    /// Where the strips show that something lies above the frame rate's
    /// Nyquist frequency: each is predicted better from the others with
    /// it than without ([`cal::Unfolded::holds_alias`]; the default). The
    /// note says which was chosen and by how much.
    #[default]
    Auto,
    /// Asked for (`--unfold`): unfolded whatever the strips show; where it
    /// cannot be done, the note says why.
    Asked,
    /// At the frame rate, the strips' delays applied there (`--no-unfold`).
    Never,
}

/// What `listen` is asked.
#[derive(Clone, Debug, Default)]
pub struct ListenOptions {
    pub video: PathBuf,
    /// The WAV written.
    pub output: PathBuf,
    /// Capture frame rate (Hz) when the file states the wrong one.
    pub fps: Option<f64>,
    pub region: Region,
    /// How motion is measured; `None`: [`Method::Gradient`], or
    /// [`Method::Phase`] with a calibration (which is fitted on it).
    pub method: Option<Method>,
    /// Independent sources the gradient method may sum (1-4; `None`: 1).
    pub sources: Option<usize>,
    pub denoise: Denoise,
    /// Also play on this speaker (`default`, part of a name, or `null`).
    pub speaker: Option<String>,
    /// A stored calibration (REPORT.json of `calibrate`) to apply.
    pub calibration: Option<PathBuf>,
    /// With a calibration's capture time across the rows: whether to
    /// unfold what the strips sampled above the frame rate's Nyquist
    /// frequency, at twice the frame rate ([`cal::unfold`]).
    pub unfold: Unfold,
    /// One sample per row instead of per frame.
    pub rolling_shutter: Option<RollingShutter>,
    /// Band-pass and band-stop filters, applied in order.
    pub filters: Vec<BandFilter>,
    pub rate: OutputRate,
    /// 32-bit float in the signal's own units (radians of phase; px for
    /// rows) instead of normalised 16-bit PCM.
    pub float: bool,
    /// `--method phase --pyramid csp` on the pyramid's half grids (the
    /// `phase` kind's `half_grids`): about twice as fast, up to 0.3 dB
    /// less SNR on noisy scenes.
    pub half_grids: bool,
    pub run: RunSettings,
}

/// What `listen` did.
#[derive(Debug, Serialize)]
pub struct ListenReport {
    pub output: PathBuf,
    /// The corrections applied from `--calibration`, by name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration: Option<String>,
    /// Samples written and their rate (Hz).
    pub samples: u64,
    pub sample_rate_hz: u32,
    /// "16-bit PCM, peak at -1 dBFS" or "32-bit float, " and the unit.
    pub encoding: String,
    /// Notes worth telling the user (e.g. a missing exposure).
    pub notes: Vec<String>,
    #[serde(skip)]
    pub run: Option<RunReport>,
}

/// Runs `listen`.
pub fn listen(o: &ListenOptions) -> Result<ListenReport> {
    let mut inputs = vec![o.video.as_path()];
    inputs.extend(o.calibration.as_deref());
    inputs.extend(o.region.mask.as_deref());
    crate::error::check_outputs(&inputs, &[&o.output])?;
    // The frame path's method (rows have their own pipeline).
    let method = if o.rolling_shutter.is_some() {
        for (flag, given) in [
            ("--method", o.method.is_some()),
            ("--sources", o.sources.is_some()),
        ] {
            if given {
                return Err(Error::usage(
                    flag,
                    "not available with --rolling-shutter (rows have their own pipeline)",
                ));
            }
        }
        None
    } else {
        Some(method(o)?)
    };
    if o.half_grids {
        let why = if o.calibration.is_some() {
            Some("not available with --calibration (calibrations are fitted on the full grids)")
        } else if method != Some(Method::Phase) || o.region.pyramid != crate::pipeline::Pyramid::Csp
        {
            Some("applies to `--method phase --pyramid csp` (the steerable pyramid's grids)")
        } else {
            None
        };
        if let Some(why) = why {
            return Err(Error::usage("--half-grids", why));
        }
    }
    let stored = match &o.calibration {
        Some(path) => {
            if o.speaker.is_some() {
                return Err(Error::usage(
                    "--calibration",
                    "not available with --speaker (the correction is applied to the finished WAV)",
                ));
            }
            Some(corrections::load(path)?)
        }
        None => None,
    };
    let (corrections, frame, terms, stored_notes) = match stored {
        Some(s) => (Some(s.corrections), s.frame, s.explained, s.notes),
        None => (None, None, Vec::new(), Vec::new()),
    };
    if let OutputRate::Hz(r) = o.rate {
        if !RATE_RANGE.contains(&r) {
            return Err(Error::usage(
                "--rate",
                format!(
                    "{r} Hz is outside {}-{} Hz",
                    RATE_RANGE.start(),
                    RATE_RANGE.end()
                ),
            ));
        }
    }
    if let Some(c) = corrections.as_deref() {
        if let Some(rs) = &o.rolling_shutter {
            return listen_rows(o, c, rs, terms.len(), stored_notes);
        }
        if c.iter().any(|c| {
            matches!(
                c,
                Correction::CaptureTime { .. } | Correction::RegionGain { .. }
            )
        }) {
            return listen_strips(o, c, method, (frame, &terms), stored_notes);
        }
    }
    let mut notes = stored_notes;
    if o.unfold == Unfold::Asked && o.rolling_shutter.is_none() {
        notes.push("--unfold: no strips of rows to unfold (no calibration, or one that recombines none: no capture_time): the recovery is at the frame rate".into());
    }
    let mut decl = match &o.rolling_shutter {
        Some(rs) => {
            if o.region.mask.is_some() {
                return Err(Error::usage(
                    "--mask",
                    "not available with --rolling-shutter yet (use --roi)",
                ));
            }
            if o.denoise != Denoise::None {
                return Err(Error::usage(
                    "--denoise",
                    "not available with --rolling-shutter yet",
                ));
            }
            rs_pipeline(o, rs, &mut notes)?
        }
        None => {
            let method = method.unwrap_or_default();
            let mut decl =
                listen_pipeline(&o.video, &o.output, o.fps, (&o.region, method), o.denoise)?;
            if o.half_grids {
                let origin = by("--half-grids");
                let phase = visual_microphone::PHASE;
                pipeline::set(&mut decl, phase, PhaseParams::half_grids, true, origin)?;
            }
            if let Some(n) = o.sources {
                let align = match method {
                    Method::Phase => visual_microphone::ALIGN,
                    Method::Gradient => tile_microphone::ALIGN,
                };
                let origin = by(&format!("--sources {n}"));
                pipeline::set(&mut decl, align, AlignParams::components, n, origin)?;
            }
            decl
        }
    };
    // The signal's rate, when known before the run: bands must lie below
    // its Nyquist frequency (checked again by the stages once it is known).
    // Asked of the file only when a filter or a calibration needs it:
    // opening a Y4M reads every frame's header.
    let signal_rate = match &o.rolling_shutter {
        Some(rs) => rs.line_delay_us.filter(|d| *d > 0.0).map(|d| 1e6 / d),
        None if corrections.is_none() && o.filters.is_empty() => None,
        None => o.fps.or_else(|| {
            crate::io::open(&o.video, crate::io::format_by_extension(&o.video))
                .ok()
                .and_then(|r| r.info().fps)
        }),
    };
    // What the calibration cannot undo at one sample a frame (a
    // calibration with --rolling-shutter took the row path above).
    if let (Some(c), Some(fs)) = (&corrections, signal_rate) {
        notes.extend(c.iter().filter_map(|c| c.cannot_correct(fs)));
    }
    for (i, f) in o.filters.iter().enumerate() {
        if let Some(rate) = signal_rate {
            f.check_rate(rate)?;
        }
        let id = format!("{}{}", f.stage().0, i + 1);
        f.insert(&mut decl, &id, "out")?;
    }
    // A calibration is applied to the finished WAV at the signal's rate;
    // it is resampled afterwards, by the same resampler.
    if corrections.is_none() && o.rate != OutputRate::Native {
        let origin = by(&match o.rate {
            OutputRate::Hz(r) => format!("--rate {r}"),
            _ => "listen's default output rate".into(),
        });
        let mut st = pipeline::new_stage::<ResampleParams>("resample", &[], origin.clone());
        if let OutputRate::Hz(r) = o.rate {
            pipeline::put(&mut st, ResampleParams::rate_hz, Some(f64::from(r)), origin)?;
        }
        pipeline::insert_before(&mut decl, "out", st)?;
    }
    if corrections.is_some() {
        crate::microphone::causal_highpass(&mut decl)?;
    }
    // A correction that depends on the recovery's scale and sign (a static
    // nonlinearity), and what the explainer kept (observables of this
    // recording), are brought to this recording's frame: its region's
    // motion in pixels and the terms' tiles are measured in the same run.
    let needs = corrections
        .as_deref()
        .is_some_and(|c| needs_observables(c, &terms));
    if needs && frame.is_none() {
        notes.push(NO_FRAME.into());
    }
    let observe = match (frame, needs, &o.calibration) {
        (Some(_), true, Some(path)) => Some(corrections::Observe::add(
            &mut decl,
            (&o.video, &o.region),
            path,
            &terms,
        )?),
        _ => None,
    };
    if let Some(dev) = &o.speaker {
        add_speaker(&mut decl, dev)?;
    }
    // A file already at the output path that this run does not write (it
    // stopped before any sound reached the WAV) is not finished again.
    let modified = || std::fs::metadata(&o.output).and_then(|m| m.modified()).ok();
    let before = modified();
    let run = pipeline::run(&decl, o.run);
    // Ctrl-C, or a stage's error (a recording cut short): the WAV holds
    // what was processed; finish it as well, with the observables
    // measured on the same frames.
    let after = modified();
    let written = after.is_some() && (run.is_ok() || after != before);
    if matches!(
        run,
        Ok(_) | Err(Error::Interrupted { .. } | Error::Stages { .. })
    ) && written
    {
        let finished = (|| -> Result<()> {
            if let Some(c) = &corrections {
                match (frame, &observe) {
                    (Some(f), Some(obs)) => {
                        match obs.apply(&o.output, (c, o.denoise), f, &terms) {
                            Ok(said) => notes.extend(said),
                            // Stopped too early to measure this recording's
                            // frame: what needs it is left out, and said.
                            Err(e) if run.is_err() => {
                                let plain: Vec<Correction> =
                                    c.iter().filter(|c| !c.needs_frame()).cloned().collect();
                                let said = corrections::apply_to_wav(&o.output, &plain, o.denoise)?;
                                notes.push(format!("{e}: the calibration's amplitude-dependent corrections and explained terms were left out"));
                                notes.extend(said);
                            }
                            Err(e) => return Err(e),
                        }
                    }
                    _ => notes.extend(corrections::apply_to_wav(&o.output, c, o.denoise)?),
                }
            }
            finish_wav(o, corrections.is_some())
        })();
        match finished {
            Ok(()) if matches!(run, Err(Error::Stages { .. })) => {
                let kept = hound::WavReader::open(&o.output)
                    .map(|r| {
                        let rate = r.spec().sample_rate.max(1);
                        format!(
                            " ({:.2} s at {rate} Hz)",
                            f64::from(r.duration()) / f64::from(rate)
                        )
                    })
                    .unwrap_or_default();
                notes.push(format!(
                    "{}: kept the sound of what was read before the error{kept}, finished as for a whole recording",
                    o.output.display()
                ));
            }
            Ok(()) => {}
            // A run that stopped keeps its own error; a WAV that could
            // not be finished is not left half done.
            Err(e) if run.is_err() => {
                let _ = std::fs::remove_file(&o.output);
                notes.push(format!(
                    "{}: removed: what the run wrote before it stopped could not be finished ({e})",
                    o.output.display()
                ));
            }
            Err(e) => return Err(e),
        }
    }
    // An interrupted run returns no report: its notes are said here.
    if run.is_err() {
        for n in &notes {
            tracing::warn!("{n}");
        }
    }
    let run = run?;
    Ok(report(o, corrections.as_deref(), method, notes, run))
}

/// What `listen` did, read back from the WAV it wrote.
fn report(
    o: &ListenOptions,
    corrections: Option<&[Correction]>,
    method: Option<Method>,
    notes: Vec<String>,
    run: RunReport,
) -> ListenReport {
    let calibration = corrections.map(corrections::describe);
    let (samples, sample_rate_hz) = match hound::WavReader::open(&o.output) {
        Ok(r) => (u64::from(r.duration()), r.spec().sample_rate),
        Err(_) => (0, 0),
    };
    ListenReport {
        output: o.output.clone(),
        samples,
        sample_rate_hz,
        encoding: if o.float {
            let unit = method.map_or("pixels of motion along x", Method::unit);
            format!("32-bit float, {unit}")
        } else {
            format!("16-bit PCM, peak at {PEAK_DBFS} dBFS")
        },
        calibration,
        notes,
        run: Some(run),
    }
}

/// `listen --calibration` with a calibration that holds a capture time
/// across the image: the strips of rows it was fitted on (over the
/// region's columns) are recovered in one run, each advanced by its delay
/// and weighted, summed, and then the report's other corrections apply.
fn listen_strips(
    o: &ListenOptions,
    corrections: &[Correction],
    method: Option<Method>,
    (frame, terms): (Option<cal::PixelFrame>, &[cal::StoredTerm]),
    stored_notes: Vec<String>,
) -> Result<ListenReport> {
    let (rows, delays_s, weights, name) = match corrections.iter().find(|c| {
        matches!(
            c,
            Correction::CaptureTime { .. } | Correction::RegionGain { .. }
        )
    }) {
        Some(Correction::CaptureTime {
            rows,
            delays_s,
            weights,
            ..
        }) => (rows, delays_s.clone(), weights, "capture_time"),
        Some(Correction::RegionGain { rows, weights }) => {
            (rows, vec![0.0; rows.len()], weights, "region_gain")
        }
        _ => return Err(Error::Analysis("no strips in the calibration".into())),
    };
    let refuse = |flag: &str| {
        Error::usage(
            flag,
            format!("not available yet with a calibration that recombines strips of rows ({name})"),
        )
    };
    if o.denoise != Denoise::None {
        return Err(refuse("--denoise"));
    }
    if !o.filters.is_empty() {
        return Err(refuse("--band/--notch"));
    }
    let layout = crate::calibrate::strip_rows(&o.video, &o.region)?;
    let cols = layout.cols;
    fits(o, rows, name, layout.height)?;
    let fs = crate::calibrate::frame_rate(&o.video, o.fps)?;
    // As on the frame path: the region's motion and the explained terms'
    // tiles are measured in the same run, to bring the calibration to this
    // recording's frame.
    let mut notes = stored_notes;
    let needs = needs_observables(corrections, terms);
    let tiles = match (frame, &o.calibration) {
        (Some(_), Some(path)) if needs => {
            corrections::Observe::tiles((&o.video, &o.region), path, terms)?
        }
        _ => {
            if needs {
                notes.push(NO_FRAME.into());
            }
            corrections::Tiles::default()
        }
    };
    let crate::calibrate::StripRun {
        signals,
        observed,
        report: run,
        ..
    } = crate::calibrate::recover_observed(
        &o.video,
        o.fps,
        &o.region,
        (cols, rows),
        (false, &tiles.rects),
        o.run,
    )?;
    // Unless --no-unfold: a readout's capture times spread over the frame
    // period sample the motion at more instants than one a frame, and what
    // lies above the frame rate's Nyquist frequency is unfolded, at twice
    // the frame rate, where the strips show that anything lies there: they
    // are better predicted, each from the others, with it than without
    // (`Unfolded::holds_alias`); with --unfold, whatever they show. Not
    // when the frame or explained terms are needed (their observables are
    // measured once a frame).
    let asked = o.unfold == Unfold::Asked;
    let tried = match (name, tiles.is_empty(), o.unfold != Unfold::Never) {
        ("capture_time", true, true) => cal::unfold(
            &signals,
            (weights, &delays_s),
            (fs, cal::Options::for_rate(fs).highpass),
        ),
        _ => None,
    };
    let ratio = tried.as_ref().map(|u| u.press_ratio);
    let unfolded = tried.filter(|u| asked || u.holds_alias());
    match (&unfolded, ratio) {
        (Some(u), Some(r)) => {
            let rate = (2.0 * fs).round() as u32;
            crate::io::wav::write_mono_f32(&o.output, rate, &u.signal)?;
            let why = if u.holds_alias() {
                format!("each strip is predicted from the others {:.1} dB better with what lies between the frame rate's Nyquist frequency and the frame rate than without it", -10.0 * r.log10())
            } else {
                format!("asked by --unfold, although each strip is predicted from the others {:.1} dB worse with what lies above the frame rate's Nyquist frequency than without it", 10.0 * r.log10())
            };
            notes.push(format!(
                "the strips' capture times spread over the frame period and {why}: it is unfolded, and the recovery is at {rate} Hz (twice the frame rate; --no-unfold keeps the frame rate)"
            ));
        }
        _ => {
            let y = cal::combine(&signals, weights, &delays_s, fs);
            crate::io::wav::write_mono_f32(&o.output, fs.round() as u32, &y)?;
            if let Some(r) = ratio {
                notes.push(format!("the strips hold nothing above the frame rate's Nyquist frequency that their delays do not predict (each is predicted from the others {:.1} dB worse with it than without): the recovery is at the frame rate, the delays applied there (--unfold unfolds it anyway)", 10.0 * r.log10()));
            } else if asked && name != "capture_time" {
                notes.push(format!("--unfold: the calibration's strips ({name}) were captured at one instant: nothing to unfold"));
            } else if asked && !tiles.is_empty() {
                notes.push("--unfold: the strips' capture times are applied at the frame rate: what the rows sampled above its Nyquist frequency is not unfolded when the calibration also needs this recording's frame or tiles (measured once a frame)".into());
            } else if asked {
                notes.push("--unfold: the strips' capture times do not spread over enough of the frame period to tell a frequency from its alias (or too few strips hold the signal): applied at the frame rate".into());
            }
        }
    }
    match frame {
        Some(f) if !tiles.is_empty() => notes.extend(corrections::apply_observed(
            &o.output,
            (&tiles, &observed),
            (corrections, Denoise::None),
            f,
            terms,
        )?),
        _ => notes.extend(corrections::apply_to_wav(
            &o.output,
            corrections,
            Denoise::None,
        )?),
    }
    finish_wav(o, true)?;
    Ok(report(o, Some(corrections), method, notes, run))
}

/// Said when a calibration needs this recording's frame or tiles and
/// holds no pixel frame to bring them to.
const NO_FRAME: &str = "the calibration holds no pixel frame (written before it was measured): its corrections apply in the calibration recording's units and sign, and its explained terms are left out";

/// Whether applying `corrections` and `terms` needs this recording's
/// observables: the region's motion in pixels (a correction that depends
/// on the recovery's scale and sign) or the explained terms' tiles.
fn needs_observables(corrections: &[Correction], terms: &[cal::StoredTerm]) -> bool {
    corrections.iter().any(Correction::needs_frame) || !terms.is_empty()
}

/// The time per row of a readout a calibration found (`capture_time`'s
/// linear member, rows read one after another), µs; `None` for delays of
/// each strip's own (parts that hear the sound at different times) or a
/// readout from the bottom up: no one line delay.
fn readout_us(corrections: &[Correction]) -> Option<f64> {
    corrections.iter().find_map(|c| match c {
        Correction::CaptureTime {
            line_delay_s,
            per_region: false,
            ..
        } if *line_delay_s > 0.0 => Some(line_delay_s * 1e6),
        _ => None,
    })
}

/// `listen --rolling-shutter --calibration` (issue 50, item 3): the row
/// path, one sample per row at its capture time, with the line delay
/// given (`--line-delay-us`) or else the one the calibration found
/// (`capture_time`, rows read one after another), so that what the rows
/// sampled above the frame rate's Nyquist frequency is heard rather than
/// aliased; then the report's other corrections at the rows' rate, and
/// the output rate. `terms`: how many explained terms the report holds
/// (the row path measures no tiles: they are left out, and said so).
fn listen_rows(
    o: &ListenOptions,
    corrections: &[Correction],
    rs: &RollingShutter,
    terms: usize,
    stored_notes: Vec<String>,
) -> Result<ListenReport> {
    let found = readout_us(corrections);
    let Some(d_us) = rs.line_delay_us.or(found) else {
        return Err(Error::usage(
            "--line-delay-us",
            "required with --rolling-shutter: the calibration found no readout across the rows (capture_time) to take it from",
        ));
    };
    let refuse = |flag: &str| Error::usage(flag, "not available with --rolling-shutter yet");
    if o.denoise != Denoise::None {
        return Err(refuse("--denoise"));
    }
    if !o.filters.is_empty() {
        return Err(refuse("--band/--notch"));
    }
    if o.region.mask.is_some() {
        return Err(refuse("--mask"));
    }
    // The rows must fit in the frame period: a line delay the calibration
    // found a hair long (its uncertainty) is held at the period over the
    // rows; one given is checked by the `rows` stage.
    let fs = crate::calibrate::frame_rate(&o.video, o.fps)?;
    let height = crate::calibrate::strip_rows(&o.video, &o.region)?.height;
    for c in corrections {
        if let Correction::CaptureTime { rows, .. } = c {
            fits(o, rows, "capture_time", height)?;
        }
    }
    let longest = 1e6 / fs / f64::from(height.max(1));
    let d = match rs.line_delay_us {
        Some(_) => d_us,
        None => d_us.min(longest),
    };
    let mut notes = stored_notes;
    match (rs.line_delay_us, found) {
        (None, _) => notes.push(format!(
            "the line delay is the calibration's: rows read one after another, {d_us:.3} µs a row"
        )),
        (Some(_), Some(f)) => notes.push(format!(
            "--line-delay-us {d_us} is used; the calibration found {f:.3} µs a row"
        )),
        _ => {}
    }
    if d < d_us {
        notes.push(format!(
            "{d_us:.3} µs a row over {height} rows is longer than the frame period: held at {d:.3} µs"
        ));
    }
    let rs = RollingShutter {
        line_delay_us: Some(d),
        ..rs.clone()
    };
    let decl = rs_pipeline(o, &rs, &mut notes)?;
    let rest: Vec<Correction> = corrections
        .iter()
        .filter(|c| {
            !matches!(
                c,
                Correction::CaptureTime { .. } | Correction::RegionGain { .. }
            ) && !c.needs_frame()
        })
        .cloned()
        .collect();
    if corrections.iter().any(Correction::needs_frame) || terms > 0 {
        notes.push("the row path measures no pixel frame or tiles yet: the report's amplitude-dependent corrections and explained terms are left out".into());
    }
    let run = pipeline::run(&decl, o.run);
    if matches!(run, Ok(_) | Err(Error::Interrupted { .. })) && o.output.exists() {
        notes.extend(corrections::apply_to_wav(&o.output, &rest, Denoise::None)?);
        finish_wav(o, true)?;
    }
    let run = run?;
    Ok(report(o, Some(&rest), None, notes, run))
}

/// Whether a stored calibration's strips of rows (`name`'s) lie within
/// the video's `height` rows; the error names the report.
fn fits(o: &ListenOptions, rows: &[(u32, u32)], name: &str, height: u32) -> Result<()> {
    let calibration = o.calibration.as_deref().unwrap_or(o.video.as_path());
    match rows.iter().find(|r| r.1 > height) {
        Some(&(_, end)) => Err(Error::input(
            calibration,
            format!(
                "its {name} strips reach row {end}, but {} has {height} rows: it was fitted on another camera or frame size",
                o.video.display()
            ),
        )),
        None => Ok(()),
    }
}

/// The method `o` runs, or why it cannot: a calibration is fitted on the
/// phase method, and `--pyramid` only means something there.
fn method(o: &ListenOptions) -> Result<Method> {
    let method = o.method.unwrap_or(if o.calibration.is_some() {
        Method::Phase
    } else {
        Method::Gradient
    });
    if method == Method::Phase && o.sources.is_some() {
        return Err(Error::usage(
            "--sources",
            "applies to the gradient method (the phase method sums every band)",
        ));
    }
    if method == Method::Gradient {
        if o.calibration.is_some() {
            return Err(Error::usage(
                "--method",
                "a calibration is fitted on, and applied to, `--method phase`",
            ));
        }
        if o.region.pyramid != crate::pipeline::Pyramid::default() {
            return Err(Error::usage(
                "--pyramid",
                "chooses the pyramid of `--method phase` (the default method, gradient, has none)",
            ));
        }
    }
    Ok(method)
}

/// Peak level of the 16-bit WAV, dBFS.
pub const PEAK_DBFS: f64 = -1.0;

/// The WAV the pipeline wrote (32-bit float) in its final form: resampled
/// when the pipeline could not (`resample`: after a calibration), then
/// 16-bit PCM peak-normalised to [`PEAK_DBFS`] unless `--float`; written
/// atomically over it.
fn finish_wav(o: &ListenOptions, resample: bool) -> Result<()> {
    if resample && o.rate != OutputRate::Native {
        // After a calibration (which holds the whole signal anyway).
        let (rate, x) = crate::io::wav::read_mono(&o.output)?;
        let to = match o.rate {
            OutputRate::Hz(r) => f64::from(r),
            _ => default_rate_hz(f64::from(rate)),
        };
        if (to - f64::from(rate)).abs() > 1e-9 {
            let x32: Vec<f32> = x.iter().map(|&v| v as f32).collect();
            let y = resample_all(&x32, f64::from(rate), to).map_err(|e| {
                Error::Analysis(format!("{}: cannot resample: {e}", o.output.display()))
            })?;
            let y: Vec<f64> = y.iter().map(|&v| f64::from(v)).collect();
            crate::io::wav::write_mono_f32(&o.output, to as u32, &y)?;
        }
    }
    if !o.float {
        // Streaming: bounded memory however long the recording.
        crate::io::wav::normalize_to_i16(&o.output, PEAK_DBFS)?;
    }
    Ok(())
}

/// Adds a `speaker` sink fed by whatever feeds the `out` sink (fan-out:
/// the WAV and the speaker get the same blocks).
fn add_speaker(decl: &mut PipelineDecl, device: &str) -> Result<()> {
    let out = pipeline::position(decl, "out")?;
    let origin = by(&format!("--speaker {device}"));
    let mut st = decl.stages[out].clone();
    st.id = "speaker".into();
    st.kind = SpeakerParams::KINDS[0].into();
    st.kind_origin = origin.clone();
    st.clear_params();
    pipeline::put(&mut st, SpeakerParams::device, device.to_string(), origin)?;
    decl.stages.push(st);
    Ok(())
}

/// The shipped rolling-shutter pipeline replayed on the video with the
/// camera's timing.
fn rs_pipeline(
    o: &ListenOptions,
    a: &RollingShutter,
    notes: &mut Vec<String>,
) -> Result<PipelineDecl> {
    let mut decl = pipeline::prepare(&PipelineOptions {
        pipeline: "rolling-shutter".into(),
        set: Vec::new(),
        replay: Some(o.video.clone()),
        fps: o.fps,
    })?;
    let Some(d) = a.line_delay_us else {
        return Err(Error::usage(
            "--line-delay-us",
            "required with --rolling-shutter (estimate it with `vibroscope rs-calibrate`)",
        ));
    };
    let (rows, fill, exposure) = (
        rolling_shutter::ROWS,
        rolling_shutter::FILL,
        rolling_shutter::EXPOSURE,
    );
    let origin = by(&format!("--line-delay-us {d}"));
    pipeline::set(&mut decl, rows, RowsParams::line_delay_us, Some(d), origin)?;
    if let Some(g) = a.frame_delay_us {
        let origin = by(&format!("--frame-delay-us {g}"));
        pipeline::set(&mut decl, rows, RowsParams::frame_delay_us, Some(g), origin)?;
    }
    // The shipped region is the simulator's object: a recording starts from the whole frame.
    let roi = o.region.roi.map(|r| r.param());
    let origin = match &o.region.roi {
        Some(r) => by(&format!("--roi {r}")),
        None => by("a recording's whole frame"),
    };
    pipeline::set(&mut decl, rows, RowsParams::roi, roi, origin)?;
    let method = match a.fill {
        Fill::Ar => FillMethod::Ar,
        Fill::Linear => FillMethod::Linear,
    };
    pipeline::set(&mut decl, fill, GapFillParams::method, method, by("--fill"))?;
    match a.exposure_us {
        Some(e) => {
            let origin = by(&format!("--exposure-us {e}"));
            pipeline::set(&mut decl, exposure, ExposureParams::exposure_us, e, origin)?;
            if a.compensate_exposure {
                pipeline::set(
                    &mut decl,
                    exposure,
                    ExposureParams::mode,
                    ExposureMode::Compensate,
                    by("--compensate-exposure"),
                )?;
            }
        }
        None => {
            if a.compensate_exposure {
                return Err(Error::usage("--compensate-exposure", "needs --exposure-us"));
            }
            notes.push(
                "no --exposure-us: the output is not band-limited to the exposure's first null"
                    .into(),
            );
            decl.stages.retain(|s| s.id != exposure.id);
            pipeline::rewire(&mut decl, rolling_shutter::OUT.id, fill.id)?;
        }
    }
    let output = o.output.clone();
    pipeline::set(
        &mut decl,
        rolling_shutter::OUT,
        WavParams::path,
        output,
        by("-o"),
    )?;
    Ok(decl)
}
