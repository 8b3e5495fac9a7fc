//! Calibration against a known sound (`vibroscope calibrate`) and its
//! stored corrections (`listen --calibration`). The recovery comes from the
//! listen pipeline (the same graph `listen` runs), the math from
//! [`crate::math::calibrate`].

use crate::engine::config::StageDecl;
use crate::engine::spec::Key;
use crate::error::{Error, Result};
use crate::io::atomic::TempPath;
pub use crate::math::calibrate::Parameters;
use crate::math::calibrate::{self as cal, Calibration, Options};
use crate::microphone::{listen_pipeline, Method};
use crate::pipeline::Denoise;
use crate::pipeline::{self, Region, RunSettings};
use crate::pipelines::stage::visual_microphone::{ALIGN, HIGHPASS, OUT, PHASE};
use crate::stages::params::{
    AlignParams, CsvParams, DisplacementParams, PhaseParams, PyramidParams, Untextured, WavParams,
};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::{Path, PathBuf};

pub use crate::math::calibrate::{EffectKind, Explanation, Observable, Step, CATALOG};

/// Called before each candidate effect is fitted (a progress display).
#[derive(Clone)]
pub struct StepHook(pub std::sync::Arc<dyn Fn(Step) + Send + Sync>);

impl std::fmt::Debug for StepHook {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("StepHook")
    }
}

/// What `calibrate` is asked.
#[derive(Clone, Debug, Default)]
pub struct CalibrateOptions {
    /// The recording of the object while the reference sound played.
    pub video: PathBuf,
    /// The sound that was played (WAV, first channel); unused with
    /// `reference_tone_hz`.
    pub reference: PathBuf,
    /// Instead of a WAV: the reference is a pure tone of this frequency
    /// whose phase is unknown (a tuning fork); its exact pitch is what the
    /// time base then measures.
    pub reference_tone_hz: Option<f64>,
    /// Where the report goes (REPORT.json).
    pub json: PathBuf,
    /// Also the corrected recovery at the reference's rate.
    pub output: Option<PathBuf>,
    pub fps: Option<f64>,
    pub region: Region,
    /// The effects to try (`None`: the whole catalog).
    pub effects: Option<Vec<EffectKind>>,
    pub run: RunSettings,
    /// Told of each candidate effect as it is fitted.
    pub on_step: Option<StepHook>,
}

