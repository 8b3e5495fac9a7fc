//! PNG plots of motion spectra (issue 5): the power spectrum and the
//! spectrogram put their peaks where the data have them, and `vibroscope
//! spectrum --png --spectrogram` writes valid PNGs of the stated size whose
//! highest line sits at the tone that moved the object (the `--png` plot:
//! the displacement amplitude spectrum in its unit, issue 18).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use vibroscope_io::plot::{
    amplitude_plot, power_plot, spectrogram_plot, PlotArea, Rgb, TimedSpectrum,
};

/// A Lorentzian line of half width `hw` at `f` over a floor of 1.
fn line_spectrum(bins: usize, df: f64, f: f64, hw: f64, height: f64) -> Vec<f64> {
    (0..bins)
        .map(|k| {
            let x = (k as f64 * df - f) / hw;
            1.0 + height / (1.0 + x * x)
        })
        .collect()
}

fn px(img: &Rgb, x: i32, y: i32) -> [u8; 3] {
    let i = ((y as u32 * img.width + x as u32) * 3) as usize;
    [img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]]
}

/// The data value at pixel column `x` / row `y` of the plotting area.
fn x_value(a: &PlotArea, x: i32) -> f64 {
    a.x_range.0 + (x - a.x_px.0) as f64 / (a.x_px.1 - a.x_px.0) as f64 * (a.x_range.1 - a.x_range.0)
}
fn y_value(a: &PlotArea, y: i32) -> f64 {
    a.y_range.1 - (y - a.y_px.0) as f64 / (a.y_px.1 - a.y_px.0) as f64 * (a.y_range.1 - a.y_range.0)
}

/// The column of the topmost blue (the curve's colour) pixel: the peak.
fn curve_top(img: &Rgb, a: &PlotArea) -> (i32, i32) {
    for y in a.y_px.0..a.y_px.1 {
        for x in a.x_px.0..a.x_px.1 {
            let [r, g, b] = px(img, x, y);
            if b > 200 && r < 80 && g < 80 {
                return (x, y);
            }
        }
    }
    panic!("no curve drawn");
}

#[test]
fn power_plot_puts_the_peak_and_its_mark_where_the_line_is() {
    let (df, f) = (0.5, 123.0);
    let p = line_spectrum(601, df, f, 1.0, 1e4);
    let peaks = vibroscope_math::peaks::find_peaks(&p, 0.0, df, &Default::default());
    let (img, area) = power_plot(&p, 0.0, df, (0.0, 300.0), &peaks, (900, 450)).unwrap();
    assert_eq!((img.width, img.height), (900, 450));
    let (x, y) = curve_top(&img, &area);
    let px_hz = (area.x_range.1 - area.x_range.0) / (area.x_px.1 - area.x_px.0) as f64;
    eprintln!(
        "curve top at {:.2} Hz, {:.1} dB (line at {f} Hz, 40 dB; one pixel = {px_hz:.2} Hz)",
        x_value(&area, x),
        y_value(&area, y)
    );
    assert!((x_value(&area, x) - f).abs() <= 2.0 * px_hz);
    assert!((y_value(&area, y) - 40.0).abs() < 1.0);
    // The peak's red mark is drawn around it.
    let red = (x - 8..=x + 8)
        .flat_map(|xx| (y - 8..=y + 8).map(move |yy| (xx, yy)))
        .filter(|&(xx, yy)| {
            let [r, g, b] = px(&img, xx, yy);
            r > 200 && g < 80 && b < 80
        })
        .count();
    assert!(red > 10, "{red} red pixels near the peak");
    // Valid PNG.
    let back = image::load_from_memory(&img.png().unwrap()).unwrap();
    assert_eq!((back.width(), back.height()), (900, 450));
}

