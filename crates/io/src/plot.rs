//! PNG plots of motion spectra: the power spectrum in dB against frequency
//! with the picked peaks marked, and a spectrogram (sliding spectra over
//! time). Drawn with plotters into an RGB buffer (text by ab_glyph from an
//! embedded DejaVu Sans, so no system fonts, fontconfig or freetype are
//! needed) and encoded with the `image` crate.

use image::ImageEncoder;
use plotters::prelude::*;
use std::sync::Once;
use vibroscope_math::peaks::Peak;

/// Where the data sit in a plot: pixel ranges of the plotting area and the
/// values at its edges (for tests and for reading pixels back).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlotArea {
    pub x_px: (i32, i32),
    pub y_px: (i32, i32),
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
}

/// An RGB8 image.
#[derive(Clone, Debug)]
pub struct Rgb {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
}

impl Rgb {
    /// PNG bytes.
    pub fn png(&self) -> Result<Vec<u8>, PlotError> {
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(
                &self.pixels,
                self.width,
                self.height,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(PlotError::Encode)?;
        Ok(out)
    }
}

static FONT: Once = Once::new();

/// Registers the embedded font as plotters' "sans-serif" (once per process).
fn font() {
    FONT.call_once(|| {
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// Why a plot was not drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The requested size is outside `MIN_SIDE..=8192` pixels a side.
    #[error("plot size must be {MIN_SIDE}..=8192 pixels each, got {width}x{height}")]
    Size { width: u32, height: u32 },
    /// Fewer than two spectrum bins fall in the band.
    #[error("fewer than 2 spectrum bins between {lo_hz} and {hi_hz} Hz")]
    Band { lo_hz: f64, hi_hz: f64 },
    /// A spectrogram of no spectra.
    #[error("no spectra to draw")]
    NoSpectra,
    /// The drawing library failed.
    #[error("plot: {0}")]
    Draw(String),
    /// The PNG encoder failed.
    #[error("{0}")]
    Encode(#[source] image::ImageError),
}

fn draw_err<E: std::fmt::Debug>(e: E) -> PlotError {
    PlotError::Draw(format!("{e:?}"))
}

/// Smallest accepted plot side, pixels.
pub const MIN_SIDE: u32 = 200;

fn check_size(width: u32, height: u32) -> Result<(), PlotError> {
    if !(MIN_SIDE..=8192).contains(&width) || !(MIN_SIDE..=8192).contains(&height) {
        return Err(PlotError::Size { width, height });
    }
    Ok(())
}

/// `(frequency, y(value))` of the bins `f0 + k·df` of `values` between
/// `band.0` and `band.1` Hz (finite values only); at least two, or a band
/// error.
fn band_points(
    values: &[f64],
    f0: f64,
    df: f64,
    band: (f64, f64),
    y: impl Fn(f64) -> f64,
) -> Result<Vec<(f64, f64)>, PlotError> {
    let pts: Vec<(f64, f64)> = values
        .iter()
        .enumerate()
        .map(|(k, &v)| (f0 + k as f64 * df, v))
        .filter(|(f, v)| *f >= band.0 && *f <= band.1 && v.is_finite())
        .map(|(f, v)| (f, y(v)))
        .collect();
    if pts.len() < 2 {
        return Err(PlotError::Band {
            lo_hz: band.0,
            hi_hz: band.1,
        });
    }
    Ok(pts)
}

/// The smallest and largest y of `pts`.
fn y_extent(pts: &[(f64, f64)]) -> (f64, f64) {
    let lo = pts.iter().map(|v| v.1).fold(f64::INFINITY, f64::min);
    let hi = pts.iter().map(|v| v.1).fold(f64::NEG_INFINITY, f64::max);
    (lo, hi)
}

/// The power spectrum `power` (density, bins `f0 + k·df`) in dB between
/// `min_hz` and `max_hz`, with `peaks` marked (red circles, labelled).
pub fn power_plot(
    power: &[f64],
    f0: f64,
    df: f64,
    band: (f64, f64),
    peaks: &[Peak],
    size: (u32, u32),
) -> Result<(Rgb, PlotArea), PlotError> {
    let (width, height) = size;
    check_size(width, height)?;
    font();
    let db = band_points(power, f0, df, band, |p| 10.0 * p.max(1e-300).log10())?;
    let (lo, hi) = y_extent(&db);
    let (lo, hi) = (lo - 3.0, hi + 6.0);
    let (xa, xb) = (db[0].0, db[db.len() - 1].0);
    let axes = Axes {
        caption: "motion power spectrum",
        x_desc: "frequency (Hz)",
        y_desc: "power (dB, relative: phase units)",
        mesh: true,
        y_ticks: None,
    };
    draw(size, &axes, (xa..xb, lo..hi), |chart| {
        chart
            .draw_series(LineSeries::new(db.iter().copied(), BLUE.stroke_width(1)))
            .map_err(draw_err)?;
        let marks: Vec<(f64, f64)> = peaks
            .iter()
            .filter(|p| p.frequency_hz >= xa && p.frequency_hz <= xb)
            .map(|p| (p.frequency_hz, p.power_db))
            .collect();
        chart
            .draw_series(marks.iter().map(|&(f, p)| {
                EmptyElement::at((f, p))
                    + Circle::new((0, 0), 5, RED.stroke_width(2))
                    + Text::new(format!("{f:.1} Hz"), (6, -16), ("sans-serif", 13))
            }))
            .map_err(draw_err)?;
        Ok(())
    })
}

/// An amplitude spectrum `amplitude` (bins `k·df`, in the unit that
/// `y_desc` names) between `band.0` and `band.1` Hz on a logarithmic axis
/// (ticks in that unit, the top six decades shown), with `peaks`
/// (frequency, amplitude, label) marked (red circles, labelled).
pub fn amplitude_plot(
    amplitude: &[f64],
    df: f64,
    band: (f64, f64),
    peaks: &[(f64, f64, String)],
    caption: &str,
    y_desc: &str,
    size: (u32, u32),
) -> Result<(Rgb, PlotArea), PlotError> {
    check_size(size.0, size.1)?;
    font();
    let log = band_points(amplitude, 0.0, df, band, |a| a.max(1e-300).log10())?;
    let (lo, hi) = y_extent(&log);
    let (lo, hi) = (lo.max(hi - 6.0) - 0.2, hi + 0.5);
    let log: Vec<(f64, f64)> = log.into_iter().map(|(f, v)| (f, v.max(lo))).collect();
    let (xa, xb) = (log[0].0, log[log.len() - 1].0);
    // Labels at whole decades only, unless the axis spans under two.
    let decades_only = hi - lo >= 2.0;
    let ticks = |v: &f64| {
        if decades_only && (v - v.round()).abs() > 1e-6 {
            return String::new();
        }
        let a = 10f64.powf(*v);
        if (1e-3..1e4).contains(&a) {
            format!("{}", (a * 1e4).round() / 1e4)
        } else {
            format!("{a:.0e}")
        }
    };
    let axes = Axes {
        caption,
        x_desc: "frequency (Hz)",
        y_desc,
        mesh: true,
        y_ticks: Some(&ticks),
    };
    draw(size, &axes, (xa..xb, lo..hi), |chart| {
        chart
            .draw_series(LineSeries::new(log.iter().copied(), BLUE.stroke_width(1)))
            .map_err(draw_err)?;
        let marks: Vec<(f64, f64, &str)> = peaks
            .iter()
            .filter(|p| p.0 >= xa && p.0 <= xb && p.1 > 0.0 && p.1.is_finite())
            .map(|p| (p.0, p.1.log10().clamp(lo, hi), p.2.as_str()))
            .collect();
        chart
            .draw_series(marks.iter().map(|&(f, v, label)| {
                EmptyElement::at((f, v))
                    + Circle::new((0, 0), 5, RED.stroke_width(2))
                    + Text::new(label.to_string(), (6, -16), ("sans-serif", 13))
            }))
            .map_err(draw_err)?;
        Ok(())
    })
}

/// Lines against a common x axis (a waveform's x and y, a spectrum),
/// each `(label, points)`, in the colours blue, red, green, ...; the
/// axes' titles say the quantities and their units.
pub fn line_plot(
    lines: &[(&str, &[(f64, f64)])],
    caption: &str,
    x_desc: &str,
    y_desc: &str,
    size: (u32, u32),
) -> Result<(Rgb, PlotArea), PlotError> {
    check_size(size.0, size.1)?;
    font();
    let all = || {
        lines
            .iter()
            .flat_map(|(_, p)| p.iter())
            .filter(|p| p.0.is_finite() && p.1.is_finite())
    };
    let (mut xa, mut xb, mut lo, mut hi) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in all() {
        (xa, xb, lo, hi) = (xa.min(x), xb.max(x), lo.min(y), hi.max(y));
    }
    if xa >= xb {
        return Err(PlotError::Draw(
            "fewer than two distinct points to plot".into(),
        ));
    }
    if lo >= hi {
        (lo, hi) = (lo - 1.0, hi + 1.0);
    }
    let pad = 0.05 * (hi - lo);
    let colours = [BLUE, RED, GREEN, MAGENTA, CYAN, BLACK];
    const NAMES: [&str; 6] = ["blue", "red", "green", "magenta", "cyan", "black"];
    let key: Vec<String> = lines
        .iter()
        .enumerate()
        .map(|(k, (label, _))| format!("{label} {}", NAMES[k % NAMES.len()]))
        .collect();
    let caption = if lines.len() > 1 {
        format!("{caption} ({})", key.join(", "))
    } else {
        caption.to_string()
    };
    let axes = Axes {
        caption: &caption,
        x_desc,
        y_desc,
        mesh: true,
        y_ticks: None,
    };
    draw(size, &axes, (xa..xb, lo - pad..hi + pad), |chart| {
        for (k, (_, pts)) in lines.iter().enumerate() {
            let c = colours[k % colours.len()];
            chart
                .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(1)))
                .map_err(draw_err)?;
        }
        Ok(())
    })
}

/// Titles of a plot.
struct Axes<'a> {
    caption: &'a str,
    x_desc: &'a str,
    y_desc: &'a str,
    mesh: bool,
    /// Tick labels of the y axis (default: plotters' numbers).
    y_ticks: Option<&'a dyn Fn(&f64) -> String>,
}

type Chart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// A white `size` canvas with titled axes over `ranges`; `series` draws
/// the data. Returns the image and where its plotting area is.
fn draw(
    size: (u32, u32),
    axes: &Axes<'_>,
    ranges: (std::ops::Range<f64>, std::ops::Range<f64>),
    series: impl FnOnce(&mut Chart<'_, '_>) -> Result<(), PlotError>,
) -> Result<(Rgb, PlotArea), PlotError> {
    let (width, height) = size;
    let mut buf = vec![255u8; (width * height * 3) as usize];
    let area;
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let (xr, yr) = ranges;
        let x_range = (xr.start, xr.end);
        let y_range = (yr.start, yr.end);
        let mut chart = ChartBuilder::on(&root)
            .caption(axes.caption, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d(xr, yr)
            .map_err(draw_err)?;
        let mut mesh = chart.configure_mesh();
        if !axes.mesh {
            mesh.disable_mesh();
        }
        if let Some(f) = axes.y_ticks {
            mesh.y_label_formatter(f);
        }
        mesh.x_desc(axes.x_desc)
            .y_desc(axes.y_desc)
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(draw_err)?;
        series(&mut chart)?;
        let (x_px, y_px) = chart.plotting_area().get_pixel_range();
        area = PlotArea {
            x_px: (x_px.start, x_px.end),
            y_px: (y_px.start, y_px.end),
            x_range,
            y_range,
        };
        root.present().map_err(draw_err)?;
    }
    Ok((
        Rgb {
            width,
            height,
            pixels: buf,
        },
        area,
    ))
}

/// A spectrum at one time, for [`spectrogram_plot`].
#[derive(Clone, Debug)]
pub struct TimedSpectrum {
    pub t_s: f64,
    pub power: Vec<f64>,
}

/// Dynamic range shown by the spectrogram, dB below its maximum.
pub const SPECTROGRAM_RANGE_DB: f64 = 60.0;

/// Sliding spectra as an image: time along x, frequency along y (low at
/// the bottom), power in dB as a dark-to-bright colour map over the top
/// [`SPECTROGRAM_RANGE_DB`].
pub fn spectrogram_plot(
    spectra: &[TimedSpectrum],
    f0: f64,
    df: f64,
    band: (f64, f64),
    size: (u32, u32),
) -> Result<(Rgb, PlotArea), PlotError> {
    spectrogram_with_track(spectra, f0, df, band, size, "spectrogram", &[])
}

/// A point of a frequency track drawn over a spectrogram (a pitch track):
/// time, frequency, and whether it is confident (drawn bold) or not
/// (drawn faint).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackPoint {
    pub t_s: f64,
    pub f_hz: f64,
    pub confident: bool,
}

