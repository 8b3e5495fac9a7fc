//! Riesz pyramid (Wadhwa, Rubinstein, Durand, Freeman, ICCP 2014, "Riesz
//! pyramids for fast phase-based video magnification"): a real band-pass
//! pyramid plus a 3-tap approximate Riesz transform, giving per pixel and
//! scale the local amplitude `A`, phase `φ` and orientation `θ` of a
//! quadrature triple, without any FFT.
//!
//! # Construction
//!
//! With `B` the separable 5-tap binomial `[1 4 6 4 1]/16` (mirrored borders,
//! `x[-1] = x[1]`) and `G0` the frame, every level `l` computes
//!
//! * `S = B * Gl`, `T = B * S`,
//! * band `I = S - T` (a difference of binomial blurs: band-pass, zero at DC
//!   and at Nyquist, peaking near 0.18 cycles per level pixel, where the
//!   3-tap Riesz approximation is good),
//! * next level `G(l+1) = T` at even rows and columns (size `ceil(n/2)`),
//! * Riesz pair `R1 = (I[x-1] - I[x+1])/2`, `R2 = (I[y-1] - I[y+1])/2`
//!   (edge-clamped), the finite-difference approximation of `-i·ω/|ω|`.
//!
//! Then `A = sqrt(I² + R1² + R2²)`, `φ = atan2(sqrt(R1² + R2²), I)` in
//! `[0, π]` and `θ = atan2(R2, R1)`. For an orientation set `θk = π·k/K`
//! (the same angles as the complex steerable pyramid), the per-orientation
//! phase is the paper's "phase × orientation" quantity projected on `θk`:
//! `φk = φ·cos(θ - θk)`. For a locally 1D pattern of frequency `f` along
//! `θ`, a translation by `d` changes `φk` by `-2π·f·(d·n)·cos(θ - θk)`, the
//! normal flow seen along `θk`. `φ0` equals the local phase of the CSP's
//! orientation-0 band for patterns varying along x (same sign convention).
//!
//! Per-orientation amplitude is `A` (shared). The wrap-safe phase change
//! ([`PhaseBands::phase_delta_into`]) uses the quaternionic difference
//! `q·conj(q_ref)` of the triples `q = I + R1·i + R2·j` as in the paper.
//!
//! No synthesis (the pyramid is used for analysis only); no low-pass
//! residual is kept. All buffers are allocated in [`RieszPyramid::new`] and
//! [`RieszPyramid::alloc_coeffs`]; [`RieszPyramid::analyze`] allocates
//! nothing and is FFT-free.
//!
//! # Speed
//!
//! Separable blurs and the per-pixel amplitude/phase step (two square
//! roots, one division and a polynomial `atan`) vectorise; on x86-64 the
//! kernels also exist compiled for AVX2 and AVX-512, chosen at run time,
//! with bit-identical results. 256x256, 4 levels, 2 orientations, one core
//! of the project's Xeon (`cargo test --release -p vibroscope-math
//! speed_report -- --nocapture`, idle): 231 Mpix/s on the SSE2 baseline,
//! 297 with AVX2, 334 with AVX-512. A reader of phase changes only (the
//! `phase` stage) skips the amplitude and phases
//! ([`RieszPyramid::set_triples_only`]). A frame of bytes is read as
//! bytes ([`RieszPyramid::analyze_levels_u8`]): no `f32` copy of it, and
//! the first blur in 16-bit integers, with the same bits.

use super::kernels::quat_phase_delta;
use super::{
    check_len, check_params, layout_accessors, BandInfo, LayoutKey, PhaseBands, Pixels,
    PyramidError, DEFAULT_ORIENTATIONS, DEFAULT_SCALES,
};
use std::f32::consts::{FRAC_PI_2, PI};

/// One level of a [`RieszCoeffs`]: the band, its Riesz pair, the local
/// amplitude and one phase image per orientation, all `width x height`.
#[derive(Clone, Debug)]
pub struct RieszLevel {
    width: usize,
    height: usize,
    band: Vec<f32>,
    r1: Vec<f32>,
    r2: Vec<f32>,
    amplitude: Vec<f32>,
    phases: Vec<Vec<f32>>,
}

