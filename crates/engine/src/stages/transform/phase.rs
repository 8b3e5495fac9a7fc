//! `phase`: per-band weighted local motion signals (thesis Eq. 3.1-3.4).
//!
//! Each frame goes through a complex steerable pyramid (`pyramid = "csp"`,
//! Eq. 3.1) or a Riesz pyramid (`"riesz"`, the fast alternative). Per band
//! `l` and pixel, the local displacement u = φ(t) - φ(t0) (Eq. 3.2) is the
//! wrapped phase difference against the first frame; the band signal is
//! a_l(t) = Σ_{x,y in roi} A(t0)² u(t) (Eq. 3.3-3.4). The weights are the
//! reference frame's contrast: with A(t)², which moves with the object, the
//! reference frame's fixed phase noise is modulated by the signal and the
//! error grows with the motion (measured: +3.3 dB instead of +6 dB for
//! twice the motion at 12 dB SNR); for the sub-pixel motions of a visual
//! microphone A(t) ≈ A(t0) anyway.
//!
//! Why not a running sum of frame-to-frame increments (which would follow
//! motions beyond half a wavelength)? In low-contrast pixels the phase is
//! noise, increments wrap, and the sum becomes a random walk of ±2π steps
//! that swamps sub-pixel signals even after A² weighting (measured: -12.7 dB
//! instead of +20 dB on the synthetic scene). Instead the reference is
//! renewed every `reference_interval_s` (default 1 s): the frame due becomes
//! the next reference (its A² the next weights), both references run side by
//! side for `reference_overlap` frames, and the next one takes over with an
//! offset per band, the mean difference of the two over the overlap, so the
//! output continues. A drift then only has to stay under half a wavelength
//! per interval, and the only random walk is one step per renewal, the
//! overlap mean's error (a 1/√(overlap+1) fraction of one sample's noise).
//!
//! The output carries one channel per band (scale-major:
//! `scale * orientations + orientation`) at each frame's capture time.
//! With `tiles = T` the region is cut into a T x T grid of local regions,
//! each summed on its own: T² x bands channels, tile-major (`tile * bands +
//! band`, tiles row by row), so a `spectrum` stage downstream adds the
//! power spectra of local motion signals as Eq. 3.17 does, instead of
//! taking the power of the whole region's mean motion, in which parts of a
//! mode moving in opposite phase cancel. All
//! channels are divided by one constant, the reference's total A² over all
//! bands, which keeps their relative weights (Eq. 3.6 sums them
//! unnormalised) and gives values of the order of radians of phase instead
//! of millions. With `normalise = "channel"` each channel is divided by
//! its own tile's and band's total A² instead: its value is then the
//! A²-weighted mean phase change of that tile and band, whatever the
//! texture's contrast there, so that tiles count alike in a sum of their
//! power spectra (a tile of strong texture otherwise weighs as the square
//! of its A²; `vibroscope learn`'s features, `docs/learning.md`). A tile
//! with no weight in a band reads zero there.

use super::audio_out::Batcher;
use super::pyramid::{
    csp_workers, pyramid_err as err, resolve_threads, Analyzer, Carried, Crew, OnFrames,
    PyramidKind, FRAME_THREADS, HALF_GRIDS, ORIENTATIONS, PYRAMID, SCALES,
};
use super::roi::{plan_region, resolve_region, Mask, Roi, RoiParam};
use crate::*;
use vibroscope_math::kernels::MAX_ORIENT;
use vibroscope_math::pyramid::{PhaseBands, PyramidError};
use vibroscope_math::riesz::RieszPyramid;

use crate::spin::{spin_until, Idle};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

params! {
    /// `phase`'s parameters.
    pub struct PhaseParams for "phase" {
        pyramid: PyramidKind = PYRAMID,
        scales: usize = SCALES,
        orientations: usize = ORIENTATIONS,
        half_grids: bool = HALF_GRIDS,
        roi: Option<RoiParam> = super::reduce::ROI,
        mask: Option<std::path::PathBuf> = super::roi::MASK,
        block: usize = ParamSpec::of(ParamType::Int, Def::Int(64))
            .ints(1, 65536)
            .unit("frames")
            .doc("frames per emitted block"),
        /// (The reference is fixed, so frames are independent: each is
        /// computed whole by one worker. Two workers on frames take them
        /// as they come, the second on a helper thread ([`Stream`]; at
        /// most `threads` frames in flight live, [`REPLAY_DEPTH`] times
        /// that on a replay). Otherwise the workers take the frames of a
        /// batch as each is free: a batch is `threads` frames live, so a
        /// frame waits for at most `threads - 1` later ones, and on a
        /// replay [`REPLAY_DEPTH`] times that, so that a worker held up by
        /// another thread on its core costs the others less.)
        threads: usize = FRAME_THREADS,
        reference_interval_s: f64 = REFERENCE_INTERVAL,
        reference_overlap: usize = REFERENCE_OVERLAP,
        tiles: usize = ParamSpec::of(ParamType::Int, Def::Int(1))
            .ints(1, 32)
            .unit("per side")
            .doc("cut the region into tiles x tiles local regions, one channel per band per tile (tile-major), so a spectrum sums local power spectra (Eq. 3.17)"),
        normalise: Normalise = ParamSpec::of(
            ParamType::Choice(&["region", "channel", "tile"]),
            Def::Str("region"),
        )
        .doc("divide every channel by the region's total A² (keeps the bands' and tiles' relative weights), by its own tile's and band's A² (its A²-weighted mean phase change: tiles of weak and strong texture count alike, and so do bands), or by its own tile's A² over all bands (tiles count alike, bands keep their relative weights within a tile)"),
    }
}

