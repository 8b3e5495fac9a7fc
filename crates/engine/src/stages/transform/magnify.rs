//! `magnify`: phase-based motion magnification (Wadhwa et al. 2013, the
//! complex steerable pyramid; 2014, the Riesz pyramid): frames in, frames
//! out, the motion in `[lo_hz, hi_hz]` multiplied by `factor` (below 1
//! attenuates, 0 removes it). See `vibroscope_math::magnify` for the
//! method. With `roi` only that region is processed and written; with
//! `side_by_side` each output frame holds the input (left) and the
//! magnified frame (right). Output frames come from the stage's own pool.
//!
//! The Riesz magnifier on two threads keeps two frames in flight on
//! regions up to 640x480 pixels (`Magnifier::process_pipelined`: two
//! hand-overs between the threads a frame instead of about twenty): each
//! magnified frame leaves when the next input frame comes, the last one
//! at the end, so a live view shows it one frame later. The frames are
//! the bytes one thread writes.

use super::reduce::ROI;
use super::roi::{Roi, RoiParam};
use crate::spin::SpinJoin;
use crate::*;
use std::sync::Arc;
use std::time::Duration;
use vibroscope_math::join::Join;
use vibroscope_math::magnify::{dither_round_u16, dither_round_u8, PIPELINE_MAX_PIXELS};
use vibroscope_math::magnify::{
    Magnifier, MagnifyError, MagnifyParams as Method, PyramidKind, DEFAULT_MAX_PHASE,
    DEFAULT_ORDER, DEFAULT_ORIENTATIONS, DEFAULT_SIGMA,
};
use vibroscope_math::pyramid::PyramidKind as Pyramid;
use vibroscope_math::rng::mix64;

params! {
    /// `magnify`'s parameters.
    pub struct MagnifyParams for "magnify" {
        lo_hz: f64 = ParamSpec::of(ParamType::Float, Def::Required)
            .above(0.0)
            .unit("Hz")
            .doc("low edge of the band whose motion is magnified"),
        hi_hz: f64 = ParamSpec::of(ParamType::Float, Def::Required)
            .above(0.0)
            .unit("Hz")
            .doc("high edge of the band (below half the frame rate)"),
        factor: f64 = ParamSpec::of(ParamType::Float, Def::Float(10.0))
            .floats(0.0, 1e6)
            .doc("motion in the band is multiplied by this; below 1 attenuates, 0 removes it"),
        pyramid: Pyramid = ParamSpec::of(ParamType::Choice(&["csp", "riesz"]), Def::Str("csp"))
            .doc("csp: complex steerable (quality); riesz: Riesz on a Laplacian pyramid (speed)"),
        scales: usize = ParamSpec::of(ParamType::Int, Def::Int(4))
            .ints(1, 16)
            .doc("pyramid scales (octaves)"),
        orientations: usize = ParamSpec::of(ParamType::Int, Def::Int(DEFAULT_ORIENTATIONS as i64))
            .ints(1, 16)
            .doc("CSP orientations (8: motion in every direction is magnified evenly; the Riesz pyramid finds each pixel's own)"),
        order: usize = ParamSpec::of(ParamType::Int, Def::Int(DEFAULT_ORDER as i64))
            .ints(1, 8)
            .doc("order of the causal Butterworth band-pass applied to each pixel's phase"),
        sigma_px: f64 = ParamSpec::of(ParamType::Float, Def::Float(DEFAULT_SIGMA as f64))
            .floats(0.0, 32.0)
            .unit("band px")
            .doc("σ of the amplitude-weighted smoothing of the phase (0 = none)"),
        max_phase_rad: f64 = ParamSpec::of(ParamType::Float, Def::Float(DEFAULT_MAX_PHASE as f64))
            .above_upto(0.0, 100.0)
            .unit("rad")
            .doc("limit of the magnified phase (π/2: a quarter of each band's wavelength)"),
        roi: Option<RoiParam> = ROI,
        side_by_side: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("write the input (left) and the magnified frame (right) side by side"),
        whole_frame: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("with roi: write the whole frame, the region magnified and the rest as it came (default: only the region)"),
        threads: usize = ParamSpec::of(ParamType::Int, Def::Int(0))
            .ints(0, 16)
            .doc("threads of the steerable pyramid (0 = one per core): its orientations are magnified in two halves, on two threads when there are two, bit-identical for any count; the Riesz pyramid splits each pass in two halves, on two threads when there are two"),
    }
}

