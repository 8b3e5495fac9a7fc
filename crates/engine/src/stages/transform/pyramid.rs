//! `pyramid`: each frame's complex steerable pyramid (`pyramid = "csp"`,
//! Portilla and Simoncelli; thesis Eq. 3.1) or Riesz pyramid (`"riesz"`,
//! Wadhwa et al. 2014) as an edge payload of its own ([`PortType::Pyramid`]):
//! per (scale, orientation) band, the local amplitude and phase, read through
//! [`vibroscope_math::pyramid::PhaseBands`].
//!
//! The coefficients travel as shared handles, not copies: a buffer goes back
//! into use when every stage downstream has let go of it (after warm-up, the
//! stage allocates nothing per frame). Frames are spread over `threads`
//! workers, each computing a whole frame, so the output does not depend on
//! the thread count.
//!
//! `phase` reads this payload as well as frames: `pyramid -> phase` gives
//! the same samples, bit for bit, as `phase` on the frames with the same
//! pyramid settings (checked in `tests/suite/replay.rs`). The split lets other
//! consumers share one pyramid; `phase` alone, which builds its pyramid
//! itself, stays the faster path.
//!
//! ```toml
//! [[stage]]
//! id = "pyr"
//! kind = "pyramid"
//! input = "cam"
//! pyramid = "riesz"   # or "csp" (default)
//! scales = 4
//! orientations = 2
//! ```

use crate::spin::SpinJoin;
use crate::*;
use std::sync::Arc;
use vibroscope_math::join::Join;
use vibroscope_math::pyramid::{ComplexSteerablePyramid, PhaseBands, PyramidCoeffs, PyramidError};
use vibroscope_math::riesz::{RieszCoeffs, RieszPyramid};

/// Which pyramid (`pyramid = "csp" | "riesz"` in `pyramid` and `phase`).
pub use vibroscope_math::pyramid::PyramidKind;

/// Pyramid settings shared by `pyramid` and `phase`.
#[derive(Clone, Copy, Debug)]
pub struct PyramidSpec {
    pub kind: PyramidKind,
    pub scales: usize,
    pub orientations: usize,
    /// The steerable pyramid's orientations 0 and K/2 on half grids.
    pub half_grids: bool,
}

/// `half_grids`, shared by `pyramid` and `phase`.
pub(super) const HALF_GRIDS: ParamSpec = ParamSpec::new("half_grids", ParamType::Bool, Def::Bool(false))
    .doc("csp only: compute orientation 0 (and K/2 for an even K) on half its scale's grid, the same band values every second column (row): with the default 2 orientations half the pyramid's work and the sums' (listen --method phase --pyramid csp: 0.89 -> 0.52 s for 2200 frames of 256x256); the A²-weighted sums then see half the samples, which cost up to 0.3 dB of SNR on noisy scenes (docs/performance.md); riesz ignores it");

/// `pyramid`, shared by `pyramid` and `phase`.
pub const PYRAMID: ParamSpec = ParamSpec::new(
    "pyramid",
    ParamType::Choice(&["csp", "riesz"]),
    Def::Str("csp"),
)
.doc("complex steerable pyramid, or the faster Riesz pyramid");
/// `scales`, shared by `pyramid` and `phase`.
pub(super) const SCALES: ParamSpec = ParamSpec::new("scales", ParamType::Int, Def::Int(4))
    .ints(1, 8)
    .doc("pyramid scales (octaves)");
/// `orientations`, shared by `pyramid` and `phase`.
pub(super) const ORIENTATIONS: ParamSpec =
    ParamSpec::new("orientations", ParamType::Int, Def::Int(2))
        .ints(1, 8)
        .doc("orientations per scale");
/// `threads`, shared by `pyramid` and `phase`.
pub(super) const FRAME_THREADS: ParamSpec = ParamSpec::new("threads", ParamType::Int, Def::Int(0))
    .ints(0, 256)
    .doc("workers, each analysing whole frames, so as many frames at once (0 = one per core, at most 8); bit-identical for any");