impl RieszLevel {
    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    /// The real band-pass image `I`.
    pub fn band(&self) -> &[f32] {
        &self.band
    }
    /// Riesz component along x.
    pub fn r1(&self) -> &[f32] {
        &self.r1
    }
    /// Riesz component along y.
    pub fn r2(&self) -> &[f32] {
        &self.r2
    }
    /// Local amplitude `A`.
    pub fn amplitude(&self) -> &[f32] {
        &self.amplitude
    }
    /// Phase projected on orientation `k`, `φ·cos(θ - θk)`.
    pub fn phase(&self, k: usize) -> Option<&[f32]> {
        self.phases.get(k).map(Vec::as_slice)
    }
    /// The quadrature triple `(I, R1, R2)` on `span` (the kernels' input).
    fn triple(&self, span: std::ops::Range<usize>) -> [&[f32]; 3] {
        [
            &self.band[span.clone()],
            &self.r1[span.clone()],
            &self.r2[span],
        ]
    }
}

/// Output of [`RieszPyramid::analyze`].
#[derive(Clone, Debug)]
pub struct RieszCoeffs {
    key: LayoutKey,
    levels: Vec<RieszLevel>,
    infos: Vec<BandInfo>,
    dirs: Vec<(f32, f32)>,
    /// The levels' amplitude and phases are computed (false after an
    /// analysis of the triples only, [`RieszPyramid::set_triples_only`]:
    /// then [`PhaseBands`] derives them from the triple when asked, with
    /// the same operations, and [`RieszLevel::amplitude`] and
    /// [`RieszLevel::phase`] hold stale values until [`RieszCoeffs::derive`]).
    derived: bool,
}

impl RieszCoeffs {
    pub fn scales(&self) -> usize {
        self.key.scales
    }
    pub fn orientations(&self) -> usize {
        self.key.orientations
    }
    pub fn levels(&self) -> &[RieszLevel] {
        &self.levels
    }
    pub fn level(&self, l: usize) -> Option<&RieszLevel> {
        self.levels.get(l)
    }
    /// Whether the levels' amplitude and phases are computed (see
    /// [`RieszPyramid::set_triples_only`]).
    pub fn is_derived(&self) -> bool {
        self.derived
    }

    /// Computes the levels' amplitude and phases from their triples (after
    /// an analysis of the triples only), as a full analysis would.
    pub fn derive(&mut self) {
        if self.derived {
            return;
        }
        let w = self.levels.iter().map(|l| l.width).max().unwrap_or(0);
        let mut q = vec![0.0f32; w];
        for level in &mut self.levels {
            derive_level(level, &self.dirs, &mut q);
        }
        self.derived = true;
    }

    /// Band index of (scale, orientation).
    pub fn band_index(&self, scale: usize, orientation: usize) -> Option<usize> {
        (scale < self.key.scales && orientation < self.key.orientations)
            .then_some(scale * self.key.orientations + orientation)
    }

    fn split(&self, i: usize) -> Result<(&RieszLevel, usize), PyramidError> {
        let k = self.key.orientations;
        match self.levels.get(i / k) {
            Some(level) if i < self.infos.len() => Ok((level, i % k)),
            _ => Err(PyramidError::BandOutOfRange {
                index: i,
                count: self.infos.len(),
            }),
        }
    }
}

impl PhaseBands for RieszCoeffs {
    fn num_bands(&self) -> usize {
        self.infos.len()
    }
    fn band_info(&self, i: usize) -> Option<&BandInfo> {
        self.infos.get(i)
    }
    fn amplitude_into(&self, i: usize, out: &mut [f32]) -> Result<(), PyramidError> {
        let (level, _) = self.split(i)?;
        check_len(level.amplitude.len(), out.len())?;
        if self.derived {
            out.copy_from_slice(&level.amplitude);
        } else {
            // As `amp_phase_row` computes it.
            let it = out
                .iter_mut()
                .zip(level.band.iter().zip(&level.r1).zip(&level.r2));
            for (a, ((&iv, &x1), &x2)) in it {
                let rr = x1 * x1 + x2 * x2;
                *a = (iv * iv + rr).sqrt();
            }
        }
        Ok(())
    }
    fn amplitude_shared(&self) -> bool {
        true
    }
    fn phase_into(&self, i: usize, out: &mut [f32]) -> Result<(), PyramidError> {
        let (level, k) = self.split(i)?;
        let p = level.phases.get(k).ok_or(PyramidError::LayoutMismatch)?;
        check_len(p.len(), out.len())?;
        if self.derived {
            out.copy_from_slice(p);
            return Ok(());
        }
        let (ck, sk) = self
            .dirs
            .get(k)
            .copied()
            .ok_or(PyramidError::LayoutMismatch)?;
        let w = level.width;
        let (mut amp, mut q) = (vec![0.0f32; w], vec![0.0f32; w]);
        for (y, o) in out.chunks_exact_mut(w).enumerate() {
            let row = y * w..(y + 1) * w;
            let (r1, r2) = (&level.r1[row.clone()], &level.r2[row.clone()]);
            amp_phase_row(&level.band[row], r1, r2, &mut amp, &mut q);
            for (((p, &q), &x1), &x2) in o.iter_mut().zip(&q).zip(r1).zip(r2) {
                *p = q * (x1 * ck + x2 * sk);
            }
        }
        Ok(())
    }
    fn phase_delta_into(
        &self,
        reference: &Self,
        i: usize,
        out: &mut [f32],
    ) -> Result<(), PyramidError> {
        if reference.key != self.key {
            return Err(PyramidError::LayoutMismatch);
        }
        let (cur, k) = self.split(i)?;
        let (prev, _) = reference.split(i)?;
        let (ck, sk) = self
            .dirs
            .get(k)
            .copied()
            .ok_or(PyramidError::LayoutMismatch)?;
        check_len(cur.band.len(), out.len())?;
        let it = out
            .iter_mut()
            .zip(cur.band.iter().zip(&cur.r1).zip(&cur.r2))
            .zip(prev.band.iter().zip(&prev.r1).zip(&prev.r2));
        for ((o, ((&a, &b), &c)), ((&d, &e), &f)) in it {
            *o = quat_phase_delta([a, b, c], [d, e, f], ck, sk);
        }
        Ok(())
    }

