//! Motion spectrum of a video (thesis Eq. 3.17) and its resonances: the
//! shipped live-spectrum graph on a recording, one whole-recording spectrum
//! (finest resolution) feeding the engine's `peaks` sink, plus time-domain
//! damping (SSI-cov, [`crate::damping`]) on the extracted motion.
//!
//! The `peaks` sink is the engine's only path to the peaks, and it writes
//! JSON: [`run_spectrum`] reads that document back once, here, into the
//! typed [`SpectrumReport`]; every other recipe (`rod`, `compare`) and the
//! damping refinement work on that value in memory.

use crate::damping::MotionTap;
use crate::engine::config::{PipelineDecl, StageDecl};
use crate::engine::spec::{Key, KindParams};
use crate::engine::RunReport;
use crate::error::Result;
use crate::io::atomic::TempPath;
pub use crate::math::stft::stft;
pub use crate::peaks::SpectrumReport;
use crate::pipeline::{self, by, put, BandFilter, PipelineOptions, Region, Roi, RunSettings};
use crate::pipelines::stage::live_spectrum::{OUT, PHASE, SPECTRUM};
use crate::stages::params::{PeaksParams, PhaseParams, SpectrumParams, SpectrumPngParams};
use crate::stages::sinks::spectrum_png::Style;
use crate::stages::transform::phase::Normalise;
use crate::stages::transform::spectrum::{Combine as CombineParam, Mode};
use crate::units::{Quantity, Scale, ScaleArg};
use std::path::{Path, PathBuf};

/// The spectrogram's default window in frames.
pub const SPECTROGRAM_WINDOW: usize = 256;

/// What `spectrum` is asked.
#[derive(Clone, Debug)]
pub struct SpectrumOptions {
    pub video: PathBuf,
    /// Render this scene file through the forward model instead of reading
    /// `video`: the frames `vibroscope simulate` would write (bit for bit),
    /// with no file between.
    pub scene: Option<PathBuf>,
    /// Output JSON: sample_rate_hz, resolution_hz and the peaks.
    pub json: PathBuf,
    pub fps: Option<f64>,
    /// At most this many peaks (the most prominent).
    pub peaks: usize,
    pub region: Region,
    /// Welch segments over the recording.
    pub segments: Option<usize>,
    /// Segment length in frames instead of `segments`.
    pub window: Option<usize>,
    /// Only peaks in this band (Hz).
    pub min_hz: Option<f64>,
    pub max_hz: Option<f64>,
    /// Only peaks that noise alone would put this high anywhere in the band
    /// with at most this probability; 1 reports every prominent peak.
    pub false_alarm: f64,
    /// Also write the spectrum (dB) into the JSON.
    pub include_spectrum: bool,
    /// Also plot the spectrum to this PNG.
    pub png: Option<PathBuf>,
    /// Also plot a spectrogram to this PNG.
    pub spectrogram: Option<PathBuf>,
    pub spectrogram_window: usize,
    /// Keep the extracted motion the SSI-cov damping ran on, as a WAV.
    pub motion_wav: Option<PathBuf>,
    /// Pixels to millimetres (`--scale`, `--known-length`); none: pixels.
    pub scale: Option<ScaleArg>,
    /// Report displacement, velocity or acceleration amplitudes.
    pub quantity: Quantity,
    /// Export each region's waveform and amplitude spectrum (CSV + PNG)
    /// named after this path (see [`crate::motion::waveform_paths`]).
    pub waveform: Option<PathBuf>,
    /// The regions of the waveforms (default: `region`'s rectangle, or
    /// the whole frame); measured in the same pass as the spectrum.
    pub regions: Vec<Roi>,
    /// Filters applied to the waveforms and the UFF export (zero-phase),
    /// in order.
    pub filters: Vec<BandFilter>,
    /// Export the regions' motion (time responses of `quantity` and their
    /// amplitude spectra, a node per region) as a Universal File (UFF 58
    /// and 15) at this path (see [`crate::motion::write_uff`]).
    pub uff: Option<PathBuf>,
    /// Cut the region into `tiles` x `tiles` local regions whose power
    /// spectra are added (Eq. 3.17's local signals; the `phase` stage's
    /// `tiles`). 1: the power of the region's mean motion. With more, the
    /// spectrum's shape is what counts: a peak's amplitude is then not the
    /// region's displacement.
    pub tiles: usize,
    /// How the channels (bands, tiles) make one spectrum: `Snr` weighs
    /// each by how far it stands out of its own noise floor (the
    /// `spectrum` stage's `combine`), `Sum` adds them (Eq. 3.17).
    pub combine: Combine,
    /// With `tiles`: what each tile's and band's signal is divided by (the
    /// `phase` stage's `normalise`).
    pub normalise: PhaseNormalise,
    pub run: RunSettings,
}