/// The steerable pyramid of `phase` and `pyramid`: with `half_grids`,
/// compact ([`ComplexSteerablePyramid::new_compact`]).
pub(super) fn new_csp(
    w: usize,
    h: usize,
    scales: usize,
    orientations: usize,
    half_grids: bool,
) -> Result<ComplexSteerablePyramid, PyramidError> {
    if half_grids {
        ComplexSteerablePyramid::new_compact(w, h, scales, orientations)
    } else {
        ComplexSteerablePyramid::new(w, h, scales, orientations)
    }
}

/// [`new_csp`] for each worker of `phase` and `pyramid` in turn, the
/// residuals off: the first made, the others its clones (the same masks,
/// not made again: at 256x256 with 2 orientations a pyramid's masks took
/// 6 ms to make).
pub(super) fn csp_workers(
    w: usize,
    h: usize,
    scales: usize,
    orientations: usize,
    half_grids: bool,
) -> impl FnMut() -> Result<ComplexSteerablePyramid, PyramidError> {
    let mut first: Option<ComplexSteerablePyramid> = None;
    move || {
        if let Some(p) = &first {
            return Ok(p.clone());
        }
        let mut p = new_csp(w, h, scales, orientations, half_grids)?;
        p.set_residuals(false);
        first = Some(p.clone());
        Ok(p)
    }
}

/// Worker threads: 0 = one per core, at most 8.
pub(super) fn resolve_threads(n: usize) -> usize {
    match n {
        0 => std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .min(8),
        n => n,
    }
}

pub(super) fn pyramid_err(e: PyramidError) -> StageError {
    StageError::dsp(format!("pyramid: {e}"))
}

/// Something that turns an item into per-band coefficients: a pyramid
/// (from a frame) or the coefficients an upstream `pyramid` stage carried.
pub(super) trait Analyzer: Send {
    type C: PhaseBands + Send + Sync;
    /// Coefficients of this analyzer's layout.
    fn alloc(&self) -> Self::C;
    /// `input` is scratch of the frame's size.
    fn analyze(
        &mut self,
        item: &Item,
        input: &mut [f32],
        c: &mut Self::C,
    ) -> Result<(), StageError>;
    /// [`Analyzer::analyze`], calling `each(c, s)` for each of the
    /// `scales` scales once it is complete: by default after the whole
    /// analysis; a pyramid built scale by scale calls it as each is made,
    /// while the scale is still in cache.
    fn analyze_scales(
        &mut self,
        item: &Item,
        input: &mut [f32],
        c: &mut Self::C,
        scales: usize,
        each: &mut dyn FnMut(&Self::C, usize),
    ) -> Result<(), StageError> {
        self.analyze(item, input, c)?;
        (0..scales).for_each(|s| each(c, s));
        Ok(())
    }
}

/// A pyramid that analyses frames.
pub(super) trait FramePyramid: Send {
    type C: PhaseBands + Send + Sync;
    fn alloc_coeffs(&self) -> Self::C;
    fn analyze_frame(&mut self, x: &[f32], c: &mut Self::C) -> Result<(), PyramidError>;
    /// [`FramePyramid::analyze_frame`] with `each(c, s)` called for each of
    /// the `scales` scales once it is complete (see
    /// [`Analyzer::analyze_scales`]).
    fn analyze_frame_scales(
        &mut self,
        x: &[f32],
        c: &mut Self::C,
        scales: usize,
        each: &mut dyn FnMut(&Self::C, usize),
    ) -> Result<(), PyramidError> {
        self.analyze_frame(x, c)?;
        (0..scales).for_each(|s| each(c, s));
        Ok(())
    }
    /// [`FramePyramid::analyze_frame_scales`] of a frame of bytes, read as
    /// bytes (no `f32` copy of the frame; the same bits).
    fn analyze_bytes_scales(
        &mut self,
        px: &[u8],
        c: &mut Self::C,
        scales: usize,
        each: &mut dyn FnMut(&Self::C, usize),
    ) -> Result<(), PyramidError>;
    /// The coefficients as an edge payload.
    fn wrap(c: Arc<Self::C>) -> PyramidData;
}