    fn weighted_phase_delta_sum(
        &self,
        reference: &Self,
        i: usize,
        weights: &[f32],
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
    ) -> Result<f64, PyramidError> {
        if reference.key != self.key {
            return Err(PyramidError::LayoutMismatch);
        }
        let (cur, k) = self.split(i)?;
        let (prev, _) = reference.split(i)?;
        let info = self.infos.get(i).ok_or(PyramidError::LayoutMismatch)?;
        crate::pyramid::check_region(info, weights, &rows, &cols)?;
        let (ck, sk) = self
            .dirs
            .get(k)
            .copied()
            .ok_or(PyramidError::LayoutMismatch)?;
        // The fused kernel with one orientation: the same code as
        // `scale_phase_delta_sums`.
        let w = cur.width;
        let mut sum = 0.0f64;
        for y in rows {
            let span = y * w + cols.start..y * w + cols.end;
            let mut acc = [0.0f32];
            super::kernels::riesz_row(
                cur.triple(span.clone()),
                prev.triple(span.clone()),
                &[&weights[span]],
                &[(ck, sk)],
                &mut acc,
            );
            sum += acc[0] as f64;
        }
        Ok(sum)
    }

    fn scale_phase_delta_sums(
        &self,
        reference: &Self,
        scale: usize,
        weights: &[&[f32]],
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
        out: &mut [f64],
    ) -> Result<(), PyramidError> {
        let k = self.key.orientations;
        if reference.key != self.key
            || weights.len() != k
            || out.len() != k
            || k > super::kernels::MAX_ORIENT
        {
            return Err(PyramidError::LayoutMismatch);
        }
        let (cur, _) = self.split(scale * k)?;
        let (prev, _) = reference.split(scale * k)?;
        for (o, wt) in weights.iter().enumerate() {
            let info = self
                .infos
                .get(scale * k + o)
                .ok_or(PyramidError::LayoutMismatch)?;
            crate::pyramid::check_region(info, wt, &rows, &cols)?;
        }
        let w = cur.width;
        out.iter_mut().for_each(|v| *v = 0.0);
        let mut acc = [0.0f32; super::kernels::MAX_ORIENT];
        let mut wrow: [&[f32]; super::kernels::MAX_ORIENT] = [&[]; super::kernels::MAX_ORIENT];
        for y in rows {
            let span = y * w + cols.start..y * w + cols.end;
            for (d, wt) in wrow.iter_mut().zip(weights) {
                *d = &wt[span.clone()];
            }
            acc[..k].iter_mut().for_each(|v| *v = 0.0);
            super::kernels::riesz_row(
                cur.triple(span.clone()),
                prev.triple(span.clone()),
                &wrow[..k],
                &self.dirs[..k],
                &mut acc[..k],
            );
            for (o, a) in out.iter_mut().zip(&acc[..k]) {
                *o += *a as f64;
            }
        }
        Ok(())
    }
}

/// Riesz pyramid for one frame size; see the module docs.
pub struct RieszPyramid {
    key: LayoutKey,
    dims: Vec<(usize, usize)>,
    /// Inputs of levels `1..scales` (decimated blurs).
    inputs: Vec<Vec<f32>>,
    s_buf: Vec<f32>,
    vrow: Vec<f32>,
    /// [`blur_row_u8`]'s vertical pass (a frame of bytes).
    vrow16: Vec<u16>,
    trow: Vec<f32>,
    qrow: Vec<f32>,
    dirs: Vec<(f32, f32)>,
    infos: Vec<BandInfo>,
    /// Whether the CPU has AVX2 (selects the 8-lane build of the kernels).
    simd: crate::join::Simd,
    /// Analyse the triples only ([`RieszPyramid::set_triples_only`]).
    triples_only: bool,
}

