//! Modal images (thesis ch. 3.5, Eq. 3.18-3.19): the slice of the spectral
//! volume U(x, y, ω) = F_t(A² u(x, y, t)) at one frequency, blurred and
//! normalised as in ch. 3.5.2, and shown with phase as hue and amplitude as
//! brightness (ch. 3.5.3).
//!
//! # What is computed
//!
//! Each frame goes through a complex steerable pyramid or a Riesz pyramid
//! ([`PyramidKind`]; two orientations: band 0 sees x motion, band 1 y).
//! At one scale `s` and per band pixel, Δφ is the wrapped phase change
//! against the first frame (Eq. 3.2) and g the phase change per input pixel
//! of motion along the band's axis (about -2π f, f the local spatial
//! frequency), measured at the end on the mean frame (where the sensor
//! noise has averaged out) moved by one pixel either way (a central
//! difference): the same for both pyramids.
//! The displacement is the least-squares fit of Δφ = g·u over the pixels
//! under the blur, each weighted by its texture A²: u = G∗(A² g Δφ) /
//! G∗(A² g²). A pixel whose phase hardly moves with the object (g near 0:
//! smooth content at a fine scale, or a static outline) adds nothing, where
//! dividing its Δφ by its own small g would turn its noise into motion.
//!
//! An optional mask ([`ModalImager::set_mask`]) limits the object: band
//! pixels whose input position is outside it get no weight (in the
//! frequency measurement and in the image), and the image is zero there.
//!
//! Per pixel the exact discrete-time Fourier transform of the tapered,
//! mean-removed displacement is accumulated *at the requested frequency
//! itself* (not at the nearest FFT bin), at each frame's capture time, so
//! nothing but a few numbers per pixel is kept: the video is streamed.
//! The taper is w(τ) = (1 - x²)², x = 2τ/T - 1, over the recording's span
//! T (Hann-like: highest sidelobe -27.7 dB against Hann's -31.5, the same
//! 18 dB/octave fall-off, a main lobe 8% narrower). Its moments are polynomial in τ, so accumulating
//! Σ u τ^k e^{-iωτ} for k = 2, 3, 4 lets the taper be applied after the last
//! frame without knowing the length in advance. The result is scaled to the
//! complex amplitude in pixels: a motion a·cos(ωτ + φ) at exactly ω reads
//! a·e^{iφ}.
//!
//! The weights A² are the mean frame's (free of the sensor noise's energy).
//! With fixed weights, the per-frame filtering of ch. 3.5.2 (Gaussian blur
//! of std σ_b of the weighted displacements and of the weights, then the
//! ratio) commutes with the temporal transform, so it is applied once at
//! the end to the transformed slice, exactly: G∗(A² g ΔΦ) / G∗(A² g²) (with
//! `normalize = false`, divided by max G∗(A² g²) instead: the unnormalised
//! images of ch. 4-5, where the texture's information acts as a mask).
//! With `Motion::Sum` (the x + y images of ch. 4-5) both bands are fitted
//! together, with g the phase change per pixel of motion along x and along
//! y for each band (a band's phase also turns with motion across its
//! axis): per pixel, the motion along its own direction
//! (`along_own_axis`); adding the two bands' sums instead, as a sum of
//! the x and y images, read a motion along x alone at half its amplitude.
//!
//! Memory: 8 f64 per band pixel and orientation; the pyramid's buffers; the
//! frame sum (one f64 per input pixel). Nothing is allocated per frame.

use crate::pyramid::{
    BandInfo, ComplexSteerablePyramid, PhaseBands, PyramidCoeffs, PyramidError, PyramidKind,
};
use crate::riesz::{RieszCoeffs, RieszPyramid};
pub use rustfft::num_complex::{Complex32, Complex64};
use std::f64::consts::TAU;

/// Which motion the image shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Motion {
    X,
    Y,
    /// Both bands fitted together: each pixel's motion along its own
    /// direction (`along_own_axis`).
    Sum,
}

impl Motion {
    /// The orientation bands this motion uses (0 = x, 1 = y).
    fn bands(self) -> &'static [usize] {
        match self {
            Motion::X => &[0],
            Motion::Y => &[1],
            Motion::Sum => &[0, 1],
        }
    }
}

/// Parameters of a modal image.
#[derive(Clone, Copy, Debug)]
pub struct ModalConfig {
    /// The frequency of the slice, Hz.
    pub freq_hz: f64,
    /// Pyramid scale (0 = finest, a 4-pixel wavelength; each next one doubles).
    pub scale: usize,
    /// σ_b, the Gaussian blur's standard deviation in input pixels (0 = none).
    pub sigma_px: f64,
    pub motion: Motion,
    /// Divide by the blurred weights (ch. 3.5.2); otherwise by their maximum.
    pub normalize: bool,
    /// The pyramid that measures local phase.
    pub pyramid: PyramidKind,
}

/// Errors of the modal imager.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModalError {
    #[error("pyramid: {0}")]
    Pyramid(#[from] PyramidError),
    #[error("frame is {got} pixels, expected {expected}")]
    FrameSize { expected: usize, got: usize },
    #[error("{0} frames span no time: a modal image needs at least 3 frames at distinct times")]
    TooShort(u64),
    #[error("frame times go backwards ({0} ns after {1} ns)")]
    TimeOrder(i64, i64),
    #[error("the mask has {got} pixels, the frames {expected}")]
    MaskSize { expected: usize, got: usize },
    #[error("the mask selects no pixel")]
    EmptyMask,
    #[error("the mask must be set before the first frame")]
    MaskTooLate,
    #[error("{0}")]
    Leader(&'static str),
}

/// A pyramid the imager analyses frames with.
trait Analyze: Send {
    type C: PhaseBands + Clone + Send;
    fn infos(&self) -> &[BandInfo];
    fn alloc(&self) -> Self::C;
    fn run(&mut self, frame: &[f32], out: &mut Self::C) -> Result<(), PyramidError>;
    /// Per band pixel, the share of the local energy oriented along the
    /// band's axis (the pyramid's own orientation selectivity: 1 for the
    /// steerable pyramid, whose bands are oriented filters).
    fn orientation_share(_c: &Self::C, _band: usize, out: &mut [f32]) {
        out.fill(1.0);
    }
}

impl Analyze for ComplexSteerablePyramid {
    type C = PyramidCoeffs;
    fn infos(&self) -> &[BandInfo] {
        self.band_infos()
    }
    fn alloc(&self) -> PyramidCoeffs {
        self.alloc_coeffs()
    }
    fn run(&mut self, frame: &[f32], out: &mut PyramidCoeffs) -> Result<(), PyramidError> {
        self.analyze(frame, out)
    }
}

impl Analyze for RieszPyramid {
    type C = RieszCoeffs;
    fn infos(&self) -> &[BandInfo] {
        self.band_infos()
    }
    fn alloc(&self) -> RieszCoeffs {
        self.alloc_coeffs()
    }
    fn run(&mut self, frame: &[f32], out: &mut RieszCoeffs) -> Result<(), PyramidError> {
        self.analyze(frame, out)
    }
    /// The Riesz pyramid's bands share one amplitude over all orientations:
    /// cos²(θ - θk) = Rk² / (R1² + R2²), Rk the Riesz pair projected on the
    /// band's axis (θ0 = 0: R1; θ1 = π/2: R2), so that texture oriented
    /// across the axis, which does not see motion along it, gets no weight.
    fn orientation_share(c: &RieszCoeffs, band: usize, out: &mut [f32]) {
        let Some(level) = c.level(band / 2) else {
            return out.fill(1.0);
        };
        let along_y = band % 2 == 1;
        for ((o, &r1), &r2) in out.iter_mut().zip(level.r1()).zip(level.r2()) {
            let e = r1 * r1 + r2 * r2;
            let k = if along_y { r2 } else { r1 };
            *o = if e > 0.0 { k * k / e } else { 0.5 };
        }
    }
}

/// A pyramid, the current frame's coefficients and the reference's.
struct Analysis<P: Analyze> {
    pyr: P,
    coeffs: P::C,
    reference: Option<P::C>,
}

impl<P: Analyze + 'static> Analysis<P> {
    /// The analysis behind the imager's interface, and the shape of `band`.
    fn boxed(pyr: P, band: usize) -> (Box<dyn Phases>, BandInfo) {
        let info = pyr.infos()[band].clone();
        let coeffs = pyr.alloc();
        let a = Analysis {
            pyr,
            coeffs,
            reference: None,
        };
        (Box::new(a), info)
    }
}