type P = MagnifyParams;

pub const KIND: KindSpec = KindSpec {
    name: "magnify",
    summary:
        "phase-based motion magnification of a band (lo_hz..hi_hz, factor): frames in, frames out",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: &[OutPort::out(PortType::Frames)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        // (An empty band, lo_hz = hi_hz, is refused with the frame rate.)
        check_band(v.lo_hz, v.hi_hz).map_err(|m| p.error("hi_hz", m))?;
        if let Some(r) = &v.roi {
            r.check().map_err(|m| p.error("roi", m))?;
        }
        Ok(Box::new(MagnifyPlan(v)))
    },
};

/// Refuses an inverted band (`lo_hz` above `hi_hz`); the frame rate's
/// limits are the magnifier's to check.
pub fn check_band(lo_hz: f64, hi_hz: f64) -> Result<(), String> {
    if lo_hz > hi_hz {
        return Err(format!(
            "the band {lo_hz} - {hi_hz} Hz is inverted (lo_hz < hi_hz)"
        ));
    }
    Ok(())
}

/// Checks `v` for the parameter `name` against the kind's declaration
/// (its range); the message says what is wrong.
pub fn check_param(name: &str, v: f64) -> Result<(), String> {
    let spec = P::PARAMS
        .iter()
        .find(|s| s.name == name)
        .ok_or_else(|| format!("`magnify` has no parameter `{name}`"))?;
    spec.check(&toml::Value::Float(v))
}

struct MagnifyPlan(P);

impl Plan for MagnifyPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(Magnify {
            p: self.0,
            pool_frames: ctx.pool_frames,
            run: None,
            tuning: ctx.observer.as_ref().map(|o| o.tuning(&ctx.id)),
            tuned: 0,
        })))
    }

    /// The Riesz magnifier on two threads holds the frame in flight.
    fn frames_held(&self) -> usize {
        1
    }
}

/// The steerable pyramid's orientations are magnified in this many parts.
const PARTS: usize = 2;

/// One thread's share of the magnifier (its orientations) and its output.
struct Part {
    magnifier: Magnifier,
    out: Vec<f32>,
    result: Result<(), vibroscope_math::pyramid::PyramidError>,
}

/// What the first frame decides.
struct Run {
    /// Input frame size.
    size: (usize, usize),
    roi: Roi,
    /// The parts (one, or one per thread); the frame is their sum.
    parts: Vec<Part>,
    /// Two threads, when there are two: the steerable pyramid's parts,
    /// the Riesz magnifier's passes, and the output's rounding, in halves.
    halves: Option<SpinJoin>,
    pool: FramePool,
    input: Vec<f32>,
    output: Vec<f32>,
    max: f32,
    /// The Riesz magnifier on two threads keeps two frames in flight
    /// (`Magnifier::process_pipelined`): each frame leaves when the next
    /// one comes, or at the end.
    pipelined: bool,
    /// The frame in flight, whose magnified frame the next call (or
    /// `finish`) gives.
    held: Option<Frame>,
}

struct Magnify {
    p: P,
    pool_frames: usize,
    run: Option<Run>,
    /// A watcher (the studio's magnified view) may change `lo_hz`, `hi_hz`
    /// and `factor` while the run goes on; the last request taken.
    tuning: Option<Arc<Tuning>>,
    tuned: u64,
}

impl Magnify {
    /// The magnifier of `range` of the orientations (all, for Riesz).
    fn magnifier(
        roi: Roi,
        params: Method,
        range: std::ops::Range<usize>,
        residuals: bool,
    ) -> Result<Magnifier, StageError> {
        Magnifier::new_part(roi.w, roi.h, params, range, residuals).map_err(|e| match e {
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
        })
    }