impl std::fmt::Debug for RieszPyramid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RieszPyramid")
            .field("width", &self.key.width)
            .field("height", &self.key.height)
            .field("scales", &self.key.scales)
            .field("orientations", &self.key.orientations)
            .finish_non_exhaustive()
    }
}

/// Radial peak of the level-0 band `b(1-b)`, `b = cos⁴(ω/2)`, in cycles
/// per pixel: `b = 1/2`.
fn band_peak() -> f32 {
    2.0 * 0.5f32.powf(0.25).acos() / (2.0 * PI)
}

impl RieszPyramid {
    /// Builds the pyramid for `width x height` frames, `scales` levels and
    /// `orientations` projection angles `π·k/orientations`. Any size >= 1x1
    /// works; levels shrink to at least 1x1.
    pub fn new(
        width: usize,
        height: usize,
        scales: usize,
        orientations: usize,
    ) -> Result<Self, PyramidError> {
        check_params(width, height, scales, orientations)?;
        let key = LayoutKey {
            width,
            height,
            scales,
            orientations,
            compact: false,
        };
        let mut dims = Vec::with_capacity(scales);
        let (mut w, mut h) = (width, height);
        for _ in 0..scales {
            dims.push((w, h));
            w = w.div_ceil(2);
            h = h.div_ceil(2);
        }
        let inputs = dims[1..].iter().map(|&(w, h)| vec![0.0; w * h]).collect();
        let dirs: Vec<(f32, f32)> = (0..orientations)
            .map(|k| {
                let t = std::f64::consts::PI * k as f64 / orientations as f64;
                (t.cos() as f32, t.sin() as f32)
            })
            .collect();
        let peak = band_peak();
        let mut infos = Vec::with_capacity(scales * orientations);
        for (l, &(w, h)) in dims.iter().enumerate() {
            for k in 0..orientations {
                infos.push(BandInfo {
                    scale: l,
                    orientation: k,
                    angle: (std::f64::consts::PI * k as f64 / orientations as f64) as f32,
                    width: w,
                    height: h,
                    step_x: width as f32 / w as f32,
                    step_y: height as f32 / h as f32,
                    centre_frequency: peak / (1u64 << l) as f32,
                });
            }
        }
        Ok(Self {
            key,
            dims,
            inputs,
            s_buf: vec![0.0; width * height],
            vrow: vec![0.0; width + 4],
            vrow16: vec![0; width + 4],
            trow: vec![0.0; width],
            qrow: vec![0.0; width],
            dirs,
            infos,
            simd: crate::join::Simd::detect(),
            triples_only: false,
        })
    }

    layout_accessors!();

    /// Shapes of all (level, orientation) bands, scale-major.
    pub fn band_infos(&self) -> &[BandInfo] {
        &self.infos
    }

    /// With `on`, [`Self::analyze`] computes each level's band and Riesz
    /// pair only, not its amplitude and phases (two square roots, a
    /// division and an arctangent a pixel, and one image per orientation):
    /// a reader of phase changes (`phase_delta_into`, the weighted sums)
    /// needs only the triples, and the amplitude and phases are derived
    /// from them when asked for through [`PhaseBands`], with the same
    /// operations (the same bits).
    pub fn set_triples_only(&mut self, on: bool) {
        self.triples_only = on;
    }

    /// Allocates coefficient storage for this pyramid (once; reuse it).
    pub fn alloc_coeffs(&self) -> RieszCoeffs {
        let k = self.key.orientations;
        let levels = self
            .dims
            .iter()
            .map(|&(w, h)| RieszLevel {
                width: w,
                height: h,
                band: vec![0.0; w * h],
                r1: vec![0.0; w * h],
                r2: vec![0.0; w * h],
                amplitude: vec![0.0; w * h],
                phases: (0..k).map(|_| vec![0.0; w * h]).collect(),
            })
            .collect();
        RieszCoeffs {
            key: self.key,
            levels,
            infos: self.infos.clone(),
            dirs: self.dirs.clone(),
            derived: true,
        }
    }

    fn check_coeffs(&self, c: &RieszCoeffs) -> Result<(), PyramidError> {
        let k = self.key.orientations;
        let ok = c.key == self.key
            && c.levels.len() == self.dims.len()
            && c.levels.iter().zip(&self.dims).all(|(l, &(w, h))| {
                let n = w * h;
                l.width == w
                    && l.height == h
                    && l.band.len() == n
                    && l.r1.len() == n
                    && l.r2.len() == n
                    && l.amplitude.len() == n
                    && l.phases.len() == k
                    && l.phases.iter().all(|p| p.len() == n)
            });
        if ok {
            Ok(())
        } else {
            Err(PyramidError::LayoutMismatch)
        }
    }