/// What the imager needs of a pyramid, whichever it is.
trait Phases: Send {
    /// Analyses a frame into the current coefficients.
    fn analyze(&mut self, frame: &[f32]) -> Result<(), PyramidError>;
    /// The current coefficients become the reference.
    fn keep_reference(&mut self);
    fn has_reference(&self) -> bool;
    /// Wrapped phase change of `band` from the reference to the current frame.
    fn delta(&self, band: usize, out: &mut [f32]) -> Result<(), PyramidError>;
    /// Amplitude of `band` in the current frame.
    fn amplitude(&self, band: usize, out: &mut [f32]) -> Result<(), PyramidError>;
    /// [`Analyze::orientation_share`] of the current frame.
    fn orientation_share(&self, band: usize, out: &mut [f32]);
    /// For the current frame and copies of it moved back (`back`) and
    /// forward (`fwd`): per band of `bands`, the wrapped phase change from
    /// `back` to the current frame (`from_back`) and from it to `fwd`
    /// (`to_fwd`). Each copy is analysed once for all the bands; the
    /// current and reference coefficients stay as they were.
    fn steps(
        &mut self,
        moved: (&[f32], &[f32]),
        bands: &[usize],
        from_back: &mut [Vec<f32>],
        to_fwd: &mut [Vec<f32>],
    ) -> Result<(), PyramidError>;
}

impl<P: Analyze> Phases for Analysis<P> {
    fn analyze(&mut self, frame: &[f32]) -> Result<(), PyramidError> {
        self.pyr.run(frame, &mut self.coeffs)
    }
    fn keep_reference(&mut self) {
        self.reference = Some(self.coeffs.clone());
    }
    fn has_reference(&self) -> bool {
        self.reference.is_some()
    }
    fn delta(&self, band: usize, out: &mut [f32]) -> Result<(), PyramidError> {
        match &self.reference {
            Some(r) => self.coeffs.phase_delta_into(r, band, out),
            None => Err(PyramidError::LayoutMismatch),
        }
    }
    fn amplitude(&self, band: usize, out: &mut [f32]) -> Result<(), PyramidError> {
        self.coeffs.amplitude_into(band, out)
    }
    fn orientation_share(&self, band: usize, out: &mut [f32]) {
        P::orientation_share(&self.coeffs, band, out)
    }
    fn steps(
        &mut self,
        (back, fwd): (&[f32], &[f32]),
        bands: &[usize],
        from_back: &mut [Vec<f32>],
        to_fwd: &mut [Vec<f32>],
    ) -> Result<(), PyramidError> {
        let mut b = self.pyr.alloc();
        self.pyr.run(back, &mut b)?;
        let mut f = self.pyr.alloc();
        self.pyr.run(fwd, &mut f)?;
        for ((&band, fb), tf) in bands.iter().zip(from_back).zip(to_fwd) {
            self.coeffs.phase_delta_into(&b, band, fb)?;
            f.phase_delta_into(&self.coeffs, band, tf)?;
        }
        Ok(())
    }
}

/// One orientation band's accumulators on the band grid.
struct BandAcc {
    band: usize,
    /// Σ Δφ τ^k e^{-iωτ}, k = 2, 3, 4, per pixel (radians: the phase per
    /// pixel of motion is measured at the end, `ModalImager::phase_per_px`).
    acc: Vec<[Complex64; 3]>,
    /// Σ Δφ per pixel (for the mean).
    sum: Vec<f64>,
    /// Σ A² per pixel over the frames: with the mean frame's A², the
    /// noise's power there ([`ModalImage::texture_to_noise`]).
    power: Vec<f64>,
}

/// Streams frames in and accumulates one frequency slice of the spectral
/// volume; [`ModalImager::finish`] returns the modal image.
pub struct ModalImager {
    cfg: ModalConfig,
    width: usize,
    height: usize,
    pyr: Box<dyn Phases>,
    /// Input pixels inside the object (all when no mask is set).
    inside: Option<Vec<bool>>,
    /// Band pixels whose input position is inside the mask.
    band_inside: Option<Vec<bool>>,
    delta: Vec<f32>,
    bands: Vec<BandAcc>,
    grid_w: usize,
    grid_h: usize,
    step: (f64, f64),
    t0_ns: Option<i64>,
    last_ns: i64,
    frames: u64,
    /// Σ frames: the mean frame, nearly free of sensor noise, is where the
    /// phase per pixel of motion is measured.
    frame_sum: Vec<f64>,
    /// Σ τ^k (k = 2, 3, 4) and Σ τ^k e^{-iωτ}: the taper's own sums.
    real_moments: [f64; 3],
    moments: [Complex64; 3],
    /// Fed by a leader's pyramid ([`ModalImager::push_following`]), its
    /// own left unused; `None` before the first frame.
    follows: Option<bool>,
}

