//! `magnify`: phase-based motion magnification (Wadhwa et al. 2013, the
//! complex steerable pyramid; 2014, the Riesz pyramid): frames in, frames
//! out, the motion in `[lo_hz, hi_hz]` multiplied by `factor` (below 1
//! attenuates, 0 removes it). See `vibroscope_math::magnify` for the
//! method. With `roi` only that region is processed and written; with
//! `side_by_side` each output frame holds the input (left) and the
//! magnified frame (right). Output frames come from the stage's own pool.

use super::reduce::ROI;
use super::roi::{Roi, RoiParam};
use crate::*;
use serde::Deserialize;
use vibroscope_math::magnify::{
    Magnifier, MagnifyError, MagnifyParams, PyramidKind, DEFAULT_MAX_PHASE, DEFAULT_ORDER,
    DEFAULT_ORIENTATIONS, DEFAULT_SIGMA,
};
use vibroscope_math::rng::mix64;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    lo_hz: f64,
    hi_hz: f64,
    factor: f64,
    pyramid: String,
    scales: usize,
    orientations: usize,
    order: usize,
    sigma_px: f64,
    max_phase_rad: f64,
    roi: Option<RoiParam>,
    side_by_side: bool,
}

const PARAMS: &[ParamSpec] = &[
    ParamSpec::new("lo_hz", ParamType::Float, Def::Required)
        .above(0.0)
        .unit("Hz")
        .doc("low edge of the band whose motion is magnified"),
    ParamSpec::new("hi_hz", ParamType::Float, Def::Required)
        .above(0.0)
        .unit("Hz")
        .doc("high edge of the band (below half the frame rate)"),
    ParamSpec::new("factor", ParamType::Float, Def::Float(10.0))
        .floats(0.0, 1e6)
        .doc("motion in the band is multiplied by this; below 1 attenuates, 0 removes it"),
    ParamSpec::new(
        "pyramid",
        ParamType::Choice(&["csp", "riesz"]),
        Def::Str("csp"),
    )
    .doc("csp: complex steerable (quality); riesz: Riesz on a Laplacian pyramid (speed)"),
    ParamSpec::new("scales", ParamType::Int, Def::Int(4))
        .ints(1, 16)
        .doc("pyramid scales (octaves)"),
    ParamSpec::new("orientations", ParamType::Int, Def::Int(DEFAULT_ORIENTATIONS as i64))
        .ints(1, 16)
        .doc("CSP orientations (8: motion in every direction is magnified evenly; the Riesz pyramid finds each pixel's own)"),
    ParamSpec::new("order", ParamType::Int, Def::Int(DEFAULT_ORDER as i64))
        .ints(1, 8)
        .doc("order of the causal Butterworth band-pass applied to each pixel's phase"),
    ParamSpec::new(
        "sigma_px",
        ParamType::Float,
        Def::Float(DEFAULT_SIGMA as f64),
    )
    .floats(0.0, 32.0)
    .unit("band px")
    .doc("σ of the amplitude-weighted smoothing of the phase (0 = none)"),
    ParamSpec::new(
        "max_phase_rad",
        ParamType::Float,
        Def::Float(DEFAULT_MAX_PHASE as f64),
    )
    .above_upto(0.0, 100.0)
    .unit("rad")
    .doc("limit of the magnified phase (π/2: a quarter of each band's wavelength)"),
    ROI,
    ParamSpec::new("side_by_side", ParamType::Bool, Def::Bool(false))
        .doc("write the input (left) and the magnified frame (right) side by side"),
];

pub const KIND: KindSpec = KindSpec {
    name: "magnify",
    summary:
        "phase-based motion magnification of a band (lo_hz..hi_hz, factor): frames in, frames out",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: &[OutPort::out(PortType::Frames)],
    params: PARAMS,
    plan: |p| {
        let v: P = p.resolve(PARAMS)?;
        // (An empty band, lo_hz = hi_hz, is refused with the frame rate.)
        if v.lo_hz > v.hi_hz {
            return Err(p.error(
                "hi_hz",
                format!(
                    "the band {} - {} Hz is inverted (lo_hz < hi_hz)",
                    v.lo_hz, v.hi_hz
                ),
            ));
        }
        if let Some(r) = &v.roi {
            r.check().map_err(|m| p.error("roi", m))?;
        }
        Ok(Box::new(MagnifyPlan(v)))
    },
};

struct MagnifyPlan(P);

impl Plan for MagnifyPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Magnify {
            p: self.0,
            pool_frames: ctx.pool_frames,
            run: None,
        })))
    }
}

/// What the first frame decides.
struct Run {
    /// Input frame size.
    size: (usize, usize),
    roi: Roi,
    magnifier: Magnifier,
    pool: FramePool,
    input: Vec<f32>,
    output: Vec<f32>,
    max: f32,
}

struct Magnify {
    p: P,
    pool_frames: usize,
    run: Option<Run>,
}