    /// Takes the watcher's latest request: the magnifier starts over at
    /// frame `f` with the new band and factor (as a run that began there
    /// would), or, if they are refused (the band against the frame rate,
    /// a value out of range), keeps the one it had and says why. The old
    /// magnifier is let go before the new one is built, so a change never
    /// holds both in memory.
    fn retune(&mut self, t: &Tuning, f: &Frame) {
        let t0 = std::time::Instant::now();
        let (version, values) = t.values();
        self.tuned = version;
        let old = self.p.clone();
        let mut refused = None;
        for (k, v) in values {
            match k.as_str() {
                "lo_hz" => self.p.lo_hz = v,
                "hi_hz" => self.p.hi_hz = v,
                "factor" => self.p.factor = v,
                _ => {
                    refused = Some(format!(
                        "`{k}` cannot be changed while the run goes on (lo_hz, hi_hz and factor can)"
                    ));
                    continue;
                }
            }
            if let Err(m) = check_param(&k, v) {
                refused = Some(format!("{k} = {v}: {m}"));
            }
        }
        if refused.is_none() {
            refused = check_band(self.p.lo_hz, self.p.hi_hz).err();
        }
        if refused.is_none() {
            // The band against the frame rate, before anything is let go.
            if let Err(e) = self.method(f.format().fps).check() {
                refused = Some(e.to_string());
            }
        }
        let result = match refused {
            Some(m) => Err(m),
            None => {
                self.run = None;
                match self.start(f) {
                    Ok(run) => {
                        self.run = Some(run);
                        Ok(f.meta().seq)
                    }
                    // (The old settings start over at this frame.)
                    Err(e) => Err(e.to_string()),
                }
            }
        };
        if result.is_err() {
            self.p = old;
        }
        tracing::info!(
            lo_hz = self.p.lo_hz,
            hi_hz = self.p.hi_hz,
            factor = self.p.factor,
            "magnify: retuned at frame {} in {:.1} ms: {result:?}",
            f.meta().seq,
            t0.elapsed().as_secs_f64() * 1e3
        );
        t.answer(version, result);
    }

    /// The magnifier's parameters at `fps`.
    fn method(&self, fps: f64) -> Method {
        Method {
            fps,
            lo_hz: self.p.lo_hz,
            hi_hz: self.p.hi_hz,
            factor: self.p.factor as f32,
            order: self.p.order,
            sigma: self.p.sigma_px as f32,
            max_phase: self.p.max_phase_rad as f32,
            pyramid: match self.p.pyramid {
                Pyramid::Csp => PyramidKind::Csp,
                Pyramid::Riesz => PyramidKind::Riesz,
            },
            scales: self.p.scales,
            orientations: self.p.orientations,
        }
    }