/// What `calibrate` found: serialises to the REPORT.json it writes.
#[derive(Clone, Debug, Serialize)]
pub struct CalibrationReport {
    #[serde(flatten)]
    pub report: cal::Report,
    /// Delay (s) and gain of the final linear model.
    #[serde(skip)]
    pub delay_s: f64,
    #[serde(skip)]
    pub gain: f64,
    /// Effects fitted but not kept: name, SNR gain (dB), parameters.
    #[serde(skip)]
    pub rejected: Vec<(String, f64, cal::Parameters)>,
    /// Files written.
    #[serde(skip)]
    pub written: Vec<PathBuf>,
    /// The reference when it was a tone (`--reference-tone`), Hz.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_tone_hz: Option<f64>,
    /// What the effects found mean that the table does not say (a tone's
    /// pitch and a clock error are one parameter).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

/// `a,b,c` as catalog entries (in catalog order).
pub fn parse_effects(list: &str) -> Result<Vec<EffectKind>> {
    let names: Vec<&str> = list
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    for n in &names {
        if !CATALOG.iter().any(|k| k.name() == *n) {
            let all: Vec<&str> = CATALOG.iter().map(|k| k.name()).collect();
            return Err(Error::usage(
                "--effects",
                format!("unknown effect `{n}` (known: {})", all.join(", ")),
            ));
        }
    }
    Ok(CATALOG
        .iter()
        .copied()
        .filter(|k| names.contains(&k.name()))
        .collect())
}

/// Reads a WAV as an input error when it is missing or unreadable.
/// Largest accepted peak of a reference WAV (full scale is 1).
pub const MAX_REFERENCE_PEAK: f64 = 1e6;

fn read_input_wav(p: &Path) -> Result<(f64, Vec<f64>)> {
    if !p.exists() {
        return Err(Error::input(p, "no such file"));
    }
    let (rate, x) = crate::io::wav::read_mono(p).map_err(|e| Error::input(p, e.to_string()))?;
    if x.is_empty() {
        return Err(Error::input(p, "the WAV file holds no samples"));
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(Error::input(p, "the WAV file holds non-finite samples"));
    }
    // The corrected recovery is written in the reference's units as 32-bit
    // floats; a reference beyond this would overflow them (3e38 once gave
    // a WAV mostly inf and NaN). A WAV's full scale is ±1.
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if peak > MAX_REFERENCE_PEAK {
        return Err(Error::input(
            p,
            format!(
                "peaks at {peak:.3e}, beyond ±{MAX_REFERENCE_PEAK:.0e} (a WAV's full scale is ±1): rescale it"
            ),
        ));
    }
    Ok((rate as f64, x))
}

/// The frame rate of `video`: `fps`, else the file's.
pub fn frame_rate(video: &Path, fps: Option<f64>) -> Result<f64> {
    if let Some(f) = fps {
        pipeline::check_fps(Some(f))?;
        return Ok(f);
    }
    if !video.exists() {
        return Err(Error::input(video, "no such file"));
    }
    let r = crate::io::open(video, crate::io::Format::Auto)
        .map_err(|e| Error::input(video, e.to_string()))?;
    r.info()
        .fps
        .ok_or_else(|| Error::input(video, "the file states no frame rate; pass --fps"))
}

/// Recovers sound from `video` with the listen pipeline (no denoising):
/// `(frame rate, samples)`.
pub fn recover(
    video: &Path,
    fps: Option<f64>,
    region: &Region,
    run: RunSettings,
) -> Result<(f64, Vec<f64>)> {
    if !video.exists() {
        return Err(Error::input(video, "no such file"));
    }
    let fs = frame_rate(video, fps)?;
    let tmp = TempPath::new("calibrate.wav");
    pipeline::run(&recovery_pipeline(video, tmp.path(), fps, region)?, run)?;
    let (_, y) = crate::io::wav::read_mono(tmp.path())?;
    Ok((fs, y))
}

/// Strips of rows the residual's image axis is read on (effect (i)).
pub const STRIPS: u32 = 8;
/// The fewest rows a strip holds (the pyramid's finer scales need a few).
const MIN_STRIP_ROWS: u32 = 4;

/// A region cut into strips of rows, with the facts of the video's header
/// the strips need.
pub struct StripLayout {
    /// The region's columns: first, count.
    pub cols: (u32, u32),
    /// Each strip's first row and end row.
    pub rows: Vec<(u32, u32)>,
    /// The frame's height in rows.
    pub height: u32,
    /// The frame's width in columns.
    pub width: u32,
}

impl StripLayout {
    /// The region the strips cover, `[x, y, w, h]` (the frame's rows when
    /// there are no strips).
    pub fn region(&self) -> [u32; 4] {
        let first = self.rows.first().map_or(0, |r| r.0);
        let last = self.rows.last().map_or(self.height, |r| r.1);
        [self.cols.0, first, self.cols.1, last - first]
    }
}

/// The region's columns and its rows cut into up to [`STRIPS`] strips of
/// equal height (the video's header is opened once).
pub fn strip_rows(video: &Path, region: &Region) -> Result<StripLayout> {
    if !video.exists() {
        return Err(Error::input(video, "no such file"));
    }
    let r = crate::io::open(video, crate::io::Format::Auto)
        .map_err(|e| Error::input(video, e.to_string()))?;
    let (w, h) = (r.info().width, r.info().height);
    let (x, y, rw, rh) = match &region.roi {
        Some(r) => (
            r.x,
            r.y,
            r.w.min(w.saturating_sub(r.x)),
            r.h.min(h.saturating_sub(r.y)),
        ),
        None => (0, 0, w, h),
    };
    let k = STRIPS.min(rh / MIN_STRIP_ROWS);
    let rows = (0..k)
        .map(|i| (y + i * rh / k, y + (i + 1) * rh / k))
        .collect();
    Ok(StripLayout {
        cols: (x, rw),
        rows,
        height: h,
        width: w,
    })
}

/// Recovers each strip of rows (`rows`, over the columns `cols`) of
/// `video` with the listen pipeline's phase method, causally high-passed
/// as [`recover`], in one run: one decoder feeds a branch per strip and,
/// with `whole`, the region's own (so the video is decoded once). Returns
/// the region's recovery (with `whole`) and one signal per strip, and the
/// motion (x, y) and mean intensity of each tile of `tiles`, measured in
/// the same run (one `displacement` stage on the decoder;
/// [`StripRun::observed`], three channels a tile).
pub fn recover_observed(
    video: &Path,
    fps: Option<f64>,
    region: &Region,
    (cols, rows): ((u32, u32), &[(u32, u32)]),
    (whole, tiles): (bool, &[[u32; 4]]),
    run: RunSettings,
) -> Result<StripRun> {
    let tmp0 = TempPath::new("strips.wav");
    let mut decl = recovery_pipeline(video, tmp0.path(), fps, region)?;
    // Before the shared pyramid takes the phase stage's input.
    let observed_temp = TempPath::new("observed.csv");
    if !tiles.is_empty() {
        add_observe(&mut decl, tiles, observed_temp.path())?;
    }
    // One pyramid per frame for every branch: `phase` computes it over the
    // whole frame whatever its region, so nine branches would compute it
    // nine times.
    let mut pyr = pipeline::new_stage::<PyramidParams>(
        "pyramid",
        &[],
        pipeline::by("calibrate (the strips' shared pyramid)"),
    );
    // One thread a stage: the branches (a phase stage per strip and per
    // set of bands, each with its own sink), the shared pyramid and the
    // observing stage keep the cores busy between them. With the phase
    // stage's default (on two cores, a helper per stage spinning between
    // frames) the helpers took 43% of a calibration's CPU: the calibrate
    // bench's clip (64x64) took 3.2 s (4.7 s of CPU) against 1.5-1.8 s,
    // and a 256x256 one 7.1-7.8 s against 4.5-4.7 s. The shared pyramid
    // takes the setting too (two threads there: 4.6-5.1 s at 256x256).
    let phase = pipeline::stage_mut(&mut decl, PHASE.id)?;
    if !phase
        .params()
        .iter()
        .any(|p| p.key == PhaseParams::threads.name)
    {
        pipeline::put(
            phase,
            PhaseParams::threads,
            1usize,
            pipeline::by("calibrate (one thread a branch: the branches share the cores)"),
        )?;
    }
    shared_pyramid(decl.stage(PHASE)?, &mut pyr)?;
    pipeline::insert_before(&mut decl, PHASE.id, pyr)?;
    let branch = [PHASE.id, ALIGN.id, HIGHPASS.id, OUT.id];
    let originals: Vec<_> = branch
        .iter()
        .map(|id| pipeline::stage_mut(&mut decl, id).map(|s| s.clone()))
        .collect::<Result<_>>()?;
    if !whole {
        decl.stages.retain(|s| !branch.contains(&s.id.as_str()));
    }
    let temps: Vec<TempPath> = rows.iter().map(|_| TempPath::new("strip.wav")).collect();
    // With the region (calibrate), each strip's bands too, before `align`
    // chooses its polarity: their signs against the reference tell which
    // parts move against which ([`cal::Strips::bands`]).
    let band_temps: Vec<TempPath> = match whole {
        true => rows.iter().map(|_| TempPath::new("bands.csv")).collect(),
        false => Vec::new(),
    };
    let origin = pipeline::by("calibrate (a strip of rows)");
    for (k, (&(a, b), tmp)) in rows.iter().zip(&temps).enumerate() {
        for st in &originals {
            let mut c = st.clone();
            c.id = format!("{}_{k}", st.id);
            for i in &mut c.inputs {
                if branch.contains(&i.from.as_str()) {
                    i.from = format!("{}_{k}", i.from);
                }
            }
            decl.stages.push(c);
        }
        let roi = crate::pipeline::Roi {
            x: cols.0,
            y: a,
            w: cols.1,
            h: b - a,
        };
        pipeline::put(
            pipeline::stage_mut(&mut decl, &format!("{}_{k}", PHASE.id))?,
            PhaseParams::roi,
            Some(roi.param()),
            origin.clone(),
        )?;
        // The bands of a strip see its motion at one time: a lag chosen
        // per recording would move the strip's delay by whole samples
        // from one recording to the next, and the delays are reused.
        pipeline::put(
            pipeline::stage_mut(&mut decl, &format!("{}_{k}", ALIGN.id))?,
            AlignParams::max_lag,
            0,
            origin.clone(),
        )?;
        pipeline::put(
            pipeline::stage_mut(&mut decl, &format!("{}_{k}", OUT.id))?,
            WavParams::path,
            tmp.path().to_path_buf(),
            origin.clone(),
        )?;
        if let Some(b) = band_temps.get(k) {
            let mut sink = pipeline::new_stage::<CsvParams>(
                &format!("bands_{k}"),
                &[&format!("{}_{k}", PHASE.id)],
                origin.clone(),
            );
            pipeline::put(
                &mut sink,
                CsvParams::path,
                b.path().to_path_buf(),
                origin.clone(),
            )?;
            decl.stages.push(sink);
        }
    }
    let report = pipeline::run(&decl, run)?;
    let observed = match tiles.is_empty() {
        true => Vec::new(),
        false => read_observed(observed_temp.path())?,
    };
    let signals = temps
        .iter()
        .map(|t| Ok(crate::io::wav::read_mono(t.path())?.1))
        .collect::<Result<_>>()?;
    let whole = match whole {
        true => Some(crate::io::wav::read_mono(tmp0.path())?.1),
        false => None,
    };
    let bands = band_temps
        .iter()
        .map(|t| read_bands(t.path()))
        .collect::<Result<_>>()?;
    Ok(StripRun {
        whole,
        signals,
        bands,
        observed,
        report,
    })
}

/// Adds to `decl` a `displacement` stage on the listen pipeline's source
/// (what its phase stage reads) measuring each tile
/// of `tiles` (motion along x and y in px, mean intensity in DN; a tile
/// without texture reads no motion) and a CSV sink writing them to `csv`:
/// the recording's observables (the residual explainer's, and the
/// region's motion for the recovery's frame).
pub fn add_observe(
    decl: &mut crate::engine::config::PipelineDecl,
    tiles: &[[u32; 4]],
    csv: &Path,
) -> Result<()> {
    let source = decl
        .stage(PHASE)?
        .inputs
        .first()
        .map(|i| i.from.clone())
        .ok_or_else(|| Error::Analysis("the listen pipeline's phase stage has no input".into()))?;
    let origin = pipeline::by("calibration (the recording's observables)");
    let mut st = pipeline::new_stage::<DisplacementParams>("observe", &[&source], origin.clone());
    let v: Vec<u32> = tiles.iter().flatten().copied().collect();
    pipeline::put(&mut st, DisplacementParams::rois, Some(v), origin.clone())?;
    pipeline::put(&mut st, DisplacementParams::intensity, true, origin.clone())?;
    pipeline::put(
        &mut st,
        DisplacementParams::untextured,
        Untextured::Zero,
        origin.clone(),
    )?;
    decl.stages.push(st);
    let mut sink = pipeline::new_stage::<CsvParams>("observe_out", &["observe"], origin.clone());
    pipeline::put(&mut sink, CsvParams::path, csv.to_path_buf(), origin)?;
    decl.stages.push(sink);
    Ok(())
}

/// The channels [`add_observe`]'s CSV holds, three a tile.
pub fn read_observed(csv: &Path) -> Result<Vec<Vec<f64>>> {
    read_bands(csv)
}

/// The shared `pyramid` stage `pyr` builds the pyramid `phase` would: it
/// takes the phase stage's `pyramid`, `scales`, `orientations` and
/// `threads` where the phase stage sets them (in the phase stage's order,
/// each with its origin); the others keep their defaults, which are the
/// phase stage's.
fn shared_pyramid(phase: &StageDecl, pyr: &mut StageDecl) -> Result<()> {
    /// `pyr`'s `to` takes `phase`'s `from` when `p` is that parameter.
    fn copy<T: Serialize + DeserializeOwned>(
        (phase, p): (&StageDecl, &crate::engine::config::Param),
        from: Key<PhaseParams, T>,
        pyr: &mut StageDecl,
        to: Key<PyramidParams, T>,
    ) -> Result<()> {
        if p.key != from.name {
            return Ok(());
        }
        // A value not of its type is left out: the phase stage's own
        // validation names it.
        if let Some(v) = phase.get(from) {
            pipeline::put(pyr, to, v, p.origin.clone())?;
        }
        Ok(())
    }
    for p in phase.params() {
        let from = (phase, p);
        copy(from, PhaseParams::pyramid, pyr, PyramidParams::pyramid)?;
        copy(from, PhaseParams::scales, pyr, PyramidParams::scales)?;
        copy(
            from,
            PhaseParams::orientations,
            pyr,
            PyramidParams::orientations,
        )?;
        copy(from, PhaseParams::threads, pyr, PyramidParams::threads)?;
    }
    Ok(())
}

/// The channels of a `csv` sink's samples (`t_s,ch0,ch1,...`), one list
/// per channel.
fn read_bands(path: &Path) -> Result<Vec<Vec<f64>>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, e.to_string()))?;
    let mut bands: Vec<Vec<f64>> = Vec::new();
    for line in text.lines().skip(1) {
        for (c, v) in line.split(',').skip(1).enumerate() {
            let v: f64 = v
                .trim()
                .parse()
                .map_err(|_| Error::input(path, format!("not a number: {v:?}")))?;
            if bands.len() <= c {
                bands.push(Vec::new());
            }
            bands[c].push(v);
        }
    }
    Ok(bands)
}