impl FramePyramid for ComplexSteerablePyramid {
    type C = PyramidCoeffs;
    fn alloc_coeffs(&self) -> PyramidCoeffs {
        ComplexSteerablePyramid::alloc_coeffs(self)
    }
    fn analyze_frame(&mut self, x: &[f32], c: &mut PyramidCoeffs) -> Result<(), PyramidError> {
        self.analyze(x, c)
    }
    /// From the bytes, each row widened as the forward FFT takes it (the
    /// same bits: [`ComplexSteerablePyramid::analyze_u8`]).
    fn analyze_bytes_scales(
        &mut self,
        px: &[u8],
        c: &mut PyramidCoeffs,
        scales: usize,
        each: &mut dyn FnMut(&PyramidCoeffs, usize),
    ) -> Result<(), PyramidError> {
        self.analyze_u8(px, c)?;
        (0..scales).for_each(|s| each(c, s));
        Ok(())
    }
    fn wrap(c: Arc<PyramidCoeffs>) -> PyramidData {
        PyramidData::Csp(c)
    }
}

impl FramePyramid for RieszPyramid {
    type C = RieszCoeffs;
    fn alloc_coeffs(&self) -> RieszCoeffs {
        RieszPyramid::alloc_coeffs(self)
    }
    fn analyze_frame(&mut self, x: &[f32], c: &mut RieszCoeffs) -> Result<(), PyramidError> {
        self.analyze(x, c)
    }
    /// Level by level: each level's phase sums read it while it is still
    /// in cache (a 256x256 level's triple is 768 KiB).
    fn analyze_frame_scales(
        &mut self,
        x: &[f32],
        c: &mut RieszCoeffs,
        _scales: usize,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) -> Result<(), PyramidError> {
        self.analyze_levels(x, c, each)
    }
    /// From the bytes, without widening them into `input` (the same bits:
    /// [`RieszPyramid::analyze_levels_u8`]).
    fn analyze_bytes_scales(
        &mut self,
        px: &[u8],
        c: &mut RieszCoeffs,
        _scales: usize,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) -> Result<(), PyramidError> {
        self.analyze_levels_u8(px, c, each)
    }
    fn wrap(c: Arc<RieszCoeffs>) -> PyramidData {
        PyramidData::Riesz(c)
    }
}

/// A pyramid on frames, as an [`Analyzer`].
pub(super) struct OnFrames<P>(pub P);

impl<P: FramePyramid> Analyzer for OnFrames<P> {
    type C = P::C;
    fn alloc(&self) -> P::C {
        self.0.alloc_coeffs()
    }
    fn analyze(&mut self, item: &Item, input: &mut [f32], c: &mut P::C) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        analyze_frame_into(&mut self.0, f, input, c, 0, &mut |_, _| {}).map_err(pyramid_err)
    }
    fn analyze_scales(
        &mut self,
        item: &Item,
        input: &mut [f32],
        c: &mut P::C,
        scales: usize,
        each: &mut dyn FnMut(&P::C, usize),
    ) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        analyze_frame_into(&mut self.0, f, input, c, scales, each).map_err(pyramid_err)
    }
}

/// `f` into `c` through `p`, calling `each(c, s)` for each of `scales`
/// scales once it is complete: a frame of bytes read as bytes
/// ([`FramePyramid::analyze_bytes_scales`], the same bits as widened),
/// 16-bit frames widened into `input` first.
fn analyze_frame_into<P: FramePyramid>(
    p: &mut P,
    f: &Frame,
    input: &mut [f32],
    c: &mut P::C,
    scales: usize,
    each: &mut dyn FnMut(&P::C, usize),
) -> Result<(), PyramidError> {
    match f.pixels() {
        PixelsRef::U8(px) => p.analyze_bytes_scales(px, c, scales, each),
        PixelsRef::U16(px) => {
            input
                .iter_mut()
                .zip(px)
                .for_each(|(d, &s)| *d = f32::from(s));
            p.analyze_frame_scales(input, c, scales, each)
        }
    }
}

/// A pyramid stage's coefficients, as an [`Analyzer`] (no work: the
/// handle is taken). `first` gives the layout.
pub(super) struct Carried<C> {
    pub first: Arc<C>,
}