/// A modal image: complex amplitude (pixels of motion) per input pixel,
/// row-major `width x height`, and the blurred weights behind each value.
#[derive(Clone, Debug)]
pub struct ModalImage {
    pub width: usize,
    pub height: usize,
    pub freq_hz: f64,
    pub data: Vec<Complex32>,
    /// G∗(A² g²), relative to its maximum: the motion information per pixel
    /// (1 = the best-textured place).
    pub confidence: Vec<f32>,
    /// The band's texture against the sensor noise: the median over the
    /// object of |B̄|² / (mean |B|² - |B̄|²), B̄ the mean frame's
    /// coefficient (the texture) and the rest the frames' spread around it
    /// (the noise, and the motion itself); the larger of the two bands'
    /// for `Motion::Sum`. Under 1, most of the image is noise: the scale
    /// sees little texture (a smooth object at a fine scale).
    pub texture_to_noise: f64,
    /// Frames and time span used.
    pub frames: u64,
    pub span_s: f64,
}

/// Adds frame time `tau` to the taper's sums (`real`: Σ τ^k, `moments`:
/// Σ τ^k e^{-iωτ}, k = 2, 3, 4, at `freq_hz`); returns τ^k e^{-iωτ}.
fn add_moments(
    freq_hz: f64,
    real: &mut [f64; 3],
    moments: &mut [Complex64; 3],
    tau: f64,
) -> [Complex64; 3] {
    let (s, co) = (TAU * freq_hz * tau).sin_cos();
    let e = Complex64::new(co, -s);
    let t2 = tau * tau;
    let p = [t2, t2 * tau, t2 * t2];
    let c = [e * p[0], e * p[1], e * p[2]];
    for k in 0..3 {
        real[k] += p[k];
        moments[k] += c[k];
    }
    c
}

impl ModalImager {
    /// An imager for `width x height` frames.
    pub fn new(width: usize, height: usize, cfg: ModalConfig) -> Result<Self, ModalError> {
        let band = cfg.scale * 2;
        let (pyr, info) = match cfg.pyramid {
            PyramidKind::Csp => {
                let mut pyr = ComplexSteerablePyramid::new(width, height, cfg.scale + 1, 2)?;
                pyr.set_residuals(false);
                Analysis::boxed(pyr, band)
            }
            PyramidKind::Riesz => {
                Analysis::boxed(RieszPyramid::new(width, height, cfg.scale + 1, 2)?, band)
            }
        };
        let n = info.len();
        let bands = cfg
            .motion
            .bands()
            .iter()
            .map(|&o| BandAcc {
                band: cfg.scale * 2 + o,
                acc: vec![[Complex64::new(0.0, 0.0); 3]; n],
                sum: vec![0.0; n],
                power: vec![0.0; n],
            })
            .collect();
        Ok(Self {
            cfg,
            width,
            height,
            pyr,
            inside: None,
            band_inside: None,
            delta: vec![0.0; n],
            bands,
            grid_w: info.width,
            grid_h: info.height,
            step: (info.step_x as f64, info.step_y as f64),
            t0_ns: None,
            last_ns: 0,
            frames: 0,
            frame_sum: vec![0.0; width * height],
            real_moments: [0.0; 3],
            moments: [Complex64::new(0.0, 0.0); 3],
            follows: None,
        })
    }

    /// Limits the object to the input pixels where `inside` is true
    /// (row-major `width x height`); call before the first frame.
    pub fn set_mask(&mut self, inside: &[bool]) -> Result<(), ModalError> {
        if self.frames > 0 {
            return Err(ModalError::MaskTooLate);
        }
        if inside.len() != self.width * self.height {
            return Err(ModalError::MaskSize {
                expected: self.width * self.height,
                got: inside.len(),
            });
        }
        let (gw, gh) = (self.grid_w, self.grid_h);
        let band: Vec<bool> = (0..gw * gh)
            .map(|i| {
                let (x, y) = self.band_to_input(i % gw, i / gw);
                inside[y * self.width + x]
            })
            .collect();
        if !band.iter().any(|&v| v) {
            return Err(ModalError::EmptyMask);
        }
        self.inside = Some(inside.to_vec());
        self.band_inside = Some(band);
        Ok(())
    }

    /// The input pixel a band pixel sits on.
    fn band_to_input(&self, bx: usize, by: usize) -> (usize, usize) {
        let x = ((bx as f64 * self.step.0).round() as usize).min(self.width - 1);
        let y = ((by as f64 * self.step.1).round() as usize).min(self.height - 1);
        (x, y)
    }

    /// Frames accumulated so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Adds one frame (row-major `width x height`) captured at `t_ns`.
    pub fn push(&mut self, frame: &[f32], t_ns: i64) -> Result<(), ModalError> {
        self.check(frame, t_ns, false)?;
        self.pyr.analyze(frame)?;
        let first = !self.pyr.has_reference();
        if first {
            self.pyr.keep_reference();
        }
        self.accumulate(None, frame, t_ns, first)
    }

    /// [`ModalImager::push`] with the pyramid `leader` has just analysed
    /// `frame` with (its own `push` of the same frame): several imagers of
    /// one recording (modes, axes) analyse each frame once, and each gets
    /// the bits it would get on its own. `leader` must be the same size
    /// and pyramid at the same scale, have taken every frame this imager
    /// takes, the first the same; an imager takes every frame one way.
    pub fn push_following(
        &mut self,
        leader: &ModalImager,
        frame: &[f32],
        t_ns: i64,
    ) -> Result<(), ModalError> {
        self.check(frame, t_ns, true)?;
        let same = (
            leader.width,
            leader.height,
            leader.cfg.scale,
            leader.cfg.pyramid,
        ) == (self.width, self.height, self.cfg.scale, self.cfg.pyramid);
        if !same
            || leader.follows != Some(false)
            || leader.last_ns != t_ns
            || leader.frames != self.frames + 1
        {
            return Err(ModalError::Leader(
                "the leader must be an imager of the same size, pyramid and scale that has just taken this frame itself",
            ));
        }
        self.accumulate(Some(&*leader.pyr), frame, t_ns, self.frames == 0)
    }

    /// The frame's size and time, and that the imager is fed one way.
    fn check(&mut self, frame: &[f32], t_ns: i64, following: bool) -> Result<(), ModalError> {
        if frame.len() != self.width * self.height {
            return Err(ModalError::FrameSize {
                expected: self.width * self.height,
                got: frame.len(),
            });
        }
        if self.frames > 0 && t_ns < self.last_ns {
            return Err(ModalError::TimeOrder(t_ns, self.last_ns));
        }
        if *self.follows.get_or_insert(following) != following {
            return Err(ModalError::Leader(
                "an imager takes every frame from its own pyramid or every frame from a leader's",
            ));
        }
        Ok(())
    }

