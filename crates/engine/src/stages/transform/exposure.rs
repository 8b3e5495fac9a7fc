//! `exposure`: undoes what it can of the rolling-shutter exposure boxcar
//! (thesis ch. 4.5; [`vibroscope_math::exposure`]) and optionally resamples to a
//! standard rate.
//!
//! `mode = "lowpass"` (default) keeps what lies below the boxcar's first
//! null at 1/`exposure_us`; `"compensate"` also inverts the boxcar where its
//! gain is above `floor_db` (-12 dB). Both are linear-phase FIR filters, so
//! the output's time stamps stay exact: a row exposed over [t, t + E]
//! stands for its centre t + E/2, and the filter's delay is taken off. With
//! `rate_hz` set, the filtered stream (band-limited to 1/E, far below 1/d)
//! is resampled by cubic interpolation. A block that does not follow its
//! predecessor in time starts a new segment (filter state reset).

use super::gap_fill::LatencyMeter;
use crate::*;
use std::sync::Arc;
use vibroscope_math::exposure::{default_taps, design, CubicResampler, Fir, Mode};

params! {
    /// `exposure`'s parameters.
    pub struct ExposureParams for "exposure" {
        exposure_us: f64 = ParamSpec::of(ParamType::Float, Def::Required)
            .range(Range::Float {
                lo: 0.0,
                lo_open: true,
                hi: 1e7,
                hi_open: false,
            })
            .unit("µs")
            .doc("each row's exposure time E (the boxcar's length)"),
        mode: Mode = ParamSpec::of(
            ParamType::Choice(&["lowpass", "compensate"]),
            Def::Str("lowpass"),
        )
        .doc("keep what lies below the first null 1/E, or also invert the boxcar"),
        floor_db: f64 = ParamSpec::of(ParamType::Float, Def::Float(-12.0))
            .range(Range::Float {
                lo: -60.0,
                lo_open: false,
                hi: 0.0,
                hi_open: true,
            })
            .unit("dB")
            .doc("compensate: lowest boxcar gain inverted"),
        taps: Option<usize> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(3, 8191)
            .doc("FIR length (odd); default about eight exposures"),
        rate_hz: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .floats(100.0, 1e6)
            .unit("Hz")
            .doc("resample the output to this rate; default: the input's"),
        report_latency: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("print the output's wall-clock latency at the end (live runs)"),
    }
}

type P = ExposureParams;

pub const KIND: KindSpec = KindSpec {
    name: "exposure",
    summary: "rolling shutter: low-pass at the exposure boxcar's first null 1/E, or invert it above -12 dB; optional resampling (rate_hz)",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        Ok(Box::new(ExposurePlan(v)))
    },
};

struct ExposurePlan(P);

impl Plan for ExposurePlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Exposure {
            p: self.0,
            seg: None,
            buf: Vec::new(),
            lat: LatencyMeter::default(),
        })))
    }
}

/// One stretch of contiguous input.
struct Segment {
    rate_in: f64,
    rate_out: f64,
    fir: Fir,
    resampler: Option<CubicResampler>,
    /// Time of output sample 0 of the segment, ns (as f64 for exactness of sums).
    t0_out_ns: f64,
    produced: u64,
    /// Where the next input block should start, ns.
    next_in_ns: f64,
}

struct Exposure {
    p: P,
    seg: Option<Segment>,
    buf: Vec<f32>,
    lat: LatencyMeter,
}

impl Exposure {
    fn start(&self, a: &AudioBlock) -> Result<Segment, StageError> {
        let e_s = self.p.exposure_us * 1e-6;
        let taps = self.p.taps.unwrap_or_else(|| default_taps(e_s, a.rate_hz));
        if 1.0 / e_s >= 0.5 * a.rate_hz {
            tracing::warn!(
                exposure_us = self.p.exposure_us,
                rate_hz = a.rate_hz,
                "the exposure null is above Nyquist; the filter only band-limits"
            );
        }
        let h = design(self.p.mode, e_s, a.rate_hz, taps, self.p.floor_db);
        let fir = Fir::new(h);
        let delay_ns = fir.delay() as f64 * 1e9 / a.rate_hz;
        let rate_out = self.p.rate_hz.unwrap_or(a.rate_hz);
        Ok(Segment {
            rate_in: a.rate_hz,
            rate_out,
            resampler: self.p.rate_hz.map(|r| CubicResampler::new(a.rate_hz, r)),
            fir,
            // Eq. 4.4 with exposure: the row is the mean over [t, t + E].
            t0_out_ns: a.t0_ns as f64 - delay_ns + 0.5 * e_s * 1e9,
            produced: 0,
            next_in_ns: a.t0_ns as f64,
        })
    }
}

impl Stage for Exposure {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Audio(a) = item else {
            return Err(StageError::expected("audio"));
        };
        if a.samples.is_empty() {
            return Ok(());
        }
        if self.p.report_latency {
            let newest = a.t0_ns + ((a.samples.len() - 1) as f64 * 1e9 / a.rate_hz).round() as i64;
            self.lat.arrived(std::time::Instant::now(), newest);
        }
        let contiguous = self.seg.as_ref().is_some_and(|s| {
            s.rate_in == a.rate_hz && (a.t0_ns as f64 - s.next_in_ns).abs() <= 0.5e9 / a.rate_hz
        });
        if !contiguous {
            self.seg = Some(self.start(&a)?);
        }
        let Some(seg) = self.seg.as_mut() else {
            return Ok(());
        };
        self.buf.clear();
        for &x in a.samples.iter() {
            let y = seg.fir.step(x as f64);
            match seg.resampler.as_mut() {
                Some(r) => r.push(y, &mut self.buf),
                None => self.buf.push(y as f32),
            }
        }
        seg.next_in_ns = a.t0_ns as f64 + a.samples.len() as f64 * 1e9 / a.rate_hz;
        if self.buf.is_empty() {
            return Ok(());
        }
        let t0 = seg.t0_out_ns + seg.produced as f64 * 1e9 / seg.rate_out;
        seg.produced += self.buf.len() as u64;
        let _ = out.emit(Item::Audio(AudioBlock {
            t0_ns: t0.round() as i64,
            rate_hz: seg.rate_out,
            samples: Arc::from(&self.buf[..]),
        }));
        if self.p.report_latency {
            self.lat.emitted(t0.round() as i64);
        }
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        if let (true, Some((max, mean))) = (self.p.report_latency, self.lat.summary_ms()) {
            eprintln!(
                "exposure latency (oldest sample of each block, capture to emission): max {max:.2} ms, mean {mean:.2} ms over {} blocks",
                self.lat.blocks()
            );
        }
        Ok(())
    }
}