type P = PhaseParams;

/// What each channel is divided by.
#[derive(serde::Deserialize, serde::Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum Normalise {
    /// The reference's total A² over every band of the region.
    Region,
    /// The reference's A² over the channel's own tile and band.
    Channel,
    /// The reference's A² over the channel's own tile, every band.
    Tile,
}

/// `reference_interval_s`, shared with `tile_motion`.
pub(super) const REFERENCE_INTERVAL: ParamSpec =
    ParamSpec::new("reference_interval_s", ParamType::Float, Def::Float(1.0))
        .at_least(0.0)
        .unit("s")
        .doc("time between reference renewals (0 = the first frame stays the reference)");
/// `reference_overlap`, shared with `tile_motion`.
pub(super) const REFERENCE_OVERLAP: ParamSpec =
    ParamSpec::new("reference_overlap", ParamType::Int, Def::Int(32))
        .ints(0, 65536)
        .unit("frames")
        .doc("frames over which old and next reference run side by side to join them");

pub const KIND: KindSpec = KindSpec {
    name: "phase",
    summary: "pyramid (csp or riesz) local phase, A²-weighted and summed per band (Eq. 3.1-3.4) -> one channel per band",
    inputs: &[InPort::one(&[PortType::Frames, PortType::Pyramid])],
    outputs: &[OutPort::out(PortType::Samples)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        let mask = plan_region(p, v.roi.as_ref(), v.mask.as_ref())?;
        Ok(Box::new(PhasePlan { p: v, mask }))
    },
};

struct PhasePlan {
    p: P,
    mask: Option<(std::path::PathBuf, Mask)>,
}

/// Frames a worker takes in a batch on a replay (live: one, so that no
/// frame waits for more than the other workers' frames), and a stream's
/// frames in flight a worker. The output is the same bits either way.
const REPLAY_DEPTH: usize = 4;

impl Plan for PhasePlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let PhasePlan { p: v, mask } = *self;
        let threads = resolve_threads(v.threads);
        let batch_frames = threads * if ctx.live { 1 } else { REPLAY_DEPTH };
        // Two workers on frames stream them, the second on a helper of the
        // stream's own: no pair's helper is started for them.
        let streams = threads == 2 && ctx.input_types.first() == Some(&PortType::Frames);
        Ok(Node::Stage(Box::new(Phase {
            crew: if streams {
                Crew::Alone
            } else {
                Crew::new(threads, "phase-worker")?
            },
            threads,
            batch_frames,
            kind: v.pyramid,
            scales: v.scales,
            orientations: v.orientations,
            half_grids: v.half_grids,
            roi: v.roi,
            mask,
            block: v.block,
            tiles: v.tiles,
            renewal: Renewal {
                interval_s: v.reference_interval_s,
                overlap: v.reference_overlap,
                normalise: v.normalise,
            },
            engine: None,
            pending: Vec::with_capacity(batch_frames),
            batch: None,
            streaming: streams,
            worker_busy_ns: Arc::clone(&ctx.worker_busy_ns),
        })))
    }

    fn frames_held(&self) -> usize {
        resolve_threads(self.p.threads) * REPLAY_DEPTH
    }
}

struct BandState {
    /// Region of the band grid that maps into the ROI.
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
    width: usize,
    /// Band pixels (width × height).
    len: usize,
    /// Band pixels inside the mask, if there is one.
    inside: Option<Vec<bool>>,
    /// Tile boundaries in band pixels (`tiles + 1` each, from x0 to x1
    /// and y0 to y1).
    xs: Vec<usize>,
    ys: Vec<usize>,
}

/// A reference frame (Eq. 3.2) with its A² weights (Eq. 3.3).
struct Reference<C> {
    c: C,
    /// A(t_ref)² per band, zero outside the mask.
    weights: Vec<Vec<f32>>,
    /// Per channel, what its sum is divided by: Σ A² over every band's
    /// region (the output scale); with `normalise = "channel"` Σ A² over
    /// its tile and band, with `"tile"` over its tile and every band
    /// (infinite where that is zero, so the channel reads zero).
    divisor: Vec<f64>,
    t_ns: i64,
    /// Added per channel to this reference's normalised sums, so the output
    /// continues across renewals.
    offset: Vec<f64>,
}

/// The next reference while both run side by side.
struct Handover<C> {
    next: Arc<Reference<C>>,
    /// Overlap frames still to compute.
    left: usize,
    /// Frames summed into the engine's `acc`.
    n: usize,
}

/// One worker's pyramid and buffers (nothing is allocated per frame).
struct Worker<A: Analyzer> {
    an: A,
    c: A::C,
    input: Vec<f32>,
}

/// What one frame of a batch gives (whichever worker computed it).
struct Slot {
    /// Σ A² Δφ per band against the reference.
    sums: Vec<f64>,
    /// The same against the next reference, during a handover.
    next_sums: Vec<f64>,
    result: Result<(), StageError>,
}

/// Per-band weighted phase sums, frames spread over workers.
struct Engine<A: Analyzer> {
    workers: Vec<Worker<A>>,
    /// One a frame of a batch (the most frames a batch takes).
    slots: Vec<std::sync::Mutex<Slot>>,
    /// Shared with the helper of a [`Stream`] by each frame in flight;
    /// changed only when none is.
    reference: Option<Arc<Reference<A::C>>>,
    handover: Option<Handover<A::C>>,
    /// A retired reference, recycled for the next renewal.
    spare: Option<Reference<A::C>>,
    /// Renew the reference this long after the last one (None = never).
    interval_ns: Option<i64>,
    overlap: usize,
    normalise: Normalise,
    bands: Arc<Vec<BandState>>,
    /// Tiles per side of the region.
    tiles: usize,
    scales: usize,
    orientations: usize,
    /// The output values of one frame.
    vals: Vec<f32>,
    /// Σ (output - next reference's normalised sum) per band, during a handover.
    acc: Vec<f64>,
    width: usize,
    height: usize,
    /// The frames streamed to a helper thread, when the engine streams.
    stream: Option<Stream<A>>,
}

