//! Phase-based motion magnification (Wadhwa, Rubinstein, Durand, Freeman:
//! "Phase-based video motion processing", SIGGRAPH 2013, with the complex
//! steerable pyramid; "Riesz pyramids for fast phase-based video
//! magnification", ICCP 2014). Per frame and band:
//!
//! 1. the local phase change since the previous frame (wrapped, complex
//!    for the CSP, quaternionic for Riesz), summed over time into a phase
//!    signal per pixel (no wrapping however far it drifts; the Riesz
//!    magnifier keeps no sum: its band-pass takes the changes,
//!    [`temporal::BandpassDesign::on_increments`]);
//! 2. a causal Butterworth band-pass of that signal per pixel
//!    ([`temporal`]), which keeps the motion in `[lo, hi]` Hz;
//! 3. amplitude-weighted Gaussian smoothing of the filtered phase
//!    (`G*(A·φ) / G*A`, σ in band pixels): phase is noise where there is
//!    no contrast;
//! 4. the filtered phase times the factor, limited to `±max_phase`
//!    (default π/2: the papers' bound `α·δ < λ/4` of each band's
//!    wavelength; a pixel beyond it gets the limit, so large factors
//!    saturate instead of blowing up), replaces the filtered phase: the
//!    band is rotated by `clamp(A·φ) - φ`;
//! 5. the pyramid is collapsed (CSP: its tight-frame synthesis; Riesz: a
//!    Laplacian pyramid, [`laplacian`]).
//!
//! A factor of 1 returns the input (up to rounding), below 1 attenuates
//! the motion in the band, 0 removes it. The CSP's high-pass and low-pass
//! residuals (and the Riesz pyramid's low-pass) pass unchanged.
//!
//! Everything is allocated in [`Magnifier::new`]; [`Magnifier::process`]
//! allocates nothing.

pub mod laplacian;
#[cfg(test)]
mod riesz_fft;
mod riesz_fir;
pub mod temporal;

use crate::join::{both, simd_fn, Join, Par, Serial, Simd};
use crate::pyramid::MAX_SCALES;
use crate::pyramid::{BandInfo, Complex32, ComplexSteerablePyramid, PyramidCoeffs, PyramidError};
use laplacian::Laplacian;
use riesz_fir::RieszFir;
use temporal::{BandpassDesign, FilterPart, PixelFilter, CHUNK};

/// Default σ of the amplitude-weighted phase smoothing, band pixels.
pub const DEFAULT_SIGMA: f32 = 1.0;
/// Default limit of the magnified phase, radians (λ/4 of motion).
pub const DEFAULT_MAX_PHASE: f32 = std::f32::consts::FRAC_PI_2;
/// Default CSP orientations: with 8, the band-limited phase of a textured
/// surface follows its motion in every direction (2 or 4 magnify less:
/// 7.9x and 9.3x for 10x on the simulator's texture).
pub const DEFAULT_ORIENTATIONS: usize = 8;
/// Default order of the temporal Butterworth band-pass.
pub const DEFAULT_ORDER: usize = 2;

/// Which pyramid carries the phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PyramidKind {
    /// Complex steerable pyramid: quality (octave bands, several
    /// orientations, FFT-based).
    Csp,
    /// Riesz pyramid on a Laplacian pyramid: speed (one quadrature triple
    /// per level, its pair by a 7x7 filter, [`riesz_fir`]).
    Riesz,
}

/// What to magnify and how.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagnifyParams {
    /// Frame rate, Hz.
    pub fps: f64,
    /// Band edges, Hz: `0 < lo < hi < fps/2`.
    pub lo_hz: f64,
    pub hi_hz: f64,
    /// Motion in the band is multiplied by this (>= 0).
    pub factor: f32,
    /// Butterworth order of the temporal band-pass (1..=8).
    pub order: usize,
    /// σ of the amplitude-weighted smoothing, band pixels (0 = none).
    pub sigma: f32,
    /// Limit of the magnified phase, radians (> 0).
    pub max_phase: f32,
    pub pyramid: PyramidKind,
    /// Pyramid scales (levels).
    pub scales: usize,
    /// CSP orientations (the Riesz pyramid has one triple per level).
    pub orientations: usize,
}

impl MagnifyParams {
    /// The defaults around a band, factor and rate.
    pub fn new(fps: f64, lo_hz: f64, hi_hz: f64, factor: f32) -> Self {
        Self {
            fps,
            lo_hz,
            hi_hz,
            factor,
            order: DEFAULT_ORDER,
            sigma: DEFAULT_SIGMA,
            max_phase: DEFAULT_MAX_PHASE,
            pyramid: PyramidKind::Csp,
            scales: crate::pyramid::DEFAULT_SCALES,
            orientations: DEFAULT_ORIENTATIONS,
        }
    }

    /// Checks every field; the error names it.
    pub fn check(&self) -> Result<(), MagnifyError> {
        let bad =
            |field: &'static str, message: String| Err(MagnifyError::Param { field, message });
        if !(self.fps.is_finite() && self.fps > 0.0) {
            return bad("fps", format!("must be a positive rate, got {}", self.fps));
        }
        let nyq = self.fps / 2.0;
        if !(self.lo_hz.is_finite() && self.hi_hz.is_finite()) {
            return bad(
                "band",
                format!("{},{} is not a pair of numbers", self.lo_hz, self.hi_hz),
            );
        }
        if self.lo_hz <= 0.0 {
            return bad(
                "band",
                format!("the low edge must be above 0 Hz, got {}", self.lo_hz),
            );
        }
        if self.lo_hz >= self.hi_hz {
            return bad(
                "band",
                format!(
                    "{},{} is inverted or empty: give LO,HI with LO < HI",
                    self.lo_hz, self.hi_hz
                ),
            );
        }
        if self.hi_hz >= nyq {
            return bad(
                "band",
                format!(
                    "the high edge {} Hz is not below the Nyquist frequency {} Hz (half of {} fps)",
                    self.hi_hz, nyq, self.fps
                ),
            );
        }
        if !(self.factor.is_finite() && self.factor >= 0.0) {
            return bad(
                "factor",
                format!("must be a number >= 0, got {}", self.factor),
            );
        }
        if !(1..=8).contains(&self.order) {
            return bad("order", format!("must be in 1..=8, got {}", self.order));
        }
        if !(self.sigma.is_finite() && self.sigma >= 0.0 && self.sigma <= 32.0) {
            return bad(
                "sigma",
                format!("must be in 0..=32 band pixels, got {}", self.sigma),
            );
        }
        if !(self.max_phase.is_finite() && self.max_phase > 0.0) {
            return bad(
                "max_phase",
                format!("must be above 0 rad, got {}", self.max_phase),
            );
        }
        Ok(())
    }
}

/// Why a magnifier cannot be built or run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MagnifyError {
    #[error("{field}: {message}")]
    Param {
        field: &'static str,
        message: String,
    },
    #[error(transparent)]
    Pyramid(#[from] PyramidError),
}

/// The kernel of the amplitude-weighted Gaussian smoothing of the phase
/// (its sums: [`csp_band`] and the Riesz magnifier's phase pass).
#[derive(Clone, Debug)]
struct WeightedBlur {
    kernel: Vec<f32>,
}

impl WeightedBlur {
    fn new(sigma: f32) -> Self {
        let kernel = if sigma > 0.0 {
            let r = (3.0 * sigma).ceil() as isize;
            let k: Vec<f32> = (-r..=r)
                .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
                .collect();
            let s: f32 = k.iter().sum();
            k.iter().map(|v| v / s).collect()
        } else {
            vec![1.0]
        };
        Self { kernel }
    }
}

/// Separable blur of `buf` (`w x h`) in place, edges clamped: the passes
/// one after another over the whole image, which the steerable magnifier
/// ran before [`csp_band`] (the tests' reference for it).
#[cfg(test)]
fn blur(kernel: &[f32], buf: &mut [f32], tmp: &mut [f32], w: usize, h: usize, simd: Simd) {
    blur_rows(simd, kernel, &buf[..w * h], &mut tmp[..w * h], w);
    blur_cols(simd, kernel, &tmp[..w * h], &mut buf[..w * h], w, h, 0);
}

/// Pixels a blur pass sums in registers at once (whole blocks; the rest
/// of a row one by one, in the same order of taps).
const BLUR_BLOCK: usize = 32;