    fn start(&self, f: &Frame) -> Result<Run, StageError> {
        let fmt = *f.format();
        let roi = Roi::resolve(self.p.roi.as_ref(), f.width(), f.height())?;
        let csp = self.p.pyramid != Pyramid::Riesz;
        // The pooled output frames beyond the region's size.
        let (w, h) = if self.p.whole_frame {
            (f.width(), f.height())
        } else {
            (roi.w, roi.h)
        };
        let out_w = if self.p.side_by_side { 2 * w } else { w };
        let extra = ((out_w * h).saturating_sub(roi.w * roi.h) as u64)
            .saturating_mul(self.pool_frames.max(2) as u64);
        crate::memory::check(
            crate::memory::magnify_bound(roi.w, roi.h, self.p.orientations, csp, extra),
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
        let params = self.method(fmt.fps);
        // The steerable pyramid's orientations in two halves, whatever the
        // threads (so the frames are bit-identical for any count), the
        // first half with the residuals; each half on its own thread when
        // there are two.
        let n = if csp {
            PARTS.min(self.p.orientations)
        } else {
            1
        };
        let k = self.p.orientations;
        let mut parts = Vec::with_capacity(n);
        for i in 0..n {
            let range = if csp {
                i * k / n..(i + 1) * k / n
            } else {
                0..k
            };
            let magnifier = Self::magnifier(roi, params, range, i == 0)?;
            parts.push(Part {
                magnifier,
                out: vec![0.0; if n > 1 { roi.w * roi.h } else { 0 }],
                result: Ok(()),
            });
        }
        let magnifier = &parts[0].magnifier;
        let format = FrameFormat {
            width: out_w as u32,
            height: h as u32,
            row_timing: None,
            ..fmt
        };
        tracing::info!(
            lo_hz = self.p.lo_hz,
            hi_hz = self.p.hi_hz,
            factor = self.p.factor,
            pyramid = self.p.pyramid.name(),
            centre_hz = magnifier.bandpass().centre_hz,
            "magnify: {}x{} region at ({}, {})",
            roi.w,
            roi.h,
            roi.x,
            roi.y
        );
        // The steerable pyramid's parts on a thread each; the Riesz
        // magnifier's passes split in two (`Magnifier::process_with`).
        // Halves of tens of microseconds need a helper that is awake when
        // they come (`SpinJoin`); rayon's sleeping workers come too late.
        let halves = if super::pyramid::resolve_threads(self.p.threads) >= 2 {
            Some(
                SpinJoin::new("magnify-half", Duration::from_micros(500))
                    .map_err(|e| StageError::thread("the magnifier's helper", e))?,
            )
        } else {
            None
        };
        // Two frames in flight take two hand-overs a frame between the
        // threads where one frame at a time takes about twenty: faster
        // where a hand-over costs as much as a pass's half.
        let pipelined = !csp && halves.is_some() && roi.w * roi.h <= PIPELINE_MAX_PIXELS;
        Ok(Run {
            size: (f.width(), f.height()),
            roi,
            parts,
            halves,
            pool: FramePool::new(format, self.pool_frames.max(2)),
            // (The pipelined magnifier loads its frames and keeps its
            // output itself.)
            input: vec![0.0; if pipelined { 0 } else { roi.w * roi.h }],
            output: vec![0.0; if pipelined { 0 } else { roi.w * roi.h }],
            max: fmt.max_value() as f32,
            pipelined,
            held: None,
        })
    }
}

impl Stage for Magnify {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        let tuned = self.tuned;
        if let Some(t) = self.tuning.as_ref().filter(|t| t.version() != tuned) {
            let t = Arc::clone(t);
            // The frame in flight leaves with the settings it came under.
            self.flush(out)?;
            self.retune(&t, &f);
        }
        if self.run.is_none() {
            self.run = Some(self.start(&f)?);
        }
        let Some(r) = self.run.as_mut() else {
            return Ok(());
        };
        let roi = r.roi;
        if (f.width(), f.height()) != r.size {
            return Err(StageError::format(format!(
                "the frame size changed mid-stream ({}x{} to {}x{})",
                r.size.0,
                r.size.1,
                f.width(),
                f.height()
            )));
        }
        let dsp =
            |e: vibroscope_math::pyramid::PyramidError| StageError::dsp(format!("magnify: {e}"));
        if r.pipelined {
            if let ([one], Some(j)) = (r.parts.as_mut_slice(), &r.halves) {
                // This frame goes in; the one held comes out.
                let held = r.held.take();
                let mut o = match &held {
                    Some(_) => out.acquire(&r.pool),
                    None => None,
                };
                let mut put = Put::new(&mut o, held.as_ref(), r.roi, &self.p, r.max);
                let mut deliver = |values: &[f32]| put.write(values);
                let mut load = |dst: &mut [f32]| load_frame(dst, &f, roi, None);
                let wrote = one
                    .magnifier
                    .process_pipelined(&mut load, &mut deliver, j)
                    .map_err(dsp)?;
                put.result()?;
                r.held = Some(f);
                if let (true, Some(o)) = (wrote, o) {
                    let _ = out.emit(Item::Frame(o.freeze()));
                }
                return Ok(());
            }
        }
        let halves = r.halves.as_ref().map(|j| j as &dyn Join);
        load_frame(&mut r.input, &f, roi, halves);
        match r.parts.as_mut_slice() {
            [one] => {
                one.result = match &r.halves {
                    Some(j) => one.magnifier.process_with(&r.input, &mut r.output, j),
                    None => one.magnifier.process(&r.input, &mut r.output),
                }
            }
            parts => {
                let input = &r.input;
                let job = |p: &mut Part| p.result = p.magnifier.process(input, &mut p.out);
                match (&mut *parts, &r.halves) {
                    ([a, b], Some(j)) => j.join(&mut || job(a), &mut || job(b)),
                    (parts, _) => parts.iter_mut().for_each(job),
                }
                r.output.copy_from_slice(&parts[0].out);
                for p in &parts[1..] {
                    for (o, v) in r.output.iter_mut().zip(&p.out) {
                        *o += v;
                    }
                }
            }
        }
        for p in r.parts.iter_mut() {
            std::mem::replace(&mut p.result, Ok(())).map_err(dsp)?;
        }
        let Some(o) = out.acquire(&r.pool) else {
            return Ok(());
        };
        let halves = r.halves.as_ref().map(|j| j as &dyn Join);
        let mut o = Some(o);
        let mut put = Put::new(&mut o, Some(&f), r.roi, &self.p, r.max);
        put.write_in_halves(&r.output, halves);
        put.result()?;
        if let Some(o) = o {
            let _ = out.emit(Item::Frame(o.freeze()));
        }
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        self.flush(out)
    }
}

