//! The motion of regions in pixels, measured alongside another graph in
//! the same pass over the video: the engine's `displacement` stage (2-D
//! least squares on a 7-tap gradient, one x and one y channel per region)
//! fed by the graph's source, written to a scratch CSV and read back once
//! into typed waveforms; and the peaks' amplitudes in physical units.

use crate::engine::config::PipelineDecl;
use crate::engine::Origin;
use crate::error::{Error, Result};
use crate::io::atomic::TempPath;
use crate::math::iir::{Shape, Sos, ZeroPhase};
use crate::pipeline::{self, BandFilter};
use crate::stages::params::{CsvParams, DisplacementParams};
use crate::units::{px_to, tone_amplitude, Quantity, Scale, Unit};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Adds `src -> displacement -> csv` to a graph and reads the result.
pub struct DisplacementTap {
    rois: Vec<[u32; 4]>,
    /// Only pixels inside this image count (`--mask`).
    mask: Option<std::path::PathBuf>,
    temp: TempPath,
}

/// One region's displacement over the recording, in pixels.
#[derive(Clone, Debug, Default)]
pub struct RegionMotion {
    /// `[x, y, w, h]`; none for the whole frame.
    pub roi: Option<[u32; 4]>,
    /// Samples per second.
    pub rate_hz: f64,
    /// Each sample's capture time, s.
    pub t_s: Vec<f64>,
    /// +x right, +y down, px.
    pub x: Vec<f32>,
    pub y: Vec<f32>,
}

impl DisplacementTap {
    /// The regions (none: the whole frame).
    pub fn new(rois: Vec<[u32; 4]>) -> DisplacementTap {
        DisplacementTap {
            rois,
            mask: None,
            temp: TempPath::new("displacement.csv"),
        }
    }

    /// Measures only the pixels inside `mask` (every region).
    pub fn with_mask(mut self, mask: Option<std::path::PathBuf>) -> DisplacementTap {
        self.mask = mask;
        self
    }

    /// Adds the stages, fed by the graph's `src`.
    pub fn add(&self, decl: &mut PipelineDecl) -> Result<()> {
        let origin = Origin::Builtin("displacement in physical units".into());
        pipeline::position(decl, "src")?;
        let mut st = pipeline::new_stage::<DisplacementParams>("disp", &["src"], origin.clone());
        if !self.rois.is_empty() {
            let v: Vec<u32> = self.rois.iter().flatten().copied().collect();
            pipeline::put(
                &mut st,
                DisplacementParams::rois,
                Some(v),
                pipeline::by("--roi"),
            )?;
        }
        if let Some(m) = &self.mask {
            pipeline::put(
                &mut st,
                DisplacementParams::mask,
                Some(m.clone()),
                pipeline::by("--mask"),
            )?;
        }
        decl.stages.push(st);
        let mut out = pipeline::new_stage::<CsvParams>("disp_out", &["disp"], origin.clone());
        pipeline::put(
            &mut out,
            CsvParams::path,
            self.temp.path().to_path_buf(),
            origin,
        )?;
        decl.stages.push(out);
        Ok(())
    }