/// `out[i] = Σ_k kernel[k] · src(k)[i]`, the taps in order from 0: in
/// blocks of [`BLUR_BLOCK`] held in registers while every tap is added
/// (one store a pixel instead of one a tap), then the rest.
#[inline(always)]
fn taps_sum<'a>(kernel: &[f32], out: &mut [f32], src: impl Fn(usize) -> &'a [f32]) {
    let n = out.len();
    let whole = n - n % BLUR_BLOCK;
    for x0 in (0..whole).step_by(BLUR_BLOCK) {
        let mut acc = [0.0f32; BLUR_BLOCK];
        for (k, c) in kernel.iter().enumerate() {
            let v = &src(k)[x0..x0 + BLUR_BLOCK];
            for (a, v) in acc.iter_mut().zip(v) {
                *a += c * v;
            }
        }
        out[x0..x0 + BLUR_BLOCK].copy_from_slice(&acc);
    }
    if whole < n {
        let rest = &mut out[whole..];
        rest.fill(0.0);
        for (k, c) in kernel.iter().enumerate() {
            for (o, v) in rest.iter_mut().zip(&src(k)[whole..n]) {
                *o += c * v;
            }
        }
    }
}

/// The longest kernel [`blur_rows`] sums with its length fixed.
const MAX_FIXED_TAPS: usize = 17;

/// `kernel` as an array of its own length (the caller matched the length).
#[inline(always)]
fn fixed<const N: usize>(kernel: &[f32]) -> &[f32; N] {
    match kernel.try_into() {
        Ok(k) => k,
        Err(_) => unreachable!("blur_rows matched the kernel's length"),
    }
}

/// One block of [`BLUR_BLOCK`] outputs of a row: `acc[i] = Σ_k c[k] ·
/// win[i + k]`, the taps in order from 0 (so the same sums as
/// [`taps_sum`]), all in registers: the tap count is fixed, so the taps
/// unroll and the window's length is known.
#[inline(always)]
fn row_block<const N: usize>(c: &[f32; N], win: &[f32]) -> [f32; BLUR_BLOCK] {
    let win = &win[..BLUR_BLOCK + N - 1];
    let mut acc = [0.0; BLUR_BLOCK];
    for (k, c) in c.iter().enumerate() {
        for (a, v) in acc.iter_mut().zip(&win[k..k + BLUR_BLOCK]) {
            *a += c * v;
        }
    }
    acc
}

/// One row of [`blur_rows`] for a kernel of `N` taps: whole blocks of
/// [`BLUR_BLOCK`] outputs, the last one overlapping the one before it
/// (it sums the same values again), and the blocks at the row's ends read
/// from a copy with the row's end pixels repeated, so every output is one
/// block's sum and none is summed pixel by pixel. The same sums, in the
/// same order, as the clamped convolution.
#[inline(always)]
fn blur_row_fixed<const N: usize>(c: &[f32; N], row: &[f32], out: &mut [f32]) {
    const B: usize = BLUR_BLOCK;
    let (w, r) = (row.len().min(out.len()), N / 2);
    let mut pad = [0.0f32; BLUR_BLOCK + MAX_FIXED_TAPS - 1];
    if w < B {
        if w > 0 {
            let sums = row_block(c, pad_window::<N>(row, 0, &mut pad));
            out[..w].copy_from_slice(&sums[..w]);
        }
        return;
    }
    let mut at = 0;
    loop {
        let win = if at >= r && at + B + r <= w {
            &row[at - r..at + B + r]
        } else {
            pad_window::<N>(row, at, &mut pad)
        };
        out[at..at + B].copy_from_slice(&row_block(c, win));
        if at + B == w {
            return;
        }
        // The last block ends at the row's end.
        at = (at + B).min(w - B);
    }
}

/// The window of a kernel of `N` taps for the block of [`BLUR_BLOCK`]
/// outputs from `at` of a row: the row's pixels `at - N/2..`, its end
/// pixels repeated beyond its ends, copied into `pad`.
#[inline(always)]
fn pad_window<'a, const N: usize>(row: &[f32], at: usize, pad: &'a mut [f32]) -> &'a [f32] {
    let (w, r) = (row.len(), N / 2);
    let pad = &mut pad[..BLUR_BLOCK + N - 1];
    let first = at.saturating_sub(r).min(w);
    let last = (at + BLUR_BLOCK + r).min(w).max(first);
    // Pixels `first..last` of the row land at `left..` of the window.
    let left = (first + r - at).min(pad.len());
    let inside = (last - first).min(pad.len() - left);
    pad[..left].fill(row[0]);
    pad[left..left + inside].copy_from_slice(&row[first..first + inside]);
    pad[left + inside..].fill(row[w - 1]);
    pad
}

simd_fn! {
/// The horizontal pass of [`blur`] over whole rows of `src` into `out`:
/// with the kernel's length fixed for the odd lengths up to
/// [`MAX_FIXED_TAPS`], the general way for any other.
fn blur_rows(kernel: &[f32], src: &[f32], out: &mut [f32], w: usize) {
    blur_rows_inline(kernel, src.chunks_exact(w).zip(out.chunks_exact_mut(w)));
}
}

/// [`blur_rows`]'s body over the rows given (each row with its output),
/// compiled for the caller's vectors: the fused steerable band pass
/// ([`csp_band`]) blurs one row at a time with it.
#[inline(always)]
fn blur_rows_inline<'a>(kernel: &[f32], rows: impl Iterator<Item = (&'a [f32], &'a mut [f32])>) {
    match kernel.len() {
        3 => blur_rows_fixed::<3>(fixed(kernel), rows),
        5 => blur_rows_fixed::<5>(fixed(kernel), rows),
        7 => blur_rows_fixed::<7>(fixed(kernel), rows),
        9 => blur_rows_fixed::<9>(fixed(kernel), rows),
        11 => blur_rows_fixed::<11>(fixed(kernel), rows),
        13 => blur_rows_fixed::<13>(fixed(kernel), rows),
        15 => blur_rows_fixed::<15>(fixed(kernel), rows),
        17 => blur_rows_fixed::<17>(fixed(kernel), rows),
        _ => blur_rows_any(kernel, rows),
    }
}

/// [`blur_rows`] for a kernel of `N` taps.
#[inline(always)]
fn blur_rows_fixed<'a, const N: usize>(
    c: &[f32; N],
    rows: impl Iterator<Item = (&'a [f32], &'a mut [f32])>,
) {
    for (row, out) in rows {
        blur_row_fixed(c, row, out);
    }
}

/// [`blur_rows`] for a kernel of any length.
#[inline(always)]
fn blur_rows_any<'a>(kernel: &[f32], rows: impl Iterator<Item = (&'a [f32], &'a mut [f32])>) {
    let r = kernel.len() / 2;
    for (row, out) in rows {
        let w = row.len();
        // Columns whose taps all fall inside the row.
        let (lo, hi) = (r.min(w), w.saturating_sub(r).max(r.min(w)));
        if hi > lo {
            taps_sum(kernel, &mut out[lo..hi], |k| &row[lo + k - r..hi + k - r]);
        }
        // The edges, clamped.
        for x in (0..lo).chain(hi.max(lo)..w) {
            let mut acc = 0.0;
            for (k, c) in kernel.iter().enumerate() {
                let xi = (x as isize + k as isize - r as isize).clamp(0, w as isize - 1) as usize;
                acc += c * row[xi];
            }
            out[x] = acc;
        }
    }
}

simd_fn! {
/// The vertical pass of [`blur`]: rows `y0..` of the output (as many as
/// `out` holds) from all `h` rows of `tmp`.
fn blur_cols(kernel: &[f32], tmp: &[f32], out: &mut [f32], w: usize, h: usize, y0: usize) {
    let r = kernel.len() / 2;
    for (dy, out) in out.chunks_exact_mut(w).enumerate() {
        let y = y0 + dy;
        taps_sum(kernel, out, |k| {
            let yi = (y as isize + k as isize - r as isize).clamp(0, h as isize - 1) as usize;
            &tmp[yi * w..(yi + 1) * w]
        });
    }
}
}

/// The rotation `clamp(factor·φ, ±limit) - φ` that replaces the filtered
/// phase `φ` by its magnified, limited version.
#[inline(always)]
fn shift(phi: f32, factor: f32, limit: f32) -> f32 {
    (factor * phi).clamp(-limit, limit) - phi
}

/// Per-band state of the CSP magnifier.
struct CspState {
    pyr: ComplexSteerablePyramid,
    /// The residuals ([`ComplexSteerablePyramid::alloc_residuals`]).
    coeffs: PyramidCoeffs,
    /// Each band's phase in the previous frame.
    prev: Vec<Vec<f32>>,
    /// Each band's band-pass state, row by row ([`PixelFilter::with_rows`]).
    filters: Vec<PixelFilter>,
    /// [`csp_band`]'s rows.
    rows: CspRows,
    /// The band being magnified (the largest band's size).
    band: Vec<Complex32>,
}

/// The rows [`csp_band`] works in, for bands up to `w` pixels wide and a
/// blur of up to `taps` taps: one row of phase, amplitude and weighted
/// phase, and the blur's horizontal pass of the weights and of the
/// weighted phase for the `taps` rows its vertical pass reads.
struct CspRows {
    w: usize,
    taps: usize,
    phase: Vec<f32>,
    amp: Vec<f32>,
    num: Vec<f32>,
    den: Vec<f32>,
    /// Row `y`'s horizontal pass at `(y % taps) * w`.
    hden: Vec<f32>,
    hnum: Vec<f32>,
    /// Where the vertical pass's rows sit in `hden` and `hnum`.
    slots: Vec<usize>,
}