/// [`spectrogram_plot`] with a `caption` and a frequency `track` drawn
/// over it: confident points as filled cyan dots, the others as small
/// grey ones (as the thesis' Fig. 4-11 marks voiced segments).
pub fn spectrogram_with_track(
    spectra: &[TimedSpectrum],
    f0: f64,
    df: f64,
    band: (f64, f64),
    size: (u32, u32),
    caption: &str,
    track: &[TrackPoint],
) -> Result<(Rgb, PlotArea), PlotError> {
    let (width, height) = size;
    check_size(width, height)?;
    font();
    if spectra.is_empty() {
        return Err(PlotError::NoSpectra);
    }
    let bins = spectra[0].power.len();
    let k0 = (((band.0 - f0) / df).ceil().max(0.0)) as usize;
    let k1 = ((((band.1 - f0) / df).floor()) as usize).min(bins.saturating_sub(1));
    if k1 <= k0 {
        return Err(PlotError::Band {
            lo_hz: band.0,
            hi_hz: band.1,
        });
    }
    let db = |p: f64| 10.0 * p.max(1e-300).log10();
    let top = spectra
        .iter()
        .flat_map(|s| s.power[k0..=k1].iter().map(|&p| db(p)))
        .fold(f64::NEG_INFINITY, f64::max);
    // Cells span half-way to their neighbours in time.
    let dt = if spectra.len() > 1 {
        (spectra[spectra.len() - 1].t_s - spectra[0].t_s) / (spectra.len() - 1) as f64
    } else {
        1.0
    };
    let (ta, tb) = (
        spectra[0].t_s - dt / 2.0,
        spectra[spectra.len() - 1].t_s + dt / 2.0,
    );
    let (fa, fb) = (f0 + (k0 as f64 - 0.5) * df, f0 + (k1 as f64 + 0.5) * df);
    let axes = Axes {
        caption,
        x_desc: "time (s)",
        y_desc: "frequency (Hz)",
        mesh: false,
        y_ticks: None,
    };
    draw(size, &axes, (ta..tb, fa..fb), |chart| {
        let cells = spectra.iter().flat_map(|s| {
            (k0..=k1).map(move |k| {
                let v = ((db(s.power[k]) - top) / SPECTROGRAM_RANGE_DB + 1.0).clamp(0.0, 1.0);
                let f = f0 + k as f64 * df;
                Rectangle::new(
                    [
                        (s.t_s - dt / 2.0, f - df / 2.0),
                        (s.t_s + dt / 2.0, f + df / 2.0),
                    ],
                    heat(v).filled(),
                )
            })
        });
        chart.draw_series(cells).map_err(draw_err)?;
        let inside = |p: &&TrackPoint| p.f_hz >= fa && p.f_hz <= fb && p.t_s >= ta && p.t_s <= tb;
        let faint = track.iter().filter(inside).filter(|p| !p.confident);
        chart
            .draw_series(
                faint.map(|p| Circle::new((p.t_s, p.f_hz), 1, RGBColor(150, 150, 150).filled())),
            )
            .map_err(draw_err)?;
        let bold = track.iter().filter(inside).filter(|p| p.confident);
        chart
            .draw_series(bold.map(|p| Circle::new((p.t_s, p.f_hz), 2, CYAN.filled())))
            .map_err(draw_err)?;
        Ok(())
    })
}