    /// Decomposes `frame` (row-major `width x height`) into `out`.
    pub fn analyze(&mut self, frame: &[f32], out: &mut RieszCoeffs) -> Result<(), PyramidError> {
        self.analyze_levels(frame, out, &mut |_, _| {})
    }

    /// [`Self::analyze`], calling `each(out, l)` as soon as level `l` is
    /// complete (its triple, and its amplitude and phases unless
    /// [`Self::set_triples_only`]), before the next level is computed: a
    /// reader of one level at a time (the phase sums) finds it still in
    /// cache. Levels above `l` are not yet computed when `each` is called.
    pub fn analyze_levels(
        &mut self,
        frame: &[f32],
        out: &mut RieszCoeffs,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) -> Result<(), PyramidError> {
        self.analyze_src(Pixels::F32(frame), out, each)
    }

    /// [`Self::analyze_levels`] of a frame of bytes: the same bits as of
    /// the frame widened to `f32`, without that copy. The first level's
    /// blur `S` is made in 16-bit integers (its every value is a multiple
    /// of 1/256 below 256, which `f32` holds exactly, so the integer sums
    /// scaled by 1/256 are the `f32` path's values to the bit), 32 lanes
    /// to a 512-bit vector where `f32` has 16.
    pub fn analyze_levels_u8(
        &mut self,
        frame: &[u8],
        out: &mut RieszCoeffs,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) -> Result<(), PyramidError> {
        self.analyze_src(Pixels::U8(frame), out, each)
    }

    fn analyze_src(
        &mut self,
        frame: Pixels<'_>,
        out: &mut RieszCoeffs,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) -> Result<(), PyramidError> {
        check_len(self.key.width * self.key.height, frame.len())?;
        self.check_coeffs(out)?;
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            // SAFETY: `simd` comes from `Simd::detect` (in `new`), which saw
            // the running CPU report the features each path enables.
            crate::join::Simd::Avx512 => {
                unsafe { self.levels_avx512(frame, out, each) };
                return Ok(());
            }
            crate::join::Simd::Avx2 => {
                unsafe { self.levels_avx2(frame, out, each) };
                return Ok(());
            }
            crate::join::Simd::Sse2 => {}
        }
        self.levels_generic(frame, out, each);
        Ok(())
    }

    fn levels_generic(
        &mut self,
        frame: Pixels<'_>,
        out: &mut RieszCoeffs,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) {
        self.levels(frame, out, each);
    }

    /// The same code compiled for AVX2 (8 lanes instead of SSE's 4). Only
    /// element-wise IEEE operations are vectorised (no FMA contraction), so
    /// results are bit-identical to the generic path.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn levels_avx2(
        &mut self,
        frame: Pixels<'_>,
        out: &mut RieszCoeffs,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) {
        self.levels(frame, out, each);
    }

    /// The same code compiled for AVX-512 (the same operations: the same
    /// bits).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx2,fma")]
    unsafe fn levels_avx512(
        &mut self,
        frame: Pixels<'_>,
        out: &mut RieszCoeffs,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) {
        self.levels(frame, out, each);
    }

    #[inline(always)]
    fn levels(
        &mut self,
        frame: Pixels<'_>,
        out: &mut RieszCoeffs,
        each: &mut dyn FnMut(&RieszCoeffs, usize),
    ) {
        let scales = self.key.scales.min(out.levels.len());
        out.derived = !self.triples_only;
        for l in 0..scales {
            let (w, h) = self.dims[l];
            let n = w * h;
            // Level input: the frame, or the decimated blur of the previous level.
            let split = l.min(self.inputs.len());
            let (before, after) = self.inputs.split_at_mut(split);
            let src = if l == 0 {
                frame
            } else {
                Pixels::F32(&before[l - 1])
            };
            let next = after.first_mut().filter(|_| l + 1 < scales);
            let level = &mut out.levels[l];
            sweep_level(
                src,
                (w, h),
                &mut self.s_buf[..n],
                level,
                next.map(Vec::as_mut_slice),
                (
                    &mut self.vrow[..w + 4],
                    &mut self.vrow16[..w + 4],
                    &mut self.trow[..w],
                ),
            );
            if !self.triples_only {
                derive_level(level, &self.dirs, &mut self.qrow[..w]);
            }
            each(out, l);
        }
    }
}