    /// Adds `frame`, analysed by `pyr` (this imager's own when `None`;
    /// `first`: it is the reference).
    fn accumulate(
        &mut self,
        pyr: Option<&dyn Phases>,
        frame: &[f32],
        t_ns: i64,
        first: bool,
    ) -> Result<(), ModalError> {
        let pyr: &dyn Phases = match pyr {
            Some(p) => p,
            None => &*self.pyr,
        };
        for (a, &v) in self.frame_sum.iter_mut().zip(frame) {
            *a += f64::from(v);
        }
        for b in &mut self.bands {
            pyr.amplitude(b.band, &mut self.delta)?;
            for (p, &a) in b.power.iter_mut().zip(&self.delta) {
                *p += f64::from(a) * f64::from(a);
            }
        }
        let t0 = *self.t0_ns.get_or_insert(t_ns);
        self.last_ns = t_ns;
        self.frames += 1;
        let freq = self.cfg.freq_hz;
        if first {
            // Δφ = 0 on the reference frame: only the taper's sums move.
            add_moments(freq, &mut self.real_moments, &mut self.moments, 0.0);
            return Ok(());
        }
        let tau = (t_ns - t0) as f64 * 1e-9;
        let c = add_moments(freq, &mut self.real_moments, &mut self.moments, tau);
        for b in &mut self.bands {
            pyr.delta(b.band, &mut self.delta)?;
            for ((a, s), &d) in b.acc.iter_mut().zip(b.sum.iter_mut()).zip(&self.delta) {
                let u = f64::from(d);
                a[0] += c[0] * u;
                a[1] += c[1] * u;
                a[2] += c[2] * u;
                *s += u;
            }
        }
        Ok(())
    }

    /// Every band's phase change per input pixel of motion along x (along
    /// y if `vertical`), per band pixel (radians), measured on the `mean`
    /// frame, which must be the one analysed last, moved by one pixel
    /// either way: the central difference, the mean of the phase changes
    /// from the copy moved by -1 to the frame and from the frame to the
    /// copy moved by +1 (one-sided, it is the slope half a pixel away,
    /// which at the finest scale read a motion along x and y together 8%
    /// low). Zero on the band's first and last columns (rows), which see
    /// the repeated edge.
    fn phase_per_px(&mut self, mean: &[f32], vertical: bool) -> Result<Vec<Vec<f64>>, ModalError> {
        let (w, h) = (self.width, self.height);
        // moved(x) = mean(x - s), the edge column (row) repeated.
        let shifted = |s: isize| -> Vec<f32> {
            let mut moved = vec![0.0f32; w * h];
            for y in 0..h {
                for x in 0..w {
                    let (sx, sy) = if vertical {
                        (x, (y as isize - s).clamp(0, h as isize - 1) as usize)
                    } else {
                        ((x as isize - s).clamp(0, w as isize - 1) as usize, y)
                    };
                    moved[y * w + x] = mean[sy * w + sx];
                }
            }
            moved
        };
        let (gw, gh) = (self.grid_w, self.grid_h);
        let bands: Vec<usize> = self.bands.iter().map(|b| b.band).collect();
        // Each one-pixel step wrapped on its own (two pixels at once would
        // wrap at the finest scale, whose phase turns up to π per pixel).
        let mut back = vec![vec![0.0f32; gw * gh]; bands.len()];
        let mut fwd = back.clone();
        self.pyr
            .steps((&shifted(-1), &shifted(1)), &bands, &mut back, &mut fwd)?;
        let (x0, x1, y0, y1) = if vertical {
            (0, gw, 1, gh.saturating_sub(1))
        } else {
            (1, gw.saturating_sub(1), 0, gh)
        };
        Ok(back
            .iter()
            .zip(&fwd)
            .map(|(back, fwd)| {
                let mut g = vec![0.0f64; gw * gh];
                for by in y0..y1 {
                    for bx in x0..x1 {
                        let p = by * gw + bx;
                        g[p] = 0.5 * (f64::from(fwd[p]) + f64::from(back[p]));
                    }
                }
                g
            })
            .collect())
    }