/// What a modal figure's brightness key says.
#[derive(Clone, Copy, Debug)]
pub struct AmplitudeKey<'a> {
    /// The amplitudes shown at brightness 0 and 1.
    pub lo: f64,
    pub hi: f64,
    /// Brightness = ((a - lo) / (hi - lo))^exponent.
    pub exponent: f64,
    /// What the amplitude is, with its unit: "amplitude (px)".
    pub label: &'a str,
}

/// Width of a modal figure's key panel, pixels.
const KEY_W: usize = 190;
/// Height of a modal figure's title band, pixels.
const TITLE_H: usize = 36;

/// The factor a modal figure enlarges a `w`×`h` image by: the whole factor
/// that brings it closest to 1280x960 without passing it, or below 1 the
/// factor that shrinks it to fit.
pub fn figure_zoom(w: usize, h: usize) -> f64 {
    let fit = (1280.0 / w.max(1) as f64).min(960.0 / h.max(1) as f64);
    if fit >= 1.0 {
        fit.floor()
    } else {
        fit
    }
}

/// A modal image people can read (thesis Fig. 3-6): `img` (the image, as a
/// rule laid over a frame of the scene) enlarged by a whole factor to about
/// 1280x960 (shrunk to fit if larger), under `caption`, beside a wheel of
/// the phase hues (hue = phase, counter-clockwise from 0° at the right, as
/// the image renders it) and a key of brightness against amplitude.
pub fn modal_figure(img: &Rgb, caption: &str, key: &AmplitudeKey<'_>) -> Result<Rgb, PlotError> {
    let (w, h) = (img.width as usize, img.height as usize);
    if w == 0 || h == 0 || img.pixels.len() != w * h * 3 {
        return Err(PlotError::Size {
            width: img.width,
            height: img.height,
        });
    }
    font();
    let z = figure_zoom(w, h);
    let (dw, dh) = (
        ((w as f64 * z).round() as usize).max(1),
        ((h as f64 * z).round() as usize).max(1),
    );
    let margin = 16;
    // Room for the title beside a narrow image.
    let width = (margin + dw + margin + KEY_W).max(760);
    let height = TITLE_H + dh.max(330) + margin;
    let mut buf = vec![255u8; width * height * 3];
    let put = |buf: &mut [u8], x: usize, y: usize, c: [u8; 3]| {
        let i = (y * width + x) * 3;
        buf[i..i + 3].copy_from_slice(&c);
    };
    // The image, nearest-neighbour (each pixel stays a flat square).
    for y in 0..dh {
        let sy = ((y as f64 / z) as usize).min(h - 1);
        for x in 0..dw {
            let sx = ((x as f64 / z) as usize).min(w - 1);
            let i = (sy * w + sx) * 3;
            let c = [img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]];
            put(&mut buf, margin + x, TITLE_H + y, c);
        }
    }
    // The phase wheel: a ring, hue by angle.
    let x0 = margin + dw + margin;
    let (cx, cy) = (x0 + KEY_W / 2, TITLE_H + 100);
    let (r_out, r_in) = (50.0, 22.0);
    for y in cy - 51..=cy + 51 {
        for x in cx - 51..=cx + 51 {
            let (dx, dy) = (x as f64 - cx as f64, cy as f64 - y as f64);
            let r = dx.hypot(dy);
            if r <= r_out && r >= r_in {
                let hue = dy.atan2(dx).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU;
                let c = vibroscope_math::modal::hsv_to_rgb(hue, 1.0, 1.0)
                    .map(|v| (v * 255.0).round() as u8);
                put(&mut buf, x, y, c);
            }
        }
    }
    // The amplitude key: brightness from 0 (bottom) to 1 (top), as it
    // shows over a mid-grey frame in the hue of phase 0.
    let (bar_x, bar_top, bar_h) = (x0 + 12, TITLE_H + 210, 110usize);
    for j in 0..=bar_h {
        let v = 1.0 - j as f64 / bar_h as f64;
        let grey = 128.0 * (1.0 - v);
        let c = [
            (grey + 255.0 * v).round() as u8,
            grey.round() as u8,
            grey.round() as u8,
        ];
        for x in bar_x..bar_x + 24 {
            put(&mut buf, x, bar_top + j, c);
        }
    }
    {
        let root =
            BitMapBackend::with_buffer(&mut buf, (width as u32, height as u32)).into_drawing_area();
        let text = |s: &str, x: usize, y: usize, size: u32| {
            root.draw(&Text::new(
                s.to_string(),
                (x as i32, y as i32),
                ("sans-serif", size),
            ))
            .map_err(draw_err)
        };
        text(caption, margin, 9, 17)?;
        text("phase", x0 + 4, TITLE_H + 14, 14)?;
        text("0°", cx + 54, cy - 8, 13)?;
        text("90°", cx - 10, cy - 68, 13)?;
        text("180°", cx - 88, cy - 8, 13)?;
        text("270°", cx - 14, cy + 54, 13)?;
        text(key.label, x0 + 4, bar_top - 26, 14)?;
        let span = (key.hi - key.lo).abs();
        let decimals = if span > 0.0 {
            ((-(span / 4.0).log10()).ceil() + 1.0).clamp(0.0, 8.0) as usize
        } else {
            3
        };
        for i in 0..=4 {
            let f = i as f64 / 4.0;
            let a = key.lo + (key.hi - key.lo) * f;
            let v = f.powf(key.exponent);
            let y = bar_top + bar_h - (v * bar_h as f64).round() as usize;
            root.draw(&PathElement::new(
                vec![
                    ((bar_x + 24) as i32, y as i32),
                    ((bar_x + 30) as i32, y as i32),
                ],
                BLACK,
            ))
            .map_err(draw_err)?;
            text(
                &format!("{a:.decimals$}"),
                bar_x + 34,
                y.saturating_sub(7),
                13,
            )?;
        }
        root.present().map_err(draw_err)?;
    }
    Ok(Rgb {
        width: width as u32,
        height: height as u32,
        pixels: buf,
    })
}