impl CspRows {
    fn new(w: usize, taps: usize) -> Self {
        let z = crate::numeric::zeros_touched::<f32>;
        Self {
            w,
            taps,
            phase: z(w),
            amp: z(w),
            num: z(w),
            den: z(w),
            hden: z(w * taps),
            hnum: z(w * taps),
            slots: vec![0; taps],
        }
    }
}

/// Per-level state of the Riesz magnifier.
struct RieszState {
    /// The Riesz pair's filter per level ([`riesz_fir`]).
    pairs: Vec<RieszFir>,
    /// Previous (I, R1, R2) per level.
    prev: Vec<[Vec<f32>; 3]>,
    /// The band-pass of the summed phase·cos θ and phase·sin θ, per level,
    /// fed their changes ([`BandpassDesign::on_increments`]): no sums kept.
    filters: Vec<[PixelFilter; 2]>,
    /// (width, height) of the levels (the pair's and phase's).
    dims: Vec<(usize, usize)>,
    /// Where each level starts in `r1` .. `ps` (and in `tmp3`, three
    /// times as far): the levels one after another, so that one
    /// hand-over runs a pass over every level.
    offs: Vec<usize>,
    /// The row where a level of `h` rows is cut into its two halves
    /// (`h / 2`; the tests move it: any cut gives the same bits).
    cut: fn(usize) -> usize,
    /// One frame's buffers; a second one once frames are pipelined
    /// ([`Magnifier::process_pipelined`]), built on its first call.
    bufs: Vec<RieszFrame>,
    /// Which of `bufs` holds a frame whose shift and collapse have not run.
    pending: Option<usize>,
    /// The pipelined frames' output (empty until then).
    out: Vec<f32>,
}

/// One frame's buffers of the Riesz magnifier, from its pyramid to the
/// phase pass's outputs: what that frame's shift and collapse read.
struct RieszFrame {
    lap: Laplacian,
    r1: Vec<f32>,
    r2: Vec<f32>,
    amp: Vec<f32>,
    pc: Vec<f32>,
    ps: Vec<f32>,
    /// The blur's horizontal pass of the three channels, every level
    /// (empty without smoothing).
    tmp3: Vec<f32>,
}

impl RieszFrame {
    fn new(width: usize, height: usize, scales: usize, smooth: bool) -> Self {
        let lap = Laplacian::new(width, height, scales);
        let total: usize = lap.dims[..scales].iter().map(|&(w, h)| w * h).sum();
        let z = crate::numeric::zeros_touched::<f32>;
        Self {
            lap,
            r1: z(total),
            r2: z(total),
            amp: z(total),
            pc: z(total),
            ps: z(total),
            tmp3: z(if smooth { 3 * total } else { 0 }),
        }
    }
}

/// Writes a frame (row-major, the magnifier's size) into the slice given:
/// [`Magnifier::process_pipelined`]'s input.
pub type Load<'a> = &'a mut (dyn FnMut(&mut [f32]) + Send);
/// Takes a magnified frame: [`Magnifier::process_pipelined`]'s output.
pub type Deliver<'a> = &'a mut (dyn FnMut(&[f32]) + Send);

/// What [`Magnifier::process_body`] is asked for.
enum Job<'a> {
    /// `frame`, magnified into `out`.
    Whole {
        frame: &'a [f32],
        out: &'a mut [f32],
    },
    /// Riesz: the frame `load` writes, up to its phase pass, and the rest
    /// of the pending one, given to `deliver`.
    Pipelined {
        load: Load<'a>,
        deliver: Deliver<'a>,
    },
    /// Riesz: the rest of the pending frame, given to `deliver`.
    Flush { deliver: Deliver<'a> },
}

enum State {
    Csp(Box<CspState>),
    Riesz(Box<RieszState>),
}

/// A streaming motion magnifier for one frame size; see the module docs.
pub struct Magnifier {
    params: MagnifyParams,
    width: usize,
    height: usize,
    design: BandpassDesign,
    blur: WeightedBlur,
    state: State,
    frames: u64,
    simd: Simd,
    profile: Option<Profile>,
    /// The steerable magnifier's frame and output when it is called as a
    /// pipelined one (empty until then).
    scratch: (Vec<f32>, Vec<f32>),
}

impl std::fmt::Debug for Magnifier {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Magnifier")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("params", &self.params)
            .finish_non_exhaustive()
    }
}

impl Magnifier {
    /// Builds the magnifier for `width x height` frames.
    pub fn new(width: usize, height: usize, params: MagnifyParams) -> Result<Self, MagnifyError> {
        Self::new_part(width, height, params, 0..params.orientations, true)
    }

    /// A part of the steerable-pyramid magnifier: only the bands of
    /// `orientations`, and the pyramid's residuals only when `residuals`.
    /// Its output is that part's share of the magnified frame: parts over
    /// disjoint orientation ranges covering them all, exactly one with the
    /// residuals, sum to what [`Self::new`]'s magnifier gives (up to float
    /// rounding), and can run on different threads. The Riesz pyramid
    /// has no such parts: it takes the whole range, with residuals.
    pub fn new_part(
        width: usize,
        height: usize,
        params: MagnifyParams,
        orientations: std::ops::Range<usize>,
        residuals: bool,
    ) -> Result<Self, MagnifyError> {
        params.check()?;
        let whole = orientations == (0..params.orientations) && residuals;
        if params.pyramid == PyramidKind::Riesz && !whole {
            return Err(MagnifyError::Param {
                field: "orientations",
                message: "the Riesz magnifier cannot be split into parts".into(),
            });
        }
        if orientations.start >= orientations.end || orientations.end > params.orientations {
            return Err(MagnifyError::Param {
                field: "orientations",
                message: format!(
                    "{}..{} is not a part of 0..{}",
                    orientations.start, orientations.end, params.orientations
                ),
            });
        }
        crate::pyramid::check_params(width, height, params.scales, params.orientations)?;
        let design = temporal::design(params.order, params.lo_hz, params.hi_hz, params.fps);
        let state = match params.pyramid {
            PyramidKind::Csp => {
                // Only this part's bands: their masks and coefficients.
                let mut pyr = ComplexSteerablePyramid::new_part(
                    width,
                    height,
                    params.scales,
                    params.orientations,
                    orientations.clone(),
                )?;
                pyr.set_residuals(residuals);
                // The residuals only: the bands are streamed through `band`.
                let coeffs = pyr.alloc_residuals();
                // Per-band state only for this part's bands.
                let lens: Vec<usize> = pyr
                    .band_infos()
                    .iter()
                    .enumerate()
                    .map(|(bi, b)| if pyr.band_active(bi) { b.len() } else { 0 })
                    .collect();
                let infos = pyr.band_infos();
                // The band-pass fed each frame's phase change.
                let steps = design.on_increments();
                let wide = infos.iter().map(|b| b.width).max().unwrap_or(0);
                let taps = WeightedBlur::new(params.sigma).kernel.len();
                State::Csp(Box::new(CspState {
                    prev: lens
                        .iter()
                        .map(|&l| crate::numeric::zeros_touched(l))
                        .collect(),
                    filters: lens
                        .iter()
                        .zip(infos)
                        .map(|(&l, b)| match l {
                            0 => PixelFilter::new(&steps, 0),
                            _ => PixelFilter::with_rows(&steps, b.width, b.height),
                        })
                        .collect(),
                    rows: CspRows::new(wide, taps),
                    band: vec![Complex32::default(); lens.iter().copied().max().unwrap_or(0)],
                    pyr,
                    coeffs,
                }))
            }
            PyramidKind::Riesz => {
                let steps = design.on_increments();
                let first = RieszFrame::new(width, height, params.scales, params.sigma > 0.0);
                let dims = &first.lap.dims[..params.scales];
                let lens: Vec<usize> = dims.iter().map(|&(w, h)| w * h).collect();
                let offs: Vec<usize> = std::iter::once(0)
                    .chain(lens.iter().scan(0, |o, l| {
                        *o += l;
                        Some(*o)
                    }))
                    .collect();
                let z = crate::numeric::zeros_touched::<f32>;
                State::Riesz(Box::new(RieszState {
                    prev: lens.iter().map(|&l| [z(l), z(l), z(l)]).collect(),
                    filters: dims
                        .iter()
                        .map(|&(w, h)| {
                            let f = || PixelFilter::with_rows(&steps, w, h);
                            [f(), f()]
                        })
                        .collect(),
                    pairs: dims.iter().map(|&(w, h)| RieszFir::new(w, h)).collect(),
                    offs,
                    dims: dims.to_vec(),
                    cut: |h| h / 2,
                    bufs: vec![first],
                    pending: None,
                    out: Vec::new(),
                }))
            }
        };
        let blur = WeightedBlur::new(params.sigma);
        Ok(Self {
            params,
            width,
            height,
            design,
            blur,
            state,
            frames: 0,
            simd: Simd::detect(),
            profile: None,
            scratch: Default::default(),
        })
    }