/// What [`recover_observed`] recovered.
pub struct StripRun {
    /// The region's recovery, when asked for.
    pub whole: Option<Vec<f64>>,
    /// One signal per strip.
    pub signals: Vec<Vec<f64>>,
    /// Each strip's bands (`phase`'s channels), with the region only.
    pub bands: Vec<Vec<Vec<f64>>>,
    /// Each observed tile's motion along x and y (px) and mean intensity
    /// (DN), three channels a tile in the order asked.
    pub observed: Vec<Vec<f64>>,
    pub report: crate::engine::RunReport,
}

/// The listen pipeline calibrations are fitted on: the phase method, no
/// denoising, the causal high-pass; its WAV goes to `out`.
fn recovery_pipeline(
    video: &Path,
    out: &Path,
    fps: Option<f64>,
    region: &Region,
) -> Result<crate::engine::config::PipelineDecl> {
    let mut decl = listen_pipeline(video, out, fps, (region, Method::Phase), Denoise::None)?;
    crate::microphone::causal_highpass(&mut decl)?;
    Ok(decl)
}

/// A recovery calibrated against its reference.
pub struct Calibrated {
    /// The video's frame rate and the reference's sample rate (Hz).
    pub frame_rate_hz: f64,
    pub reference_rate_hz: f64,
    pub reference: Vec<f64>,
    pub calibration: Calibration,
}

