//! `rows`: a rolling-shutter camera as a row-rate sensor (thesis ch. 4.5).
//!
//! Row y of frame n is captured at t_n + y·d (line delay d, exposed for E),
//! so each row is one motion sample (Eq. 4.4: row y shows
//! B(x - α s(t_n + y d), y)). Per row, 1-D local phase along x with A²
//! weights from one or more scales ([`vibroscope_math::row_phase`]) gives the
//! displacement in pixels; every sample carries its capture time in
//! `times_ns` and the block's `rate_hz` is 1/d. A frame's samples leave as
//! soon as its rows are processed.
//!
//! The reference of row y is row y of the first frame, which moved with the
//! signal at its own time: left alone, that offset repeats every frame (a
//! comb at the frame rate and its harmonics, as strong as the signal). Each
//! row therefore subtracts its own running mean over frames (cumulative,
//! then exponential with time constant `row_mean_s`): a notch about
//! 1/(2π row_mean_s) Hz wide at each harmonic of the frame rate, which also
//! removes fixed differences between rows. The first frame reads zero.
//!
//! The line delay comes from `line_delay_us` or, when absent, from the
//! camera (the frame format's row timing). `frame_delay_us`, when given, is
//! checked against the frame period and the row count (the gap is
//! otherwise implied by the frames' own timestamps).

use super::roi::{Roi, RoiParam};
use crate::*;
use std::sync::Arc;
use vibroscope_math::row_phase::{RowPhase, MAX_WAVELENGTH_PX, MIN_WAVELENGTH_PX};

/// `line_delay_us`, shared with `synthetic`.
pub const LINE_DELAY_US: ParamSpec = ParamSpec::new(
    "line_delay_us",
    ParamType::Float,
    Def::Optional,
)
.above_upto(0.0, 1e6)
.unit("µs")
.doc(
    "rolling shutter: time between the starts of consecutive rows; default: the frames' row timing",
);
/// `frame_delay_us`, shared with `synthetic`.
pub const FRAME_DELAY_US: ParamSpec =
    ParamSpec::new("frame_delay_us", ParamType::Float, Def::Optional)
        .floats(0.0, 1e7)
        .unit("µs")
        .doc("blind time between a frame's last row and the next's first (checked only)");

params! {
    /// `rows`'s parameters.
    pub struct RowsParams for "rows" {
        line_delay_us: Option<f64> = LINE_DELAY_US,
        frame_delay_us: Option<f64> = FRAME_DELAY_US,
        wavelengths_px: Vec<f64> = ParamSpec::of(ParamType::Floats, Def::Toml("[8.0, 16.0]"))
            .floats(MIN_WAVELENGTH_PX, MAX_WAVELENGTH_PX)
            .unit("px")
            .doc("Gabor wavelengths along x, one per scale (1 to 8)"),
        roi: Option<RoiParam> = super::reduce::ROI,
        row_mean_s: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.5))
            .at_least(0.0)
            .unit("s")
            .doc("time constant of the per-row running mean removed (0 = off)"),
    }
}

type P = RowsParams;

/// Relative tolerance when a stated frame delay is checked against
/// 1/fps - rows·d (spec sheets round; the thesis' own DSLR figures are 0.9% apart).
pub const FRAME_DELAY_TOLERANCE: f64 = 0.02;

/// Checks a line delay given in µs; the message names the value.
pub fn check_line_delay_us(v: f64) -> Result<f64, String> {
    if v.is_finite() && v > 0.0 && v <= 1e6 {
        Ok(v)
    } else {
        Err(format!("must be > 0 and at most 1e6 us, got {v}"))
    }
}

/// Checks a frame or exposure time given in µs (>= 0).
pub fn check_time_us(v: f64) -> Result<f64, String> {
    if v.is_finite() && (0.0..=1e7).contains(&v) {
        Ok(v)
    } else {
        Err(format!("must be >= 0 and at most 1e7 us, got {v}"))
    }
}

