//! `vibroscope spectrum`.

use super::{UnitArgs, VideoArgs};
use std::path::PathBuf;
use std::process::ExitCode;
use vibroscope::pipeline::BandFilter;
use vibroscope::pipeline::{short, RunSettings};
use vibroscope::spectrum::{self, SpectrumOptions, SpectrumReport, SPECTROGRAM_WINDOW};
use vibroscope::units::Quantity;

/// Motion spectrum of a video and its resonances (frequency, damping, strength).
///
/// Motion spectrum of a video (thesis Eq. 3.17) and its resonances:
/// frequency, damping ratio with its uncertainty and method, power and
/// prominence of each peak, as JSON.
#[derive(clap::Args, Clone)]
#[command(after_help = "Examples:\n  \
    vibroscope spectrum ../shared/data/guitar.mp4 --fps 600 -o guitar.json\n  \
    vibroscope spectrum beam.y4m --json beam.json --peaks 3 --roi 0,0,64,64\n  \
    vibroscope spectrum beam.y4m -o beam.json --uff beam.uff --region 0,0,32,32 --region 32,0,32,32")]
pub struct Args {
    #[command(flatten)]
    pub spectrum: SpectrumArgs,
    #[command(flatten)]
    pub units: UnitArgs,
    /// Report the peaks' amplitudes as displacement, velocity (ω·X) or
    /// acceleration (ω²·X), in px/s... or, with a scale, µm/s, mm/s², ...
    #[arg(long, value_enum, default_value = "displacement")]
    pub quantity: QuantityArg,
    /// Also write each region's motion: OUT.csv (t_s, x and y displacement
    /// in px, µm or mm), OUT.png (its plot), OUT.spectrum.csv and
    /// OUT.spectrum.png (amplitude spectrum of --quantity); with several
    /// --region, OUT.roi1.csv, OUT.roi2.csv, ... (the list is printed).
    #[arg(long, value_name = "OUT.csv")]
    pub waveform: Option<PathBuf>,
    /// Also write each region's motion as a Universal File (UFF, ASCII):
    /// a node per region at its centre (data set 15; image axes, +x
    /// right, +y down; mm with a scale, else px; data set 164 says mm),
    /// and per region and axis the time response of --quantity and its
    /// amplitude spectrum (data sets 58; node k is region k, direction 1
    /// is +x, 2 is +y). pyuff, ME'scope and most modal tools read it.
    #[arg(long, value_name = "OUT.uff")]
    pub uff: Option<PathBuf>,
    /// A region for --waveform and --uff, X,Y,W,H in pixels; repeat for several
    /// (all measured in the same pass; default: the --roi, or the whole frame).
    #[arg(long = "region", value_name = "X,Y,W,H", value_parser = super::parse_roi, action = clap::ArgAction::Append)]
    pub regions: Vec<vibroscope::pipeline::Roi>,
    /// Band-pass the --waveform and --uff exports to LO,HI Hz (zero-phase
    /// Butterworth, as listen --band); the peaks are not filtered.
    #[arg(long, value_name = "LO,HI", value_parser = parse_band, action = clap::ArgAction::Append)]
    pub band: Vec<BandFilter>,
    /// Take out F Hz (band-stop F-WIDTH/2..F+WIDTH/2, WIDTH default F/10)
    /// from the --waveform and --uff exports; repeat for several.
    #[arg(long, value_name = "F[,WIDTH]", value_parser = parse_notch, action = clap::ArgAction::Append)]
    pub notch: Vec<BandFilter>,
    /// Print the per-stage summary at exit.
    #[arg(long)]
    pub stats: bool,
}

