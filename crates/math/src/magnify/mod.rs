//! Phase-based motion magnification (Wadhwa, Rubinstein, Durand, Freeman:
//! "Phase-based video motion processing", SIGGRAPH 2013, with the complex
//! steerable pyramid; "Riesz pyramids for fast phase-based video
//! magnification", ICCP 2014). Per frame and band:
//!
//! 1. the local phase change since the previous frame (wrapped, complex
//!    for the CSP, quaternionic for Riesz), summed over time into a phase
//!    signal per pixel (no wrapping however far it drifts);
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
mod riesz_fft;
pub mod temporal;

use crate::pyramid::{Complex32, ComplexSteerablePyramid, PyramidCoeffs, PyramidError};
use laplacian::Laplacian;
use riesz_fft::RieszFft;
use temporal::{BandpassDesign, PixelFilter};

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
    /// per level, its pair by one FFT each way, [`riesz_fft`]).
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

/// Amplitude-weighted Gaussian smoothing, allocated once for the largest band.
#[derive(Clone, Debug)]
struct WeightedBlur {
    kernel: Vec<f32>,
    num: Vec<f32>,
    den: Vec<f32>,
    tmp: Vec<f32>,
}

impl WeightedBlur {
    fn new(sigma: f32, max_len: usize) -> Self {
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
        Self {
            kernel,
            num: vec![0.0; max_len],
            den: vec![0.0; max_len],
            tmp: vec![0.0; max_len],
        }
    }

    /// `phase[c] <- G*(amp·phase[c]) / G*amp` for each channel `c` (the
    /// channels share the weights).
    fn apply(&mut self, amp: &[f32], phases: &mut [&mut [f32]], w: usize, h: usize) {
        if self.kernel.len() == 1 {
            return;
        }
        let n = w * h;
        self.den[..n].copy_from_slice(&amp[..n]);
        blur(&self.kernel, &mut self.den[..n], &mut self.tmp[..n], w, h);
        for p in phases.iter_mut() {
            for ((o, a), v) in self.num[..n].iter_mut().zip(&amp[..n]).zip(p.iter()) {
                *o = a * v;
            }
            blur(&self.kernel, &mut self.num[..n], &mut self.tmp[..n], w, h);
            for ((v, nu), de) in p.iter_mut().zip(&self.num[..n]).zip(&self.den[..n]) {
                *v = if *de > 1e-12 { nu / de } else { 0.0 };
            }
        }
    }
}