    /// The regions' waveforms, after the run.
    pub fn read(&self) -> Result<Vec<RegionMotion>> {
        let p = self.temp.path();
        let text = std::fs::read_to_string(p).map_err(|e| Error::Document {
            path: p.to_path_buf(),
            message: format!("cannot read the displacement: {e}"),
        })?;
        let n = self.rois.len().max(1);
        let mut regions: Vec<RegionMotion> = (0..n)
            .map(|k| RegionMotion {
                roi: self.rois.get(k).copied(),
                ..RegionMotion::default()
            })
            .collect();
        let mut t_s = Vec::new();
        for (i, line) in text.lines().enumerate().skip(1) {
            let v: std::result::Result<Vec<f64>, _> =
                line.split(',').map(str::parse::<f64>).collect();
            let v = match v {
                Ok(v) if v.len() == 1 + 2 * n => v,
                _ => {
                    return Err(Error::Document {
                        path: p.to_path_buf(),
                        message: format!(
                            "line {}: not a displacement row of {} regions: `{line}`",
                            i + 1,
                            n
                        ),
                    })
                }
            };
            t_s.push(v[0]);
            for (k, r) in regions.iter_mut().enumerate() {
                r.x.push(v[1 + 2 * k] as f32);
                r.y.push(v[2 + 2 * k] as f32);
            }
        }
        let rate_hz = match (t_s.first(), t_s.last()) {
            (Some(a), Some(b)) if t_s.len() > 1 && b > a => (t_s.len() - 1) as f64 / (b - a),
            _ => f64::NAN,
        };
        for r in &mut regions {
            r.rate_hz = rate_hz;
            r.t_s.clone_from(&t_s);
        }
        Ok(regions)
    }
}

/// How the reported motion was measured and in which unit.
#[derive(Clone, Debug, Serialize)]
pub struct MotionSummary {
    /// The unit of every `amplitude` (and waveform value) of this report.
    pub unit: Unit,
    pub quantity: Quantity,
    /// Pixels to millimetres; absent: the values are in pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<Scale>,
    /// The region measured, `[x, y, w, h]`; absent: the whole frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roi: Option<[u32; 4]>,
    pub method: &'static str,
}

/// What [`MotionSummary::method`] says.
pub const METHOD: &str = "2-D least-squares displacement of the region against the first frame (7-tap gradient); amplitude: the sinusoid fitted at the peak's frequency over the recording, x and y in quadrature";

/// The amplitudes (of `quantity`, in the unit chosen for the largest of
/// them) at the peaks' frequencies `freqs_hz` (each refined within
/// `search_hz`) in region `r`'s displacement.
pub fn peak_amplitudes(
    freqs_hz: &[f64],
    search_hz: f64,
    r: &RegionMotion,
    scale: Option<&Scale>,
    quantity: Quantity,
) -> (Vec<f64>, MotionSummary) {
    let px: Vec<f64> = freqs_hz
        .iter()
        .map(|&f0| {
            let (a, f) = tone_amplitude(&[&r.x, &r.y], r.rate_hz, f0, search_hz);
            a * quantity.gain(f)
        })
        .collect();
    let largest = px
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let unit = Scale::unit(scale, quantity, largest);
    let k = px_to(unit, scale);
    let summary = MotionSummary {
        unit,
        quantity,
        scale: scale.copied(),
        roi: r.roi,
        method: METHOD,
    };
    (px.iter().map(|a| a * k).collect(), summary)
}

/// The files of one region's waveform export, and their unit.
#[derive(Clone, Debug, Serialize)]
pub struct WaveformFiles {
    /// 1-based region number, as in the file names.
    pub region: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roi: Option<[u32; 4]>,
    /// `t_s,x_<unit>,y_<unit>` and its plot.
    pub csv: PathBuf,
    pub png: PathBuf,
    /// `freq_hz,amplitude_<unit>` (of the quantity) and its plot.
    pub spectrum_csv: PathBuf,
    pub spectrum_png: PathBuf,
    /// Unit of the waveform (displacement).
    pub unit: Unit,
    /// Unit of the spectrum (the quantity asked).
    pub spectrum_unit: Unit,
    /// The strongest line of the spectrum above the first bins: Hz, amplitude.
    pub strongest_hz: f64,
    pub strongest_amplitude: f64,
}