    /// The blurred, normalised slice at full input resolution.
    ///
    /// Measures the weights and each band's phase per pixel of motion on
    /// the mean frame first, which analyses it and its copies moved one
    /// pixel either way along each axis the motion needs (3 or 5 frames);
    /// the reference and the sums stay as they were, so more frames may
    /// follow and `finish` again.
    pub fn finish(&mut self) -> Result<ModalImage, ModalError> {
        let span = (self.last_ns - self.t0_ns.unwrap_or(0)) as f64 * 1e-9;
        if self.frames < 3 || span <= 0.0 {
            return Err(ModalError::TooShort(self.frames));
        }
        // w(τ) = 16 τ² (T - τ)² / T⁴ = (16/T⁴)(T² τ² - 2T τ³ + τ⁴).
        let t = span;
        let g = 16.0 / (t * t * t * t);
        let coef = [g * t * t, -2.0 * g * t, g];
        let sum_w: f64 = (0..3).map(|k| coef[k] * self.real_moments[k]).sum();
        let big_w: Complex64 = (0..3).map(|k| self.moments[k] * coef[k]).sum();
        let n = self.frames as f64;
        let gn = self.grid_w * self.grid_h;
        let mean: Vec<f32> = self.frame_sum.iter().map(|&v| (v / n) as f32).collect();
        let mut amp = vec![0.0f32; gn];
        let mut share = vec![0.0f32; gn];
        let mut texture_to_noise = 0.0f64;
        // The weights from the mean frame: the texture's A² without the
        // sensor noise's, times the share oriented along the band's axis.
        self.pyr.analyze(&mean)?;
        let along_x = match self.cfg.motion {
            Motion::Y => None,
            _ => Some(self.phase_per_px(&mean, false)?),
        };
        let along_y = match self.cfg.motion {
            Motion::X => None,
            _ => Some(self.phase_per_px(&mean, true)?),
        };
        // Per band pixel: r = Σ A² g ΔΦ (x and y components, complex) and
        // G = Σ A² g gᵀ over the bands, g the phase change per pixel of
        // motion along x and y (with one band, along its own axis only).
        let zero = Complex64::new(0.0, 0.0);
        let (mut rx, mut ry) = (vec![zero; gn], vec![zero; gn]);
        let (mut gxx, mut gxy, mut gyy) = (vec![0.0f64; gn], vec![0.0f64; gn], vec![0.0f64; gn]);
        for bi in 0..self.bands.len() {
            let band = self.bands[bi].band;
            self.pyr.amplitude(band, &mut amp)?;
            self.pyr.orientation_share(band, &mut share);
            let b = &self.bands[bi];
            let mut ratios: Vec<f64> = (0..gn)
                .filter(|&p| self.band_inside.as_ref().is_none_or(|m| m[p]))
                .map(|p| {
                    let texture = f64::from(amp[p]) * f64::from(amp[p]);
                    let noise = b.power[p] / n - texture;
                    if noise > 0.0 {
                        texture / noise
                    } else {
                        f64::INFINITY
                    }
                })
                .collect();
            if !ratios.is_empty() {
                let mid = ratios.len() / 2;
                let (_, m, _) = ratios.select_nth_unstable_by(mid, f64::total_cmp);
                texture_to_noise = texture_to_noise.max(*m);
            }
            for p in 0..gn {
                if self.band_inside.as_ref().is_some_and(|m| !m[p]) {
                    continue;
                }
                let w = f64::from(amp[p]) * f64::from(amp[p]) * f64::from(share[p]);
                let gx = along_x.as_ref().map_or(0.0, |g| g[bi][p]);
                let gy = along_y.as_ref().map_or(0.0, |g| g[bi][p]);
                let a = &b.acc[p];
                let x: Complex64 = (0..3).map(|k| a[k] * coef[k]).sum();
                // Mean removed exactly: the taper's transform times the mean.
                let u = (x - big_w * (b.sum[p] / n)) * (2.0 / sum_w);
                rx[p] += u * (w * gx);
                ry[p] += u * (w * gy);
                gxx[p] += w * gx * gx;
                gxy[p] += w * gx * gy;
                gyy[p] += w * gy * gy;
            }
        }
        let sx = self.cfg.sigma_px / self.step.0;
        let sy = self.cfg.sigma_px / self.step.1;
        let (w, h) = (self.grid_w, self.grid_h);
        for r in [&mut rx, &mut ry] {
            let mut re: Vec<f64> = r.iter().map(|c| c.re).collect();
            let mut im: Vec<f64> = r.iter().map(|c| c.im).collect();
            gaussian_blur(&mut re, w, h, sx, sy);
            gaussian_blur(&mut im, w, h, sx, sy);
            for ((c, re), im) in r.iter_mut().zip(re).zip(im) {
                *c = Complex64::new(re, im);
            }
        }
        for g in [&mut gxx, &mut gxy, &mut gyy] {
            gaussian_blur(g, w, h, sx, sy);
        }
        // The amplitude and its information per pixel: the fit along the
        // band's axis, or (x and y together) along each pixel's own
        // direction of motion.
        let fit_one = |r: &[Complex64], d: &[f64]| -> (Vec<Complex64>, Vec<f64>) {
            let u = r
                .iter()
                .zip(d)
                .map(|(&r, &d)| if d > 0.0 { r / d } else { zero })
                .collect();
            (u, d.to_vec())
        };
        let (amp_grid, den) = match self.cfg.motion {
            Motion::Sum => along_own_axis(&rx, &ry, &gxx, &gxy, &gyy),
            Motion::X => fit_one(&rx, &gxx),
            Motion::Y => fit_one(&ry, &gyy),
        };
        let dmax = den.iter().copied().fold(0.0f64, f64::max);
        let floor = dmax * 1e-9;
        let grid: Vec<Complex64> = amp_grid
            .iter()
            .zip(&den)
            .map(|(&u, &d)| {
                if d <= floor {
                    Complex64::new(0.0, 0.0)
                } else if self.cfg.normalize {
                    u
                } else {
                    u * (d / dmax)
                }
            })
            .collect();
        let conf: Vec<f64> = den
            .iter()
            .map(|&d| if dmax > 0.0 { d / dmax } else { 0.0 })
            .collect();
        let (fw, fh) = (self.width, self.height);
        let mut data = Vec::with_capacity(fw * fh);
        let mut confidence = Vec::with_capacity(fw * fh);
        for y in 0..fh {
            for x in 0..fw {
                if self.inside.as_ref().is_some_and(|m| !m[y * fw + x]) {
                    data.push(Complex32::new(0.0, 0.0));
                    confidence.push(0.0);
                    continue;
                }
                let (gx, gy) = (x as f64 / self.step.0, y as f64 / self.step.1);
                let v = bilinear(&grid, w, h, gx, gy);
                data.push(Complex32::new(v.re as f32, v.im as f32));
                let c = bilinear(&conf, w, h, gx, gy);
                confidence.push(c as f32);
            }
        }
        Ok(ModalImage {
            width: fw,
            height: fh,
            freq_hz: self.cfg.freq_hz,
            data,
            confidence,
            texture_to_noise,
            frames: self.frames,
            span_s: span,
        })
    }
}

/// The blurred sums of both bands (`rx`, `ry`: G∗Σ A² g ΔΦ along x and y;
/// `gxx`, `gxy`, `gyy`: G∗Σ A² g gᵀ) fitted, per pixel, to one motion
/// along an unknown direction v = (cos α, sin α): a, the complex amplitude
/// along v, = vᵀr / vᵀGv, with the v that explains the most (the
/// generalised eigenvector of Re(r rᴴ) against G). A motion along x alone
/// reads its full amplitude (an average of the x and y bands' fits would
/// read half of it), and each band's phase change from motion across its
/// axis counts. The direction's sign is taken on the side of the frame's
/// overall direction, so that in-phase motion keeps one phase across the
/// image. Returns the amplitudes and the information along each pixel's
/// direction (vᵀGv).
fn along_own_axis(
    rx: &[Complex64],
    ry: &[Complex64],
    gxx: &[f64],
    gxy: &[f64],
    gyy: &[f64],
) -> (Vec<Complex64>, Vec<f64>) {
    let outer = |a: Complex64, b: Complex64| (a * b.conj()).re;
    let n = rx.len();
    let (mut a, mut g) = ([0.0f64; 3], [0.0f64; 3]);
    for p in 0..n {
        a[0] += outer(rx[p], rx[p]);
        a[1] += outer(rx[p], ry[p]);
        a[2] += outer(ry[p], ry[p]);
        g[0] += gxx[p];
        g[1] += gxy[p];
        g[2] += gyy[p];
    }
    let overall = principal(a, g).unwrap_or((1.0, 0.0));
    let mut amp = Vec::with_capacity(n);
    let mut info = Vec::with_capacity(n);
    for p in 0..n {
        let (r1, r2) = (rx[p], ry[p]);
        let a = [outer(r1, r1), outer(r1, r2), outer(r2, r2)];
        let Some((mut cx, mut cy)) = principal(a, [gxx[p], gxy[p], gyy[p]]) else {
            amp.push(Complex64::new(0.0, 0.0));
            info.push(0.0);
            continue;
        };
        if cx * overall.0 + cy * overall.1 < 0.0 {
            (cx, cy) = (-cx, -cy);
        }
        let d = gxx[p] * cx * cx + 2.0 * gxy[p] * cx * cy + gyy[p] * cy * cy;
        amp.push(if d > 0.0 {
            (r1 * cx + r2 * cy) / d
        } else {
            Complex64::new(0.0, 0.0)
        });
        info.push(d.max(0.0));
    }
    (amp, info)
}