/// What the object heard.
#[derive(Clone, Copy, Debug)]
pub enum ReferenceSource<'a> {
    /// A WAV file (first channel).
    Wav(&'a Path),
    /// A pure tone of this frequency (Hz), phase unknown.
    Tone(f64),
}

/// Highest tone `--reference-tone` accepts, Hz (beyond hearing; the tone
/// is synthesised at four times the higher of it and the frame rate, so
/// this also bounds its memory).
pub const MAX_TONE_HZ: f64 = 25_000.0;

/// A unit-peak tone at `hz` sampled at `rate` for `secs` (its phase is
/// what the delay fits).
fn tone(hz: f64, rate: f64, secs: f64) -> Vec<f64> {
    let n = (secs * rate).ceil() as usize;
    (0..n)
        .map(|i| (std::f64::consts::TAU * (hz * i as f64 / rate).fract()).sin())
        .collect()
}

/// Recovers `video` and calibrates it against `reference`, telling
/// `on_step` of each candidate effect as it is fitted (errors that are the
/// user's are [`Error::Input`] or [`Error::Usage`]).
pub fn calibrate_video(
    video: &Path,
    reference: &Path,
    fps: Option<f64>,
    region: &Region,
    opts: Option<Options>,
    run: RunSettings,
    on_step: Option<&StepHook>,
) -> Result<Calibrated> {
    calibrate_video_from(
        video,
        ReferenceSource::Wav(reference),
        fps,
        region,
        opts,
        run,
        on_step,
    )
}

