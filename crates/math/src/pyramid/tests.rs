//! Test helpers shared by the pyramids' tests (a counting allocator, a
//! seeded generator, translated textures), and tests of both pyramids.

use super::csp::signed_index;
use super::{ComplexSteerablePyramid, PyramidCoeffs, RieszCoeffs, RieszPyramid};
use rustfft::num_complex::Complex64;

/// Thread-local counting allocator: counts allocations made by the
/// calling thread only, so concurrently running tests do not interfere.
pub(crate) mod alloc_count {
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    thread_local! {
        static COUNT: Cell<u64> = const { Cell::new(0) };
    }

    fn bump() {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
    }

    pub struct Counting;

    // SAFETY: forwards to the system allocator unchanged; only counts calls.
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, l: Layout) -> *mut u8 {
            bump();
            // SAFETY: same contract as the caller's.
            unsafe { System.alloc(l) }
        }
        unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
            bump();
            // SAFETY: same contract as the caller's.
            unsafe { System.alloc_zeroed(l) }
        }
        unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
            // SAFETY: same contract as the caller's.
            unsafe { System.dealloc(p, l) }
        }
        unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
            bump();
            // SAFETY: same contract as the caller's.
            unsafe { System.realloc(p, l, n) }
        }
    }

    #[global_allocator]
    static A: Counting = Counting;

    /// Allocations made so far by this thread.
    pub fn allocations() -> u64 {
        COUNT.try_with(Cell::get).unwrap_or(0)
    }
}

/// `n` seeded standard normal samples.
pub(crate) fn noise(n: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    (0..n).map(|_| rng.normal() as f32).collect()
}

/// SplitMix64 with Box-Muller normals (seeded, reproducible).
pub(crate) struct Rng(u64);
impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

#[derive(Clone, Copy, Debug)]
pub(crate) enum Texture {
    /// White noise, smoothly band-limited below ~0.3 cycles/pixel.
    BandLimited,
    /// 1/f amplitude spectrum (natural-image-like), gently rolled off.
    Natural,
}

/// 2D DFT in f64 (rows then columns), `inverse` unnormalised.
pub(crate) fn fft2(data: &mut [Complex64], w: usize, h: usize, inverse: bool) {
    let mut p = rustfft::FftPlanner::<f64>::new();
    let (fx, fy) = if inverse {
        (p.plan_fft_inverse(w), p.plan_fft_inverse(h))
    } else {
        (p.plan_fft_forward(w), p.plan_fft_forward(h))
    };
    fx.process(data);
    let mut col = vec![Complex64::default(); h];
    for x in 0..w {
        for y in 0..h {
            col[y] = data[y * w + x];
        }
        fy.process(&mut col);
        for y in 0..h {
            data[y * w + x] = col[y];
        }
    }
}

/// A seeded texture of unit RMS, translated by `(dx, dy)` pixels with
/// the Fourier shift theorem (exact, periodic). Nyquist bins are zeroed
/// so that any sub-pixel shift keeps the image real.
pub(crate) fn texture(w: usize, h: usize, seed: u64, kind: Texture, dx: f64, dy: f64) -> Vec<f32> {
    let mut rng = Rng::new(seed);
    let mut spec: Vec<Complex64> = (0..w * h)
        .map(|_| Complex64::new(rng.normal(), 0.0))
        .collect();
    fft2(&mut spec, w, h, false);
    let mut energy = 0.0;
    for y in 0..h {
        let ky = signed_index(y, h);
        for x in 0..w {
            let kx = signed_index(x, w);
            let nyq = (w.is_multiple_of(2) && kx == -(w as isize) / 2)
                || (h.is_multiple_of(2) && ky == -(h as isize) / 2);
            let f = (kx as f64 / w as f64).hypot(ky as f64 / h as f64);
            let gain = match kind {
                Texture::BandLimited => (-(f / 0.22).powi(4)).exp(),
                Texture::Natural => (-(f / 0.4).powi(6)).exp() / (f + 0.004),
            };
            let gain = if nyq || (kx == 0 && ky == 0) {
                0.0
            } else {
                gain
            };
            let phase = -2.0
                * std::f64::consts::PI
                * (kx as f64 * dx / w as f64 + ky as f64 * dy / h as f64);
            let v = spec[y * w + x] * gain;
            energy += v.norm_sqr();
            spec[y * w + x] = v * Complex64::from_polar(1.0, phase);
        }
    }
    fft2(&mut spec, w, h, true);
    // Parseval: RMS = sqrt(energy) / (w h).
    let scale = (w * h) as f64 / energy.sqrt().max(1e-300);
    spec.iter()
        .map(|c| (c.re * scale / (w * h) as f64) as f32)
        .collect()
}

#[test]
fn types_are_send_and_sync() {
    fn check<T: Send + Sync>() {}
    check::<ComplexSteerablePyramid>();
    check::<PyramidCoeffs>();
    check::<RieszPyramid>();
    check::<RieszCoeffs>();
}