    pub fn params(&self) -> &MagnifyParams {
        &self.params
    }

    /// Switches the per-step profile on (from zero) or off.
    pub fn set_profiling(&mut self, on: bool) {
        self.profile = on.then(Profile::default);
    }

    /// The per-step profile since it was switched on ([`STEPS`]).
    pub fn profile(&self) -> Option<&Profile> {
        self.profile.as_ref()
    }

    /// The vector width the per-pixel loops run at: `sse2`, `avx2` or
    /// `avx512`.
    pub fn simd(&self) -> &'static str {
        self.simd.name()
    }

    /// The temporal band-pass in use (its response, for reports).
    pub fn bandpass(&self) -> &BandpassDesign {
        &self.design
    }

    /// Magnifies one frame (row-major `width x height`, any intensity
    /// scale) into `out` (same size). Frames must come in time order.
    ///
    /// The per-pixel loops are compiled three times, for SSE2, AVX2 and
    /// AVX-512 (chosen once, in [`Self::new_part`], from what the CPU
    /// reports): the same IEEE operations in the same order (no FMA
    /// contraction), so every path gives the same bits.
    pub fn process(&mut self, frame: &[f32], out: &mut [f32]) -> Result<(), PyramidError> {
        self.process_with(frame, out, &Serial)
    }

    /// [`Self::process`], each of the Riesz magnifier's passes in two
    /// halves through `j` (both cores, when `j` runs them at once): the
    /// pyramid's passes level by level, the pair, the phase step and the
    /// shift over every level at once, each level's rows cut in two. The
    /// same bits however `j` runs them. The steerable pyramid's
    /// magnifier runs on the caller's thread (it splits by orientations:
    /// [`Self::new_part`]). Not to be mixed with
    /// [`Self::process_pipelined`] without a [`Self::flush`] between.
    pub fn process_with(
        &mut self,
        frame: &[f32],
        out: &mut [f32],
        j: &dyn Join,
    ) -> Result<(), PyramidError> {
        let n = self.width * self.height;
        crate::pyramid::check_len(n, frame.len())?;
        crate::pyramid::check_len(n, out.len())?;
        self.dispatch(Job::Whole { frame, out }, j).map(|_| ())
    }

    /// [`Self::process_with`] with two frames in flight, for the Riesz
    /// magnifier on two threads. `load` writes the frame (row-major,
    /// `width x height`) straight into the pyramid; `deliver` is given
    /// the *previous* frame, magnified. Two hand-overs a frame where
    /// [`Self::process_with`] makes about twenty: the first runs this
    /// frame's `load` and pyramid, then the first rows of the previous
    /// frame's shift, on the calling thread, and the other rows of that
    /// shift on the other; the second runs the previous frame's collapse
    /// and `deliver`, then the first rows of this frame's Riesz pair and
    /// phase pass, on the calling thread, and the other rows on the
    /// other. Both closures run in the first half of a hand-over (on the
    /// calling thread with a join that runs its first half there, as the
    /// engine's does). The cost: a second frame's buffers, and one frame
    /// of latency.
    ///
    /// Returns whether `deliver` was called (not on the first frame after
    /// [`Self::new`] or a [`Self::flush`]); [`Self::flush`] delivers the
    /// last frame. The frames are the same bits as
    /// [`Self::process_with`]'s, one call later. The steerable pyramid's
    /// magnifier has no such split: it loads, magnifies and delivers the
    /// frame itself in the one call, and returns `true`.
    pub fn process_pipelined(
        &mut self,
        load: Load<'_>,
        deliver: Deliver<'_>,
        j: &dyn Join,
    ) -> Result<bool, PyramidError> {
        self.dispatch(Job::Pipelined { load, deliver }, j)
    }

    /// The frame [`Self::process_pipelined`] still holds, magnified and
    /// given to `deliver`; `false` (`deliver` not called) when it holds
    /// none.
    pub fn flush(&mut self, deliver: Deliver<'_>, j: &dyn Join) -> Result<bool, PyramidError> {
        self.dispatch(Job::Flush { deliver }, j)
    }

    fn dispatch(&mut self, job: Job<'_>, j: &dyn Join) -> Result<bool, PyramidError> {
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            // SAFETY: `simd` names only what the running CPU reported
            // (`Simd::detect`), which is all these paths need.
            Simd::Avx512 => return unsafe { self.process_avx512(job, j) },
            Simd::Avx2 => return unsafe { self.process_avx2(job, j) },
            Simd::Sse2 => {}
        }
        self.process_body(job, j)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx2,fma")]
    unsafe fn process_avx512(&mut self, job: Job<'_>, j: &dyn Join) -> Result<bool, PyramidError> {
        self.process_body(job, j)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn process_avx2(&mut self, job: Job<'_>, j: &dyn Join) -> Result<bool, PyramidError> {
        self.process_body(job, j)
    }

    #[inline(always)]
    fn process_body(&mut self, job: Job<'_>, j: &dyn Join) -> Result<bool, PyramidError> {
        let j = Par { j, simd: self.simd };
        let n = self.width * self.height;
        // `piped`: the pipelined call's closures (the Riesz magnifier's).
        let (frame, out, piped) = match job {
            Job::Whole { frame, out } => (frame, out, None),
            Job::Pipelined { load, deliver } => {
                if let State::Csp(_) = self.state {
                    // No split: this frame, at once.
                    let (mut frame, mut out) = std::mem::take(&mut self.scratch);
                    frame.resize(n, 0.0);
                    out.resize(n, 0.0);
                    load(&mut frame);
                    let whole = Job::Whole {
                        frame: &frame,
                        out: &mut out,
                    };
                    let r = self.dispatch(whole, j.j);
                    if r.is_ok() {
                        deliver(&out);
                    }
                    self.scratch = (frame, out);
                    return r;
                }
                (&[][..], &mut [][..], Some((load, deliver)))
            }
            Job::Flush { deliver } => {
                let State::Riesz(s) = &mut self.state else {
                    return Ok(false);
                };
                let Some(i) = s.pending.take() else {
                    return Ok(false);
                };
                let (p, kernel) = (self.params, &self.blur.kernel[..]);
                let geo = RieszGeo::new(&s.dims, &s.offs, s.cut, n);
                let b = &mut s.bufs[i];
                geo.shift(b, kernel, p.factor, p.max_phase, j, || {});
                b.lap.collapse_with(&mut s.out, j);
                deliver(&s.out);
                return Ok(true);
            }
        };
        let first = self.frames == 0;
        self.frames += 1;
        let p = self.params;
        if let Some(pr) = self.profile.as_mut() {
            pr.frames += 1;
        }
        let mut laps = Laps::new(self.profile.as_mut());
        match &mut self.state {
            State::Csp(s) => {
                // A band at a time from its inverse FFT to its forward
                // one (in cache throughout), one buffer for every band.
                s.pyr.stream_begin(frame, &mut s.coeffs)?;
                laps.lap(0);
                for bi in 0..s.prev.len() {
                    if !s.pyr.band_active(bi) {
                        continue;
                    }
                    let Some(&BandInfo {
                        width: w,
                        height: h,
                        ..
                    }) = s.pyr.band_infos().get(bi)
                    else {
                        continue;
                    };
                    let data = &mut s.band[..w * h];
                    s.pyr.stream_band(bi, data)?;
                    laps.lap(0);
                    csp_band(
                        BandSweep {
                            data,
                            prev: &mut s.prev[bi],
                            filter: &mut s.filters[bi],
                            w,
                            h,
                        },
                        &mut s.rows,
                        &self.blur.kernel,
                        (p.factor, p.max_phase),
                        first,
                    );
                    laps.lap(2);
                    s.pyr.stream_band_back(bi, data)?;
                    laps.lap(6);
                }
                let r = s.pyr.stream_end(&s.coeffs, out);
                laps.lap(6);
                r.map(|_| true)
            }
            State::Riesz(s) => {
                let geo = RieszGeo::new(&s.dims, &s.offs, s.cut, n);
                let kernel = &self.blur.kernel[..];
                let smooth = kernel.len() > 1;
                let Some((load, deliver)) = piped else {
                    let b = &mut s.bufs[0];
                    b.lap.analyze_with(frame, j);
                    laps.lap(0);
                    geo.pair(b, &mut s.pairs, j);
                    laps.lap(1);
                    geo.phase(
                        b,
                        &mut s.prev,
                        &mut s.filters,
                        None,
                        kernel,
                        first,
                        j,
                        || {},
                    );
                    laps.lap(2);
                    laps.lap(3);
                    if !smooth {
                        laps.lap(4);
                    }
                    geo.shift(b, kernel, p.factor, p.max_phase, j, || {});
                    if smooth {
                        laps.lap(4);
                    }
                    laps.lap(5);
                    b.lap.collapse_with(out, j);
                    laps.lap(6);
                    return Ok(true);
                };
                // Pipelined: this frame into the buffers the pending one
                // does not hold.
                if s.bufs.len() < 2 {
                    s.bufs
                        .push(RieszFrame::new(self.width, self.height, p.scales, smooth));
                    s.out = crate::numeric::zeros_touched(n);
                }
                let cur = s.pending.map_or(0, |i| 1 - i);
                let (lo, hi) = s.bufs.split_at_mut(1);
                let (b, older) = if cur == 0 {
                    (&mut lo[0], &mut hi[0])
                } else {
                    (&mut hi[0], &mut lo[0])
                };
                let wrote = s.pending.is_some();
                let pairs = Some(&mut s.pairs[..]);
                let (prev, filters, out) = (&mut s.prev, &mut s.filters, &mut s.out);
                if wrote {
                    // Inside a half, its passes in turn.
                    let one = Par {
                        j: &Serial,
                        simd: j.simd,
                    };
                    // Hand-over 1: this frame's load and pyramid, then the
                    // first rows of the previous frame's shift, on this
                    // thread; the rest of the shift on the other.
                    let shift = RieszGeo {
                        cut: |h| h * SHIFT_SHARE / 100,
                        ..geo
                    };
                    let (fa, mp) = (p.factor, p.max_phase);
                    let pyramid = || {
                        load(&mut b.lap.bands[0][..n]);
                        b.lap.analyze_loaded_with(one);
                    };
                    shift.shift(older, kernel, fa, mp, j, pyramid);
                    // Hand-over 2: the previous frame's collapse and
                    // delivery, then the first rows of this frame's pair
                    // and phase pass, on this thread; the rest of them on
                    // the other.
                    let phase = RieszGeo {
                        cut: |h| h * PHASE_SHARE / 100,
                        ..geo
                    };
                    let collapse = || {
                        older.lap.collapse_with(out, one);
                        deliver(out);
                    };
                    phase.phase(b, prev, filters, pairs, kernel, first, j, collapse);
                } else {
                    load(&mut b.lap.bands[0][..n]);
                    b.lap.analyze_loaded_with(j);
                    geo.phase(b, prev, filters, pairs, kernel, first, j, || {});
                }
                laps.lap(2);
                s.pending = Some(cur);
                Ok(wrote)
            }
        }
    }
}

