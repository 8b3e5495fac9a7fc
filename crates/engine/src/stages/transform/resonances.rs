//! `resonances`: the resonances of a stream of spectra, as a stream of peak
//! sets (frequency, damping and amplitude with their uncertainties) that
//! `zenoh_pub` sends and `vibroscope monitor` tracks. Every `average`
//! spectra that arrive are averaged and their peaks picked exactly as the
//! `peaks` sink picks them at the end of a run ([`vibroscope_math::peaks`]:
//! prominence, significance against the local floor, damping through the
//! taper's spectral window). The set carries the time of the middle of the
//! spectra averaged; an empty set (nothing stood out) is still emitted, so a
//! downstream tracker sees the camera alive.

use super::peak_search::{check_band, search_options, FALSE_ALARM, MAX_HZ, MIN_HZ, MIN_PROMINENCE};
use crate::*;
use vibroscope_math::peaks::find_peaks;

params! {
    /// `resonances`'s parameters.
    pub struct ResonancesParams for "resonances" {
        peaks: usize = ParamSpec::of(ParamType::Int, Def::Int(5))
            .ints(1, 1000)
            .doc("most prominent peaks in each set"),
        min_prominence_db: f64 = MIN_PROMINENCE,
        min_hz: Option<f64> = MIN_HZ,
        max_hz: Option<f64> = MAX_HZ,
        false_alarm: f64 = FALSE_ALARM,
        average: usize = ParamSpec::of(ParamType::Int, Def::Int(1))
            .ints(1, 100_000)
            .doc("spectra averaged into each peak set (consecutive, not overlapping)"),
    }
}

type P = ResonancesParams;

pub const KIND: KindSpec = KindSpec {
    name: "resonances",
    summary: "picks the resonances of each spectrum (or of each `average` spectra) and emits them as a peak set: frequency, damping, power, with uncertainties",
    inputs: &[InPort::one(&[PortType::Spectrum])],
    outputs: &[OutPort::out(PortType::Peaks)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        check_band(p, v.min_hz, v.max_hz)?;
        Ok(Box::new(Plan_(v)))
    },
};

struct Plan_(P);

impl Plan for Plan_ {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Resonances {
            p: self.0,
            sum: Vec::new(),
            count: 0,
            first_t_ns: 0,
        })))
    }
}

struct Resonances {
    p: P,
    /// Running sum of the spectra of the current set.
    sum: Vec<f64>,
    count: usize,
    first_t_ns: i64,
}

impl Stage for Resonances {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Spectrum(s) = item else {
            return Ok(());
        };
        if s.power.len() != self.sum.len() {
            // The first spectrum, or a new layout: start the set again.
            self.sum.clear();
            self.sum.resize(s.power.len(), 0.0);
            self.count = 0;
        }
        if self.count == 0 {
            self.first_t_ns = s.t_ns;
        }
        for (a, &p) in self.sum.iter_mut().zip(s.power.iter()) {
            *a += p as f64;
        }
        self.count += 1;
        if self.count < self.p.average {
            return Ok(());
        }
        let n = self.count as f64;
        self.sum.iter_mut().for_each(|a| *a /= n);
        let p = &self.p;
        let opts = search_options(
            p.peaks,
            p.min_prominence_db,
            p.min_hz,
            p.max_hz,
            p.false_alarm,
            &s,
            self.count,
        );
        let peaks = find_peaks(&self.sum, s.f0_hz, s.resolution_hz, &opts);
        let t_ns = self.first_t_ns + (s.t_ns - self.first_t_ns) / 2;
        self.sum.iter_mut().for_each(|a| *a = 0.0);
        self.count = 0;
        // A closed downstream means the run is stopping; nothing to report.
        let _ = out.emit(Item::Peaks(PeakSet {
            t_ns,
            peaks: peaks.iter().map(Resonance::from).collect(),
        }));
        Ok(())
    }
}