/// The paths of region `k` (1-based) of `n` for `--waveform base`:
/// `base` itself for one region, `STEM.roiK.EXT` for several; the plot
/// beside it as `.png`, the spectrum as `.spectrum.csv`/`.spectrum.png`.
pub fn waveform_paths(base: &Path, k: usize, n: usize) -> [PathBuf; 4] {
    let ext = base
        .extension()
        .map_or("csv".to_string(), |e| e.to_string_lossy().into_owned());
    let stem = base.with_extension("");
    let stem = if n > 1 {
        let mut s = stem.into_os_string();
        s.push(format!(".roi{k}"));
        PathBuf::from(s)
    } else {
        stem
    };
    let with = |suffix: &str| {
        let mut s = stem.clone().into_os_string();
        s.push(suffix);
        PathBuf::from(s)
    };
    [
        with(&format!(".{ext}")),
        with(".png"),
        with(".spectrum.csv"),
        with(".spectrum.png"),
    ]
}

/// Filters `y` by each of `filters` in turn, zero-phase (forward and
/// backward: magnitude |H|², no delay), with the Butterworth designs of
/// the `bandpass`/`bandstop` kinds (order 2).
pub fn filter(y: &[f32], rate_hz: f64, filters: &[BandFilter]) -> Result<Vec<f32>> {
    let mut cur = y.to_vec();
    for f in filters {
        f.check_rate(rate_hz)?;
        let (kind, lo_hz, hi_hz) = f.stage();
        let shape = if kind == "bandpass" {
            Shape::Bandpass { lo_hz, hi_hz }
        } else {
            Shape::Bandstop { lo_hz, hi_hz }
        };
        let sos = Sos::butterworth(2, shape, rate_hz)
            .map_err(|e| crate::error::Error::usage(f.flag(), e.to_string()))?;
        let mut zp = ZeroPhase::new(sos);
        zp.push(&cur);
        let mut out = Vec::with_capacity(cur.len());
        zp.release(cur.len(), true, &mut out);
        cur = out;
    }
    Ok(cur)
}

fn write_csv(path: &Path, header: &str, rows: impl Iterator<Item = String>) -> Result<()> {
    let mut text = String::from(header);
    text.push('\n');
    for r in rows {
        text.push_str(&r);
        text.push('\n');
    }
    crate::io::atomic::write_atomic(path, text.as_bytes())?;
    Ok(())
}

/// Writes a plot as a PNG (whole, or not at all).
pub(crate) fn write_png(
    path: &Path,
    plot: std::result::Result<
        (crate::io::plot::Rgb, crate::io::plot::PlotArea),
        crate::io::plot::PlotError,
    >,
) -> Result<()> {
    let (img, _) = plot.map_err(crate::io::Error::from)?;
    let png = img.png().map_err(crate::io::Error::from)?;
    crate::io::atomic::write_atomic(path, &png)?;
    Ok(())
}