/// The largest frame (pixels) whose Riesz magnifier is worth running with
/// two frames in flight ([`Magnifier::process_pipelined`]), on a 2-core
/// Xeon with AVX-512 (`magnify`, session 69): 1.17x faster at 256x256,
/// 1.1x at 640x480, the same at 384x384, but 1.5x slower at 1920x1080
/// (42 against 28.6 ms a frame), where every pass of one frame takes
/// milliseconds and its halves' hand-overs cost nothing, while the
/// pipeline's fixed shares of the work no longer balance its threads.
pub const PIPELINE_MAX_PIXELS: usize = 640 * 480;

/// Two frames in flight ([`Magnifier::process_pipelined`]): the first
/// half's share, in hundredths of each level's rows, of the shift (that
/// thread also loads the next frame and builds its pyramid: 0.12 of 0.22
/// ms a frame at 256x256 on one core) and of the pair and phase pass (it
/// also collapses and delivers the previous frame: about 0.08 of 0.47
/// ms), so that the two threads finish together. Any share gives the same
/// bits; the times are `cargo bench --bench roofline -- --kernels`.
const SHIFT_SHARE: usize = 23;
const PHASE_SHARE: usize = 42;

/// Where the Riesz magnifier's levels are and how they are cut: what each
/// of its passes over every level needs besides a frame's buffers.
#[derive(Clone, Copy)]
struct RieszGeo<'a> {
    dims: &'a [(usize, usize)],
    offs: &'a [usize],
    cut: fn(usize) -> usize,
    /// The passes are split in halves (the frame is large enough).
    split: bool,
}

impl<'a> RieszGeo<'a> {
    fn new(
        dims: &'a [(usize, usize)],
        offs: &'a [usize],
        cut: fn(usize) -> usize,
        pixels: usize,
    ) -> Self {
        Self {
            dims,
            offs,
            cut,
            split: pixels >= laplacian::SPLIT_MIN,
        }
    }

    /// First row of a level's second half, as an index into the level.
    #[inline(always)]
    fn mid(&self, l: usize) -> usize {
        (self.cut)(self.dims[l].1) * self.dims[l].0
    }

    #[inline(always)]
    fn len(&self, l: usize) -> usize {
        self.dims[l].0 * self.dims[l].1
    }

    /// The Riesz pair of every level of `b`'s pyramid.
    #[inline(always)]
    fn pair(&self, b: &mut RieszFrame, pairs: &mut [RieszFir], j: Par<'_>) {
        let (v, cut) = (j.simd, self.cut);
        let mut jobs: [[Option<PairJob>; MAX_SCALES]; 2] = Default::default();
        let (mut r1, mut r2) = (&mut b.r1[..], &mut b.r2[..]);
        for (l, fir) in pairs.iter_mut().enumerate().take(self.dims.len()) {
            let band = &b.lap.bands[l][..self.len(l)];
            let q1 = take_level(&mut r1, self.len(l)).split_at_mut(self.mid(l));
            let q2 = take_level(&mut r2, self.len(l)).split_at_mut(self.mid(l));
            let [f0, f1] = fir.halves();
            let y1 = cut(self.dims[l].1);
            jobs[0][l] = Some(PairJob {
                fir: f0,
                band,
                y0: 0,
                r1: q1.0,
                r2: q2.0,
            });
            jobs[1][l] = Some(PairJob {
                fir: f1,
                band,
                y0: y1,
                r1: q1.1,
                r2: q2.1,
            });
        }
        let [x, y] = &mut jobs;
        both(
            j,
            self.split,
            || PairJob::run_all(x, v),
            || PairJob::run_all(y, v),
        );
    }