/// Unwraps the payload of one pyramid kind.
pub(super) trait CarriedKind: PhaseBands + Send + Sync + Sized {
    const NAME: &'static str;
    fn get(d: &PyramidData) -> Option<&Arc<Self>>;
}

impl CarriedKind for PyramidCoeffs {
    const NAME: &'static str = "csp";
    fn get(d: &PyramidData) -> Option<&Arc<Self>> {
        match d {
            PyramidData::Csp(c) => Some(c),
            PyramidData::Riesz(_) => None,
        }
    }
}

impl CarriedKind for RieszCoeffs {
    const NAME: &'static str = "riesz";
    fn get(d: &PyramidData) -> Option<&Arc<Self>> {
        match d {
            PyramidData::Riesz(c) => Some(c),
            PyramidData::Csp(_) => None,
        }
    }
}

impl<C: CarriedKind> Analyzer for Carried<C> {
    type C = Arc<C>;
    fn alloc(&self) -> Arc<C> {
        Arc::clone(&self.first)
    }
    fn analyze(&mut self, item: &Item, _: &mut [f32], c: &mut Arc<C>) -> Result<(), StageError> {
        let Item::Pyramid(p) = item else {
            return Err(StageError::expected("pyramid coefficients"));
        };
        let got = C::get(&p.data).ok_or_else(|| {
            StageError::format(format!(
                "the pyramid kind changed mid-stream (expected {})",
                C::NAME
            ))
        })?;
        *c = Arc::clone(got);
        Ok(())
    }
}

params! {
    /// `pyramid`'s parameters.
    pub struct PyramidParams for "pyramid" {
        pyramid: PyramidKind = PYRAMID,
        scales: usize = SCALES,
        orientations: usize = ORIENTATIONS,
        half_grids: bool = HALF_GRIDS,
        threads: usize = FRAME_THREADS,
    }
}

type P = PyramidParams;

pub const KIND: KindSpec = KindSpec {
    name: "pyramid",
    summary: "complex steerable or Riesz pyramid per frame (Eq. 3.1) -> local amplitude and phase per band, for phase",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: &[OutPort::out(PortType::Pyramid)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        let spec = PyramidSpec {
            kind: v.pyramid,
            scales: v.scales,
            orientations: v.orientations,
            half_grids: v.half_grids,
        };
        Ok(Box::new(PyramidPlan {
            spec,
            threads: resolve_threads(v.threads),
        }))
    },
};

struct PyramidPlan {
    spec: PyramidSpec,
    threads: usize,
}

impl Plan for PyramidPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(PyramidStage {
            crew: Crew::new(self.threads, "pyramid-worker")?,
            spec: self.spec,
            threads: self.threads,
            held_downstream: ctx.held_downstream,
            workers: None,
            pending: Vec::with_capacity(self.threads),
        })))
    }

    fn frames_held(&self) -> usize {
        self.threads
    }
}

/// The threads a batch of frames (one per worker) is spread over.
///
/// Two workers, the common case on a two-core machine, run as the
/// caller and one helper that spins between batches ([`SpinJoin`]): a
/// 256x256 frame's analysis takes a few hundred microseconds, and rayon's
/// sleeping workers took tens of them to wake for each batch (about 15% of
/// `listen --method phase`'s time went to waking and sleeping). More than
/// two go to a rayon pool.
pub(super) enum Crew {
    Alone,
    Pair(SpinJoin),
    Pool(rayon::ThreadPool),
}

impl Crew {
    /// A crew of `threads` threads (the caller's included); `name` names
    /// the helper threads.
    pub(super) fn new(threads: usize, name: &str) -> Result<Self, StageError> {
        Ok(match threads {
            0 | 1 => Crew::Alone,
            2 => Crew::Pair(
                SpinJoin::new(name, std::time::Duration::from_micros(500))
                    .map_err(|e| StageError::thread(format!("the {name} helper"), e))?,
            ),
            _ => match super::reduce::thread_pool(threads)? {
                Some(pool) => Crew::Pool(pool),
                None => Crew::Alone,
            },
        })
    }