/// [`calibrate_video`] against a WAV or a tone.
pub fn calibrate_video_from(
    video: &Path,
    reference: ReferenceSource<'_>,
    fps: Option<f64>,
    region: &Region,
    opts: Option<Options>,
    run: RunSettings,
    on_step: Option<&StepHook>,
) -> Result<Calibrated> {
    let reference = match reference {
        ReferenceSource::Wav(p) => p,
        ReferenceSource::Tone(hz) => {
            if !(hz.is_finite() && hz > 0.0 && hz <= MAX_TONE_HZ) {
                return Err(Error::usage(
                    "--reference-tone",
                    format!("must be a frequency above 0 and at most {MAX_TONE_HZ} Hz, got {hz}"),
                ));
            }
            let (fs, y, strips, observed) = recover_all(video, fps, region, opts.as_ref(), run)
                .map_err(Error::damaged_recording_as_input)?;
            // Sampled well above the frame rate and the tone (the model
            // samples it at the frame times, band-limited), a second
            // longer than the video (the delay is searched over ±0.5 s).
            let fr = (4.0 * fs.max(hz)).ceil();
            let r = tone(hz, fr, y.len() as f64 / fs + 1.0);
            return calibrate_recovery(video, (y, strips, observed), fs, r, fr, opts, on_step);
        }
    };
    let (fr, r) = read_input_wav(reference)?;
    if cal::check_silent(&r).is_err() {
        // Named here, before the recovery: the file is the user's mistake.
        return Err(Error::input(
            reference,
            "is silent (no sample above one 16-bit step): there is nothing to calibrate against",
        ));
    }
    let fs = frame_rate(video, fps)?;
    if fr < fs {
        return Err(Error::input(
            reference,
            format!(
                "sampled at {fr} Hz, below the video's frame rate of {fs} Hz: the reference must hold every frequency the camera can see"
            ),
        ));
    }
    let (fs, y, strips, observed) = recover_all(video, fps, region, opts.as_ref(), run)
        .map_err(Error::damaged_recording_as_input)?;
    let (dv, dr) = (y.len() as f64 / fs, r.len() as f64 / fr);
    if dr + 0.5 / fs < dv {
        return Err(Error::input(
            reference,
            format!(
                "{dr:.3} s long, shorter than the video {} ({dv:.3} s at {fs} Hz)",
                video.display()
            ),
        ));
    }
    calibrate_recovery(video, (y, strips, observed), fs, r, fr, opts, on_step)
}