#[test]
fn spectrogram_rows_follow_the_tone_over_time() {
    let (df, bins) = (2.0, 151);
    // 50 Hz for the first 20 spectra, 200 Hz for the next 20.
    let spectra: Vec<TimedSpectrum> = (0..40)
        .map(|i| TimedSpectrum {
            t_s: i as f64 * 0.1,
            power: line_spectrum(bins, df, if i < 20 { 50.0 } else { 200.0 }, 2.0, 1e5),
        })
        .collect();
    let (img, a) = spectrogram_plot(&spectra, 0.0, df, (0.0, 300.0), (800, 400)).unwrap();
    let row_of = |f: f64| {
        a.y_px.0
            + ((a.y_range.1 - f) / (a.y_range.1 - a.y_range.0) * (a.y_px.1 - a.y_px.0) as f64)
                as i32
    };
    let col_of = |t: f64| {
        a.x_px.0
            + ((t - a.x_range.0) / (a.x_range.1 - a.x_range.0) * (a.x_px.1 - a.x_px.0) as f64)
                as i32
    };
    let bright = |x: i32, y: i32| px(&img, x, y).iter().map(|&v| v as u32).sum::<u32>();
    let (early, late) = (col_of(0.9), col_of(3.0));
    for (f, on, off) in [(50.0, early, late), (200.0, late, early)] {
        let y = row_of(f);
        let quiet = row_of(125.0);
        eprintln!(
            "{f} Hz row: {} when sounding, {} when not; a quiet row (125 Hz): {}",
            bright(on, y),
            bright(off, y),
            bright(on, quiet)
        );
        assert!(bright(on, y) > bright(off, y) + 150);
        assert!(bright(on, y) > bright(on, quiet) + 150);
    }
}

/// `vibroscope spectrum` on a rendered 120 Hz tone: the JSON, a power plot
/// and a spectrogram, each a valid PNG of the default size; the power
/// plot's highest point is at 120 Hz.
#[test]
fn spectrum_command_writes_the_plots() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "width = 64\nheight = 64\nfps = 1000.0\nduration_s = 1.0\namplitude_px = 0.1\n\
                 signal = { type = \"tone\", freq_hz = 120.0 }\n";
    std::fs::write(dir.path().join("s.toml"), scene).unwrap();
    let o = run_in(dir.path(), &["simulate", "s.toml", "-o", "s.y4m"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let o = run_in(
        dir.path(),
        &[
            "spectrum",
            "s.y4m",
            "--json",
            "s.json",
            "--png",
            "p.png",
            "--spectrogram",
            "g.png",
            "--spectrogram-window",
            "128",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    for f in ["p.png", "g.png"] {
        let img = image::open(dir.path().join(f)).unwrap();
        assert_eq!((img.width(), img.height()), (900, 450), "{f}");
    }
    // Where the command's plot has its data: the same layout as a plot of
    // the same band and size (the layout does not depend on the values).
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    let df = json["resolution_hz"].as_f64().unwrap();
    let bins = (json["sample_rate_hz"].as_f64().unwrap() / 2.0 / df).round() as usize + 1;
    let flat = vec![1.0; bins];
    let (_, area) = amplitude_plot(&flat, df, (0.0, 500.0), &[], "", "", (900, 450)).unwrap();
    let img = image::open(dir.path().join("p.png")).unwrap().to_rgb8();
    let rgb = Rgb {
        width: img.width(),
        height: img.height(),
        pixels: img.into_raw(),
    };
    let (x, y) = curve_top(&rgb, &area);
    let px_hz = 500.0 / (area.x_px.1 - area.x_px.0) as f64;
    eprintln!("amplitude plot peak at {:.1} Hz", x_value(&area, x));
    assert!((x_value(&area, x) - 120.0).abs() <= 2.0 * px_hz + df);
    // The peak's mark (its amplitude from the report, in the same unit as
    // the axis) sits on the curve's top: the red circle's centre.
    let (mut sy, mut n) = (0i64, 0i64);
    for yy in area.y_px.0..area.y_px.1 {
        for xx in area.x_px.0..area.x_px.1 {
            let [r, g, b] = px(&rgb, xx, yy);
            if r > 200 && g < 80 && b < 80 {
                sy += i64::from(yy);
                n += 1;
            }
        }
    }
    assert!(n > 0, "no peak mark drawn");
    let mark_y = (sy / n) as i32;
    eprintln!("peak mark at row {mark_y}, curve top at row {y}");
    assert!((mark_y - y).abs() <= 6, "mark {mark_y} vs curve {y}");
}