/// The spectrum's flags (shared with `rod`).
#[derive(clap::Args, Clone)]
pub struct SpectrumArgs {
    /// The recording (.y4m, .cine, .mraw/.cih, or anything ffmpeg reads).
    pub video: PathBuf,
    /// Output JSON (the main output; also spelled --json).
    #[arg(
        short = 'o',
        long = "json",
        visible_alias = "output",
        value_name = "OUT.json"
    )]
    pub json: PathBuf,
    #[command(flatten)]
    pub video_args: VideoArgs,
    /// Report at most this many peaks (the most prominent).
    #[arg(long, default_value_t = 5, value_name = "N")]
    pub peaks: usize,
    /// Welch segments over the recording (more: less noise, coarser bins;
    /// default one per 2048 frames, 1 to 64).
    #[arg(long, value_name = "K")]
    pub segments: Option<usize>,
    /// Segment length in frames instead of --segments (even).
    #[arg(long, value_name = "FRAMES")]
    pub window: Option<usize>,
    /// Report only peaks that noise alone would put this high anywhere in
    /// the band with at most this probability (against each peak's local
    /// noise floor and the spectrum's averages; 0 < P <= 1).
    #[arg(long, value_name = "P", default_value_t = vibroscope::peaks::DEFAULT_FALSE_ALARM)]
    pub false_alarm: f64,
    /// Report every prominent peak, significant or not (each with its
    /// false-alarm probability): --false-alarm 1.
    #[arg(long, conflicts_with = "false_alarm")]
    pub all_peaks: bool,
    /// Only peaks above this frequency (Hz).
    #[arg(long, value_name = "HZ")]
    pub min_hz: Option<f64>,
    /// Only peaks below this frequency (Hz).
    #[arg(long, value_name = "HZ")]
    pub max_hz: Option<f64>,
    /// How the bands' spectra make one: `snr` scales each to its own
    /// noise floor and weighs it by how far it stands out (a band across
    /// the motion, or noise, adds nothing: a vibration that a small part
    /// of the frame carries is found without a --roi); `sum` adds them
    /// (Eq. 3.17 as written).
    #[arg(long, value_enum, default_value = "snr")]
    pub combine: CombineArg,
    /// Also write the spectrum (dB) into the JSON.
    #[arg(long)]
    pub include_spectrum: bool,
    /// Also plot the amplitude spectrum of --quantity (logarithmic axis in
    /// px, or µm/mm with --scale; peaks marked with their amplitudes) to
    /// this PNG.
    #[arg(long, value_name = "OUT.png")]
    pub png: Option<PathBuf>,
    /// Also plot sliding spectra over time (a spectrogram) to this PNG.
    #[arg(long, value_name = "OUT.png")]
    pub spectrogram: Option<PathBuf>,
    /// The spectrogram's window in frames (hop: an eighth of it).
    #[arg(long, value_name = "FRAMES", default_value_t = SPECTROGRAM_WINDOW)]
    pub spectrogram_window: usize,
    /// Keep the extracted motion (bands aligned and summed) that the
    /// time-domain damping (SSI-cov) ran on, as a WAV.
    #[arg(long, value_name = "OUT.wav")]
    pub motion_wav: Option<PathBuf>,
}