/// What [`recover_all`] returns: the frame rate, the region's recovery,
/// the strips' (when read), the recording's observables and the region's
/// own motion in pixels (x, y).
type Recovered = (f64, Vec<f64>, Option<cal::Strips>, Observed);

/// The recording's observables for the explainer and the region's own
/// motion in pixels (x, y; empty when not measured).
#[derive(Default)]
struct Observed {
    covariates: Vec<cal::Covariate>,
    region_px: (Vec<f64>, Vec<f64>),
}

/// Most tiles across either axis of the frame the explainer observes.
pub const OBSERVED_TILES: u32 = 6;
/// The fewest pixels a tile's side holds.
const MIN_TILE_PX: u32 = 10;

/// The tiles of a `w`×`h` frame the residual explainer observes (up to
/// [`OBSERVED_TILES`] a side, at least [`MIN_TILE_PX`] each), each with
/// whether it overlaps the region `[x, y, w, h]`.
pub fn observation_tiles(w: u32, h: u32, region: [u32; 4]) -> Vec<([u32; 4], bool)> {
    let nx = (w / MIN_TILE_PX).clamp(1, OBSERVED_TILES);
    let ny = (h / MIN_TILE_PX).clamp(1, OBSERVED_TILES);
    let [rx, ry, rw, rh] = region;
    let mut out = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (x0, x1) = (i * w / nx, (i + 1) * w / nx);
            let (y0, y1) = (j * h / ny, (j + 1) * h / ny);
            let overlaps = x0 < rx + rw && rx < x1 && y0 < ry + rh && ry < y1;
            out.push(([x0, y0, x1 - x0, y1 - y0], overlaps));
        }
    }
    out
}

/// Most lines (rows, and columns) observed across the region on either
/// axis; a region taller (wider) is observed in bands of rows (columns).
pub const OBSERVED_LINES: u32 = 64;
/// The fewest pixels a line's part holds, beside the pixels the
/// `displacement` stage leaves out at the frame's edge.
const MIN_LINE_PX: u32 = 8;

/// The sensor's lines the residual explainer observes in a `w`×`h` frame
/// around the region `[x, y, w, h]`: each row crossing the region (a band
/// of rows when the region has more than [`OBSERVED_LINES`]), in its parts
/// left and right of the region, and each column crossing it, above and
/// below; a part narrower than [`MIN_LINE_PX`] (after the frame's edge) is
/// left out, so a region as wide as the frame has no rows observed.
pub fn observation_lines(w: u32, h: u32, region: [u32; 4]) -> Vec<([u32; 4], cal::Observable)> {
    let edge = crate::stages::transform::displacement::MARGIN as u32;
    let [rx, ry, rw, rh] = region;
    let mut out = Vec::new();
    // Along rows (`along` the frame's width) or columns.
    for (obs, (lo, len, full), (a, b, other)) in [
        (cal::Observable::RowIntensity, (ry, rh, h), (rx, rw, w)),
        (cal::Observable::ColumnIntensity, (rx, rw, w), (ry, rh, h)),
    ] {
        let band = len.div_ceil(OBSERVED_LINES).max(1);
        let (start, end) = (lo.max(edge), (lo + len).min(full.saturating_sub(edge)));
        let before = a >= edge + MIN_LINE_PX;
        let after = other >= a + b + edge + MIN_LINE_PX;
        let mut k = start;
        while k + band <= end {
            let parts = [
                before.then_some((0, a)),
                after.then_some((a + b, other - a - b)),
            ];
            for (p0, plen) in parts.into_iter().flatten() {
                out.push((
                    match obs {
                        cal::Observable::RowIntensity => [p0, k, plen, band],
                        _ => [k, p0, band, plen],
                    },
                    obs,
                ));
            }
            k += band;
        }
    }
    out
}