/// Images one under the other on white, left-aligned (a contact sheet of
/// figures); at most 8192 pixels a side.
pub fn stack(images: &[Rgb]) -> Result<Rgb, PlotError> {
    let width = images.iter().map(|i| i.width).max().unwrap_or(0);
    let height: u64 = images.iter().map(|i| u64::from(i.height)).sum();
    if width == 0 || height == 0 || width > 8192 || height > 8192 {
        return Err(PlotError::Size {
            width,
            height: height.min(u64::from(u32::MAX)) as u32,
        });
    }
    let row = width as usize * 3;
    let mut pixels = vec![255u8; row * height as usize];
    let mut y0 = 0usize;
    for img in images {
        let r = img.width as usize * 3;
        for (y, src) in img.pixels.chunks_exact(r).enumerate() {
            let at = (y0 + y) * row;
            pixels[at..at + r].copy_from_slice(src);
        }
        y0 += img.height as usize;
    }
    Ok(Rgb {
        width,
        height: height as u32,
        pixels,
    })
}

/// Black → purple → orange → light yellow, monotone in brightness.
pub fn heat(v: f64) -> RGBColor {
    let v = v.clamp(0.0, 1.0);
    let r = (1.6 * v).min(1.0);
    let g = (1.4 * v - 0.35).clamp(0.0, 1.0);
    let b = if v < 0.4 {
        1.2 * v
    } else {
        (0.48 - 0.8 * (v - 0.4)).max(0.0) + 1.6 * (v - 0.8).max(0.0)
    };
    let c = |x: f64| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    RGBColor(c(r), c(g), c(b))
}