/// Writes each region's waveform (filtered by `filters`) and amplitude
/// spectrum (of `quantity`) as CSV and PNG, in physical units with a scale.
pub fn write_waveforms(
    regions: &[RegionMotion],
    base: &Path,
    scale: Option<&Scale>,
    quantity: Quantity,
    filters: &[BandFilter],
) -> Result<Vec<WaveformFiles>> {
    // Filter everything first: a bad band fails before any file is written.
    let mut filtered = Vec::with_capacity(regions.len());
    for r in regions {
        filtered.push((
            filter(&r.x, r.rate_hz, filters)?,
            filter(&r.y, r.rate_hz, filters)?,
        ));
    }
    let n = regions.len();
    let mut files = Vec::with_capacity(n);
    for (k, (r, (x, y))) in regions.iter().zip(&filtered).enumerate() {
        let [csv, png, spectrum_csv, spectrum_png] = waveform_paths(base, k + 1, n);
        let name = match r.roi {
            Some([rx, ry, rw, rh]) => format!("region {} ({rx},{ry},{rw},{rh})", k + 1),
            None => format!("region {} (whole frame)", k + 1),
        };
        // The waveform: displacement, mean removed.
        let mean = |v: &[f32]| v.iter().map(|&a| f64::from(a)).sum::<f64>() / v.len().max(1) as f64;
        let (mx, my) = (mean(x), mean(y));
        let largest = x
            .iter()
            .map(|&v| (f64::from(v) - mx).abs())
            .chain(y.iter().map(|&v| (f64::from(v) - my).abs()))
            .fold(0.0, f64::max);
        let unit = Scale::unit(scale, Quantity::Displacement, largest);
        let c = px_to(unit, scale);
        let xs: Vec<(f64, f64)> = r
            .t_s
            .iter()
            .zip(x)
            .map(|(&t, &v)| (t, (f64::from(v) - mx) * c))
            .collect();
        let ys: Vec<(f64, f64)> = r
            .t_s
            .iter()
            .zip(y)
            .map(|(&t, &v)| (t, (f64::from(v) - my) * c))
            .collect();
        write_csv(
            &csv,
            &format!("t_s,x_{unit},y_{unit}"),
            xs.iter()
                .zip(&ys)
                .map(|(a, b)| format!("{:.9},{},{}", a.0, a.1, b.1)),
        )?;
        write_png(
            &png,
            crate::io::plot::line_plot(
                &[("x", &xs), ("y", &ys)],
                &format!("displacement, {name}"),
                "time (s)",
                &format!("displacement ({unit})"),
                (900, 400),
            ),
        )?;
        // The amplitude spectrum of the quantity.
        let (amp, df) = crate::math::amplitude::amplitude_spectrum(&[x, y], r.rate_hz);
        let q: Vec<f64> = amp
            .iter()
            .enumerate()
            .map(|(i, &a)| a * quantity.gain(i as f64 * df))
            .collect();
        // The first bins hold what the window leaks of a drift: skip them
        // when picking the unit and the strongest line.
        let (strongest_i, strongest) =
            q.iter()
                .enumerate()
                .skip(2)
                .fold((0, 0.0), |b, (i, &v)| if v > b.1 { (i, v) } else { b });
        let sunit = Scale::unit(scale, quantity, strongest);
        let sc = px_to(sunit, scale);
        let pts: Vec<(f64, f64)> = q
            .iter()
            .enumerate()
            .map(|(i, &v)| (i as f64 * df, v * sc))
            .collect();
        write_csv(
            &spectrum_csv,
            &format!("freq_hz,amplitude_{sunit}"),
            pts.iter().map(|(f, v)| format!("{f},{v}")),
        )?;
        write_png(
            &spectrum_png,
            crate::io::plot::line_plot(
                &[(quantity.name(), &pts)],
                &format!("{} amplitude spectrum, {name}", quantity.name()),
                "frequency (Hz)",
                &format!("{} amplitude ({sunit})", quantity.name()),
                (900, 400),
            ),
        )?;
        files.push(WaveformFiles {
            region: k + 1,
            roi: r.roi,
            csv,
            png,
            spectrum_csv,
            spectrum_png,
            unit,
            spectrum_unit: sunit,
            strongest_hz: strongest_i as f64 * df,
            strongest_amplitude: strongest * sc,
        });
    }
    Ok(files)
}

/// What a UFF export holds (the `uff` field of `spectrum`'s JSON).
#[derive(Clone, Debug, Serialize)]
pub struct UffExport {
    pub path: PathBuf,
    /// One node per region (data set 15), numbered from 1 as the regions.
    pub nodes: usize,
    /// Data sets 58: per region and axis (x, then y), the time response
    /// and its amplitude spectrum.
    pub records: usize,
    /// The quantity of every record, its unit in the time responses and
    /// in the spectra (`mm`, `mm/s`, `px/s²`...).
    pub quantity: Quantity,
    pub unit: String,
    /// Length unit of the node coordinates (`mm`, or `px`).
    pub coordinates: String,
}

/// An ASCII-only unit label for UFF (`px/s^2`, `mm/s`).
fn uff_unit(length: &str, quantity: Quantity) -> String {
    match quantity {
        Quantity::Displacement => length.to_string(),
        Quantity::Velocity => format!("{length}/s"),
        Quantity::Acceleration => format!("{length}/s^2"),
    }
}

