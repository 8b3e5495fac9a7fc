//! `peaks`: resonances of a motion spectrum, written as one JSON document at
//! the end (atomically). The spectra that arrive are averaged (one from
//! `spectrum` in `mode = "whole"`; from a sliding `spectrum`, the mean over
//! the run), then peaks are picked by prominence, kept when significant
//! against their local noise floor (`false_alarm`), listed strongest first,
//! and their damping estimated ([`vibroscope_math::peaks`]). Each line is fitted as seen through the
//! spectral window of the taper the spectrum carries ([`Spectrum::taper`]),
//! so the taper is not restated here.
//!
//! ```json
//! {"sample_rate_hz": 600.0, "resolution_hz": 0.29, "spectra_averaged": 1,
//!  "peaks": [{"frequency_hz", "frequency_std_hz", "damping_ratio",
//!             "damping_ratio_std", "damping_method", "power_db",
//!             "prominence_db", "floor_db", "false_alarm",
//!             "damping_estimates": [{"method", "damping_ratio",
//!             "damping_ratio_std"}], "fit_range_hz", "resolved",
//!             "class": "resonance", "class_reason": ""}],
//!  "others": [...]}
//! ```
//! `peaks` holds the resonances only; `others` the peaks the resonance test
//! turned away (`class` `drift` or `broadband`, with `class_reason`), never
//! ranked among them ([`vibroscope_math::peaks::find_peaks_classified`]).
//! `include_spectrum = true` adds `"spectrum": {"f0_hz", "resolution_hz",
//! "power_db": [...]}`.

use crate::stages::transform::peak_search::{
    check_band, search_options, FALSE_ALARM, MAX_HZ, MIN_HZ, MIN_PROMINENCE,
};
use crate::*;
use std::path::PathBuf;
use std::sync::Arc;
use vibroscope_math::peaks::find_peaks_classified;

params! {
    /// `peaks`'s parameters.
    pub struct PeaksParams for "peaks" {
        path: PathBuf = ParamSpec::of(ParamType::Path, Def::Required)
            .doc("the JSON file (written atomically at the end)"),
        peaks: usize = ParamSpec::of(ParamType::Int, Def::Int(5))
            .ints(1, 1000)
            .doc("most prominent peaks reported"),
        min_prominence_db: f64 = MIN_PROMINENCE,
        min_hz: Option<f64> = MIN_HZ,
        max_hz: Option<f64> = MAX_HZ,
        false_alarm: f64 = FALSE_ALARM,
        include_spectrum: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("add the mean spectrum (dB) to the JSON"),
    }
}

type P = PeaksParams;

pub const KIND: KindSpec = KindSpec {
    name: "peaks",
    summary: "picks resonances (prominence) of the mean spectrum, with damping and uncertainties, as JSON at the end",
    inputs: &[InPort::one(&[PortType::Spectrum])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        check_band(p, v.min_hz, v.max_hz)?;
        Ok(Box::new(PeaksPlan(v)))
    },
};

struct PeaksPlan(P);

impl Plan for PeaksPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Peaks {
            p: self.0,
            sum: Vec::new(),
            count: 0,
            f0: 0.0,
            df: 0.0,
            last: None,
        })))
    }
}

struct Peaks {
    p: P,
    sum: Vec<f64>,
    count: usize,
    f0: f64,
    df: f64,
    /// The facts of the last spectrum (taper, window, rate).
    last: Option<Spectrum>,
}

impl Stage for Peaks {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let Item::Spectrum(s) = item else {
            return Ok(());
        };
        if s.power.len() != self.sum.len() || s.resolution_hz != self.df || s.f0_hz != self.f0 {
            // A new layout: start the average again.
            self.sum = vec![0.0; s.power.len()];
            self.count = 0;
            self.f0 = s.f0_hz;
            self.df = s.resolution_hz;
        }
        for (a, &p) in self.sum.iter_mut().zip(s.power.iter()) {
            *a += p as f64;
        }
        self.count += 1;
        self.last = Some(Spectrum {
            power: Arc::from([]),
            ..s
        });
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        let Some(last) = self.last.as_ref().filter(|_| self.count > 0) else {
            return Err(StageError::dsp(format!(
                "{}: no spectrum arrived (is the recording shorter than one window?)",
                self.p.path.display()
            )));
        };
        let mean: Vec<f64> = self.sum.iter().map(|s| s / self.count as f64).collect();
        let p = &self.p;
        let opts = search_options(
            p.peaks,
            p.min_prominence_db,
            p.min_hz,
            p.max_hz,
            p.false_alarm,
            last,
            self.count,
        );
        let (peaks, others) = find_peaks_classified(&mean, self.f0, self.df, &opts);
        for pk in &peaks {
            tracing::info!(
                frequency_hz = pk.frequency_hz,
                damping_ratio = pk.damping_ratio,
                method = %pk.damping_method,
                "peak"
            );
        }
        let mut doc = serde_json::json!({
            "sample_rate_hz": last.rate_hz,
            "taper": last.taper.name(),
            "resolution_hz": self.df,
            "spectra_averaged": self.count,
            "peaks": peaks,
            "others": others,
        });
        if self.p.include_spectrum {
            let db: Vec<f64> = mean
                .iter()
                .map(|&p| 10.0 * p.max(f64::MIN_POSITIVE).log10())
                .collect();
            doc["spectrum"] = serde_json::json!({
                "f0_hz": self.f0,
                "resolution_hz": self.df,
                "power_db": db,
            });
        }
        let text = serde_json::to_vec_pretty(&doc)
            .map_err(|e| StageError::file("write", &self.p.path, e.into()))?;
        super::write_atomic(&self.p.path, &text)
    }
}