/// One panel of [`scatter_panels`]: points `(x[i], y[i])` coloured by
/// `group[i]`, with the line y = x.
#[derive(Clone, Debug)]
pub struct Scatter {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub group: Vec<String>,
}

/// Correlation plots side by side (thesis Fig. 5-10): predicted against
/// true, one colour per group (object), the diagonal dashed. PNG bytes.
pub fn scatter_panels(panels: &[Scatter]) -> Result<Vec<u8>, PlotError> {
    let n = panels.len().max(1) as u32;
    let (width, height) = (480 * n, 480);
    check_size(width, height)?;
    font();
    let mut buf = vec![255u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let areas = root.split_evenly((1, n as usize));
        for (p, area) in panels.iter().zip(areas) {
            let vals = p.x.iter().chain(&p.y).copied().filter(|v| v.is_finite());
            let lo = vals.clone().fold(f64::INFINITY, f64::min);
            let hi = vals.fold(f64::NEG_INFINITY, f64::max);
            let (lo, hi) = if lo.is_finite() && hi > lo {
                let m = 0.05 * (hi - lo);
                (lo - m, hi + m)
            } else {
                (0.0, 1.0)
            };
            let mut chart = ChartBuilder::on(&area)
                .caption(&p.title, ("sans-serif", 15))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(56)
                .build_cartesian_2d(lo..hi, lo..hi)
                .map_err(draw_err)?;
            chart
                .configure_mesh()
                .x_desc(p.x_label.as_str())
                .y_desc(p.y_label.as_str())
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(draw_err)?;
            chart
                .draw_series(DashedLineSeries::new(
                    [(lo, lo), (hi, hi)],
                    6,
                    4,
                    BLACK.mix(0.5).stroke_width(1),
                ))
                .map_err(draw_err)?;
            let mut groups: Vec<&String> = p.group.iter().collect();
            groups.sort();
            groups.dedup();
            let colour = |g: &String| {
                let k = groups.iter().position(|x| *x == g).unwrap_or(0);
                let v = 0.15 + 0.75 * k as f64 / groups.len().max(2) as f64;
                let c = heat(v);
                RGBColor(c.0, c.1, 255 - c.2 / 2)
            };
            chart
                .draw_series(
                    p.x.iter()
                        .zip(&p.y)
                        .zip(&p.group)
                        .filter(|((x, y), _)| x.is_finite() && y.is_finite())
                        .map(|((&x, &y), g)| Circle::new((x, y), 4, colour(g).stroke_width(2))),
                )
                .map_err(draw_err)?;
        }
        root.present().map_err(draw_err)?;
    }
    Rgb {
        width,
        height,
        pixels: buf,
    }
    .png()
}