    /// The phase pass of every level of `b` against the state `prev` and
    /// `filters` (the frames' order): `amp` ends as the amplitude, `pc`
    /// and `ps` as `A·φ` of the two phase components (the filtered φ
    /// itself without smoothing), `tmp3` as their blur's horizontal pass.
    /// With `pairs`, each half first makes its rows of the Riesz pair (as
    /// [`Self::pair`] would), so that the pass needs no hand-over of its
    /// own; `before` runs first in the first half.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn phase(
        &self,
        b: &mut RieszFrame,
        prev: &mut [[Vec<f32>; 3]],
        filters: &mut [[PixelFilter; 2]],
        pairs: Option<&mut [RieszFir]>,
        kernel: &[f32],
        first: bool,
        j: Par<'_>,
        mut before: impl FnMut() + Send,
    ) {
        let (v, cut, offs) = (j.simd, self.cut, self.offs);
        let smooth = kernel.len() > 1;
        let scales = self.dims.len();
        let mut jobs: [[Option<PhaseJob>; MAX_SCALES]; 2] = Default::default();
        let (mut den, mut nc, mut ns) = (&mut b.amp[..], &mut b.pc[..], &mut b.ps[..]);
        let (mut r1, mut r2) = (&mut b.r1[..], &mut b.r2[..]);
        let mut tmp = &mut b.tmp3[..if smooth { 3 * offs[scales] } else { 0 }];
        let mut firs = pairs.map(|p| p.iter_mut());
        let levels = prev.iter_mut().zip(filters.iter_mut());
        for (l, ([pi, p1, p2], [fc, fs])) in levels.enumerate().take(scales) {
            let (w, h) = self.dims[l];
            let (n, m) = (self.len(l), self.mid(l));
            let level = &b.lap.bands[l][..n];
            let bd = level.split_at(m);
            let q1 = take_level(&mut r1, n).split_at_mut(m);
            let q2 = take_level(&mut r2, n).split_at_mut(m);
            let (pair0, pair1) = match firs.as_mut().and_then(|f| f.next()) {
                Some(fir) => {
                    let [f0, f1] = fir.halves();
                    (
                        PairIn::Make {
                            fir: f0,
                            level,
                            r: [q1.0, q2.0],
                        },
                        PairIn::Make {
                            fir: f1,
                            level,
                            r: [q1.1, q2.1],
                        },
                    )
                }
                None => (
                    PairIn::Given([&*q1.0, &*q2.0]),
                    PairIn::Given([&*q1.1, &*q2.1]),
                ),
            };
            let (pi, p1, p2) = (
                pi[..n].split_at_mut(m),
                p1[..n].split_at_mut(m),
                p2[..n].split_at_mut(m),
            );
            let outs = [&mut den, &mut nc, &mut ns].map(|x| take_level(x, n).split_at_mut(m));
            let [d, c, sn] = outs;
            let ((fc0, fc1), (fs0, fs1)) = (fc.parts(cut(h)), fs.parts(cut(h)));
            let t = take_level(&mut tmp, if smooth { 3 * n } else { 0 });
            let (t0, t12) = t.split_at_mut(t.len() / 3);
            let (t1, t2) = t12.split_at_mut(t0.len());
            let at = if smooth { m } else { 0 };
            let (x0, y0) = t0.split_at_mut(at);
            let (x1, y1) = t1.split_at_mut(at);
            let (x2, y2) = t2.split_at_mut(at);
            jobs[0][l] = Some(PhaseJob {
                w,
                y0: 0,
                band: bd.0,
                pair: pair0,
                state: [pi.0, p1.0, p2.0],
                outs: [d.0, c.0, sn.0],
                filters: [fc0, fs0],
                rows_out: [x0, x1, x2],
            });
            jobs[1][l] = Some(PhaseJob {
                w,
                y0: cut(h),
                band: bd.1,
                pair: pair1,
                state: [pi.1, p1.1, p2.1],
                outs: [d.1, c.1, sn.1],
                filters: [fc1, fs1],
                rows_out: [y0, y1, y2],
            });
        }
        let [x, y] = &mut jobs;
        both(
            j,
            self.split,
            || {
                before();
                PhaseJob::run_all(x, v, first, kernel)
            },
            || PhaseJob::run_all(y, v, first, kernel),
        );
    }

    /// The blur's vertical pass and the phase shift of every level of
    /// `b`, in place in its pyramid's bands.
    /// `before` runs first in the first half.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn shift(
        &self,
        b: &mut RieszFrame,
        kernel: &[f32],
        factor: f32,
        limit: f32,
        j: Par<'_>,
        mut before: impl FnMut() + Send,
    ) {
        let (v, cut, offs) = (j.simd, self.cut, self.offs);
        let smooth = kernel.len() > 1;
        let scales = self.dims.len();
        let mut jobs: [[Option<ShiftJob>; MAX_SCALES]; 2] = Default::default();
        let (mut den, mut nc, mut ns) = (&mut b.amp[..], &mut b.pc[..], &mut b.ps[..]);
        let tmp = &b.tmp3[..if smooth { 3 * offs[scales] } else { 0 }];
        for (l, band) in b.lap.bands.iter_mut().enumerate().take(scales) {
            let (w, h) = self.dims[l];
            let (n, m, o) = (self.len(l), self.mid(l), offs[l]);
            let (q1, q2) = (b.r1[o..o + n].split_at(m), b.r2[o..o + n].split_at(m));
            let bd = band[..n].split_at_mut(m);
            let [d, c, sn] = [&mut den, &mut nc, &mut ns].map(|x| take_level(x, n).split_at_mut(m));
            let t = if smooth {
                &tmp[3 * o..3 * (o + n)]
            } else {
                &[][..]
            };
            let (t0, t12) = t.split_at(t.len() / 3);
            let (t1, t2) = t12.split_at(t0.len());
            jobs[0][l] = Some(ShiftJob {
                w,
                h,
                y0: 0,
                band: bd.0,
                pair: [q1.0, q2.0],
                outs: [d.0, c.0, sn.0],
                tmps: [t0, t1, t2],
            });
            jobs[1][l] = Some(ShiftJob {
                w,
                h,
                y0: cut(h),
                band: bd.1,
                pair: [q1.1, q2.1],
                outs: [d.1, c.1, sn.1],
                tmps: [t0, t1, t2],
            });
        }
        let run = |jobs: &mut [Option<ShiftJob>]| {
            ShiftJob::run_all(jobs, v, kernel, factor, limit);
        };
        let [x, y] = &mut jobs;
        both(
            j,
            self.split,
            || {
                before();
                run(x)
            },
            || run(y),
        );
    }
}

/// The next `n` values of `rest` (levels one after another); `rest`
/// keeps the ones after them.
#[inline(always)]
fn take_level<'a>(rest: &mut &'a mut [f32], n: usize) -> &'a mut [f32] {
    let (level, tail) = std::mem::take(rest).split_at_mut(n);
    *rest = tail;
    level
}

/// One half of a level's rows of the Riesz pair, for the pass over every
/// level.
struct PairJob<'a> {
    fir: riesz_fir::PairHalf<'a>,
    /// The whole level (the filter reads 3 rows beyond the half).
    band: &'a [f32],
    y0: usize,
    r1: &'a mut [f32],
    r2: &'a mut [f32],
}

impl PairJob<'_> {
    #[inline(always)]
    fn run_all(jobs: &mut [Option<Self>], v: Simd) {
        for job in jobs.iter_mut().flatten() {
            job.fir.rows(v, job.band, job.y0, job.r1, job.r2);
        }
    }
}