/// The unit v maximising vᵀAv / vᵀGv for symmetric 2x2 A = [a0 a1; a1 a2]
/// and positive semi-definite G = [g0 g1; g1 g2] (the generalised
/// eigenvector, through G's Cholesky factor; G is lifted by 1e-9 of its
/// trace so that information along one direction only still gives it).
/// None where G is zero or the numbers are not finite.
fn principal(a: [f64; 3], g: [f64; 3]) -> Option<(f64, f64)> {
    let eps = 1e-9 * (g[0] + g[2]);
    if !(eps > 0.0 && eps.is_finite()) {
        return None;
    }
    let (g0, g1, g2) = (g[0] + eps, g[1], g[2] + eps);
    let l11 = g0.sqrt();
    let l21 = g1 / l11;
    let l22 = (g2 - l21 * l21).max(eps).sqrt();
    // L⁻¹ = [[i11, 0], [i21, i22]]; M = L⁻¹ A L⁻ᵀ.
    let (i11, i22) = (1.0 / l11, 1.0 / l22);
    let i21 = -l21 * i11 * i22;
    let m00 = i11 * i11 * a[0];
    let m01 = i11 * (i21 * a[0] + i22 * a[1]);
    let m11 = i21 * i21 * a[0] + 2.0 * i21 * i22 * a[1] + i22 * i22 * a[2];
    let beta = 0.5 * (2.0 * m01).atan2(m00 - m11);
    let (w0, w1) = (beta.cos(), beta.sin());
    // v = L⁻ᵀ w.
    let (vx, vy) = (i11 * w0 + i21 * w1, i22 * w1);
    let norm = vx.hypot(vy);
    (norm > 0.0 && norm.is_finite()).then(|| (vx / norm, vy / norm))
}

/// Values that bilinear interpolation can mix.
trait Lerp: Copy + std::ops::Mul<f64, Output = Self> + std::ops::Add<Output = Self> {}
impl Lerp for f64 {}
impl Lerp for Complex64 {}

/// Bilinear sample of a `w x h` grid at (x, y), clamped to the grid.
fn bilinear<T: Lerp>(g: &[T], w: usize, h: usize, x: f64, y: f64) -> T {
    let x = x.clamp(0.0, (w - 1) as f64);
    let y = y.clamp(0.0, (h - 1) as f64);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let row = |yy: usize| g[yy * w + x0] * (1.0 - fx) + g[yy * w + x1] * fx;
    row(y0) * (1.0 - fy) + row(y1) * fy
}

/// A complex mode shape's checks (issue 51): how far it is from a real,
/// standing mode, whose parts all move in phase or in antiphase.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ShapeChecks {
    /// Modal phase collinearity: ((Sxx - Syy)² + 4 Sxy²) / (Sxx + Syy)²
    /// over the shape's real and imaginary parts (Pappa, Elliott and
    /// Schenk 1993, in its eigenvalue form): 1 when every point lies on one
    /// line through the origin of the complex plane, 0 when they spread
    /// evenly about it (noise, a travelling wave).
    pub mpc: f64,
    /// Mean phase deviation, degrees: each point's angle from the shape's
    /// principal line, weighted by its magnitude (Reynders, Houbrechts and
    /// De Roeck 2012): 0 for a real mode, 45 for phases spread evenly.
    pub mpd_deg: f64,
}

/// [`ShapeChecks`] of `shape` (its non-finite points left out); `None`
/// when it holds no motion.
pub fn shape_checks(shape: &[Complex32]) -> Option<ShapeChecks> {
    let pts = shape
        .iter()
        .filter(|c| c.re.is_finite() && c.im.is_finite())
        .map(|c| (f64::from(c.re), f64::from(c.im)));
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for (x, y) in pts.clone() {
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
    }
    let total = sxx + syy;
    if !(total.is_finite() && total > 0.0) {
        return None;
    }
    let mpc = ((sxx - syy).powi(2) + 4.0 * sxy * sxy) / (total * total);
    // The principal line's angle (the scatter's major axis).
    let alpha = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (sa, ca) = alpha.sin_cos();
    let (mut num, mut den) = (0.0, 0.0);
    for (x, y) in pts {
        let m = x.hypot(y);
        if m > 0.0 {
            // The component across the line over the magnitude.
            let across = (-x * sa + y * ca).abs() / m;
            num += m * across.clamp(0.0, 1.0).asin();
            den += m;
        }
    }
    Some(ShapeChecks {
        mpc: mpc.clamp(0.0, 1.0),
        mpd_deg: (num / den).to_degrees(),
    })
}

/// Separable Gaussian blur in place (std `sx`, `sy` grid pixels, kernel
/// to ±3σ), zero outside the grid: with the ratio of ch. 3.5.2 that is
/// normalised convolution, exact at the borders.
pub fn gaussian_blur(v: &mut [f64], w: usize, h: usize, sx: f64, sy: f64) {
    let kernel = |s: f64| -> Vec<f64> {
        if !(s.is_finite() && s > 0.0) {
            return vec![1.0];
        }
        let r = (3.0 * s).ceil() as isize;
        (-r..=r)
            .map(|i| (-0.5 * (i as f64 / s).powi(2)).exp())
            .collect()
    };
    let pass = |v: &mut [f64], k: &[f64], n: usize, stride: usize, lines: usize, lstride: usize| {
        let r = (k.len() / 2) as isize;
        let mut line = vec![0.0; n];
        for l in 0..lines {
            for (i, d) in line.iter_mut().enumerate() {
                *d = v[l * lstride + i * stride];
            }
            for i in 0..n as isize {
                let mut acc = 0.0;
                for (j, &kv) in k.iter().enumerate() {
                    let p = i + j as isize - r;
                    if p >= 0 && p < n as isize {
                        acc += kv * line[p as usize];
                    }
                }
                v[l * lstride + i as usize * stride] = acc;
            }
        }
    };
    let kx = kernel(sx);
    let ky = kernel(sy);
    if kx.len() > 1 {
        pass(v, &kx, w, 1, h, w);
    }
    if ky.len() > 1 {
        pass(v, &ky, h, w, w, 1);
    }
}

/// How a modal image is drawn.
#[derive(Clone, Copy, Debug)]
pub struct Visual {
    /// Brightness = ((|U| - min) / (max - min))^exponent.
    pub exponent: f64,
}

/// The image rotated by one global phase so that it is as real as possible
/// (arg Σ U² / 2): in-phase regions share a hue, opposite ones take the
/// opposite hue. Temporal phase has no absolute origin, so this changes
/// nothing physical.
pub fn align_phase(data: &[Complex32]) -> Vec<Complex32> {
    let s: Complex64 = data
        .iter()
        .map(|c| {
            let c = Complex64::new(c.re as f64, c.im as f64);
            c * c
        })
        .sum();
    let rot = Complex64::from_polar(1.0, -0.5 * s.arg());
    let r = Complex32::new(rot.re as f32, rot.im as f32);
    data.iter().map(|c| c * r).collect()
}