/// How `phase` renews its reference, and what each channel is divided by.
#[derive(Clone, Copy)]
struct Renewal {
    interval_s: f64,
    overlap: usize,
    /// What each channel is divided by.
    normalise: Normalise,
}

/// The object-safe face of [`Engine`] (one per pyramid kind).
trait FrameSignals: Send {
    /// Output channels (bands x tiles²).
    fn channels(&self) -> usize;
    fn size(&self) -> (usize, usize);
    /// Computes `frames` in order and calls `emit` with each frame's
    /// normalised band signals.
    fn run(
        &mut self,
        frames: &[Item],
        crew: &Crew,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError>;
    /// Moves the second worker onto a helper thread of its own and
    /// computes frames as they come ([`Stream`]), at most `depth` in
    /// flight. False (nothing changed) with fewer than two workers.
    /// The helper adds its working time to `busy_ns`.
    fn start_stream(&mut self, depth: usize, busy_ns: Arc<AtomicU64>) -> Result<bool, StageError>;
    /// Streams one frame (after [`FrameSignals::start_stream`]): frames
    /// done are emitted in order.
    fn push(
        &mut self,
        f: Item,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError>;
    /// Computes and emits every frame in flight.
    fn drain(
        &mut self,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError>;
}

impl<A: Analyzer> Engine<A> {
    fn new(
        mut make: impl FnMut() -> Result<A, PyramidError>,
        (workers, batch_frames): (usize, usize),
        (scales, orientations): (usize, usize),
        (roi, mask, tiles): (Roi, Option<&Mask>, usize),
        renewal: Renewal,
        (width, height): (usize, usize),
    ) -> Result<Self, StageError> {
        let tiles = tiles.max(1);
        let nb = scales * orientations * tiles * tiles;
        let mut ws = Vec::with_capacity(workers);
        for _ in 0..workers.max(1) {
            let an = make().map_err(err)?;
            let c = an.alloc();
            ws.push(Worker {
                an,
                c,
                input: vec![0.0; width * height],
            });
        }
        let slots = (0..batch_frames.max(workers).max(1))
            .map(|_| {
                std::sync::Mutex::new(Slot {
                    sums: vec![0.0; nb],
                    next_sums: vec![0.0; nb],
                    result: Ok(()),
                })
            })
            .collect();
        let c = &ws[0].c;
        let mut bands = Vec::with_capacity(c.num_bands());
        for i in 0..c.num_bands() {
            let b = c
                .band_info(i)
                .ok_or_else(|| err(PyramidError::LayoutMismatch))?;
            // Band pixel x' sits at input x = x' * step.
            let to_band =
                |v: usize, step: f32, n: usize| ((v as f32 / step).ceil() as usize).min(n);
            let x0 = to_band(roi.x, b.step_x, b.width);
            let x1 = to_band(roi.x + roi.w, b.step_x, b.width).max(x0);
            let y0 = to_band(roi.y, b.step_y, b.height);
            let y1 = to_band(roi.y + roi.h, b.step_y, b.height).max(y0);
            // Tile t of T spans input [start + t·len/T, start + (t+1)·len/T).
            let cuts = |start: usize, len: usize, step: f32, n: usize, lo: usize, hi: usize| {
                (0..=tiles)
                    .map(|t| to_band(start + t * len / tiles, step, n).clamp(lo, hi))
                    .collect::<Vec<usize>>()
            };
            let xs = cuts(roi.x, roi.w, b.step_x, b.width, x0, x1);
            let ys = cuts(roi.y, roi.h, b.step_y, b.height, y0, y1);
            // Band pixels whose input position falls outside the mask get
            // no weight (multiplied into A² of each reference).
            let inside = mask.map(|m| {
                (0..b.len())
                    .map(|i| {
                        let (bx, by) = (i % b.width, i / b.width);
                        let x = ((bx as f32 * b.step_x).round() as usize).min(width - 1);
                        let y = ((by as f32 * b.step_y).round() as usize).min(height - 1);
                        m.at(x, y)
                    })
                    .collect::<Vec<bool>>()
            });
            bands.push(BandState {
                x0,
                x1,
                y0,
                y1,
                width: b.width,
                len: b.len(),
                inside,
                xs,
                ys,
            });
        }
        let interval_ns = (renewal.interval_s > 0.0).then_some((renewal.interval_s * 1e9) as i64);
        Ok(Self {
            workers: ws,
            slots,
            reference: None,
            handover: None,
            spare: None,
            interval_ns,
            overlap: renewal.overlap,
            normalise: renewal.normalise,
            bands: Arc::new(bands),
            tiles,
            scales,
            orientations,
            vals: vec![0.0; nb],
            acc: vec![0.0; nb],
            width,
            height,
            stream: None,
        })
    }

    /// Turns worker `w`'s last analysed frame into a reference (its
    /// coefficients are swapped out, not copied; a spare is reused). `None`
    /// when the frame has no contrast in the region.
    fn make_reference(
        &mut self,
        w: usize,
        t_ns: i64,
    ) -> Result<Option<Reference<A::C>>, StageError> {
        let nb = self.vals.len();
        let mut r = match self.spare.take() {
            Some(r) => r,
            None => Reference {
                c: self.workers[0].an.alloc(),
                weights: self.bands.iter().map(|b| vec![0.0; b.len]).collect(),
                divisor: vec![0.0; nb],
                t_ns: 0,
                offset: vec![0.0; nb],
            },
        };
        std::mem::swap(&mut r.c, &mut self.workers[w].c);
        let mut total = 0.0f64;
        for (i, (b, wt)) in self.bands.iter().zip(r.weights.iter_mut()).enumerate() {
            r.c.amplitude_into(i, wt).map_err(err)?;
            wt.iter_mut().for_each(|a| *a = *a * *a);
            if let Some(inside) = &b.inside {
                for (w, &i) in wt.iter_mut().zip(inside) {
                    if !i {
                        *w = 0.0;
                    }
                }
            }
            for y in b.y0..b.y1 {
                total += wt[y * b.width + b.x0..y * b.width + b.x1]
                    .iter()
                    .map(|&w| w as f64)
                    .sum::<f64>();
            }
        }
        if self.normalise == Normalise::Region {
            r.divisor.iter_mut().for_each(|d| *d = total);
        } else {
            // Σ A² per tile and band (tile-major, as the channels).
            let (nbands, tiles) = (self.bands.len(), self.tiles);
            for (i, (b, wt)) in self.bands.iter().zip(&r.weights).enumerate() {
                for t in 0..tiles * tiles {
                    let (ty, tx) = (t / tiles, t % tiles);
                    r.divisor[t * nbands + i] = (b.ys[ty]..b.ys[ty + 1])
                        .flat_map(|y| &wt[y * b.width + b.xs[tx]..y * b.width + b.xs[tx + 1]])
                        .map(|&w| w as f64)
                        .sum();
                }
            }
            if self.normalise == Normalise::Tile {
                for tile in r.divisor.chunks_mut(nbands) {
                    let sum: f64 = tile.iter().sum();
                    tile.iter_mut().for_each(|d| *d = sum);
                }
            }
            for d in r.divisor.iter_mut().filter(|d| **d <= 0.0) {
                *d = f64::INFINITY;
            }
        }
        r.t_ns = t_ns;
        r.offset.iter_mut().for_each(|o| *o = 0.0);
        if total > 0.0 {
            Ok(Some(r))
        } else {
            self.spare = Some(r);
            Ok(None)
        }
    }

    /// The first frame becomes the reference.
    fn set_reference(&mut self, f: &Item) -> Result<(), StageError> {
        let w0 = &mut self.workers[0];
        w0.an.analyze(f, &mut w0.input, &mut w0.c)?;
        let r = self.make_reference(0, f.t_ns())?.ok_or_else(|| {
            StageError::dsp("the region has no texture (zero local contrast in every band)")
        })?;
        self.reference = Some(Arc::new(r));
        Ok(())
    }

    /// Whether a frame at `t_ns` starts a renewal.
    fn due(&self, t_ns: i64) -> bool {
        match (&self.reference, self.interval_ns) {
            (Some(r), Some(iv)) if self.handover.is_none() => t_ns.saturating_sub(r.t_ns) >= iv,
            _ => false,
        }
    }

    /// Ends a handover: the next reference takes over. No frame may be in
    /// flight (nothing else holds the references).
    fn take_over(&mut self) -> Result<(), StageError> {
        if let Some(mut h) = self.handover.take() {
            let n = h.n.max(1) as f64;
            let next = Arc::get_mut(&mut h.next).ok_or_else(shared_reference)?;
            for (o, a) in next.offset.iter_mut().zip(&self.acc) {
                *o = a / n;
            }
            self.spare = self
                .reference
                .replace(h.next)
                .and_then(|r| Arc::try_unwrap(r).ok());
        }
        Ok(())
    }

    /// Computes `batch` (its frames shared among the workers; during a
    /// handover also against the next reference) and emits it in order.
    fn batch(
        &mut self,
        batch: &[Item],
        crew: &Crew,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError> {
        let Some(reference) = self.reference.as_deref() else {
            return Ok(());
        };
        let next = self.handover.as_ref().map(|h| &*h.next);
        let (bands, scales, k) = (&self.bands[..], self.scales, self.orientations);
        let tiles = self.tiles;
        let slots = &self.slots[..batch.len()];
        crew.share(&mut self.workers, batch.len(), |w: &mut Worker<A>, i| {
            let mut s = slots[i].lock().unwrap_or_else(|e| e.into_inner());
            let s = &mut *s;
            s.result = compute(
                w,
                s,
                &batch[i],
                (reference, next),
                bands,
                (scales, k, tiles),
            );
        });
        for (slot, f) in self.slots.iter_mut().zip(batch) {
            let w = slot.get_mut().unwrap_or_else(|e| e.into_inner());
            std::mem::replace(&mut w.result, Ok(()))?;
            let out = (&mut self.vals[..], &mut self.acc[..]);
            emit_frame(out, reference, self.handover.as_mut(), w, f, emit);
        }
        Ok(())
    }

    /// A renewal: `f` is computed against the current reference, emitted,
    /// and becomes the next reference.
    fn renew(
        &mut self,
        f: &Item,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError> {
        self.batch(std::slice::from_ref(f), &Crew::Alone, emit)?;
        let t_ns = f.t_ns();
        match self.make_reference(0, t_ns)? {
            Some(next) => {
                let next = Arc::new(next);
                // On its own frame the next reference reads zero.
                for (a, &v) in self.acc.iter_mut().zip(&self.vals) {
                    *a = v as f64;
                }
                self.handover = Some(Handover {
                    next,
                    left: self.overlap,
                    n: 1,
                });
                if self.overlap == 0 {
                    self.take_over()?;
                }
            }
            // No contrast to renew from: try again an interval later.
            None => {
                if let Some(r) = self.reference.as_mut() {
                    Arc::get_mut(r).ok_or_else(shared_reference)?.t_ns = t_ns;
                }
            }
        }
        Ok(())
    }
}

/// A frame's output values from its sums (and, during a handover, its
/// part of the next reference's offset), emitted.
fn emit_frame<C>(
    (vals, acc): (&mut [f32], &mut [f64]),
    reference: &Reference<C>,
    handover: Option<&mut Handover<C>>,
    w: &Slot,
    f: &Item,
    emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
) {
    let now = vals.iter_mut().zip(&w.sums).zip(&reference.offset);
    for (((v, s), o), d) in now.zip(&reference.divisor) {
        *v = (o + s / d) as f32;
    }
    if let Some(h) = handover {
        let next = acc.iter_mut().zip(vals.iter()).zip(&w.next_sums);
        for (((a, v), s), d) in next.zip(&h.next.divisor) {
            *a += *v as f64 - s / d;
        }
        h.n += 1;
        h.left = h.left.saturating_sub(1);
    }
    emit(f, &mut vals.iter().copied());
}

/// The error for a reference still held by a frame in flight when it is
/// to change (a broken invariant of [`Stream`], never expected).
fn shared_reference() -> StageError {
    StageError::dsp("the phase reference changed while a frame in flight still used it")
}

/// Eq. 3.2-3.4 for one frame: Σ A(t_ref)² (φ(t) - φ(t_ref)) per band
/// (and tile), against the reference and, during a handover, the next one.
fn compute<A: Analyzer>(
    w: &mut Worker<A>,
    slot: &mut Slot,
    f: &Item,
    (reference, next): (&Reference<A::C>, Option<&Reference<A::C>>),
    bands: &[BandState],
    (scales, k, tiles): (usize, usize, usize),
) -> Result<(), StageError> {
    let nb = scales * k;
    let Worker { an, c, input } = w;
    let Slot {
        sums, next_sums, ..
    } = slot;
    let mut refs = [Some((reference, sums)), next.map(|n| (n, next_sums))];
    // Each scale's sums are taken as soon as the analysis has made it
    // (still in cache, for a pyramid built scale by scale).
    let mut result = Ok(());
    an.analyze_scales(f, input, c, scales, &mut |c, s| {
        if result.is_err() {
            return;
        }
        // A pyramid whose orientations share one amplitude (Riesz) reads
        // one weight image for all of them (the others are copies).
        let shared = c.amplitude_shared();
        for (r, sums) in refs.iter_mut().flatten() {
            let mut weights: [&[f32]; MAX_ORIENT] = [&[]; MAX_ORIENT];
            for (o, d) in weights.iter_mut().enumerate().take(k) {
                *d = &r.weights[s * k + if shared { 0 } else { o }];
            }
            let scale_bands = &bands[s * k..(s + 1) * k];
            let b = &scale_bands[0];
            // A compact steerable pyramid's orientations 0 and K/2 have
            // grids of their own (half the columns or rows): each band
            // then sums its own region.
            let shared_grid = scale_bands
                .iter()
                .all(|o| (o.width, o.len) == (b.width, b.len));
            for t in 0..tiles * tiles {
                let (ty, tx) = (t / tiles, t % tiles);
                let o = t * nb + s * k;
                let res = if shared_grid {
                    c.scale_phase_delta_sums(
                        &r.c,
                        s,
                        &weights[..k],
                        b.ys[ty]..b.ys[ty + 1],
                        b.xs[tx]..b.xs[tx + 1],
                        &mut sums[o..o + k],
                    )
                } else {
                    scale_bands.iter().enumerate().try_for_each(|(j, bj)| {
                        sums[o + j] = c.weighted_phase_delta_sum(
                            &r.c,
                            s * k + j,
                            weights[j],
                            bj.ys[ty]..bj.ys[ty + 1],
                            bj.xs[tx]..bj.xs[tx + 1],
                        )?;
                        Ok(())
                    })
                };
                if let Err(e) = res {
                    result = Err(err(e));
                    return;
                }
            }
        }
    })?;
    result
}

impl<A: Analyzer + 'static> FrameSignals for Engine<A> {
    fn channels(&self) -> usize {
        self.vals.len()
    }
    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn run(
        &mut self,
        frames: &[Item],
        crew: &Crew,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError> {
        let mut rest = frames;
        if self.reference.is_none() {
            let Some((first, tail)) = frames.split_first() else {
                return Ok(());
            };
            self.set_reference(first)?;
            emit(first, &mut std::iter::repeat_n(0.0, self.vals.len()));
            rest = tail;
        }
        while let Some(first) = rest.first() {
            if self.due(first.t_ns()) {
                self.renew(first, emit)?;
                rest = &rest[1..];
                continue;
            }
            // A batch never spans a change of reference.
            let mut n = rest.len().min(self.slots.len());
            match &self.handover {
                Some(h) => n = n.min(h.left.max(1)),
                None => {
                    if let Some(i) = rest[1..n].iter().position(|f| self.due(f.t_ns())) {
                        n = i + 1;
                    }
                }
            }
            self.batch(&rest[..n], crew, emit)?;
            if self.handover.as_ref().is_some_and(|h| h.left == 0) {
                self.take_over()?;
            }
            rest = &rest[n..];
        }
        Ok(())
    }

    fn start_stream(&mut self, depth: usize, busy_ns: Arc<AtomicU64>) -> Result<bool, StageError> {
        if self.stream.is_some() {
            return Ok(true);
        }
        if self.workers.len() < 2 {
            return Ok(false);
        }
        let Some(helper) = self.workers.pop() else {
            return Ok(false);
        };
        let nb = self.vals.len();
        let depth = depth.max(2);
        let shared = Arc::new(StreamShared {
            flights: (0..depth)
                .map(|_| {
                    Mutex::new(Flight {
                        item: None,
                        refs: None,
                        out: Slot {
                            sums: vec![0.0; nb],
                            next_sums: vec![0.0; nb],
                            result: Ok(()),
                        },
                    })
                })
                .collect(),
            done: (0..depth).map(|_| AtomicBool::new(false)).collect(),
            published: AtomicUsize::new(0),
            claimed: AtomicUsize::new(0),
            sleeping: AtomicBool::new(false),
            exit: AtomicBool::new(false),
            bands: Arc::clone(&self.bands),
            dims: (self.scales, self.orientations, self.tiles),
        });
        let s = Arc::clone(&shared);
        let thread = std::thread::Builder::new()
            .name("phase-worker".into())
            .spawn(move || stream_helper(&s, helper, STREAM_SPIN, &busy_ns))
            .map_err(|e| StageError::thread("the phase-worker helper", e))?;
        self.stream = Some(Stream {
            shared,
            thread: Some(thread),
            published: 0,
            emitted: 0,
        });
        Ok(true)
    }

    fn push(
        &mut self,
        f: Item,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError> {
        if self.stream.is_none() {
            return self.run(std::slice::from_ref(&f), &Crew::Alone, emit);
        }
        if self.reference.is_none() {
            self.set_reference(&f)?;
            emit(&f, &mut std::iter::repeat_n(0.0, self.vals.len()));
            return Ok(());
        }
        if self.due(f.t_ns()) {
            // The references change: nothing may be in flight.
            self.drain(emit)?;
            return self.renew(&f, emit);
        }
        // During a handover only its last `left` frames are computed
        // against the pair; the frames after wait until it ends.
        if let Some(h) = &self.handover {
            if self.in_flight() >= h.left {
                self.drain(emit)?;
            }
        }
        while self.in_flight() >= self.depth() {
            self.step(emit)?;
        }
        self.publish(f)?;
        // Compute here while the helper has another frame waiting, so it
        // never waits for this thread to hand it one.
        while self.untaken() >= 2 {
            self.step(emit)?;
        }
        self.collect(emit)
    }

    fn drain(
        &mut self,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError> {
        while self.in_flight() > 0 {
            self.step(emit)?;
        }
        Ok(())
    }
}

/// How long a [`Stream`]'s helper spins for the next frame before it
/// parks (as the pair's helper does: [`Crew`]).
const STREAM_SPIN: Duration = Duration::from_micros(500);

/// The references a frame is computed against (the next one's during a
/// handover), held by the frame while it is in flight.
type Refs<C> = (Arc<Reference<C>>, Option<Arc<Reference<C>>>);

/// A frame in flight on a [`Stream`]: published, maybe computed, not yet
/// emitted.
struct Flight<C> {
    item: Option<Item>,
    /// Taken (and dropped) by whichever worker computes the frame.
    refs: Option<Refs<C>>,
    out: Slot,
}

/// Frames spread over the stage's thread and one helper thread as they
/// come, without batches: the stage's thread publishes each frame, and
/// each worker takes the oldest frame nobody has taken whenever it is
/// free. The stage's thread computes a frame only while another one waits
/// for the helper, so neither thread waits for the other at a batch's end
/// (with batches of 8 frames the stage's thread spent about 8% of its
/// time waiting for the helper's last frame, and the source's reading,
/// which takes a core now and then, fell in those waits). Frames are
/// emitted in order; each is computed whole by one worker, as in a batch,
/// so the output is the same bits.
struct Stream<A: Analyzer> {
    shared: Arc<StreamShared<A>>,
    thread: Option<std::thread::JoinHandle<()>>,
    /// Frames published and emitted (numbered from 0).
    published: usize,
    emitted: usize,
}

impl<A: Analyzer> Drop for Stream<A> {
    fn drop(&mut self) {
        self.shared.exit.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}

/// What the stage's thread and the helper of a [`Stream`] share.
struct StreamShared<A: Analyzer> {
    /// Frame `n` sits in `flights[n % depth]`.
    flights: Box<[Mutex<Flight<A::C>>]>,
    /// Whether the frame in each flight is computed.
    done: Box<[AtomicBool]>,
    /// Frames published, and taken by a worker.
    published: AtomicUsize,
    claimed: AtomicUsize,
    sleeping: AtomicBool,
    exit: AtomicBool,
    bands: Arc<Vec<BandState>>,
    /// Scales, orientations, tiles.
    dims: (usize, usize, usize),
}

impl<A: Analyzer> StreamShared<A> {
    /// Takes the oldest published frame nobody has taken: its number.
    fn claim(&self) -> Option<usize> {
        let mut c = self.claimed.load(Ordering::Acquire);
        loop {
            if c >= self.published.load(Ordering::Acquire) {
                return None;
            }
            match self
                .claimed
                .compare_exchange_weak(c, c + 1, Ordering::AcqRel, Ordering::Acquire)
            {
                Ok(_) => return Some(c),
                Err(now) => c = now,
            }
        }
    }

    /// Computes frame `n` (taken by [`StreamShared::claim`]) with `w`, and
    /// marks it done. A panic becomes the frame's error.
    fn compute(&self, w: &mut Worker<A>, n: usize) {
        let i = n % self.flights.len();
        {
            let mut g = self.flights[i].lock().unwrap_or_else(|e| e.into_inner());
            let Flight { item, refs, out } = &mut *g;
            out.result = match (item.as_ref(), refs.take()) {
                (Some(f), Some((r, next))) => {
                    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        compute(w, out, f, (&r, next.as_deref()), &self.bands, self.dims)
                    }));
                    run.unwrap_or_else(|_| Err(StageError::dsp("a phase worker panicked")))
                }
                _ => Err(StageError::dsp("a phase frame in flight had no frame")),
            };
        }
        self.done[i].store(true, Ordering::Release);
    }
}

/// The helper of a [`Stream`]: takes frames as they are published,
/// spinning between them for `spin`, then parking until the next. Its
/// time computing goes to `busy_ns` (the stage's busy time when larger
/// than its own thread's: a live stream's frames may all come here).
fn stream_helper<A: Analyzer>(
    s: &StreamShared<A>,
    mut w: Worker<A>,
    spin: Duration,
    busy_ns: &AtomicU64,
) {
    let mut idle = Idle::new(spin);
    loop {
        if s.exit.load(Ordering::Acquire) {
            return;
        }
        if let Some(n) = s.claim() {
            let t = Instant::now();
            s.compute(&mut w, n);
            busy_ns.fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
            idle.worked();
            continue;
        }
        idle.wait(&s.sleeping, || {
            s.published.load(Ordering::SeqCst) > s.claimed.load(Ordering::SeqCst)
                || s.exit.load(Ordering::SeqCst)
        });
    }
}

impl<A: Analyzer> Engine<A> {
    fn depth(&self) -> usize {
        self.stream.as_ref().map_or(1, |s| s.shared.flights.len())
    }

    /// Frames published and not yet emitted.
    fn in_flight(&self) -> usize {
        self.stream.as_ref().map_or(0, |s| s.published - s.emitted)
    }

    /// Frames published that no worker has taken.
    fn untaken(&self) -> usize {
        self.stream.as_ref().map_or(0, |s| {
            s.published
                .saturating_sub(s.shared.claimed.load(Ordering::Acquire))
        })
    }

    /// Publishes `f` with the references of its time, and wakes the
    /// helper if it sleeps.
    fn publish(&mut self, f: Item) -> Result<(), StageError> {
        let Some(reference) = self.reference.as_ref() else {
            return Err(StageError::dsp(
                "a phase frame published before the reference",
            ));
        };
        let refs = (
            Arc::clone(reference),
            self.handover.as_ref().map(|h| Arc::clone(&h.next)),
        );
        let Some(st) = self.stream.as_mut() else {
            return Ok(());
        };
        let i = st.published % st.shared.flights.len();
        {
            let mut g = st.shared.flights[i]
                .lock()
                .unwrap_or_else(|e| e.into_inner());
            g.item = Some(f);
            g.refs = Some(refs);
        }
        st.published += 1;
        st.shared.published.store(st.published, Ordering::SeqCst);
        if st.shared.sleeping.load(Ordering::SeqCst) {
            if let Some(t) = &st.thread {
                t.thread().unpark();
            }
        }
        Ok(())
    }

    /// Computes here the oldest frame nobody has taken or, when the helper
    /// has taken them all, waits for the oldest in flight; then emits what
    /// is done. Only with frames in flight.
    fn step(
        &mut self,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError> {
        let (Some(st), Some(w)) = (self.stream.as_ref(), self.workers.first_mut()) else {
            return Ok(());
        };
        if let Some(n) = st.shared.claim() {
            st.shared.compute(w, n);
        } else {
            let done = &st.shared.done[st.emitted % st.shared.flights.len()];
            spin_until(|| done.load(Ordering::Acquire));
        }
        self.collect(emit)
    }

    /// Emits, in order, the frames in flight that are done; ends a
    /// handover whose last frame was emitted.
    fn collect(
        &mut self,
        emit: &mut dyn FnMut(&Item, &mut dyn Iterator<Item = f32>),
    ) -> Result<(), StageError> {
        loop {
            let Some(st) = self.stream.as_mut() else {
                return Ok(());
            };
            if st.emitted == st.published {
                return Ok(());
            }
            let i = st.emitted % st.shared.flights.len();
            if !st.shared.done[i].load(Ordering::Acquire) {
                return Ok(());
            }
            st.shared.done[i].store(false, Ordering::Relaxed);
            st.emitted += 1;
            let mut g = st.shared.flights[i]
                .lock()
                .unwrap_or_else(|e| e.into_inner());
            let item = g.item.take();
            std::mem::replace(&mut g.out.result, Ok(()))?;
            let (Some(reference), Some(f)) = (self.reference.as_deref(), item.as_ref()) else {
                return Err(StageError::dsp("a phase frame in flight had no frame"));
            };
            let out = (&mut self.vals[..], &mut self.acc[..]);
            emit_frame(out, reference, self.handover.as_mut(), &g.out, f, emit);
            drop(g);
            if self.handover.as_ref().is_some_and(|h| h.left == 0) {
                self.take_over()?;
            }
        }
    }
}

struct Phase {
    crew: Crew,
    threads: usize,
    /// Frames computed together (see [`REPLAY_DEPTH`]).
    batch_frames: usize,
    kind: PyramidKind,
    scales: usize,
    orientations: usize,
    half_grids: bool,
    roi: Option<RoiParam>,
    mask: Option<(std::path::PathBuf, Mask)>,
    block: usize,
    tiles: usize,
    renewal: Renewal,
    engine: Option<Box<dyn FrameSignals>>,
    /// Frames (or their pyramids) waiting for a full batch.
    pending: Vec<Item>,
    /// Band signals into sample blocks (set up with the engine).
    batch: Option<Batcher>,
    /// Frames go to the engine one by one, two workers taking them as
    /// they come ([`Stream`]; frames in, two threads), not in batches
    /// (then `crew` is alone).
    streaming: bool,
    /// Where a stream's helper adds its working time ([`BuildCtx`]).
    worker_busy_ns: Arc<AtomicU64>,
}

/// Size of the frame behind an item (frames or pyramid coefficients).
fn item_size(item: &Item) -> Option<(usize, usize)> {
    match item {
        Item::Frame(f) => Some((f.width(), f.height())),
        Item::Pyramid(p) => Some((p.width, p.height)),
        _ => None,
    }
}

/// Nominal frame rate of an item's frame.
fn item_fps(item: &Item) -> f64 {
    match item {
        Item::Frame(f) => f.format().fps,
        Item::Pyramid(p) => p.fps,
        _ => 0.0,
    }
}

impl Phase {
    /// Refuses, before allocating, a frame size whose pyramids would not
    /// fit in the memory the process may take (`crate::memory`).
    fn check_memory(&self, w: usize, h: usize) -> Result<(), StageError> {
        let csp = matches!(self.kind, PyramidKind::Csp);
        crate::memory::check(
            crate::memory::phase_bound(w, h, self.orientations, self.threads, csp),
            &format!(
                "{w}x{h} frames with the {} pyramid, {} orientations and {} workers",
                if csp { "steerable" } else { "Riesz" },
                self.orientations,
                self.threads,
            ),
            "lower `threads` (workers), crop the frames before this stage (a `roi` stage) or use the Riesz pyramid",
        )
        .map_err(|message| StageError::Config {
            field: "memory",
            message,
        })
    }

    fn init(&mut self, f: &Item) -> Result<(), StageError> {
        let (w, h) = item_size(f).ok_or_else(|| StageError::expected("frames or a pyramid"))?;
        let (roi, mask) = resolve_region(self.roi.as_ref(), self.mask.take(), w, h)?;
        // Coefficients from an upstream `pyramid` stage come in buffers
        // it recycles once let go: hold no more of them than the workers
        // (the analysis, the work a deeper batch shares out, is upstream).
        if let Item::Pyramid(_) = f {
            self.batch_frames = self.threads;
        }
        let n = (self.threads, self.batch_frames);
        if let Item::Frame(_) = f {
            self.check_memory(w, h)?;
        }
        let region = (roi, mask.as_ref(), self.tiles);
        let engine: Box<dyn FrameSignals> = match f {
            // An upstream `pyramid` stage decides the pyramid and its layout.
            Item::Pyramid(p) => {
                let sk = p.data.layout();
                match &p.data {
                    PyramidData::Csp(c) => Box::new(Engine::new(
                        || Ok(Carried { first: c.clone() }),
                        n,
                        sk,
                        region,
                        self.renewal,
                        (w, h),
                    )?),
                    PyramidData::Riesz(c) => Box::new(Engine::new(
                        || Ok(Carried { first: c.clone() }),
                        n,
                        sk,
                        region,
                        self.renewal,
                        (w, h),
                    )?),
                }
            }
            _ => {
                let (s, k, half) = (self.scales, self.orientations, self.half_grids);
                match self.kind {
                    PyramidKind::Csp => Box::new(Engine::new(
                        {
                            let mut make = csp_workers(w, h, s, k, half);
                            move || make().map(OnFrames)
                        },
                        n,
                        (s, k),
                        region,
                        self.renewal,
                        (w, h),
                    )?),
                    PyramidKind::Riesz => Box::new(Engine::new(
                        || {
                            // The sums read the triples only; the A² of a
                            // reference is derived from its triple.
                            let mut p = RieszPyramid::new(w, h, s, k)?;
                            p.set_triples_only(true);
                            Ok(OnFrames(p))
                        },
                        n,
                        (s, k),
                        region,
                        self.renewal,
                        (w, h),
                    )?),
                }
            }
        };
        self.batch = Some(Batcher::samples(self.block, engine.channels()));
        let mut engine = engine;
        // Pyramids from upstream come in batches, in buffers recycled once
        // the batch lets them go.
        if self.streaming {
            self.streaming = matches!(f, Item::Frame(_))
                && engine.start_stream(self.batch_frames, Arc::clone(&self.worker_busy_ns))?;
        }
        self.engine = Some(engine);
        Ok(())
    }

    /// Computes the pending frames and appends their samples to the block.
    fn run_pending(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        let (Some(engine), Some(batch)) = (self.engine.as_mut(), self.batch.as_mut()) else {
            return Ok(());
        };
        let r = engine.run(&self.pending, &self.crew, &mut |f, vals| {
            batch.push(f.t_ns(), item_fps(f), vals, out)
        });
        self.pending.clear();
        r
    }
}

impl Stage for Phase {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        if self.engine.is_none() {
            self.init(&item)?;
        }
        if let Some(e) = &self.engine {
            if item_size(&item) != Some(e.size()) {
                return Err(StageError::format("the frame size changed mid-stream"));
            }
        }
        if self.streaming {
            let (Some(engine), Some(batch)) = (self.engine.as_mut(), self.batch.as_mut()) else {
                return Ok(());
            };
            return engine.push(item, &mut |f, vals| {
                batch.push(f.t_ns(), item_fps(f), vals, out)
            });
        }
        self.pending.push(item);
        if self.pending.len() >= self.batch_frames {
            self.run_pending(out)?;
        }
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        let mut r = self.run_pending(out);
        if let (true, Some(engine), Some(batch)) =
            (self.streaming, self.engine.as_mut(), self.batch.as_mut())
        {
            let drained = engine.drain(&mut |f, vals| batch.push(f.t_ns(), item_fps(f), vals, out));
            r = r.and(drained);
        }
        if let Some(b) = self.batch.as_mut() {
            b.flush(out);
        }
        r
    }
}