impl Magnify {
    /// The frame in flight (the Riesz magnifier on two threads), magnified
    /// and sent.
    fn flush(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        let Some(r) = self.run.as_mut() else {
            return Ok(());
        };
        let Some(held) = r.held.take() else {
            return Ok(());
        };
        let ([one], Some(j)) = (r.parts.as_mut_slice(), &r.halves) else {
            return Ok(());
        };
        let mut o = out.acquire(&r.pool);
        let mut put = Put::new(&mut o, Some(&held), r.roi, &self.p, r.max);
        let mut deliver = |values: &[f32]| put.write(values);
        let wrote = one
            .magnifier
            .flush(&mut deliver, j)
            .map_err(|e| StageError::dsp(format!("magnify: {e}")))?;
        put.result()?;
        if let (true, Some(o)) = (wrote, o) {
            let _ = out.emit(Item::Frame(o.freeze()));
        }
        Ok(())
    }
}

/// Writes the magnified values of input frame `f` into an output frame
/// from the pool (its meta set to `f`'s): the layout of [`write_frame`].
/// With no output frame (the run is stopping) or no input frame, nothing.
struct Put<'a> {
    o: &'a mut Option<FrameMut>,
    f: Option<&'a Frame>,
    at: Option<Layout>,
    failed: Option<StageError>,
}

impl<'a> Put<'a> {
    fn new(o: &'a mut Option<FrameMut>, f: Option<&'a Frame>, roi: Roi, p: &P, max: f32) -> Self {
        let at = o.as_mut().zip(f).map(|(o, f)| {
            *o.meta_mut() = *f.meta();
            Layout {
                fw: f.width(),
                fh: f.height(),
                ow: o.format().width as usize,
                roi,
                side: p.side_by_side,
                whole: p.whole_frame,
                // The magnified frame is dithered (uniform, ±½ DN) before
                // rounding: a change smaller than half a level would
                // otherwise round back to the input's own integers, and
                // small motions (or factors near 1) would vanish in a dead
                // zone. Deterministic per frame and pixel.
                key: mix64(f.meta().seq ^ 0x006d_6167_6e69_6679),
                max,
            }
        });
        Self {
            o,
            f,
            at,
            failed: None,
        }
    }

    /// The magnified `values`, in one pass on this thread.
    fn write(&mut self, values: &[f32]) {
        self.write_in_halves(values, None);
    }

    /// The magnified `values`, in two halves of rows through `halves`.
    fn write_in_halves(&mut self, values: &[f32], halves: Option<&dyn Join>) {
        let (Some(o), Some(f), Some(at)) = (self.o.as_mut(), self.f, self.at.as_ref()) else {
            return;
        };
        match (o.pixels_mut(), f.pixels()) {
            (PixelsMut::U8(px), PixelsRef::U8(s)) => {
                write_frame(px, s, values, at, halves, dither_round_u8)
            }
            (PixelsMut::U16(px), PixelsRef::U16(s)) => {
                write_frame(px, s, values, at, halves, dither_round_u16)
            }
            _ => {
                self.failed = Some(StageError::format(
                    "the output's depth differs from the input's",
                ))
            }
        }
    }