/// RGB8 pixels of the visualisation (ch. 3.5.3): hue = phase (0 = red,
/// ±π = cyan), value = normalised amplitude to the exponent, full saturation.
pub fn render_rgb(img: &ModalImage, vis: Visual) -> Vec<u8> {
    render_rgb_data(&img.data, vis)
}

/// [`render_rgb`] of a complex image's values (row-major).
pub fn render_rgb_data(data: &[Complex32], vis: Visual) -> Vec<u8> {
    let data = align_phase(data);
    let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
    for c in &data {
        let a = c.norm();
        lo = lo.min(a);
        hi = hi.max(a);
    }
    let range = (hi - lo).max(f32::MIN_POSITIVE);
    let mut out = Vec::with_capacity(data.len() * 3);
    for c in &data {
        let v = (((c.norm() - lo) / range) as f64)
            .clamp(0.0, 1.0)
            .powf(vis.exponent);
        let hue = (c.arg() as f64).rem_euclid(TAU) / TAU;
        let rgb = hsv_to_rgb(hue, 1.0, v);
        out.extend(rgb.map(|x| (x * 255.0 + 0.5).clamp(0.0, 255.0) as u8));
    }
    out
}

/// A rendered modal image (`rgb`, from [`render_rgb`]) laid over a
/// grayscale frame of the scene (`gray`, 0-255, the same pixels): the
/// mode's colour where it is bright, the frame (dimmed to 25-75% grey)
/// where the mode is dark, in proportion to the brightness v = max(r, g, b):
/// out = frame (1 - v) + rgb. Without a frame (`gray` of another length)
/// the image is returned as it is.
pub fn overlay_rgb(rgb: &[u8], gray: &[u8]) -> Vec<u8> {
    if gray.len() * 3 != rgb.len() {
        return rgb.to_vec();
    }
    let mut out = Vec::with_capacity(rgb.len());
    for (px, &g) in rgb.chunks_exact(3).zip(gray) {
        let v = f32::from(px[0].max(px[1]).max(px[2])) / 255.0;
        let base = (64.0 + f32::from(g) * (128.0 / 255.0)) * (1.0 - v);
        out.extend(
            px.iter()
                .map(|&c| (base + f32::from(c)).round().min(255.0) as u8),
        );
    }
    out
}

/// HSV (each in [0, 1]) to RGB in [0, 1].
pub fn hsv_to_rgb(h: f64, s: f64, v: f64) -> [f64; 3] {
    let h6 = (h.rem_euclid(1.0)) * 6.0;
    let i = h6.floor();
    let f = h6 - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match i as u32 % 6 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

/// A `.npy` file (format 1.0) of a complex64 `(height, width)` C-order
/// array: readable by `numpy.load`.
pub fn npy_complex64(data: &[Complex32], width: usize, height: usize) -> Vec<u8> {
    let dict =
        format!("{{'descr': '<c8', 'fortran_order': False, 'shape': ({height}, {width}), }}");
    // Magic (6) + version (2) + length (2) + header, padded with spaces and
    // a newline to a multiple of 64 bytes.
    let unpadded = 10 + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    let header_len = dict.len() + pad + 1;
    let mut out = Vec::with_capacity(10 + header_len + data.len() * 8);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend(std::iter::repeat_n(b' ', pad));
    out.push(b'\n');
    for c in data {
        out.extend_from_slice(&c.re.to_le_bytes());
        out.extend_from_slice(&c.im.to_le_bytes());
    }
    out
}

/// Why [`read_npy_complex64`] refused its input.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NpyError {
    #[error("not a .npy file (bad magic)")]
    Magic,
    #[error("unsupported .npy version {0}")]
    Version(u8),
    #[error("truncated .npy header")]
    TruncatedHeader,
    /// The header, which declares another dtype or Fortran order.
    #[error("not a C-order complex64 array: {0}")]
    Layout(String),
    #[error("no shape in the .npy header")]
    NoShape,
    #[error("shape `{shape}`: {source}")]
    BadShape {
        shape: String,
        #[source]
        source: std::num::ParseIntError,
    },
    #[error("expected a 2-D shape, got ({0})")]
    NotTwoD(String),
    #[error("{got} data bytes for a {height}x{width} complex64 array (expected {expected})")]
    DataLength {
        got: usize,
        height: usize,
        width: usize,
        expected: usize,
    },
}