/// The region's recovery `(frame rate, samples)` and, when the effects to
/// try include the capture time or the region gain (the default) and the
/// region has rows enough for three strips, the strips' recoveries and
/// bands from the same run.
fn recover_all(
    video: &Path,
    fps: Option<f64>,
    region: &Region,
    opts: Option<&Options>,
    run: RunSettings,
) -> Result<Recovered> {
    let wanted = |o: &Options| {
        o.effects
            .iter()
            .any(|k| matches!(k, EffectKind::CaptureTime | EffectKind::RegionGain))
    };
    if opts.is_none_or(wanted) {
        let layout = strip_rows(video, region)?;
        if layout.rows.len() >= 3 {
            let fs = frame_rate(video, fps)?;
            let rect = layout.region();
            let (mut tiles, lines) = match opts.is_none_or(|o| o.explain) {
                true => (
                    observation_tiles(layout.width, layout.height, rect),
                    observation_lines(layout.width, layout.height, rect),
                ),
                false => (Vec::new(), Vec::new()),
            };
            tiles.extend(lines.iter().map(|l| (l.0, false)));
            // The region itself, last: its motion in pixels is the
            // recovery's physical frame.
            tiles.push((rect, true));
            let rects: Vec<[u32; 4]> = tiles.iter().map(|t| t.0).collect();
            let StripRun {
                whole,
                signals,
                bands,
                observed,
                ..
            } = recover_observed(
                video,
                fps,
                region,
                (layout.cols, &layout.rows),
                (true, &rects),
                run,
            )?;
            let y =
                whole.ok_or_else(|| Error::Analysis("the region's recovery is missing".into()))?;
            let strips = cal::Strips {
                rows: layout.rows,
                signals,
                bands,
            };
            let lines: Vec<cal::Observable> = lines.iter().map(|l| l.1).collect();
            return Ok((fs, y, Some(strips), observations(&tiles, &lines, observed)));
        }
    }
    let (fs, y) = recover(video, fps, region, run)?;
    Ok((fs, y, None, Observed::default()))
}

/// The observed channels (three a tile: x, y, intensity) as the
/// explainer's candidates, the last tile's (the region's) motion apart:
/// `tiles` ends with one rectangle for each of `lines` (their intensity
/// only, as that line's observable), then the region's.
fn observations(
    tiles: &[([u32; 4], bool)],
    lines: &[cal::Observable],
    mut observed: Vec<Vec<f64>>,
) -> Observed {
    let n_tiles = tiles.len().saturating_sub(lines.len() + 1);
    use cal::Observable::{Intensity, MotionX, MotionY};
    let mut out = Observed::default();
    if observed.len() == 3 * tiles.len() && !tiles.is_empty() {
        let _intensity = observed.pop();
        let py = observed.pop().unwrap_or_default();
        let px = observed.pop().unwrap_or_default();
        out.region_px = (px, py);
    }
    for (k, values) in observed.into_iter().enumerate() {
        let Some(&(rect, inside)) = tiles.get(k / 3) else {
            break;
        };
        let observable = match (k / 3).checked_sub(n_tiles) {
            None => [MotionX, MotionY, Intensity][k % 3],
            Some(l) if k % 3 == 2 => match lines.get(l) {
                Some(&o) => o,
                None => break,
            },
            Some(_) => continue,
        };
        out.covariates.push(cal::Covariate {
            observable,
            rect,
            inside,
            values,
        });
    }
    out
}

/// The motion (x, y in pixels) of each observed tile overlapping the
/// region, from the explainer's observables: where the recovery's frame
/// reads the object's motion ([`cal::pixel_frame_on_tiles`]).
fn region_tiles(covs: &[cal::Covariate]) -> Vec<(&[f64], &[f64])> {
    let of = |rect: [u32; 4], o: cal::Observable| {
        covs.iter()
            .find(|c| c.inside && c.rect == rect && c.observable == o)
            .map(|c| c.values.as_slice())
    };
    covs.iter()
        .filter(|c| c.inside && c.observable == cal::Observable::MotionX)
        .filter_map(|c| Some((c.values.as_slice(), of(c.rect, cal::Observable::MotionY)?)))
        .collect()
}

/// How the recovery's `phase` stage renews its reference at `fs`,
/// `(interval, overlap)` in frames ([`Options::renewal`]): its defaults,
/// which the recovery pipelines keep; `None` when it never renews.
pub fn recovery_renewal(fs: f64) -> Option<(usize, usize)> {
    let s: f64 = PhaseParams::reference_interval_s.default_value()?;
    let o: usize = PhaseParams::reference_overlap.default_value()?;
    (s > 0.0 && fs.is_finite()).then(|| (((s * fs).round() as usize).max(1), o))
}

/// The farthest lag (frames) by which the recovery's `align` stage shifts
/// a band ([`Options::line_reach`]): its default, which the recovery
/// pipelines keep.
pub fn recovery_reach() -> usize {
    AlignParams::max_lag.default_value().unwrap_or(0)
}