/// The frame delay implied by `rows` rows at line delay `d_us` and `fps`,
/// after checking that the rows fit in the frame period and that a stated
/// `frame_delay_us` agrees within [`FRAME_DELAY_TOLERANCE`] of the period.
/// Errors name the field to fix.
pub fn frame_delay_us(
    rows: usize,
    d_us: f64,
    fps: f64,
    stated_us: Option<f64>,
) -> Result<f64, (&'static str, String)> {
    let period = 1e6 / fps;
    let readout = rows as f64 * d_us;
    if readout > period * (1.0 + 1e-9) {
        return Err((
            "line_delay_us",
            format!(
                "{d_us} us x {rows} rows = {readout:.1} us is longer than the frame period {period:.1} us ({fps} fps)"
            ),
        ));
    }
    let implied = (period - readout).max(0.0);
    if let Some(g) = stated_us {
        if (g - implied).abs() > FRAME_DELAY_TOLERANCE * period {
            return Err((
                "frame_delay_us",
                format!(
                    "{g} us is inconsistent with {fps} fps and {rows} rows x {d_us} us: the frame period {period:.1} us leaves {implied:.1} us"
                ),
            ));
        }
    }
    Ok(implied)
}

pub const KIND: KindSpec = KindSpec {
    name: "rows",
    summary: "rolling shutter: one motion sample per row (1-D local phase along x, A² weights) at its capture time",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: &[OutPort::out(PortType::Samples)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        if v.wavelengths_px.is_empty() || v.wavelengths_px.len() > 8 {
            return Err(p.error(
                "wavelengths_px",
                format!("give 1 to 8 wavelengths, got {}", v.wavelengths_px.len()),
            ));
        }
        if let Some(r) = &v.roi {
            r.check().map_err(|m| p.error("roi", m))?;
        }
        Ok(Box::new(RowsPlan(v)))
    },
};

struct RowsPlan(P);

impl Plan for RowsPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Rows {
            p: self.0,
            st: None,
        })))
    }
}

struct State {
    est: RowPhase,
    roi: Roi,
    width: usize,
    height: usize,
    d_ns: f64,
    /// Smallest per-frame weight of the running mean (frame period / row_mean_s).
    alpha_min: f64,
    line: Vec<f32>,
    mean: Vec<f64>,
    frames: u64,
    last_t: Option<i64>,
    values: Vec<f32>,
    times: Vec<i64>,
}

struct Rows {
    p: P,
    st: Option<State>,
}

fn load_row(px: PixelsRef<'_>, start: usize, dst: &mut [f32]) {
    let end = start + dst.len();
    match px {
        PixelsRef::U8(d) => dst
            .iter_mut()
            .zip(&d[start..end])
            .for_each(|(o, &v)| *o = v as f32),
        PixelsRef::U16(d) => dst
            .iter_mut()
            .zip(&d[start..end])
            .for_each(|(o, &v)| *o = v as f32),
    }
}