impl SpectrumArgs {
    pub fn options(&self, progress: bool) -> SpectrumOptions {
        SpectrumOptions {
            fps: self.video_args.fps,
            peaks: self.peaks,
            region: self.video_args.region(),
            segments: self.segments,
            window: self.window,
            min_hz: self.min_hz,
            max_hz: self.max_hz,
            false_alarm: if self.all_peaks {
                1.0
            } else {
                self.false_alarm
            },
            include_spectrum: self.include_spectrum,
            combine: match self.combine {
                CombineArg::Snr => spectrum::Combine::Snr,
                CombineArg::Sum => spectrum::Combine::Sum,
            },
            png: self.png.clone(),
            spectrogram: self.spectrogram.clone(),
            spectrogram_window: self.spectrogram_window,
            motion_wav: self.motion_wav.clone(),
            run: RunSettings { progress },
            ..SpectrumOptions::new(&self.video, &self.json)
        }
    }
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum CombineArg {
    Snr,
    Sum,
}

#[derive(Clone, Copy, Debug, Default, clap::ValueEnum)]
pub enum QuantityArg {
    #[default]
    Displacement,
    Velocity,
    Acceleration,
}

impl From<QuantityArg> for Quantity {
    fn from(q: QuantityArg) -> Quantity {
        match q {
            QuantityArg::Displacement => Quantity::Displacement,
            QuantityArg::Velocity => Quantity::Velocity,
            QuantityArg::Acceleration => Quantity::Acceleration,
        }
    }
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let mut o = a.spectrum.options(true);
    o.scale = a.units.scale();
    o.quantity = a.quantity.into();
    o.waveform = a.waveform.clone();
    o.uff = a.uff.clone();
    o.regions = a.regions.clone();
    o.filters = a.band.iter().chain(&a.notch).copied().collect();
    if o.waveform.is_none() && o.uff.is_none() && !(o.regions.is_empty() && o.filters.is_empty()) {
        eprintln!("error: --region, --band and --notch apply to the --waveform and --uff exports: give --waveform OUT.csv or --uff OUT.uff");
        return Ok(ExitCode::from(2));
    }
    super::warn_playback_rate(&o.video, o.fps);
    let bar = super::Bar::start(true);
    let r = spectrum::spectrum(&o);
    drop(bar);
    let (r, _) = super::stats(a.stats, r, |(_, run)| Some(run.table()))?;
    for p in &r.written {
        super::wrote(p);
    }
    summary(&r);
    if let Some(u) = &r.uff {
        eprintln!(
            "UFF {}: {} nodes (region centres, {}), {} records ({} in {}: time responses and amplitude spectra, x and y)",
            u.path.display(),
            u.nodes,
            u.coordinates,
            u.records,
            u.quantity.name(),
            u.unit
        );
    }
    for w in &r.waveforms {
        let roi = w.roi.map_or("whole frame".to_string(), |[x, y, ww, hh]| {
            format!("{x},{y},{ww},{hh}")
        });
        eprintln!(
            "region {} ({roi}): waveform {} ({}), spectrum {} ({}; strongest {} {} at {} Hz)",
            w.region,
            w.csv.display(),
            w.unit,
            w.spectrum_csv.display(),
            w.spectrum_unit,
            significant(w.strongest_amplitude),
            w.spectrum_unit,
            super::num(w.strongest_hz, 2)
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The resonances, strongest first (the largest power above its own
/// floor), then the peaks that are not resonances, with the reason.
fn summary(r: &SpectrumReport) {
    others(r);
    if r.peaks.is_empty() {
        eprintln!(
            "no resonance stands out (resolution {:.3} Hz at {} Hz)",
            r.resolution_hz,
            short(r.sample_rate_hz)
        );
        return;
    }
    let mut peaks: Vec<_> = r.peaks.iter().collect();
    peaks.sort_by(|a, b| b.above_floor_db().total_cmp(&a.above_floor_db()));
    eprintln!(
        "{} resonances, strongest (most power above its own floor) first (resolution {:.3} Hz at {} Hz sampling):",
        peaks.len(),
        r.resolution_hz,
        short(r.sample_rate_hz)
    );
    if let Some(m) = &r.motion {
        let scale = match &m.scale {
            None => "no scale given: pixels".to_string(),
            Some(s) => match &s.known_length {
                None => format!("{} mm/px", s.mm_per_px),
                Some(k) => format!(
                    "{:.6} mm/px from {} mm over {:.2} px",
                    s.mm_per_px,
                    k.length_mm,
                    k.distance_px()
                ),
            },
        };
        eprintln!("  {} amplitudes in {} ({scale})", m.quantity.name(), m.unit);
    }
    for p in peaks.iter().take(5) {
        // A resonance's uncertainty is below a tenth of its frequency (the
        // resonance test); one the fit could not give is the bin's.
        let f_std = if p.frequency_std_hz.is_finite() && p.frequency_std_hz > 0.0 {
            format!("± {}", significant(p.frequency_std_hz))
        } else {
            format!(
                "± {} (the bin's quantisation)",
                significant(r.resolution_hz / 12f64.sqrt())
            )
        };
        let damping = if p.damping_method.starts_with("resolution_limit") {
            format!(
                "damping < {} (peak narrower than the bins: record longer to resolve it)",
                super::num(p.damping_ratio, 4)
            )
        } else {
            let std = if p.damping_ratio_std.is_finite() {
                format!("± {}", significant(p.damping_ratio_std))
            } else {
                // One estimate, no scatter to measure it by.
                "(one estimate: uncertainty at most the value)".into()
            };
            format!(
                "damping {} {std} ({})",
                significant(p.damping_ratio),
                p.damping_method
            )
        };
        // A struck object's ring-down, beside the main estimate.
        let damping = match p
            .damping_estimates
            .iter()
            .find(|e| e.method == "free_decay")
        {
            Some(e) => format!(
                "{damping}; free decay {} ± {}",
                significant(e.damping_ratio),
                significant(e.damping_ratio_std)
            ),
            None => damping,
        };
        let amp = match (p.amplitude, &r.motion) {
            (Some(a), Some(m)) => format!("  {} {}", significant(a), m.unit),
            _ => String::new(),
        };
        let chance = if p.false_alarm.is_finite() {
            let fa = if p.false_alarm < 1e-12 {
                "< 1e-12".to_string()
            } else {
                format!("{:.1e}", p.false_alarm)
            };
            format!(
                ", {} dB above the noise floor (false alarm {fa})",
                super::num(p.power_db - p.floor_db, 1),
            )
        } else {
            String::new()
        };
        eprintln!(
            "  {:>10} {f_std} Hz{amp}  {damping}  {} dB above its surroundings{chance}",
            super::num(p.frequency_hz, 3),
            super::num(p.prominence_db, 1)
        );
    }
}

/// The peaks the resonance test turned away (drift, broadband), never
/// ranked among the resonances.
fn others(r: &SpectrumReport) {
    if r.others.is_empty() {
        return;
    }
    eprintln!(
        "{} peaks that are not resonances (not ranked; see docs/resonances.md):",
        r.others.len()
    );
    for p in &r.others {
        let class = serde_json::to_value(p.class)
            .ok()
            .and_then(|v| v.as_str().map(str::to_owned))
            .unwrap_or_default();
        eprintln!(
            "  {:>10} Hz  {class}: {}",
            super::num(p.frequency_hz, 3),
            p.class_reason
        );
    }
}

/// Four significant digits (`48.71`, `0.003125`), `n/a` when not finite.
pub fn significant(v: f64) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let decimals = (3 - v.abs().log10().floor() as i32).clamp(0, 12) as usize;
    format!("{v:.decimals$}")
}

fn parse_band(s: &str) -> Result<BandFilter, String> {
    BandFilter::band(s).map_err(|e| e.message)
}

fn parse_notch(s: &str) -> Result<BandFilter, String> {
    BandFilter::notch(s).map_err(|e| e.message)
}