    fn result(&mut self) -> Result<(), StageError> {
        self.failed.take().map_or(Ok(()), Err)
    }
}

/// The region `roi` of frame `f` into `input` as `f32`, in two halves of
/// rows through `halves` when there is a helper.
fn load_frame(input: &mut [f32], f: &Frame, roi: Roi, halves: Option<&dyn Join>) {
    match f.pixels() {
        PixelsRef::U8(p) => load_region(input, p, f.width(), roi, halves),
        PixelsRef::U16(p) => load_region(input, p, f.width(), roi, halves),
    }
}

/// The region `roi` of a frame `src` (`fw` wide) into `input` as `f32`,
/// in two halves of rows through `halves` when there is a helper.
fn load_region<T: Copy + Send + Sync + Into<f32>>(
    input: &mut [f32],
    src: &[T],
    fw: usize,
    roi: Roi,
    halves: Option<&dyn Join>,
) {
    let load = |rows: &mut [f32], y0: usize| {
        for (y, row) in rows.chunks_exact_mut(roi.w).enumerate() {
            let start = (roi.y + y0 + y) * fw + roi.x;
            for (o, v) in row.iter_mut().zip(&src[start..start + roi.w]) {
                *o = (*v).into();
            }
        }
    };
    match halves {
        Some(j) => {
            let cut = roi.h / 2;
            let (a, b) = input.split_at_mut(cut * roi.w);
            j.join(&mut || load(a, 0), &mut || load(b, cut));
        }
        None => load(input, 0),
    }
}

/// Where an output frame's pixels come from.
struct Layout {
    /// Input frame size.
    fw: usize,
    fh: usize,
    /// Output frame width.
    ow: usize,
    roi: Roi,
    side: bool,
    whole: bool,
    /// The dither's key for this frame.
    key: u64,
    /// The largest pixel level.
    max: f32,
}

/// How the region's magnified values become pixels: `(values, key,
/// first, max, out)` writes `values` (pixels `first..` of the region)
/// dithered, rounded and limited to `0..=max` into `out`
/// ([`dither_round_u8`], [`dither_round_u16`]).
type Round<T> = fn(&[f32], u64, usize, f32, &mut [T]);

/// Writes one output frame `p`: the region's magnified values `output`
/// (dithered and rounded by `put`), after the input's own pixels where the
/// output shows them: the whole input frame `src` around the region with
/// `whole`, the input on the left with `side` (its region, or the whole
/// frame). In two halves of rows through `halves` when there is a helper;
/// the same bytes either way (the dither depends on the pixel, not on the
/// half).
fn write_frame<T: Copy + Send + Sync>(
    p: &mut [T],
    src: &[T],
    output: &[f32],
    at: &Layout,
    halves: Option<&dyn Join>,
    put: Round<T>,
) {
    let h = if at.whole { at.fh } else { at.roi.h };
    let rows = |p: &mut [T], y0: usize, y1: usize| {
        write_rows(p, src, output, at, y0..y1, put);
    };
    let cut = match halves {
        Some(_) => h / 2,
        None => h,
    };
    let (pa, pb) = p.split_at_mut((cut * at.ow).min(p.len()));
    match halves {
        Some(j) => j.join(&mut || rows(pa, 0, cut), &mut || rows(pb, cut, h)),
        None => rows(pa, 0, cut),
    }
}

