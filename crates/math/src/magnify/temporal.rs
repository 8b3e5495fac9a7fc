//! The causal temporal band-pass applied to every pixel's phase: a
//! Butterworth band-pass (low-pass prototype, low-pass to band-pass by
//! `s -> (s² + w0²) / (B·s)`, bilinear transform with both edges
//! pre-warped), as second-order sections with unit gain and zero phase at
//! the centre frequency `sqrt(lo·hi)` (pre-warped). Wadhwa et al. (2014)
//! use the order-1 case (one section) per pixel; a higher order rejects
//! out-of-band motion more steeply.
//!
//! The state is per pixel, f32, transposed direct form II: the filter
//! runs over whole bands at once, allocating nothing.

use realfft::num_complex::Complex;
use std::f64::consts::PI;

/// One section: `b0 + b1 z⁻¹ + b2 z⁻²` over `1 + a1 z⁻¹ + a2 z⁻²`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Section {
    pub b: [f32; 3],
    pub a: [f32; 2],
}

/// The designed band-pass: its sections (apply in order).
#[derive(Clone, Debug, PartialEq)]
pub struct BandpassDesign {
    pub sections: Vec<Section>,
    /// The frequency of unit gain and zero phase, Hz.
    pub centre_hz: f64,
}

/// Designs the order-`order` Butterworth band-pass `[lo_hz, hi_hz]` at
/// `rate_hz`. The caller checks `0 < lo < hi < rate/2` and `order >= 1`.
pub fn design(order: usize, lo_hz: f64, hi_hz: f64, rate_hz: f64) -> BandpassDesign {
    let wl = (PI * lo_hz / rate_hz).tan();
    let wh = (PI * hi_hz / rate_hz).tan();
    let bw = wh - wl;
    let w0sq = wl * wh;
    let n = order as f64;
    let one = Complex::new(1.0, 0.0);
    // Analog band-pass poles: for each prototype pole p (upper half plane
    // and the real one), the roots of s² - p·B·s + w0² = 0 and their
    // conjugates.
    let mut poles: Vec<Complex<f64>> = Vec::with_capacity(2 * order);
    for k in 0..order {
        let th = PI * (2.0 * k as f64 + n + 1.0) / (2.0 * n);
        let p = Complex::from_polar(1.0, th);
        if p.im < -1e-12 {
            continue;
        }
        let pb = p * bw;
        let disc = (pb * pb - 4.0 * w0sq).sqrt();
        for s in [(pb + disc) * 0.5, (pb - disc) * 0.5] {
            poles.push(s);
        }
    }
    // Bilinear (pre-warped, s = (1 - z⁻¹)/(1 + z⁻¹)): z = (1 + s)/(1 - s).
    let zs: Vec<Complex<f64>> = poles.iter().map(|&s| (one + s) / (one - s)).collect();
    // Each complex pole with its conjugate makes a section (a real
    // prototype pole gives a conjugate pair, generated twice: keep one);
    // real poles go two to a section.
    let mut out: Vec<[f64; 2]> = Vec::with_capacity(order);
    let mut seen: Vec<Complex<f64>> = Vec::new();
    let mut reals: Vec<f64> = Vec::new();
    for z in zs {
        if z.im.abs() < 1e-12 {
            reals.push(z.re);
        } else if !seen.iter().any(|s| (s - z.conj()).norm() < 1e-9) {
            seen.push(z);
            out.push([-2.0 * z.re, z.norm_sqr()]);
        }
    }
    for pair in reals.chunks(2) {
        let (r1, r2) = (pair[0], pair.get(1).copied().unwrap_or(0.0));
        out.push([-(r1 + r2), r1 * r2]);
    }
    // Zeros: s = 0 (z = 1) and s = ∞ (z = -1), one of each per section.
    let mut secs: Vec<Section> = out
        .iter()
        .map(|a| Section {
            b: [1.0, 0.0, -1.0],
            a: [a[0] as f32, a[1] as f32],
        })
        .collect();
    // Normalise to unit gain at the centre.
    let centre_hz = rate_hz / PI * w0sq.sqrt().atan();
    let w = 2.0 * PI * centre_hz / rate_hz;
    let (z1, z2) = (
        Complex::from_polar(1.0, -w),
        Complex::from_polar(1.0, -2.0 * w),
    );
    let h: Complex<f64> = out
        .iter()
        .map(|a| (one - z2) / (one + z1 * a[0] + z2 * a[1]))
        .product();
    let g = 1.0 / h.norm();
    // Spread the gain over the sections (keeps intermediate values moderate).
    let gs = g.powf(1.0 / secs.len().max(1) as f64);
    for s in &mut secs {
        s.b = [gs as f32, 0.0, -gs as f32];
    }
    BandpassDesign {
        sections: secs,
        centre_hz,
    }
}

impl BandpassDesign {
    /// The same filter for a signal's changes `x[t] - x[t-1]` instead of
    /// the signal: the first section's numerator divided by `1 - z⁻¹`
    /// (every section has a zero at `z = 1`: `b0 + b1 + b2 = 0`), so that
    /// `b0 + b1 z⁻¹ + b2 z⁻²` becomes `b0 + (b0 + b1) z⁻¹`. Fed the changes
    /// from rest, it gives what this one gives fed their running sum, with
    /// no sum kept (which grows without bound as phase drifts).
    pub fn on_increments(&self) -> Self {
        let mut d = self.clone();
        if let Some(s) = d.sections.first_mut() {
            s.b = [s.b[0], s.b[0] + s.b[1], 0.0];
        }
        d
    }