/// Mirror index (`x[-1] = x[1]`) into `0..n`, for any `n >= 1`. One
/// reflection (the taps' case: `-n < i < 2n - 1`) costs no division.
#[inline(always)]
fn reflect(i: isize, n: usize) -> usize {
    let m = n as isize;
    if (0..m).contains(&i) {
        return i as usize;
    }
    if i < 0 && -i < m {
        return (-i) as usize;
    }
    if i >= m && i < 2 * m - 1 {
        return (2 * (m - 1) - i) as usize;
    }
    if n == 1 {
        return 0;
    }
    let p = 2 * (n as isize - 1);
    let m = i.rem_euclid(p);
    if m >= n as isize {
        (p - m) as usize
    } else {
        m as usize
    }
}

const B0: f32 = 6.0 / 16.0;
const B1: f32 = 4.0 / 16.0;
const B2: f32 = 1.0 / 16.0;

/// Vertical 5-tap binomial of rows `y-2..=y+2` of `src` into `dst`.
#[inline(always)]
fn vblur_row(src: &[f32], w: usize, h: usize, y: usize, dst: &mut [f32]) {
    let row = |d: isize| -> &[f32] {
        let yy = reflect(y as isize + d, h);
        &src[yy * w..(yy + 1) * w]
    };
    let n = w.min(dst.len());
    let (a, b, c, d, e) = (
        &row(-2)[..n],
        &row(-1)[..n],
        &row(0)[..n],
        &row(1)[..n],
        &row(2)[..n],
    );
    let o = &mut dst[..n];
    for i in 0..n {
        o[i] = B2 * (a[i] + e[i]) + B1 * (b[i] + d[i]) + B0 * c[i];
    }
}

/// Horizontal 5-tap binomial of `src` into `dst` (same length), mirrored
/// pixel by pixel: rows too narrow for [`blur_row`]'s padding.
#[inline(always)]
fn hblur_row(src: &[f32], dst: &mut [f32]) {
    let w = src.len().min(dst.len());
    let at = |i: isize| src[reflect(i, w)];
    for (x, o) in dst.iter_mut().enumerate().take(w) {
        let x = x as isize;
        *o = B2 * (at(x - 2) + at(x + 2)) + B1 * (at(x - 1) + at(x + 1)) + B0 * at(x);
    }
}

/// Row `y` of the 5x5 binomial blur of `src` (`w x h`) into `dst`: the
/// vertical pass into `padded[2..w + 2]`, its mirrored pixels on either
/// side (`x[-i] = x[i]`, `x[w-1+i] = x[w-1-i]`), then the horizontal
/// pass over the whole row in one loop (no edge pixels apart, so the
/// vectorised loop covers rows of 32 or 64 without a scalar or
/// half-width tail). The same sums in the same order as
/// [`hblur_row`]'s: the same bits.
#[inline(always)]
fn blur_row(src: &[f32], (w, h): (usize, usize), y: usize, padded: &mut [f32], dst: &mut [f32]) {
    if w < 3 || padded.len() < w + 4 || dst.len() < w {
        vblur_row(src, w, h, y, padded);
        hblur_row(&padded[..w.min(padded.len())], dst);
        return;
    }
    vblur_row(src, w, h, y, &mut padded[2..w + 2]);
    let [a, b, c, d, e] = mirrored_taps(padded, w);
    let o = &mut dst[..w];
    for i in 0..w {
        o[i] = B2 * (a[i] + e[i]) + B1 * (b[i] + d[i]) + B0 * c[i];
    }
}

/// Sets the mirrored pixels on either side of `padded[2..w + 2]`
/// (`x[-i] = x[i]`, `x[w-1+i] = x[w-1-i]`) and returns the five windows
/// the horizontal taps read (`w >= 3`, `padded` at least `w + 4` long).
#[inline(always)]
fn mirrored_taps<T: Copy>(padded: &mut [T], w: usize) -> [&[T]; 5] {
    padded[0] = padded[4];
    padded[1] = padded[3];
    padded[w + 2] = padded[w];
    padded[w + 3] = padded[w - 1];
    let p = &padded[..w + 4];
    [
        &p[0..w],
        &p[1..w + 1],
        &p[2..w + 2],
        &p[3..w + 3],
        &p[4..w + 4],
    ]
}