/// The math on a recovery `y` (at `fs`) against `r` (at `fr`).
fn calibrate_recovery(
    video: &Path,
    (y, strips, observed): (Vec<f64>, Option<cal::Strips>, Observed),
    fs: f64,
    r: Vec<f64>,
    fr: f64,
    opts: Option<Options>,
    on_step: Option<&StepHook>,
) -> Result<Calibrated> {
    let opts = Options {
        renewal: recovery_renewal(fs),
        line_reach: recovery_reach(),
        ..opts.unwrap_or_else(|| Options::for_rate(fs))
    };
    let mut hook = |s: Step| {
        if let Some(h) = on_step {
            (h.0)(s)
        }
    };
    let covs = &observed.covariates;
    let c = cal::calibrate_with(&y, (strips.as_ref(), covs), fs, (&r, fr), &opts, &mut hook);
    // A signal during the fit wins over what the fit concluded (a refusal
    // included): the user asked to stop.
    pipeline::check_interrupt()?;
    let mut c = c.map_err(|e| Error::input(video, e.to_string()))?;
    let (px, py) = &observed.region_px;
    let tiles = region_tiles(&observed.covariates);
    c.report.pixel_frame = cal::pixel_frame_on_tiles(&y, (px, py), &tiles, fs, opts.highpass, None);
    Ok(Calibrated {
        frame_rate_hz: fs,
        reference_rate_hz: fr,
        reference: r,
        calibration: c,
    })
}

/// Runs `calibrate`: writes the report (and the corrected recovery).
pub fn calibrate(o: &CalibrateOptions) -> Result<CalibrationReport> {
    let _steps = pipeline::Steps::begin();
    let mut inputs = vec![o.video.as_path()];
    if o.reference_tone_hz.is_none() {
        inputs.push(o.reference.as_path());
    }
    inputs.extend(o.region.mask.as_deref());
    let mut outputs = vec![o.json.as_path()];
    outputs.extend(o.output.as_deref());
    crate::error::check_outputs(&inputs, &outputs)?;
    let opts = match (&o.effects, frame_rate(&o.video, o.fps)) {
        (Some(e), Ok(fs)) => Some(Options {
            effects: e.clone(),
            ..Options::for_rate(fs)
        }),
        _ => None,
    };
    let Calibrated {
        frame_rate_hz: fs,
        reference_rate_hz: fr,
        reference: r,
        calibration: c,
    } = calibrate_video_from(
        &o.video,
        match o.reference_tone_hz {
            Some(hz) => ReferenceSource::Tone(hz),
            None => ReferenceSource::Wav(&o.reference),
        },
        o.fps,
        &o.region,
        opts,
        o.run,
        o.on_step.as_ref(),
    )?;
    // Where a kept transfer table was not measured (above the highest
    // frequency the reference reached).
    let mut notes: Vec<String> = c
        .corrections
        .iter()
        .filter_map(|k| k.unmeasured(fs))
        .collect();
    if let Some(hz) = o.reference_tone_hz {
        if let Some(cal::Parameters::TimeBase {
            clock_error_ppm,
            true_fps,
            ..
        }) = c
            .report
            .effects
            .iter()
            .find(|e| e.name == "time_base")
            .map(|e| &e.parameters)
        {
            notes.push(format!(
                "against a tone, a clock error and the tone's own pitch are one parameter: either the tone was at {:.4} Hz on the declared {fs} fps, or the camera ran at {true_fps:.4} fps and the tone was at {hz} Hz (a second, independent reference would tell them apart)",
                hz * (1.0 - clock_error_ppm * 1e-6)
            ));
        }
    }
    // One report: what is not serialised (rejected candidates, files
    // written) rides along for the terminal.
    let mut report = CalibrationReport {
        report: c.report,
        delay_s: c.delay_s,
        gain: c.gain,
        rejected: c
            .rejected
            .iter()
            .map(|e| (e.name.to_string(), e.snr_gain_db, e.parameters.clone()))
            .collect(),
        written: Vec::new(),
        reference_tone_hz: o.reference_tone_hz,
        notes,
    };
    crate::json::write(&o.json, &report)?;
    if let Some(out) = &o.output {
        // Reference time of corrected sample n is n / fs - delay.
        let end = c.corrected.len() as f64 / fs - c.delay_s;
        let count = ((end * fr).floor().max(0.0) as usize).min(r.len());
        let x = cal::sample_at(
            &c.corrected,
            fs,
            (0..count).map(|k| k as f64 / fr + c.delay_s),
        );
        crate::io::wav::write_mono_f32(out, fr as u32, &x)?;
        report.written.push(out.clone());
    }
    report.written.push(o.json.clone());
    Ok(report)
}