/// What the `phase` stage divides each tile's and band's signal by (its
/// `normalise`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PhaseNormalise {
    /// Its own tile's and band's A²: every tile and band counts alike.
    Channel,
    /// Its own tile's A² over all bands: every tile counts alike, the
    /// bands keep their relative weights within it.
    Tile,
    /// The region's total A²: tiles and bands keep their relative weights.
    Region,
}

impl PhaseNormalise {
    /// The `phase` stage's value.
    pub fn param(self) -> Normalise {
        match self {
            PhaseNormalise::Channel => Normalise::Channel,
            PhaseNormalise::Tile => Normalise::Tile,
            PhaseNormalise::Region => Normalise::Region,
        }
    }
}

/// How the channels' spectra make one (the `spectrum` stage's `combine`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Combine {
    /// Each channel scaled to its noise floor, weighted by its excess over
    /// it: noise-only bands and tiles add nothing.
    #[default]
    Snr,
    /// The channels' power spectra added (Eq. 3.17).
    Sum,
}

impl Combine {
    pub fn name(self) -> &'static str {
        match self {
            Combine::Snr => "snr",
            Combine::Sum => "sum",
        }
    }

    /// The `spectrum` stage's value.
    pub fn param(self) -> CombineParam {
        match self {
            Combine::Snr => CombineParam::Snr,
            Combine::Sum => CombineParam::Sum,
        }
    }
}

impl SpectrumOptions {
    /// Defaults for `video`, writing `json`.
    pub fn new(video: impl Into<PathBuf>, json: impl Into<PathBuf>) -> SpectrumOptions {
        SpectrumOptions {
            video: video.into(),
            scene: None,
            json: json.into(),
            fps: None,
            peaks: 5,
            region: Region::default(),
            segments: None,
            window: None,
            min_hz: None,
            false_alarm: crate::math::peaks::DEFAULT_FALSE_ALARM,
            max_hz: None,
            include_spectrum: false,
            png: None,
            spectrogram: None,
            spectrogram_window: SPECTROGRAM_WINDOW,
            motion_wav: None,
            scale: None,
            quantity: Quantity::Displacement,
            waveform: None,
            uff: None,
            regions: Vec::new(),
            filters: Vec::new(),
            tiles: 1,
            combine: Combine::default(),
            normalise: PhaseNormalise::Region,
            run: RunSettings::default(),
        }
    }
}