/// [`blur_row`] of a frame of bytes, into `f32`, in 16-bit integers: with
/// the taps `[1 4 6 4 1]`, the vertical pass of bytes is at most
/// 16 · 255 and the horizontal pass of those at most 256 · 255 = 65280,
/// so neither overflows; `blur_row`'s `f32` sums of the same pixels are
/// exact (multiples of 1/16, then of 1/256, below 256: at most 16 bits
/// of mantissa), so this row, scaled by 1/256, is its row to the bit.
/// `padded` holds the vertical pass with its mirrored pixels, as in
/// [`blur_row`]. Rows too narrow for the padding are made as
/// `blur_row`'s narrow path makes them (mirrored pixel by pixel), in the
/// same integers.
#[inline(always)]
fn blur_row_u8(src: &[u8], (w, h): (usize, usize), y: usize, padded: &mut [u16], dst: &mut [f32]) {
    let vertical = |x: usize, o: &mut u16| {
        let at = |d: isize| u16::from(src[reflect(y as isize + d, h) * w + x]);
        *o = (at(-2) + at(2)) + 4 * (at(-1) + at(1)) + 6 * at(0);
    };
    if w < 3 || padded.len() < w + 4 || dst.len() < w {
        // As `blur_row`'s narrow path: the vertical pass into `padded`,
        // then the horizontal one mirrored pixel by pixel.
        let n = w.min(padded.len());
        for (x, o) in padded[..n].iter_mut().enumerate() {
            vertical(x, o);
        }
        let m = n.min(dst.len());
        let at = |i: isize| padded[reflect(i, m)];
        for (x, o) in dst.iter_mut().enumerate().take(m) {
            let x = x as isize;
            let v = (at(x - 2) + at(x + 2)) + 4 * (at(x - 1) + at(x + 1)) + 6 * at(x);
            *o = f32::from(v) * (1.0 / 256.0);
        }
        return;
    }
    let row = |d: isize| -> &[u8] {
        let yy = reflect(y as isize + d, h);
        &src[yy * w..(yy + 1) * w]
    };
    let (a, b, c, d, e) = (row(-2), row(-1), row(0), row(1), row(2));
    {
        let o = &mut padded[2..w + 2];
        for i in 0..w {
            let (a, b, c, d, e) = (
                u16::from(a[i]),
                u16::from(b[i]),
                u16::from(c[i]),
                u16::from(d[i]),
                u16::from(e[i]),
            );
            o[i] = (a + e) + 4 * (b + d) + 6 * c;
        }
    }
    let [a, b, c, d, e] = mirrored_taps(padded, w);
    let o = &mut dst[..w];
    for i in 0..w {
        let v = (a[i] + e[i]) + 4 * (b[i] + d[i]) + 6 * c[i];
        o[i] = f32::from(v) * (1.0 / 256.0);
    }
}

/// One level in one sweep of rows (each row's inputs still in L1, not
/// a pass over the whole level per step): `S = B * src` (kept: `T` reads
/// five of its rows), `T = B * S`, `band = S - T`, `next = T` at even rows
/// and columns, and the Riesz pair (`r2` one row behind the band, which
/// it reads above and below). The same operations as one whole-level pass
/// per step: the same bits.
#[inline(always)]
fn sweep_level(
    src: Pixels<'_>,
    (w, h): (usize, usize),
    s: &mut [f32],
    level: &mut RieszLevel,
    mut next: Option<&mut [f32]>,
    (vrow, vrow16, trow): (&mut [f32], &mut [u16], &mut [f32]),
) {
    let nw = w.div_ceil(2);
    let RieszLevel { band, r1, r2, .. } = level;
    // Rows of `S` computed so far: `T`'s row y reads rows up to y + 2
    // (mirrored rows below the last are rows above it).
    let mut done = 0;
    for y in 0..h {
        while done < (y + 3).min(h) {
            let dst = &mut s[done * w..(done + 1) * w];
            match src {
                Pixels::F32(x) => blur_row(x, (w, h), done, vrow, dst),
                Pixels::U8(x) => blur_row_u8(x, (w, h), done, vrow16, dst),
            }
            done += 1;
        }
        blur_row(s, (w, h), y, vrow, trow);
        let row = y * w..(y + 1) * w;
        for ((o, a), b) in band[row.clone()]
            .iter_mut()
            .zip(&s[row.clone()])
            .zip(trow.iter())
        {
            *o = a - b;
        }
        r1_row(&band[row.clone()], &mut r1[row.clone()]);
        if y.is_multiple_of(2) {
            if let Some(nb) = next.as_deref_mut() {
                let dst = &mut nb[(y / 2) * nw..(y / 2 + 1) * nw];
                // Even columns, in pairs (vectorised; `step_by(2)` was a
                // scalar loop).
                let pairs = (w / 2).min(dst.len());
                for (o, p) in dst[..pairs].iter_mut().zip(trow.chunks_exact(2)) {
                    *o = p[0];
                }
                if pairs < dst.len() {
                    dst[pairs] = trow[2 * pairs];
                }
            }
        }
        if y >= 1 {
            r2_row(band, w, h, y - 1, r2);
        }
    }
    if h >= 1 {
        r2_row(band, w, h, h - 1, r2);
    }
}