/// Reads back what [`npy_complex64`] writes (for tests and tools): the
/// shape `(height, width)` and the values. Other `.npy` layouts are refused.
pub fn read_npy_complex64(bytes: &[u8]) -> Result<(usize, usize, Vec<Complex32>), NpyError> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(NpyError::Magic);
    }
    let (len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(NpyError::Version(v)),
    };
    let header = bytes
        .get(start..start + len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or(NpyError::TruncatedHeader)?;
    if !header.contains("'descr': '<c8'") || !header.contains("'fortran_order': False") {
        return Err(NpyError::Layout(header.trim().to_string()));
    }
    let shape = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .ok_or(NpyError::NoShape)?;
    let dims: Vec<usize> = shape
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>().map_err(|source| NpyError::BadShape {
                shape: shape.to_string(),
                source,
            })
        })
        .collect::<Result<_, _>>()?;
    let [h, w] = dims[..] else {
        return Err(NpyError::NotTwoD(shape.to_string()));
    };
    let body = &bytes[start + len..];
    if body.len() != w * h * 8 {
        return Err(NpyError::DataLength {
            got: body.len(),
            height: h,
            width: w,
            expected: w * h * 8,
        });
    }
    let data = body
        .chunks_exact(8)
        .map(|c| {
            Complex32::new(
                f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            )
        })
        .collect();
    Ok((h, w, data))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// Imagers fed a leader's analysis (two axes, two frequencies) give the
    /// bits they give each on its own pyramid, on both pyramids; and a
    /// leader of another scale, one that has not just taken the frame, or
    /// an imager fed both ways is refused.
    #[test]
    fn imagers_following_a_leader_get_the_bits_they_get_alone() {
        let (w, h, fps) = (40usize, 32usize, 200.0);
        let frame = |k: usize| -> Vec<f32> {
            let t = k as f64 / fps;
            (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    let d =
                        0.2 * (TAU * 12.0 * t).sin() * y / h as f64 + 0.1 * (TAU * 31.0 * t).sin();
                    let e = 0.15 * (TAU * 12.0 * t).cos() * x / w as f64;
                    (100.0
                        + 40.0 * ((x - d) * 0.7).sin() * ((y - e) * 0.45).cos()
                        + 20.0 * ((x - d) * 0.23 + (y - e) * 0.31).sin()) as f32
                })
                .collect()
        };
        let bits = |m: &ModalImage| -> Vec<(u32, u32, u32)> {
            m.data
                .iter()
                .zip(&m.confidence)
                .map(|(c, w)| (c.re.to_bits(), c.im.to_bits(), w.to_bits()))
                .collect()
        };
        for pyramid in [PyramidKind::Csp, PyramidKind::Riesz] {
            let cfg = |freq_hz, motion, scale| ModalConfig {
                freq_hz,
                scale,
                sigma_px: 1.5,
                motion,
                normalize: true,
                pyramid,
            };
            let cfgs = [
                cfg(12.0, Motion::X, 0),
                cfg(12.0, Motion::Y, 0),
                cfg(31.0, Motion::Sum, 0),
            ];
            let make = || -> Vec<ModalImager> {
                cfgs.iter()
                    .map(|c| ModalImager::new(w, h, *c).unwrap())
                    .collect()
            };
            let (mut alone, mut shared) = (make(), make());
            let mut coarser = ModalImager::new(w, h, cfg(12.0, Motion::X, 1)).unwrap();
            for k in 0..120 {
                let (f, t) = (frame(k), (k as f64 / fps * 1e9) as i64);
                for im in &mut alone {
                    im.push(&f, t).unwrap();
                }
                let (lead, rest) = shared.split_first_mut().unwrap();
                if k == 5 {
                    // The leader has not taken this frame yet.
                    assert!(matches!(
                        rest[0].push_following(lead, &f, t),
                        Err(ModalError::Leader(_))
                    ));
                }
                lead.push(&f, t).unwrap();
                for im in rest.iter_mut() {
                    im.push_following(lead, &f, t).unwrap();
                }
                assert!(matches!(
                    coarser.push_following(lead, &f, t),
                    Err(ModalError::Leader(_))
                ));
            }
            assert!(matches!(
                shared[1].push(&frame(120), 120 * 5_000_000),
                Err(ModalError::Leader(_))
            ));
            for (a, b) in alone.iter_mut().zip(&mut shared) {
                let (a, b) = (a.finish().unwrap(), b.finish().unwrap());
                assert!(a.data.iter().any(|c| c.norm() > 0.0));
                assert_eq!(bits(&a), bits(&b), "{pyramid:?} {} Hz", a.freq_hz);
            }
        }
    }

    #[test]
    fn npy_round_trips_and_pads_to_64() {
        let d: Vec<Complex32> = (0..6)
            .map(|i| Complex32::new(i as f32, -(i as f32)))
            .collect();
        let b = npy_complex64(&d, 3, 2);
        let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
        assert_eq!((10 + hl) % 64, 0);
        assert_eq!(b[10 + hl - 1], b'\n');
        let (h, w, back) = read_npy_complex64(&b).unwrap();
        assert_eq!((h, w), (2, 3));
        assert_eq!(back, d);
    }

    #[test]
    fn blur_preserves_the_sum_away_from_borders_and_the_ratio_is_exact() {
        let (w, h) = (41, 31);
        let mut v = vec![0.0; w * h];
        v[15 * w + 20] = 1.0;
        gaussian_blur(&mut v, w, h, 2.0, 3.0);
        let s: f64 = v.iter().sum();
        // The kernels are not normalised; the ratio of two blurs is what counts.
        let k = |s: f64| -> f64 {
            let r = (3.0 * s).ceil() as i32;
            (-r..=r)
                .map(|i| (-0.5 * (i as f64 / s).powi(2)).exp())
                .sum()
        };
        assert!((s - k(2.0) * k(3.0)).abs() < 1e-9, "{s}");
        // A constant field over constant weights stays constant, also at borders.
        let mut num = vec![2.5; w * h];
        let mut den = vec![1.0; w * h];
        gaussian_blur(&mut num, w, h, 4.0, 4.0);
        gaussian_blur(&mut den, w, h, 4.0, 4.0);
        for (a, b) in num.iter().zip(&den) {
            assert!((a / b - 2.5).abs() < 1e-12);
        }
    }

    #[test]
    fn hsv_primaries() {
        assert_eq!(hsv_to_rgb(0.0, 1.0, 1.0), [1.0, 0.0, 0.0]);
        let c = hsv_to_rgb(0.5, 1.0, 1.0);
        assert!(c[0].abs() < 1e-12 && (c[1] - 1.0).abs() < 1e-12 && (c[2] - 1.0).abs() < 1e-12);
    }

    /// The overlay shows the frame where the mode is dark (dimmed to
    /// 25-75% grey), the mode's colour where it is bright, and a mix
    /// between; a frame of the wrong size leaves the image alone.
    #[test]
    fn overlay_mixes_by_brightness() {
        // Black (v = 0), full red (v = 1), half cyan (v = 0.5).
        let rgb = [0, 0, 0, 255, 0, 0, 0, 128, 128];
        let gray = [255, 0, 0];
        let out = overlay_rgb(&rgb, &gray);
        assert_eq!(&out[..3], &[192, 192, 192]);
        assert_eq!(&out[3..6], &[255, 0, 0]);
        let base = (64.0f32 * (1.0 - 128.0 / 255.0)).round() as u8;
        assert_eq!(&out[6..9], &[base, base + 128, base + 128]);
        assert_eq!(overlay_rgb(&rgb, &gray[..2]), rgb.to_vec());
    }

    #[test]
    fn a_real_shape_is_collinear_and_noise_is_not() {
        use crate::rng::Xoshiro256;
        // A standing shape at any phase: MPC 1, MPD 0.
        let rot = Complex32::from_polar(1.0, 0.7);
        let real: Vec<Complex32> = (0..200).map(|i| rot * ((i as f32 * 0.05).sin())).collect();
        let c = shape_checks(&real).unwrap();
        assert!(c.mpc > 0.9999 && c.mpd_deg < 0.01, "{c:?}");
        // Random phases: MPC near 0, MPD near 45 degrees.
        let mut rng = Xoshiro256::new(3);
        let noise: Vec<Complex32> = (0..20_000)
            .map(|_| Complex32::from_polar(1.0, (rng.next_f64() * std::f64::consts::TAU) as f32))
            .collect();
        let c = shape_checks(&noise).unwrap();
        assert!(c.mpc < 0.05 && (c.mpd_deg - 45.0).abs() < 3.0, "{c:?}");
        // A travelling wave (phase along the shape): not collinear.
        let wave: Vec<Complex32> = (0..200)
            .map(|i| Complex32::from_polar(1.0, i as f32 * 0.1))
            .collect();
        assert!(shape_checks(&wave).unwrap().mpc < 0.2);
        assert!(shape_checks(&[Complex32::new(0.0, 0.0); 4]).is_none());
    }
}