/// Writes every region's motion as one Universal File (`path`): data set
/// 164 (millimetres, with a scale), 15 (a node per region at its centre,
/// image axes: +x right, +y down, z 0; mm with a scale, else px), and per
/// region four data sets 58: the x and y time responses of `quantity`
/// (mean removed; velocity and acceleration by
/// [`crate::math::amplitude::time_derivative`]) and their amplitude
/// spectra (as `--waveform`'s, per axis). Response node k is region k,
/// direction 1 (+x) or 2 (+y). `filters` apply first, as to the waveforms.
pub fn write_uff(
    regions: &[RegionMotion],
    frame: (u32, u32),
    path: &Path,
    video: &Path,
    scale: Option<&Scale>,
    quantity: Quantity,
    filters: &[BandFilter],
) -> Result<UffExport> {
    use crate::io::uff::{self, Axis, Function, FunctionType, Node, Units};
    let (length, per_px) = match scale {
        Some(s) => ("mm", s.mm_per_px),
        None => ("px", 1.0),
    };
    let unit = uff_unit(length, quantity);
    let ordinate = |spectrum: bool| Axis {
        data_type: match quantity {
            Quantity::Displacement => 8,
            Quantity::Velocity => 11,
            Quantity::Acceleration => 12,
        },
        length_exp: 1,
        label: format!(
            "{}{}",
            match quantity {
                Quantity::Displacement => "Displacement",
                Quantity::Velocity => "Velocity",
                Quantity::Acceleration => "Acceleration",
            },
            if spectrum { " ampl." } else { "" }
        ),
        units: unit.clone(),
    };
    let source = video.file_name().map_or_else(
        || video.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut nodes = Vec::with_capacity(regions.len());
    let mut functions = Vec::with_capacity(4 * regions.len());
    for (k, r) in regions.iter().enumerate() {
        let label = k as u32 + 1;
        let [rx, ry, rw, rh] = r.roi.unwrap_or([0, 0, frame.0, frame.1]);
        let centre = [
            (f64::from(rx) + f64::from(rw) / 2.0) * per_px,
            (f64::from(ry) + f64::from(rh) / 2.0) * per_px,
            0.0,
        ];
        nodes.push(Node { label, xyz: centre });
        let n = r.t_s.len();
        let (t0, dt) = (r.t_s.first().copied().unwrap_or(0.0), 1.0 / r.rate_hz);
        // Data set 58 is written evenly spaced: refuse a record whose
        // samples are not (dropped frames), rather than move them.
        if n < 2 || !dt.is_finite() {
            return Err(Error::usage(
                "--uff",
                format!("region {label} has {n} samples: too few for a UFF record"),
            ));
        }
        if let Some((i, t)) = r
            .t_s
            .iter()
            .enumerate()
            .find(|&(i, &t)| (t - t0 - i as f64 * dt).abs() > 0.01 * dt)
        {
            return Err(Error::usage(
                "--uff",
                format!(
                    "UFF 58 records are evenly spaced, but sample {i} of region {label} is at {t:.6} s, \
                     not {:.6} s (dropped frames?); --waveform keeps each sample's own time",
                    t0 + i as f64 * dt
                ),
            ));
        }
        let roi = format!("{rx},{ry},{rw},{rh}");
        for (dir, name, v) in [(1, "x", &r.x), (2, "y", &r.y)] {
            let v = filter(v, r.rate_hz, filters)?;
            let mean = v.iter().map(|&a| f64::from(a)).sum::<f64>() / n as f64;
            let d: Vec<f64> = v.iter().map(|&a| (f64::from(a) - mean) * per_px).collect();
            let q = crate::math::amplitude::time_derivative(&d, r.rate_hz, quantity.order() as u32);
            // One record of this region and axis: its kind, abscissa
            // (start, step, what: 17 time in s, 18 frequency in Hz) and data.
            let record = |kind: FunctionType, start: f64, step: f64, data: Vec<f64>| {
                let (what, code, axis, unit) = match kind {
                    FunctionType::TimeResponse => ("time response", 17, "Time", "s"),
                    FunctionType::Spectrum => ("amplitude spectrum", 18, "Frequency", "Hz"),
                };
                Function {
                    ids: [
                        format!(
                            "vibroscope {} {what}, region {label} ({roi}) along +{name}",
                            quantity.name()
                        ),
                        format!("source {source}"),
                        String::from("NONE"),
                        format!("image axes: +x right, +y down; {length}"),
                        String::from("NONE"),
                    ],
                    kind,
                    function_id: 0,
                    response_name: format!("roi{label}"),
                    response_node: label,
                    response_dir: dir,
                    abscissa_min: start,
                    abscissa_step: step,
                    abscissa: Axis {
                        data_type: code,
                        length_exp: 0,
                        label: axis.into(),
                        units: unit.into(),
                    },
                    ordinate: ordinate(kind == FunctionType::Spectrum),
                    data,
                }
            };
            functions.push(record(FunctionType::TimeResponse, t0, dt, q));
            let (amp, df) = crate::math::amplitude::amplitude_spectrum(&[&v], r.rate_hz);
            let spec: Vec<f64> = amp
                .iter()
                .enumerate()
                .map(|(i, &a)| a * quantity.gain(i as f64 * df) * per_px)
                .collect();
            functions.push(record(FunctionType::Spectrum, 0.0, df, spec));
        }
    }
    // Function ids count the records from 1, in file order.
    for (i, f) in functions.iter_mut().enumerate() {
        f.function_id = i as u32 + 1;
    }
    let units = scale.map(|_| Units::millimetre());
    let text = uff::to_string(units.as_ref(), &nodes, &functions);
    crate::io::atomic::write_atomic(path, text.as_bytes())?;
    Ok(UffExport {
        path: path.to_path_buf(),
        nodes: nodes.len(),
        records: functions.len(),
        quantity,
        unit,
        coordinates: length.into(),
    })
}

/// Measures the displacement of each of `rois` (none: the whole frame) in
/// `video` (the `motion` pipeline's source, at `fps` when given): one pass,
/// the same `displacement` stage as `spectrum --waveform`, in pixels
/// (+x right, +y down), each sample with its capture time.
pub fn displacement(
    video: &Path,
    fps: Option<f64>,
    rois: Vec<[u32; 4]>,
    run: pipeline::RunSettings,
) -> Result<Vec<RegionMotion>> {
    check_regions(video, fps, &rois, "regions")?;
    let mut decl = pipeline::prepare(&pipeline::PipelineOptions {
        pipeline: "motion".into(),
        set: Vec::new(),
        replay: Some(video.to_path_buf()),
        fps,
    })?;
    let src = pipeline::source_id(&decl).map(str::to_owned);
    decl.stages.retain(|s| Some(&s.id) == src.as_ref());
    let tap = DisplacementTap::new(rois);
    tap.add(&mut decl)?;
    pipeline::run(&decl, run)?;
    tap.read()
}

/// Refuses, before any work, a region of `rois` that does not fit in the
/// frame of `video` (named by `flag` and its 1-based number); returns the
/// frame's size.
pub fn check_regions(
    video: &Path,
    fps: Option<f64>,
    rois: &[[u32; 4]],
    flag: &str,
) -> Result<(u32, u32)> {
    let p = crate::probe::probe(video, fps)?;
    for (k, &[x, y, w, h]) in rois.iter().enumerate() {
        let fits =
            |a: u32, b: u32, size: u32| b > 0 && u64::from(a) + u64::from(b) <= u64::from(size);
        if !(fits(x, w, p.width) && fits(y, h, p.height)) {
            return Err(Error::usage(
                flag,
                format!(
                    "region {} ({x},{y},{w},{h}) does not fit in the {}x{} frame of {}",
                    k + 1,
                    p.width,
                    p.height,
                    video.display()
                ),
            ));
        }
    }
    Ok((p.width, p.height))
}
