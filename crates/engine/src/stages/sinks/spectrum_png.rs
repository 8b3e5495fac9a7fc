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

use crate::stages::transform::peak_search;
use crate::stages::transform::spectrum::TaperExt;
use crate::*;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use vibroscope_io::plot::{power_plot, spectrogram_plot, TimedSpectrum};
use vibroscope_math::peaks::{find_peaks, PeakOptions};

#[derive(Deserialize, Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum Style {
    Power,
    Spectrogram,
}

const SIDE: (i64, i64) = (vibroscope_io::plot::MIN_SIDE as i64, 8192);

params! {
    /// `spectrum_png`'s parameters.
    pub struct SpectrumPngParams for "spectrum_png" {
        path: PathBuf = ParamSpec::of(ParamType::Path, Def::Required)
            .doc("the PNG file (written atomically at the end)"),
        style: Style = ParamSpec::of(ParamType::Choice(&["power", "spectrogram"]), Def::Str("power"))
            .doc("mean spectrum in dB with peaks marked, or every spectrum as a column"),
        peaks: usize = ParamSpec::of(ParamType::Int, Def::Int(5))
            .ints(0, 100)
            .doc("power: most prominent peaks marked (0 = none)"),
        min_hz: Option<f64> = peak_search::MIN_HZ
            .doc("lower edge of the band shown; default: the first bin"),
        max_hz: Option<f64> = peak_search::MAX_HZ
            .doc("upper edge of the band shown (> min_hz); default: Nyquist"),
        width: u32 = ParamSpec::of(ParamType::Int, Def::Int(900))
            .ints(SIDE.0, SIDE.1)
            .unit("px")
            .doc("image width"),
        height: u32 = ParamSpec::of(ParamType::Int, Def::Int(450))
            .ints(SIDE.0, SIDE.1)
            .unit("px")
            .doc("image height"),
    }
}

type P = SpectrumPngParams;

pub const KIND: KindSpec = KindSpec {
    name: "spectrum_png",
    summary: "PNG plot of spectra at the end: style = \"power\" (mean spectrum in dB, peaks marked) or \"spectrogram\"",
    inputs: &[InPort::one(&[PortType::Spectrum])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        peak_search::check_band(p, v.min_hz, v.max_hz)?;
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
            kernel: Vec::new(),
            segments: 1,
        })))
    }
}

struct SpectrumPng {
    p: P,
    spectra: Vec<TimedSpectrum>,
    f0: f64,
    df: f64,
    /// The spectral window of the spectra's taper (for the peak fits).
    kernel: Vec<f64>,
    /// Welch segments of each spectrum (for the peaks' significance).
    segments: usize,
}

impl SpectrumPng {
    /// The plot could not be drawn or encoded.
    fn err(&self, m: impl std::fmt::Display) -> StageError {
        StageError::file("write", &self.p.path, std::io::Error::other(m.to_string()))
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
            self.segments = s.segments.max(1);
            self.kernel = if self.p.peaks > 0 {
                s.taper.power_kernel(s.window, 4)
            } else {
                Vec::new()
            };
        }
        self.spectra.push(TimedSpectrum {
            t_s: s.t_ns as f64 * 1e-9,
            power: s.power.iter().map(|&p| p as f64).collect(),
        });
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        let Some(first) = self.spectra.first() else {
            return Err(StageError::dsp(format!(
                "{}: no spectrum arrived (is the recording shorter than one window?)",
                self.p.path.display()
            )));
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
                        window_kernel: self.kernel.clone(),
                        // As the `peaks` sink: segments times spectra.
                        segments: self.segments.saturating_mul(self.spectra.len()),
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