    /// Runs `job` on each (worker, item) pair of a batch: across the crew
    /// when there are several, in order on this thread otherwise.
    pub(super) fn spread<W: Send, T: Sync>(
        &self,
        workers: &mut [W],
        batch: &[T],
        job: impl Fn(&mut W, &T) + Send + Sync,
    ) {
        use rayon::prelude::*;
        match (self, workers, batch) {
            (Crew::Pair(two), [w0, w1, ..], [t0, t1]) => {
                two.join(&mut || job(w0, t0), &mut || job(w1, t1));
            }
            (Crew::Pool(pool), workers, batch) if batch.len() > 1 => pool.install(|| {
                workers
                    .par_iter_mut()
                    .zip(batch.par_iter())
                    .for_each(|(w, t)| job(w, t))
            }),
            (_, workers, batch) => workers.iter_mut().zip(batch).for_each(|(w, t)| job(w, t)),
        }
    }

    /// Runs `job(worker, i)` for each `i` in `0..n`, each worker taking
    /// the next `i` as soon as it is free (so a worker whose core the OS
    /// lent to another thread takes fewer, and neither waits for the
    /// other's share); in order on the first worker when alone.
    pub(super) fn share<W: Send>(
        &self,
        workers: &mut [W],
        n: usize,
        job: impl Fn(&mut W, usize) + Send + Sync,
    ) {
        use rayon::prelude::*;
        use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
        let next = AtomicUsize::new(0);
        let take = |w: &mut W| loop {
            let i = next.fetch_add(1, Relaxed);
            if i >= n {
                break;
            }
            job(w, i);
        };
        match (self, workers) {
            (Crew::Pair(two), [w0, w1, ..]) if n > 1 => {
                two.join(&mut || take(w0), &mut || take(w1));
            }
            (Crew::Pool(pool), workers) if n > 1 && workers.len() > 1 => {
                pool.install(|| workers.par_iter_mut().for_each(take))
            }
            (_, [w0, ..]) => take(w0),
            (_, []) => {}
        }
    }
}

/// Shared buffers that come back into use once nobody else holds them.
struct Recycler<T> {
    items: Vec<Arc<T>>,
}

impl<T> Recycler<T> {
    /// A buffer no other handle points at, or a new one.
    fn take(&mut self, make: impl FnOnce() -> T) -> Arc<T> {
        match self.items.iter().position(|a| Arc::strong_count(a) == 1) {
            Some(i) => self.items.swap_remove(i),
            None => Arc::new(make()),
        }
    }

    fn keep(&mut self, a: &Arc<T>) {
        self.items.push(Arc::clone(a));
    }
}

struct Worker<A: FramePyramid> {
    an: A,
    input: Vec<f32>,
    out: Option<Arc<A::C>>,
    result: Result<(), StageError>,
}

/// The pyramid per frame, frames spread over workers.
trait Analyse: Send {
    fn size(&self) -> (usize, usize);
    fn run(&mut self, frames: &[Frame], crew: &Crew, out: &mut Emitter) -> Result<(), StageError>;
}

struct Workers<A: FramePyramid> {
    workers: Vec<Worker<A>>,
    recycler: Recycler<A::C>,
    size: (usize, usize),
}

impl<A: FramePyramid> Workers<A> {
    fn new(
        mut make: impl FnMut() -> Result<A, PyramidError>,
        n: usize,
        (w, h): (usize, usize),
    ) -> Result<Self, StageError> {
        let mut workers = Vec::with_capacity(n.max(1));
        for _ in 0..n.max(1) {
            workers.push(Worker {
                an: make().map_err(pyramid_err)?,
                input: vec![0.0; w * h],
                out: None,
                result: Ok(()),
            });
        }
        Ok(Self {
            workers,
            recycler: Recycler { items: Vec::new() },
            size: (w, h),
        })
    }
}

impl<A: FramePyramid> Analyse for Workers<A> {
    fn size(&self) -> (usize, usize) {
        self.size
    }