    /// Complex response at `f_hz` for a stream at `rate_hz` (f64 from the
    /// stored f32 coefficients).
    pub fn response_at(&self, f_hz: f64, rate_hz: f64) -> Complex<f64> {
        let widen = |v: [f32; 3]| v.map(f64::from);
        crate::iir::cascade_response(
            self.sections
                .iter()
                .map(|s| (widen(s.b), [f64::from(s.a[0]), f64::from(s.a[1])])),
            f_hz,
            rate_hz,
        )
    }
}

/// Pixels per block of a [`PixelFilter`]'s state.
pub const CHUNK: usize = 64;

/// Per-pixel state of a [`BandpassDesign`] over `n` pixels (or `h` rows
/// of `w`), in blocks of up to [`CHUNK`] pixels of one row: per block, per
/// section, register 0 of the block's pixels then register 1 (contiguous
/// runs: the step vectorises, and a block's whole state is together).
#[derive(Clone, Debug)]
pub struct PixelFilter {
    sections: Vec<Section>,
    state: Vec<f32>,
    /// Row width and blocks per row.
    w: usize,
    per_row: usize,
}

/// The state of a run of whole rows ([`PixelFilter::parts`]).
pub struct FilterPart<'a> {
    sections: &'a [Section],
    state: &'a mut [f32],
    first_row: usize,
    per_row: usize,
}

/// One time step of the pixels of one block (`x.len() <= CHUNK`), its
/// state `st`.
#[inline(always)]
fn step_block(sections: &[Section], st: &mut [f32], x: &mut [f32]) {
    for (s, regs) in sections.iter().zip(st.chunks_exact_mut(2 * CHUNK)) {
        let (b0, b1, b2, a1, a2) = (s.b[0], s.b[1], s.b[2], s.a[0], s.a[1]);
        let (r0, r1) = regs.split_at_mut(CHUNK);
        for ((v, p), q) in x.iter_mut().zip(r0.iter_mut()).zip(r1.iter_mut()) {
            let xin = *v;
            let y = b0 * xin + *p;
            *p = b1 * xin - a1 * y + *q;
            *q = b2 * xin - a2 * y;
            *v = y;
        }
    }
}

impl PixelFilter {
    /// The state of `n` pixels (one row).
    pub fn new(design: &BandpassDesign, n: usize) -> Self {
        Self::with_rows(design, n, 1)
    }

    /// The state of `h` rows of `w` pixels (blocks never straddle rows,
    /// so the rows can be split anywhere: [`Self::parts`]).
    pub fn with_rows(design: &BandpassDesign, w: usize, h: usize) -> Self {
        let per_row = w.div_ceil(CHUNK);
        Self {
            state: crate::numeric::zeros_touched(h * per_row * 2 * CHUNK * design.sections.len()),
            sections: design.sections.clone(),
            w,
            per_row,
        }
    }

    fn block_len(&self) -> usize {
        2 * CHUNK * self.sections.len()
    }

    /// Filters one time step of every pixel in place: `x[i]` in, `y[i]` out.
    #[inline(always)]
    pub fn step(&mut self, x: &mut [f32]) {
        let b = self.block_len();
        let w = self.w.max(1);
        let blocks = x.chunks_mut(w).flat_map(|row| row.chunks_mut(CHUNK));
        for (xs, st) in blocks.zip(self.state.chunks_exact_mut(b)) {
            step_block(&self.sections, st, xs);
        }
    }

    /// One time step of row `y`'s pixels in place (a filter made
    /// [`Self::with_rows`]; `x` is the row, at most `w` pixels): the
    /// same operations on each pixel as [`Self::step`].
    #[inline(always)]
    pub fn step_row(&mut self, y: usize, x: &mut [f32]) {
        let b = self.block_len();
        let row = &mut self.state[y * self.per_row * b..(y + 1) * self.per_row * b];
        let len = x.len().min(self.w);
        for (xs, st) in x[..len].chunks_mut(CHUNK).zip(row.chunks_exact_mut(b)) {
            step_block(&self.sections, st, xs);
        }
    }

    /// The state split at row `mid`: rows `..mid` and `mid..`, to step at
    /// once.
    pub fn parts(&mut self, mid: usize) -> (FilterPart<'_>, FilterPart<'_>) {
        let row = self.per_row * self.block_len();
        let split = (mid * row).min(self.state.len());
        let (s0, s1) = self.state.split_at_mut(split);
        let part = |state, first_row| FilterPart {
            sections: &self.sections,
            state,
            first_row,
            per_row: self.per_row,
        };
        (part(s0, 0), part(s1, mid))
    }
}

impl FilterPart<'_> {
    /// One time step of the pixels `x0..x0 + x.len()` of row `y` (`x0` a
    /// multiple of [`CHUNK`], `x` at most one block).
    #[inline(always)]
    pub fn step_at(&mut self, x: &mut [f32], y: usize, x0: usize) {
        let b = 2 * CHUNK * self.sections.len();
        let k = (y - self.first_row) * self.per_row + x0 / CHUNK;
        step_block(self.sections, &mut self.state[k * b..(k + 1) * b], x);
    }
}