/// The spectrum graph for `o`, its peaks written to `json`.
pub fn spectrum_pipeline(o: &SpectrumOptions, json: &Path) -> Result<PipelineDecl> {
    let mut decl = pipeline::prepare(&PipelineOptions {
        pipeline: "live-spectrum".into(),
        set: Vec::new(),
        replay: o.scene.is_none().then(|| o.video.clone()),
        fps: None,
    })?;
    if let Some(scene) = &o.scene {
        pipeline::apply_scene(&mut decl, &pipeline::SceneFile::read(scene)?)?;
    }
    if let Some(f) = o.fps {
        pipeline::apply_fps(&mut decl, f)?;
    }
    o.region.apply(&mut decl, PHASE)?;
    pipeline::set(&mut decl, PHASE, PhaseParams::scales, 4, by("spectrum"))?;
    pipeline::set(&mut decl, PHASE, PhaseParams::block, 64, by("spectrum"))?;
    if o.tiles > 1 {
        pipeline::set(
            &mut decl,
            PHASE,
            PhaseParams::tiles,
            pipeline::count(o.tiles),
            by("tiles"),
        )?;
    }
    if o.normalise != PhaseNormalise::Region {
        let v = o.normalise.param();
        pipeline::set(&mut decl, PHASE, PhaseParams::normalise, v, by("normalise"))?;
    }
    let st = decl.stage_mut(SPECTRUM)?;
    st.unset(SpectrumParams::window);
    st.unset(SpectrumParams::hop);
    st.unset(SpectrumParams::welch);
    pipeline::set(
        &mut decl,
        SPECTRUM,
        SpectrumParams::mode,
        Mode::Whole,
        by("spectrum"),
    )?;
    let combine = o.combine.param();
    pipeline::set(
        &mut decl,
        SPECTRUM,
        SpectrumParams::combine,
        combine,
        by("--combine"),
    )?;
    if let Some(k) = o.segments {
        pipeline::set(
            &mut decl,
            SPECTRUM,
            SpectrumParams::segments,
            Some(pipeline::count(k)),
            by("--segments"),
        )?;
    }
    if let Some(w) = o.window {
        pipeline::set(
            &mut decl,
            SPECTRUM,
            SpectrumParams::window,
            Some(pipeline::count(w)),
            by("--window"),
        )?;
    }
    pipeline::set(
        &mut decl,
        OUT,
        PeaksParams::path,
        json.to_path_buf(),
        by("--json"),
    )?;
    pipeline::set(
        &mut decl,
        OUT,
        PeaksParams::peaks,
        pipeline::count(o.peaks),
        by("--peaks"),
    )?;
    let fa = o.false_alarm;
    pipeline::set(
        &mut decl,
        OUT,
        PeaksParams::false_alarm,
        fa,
        by("--false-alarm"),
    )?;
    let file = decl.file.clone();
    band(
        decl.stage_mut(OUT)?,
        &file,
        PeaksParams::min_hz,
        PeaksParams::max_hz,
        o,
    )?;
    if o.include_spectrum {
        let origin = by("--include-spectrum");
        pipeline::set(&mut decl, OUT, PeaksParams::include_spectrum, true, origin)?;
    }
    add_plots(&mut decl, o)?;
    Ok(decl)
}

/// Sets `o`'s band (`--min-hz`, `--max-hz`) as `min` and `max` of `st`
/// (`file` names the pipeline in errors).
fn band<K: KindParams>(
    st: &mut StageDecl,
    file: &str,
    min: Key<K, Option<f64>>,
    max: Key<K, Option<f64>>,
    o: &SpectrumOptions,
) -> Result<()> {
    if let Some(f) = o.min_hz {
        st.set(file, min, Some(f), by("--min-hz"))?;
    }
    if let Some(f) = o.max_hz {
        st.set(file, max, Some(f), by("--max-hz"))?;
    }
    Ok(())
}

/// Adds `spectrogram_spectrum` -> `spectrogram` (sliding spectra from
/// `phase`). The `--png` plot is drawn after the run, from the measured
/// displacement ([`amplitude_png`]), since its axis carries the unit.
fn add_plots(decl: &mut PipelineDecl, o: &SpectrumOptions) -> Result<()> {
    let spec = pipeline::position(decl, SPECTRUM.id)?;
    if let Some(p) = &o.spectrogram {
        let flag = "--spectrogram-window";
        let mut sp = decl.stages[spec].clone();
        sp.id = "spectrogram_spectrum".into();
        sp.clear_params();
        let w = pipeline::count(o.spectrogram_window);
        put(
            &mut sp,
            SpectrumParams::mode,
            Mode::Sliding,
            by("--spectrogram"),
        )?;
        put(&mut sp, SpectrumParams::window, Some(w), by(flag))?;
        put(&mut sp, SpectrumParams::hop, Some((w / 8).max(1)), by(flag))?;
        decl.stages.push(sp);
        let mut st = pipeline::new_stage::<SpectrumPngParams>(
            "spectrogram",
            &["spectrogram_spectrum"],
            by("--spectrogram"),
        );
        put(
            &mut st,
            SpectrumPngParams::path,
            p.clone(),
            by("--spectrogram"),
        )?;
        let style = Style::Spectrogram;
        put(
            &mut st,
            SpectrumPngParams::style,
            style,
            by("--spectrogram"),
        )?;
        let (min, max) = (SpectrumPngParams::min_hz, SpectrumPngParams::max_hz);
        band(&mut st, "vibroscope", min, max, o)?;
        decl.stages.push(st);
    }
    Ok(())
}