impl Rows {
    fn init(&self, f: &Frame) -> Result<State, StageError> {
        let fmt = f.format();
        let d_us = match (self.p.line_delay_us, fmt.row_timing) {
            (Some(d), _) => d,
            (None, Some(rt)) => rt.line_delay_ns * 1e-3,
            (None, None) => {
                return Err(StageError::config(
                    "line_delay_us",
                    "not set and the camera reports no row timing; \
                     give the line delay (or estimate it with `vibroscope rs-calibrate`)",
                ))
            }
        };
        check_line_delay_us(d_us).map_err(|m| StageError::config("line_delay_us", m))?;
        let (w, h) = (f.width(), f.height());
        let implied = frame_delay_us(h, d_us, fmt.fps, self.p.frame_delay_us)
            .map_err(|(field, m)| StageError::config(field, m))?;
        let roi = Roi::resolve(self.p.roi.as_ref(), w, h)?;
        let est = RowPhase::new(w, roi.x, roi.x + roi.w, roi.h, &self.p.wavelengths_px)
            .map_err(|m| StageError::config("wavelengths_px", format!("(with the roi) {m}")))?;
        tracing::info!(
            line_delay_us = d_us,
            frame_delay_us = implied,
            rows = h,
            rate_hz = 1e6 / d_us,
            missing = implied / (implied + h as f64 * d_us),
            "rolling shutter"
        );
        let alpha_min = if self.p.row_mean_s > 0.0 {
            (1.0 / (fmt.fps * self.p.row_mean_s)).min(1.0)
        } else {
            0.0
        };
        Ok(State {
            est,
            roi,
            width: w,
            height: h,
            d_ns: d_us * 1e3,
            alpha_min,
            line: vec![0.0; w],
            mean: vec![0.0; roi.h],
            frames: 0,
            last_t: None,
            values: Vec::with_capacity(roi.h),
            times: Vec::with_capacity(roi.h),
        })
    }
}

impl Stage for Rows {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        if self.st.is_none() {
            self.st = Some(self.init(&f)?);
        }
        let use_mean = self.p.row_mean_s > 0.0;
        let Some(st) = self.st.as_mut() else {
            return Ok(());
        };
        if (f.width(), f.height()) != (st.width, st.height) {
            return Err(StageError::format("the frame size changed mid-stream"));
        }
        let t = f.meta().t_ns;
        if let Some(prev) = st.last_t {
            let readout = st.height as f64 * st.d_ns;
            if ((t - prev) as f64) < readout * (1.0 - 1e-6) {
                return Err(StageError::config(
                    "line_delay_us",
                    format!(
                        "frames {} ns apart, but {} rows x line delay take {readout:.0} ns: \
                     too long for these timestamps",
                        t - prev,
                        st.height
                    ),
                ));
            }
        }
        st.last_t = Some(t);
        let first = st.frames == 0;
        // Cumulative mean for the first frames, then exponential.
        let alpha = if st.frames == 0 {
            0.0
        } else {
            (1.0 / st.frames as f64).max(st.alpha_min)
        };
        st.values.clear();
        st.times.clear();
        let px = f.pixels();
        for i in 0..st.roi.h {
            let y = st.roi.y + i;
            load_row(px, y * st.width, &mut st.line);
            let u = if first {
                st.est.set_reference(i, &st.line);
                0.0
            } else {
                st.est.displacement(i, &st.line)
            };
            let v = if use_mean && !first {
                let v = u - st.mean[i];
                st.mean[i] += alpha * (u - st.mean[i]);
                v
            } else {
                u
            };
            st.values.push(v as f32);
            st.times.push(t + (y as f64 * st.d_ns).round() as i64);
        }
        st.frames += 1;
        let _ = out.emit(Item::Samples(SampleBlock {
            t0_ns: st.times[0],
            rate_hz: 1e9 / st.d_ns,
            channels: 1,
            data: Arc::from(&st.values[..]),
            times_ns: Some(Arc::from(&st.times[..])),
        }));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_delay_checks_name_the_field() {
        // The thesis DSLR: 720 rows x 16 us at 60 fps leaves 5146.7 us; 5 ms is within 2%.
        let g = frame_delay_us(720, 16.0, 60.0, Some(5000.0)).unwrap();
        assert!((g - 5146.67).abs() < 0.1, "{g}");
        assert_eq!(
            frame_delay_us(720, 16.0, 60.0, Some(9000.0)).unwrap_err().0,
            "frame_delay_us"
        );
        assert_eq!(
            frame_delay_us(720, 30.0, 60.0, None).unwrap_err().0,
            "line_delay_us"
        );
        assert!(check_line_delay_us(0.0).is_err());
        assert!(check_line_delay_us(f64::NAN).is_err());
        assert!(check_time_us(-1.0).is_err());
    }
}