/// Output rows `ys` of [`write_frame`] into `p` (those rows), the
/// region's values from `magnified` (the whole region's).
fn write_rows<T: Copy>(
    p: &mut [T],
    src: &[T],
    magnified: &[f32],
    at: &Layout,
    ys: std::ops::Range<usize>,
    put: Round<T>,
) {
    let (roi, fw, ow) = (at.roi, at.fw, at.ow);
    let (w, ox, oy) = if at.whole {
        (fw, roi.x, roi.y)
    } else {
        (roi.w, 0, 0)
    };
    for (dy, y) in ys.enumerate() {
        let base = dy * ow;
        let main = if at.side { base + w } else { base };
        let region = (oy..oy + roi.h).contains(&y);
        if at.whole {
            let row = &src[y * fw..(y + 1) * fw];
            if region {
                // Only the pixels around the region: it is written below.
                p[main..main + ox].copy_from_slice(&row[..ox]);
                p[main + ox + roi.w..main + w].copy_from_slice(&row[ox + roi.w..]);
            } else {
                p[main..main + w].copy_from_slice(row);
            }
            if at.side {
                p[base..base + w].copy_from_slice(row);
            }
        } else if at.side {
            let start = (roi.y + y) * fw + roi.x;
            p[base..base + w].copy_from_slice(&src[start..start + w]);
        }
        if region {
            let first = (y - oy) * roi.w;
            let values = &magnified[first..first + roi.w];
            put(
                values,
                at.key,
                first,
                at.max,
                &mut p[main + ox..main + ox + roi.w],
            );
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// An output frame made in two halves of rows (through the spinning
    /// helper) has the same bytes as one made in one pass, and both hold
    /// what each layout promises pixel by pixel: the region's values
    /// dithered and rounded, the input around the region (`whole`), the
    /// input on the left (`side`).
    use vibroscope_math::magnify::dither_round;

    #[test]
    fn output_frames_in_halves_equal_the_plain_layout() {
        let (fw, fh) = (37usize, 23usize);
        let src: Vec<u8> = (0..fw * fh).map(|i| (i * 31 % 251) as u8).collect();
        let j = SpinJoin::new("test-half", Duration::from_micros(50)).unwrap();
        for (x, y, w, h) in [
            (0, 0, 37, 23),
            (5, 3, 11, 7),
            (0, 12, 37, 11),
            (20, 0, 17, 1),
        ] {
            let roi = Roi { x, y, w, h };
            let mut input = vec![0.0f32; w * h];
            load_region(&mut input, &src, fw, roi, Some(&j));
            for (k, v) in input.iter().enumerate() {
                assert_eq!(*v, f32::from(src[(y + k / w) * fw + x + k % w]));
            }
            let values: Vec<f32> = (0..w * h)
                .map(|i| 100.0 + (i as f32 * 0.37).sin() * 90.0)
                .collect();
            for (side, whole) in [(false, false), (true, false), (false, true), (true, true)] {
                let (cw, ch) = if whole { (fw, fh) } else { (w, h) };
                let ow = if side { 2 * cw } else { cw };
                let at = Layout {
                    fw,
                    fh,
                    ow,
                    roi,
                    side,
                    whole,
                    key: 7,
                    max: 255.0,
                };
                let mut frames = Vec::new();
                for halves in [None, Some(&j as &dyn Join)] {
                    let mut p = vec![0u8; ow * ch];
                    write_frame(&mut p, &src, &values, &at, halves, dither_round_u8);
                    frames.push(p);
                }
                assert_eq!(frames[0], frames[1], "{roi:?} side {side} whole {whole}");
                let mut rounded = values.clone();
                dither_round(&mut rounded, 7, 0, 255.0);
                let p = &frames[0];
                for oy in 0..ch {
                    for ox in 0..cw {
                        let main = p[oy * ow + if side { cw } else { 0 } + ox];
                        let (fx, fy) = if whole { (ox, oy) } else { (x + ox, y + oy) };
                        let inside = (x..x + w).contains(&fx) && (y..y + h).contains(&fy);
                        let want = if inside {
                            rounded[(fy - y) * w + fx - x] as u8
                        } else {
                            src[fy * fw + fx]
                        };
                        assert_eq!(main, want, "{roi:?} side {side} whole {whole} at {ox},{oy}");
                        if side {
                            assert_eq!(p[oy * ow + ox], src[fy * fw + fx], "left at {ox},{oy}");
                        }
                    }
                }
            }
        }
    }
}