    fn run(&mut self, frames: &[Frame], crew: &Crew, out: &mut Emitter) -> Result<(), StageError> {
        for batch in frames.chunks(self.workers.len()) {
            let workers = &mut self.workers[..batch.len()];
            for w in workers.iter_mut() {
                let an = &w.an;
                w.out = Some(self.recycler.take(|| an.alloc_coeffs()));
            }
            let job = |w: &mut Worker<A>, f: &Frame| {
                w.result = match w.out.as_mut().and_then(Arc::get_mut) {
                    Some(c) => analyze_frame_into(&mut w.an, f, &mut w.input, c, 0, &mut |_, _| {})
                        .map_err(pyramid_err),
                    None => Err(StageError::Internal("pyramid buffer still shared")),
                };
            };
            crew.spread(workers, batch, job);
            for (w, f) in workers.iter_mut().zip(batch) {
                std::mem::replace(&mut w.result, Ok(()))?;
                let Some(c) = w.out.take() else {
                    continue;
                };
                self.recycler.keep(&c);
                let _ = out.emit(Item::Pyramid(PyramidFrame {
                    t_ns: f.meta().t_ns,
                    seq: f.meta().seq,
                    fps: f.format().fps,
                    width: f.width(),
                    height: f.height(),
                    data: A::wrap(c),
                }));
            }
        }
        Ok(())
    }
}

struct PyramidStage {
    crew: Crew,
    spec: PyramidSpec,
    threads: usize,
    /// Coefficient sets the consumers can hold at once (rings + working).
    held_downstream: usize,
    workers: Option<Box<dyn Analyse>>,
    /// Frames waiting for a full batch (one per worker).
    pending: Vec<Frame>,
}

impl PyramidStage {
    fn init(&mut self, f: &Frame) -> Result<(), StageError> {
        let (w, h) = (f.width(), f.height());
        let PyramidSpec {
            kind,
            scales: s,
            orientations: k,
            half_grids,
        } = self.spec;
        let n = self.threads;
        // The workers' pyramids take what the `phase` stage's take; the
        // coefficient sets in flight are recycled, so there are at most
        // as many as the consumers can hold plus one per worker.
        let csp = matches!(kind, PyramidKind::Csp);
        let sets = (self.held_downstream + n + 1) as u64;
        let need = crate::memory::phase_bound(w, h, k, n, csp).saturating_add(
            sets.saturating_mul(crate::memory::pyramid_item_bytes(w, h, s, k, csp)),
        );
        crate::memory::check(
            need,
            &format!(
                "{w}x{h} frames with the {} pyramid, {k} orientations, {n} workers and up to {sets} coefficient sets in flight",
                if csp { "steerable" } else { "Riesz" },
            ),
            if csp {
                "lower `threads` (workers) or the `capacity` of the edges after this stage, or crop the frames before it (a `roi` stage)"
            } else {
                "lower `threads` (workers) or the `capacity` of the edges after this stage, crop the frames before it (a `roi` stage) or use the steerable pyramid (`csp`)"
            },
        )
        .map_err(|message| StageError::Config {
            field: "memory",
            message,
        })?;
        self.workers = Some(match kind {
            PyramidKind::Csp => Box::new(Workers::new(
                csp_workers(w, h, s, k, half_grids),
                n,
                (w, h),
            )?),
            PyramidKind::Riesz => {
                Box::new(Workers::new(|| RieszPyramid::new(w, h, s, k), n, (w, h))?)
            }
        });
        Ok(())
    }

    fn run_pending(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        let Some(workers) = self.workers.as_mut() else {
            return Ok(());
        };
        let r = workers.run(&self.pending, &self.crew, out);
        self.pending.clear();
        r
    }
}

impl Stage for PyramidStage {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        if self.workers.is_none() {
            self.init(&f)?;
        }
        if let Some(w) = &self.workers {
            if (f.width(), f.height()) != w.size() {
                return Err(StageError::format("the frame size changed mid-stream"));
            }
        }
        self.pending.push(f);
        if self.pending.len() >= self.threads {
            self.run_pending(out)?;
        }
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        self.run_pending(out)
    }
}