/// Separable blur of `buf` (`w x h`) in place, edges clamped. Each pass
/// runs tap by tap over whole rows (the interior without index clamping),
/// which vectorises.
fn blur(kernel: &[f32], buf: &mut [f32], tmp: &mut [f32], w: usize, h: usize) {
    let r = kernel.len() / 2;
    for y in 0..h {
        let row = &buf[y * w..(y + 1) * w];
        let out = &mut tmp[y * w..(y + 1) * w];
        // Columns whose taps all fall inside the row.
        let (lo, hi) = (r.min(w), w.saturating_sub(r).max(r.min(w)));
        if hi > lo {
            out[lo..hi].fill(0.0);
            for (k, c) in kernel.iter().enumerate() {
                for (o, v) in out[lo..hi].iter_mut().zip(&row[lo + k - r..hi + k - r]) {
                    *o += c * v;
                }
            }
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
    for (y, out) in buf.chunks_exact_mut(w).take(h).enumerate() {
        out.fill(0.0);
        for (k, c) in kernel.iter().enumerate() {
            let yi = (y as isize + k as isize - r as isize).clamp(0, h as isize - 1) as usize;
            for (o, v) in out.iter_mut().zip(&tmp[yi * w..(yi + 1) * w]) {
                *o += c * v;
            }
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
    coeffs: PyramidCoeffs,
    prev: Vec<Vec<Complex32>>,
    acc: Vec<Vec<f32>>,
    filters: Vec<PixelFilter>,
    phase: Vec<f32>,
    amp: Vec<f32>,
}

/// Per-level state of the Riesz magnifier.
struct RieszState {
    lap: Laplacian,
    /// The exact Riesz pair per level ([`riesz_fft`]).
    ffts: Vec<RieszFft>,
    /// Previous (I, R1, R2) per level.
    prev: Vec<[Vec<f32>; 3]>,
    /// Summed phase·cos θ and phase·sin θ per level.
    acc: Vec<[Vec<f32>; 2]>,
    filters: Vec<[PixelFilter; 2]>,
    r1: Vec<f32>,
    r2: Vec<f32>,
    amp: Vec<f32>,
    pc: Vec<f32>,
    ps: Vec<f32>,
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
        let n = width * height;
        let blur = WeightedBlur::new(params.sigma, n);
        let state = match params.pyramid {
            PyramidKind::Csp => {
                let mut pyr = ComplexSteerablePyramid::new(
                    width,
                    height,
                    params.scales,
                    params.orientations,
                )?;
                pyr.set_orientations(orientations.clone());
                pyr.set_residuals(residuals);
                let coeffs = pyr.alloc_coeffs();
                // Per-band state only for this part's bands.
                let lens: Vec<usize> = pyr
                    .band_infos()
                    .iter()
                    .enumerate()
                    .map(|(bi, b)| if pyr.band_active(bi) { b.len() } else { 0 })
                    .collect();
                let max = lens.iter().copied().max().unwrap_or(0);
                State::Csp(Box::new(CspState {
                    prev: lens
                        .iter()
                        .map(|&l| vec![Complex32::new(0.0, 0.0); l])
                        .collect(),
                    acc: lens.iter().map(|&l| vec![0.0; l]).collect(),
                    filters: lens.iter().map(|&l| PixelFilter::new(&design, l)).collect(),
                    phase: vec![0.0; max],
                    amp: vec![0.0; max],
                    pyr,
                    coeffs,
                }))
            }
            PyramidKind::Riesz => {
                let lap = Laplacian::new(width, height, params.scales);
                let lens: Vec<usize> = lap.dims[..params.scales]
                    .iter()
                    .map(|&(w, h)| w * h)
                    .collect();
                let z = |l: usize| vec![0.0f32; l];
                State::Riesz(Box::new(RieszState {
                    prev: lens.iter().map(|&l| [z(l), z(l), z(l)]).collect(),
                    acc: lens.iter().map(|&l| [z(l), z(l)]).collect(),
                    filters: lens
                        .iter()
                        .map(|&l| [PixelFilter::new(&design, l), PixelFilter::new(&design, l)])
                        .collect(),
                    ffts: lap.dims[..params.scales]
                        .iter()
                        .map(|&(w, h)| RieszFft::new(w, h))
                        .collect(),
                    r1: z(n),
                    r2: z(n),
                    amp: z(n),
                    pc: z(n),
                    ps: z(n),
                    lap,
                }))
            }
        };
        Ok(Self {
            params,
            width,
            height,
            design,
            blur,
            state,
            frames: 0,
        })
    }

    pub fn params(&self) -> &MagnifyParams {
        &self.params
    }

    /// The temporal band-pass in use (its response, for reports).
    pub fn bandpass(&self) -> &BandpassDesign {
        &self.design
    }

    /// Magnifies one frame (row-major `width x height`, any intensity
    /// scale) into `out` (same size). Frames must come in time order.
    pub fn process(&mut self, frame: &[f32], out: &mut [f32]) -> Result<(), PyramidError> {
        let n = self.width * self.height;
        crate::pyramid::check_len(n, frame.len())?;
        crate::pyramid::check_len(n, out.len())?;
        let first = self.frames == 0;
        self.frames += 1;
        let p = self.params;
        match &mut self.state {
            State::Csp(s) => {
                s.pyr.analyze(frame, &mut s.coeffs)?;
                for bi in 0..s.coeffs.num_bands() {
                    if !s.pyr.band_active(bi) {
                        continue;
                    }
                    let Some(band) = s.coeffs.band_mut(bi) else {
                        continue;
                    };
                    let (w, h) = (band.width(), band.height());
                    let len = w * h;
                    let data = band.data_mut();
                    let (prev, acc) = (&mut s.prev[bi], &mut s.acc[bi]);
                    let (phase, amp) = (&mut s.phase[..len], &mut s.amp[..len]);
                    // Eq. 3.2: wrapped phase change since the previous frame, summed.
                    for ((((c, pv), a), ph), am) in data
                        .iter()
                        .zip(prev.iter_mut())
                        .zip(acc.iter_mut())
                        .zip(phase.iter_mut())
                        .zip(amp.iter_mut())
                    {
                        if !first {
                            let d = c * pv.conj();
                            *a += crate::fastmath::atan2(d.im, d.re);
                        }
                        *pv = *c;
                        *ph = *a;
                        *am = (c.re * c.re + c.im * c.im).sqrt();
                    }
                    s.filters[bi].step(phase);
                    self.blur.apply(amp, &mut [phase], w, h);
                    for (c, &ph) in data.iter_mut().zip(phase.iter()) {
                        let psi = shift(ph, p.factor, p.max_phase);
                        let (sn, cs) = crate::fastmath::sin_cos(psi);
                        *c *= Complex32::new(cs, sn);
                    }
                }
                s.pyr.synthesize(&s.coeffs, out)
            }
            State::Riesz(s) => {
                s.lap.analyze(frame);
                for l in 0..p.scales {
                    let (w, h) = s.lap.dims[l];
                    let len = w * h;
                    let band = &mut s.lap.bands[l];
                    let (r1, r2) = (&mut s.r1[..len], &mut s.r2[..len]);
                    s.ffts[l].pair(band, r1, r2);
                    let [pi, p1, p2] = &mut s.prev[l];
                    let [ac, as_] = &mut s.acc[l];
                    let (amp, pc, ps) = (&mut s.amp[..len], &mut s.pc[..len], &mut s.ps[..len]);
                    for i in 0..len {
                        let (iv, x1, x2) = (band[i], r1[i], r2[i]);
                        if !first {
                            // Quaternionic phase difference q·conj(q_prev)
                            // (Wadhwa et al. 2014): angle and in-plane axis.
                            let (qi, q1, q2) = (pi[i], p1[i], p2[i]);
                            let re = iv * qi + x1 * q1 + x2 * q2;
                            let vx = -iv * q1 + qi * x1;
                            let vy = -iv * q2 + qi * x2;
                            let vn = (vx * vx + vy * vy).sqrt();
                            if vn > 0.0 {
                                let d = crate::fastmath::atan2(vn, re) / vn;
                                ac[i] += d * vx;
                                as_[i] += d * vy;
                            }
                        }
                        (pi[i], p1[i], p2[i]) = (iv, x1, x2);
                        amp[i] = (iv * iv + x1 * x1 + x2 * x2).sqrt();
                        pc[i] = ac[i];
                        ps[i] = as_[i];
                    }
                    let [fc, fs] = &mut s.filters[l];
                    fc.step(pc);
                    fs.step(ps);
                    self.blur.apply(amp, &mut [&mut *pc, &mut *ps], w, h);
                    for i in 0..len {
                        let (c, sn) = (pc[i], ps[i]);
                        let mag = (c * c + sn * sn).sqrt();
                        if mag <= 0.0 {
                            continue;
                        }
                        // Real part of q·exp(n·ψ), n the unit axis (c, s)/|φ|.
                        let psi = shift(mag, p.factor, p.max_phase);
                        let (sp, cp) = crate::fastmath::sin_cos(psi);
                        band[i] = cp * band[i] - sp * (c * r1[i] + sn * r2[i]) / mag;
                    }
                }
                s.lap.collapse(out);
                Ok(())
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests;