/// Runs the spectrum graph (peaks into a scratch file, read back once into
/// the typed report) and, with `damping`, the SSI-cov refinement.
pub fn run_spectrum(o: &SpectrumOptions, damping: bool) -> Result<(SpectrumReport, RunReport)> {
    run_spectrum_with(o, damping, None)
}

/// [`run_spectrum`], and with `disp` the regions' displacement too (one
/// pass): the studio's region view reads the waveform and the peaks of one
/// run this way.
pub fn run_spectrum_with(
    o: &SpectrumOptions,
    damping: bool,
    disp: Option<&DisplacementTap>,
) -> Result<(SpectrumReport, RunReport)> {
    let tmp = TempPath::new("peaks.json");
    let mut decl = spectrum_pipeline(o, tmp.path())?;
    let tap = if damping {
        Some(MotionTap::add(&mut decl, o.motion_wav.clone())?)
    } else {
        None
    };
    if let Some(d) = disp {
        d.add(&mut decl)?;
    }
    let run = pipeline::run(&decl, o.run).map_err(|e| {
        // A scene's mistakes are told against its file, not the graph's source.
        match (&o.scene, pipeline::source_id(&decl)) {
            (Some(p), Some(src)) => match pipeline::SceneFile::read(p) {
                Ok(f) => f.told(e, src),
                Err(_) => e,
            },
            _ => e,
        }
    })?;
    let mut report: SpectrumReport = crate::json::read(tmp.path(), "the peaks document")?;
    report.combine = Some(o.combine.name());
    if let Some(tap) = tap {
        tap.refine(&mut report, &Default::default())?;
    }
    Ok((report, run))
}

/// Refuses outputs that are an input or cannot be written, before the run.
pub fn check_outputs(o: &SpectrumOptions) -> Result<()> {
    let mut inputs = vec![o.video.as_path()];
    inputs.extend(o.region.mask.as_deref());
    let mut outputs: Vec<PathBuf> = outputs(o).cloned().collect();
    if let Some(base) = &o.waveform {
        let n = o.regions.len().max(1);
        for k in 1..=n {
            outputs.extend(crate::motion::waveform_paths(base, k, n));
        }
    }
    outputs.extend(o.uff.iter().cloned());
    let outputs: Vec<&Path> = outputs.iter().map(PathBuf::as_path).collect();
    crate::error::check_outputs(&inputs, &outputs)
}

/// The files `spectrum` writes: the JSON, then the optional plots and WAV.
fn outputs(o: &SpectrumOptions) -> impl Iterator<Item = &PathBuf> {
    [
        Some(&o.json),
        o.png.as_ref(),
        o.spectrogram.as_ref(),
        o.motion_wav.as_ref(),
    ]
    .into_iter()
    .flatten()
}