/// One half of a level's rows of the phase step, band-pass and the
/// blur's horizontal pass ([`riesz_phase_run`]).
struct PhaseJob<'a> {
    w: usize,
    y0: usize,
    /// This half's rows of the band.
    band: &'a [f32],
    pair: PairIn<'a>,
    state: [&'a mut [f32]; 3],
    outs: [&'a mut [f32]; 3],
    filters: [FilterPart<'a>; 2],
    rows_out: [&'a mut [f32]; 3],
}

impl PhaseJob<'_> {
    #[inline(always)]
    fn run_all(jobs: &mut [Option<Self>], v: Simd, first: bool, kernel: &[f32]) {
        for job in jobs.iter_mut().flatten() {
            let (q1, q2): (&[f32], &[f32]) = match &mut job.pair {
                PairIn::Given([q1, q2]) => (q1, q2),
                PairIn::Make {
                    fir,
                    level,
                    r: [q1, q2],
                } => {
                    fir.rows(v, level, job.y0, q1, q2);
                    (q1, q2)
                }
            };
            let [pi, p1, p2] = &mut job.state;
            let [d, c, sn] = &mut job.outs;
            let [fc, fs] = &mut job.filters;
            let [x0, x1, x2] = &mut job.rows_out;
            riesz_phase_run(
                v,
                v,
                first,
                job.w,
                job.y0,
                [job.band, q1, q2],
                [&mut **pi, &mut **p1, &mut **p2],
                [&mut **d, &mut **c, &mut **sn],
                [fc, fs],
                kernel,
                [&mut **x0, &mut **x1, &mut **x2],
            );
        }
    }
}

/// A half's rows of the Riesz pair, for the phase pass.
enum PairIn<'a> {
    /// Made by [`RieszGeo::pair`] before the pass.
    Given([&'a [f32]; 2]),
    /// To be made by the half itself from the whole `level`, into `r`.
    Make {
        fir: riesz_fir::PairHalf<'a>,
        level: &'a [f32],
        r: [&'a mut [f32]; 2],
    },
}

/// One half of a level's rows of the blur's vertical pass (with
/// smoothing) and the phase shift.
struct ShiftJob<'a> {
    w: usize,
    h: usize,
    y0: usize,
    band: &'a mut [f32],
    pair: [&'a [f32]; 2],
    /// `den`, `nc`, `ns`: the blur's output rows (without smoothing, the
    /// unsmoothed values themselves).
    outs: [&'a mut [f32]; 3],
    /// The horizontal pass of the whole level's three channels (empty
    /// without smoothing).
    tmps: [&'a [f32]; 3],
}

impl ShiftJob<'_> {
    /// With smoothing, by groups of rows: each group's vertical blur is
    /// handed to the shift at once, while it is in cache.
    #[inline(always)]
    fn run_all(jobs: &mut [Option<Self>], v: Simd, kernel: &[f32], factor: f32, limit: f32) {
        const GROUP: usize = 8;
        let smooth = kernel.len() > 1;
        for job in jobs.iter_mut().flatten() {
            let (w, h) = (job.w, job.h);
            let [r1, r2] = job.pair;
            let [d, c, sn] = &mut job.outs;
            if !smooth {
                let outs = [&**d, &**c, &**sn];
                riesz_shift(v, job.band, [r1, r2], outs, false, factor, limit);
                continue;
            }
            let g = GROUP * w;
            let groups = d.chunks_mut(g).zip(c.chunks_mut(g)).zip(sn.chunks_mut(g));
            for (k, ((d, c), sn)) in groups.enumerate() {
                let y = job.y0 + k * GROUP;
                for (t, o) in job.tmps.iter().zip([&mut *d, &mut *c, &mut *sn]) {
                    blur_cols(v, kernel, t, o, w, h, y);
                }
                let rows = k * g..k * g + d.len();
                let q = [&r1[rows.clone()], &r2[rows.clone()]];
                riesz_shift(v, &mut job.band[rows], q, [d, c, sn], true, factor, limit);
            }
        }
    }
}

/// Complex band pixels taken apart into real and imaginary lanes at a
/// time by [`csp_phase_step`] and [`csp_shift`]: read one by one from
/// the interleaved pairs, the vectorised loops gathered each lane
/// (`vgatherqps`), which AMD's cores run several times slower than
/// loads and shuffles.
const CSP_LANES: usize = 16;

/// The steerable magnifier's phase step on one band (Eq. 3.2): each
/// pixel's phase, its change since the previous frame's (`prev`) wrapped
/// into `[-π, π]` into `change` (0 on the first frame), the phase into
/// `prev`, the amplitude into `amp`. The band-pass takes the changes
/// ([`BandpassDesign::on_increments`]): no running sum of them is kept
/// (in f32 it lost digits as the phase drifted), and a pixel's state is
/// its phase, 4 bytes where the previous complex value and the sum were 12.
#[inline(always)]
fn csp_phase_step(
    data: &[Complex32],
    prev: &mut [f32],
    change: &mut [f32],
    amp: &mut [f32],
    first: bool,
) {
    use std::f32::consts::{PI, TAU};
    const K: usize = CSP_LANES;
    let n = data.len().min(prev.len()).min(change.len()).min(amp.len());
    let whole = n / K * K;
    #[inline(always)]
    fn one(re: f32, im: f32, pv: &mut f32, ch: &mut f32, am: &mut f32, first: bool) {
        let a = crate::fastmath::atan2(im, re);
        let d = a - *pv;
        let d = if d > PI {
            d - TAU
        } else if d < -PI {
            d + TAU
        } else {
            d
        };
        *ch = if first { 0.0 } else { d };
        *pv = a;
        *am = (re * re + im * im).sqrt();
    }
    for (((c, pv), ch), am) in data[..whole]
        .chunks_exact(K)
        .zip(prev[..whole].chunks_exact_mut(K))
        .zip(change[..whole].chunks_exact_mut(K))
        .zip(amp[..whole].chunks_exact_mut(K))
    {
        let (mut re, mut im) = ([0f32; K], [0f32; K]);
        for i in 0..K {
            re[i] = c[i].re;
            im[i] = c[i].im;
        }
        for i in 0..K {
            one(re[i], im[i], &mut pv[i], &mut ch[i], &mut am[i], first);
        }
    }
    for (((c, pv), ch), am) in data[whole..n]
        .iter()
        .zip(&mut prev[whole..n])
        .zip(&mut change[whole..n])
        .zip(&mut amp[whole..n])
    {
        one(c.re, c.im, pv, ch, am, first);
    }
}

/// One band of the steerable magnifier and its state.
struct BandSweep<'a> {
    data: &'a mut [Complex32],
    prev: &'a mut [f32],
    filter: &'a mut PixelFilter,
    w: usize,
    h: usize,
}

/// The steerable magnifier's per-pixel steps on one band in one sweep of
/// its rows: a row's phase step ([`csp_phase_step`]), band-pass and the
/// blur's horizontal pass as soon as the blur's vertical pass needs it,
/// then that pass, the weighted mean and the shift ([`csp_shift`]) of
/// the row `r` above (`r` the kernel's radius). A row's values are still
/// in L1 or L2 when the next step reads them, where a pass over the
/// whole band per step wrote and read them from L3 (the band's state
/// does not fit L2 at 256x256). The same operations on each pixel as the
/// steps one after another: the same bits.
#[inline(always)]
fn csp_band(
    band: BandSweep<'_>,
    rows: &mut CspRows,
    kernel: &[f32],
    (factor, limit): (f32, f32),
    first: bool,
) {
    let BandSweep {
        data,
        prev,
        filter,
        w,
        h,
    } = band;
    if w * h == 0 {
        return;
    }
    if w > rows.w || kernel.len() > rows.taps {
        // (Not reached: the magnifier sized them for its bands and kernel.)
        *rows = CspRows::new(w.max(rows.w), kernel.len().max(rows.taps));
    }
    let CspRows {
        phase,
        amp,
        num,
        den,
        hden,
        hnum,
        slots,
        ..
    } = rows;
    let (phase, amp, num, den) = (&mut phase[..w], &mut amp[..w], &mut num[..w], &mut den[..w]);
    // Row `y`'s phase step and band-pass into `phase` and `amp` (a
    // macro, not a closure: a closure is not compiled for the calling
    // function's vectors).
    macro_rules! step {
        ($y:expr, $phase:expr, $amp:expr) => {{
            let at = $y * w..($y + 1) * w;
            csp_phase_step(&data[at.clone()], &mut prev[at], $phase, $amp, first);
            filter.step_row($y, $phase);
        }};
    }
    if kernel.len() <= 1 {
        // No blur: each row shifted by its own filtered phase.
        for y in 0..h {
            step!(y, phase, amp);
            let turns = (&mut num[..], &mut den[..]);
            csp_shift(&mut data[y * w..(y + 1) * w], phase, turns, factor, limit);
        }
        return;
    }
    let (k, r) = (kernel.len(), kernel.len() / 2);
    let mut done = 0;
    for y in 0..h {
        // The rows the vertical pass of row `y` reads, up to `y + r`.
        while done < (y + r + 1).min(h) {
            step!(done, phase, amp);
            for ((o, a), v) in num.iter_mut().zip(amp.iter()).zip(phase.iter()) {
                *o = a * v;
            }
            let slot = (done % k) * w..(done % k + 1) * w;
            let (hd, hn) = (&mut hden[slot.clone()], &mut hnum[slot]);
            blur_rows_inline(kernel, [(&*amp, hd), (&*num, hn)].into_iter());
            done += 1;
        }
        // The ring's slot of row `y + i - r` (clamped to the band, as
        // `blur_cols` clamps).
        for (i, o) in slots.iter_mut().enumerate().take(k) {
            let yi = (y as isize + i as isize - r as isize).clamp(0, h as isize - 1) as usize;
            *o = (yi % k) * w;
        }
        taps_sum(kernel, den, |i| &hden[slots[i]..slots[i] + w]);
        taps_sum(kernel, num, |i| &hnum[slots[i]..slots[i] + w]);
        for ((v, nu), de) in phase.iter_mut().zip(num.iter()).zip(den.iter()) {
            *v = if *de > 1e-12 { nu / de } else { 0.0 };
        }
        let turns = (&mut num[..], &mut den[..]);
        csp_shift(&mut data[y * w..(y + 1) * w], phase, turns, factor, limit);
    }
}

/// The steerable magnifier's phase shift on one band: each pixel turned
/// by its magnified phase change ([`shift`] of `phase`), the turns' sines
/// and cosines first into `sn` and `cs` (at least as long as `data`):
/// two plain loops over the row, which vectorise wherever they are
/// inlined (lanes of 16 in one loop did not, inlined into the band's
/// sweep: its sine and cosine ran lane by lane).
#[inline(always)]
fn csp_shift(
    data: &mut [Complex32],
    phase: &[f32],
    (sn, cs): (&mut [f32], &mut [f32]),
    factor: f32,
    limit: f32,
) {
    let n = data.len().min(phase.len()).min(sn.len()).min(cs.len());
    let (data, phase, sn, cs) = (&mut data[..n], &phase[..n], &mut sn[..n], &mut cs[..n]);
    for ((s, c), &ph) in sn.iter_mut().zip(cs.iter_mut()).zip(phase) {
        (*s, *c) = crate::fastmath::sin_cos(shift(ph, factor, limit));
    }
    for ((d, &s), &c) in data.iter_mut().zip(sn.iter()).zip(cs.iter()) {
        *d *= Complex32::new(c, s);
    }
}

/// The Riesz magnifier's phase step over a run of pixels: the quaternionic
/// phase difference `q·conj(q_prev)` (Wadhwa et al. 2014), its angle times
/// its in-plane axis into `out` (the change of the summed phase; 0 where
/// the axis vanishes and on the first frame: a select, so that the loop
/// vectorises), `prev` set to `q`, `amp` to `|q|`. Its own function so
/// that its slices are known not to overlap (the loop vectorises without
/// runtime checks).
#[inline(always)]
fn riesz_phase_step(
    first: bool,
    [band, r1, r2]: [&[f32]; 3],
    [pi, p1, p2]: [&mut [f32]; 3],
    amp: &mut [f32],
    [xc, xs]: [&mut [f32]; 2],
) {
    let m = band.len();
    let (r1, r2, pi, p1, p2) = (&r1[..m], &r2[..m], &mut pi[..m], &mut p1[..m], &mut p2[..m]);
    let (amp, xc, xs) = (&mut amp[..m], &mut xc[..m], &mut xs[..m]);
    for k in 0..m {
        let (iv, x1, x2) = (band[k], r1[k], r2[k]);
        let (qi, q1, q2) = (pi[k], p1[k], p2[k]);
        let re = iv * qi + x1 * q1 + x2 * q2;
        let vx = -iv * q1 + qi * x1;
        let vy = -iv * q2 + qi * x2;
        let vn = (vx * vx + vy * vy).sqrt();
        let d = crate::fastmath::atan2(vn, re) / vn;
        let moved = vn > 0.0 && !first;
        xc[k] = if moved { d * vx } else { 0.0 };
        xs[k] = if moved { d * vy } else { 0.0 };
        (pi[k], p1[k], p2[k]) = (iv, x1, x2);
        amp[k] = (iv * iv + x1 * x1 + x2 * x2).sqrt();
    }
}

simd_fn! {
/// Rows `y0..` of a Riesz level (`w` wide; the slices hold those rows), in
/// blocks of [`CHUNK`] pixels: the phase step, the temporal band-pass of
/// the block (its sections in turn, both components), and the smoothing's
/// numerators `A·φ` into `nc`, `ns` (`φ` itself without smoothing). With
/// smoothing, each finished row of `den`, `nc`, `ns` is blurred along x
/// into `rows_out` at once (its vertical pass comes when all rows are).
fn riesz_phase_run(
    vec: Simd,
    first: bool,
    w: usize,
    y0: usize,
    input: [&[f32]; 3],
    state: [&mut [f32]; 3],
    outs: [&mut [f32]; 3],
    filters: [&mut FilterPart<'_>; 2],
    kernel: &[f32],
    rows_out: [&mut [f32]; 3],
) {
    let [band, r1, r2] = input;
    let [pi, p1, p2] = state;
    let [den, nc, ns] = outs;
    let [fc, fs] = filters;
    let mut rows_out = rows_out;
    let smooth = kernel.len() > 1;
    let rows = band.len() / w.max(1);
    for ry in 0..rows {
        for x0 in (0..w).step_by(CHUNK) {
            let m = CHUNK.min(w - x0);
            let (mut xc, mut xs) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
            let r = ry * w + x0..ry * w + x0 + m;
            let (xc, xs) = (&mut xc[..m], &mut xs[..m]);
            riesz_phase_step(
                first,
                [&band[r.clone()], &r1[r.clone()], &r2[r.clone()]],
                [&mut pi[r.clone()], &mut p1[r.clone()], &mut p2[r.clone()]],
                &mut den[r.clone()],
                [&mut *xc, &mut *xs],
            );
            fc.step_at(xc, y0 + ry, x0);
            fs.step_at(xs, y0 + ry, x0);
            let (dn, ncc, nsc) = (&den[r.clone()], &mut nc[r.clone()], &mut ns[r]);
            if smooth {
                times(dn, xc, ncc);
                times(dn, xs, nsc);
            } else {
                ncc.copy_from_slice(xc);
                nsc.copy_from_slice(xs);
            }
        }
        if smooth {
            let row = ry * w..(ry + 1) * w;
            for (src, dst) in [&*den, &*nc, &*ns].into_iter().zip(rows_out.iter_mut()) {
                blur_rows(vec, kernel, &src[row.clone()], &mut dst[row.clone()], w);
            }
        }
    }
}
}

/// `out[k] = a[k] · b[k]`.
#[inline(always)]
fn times(a: &[f32], b: &[f32], out: &mut [f32]) {
    for ((o, x), y) in out.iter_mut().zip(a).zip(b) {
        *o = x * y;
    }
}

simd_fn! {
/// The Riesz magnifier's phase shift of one level: the smoothed phase
/// `(c, s) = G*(A·φ) / G*A` (or `nc`, `ns` themselves without smoothing),
/// magnified and limited, rotates the band: `band <- Re(q·exp(n·ψ))`, `n`
/// the unit axis `(c, s)/|φ|` (the band as it is where there is no phase).
fn riesz_shift(
    band: &mut [f32],
    pair: [&[f32]; 2],
    smoothed: [&[f32]; 3],
    smooth: bool,
    factor: f32,
    max_phase: f32,
) {
    let [r1, r2] = pair;
    let [den, nc, ns] = smoothed;
    let m = band.len();
    let (r1, r2, den, nc, ns) = (&r1[..m], &r2[..m], &den[..m], &nc[..m], &ns[..m]);
    for i in 0..m {
        let (c, sn) = if smooth {
            let de = den[i];
            let q = |nu: f32| if de > 1e-12 { nu / de } else { 0.0 };
            (q(nc[i]), q(ns[i]))
        } else {
            (nc[i], ns[i])
        };
        let mag = (c * c + sn * sn).sqrt();
        let psi = shift(mag, factor, max_phase);
        let (sp, cp) = crate::fastmath::sin_cos(psi);
        let rotated = cp * band[i] - sp * (c * r1[i] + sn * r2[i]) / mag;
        band[i] = if mag > 0.0 { rotated } else { band[i] };
    }
}
}

/// The dither of pixel `i` under `key`: uniform in `[-½, ½)`.
#[inline(always)]
fn dither(key: u64, i: usize) -> f32 {
    let h = crate::rng::mix64(key ^ i as u64);
    (h >> 40) as f32 * (1.0 / 16_777_216.0) - 0.5
}

simd_fn! {
fn dither_round_body(values: &mut [f32], key: u64, first: usize, max: f32) {
    for (i, v) in values.iter_mut().enumerate() {
        *v = (*v + dither(key, first + i)).round().clamp(0.0, max);
    }
}
}

/// `$name`: [`dither_round`] into pixels of type `$t`, whose largest
/// value is `$lim`.
macro_rules! dither_round_into {
    ($name:ident, $t:ty, $lim:expr) => {
        simd_fn! {
        fn $name(values: &[f32], key: u64, first: usize, max: f32, out: &mut [$t]) {
            // (`as` would saturate the same way; this limit lets the
            // conversion below skip the checks that kept it from
            // vectorising.)
            let max = max.min($lim);
            for (i, (o, v)) in out.iter_mut().zip(values).enumerate() {
                let r = (*v + dither(key, first + i)).round().clamp(0.0, max);
                // A NaN value becomes 0, as `as` makes it.
                let r = if r >= 0.0 { r } else { 0.0 };
                // SAFETY: `r` is finite and in `0..=$lim`, which `i32` holds.
                *o = unsafe { r.to_int_unchecked::<i32>() } as $t;
            }
        }
        }
    };
}
dither_round_into!(dither_round_u8_body, u8, 255.0);
dither_round_into!(dither_round_u16_body, u16, 65535.0);

/// [`dither_round`] written as 8-bit pixels into `out` (as long as
/// `values`; `max` at most 255): the same levels in one pass, `values`
/// left as they are.
pub fn dither_round_u8(values: &[f32], key: u64, first: usize, max: f32, out: &mut [u8]) {
    dither_round_u8_body(Simd::detect(), values, key, first, max, out);
}

/// [`dither_round_u8`] for 16-bit pixels (`max` at most 65535).
pub fn dither_round_u16(values: &[f32], key: u64, first: usize, max: f32, out: &mut [u16]) {
    dither_round_u16_body(Simd::detect(), values, key, first, max, out);
}

/// A magnified frame's values made pixel levels: each `values[i]` (pixel
/// `first + i` of the frame) plus a uniform dither in `[-½, ½)` drawn from
/// `mix64(key ^ pixel)`, rounded and limited to `0..=max`. The dither
/// keeps a change smaller than half a level from rounding back to the
/// input's own integers. Vectorised (AVX2, AVX-512 where present).
pub fn dither_round(values: &mut [f32], key: u64, first: usize, max: f32) {
    dither_round_body(Simd::detect(), values, key, first, max);
}

/// The steps of [`Magnifier::process`], in the order they run, for a
/// profile ([`Magnifier::set_profiling`]): each kernel's share of a frame,
/// which `docs/performance.md` sets against its bound. The Riesz
/// magnifier fuses some: the band-pass (and the blur's horizontal pass)
/// into the phase step, the shift into the blur's vertical pass; a fused
/// step's time counts in the step it is fused into.
pub const STEPS: [&str; 7] = [
    "pyramid build",
    "Riesz pair (7x7 filter)",
    "phase difference, sum, amplitude",
    "temporal band-pass",
    "amplitude-weighted blur",
    "phase shift",
    "pyramid collapse",
];

/// Time spent in each of [`STEPS`] since profiling was switched on, and
/// the frames it covers.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Profile {
    pub seconds: [f64; STEPS.len()],
    pub frames: u64,
}

/// The clock of a profiled run: `lap(k)` adds the time since the last lap
/// to step `k`. A no-op (no clock read) when profiling is off.
struct Laps<'a> {
    profile: Option<&'a mut Profile>,
    last: Option<std::time::Instant>,
}

impl<'a> Laps<'a> {
    fn new(profile: Option<&'a mut Profile>) -> Self {
        let last = profile.as_ref().map(|_| std::time::Instant::now());
        Self { profile, last }
    }
    #[inline(always)]
    fn lap(&mut self, step: usize) {
        if let (Some(p), Some(last)) = (self.profile.as_deref_mut(), self.last.as_mut()) {
            let now = std::time::Instant::now();
            p.seconds[step] += (now - *last).as_secs_f64();
            *last = now;
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests;
