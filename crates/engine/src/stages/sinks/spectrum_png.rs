//! `spectrum_png`: a PNG plot of the spectra that arrive, written at the
//! end ([`vibroscope_io::plot`]). `style = "power"`: the mean spectrum
//! in dB against frequency, with the `peaks` most prominent peaks marked
//! (picked as the `peaks` sink picks them); `style = "spectrogram"`: every
//! spectrum as one column, time along x, frequency up.
//!
//! ```toml
//! [[stage]]
//! id = "plot"
//! kind = "spectrum_png"
//! input = "spectrum"
//! path = "spectrum.png"
//! style = "power"      # or "spectrogram"
//! peaks = 5            # power: peaks marked (0 = none)
//! min_hz = 20.0        # optional band shown
//! max_hz = 500.0
//! width = 900
//! height = 450
//! ```

use crate::*;
use serde::Deserialize;
use std::path::PathBuf;
use vibroscope_io::plot::{power_plot, spectrogram_plot, TimedSpectrum};
use vibroscope_math::peaks::{find_peaks, PeakOptions};

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
enum Style {
    Power,
    Spectrogram,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    path: PathBuf,
    #[serde(default = "d_style")]
    style: Style,
    #[serde(default = "d_peaks")]
    peaks: usize,
    min_hz: Option<f64>,
    max_hz: Option<f64>,
    #[serde(default = "d_width")]
    width: u32,
    #[serde(default = "d_height")]
    height: u32,
    /// The spectrum's taper (for the peak fits, as in `peaks`).
    #[serde(default = "d_taper")]
    taper: String,
}
fn d_style() -> Style {
    Style::Power
}
fn d_peaks() -> usize {
    5
}
fn d_width() -> u32 {
    900
}
fn d_height() -> u32 {
    450
}
fn d_taper() -> String {
    "hann".into()
}

pub const KIND: KindSpec = KindSpec {
    name: "spectrum_png",
    summary: "PNG plot of spectra at the end: style = \"power\" (mean spectrum in dB, peaks marked) or \"spectrogram\"",
    accepts: &[PortType::Spectrum],
    max_inputs: 1,
    output: Output::None,
    plan: |p| {
        let v: P = p.parse()?;
        if v.peaks > 100 {
            return Err(p.error("peaks", format!("must be 0..=100, got {}", v.peaks)));
        }
        for (name, n) in [("width", v.width), ("height", v.height)] {
            if !(vibroscope_io::plot::MIN_SIDE..=8192).contains(&n) {
                return Err(p.error(
                    name,
                    format!(
                        "must be {}..=8192 pixels, got {n}",
                        vibroscope_io::plot::MIN_SIDE
                    ),
                ));
            }
        }
        super::peaks::check_band_taper(p, v.min_hz, v.max_hz, &v.taper)?;
        Ok(Box::new(PlotPlan(v)))
    },
};

struct PlotPlan(P);

impl Plan for PlotPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(SpectrumPng {
            p: self.0,
            spectra: Vec::new(),
            f0: 0.0,
            df: 0.0,
        })))
    }
}

struct SpectrumPng {
    p: P,
    spectra: Vec<TimedSpectrum>,
    f0: f64,
    df: f64,
}

impl SpectrumPng {
    fn err(&self, m: impl std::fmt::Display) -> StageError {
        StageError::msg(format!("{}: {m}", self.p.path.display()))
    }
}

impl Stage for SpectrumPng {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let Item::Spectrum(s) = item else {
            return Ok(());
        };
        let same = self
            .spectra
            .first()
            .is_some_and(|f| f.power.len() == s.power.len());
        if !same || s.resolution_hz != self.df || s.f0_hz != self.f0 {
            // A new layout: start again (as `peaks` does).
            self.spectra.clear();
            self.f0 = s.f0_hz;
            self.df = s.resolution_hz;
        }
        self.spectra.push(TimedSpectrum {
            t_s: s.t_ns as f64 * 1e-9,
            power: s.power.iter().map(|&p| p as f64).collect(),
        });
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        let Some(first) = self.spectra.first() else {
            return Err(self.err("no spectrum arrived (is the recording shorter than one window?)"));
        };
        let bins = first.power.len();
        let nyquist = self.f0 + (bins.saturating_sub(1)) as f64 * self.df;
        let band = (
            self.p.min_hz.unwrap_or(self.f0),
            self.p.max_hz.unwrap_or(nyquist).min(nyquist),
        );
        let size = (self.p.width, self.p.height);
        let (rgb, _) = match self.p.style {
            Style::Power => {
                let n = self.spectra.len() as f64;
                let mut mean = vec![0.0; bins];
                for s in &self.spectra {
                    for (m, p) in mean.iter_mut().zip(&s.power) {
                        *m += p / n;
                    }
                }
                let peaks = if self.p.peaks > 0 {
                    let opts = PeakOptions {
                        max_peaks: self.p.peaks,
                        min_hz: self.p.min_hz,
                        max_hz: self.p.max_hz,
                        window_kernel: match super::peaks::taper_of(&self.p.taper).flatten() {
                            Some(t) => t.power_kernel(2 * (bins - 1), 4),
                            None => Vec::new(),
                        },
                        ..Default::default()
                    };
                    find_peaks(&mean, self.f0, self.df, &opts)
                } else {
                    Vec::new()
                };
                power_plot(&mean, self.f0, self.df, band, &peaks, size)
            }
            Style::Spectrogram => spectrogram_plot(&self.spectra, self.f0, self.df, band, size),
        }
        .map_err(|e| self.err(e))?;
        let png = rgb.png().map_err(|e| self.err(e))?;
        super::write_atomic(&self.p.path, &png)
    }
}