/// Runs `spectrum`: writes the JSON (and the plots).
pub fn spectrum(o: &SpectrumOptions) -> Result<(SpectrumReport, RunReport)> {
    let scale = resolve_scale(&o.video, o.fps, o.scale.as_ref())?;
    check_outputs(o)?;
    if o.scene.is_none() && !o.regions.is_empty() {
        let rois: Vec<[u32; 4]> = o.regions.iter().map(|r| [r.x, r.y, r.w, r.h]).collect();
        crate::motion::check_regions(&o.video, o.fps, &rois, "--region")?;
    }
    // Region 0 is the spectrum's own (its peaks' amplitudes); the
    // waveforms' regions follow, all in one `displacement` stage.
    let whole = |r: &Roi| [r.x, r.y, r.w, r.h];
    let first = o.region.roi.as_ref().map(whole);
    let mut rois: Vec<[u32; 4]> = Vec::new();
    if !o.regions.is_empty() || first.is_some() {
        let first = match first {
            Some(r) => r,
            None => {
                let p = crate::probe::probe(&o.video, o.fps)?;
                [0, 0, p.width, p.height]
            }
        };
        rois.push(first);
        rois.extend(o.regions.iter().map(whole));
    }
    let disp = DisplacementTap::new(rois).with_mask(o.region.mask.clone());
    let (mut report, run) = run_spectrum_with(o, true, Some(&disp))?;
    let mut regions = disp.read()?;
    if let Some(r) = regions.first() {
        let freqs: Vec<f64> = report.peaks.iter().map(|p| p.frequency_hz).collect();
        let (amps, summary) = crate::motion::peak_amplitudes(
            &freqs,
            report.resolution_hz,
            r,
            scale.as_ref(),
            o.quantity,
        );
        for (p, a) in report.peaks.iter_mut().zip(amps) {
            p.amplitude = Some(a);
        }
        if let Some(png) = &o.png {
            amplitude_png(png, o, r, &report, &summary, scale.as_ref())?;
        }
        report.motion = Some(summary);
    }
    // Region 0 was the spectrum's own: the exports have their --region.
    if (o.waveform.is_some() || o.uff.is_some()) && !o.regions.is_empty() {
        regions.remove(0);
    }
    if let Some(base) = &o.waveform {
        report.waveforms =
            crate::motion::write_waveforms(&regions, base, scale.as_ref(), o.quantity, &o.filters)?;
    }
    if let Some(path) = &o.uff {
        // The whole frame's node is at its centre.
        let frame = if regions.iter().all(|r| r.roi.is_some()) {
            (0, 0)
        } else {
            let p = crate::probe::probe(&o.video, o.fps)?;
            (p.width, p.height)
        };
        report.uff = Some(crate::motion::write_uff(
            &regions,
            frame,
            path,
            &o.video,
            scale.as_ref(),
            o.quantity,
            &o.filters,
        )?);
    }
    crate::json::write(&o.json, &report)?;
    report.written = outputs(o).cloned().collect();
    report.written.extend(o.uff.iter().cloned());
    for w in &report.waveforms {
        report
            .written
            .extend([&w.csv, &w.png, &w.spectrum_csv, &w.spectrum_png].map(PathBuf::clone));
    }
    Ok((report, run))
}

/// The `--png` plot: the amplitude spectrum of the quantity asked in region
/// `r` (x and y in quadrature, as the peaks' amplitudes) in the report's
/// unit on a logarithmic axis, each peak marked with its frequency and
/// amplitude.
fn amplitude_png(
    path: &Path,
    o: &SpectrumOptions,
    r: &crate::motion::RegionMotion,
    report: &SpectrumReport,
    summary: &crate::motion::MotionSummary,
    scale: Option<&Scale>,
) -> Result<()> {
    let (amp, df) = crate::math::amplitude::amplitude_spectrum(&[&r.x, &r.y], r.rate_hz);
    let k = crate::units::px_to(summary.unit, scale);
    let q: Vec<f64> = amp
        .iter()
        .enumerate()
        .map(|(i, &a)| a * o.quantity.gain(i as f64 * df) * k)
        .collect();
    let unit = summary.unit;
    let peaks: Vec<(f64, f64, String)> = report
        .peaks
        .iter()
        .filter_map(|p| {
            let a = p.amplitude?;
            Some((
                p.frequency_hz,
                a,
                format!("{:.1} Hz, {} {unit}", p.frequency_hz, sig3(a)),
            ))
        })
        .collect();
    let band = (o.min_hz.unwrap_or(0.0), o.max_hz.unwrap_or(r.rate_hz / 2.0));
    let name = match r.roi {
        Some([x, y, w, h]) => format!("region ({x},{y},{w},{h})"),
        None => "whole frame".to_string(),
    };
    let q_name = o.quantity.name();
    crate::motion::write_png(
        path,
        crate::io::plot::amplitude_plot(
            &q,
            df,
            band,
            &peaks,
            &format!("{q_name} amplitude spectrum, {name}"),
            &format!("{q_name} amplitude ({unit})"),
            (900, 450),
        ),
    )
}

/// `v` with three significant digits.
fn sig3(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

/// The scale of `arg` for `video` (its frame size read when points are
/// given): a usage error naming the flag when it is wrong.
pub fn resolve_scale(
    video: &Path,
    fps: Option<f64>,
    arg: Option<&ScaleArg>,
) -> Result<Option<Scale>> {
    let Some(arg) = arg else {
        return Ok(None);
    };
    let (w, h) = match arg {
        ScaleArg::MmPerPx(_) => (u32::MAX, u32::MAX),
        ScaleArg::KnownLength(_) => {
            let p = crate::probe::probe(video, fps)?;
            (p.width, p.height)
        }
    };
    Ok(Some(arg.resolve(w, h)?))
}

pub use crate::motion::DisplacementTap;