/// Along x: `(I[x-1] - I[x+1]) / 2`, edge-clamped.
#[inline(always)]
fn r1_row(mid: &[f32], r1: &mut [f32]) {
    let w = mid.len().min(r1.len());
    if w == 0 {
        return;
    }
    if w >= 3 {
        let n = w - 2;
        let (a, c) = (&mid[0..n], &mid[2..n + 2]);
        let o = &mut r1[1..n + 1];
        for i in 0..n {
            o[i] = 0.5 * (a[i] - c[i]);
        }
    }
    r1[0] = 0.5 * (mid[0] - mid[1.min(w - 1)]);
    r1[w - 1] = 0.5 * (mid[w.saturating_sub(2)] - mid[w - 1]);
}

/// Row `y` of `R2 = (I[y-1] - I[y+1]) / 2`, edge-clamped.
#[inline(always)]
fn r2_row(band: &[f32], w: usize, h: usize, y: usize, r2: &mut [f32]) {
    let up = y.saturating_sub(1);
    let dn = (y + 1).min(h - 1);
    let (ur, dr) = (&band[up * w..(up + 1) * w], &band[dn * w..(dn + 1) * w]);
    for ((o, a), b) in r2[y * w..(y + 1) * w].iter_mut().zip(ur).zip(dr) {
        *o = 0.5 * (a - b);
    }
}

/// Odd minimax-style polynomial for `atan(a)`, `a` in `[0, 1]` (error
/// about 3e-7 rad).
#[inline(always)]
fn atan_unit(a: f32) -> f32 {
    let s = a * a;
    let p = 0.999_996_6
        + s * (-0.333_183_03
            + s * (0.198_132_16
                + s * (-0.132_475_31
                    + s * (0.079_811_34 + s * (-0.033_726_04 + s * 0.006_842_657)))));
    p * a
}

/// `atan2(y, x)` for `y >= 0`, in `[0, π]`; max error about 3e-7 rad.
#[cfg(test)]
fn atan2_upper(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let a = ax.min(y) / ax.max(y).max(f32::MIN_POSITIVE);
    finish_atan(atan_unit(a), y, x)
}

/// Maps `atan(min/max)` of `(y >= 0, |x|)` back to `atan2(y, x)`.
#[inline(always)]
fn finish_atan(t: f32, y: f32, x: f32) -> f32 {
    let t = if y > x.abs() { FRAC_PI_2 - t } else { t };
    if x < 0.0 {
        PI - t
    } else {
        t
    }
}

/// Per pixel of a row: amplitude, and `φ/|R|` into `q` (0 where `R = 0`).
/// Two square roots and one division per pixel.
#[inline(always)]
fn amp_phase_row(mid: &[f32], r1: &[f32], r2: &[f32], amp: &mut [f32], q: &mut [f32]) {
    for ((((a, q), &iv), &x1), &x2) in amp.iter_mut().zip(q.iter_mut()).zip(mid).zip(r1).zip(r2) {
        let rr = x1 * x1 + x2 * x2;
        *a = (iv * iv + rr).sqrt();
        let r = rr.sqrt();
        let ax = iv.abs();
        let (mn, mx) = if r > ax { (ax, r) } else { (r, ax) };
        // One division gives both 1/r and 1/mx.
        let den = r * mx;
        let inv = if den > 0.0 { 1.0 / den } else { 0.0 };
        let phi = finish_atan(atan_unit(mn * r * inv), r, iv);
        *q = phi * mx * inv;
    }
}

/// Amplitude and projected phases of one level, from its triple.
#[inline(always)]
fn derive_level(level: &mut RieszLevel, dirs: &[(f32, f32)], qrow: &mut [f32]) {
    let (w, h) = (level.width, level.height);
    for y in 0..h {
        let row = y * w..(y + 1) * w;
        let mid = &level.band[row.clone()];
        let r1 = &level.r1[row.clone()];
        let r2 = &level.r2[row.clone()];
        let amp = &mut level.amplitude[row.clone()];
        let q = &mut qrow[..w];
        amp_phase_row(mid, r1, r2, amp, q);
        for (p, &(ck, sk)) in level.phases.iter_mut().zip(dirs) {
            for (((p, &q), &x1), &x2) in p[row.clone()].iter_mut().zip(q.iter()).zip(r1).zip(r2) {
                *p = q * (x1 * ck + x2 * sk);
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
#[path = "riesz_tests.rs"]
mod tests;