impl Magnify {
    fn start(&self, f: &Frame) -> Result<Run, StageError> {
        let fmt = *f.format();
        let roi = Roi::resolve(self.p.roi.as_ref(), f.width(), f.height())?;
        let csp = self.p.pyramid != "riesz";
        crate::memory::check(
            crate::memory::magnify_bound(
                roi.w,
                roi.h,
                self.p.orientations,
                csp,
                if self.p.side_by_side {
                    self.pool_frames.max(2)
                } else {
                    0
                },
            ),
            &format!(
                "magnifying {}x{} pixels with the {} pyramid{}",
                roi.w,
                roi.h,
                if csp { "steerable" } else { "Riesz" },
                if csp {
                    format!(" and {} orientations", self.p.orientations)
                } else {
                    String::new()
                }
            ),
            if csp {
                "give a region (roi), fewer orientations or the Riesz pyramid"
            } else {
                "give a region (roi)"
            },
        )
        .map_err(|message| StageError::Config {
            field: "memory",
            message,
        })?;
        let params = MagnifyParams {
            fps: fmt.fps,
            lo_hz: self.p.lo_hz,
            hi_hz: self.p.hi_hz,
            factor: self.p.factor as f32,
            order: self.p.order,
            sigma: self.p.sigma_px as f32,
            max_phase: self.p.max_phase_rad as f32,
            pyramid: if self.p.pyramid == "riesz" {
                PyramidKind::Riesz
            } else {
                PyramidKind::Csp
            },
            scales: self.p.scales,
            orientations: self.p.orientations,
        };
        let magnifier = Magnifier::new(roi.w, roi.h, params).map_err(|e| match e {
            MagnifyError::Param { field, message } => StageError::config(
                match field {
                    "band" => "hi_hz",
                    "factor" => "factor",
                    "fps" => "fps",
                    _ => "magnify",
                },
                message,
            ),
            MagnifyError::Pyramid(e) => StageError::dsp(format!("magnify: {e}")),
        })?;
        let out_w = if self.p.side_by_side {
            2 * roi.w
        } else {
            roi.w
        };
        let format = FrameFormat {
            width: out_w as u32,
            height: roi.h as u32,
            row_timing: None,
            ..fmt
        };
        tracing::info!(
            lo_hz = self.p.lo_hz,
            hi_hz = self.p.hi_hz,
            factor = self.p.factor,
            pyramid = %self.p.pyramid,
            centre_hz = magnifier.bandpass().centre_hz,
            "magnify: {}x{} region at ({}, {})",
            roi.w,
            roi.h,
            roi.x,
            roi.y
        );
        Ok(Run {
            size: (f.width(), f.height()),
            roi,
            magnifier,
            pool: FramePool::new(format, self.pool_frames.max(2)),
            input: vec![0.0; roi.w * roi.h],
            output: vec![0.0; roi.w * roi.h],
            max: fmt.max_value() as f32,
        })
    }
}

impl Stage for Magnify {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        if self.run.is_none() {
            self.run = Some(self.start(&f)?);
        }
        let Some(r) = self.run.as_mut() else {
            return Ok(());
        };
        let (fw, roi) = (f.width(), r.roi);
        if (f.width(), f.height()) != r.size {
            return Err(StageError::format(format!(
                "the frame size changed mid-stream ({}x{} to {}x{})",
                r.size.0,
                r.size.1,
                f.width(),
                f.height()
            )));
        }
        let src = f.pixels();
        for (y, row) in r.input.chunks_exact_mut(roi.w).enumerate() {
            let start = (roi.y + y) * fw + roi.x;
            match src {
                PixelsRef::U8(p) => row
                    .iter_mut()
                    .zip(&p[start..start + roi.w])
                    .for_each(|(o, v)| *o = *v as f32),
                PixelsRef::U16(p) => row
                    .iter_mut()
                    .zip(&p[start..start + roi.w])
                    .for_each(|(o, v)| *o = *v as f32),
            }
        }
        r.magnifier
            .process(&r.input, &mut r.output)
            .map_err(|e| StageError::dsp(format!("magnify: {e}")))?;
        let Some(mut o) = out.acquire(&r.pool) else {
            return Ok(());
        };
        *o.meta_mut() = *f.meta();
        let ow = o.format().width as usize;
        let side = self.p.side_by_side;
        let max = r.max;
        // The magnified frame is dithered (uniform, ±½ DN) before rounding:
        // a change smaller than half a level would otherwise round back to
        // the input's own integers, and small motions (or factors near 1)
        // would vanish in a dead zone. Deterministic per frame and pixel.
        let key = mix64(f.meta().seq ^ 0x006d_6167_6e69_6679);
        let dither = |i: usize| (mix64(key ^ i as u64) >> 40) as f32 * (1.0 / 16_777_216.0) - 0.5;
        for y in 0..roi.h {
            let row = y * roi.w..(y + 1) * roi.w;
            let base = y * ow;
            let (mag_at, input) = (
                if side { base + roi.w } else { base },
                &r.input[row.clone()],
            );
            let output = &r.output[row.clone()];
            match o.pixels_mut() {
                PixelsMut::U8(p) => {
                    if side {
                        for (d, v) in p[base..base + roi.w].iter_mut().zip(input) {
                            *d = *v as u8;
                        }
                    }
                    for (k, (d, v)) in p[mag_at..mag_at + roi.w].iter_mut().zip(output).enumerate()
                    {
                        *d = (v + dither(row.start + k)).round().clamp(0.0, max) as u8;
                    }
                }
                PixelsMut::U16(p) => {
                    if side {
                        for (d, v) in p[base..base + roi.w].iter_mut().zip(input) {
                            *d = *v as u16;
                        }
                    }
                    for (k, (d, v)) in p[mag_at..mag_at + roi.w].iter_mut().zip(output).enumerate()
                    {
                        *d = (v + dither(row.start + k)).round().clamp(0.0, max) as u16;
                    }
                }
            }
        }
        let _ = out.emit(Item::Frame(o.freeze()));
        Ok(())
    }
}
