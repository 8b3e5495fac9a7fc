//! Signal tools of calibration: band-limited resampling, STFT
//! equalisation, spectra, one-dimensional minimisation, the high-pass.

use crate::numeric::bessel_i0;
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use std::f64::consts::PI;

/// Half-width of the band-limited interpolator, in input samples.
const SINC_HALF: isize = 32;

/// Kaiser window shape of the interpolator.
const BETA: f64 = 8.0;

/// Taps of the interpolator.
const TAPS: usize = 2 * SINC_HALF as usize;

/// Fractional positions tabulated per sample (cubic interpolation between
/// them is within about 1e-11 of the windowed sinc).
const PHASES: usize = 512;

/// The windowed sinc `w(d) sinc(d)` of tap `t` (input sample
/// `floor(p) - H + 1 + t`, at distance `d = frac + H - 1 - t` from `p`)
/// for `frac = (j - 1) / PHASES`: row `j` holds the 2H taps, `j` in
/// `0..PHASES + 4` (one phase below 0 and two past 1, for the cubic), so
/// a sample's kernel is four contiguous rows blended. Computed once (a
/// Bessel function and a sine per tap cost 90% of a calibration; a
/// division per tap, to apply the sinc per sample, cost 45% of it).
fn kernel_table() -> &'static [[f64; TAPS]] {
    static TABLE: std::sync::OnceLock<Vec<[f64; TAPS]>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let i0b = bessel_i0(BETA);
        (0..PHASES + 4)
            .map(|j| {
                let mut row = [0.0; TAPS];
                for (t, h) in row.iter_mut().enumerate() {
                    let d = (j as f64 - 1.0) / PHASES as f64 + (SINC_HALF - 1) as f64 - t as f64;
                    let r = (d / SINC_HALF as f64).clamp(-1.0, 1.0);
                    let w = bessel_i0(BETA * (1.0 - r * r).max(0.0).sqrt()) / i0b;
                    let sinc = if d == 0.0 {
                        1.0
                    } else {
                        (PI * d).sin() / (PI * d)
                    };
                    *h = w * sinc;
                }
                row
            })
            .collect()
    })
}

/// `x` (sampled at `rate`) at arbitrary `times` (seconds; sample `i` is at
/// `i / rate`), by a Kaiser-windowed sinc at `x`'s own Nyquist frequency
/// (exact at sample instants); zero outside `x`. The kernel is tabulated
/// at `PHASES` fractional positions and interpolated between them by a
/// four-point Lagrange cubic: no division or sine per output sample.
pub fn sample_at(x: &[f64], rate: f64, times: impl Iterator<Item = f64>) -> Vec<f64> {
    let table = kernel_table();
    let h = SINC_HALF;
    let n = x.len() as isize;
    let simd = crate::join::Simd::detect();
    times
        .map(|t| {
            let p = t * rate;
            if !p.is_finite() || p < -(h as f64) || p > (n + h) as f64 {
                return 0.0;
            }
            // Within 1e-9 of a sample, the sample (the kernel there is
            // that sample's alone, to within the interpolation).
            let near = p.round();
            let (c0, frac) = if (p - near).abs() < 1e-9 {
                (near as isize, 0.0)
            } else {
                (p.floor() as isize, p - p.floor())
            };
            if frac == 0.0 {
                return if (0..n).contains(&c0) {
                    x[c0 as usize]
                } else {
                    0.0
                };
            }
            // Phase `q = floor(u)` is row `q + 1`; rows `q..q + 4` are the
            // phases `q - 1..=q + 2` the cubic passes through.
            let u = frac * PHASES as f64;
            let q = (u as usize).min(PHASES);
            let f = u - q as f64;
            let c = [
                -f * (f - 1.0) * (f - 2.0) / 6.0,
                (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0,
                -(f + 1.0) * f * (f - 2.0) / 2.0,
                (f + 1.0) * f * (f - 1.0) / 6.0,
            ];
            // Tap t reads input sample c0 - H + 1 + t; near the ends only
            // the taps inside `x`.
            let first = c0 - h + 1;
            let lo = (-first).clamp(0, TAPS as isize) as usize;
            let hi = (n - first).clamp(0, TAPS as isize) as usize;
            if lo >= hi {
                return 0.0;
            }
            let s0 = (first + lo as isize) as usize;
            let rows = [&table[q], &table[q + 1], &table[q + 2], &table[q + 3]].map(|r| &r[lo..hi]);
            blend_dot(simd, &x[s0..s0 + (hi - lo)], rows, c)
        })
        .collect()
}

crate::join::simd_fn! {
    /// `x · (c0 r0 + c1 r1 + c2 r2 + c3 r3)` over `x`'s length (each row
    /// at least as long), in eight running sums: one sum in turn waits on
    /// each add, and the blended kernel is never stored. No fused
    /// multiply-add, so every vector width gives the same bits.
    fn blend_dot(x: &[f64], rows: [&[f64]; 4], c: [f64; 4]) -> f64 {
        let n = x.len();
        let (xc, xt) = x.as_chunks::<8>();
        let [r0, r1, r2, r3] = rows.map(|r| r[..n].as_chunks::<8>());
        let mut acc = [0.0; 8];
        for ((((x, a), b), d), e) in xc.iter().zip(r0.0).zip(r1.0).zip(r2.0).zip(r3.0) {
            for k in 0..8 {
                acc[k] += x[k] * (c[0] * a[k] + c[1] * b[k] + c[2] * d[k] + c[3] * e[k]);
            }
        }
        let mut tail = 0.0;
        for ((((x, a), b), d), e) in xt.iter().zip(r0.1).zip(r1.1).zip(r2.1).zip(r3.1) {
            tail += x * (c[0] * a + c[1] * b + c[2] * d + c[3] * e);
        }
        acc.iter().sum::<f64>() + tail
    }
}

crate::join::simd_fn! {
    /// `Σ a·b·w` over the shortest slice's length, in eight running sums
    /// added in a fixed order at the end (as [`blend_dot`]): a single sum
    /// waits on each add (the explainer's fits were bound by that). Each
    /// product as `(a·b)·w`, no fused multiply-add: every vector width
    /// gives the same bits.
    pub(super) fn weighted_dot(a: &[f64], b: &[f64], w: &[f64]) -> f64 {
        let n = a.len().min(b.len()).min(w.len());
        let (ac, at) = a[..n].as_chunks::<8>();
        let (bc, bt) = b[..n].as_chunks::<8>();
        let (wc, wt) = w[..n].as_chunks::<8>();
        let mut acc = [0.0; 8];
        for ((a, b), w) in ac.iter().zip(bc).zip(wc) {
            for k in 0..8 {
                acc[k] += a[k] * b[k] * w[k];
            }
        }
        let mut tail = 0.0;
        for ((a, b), w) in at.iter().zip(bt).zip(wt) {
            tail += a * b * w;
        }
        acc.iter().sum::<f64>() + tail
    }
}

crate::join::simd_fn! {
    /// `Σ a·b` over the shorter slice's length, as [`weighted_dot`].
    pub(super) fn plain_dot(a: &[f64], b: &[f64]) -> f64 {
        let n = a.len().min(b.len());
        let (ac, at) = a[..n].as_chunks::<8>();
        let (bc, bt) = b[..n].as_chunks::<8>();
        let mut acc = [0.0; 8];
        for (a, b) in ac.iter().zip(bc) {
            for k in 0..8 {
                acc[k] += a[k] * b[k];
            }
        }
        let mut tail = 0.0;
        for (a, b) in at.iter().zip(bt) {
            tail += a * b;
        }
        acc.iter().sum::<f64>() + tail
    }
}

/// STFT length for a rate: about 0.1 s, a power of two in 64..=4096.
pub fn stft_len(fs: f64) -> usize {
    ((0.1 * fs).max(64.0) as usize)
        .next_power_of_two()
        .clamp(64, 4096)
}

/// Periodic sqrt-Hann frames, hop N/2, zero-phase gain `gain(f)` per bin,
/// weighted overlap-add (perfect reconstruction for gain 1).
pub fn equalize(x: &[f64], fs: f64, gain: impl Fn(f64) -> Complex<f64>) -> Vec<f64> {
    let nfft = stft_len(fs);
    let hop = nfft / 2;
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(nfft);
    let inv = planner.plan_fft_inverse(nfft);
    let win: Vec<f64> = (0..nfft)
        .map(|i| (0.5 - 0.5 * (2.0 * PI * i as f64 / nfft as f64).cos()).sqrt())
        .collect();
    let g: Vec<Complex<f64>> = (0..=nfft / 2)
        .map(|k| gain(k as f64 * fs / nfft as f64))
        .collect();
    // Padded by one frame on each side.
    let len = x.len() + 2 * nfft;
    let mut padded = vec![0.0; len];
    padded[nfft..nfft + x.len()].copy_from_slice(x);
    let mut out = vec![0.0; len];
    let mut buf = fwd.make_input_vec();
    let mut spec = fwd.make_output_vec();
    let mut s = 0;
    while s + nfft <= len {
        for i in 0..nfft {
            buf[i] = padded[s + i] * win[i];
        }
        let _ = fwd.process(&mut buf, &mut spec);
        for (c, gk) in spec.iter_mut().zip(&g) {
            *c *= *gk;
        }
        if let Some(c) = spec.first_mut() {
            c.im = 0.0;
        }
        if let Some(c) = spec.last_mut() {
            c.im = 0.0;
        }
        let _ = inv.process(&mut spec, &mut buf);
        for i in 0..nfft {
            out[s + i] += buf[i] * win[i] / nfft as f64;
        }
        s += hop;
    }
    out[nfft..nfft + x.len()].to_vec()
}

/// Hann-windowed STFT frames (hop N/2) of `x`: one spectrum per frame.
pub(super) fn stft(x: &[f64], nfft: usize) -> Vec<Vec<Complex<f64>>> {
    crate::stft::stft(x, nfft, nfft / 2)
}

/// Welch power spectrum (mean of |STFT|²) with `nfft`.
pub(super) fn welch(x: &[f64], nfft: usize) -> Vec<f64> {
    let frames = stft(x, nfft);
    let mut p = vec![0.0; nfft / 2 + 1];
    for f in &frames {
        for (a, c) in p.iter_mut().zip(f) {
            *a += c.norm_sqr();
        }
    }
    let k = frames.len().max(1) as f64;
    p.iter_mut().for_each(|v| *v /= k);
    p
}

/// Golden-section minimisation of `f` on `[a, b]`; returns `(x, f(x))`.
pub(super) fn golden(
    mut f: impl FnMut(f64) -> f64,
    mut a: f64,
    mut b: f64,
    iters: usize,
) -> (f64, f64) {
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd {
        (c, fc)
    } else {
        (d, fd)
    }
}

/// One standard deviation of a parameter at a minimum `x` of `sse` by the
/// Δχ² = 1 rule: the curvature of `sse` by central differences with step
/// `h`, residual variance `sigma2`.
pub(super) fn curvature_sigma(mut sse: impl FnMut(f64) -> f64, x: f64, h: f64, sigma2: f64) -> f64 {
    let (a, b, c) = (sse(x - h), sse(x), sse(x + h));
    let curv = (a + c - 2.0 * b) / (h * h);
    if curv > 0.0 {
        (2.0 * sigma2 / curv).sqrt()
    } else {
        f64::INFINITY
    }
}

pub(super) use crate::numeric::jackknife_std as jackknife;

/// Least-squares gain of `z ≈ g t` and the squared error left.
pub(super) fn gain_sse(t: &[f64], z: &[f64]) -> (f64, f64) {
    let tt: f64 = t.iter().map(|v| v * v).sum();
    let tz: f64 = t.iter().zip(z).map(|(a, b)| a * b).sum();
    let zz: f64 = z.iter().map(|v| v * v).sum();
    if tt <= 0.0 {
        return (0.0, zz);
    }
    let g = tz / tt;
    (g, (zz - g * tz).max(0.0))
}

/// A spectrum's strongest bin, its power and the frequency of its peak
/// (refined by a parabola through the log powers of the bin and its
/// neighbours), with `df` the bin's width.
pub(super) fn dominant(b: &[Complex<f64>], df: f64) -> (usize, f64, f64) {
    let nb = b.len();
    let (k, p) = b
        .iter()
        .enumerate()
        .map(|(k, c)| (k, c.norm_sqr()))
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .unwrap_or((0, 0.0));
    let f = if k > 0 && k + 1 < nb {
        let (l, c, r) = (
            b[k - 1].norm_sqr().max(1e-300).ln(),
            p.max(1e-300).ln(),
            b[k + 1].norm_sqr().max(1e-300).ln(),
        );
        let den = l - 2.0 * c + r;
        (k as f64 + if den < 0.0 { 0.5 * (l - r) / den } else { 0.0 }) * df
    } else {
        k as f64 * df
    };
    (k, p, f)
}

/// Alias of frequency `f` sampled at `fs`, folded into `[0, fs/2]`.
pub fn alias(f: f64, fs: f64) -> f64 {
    let m = f.rem_euclid(fs);
    if m > fs / 2.0 {
        fs - m
    } else {
        m
    }
}

/// `x` with the recovery's high-pass undone where it passes more than half
/// the amplitude (below that, the band is left out: it holds drift and
/// noise the inverse would lift).
pub(super) fn undo_highpass(x: &[f64], fs: f64, hp: Option<(usize, f64)>) -> Vec<f64> {
    let Some(sos) = hp.and_then(|(o, c)| crate::iir::Sos::butterworth_highpass(o, c, fs).ok())
    else {
        return x.to_vec();
    };
    equalize(x, fs, |f| {
        let h = sos.response_at(f, fs);
        if h.norm() > 0.5 {
            h.inv()
        } else {
            Complex::new(0.0, 0.0)
        }
    })
}

/// `x` through the recovery's high-pass (the pipeline's IIR filter).
pub(super) fn redo_highpass(x: &[f64], fs: f64, hp: Option<(usize, f64)>) -> Vec<f64> {
    match hp.and_then(|(o, c)| crate::iir::Sos::butterworth_highpass(o, c, fs).ok()) {
        Some(mut sos) => x.iter().map(|&v| sos.step(v)).collect(),
        None => x.to_vec(),
    }
}

/// `v` less its mean, through the recovery's high-pass: an observable
/// (a tile's motion or intensity) made comparable with the recovery.
pub fn centred_highpass(v: &[f64], fs: f64, hp: Option<(usize, f64)>) -> Vec<f64> {
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    redo_highpass(&v.iter().map(|a| a - mean).collect::<Vec<_>>(), fs, hp)
}

/// `x` averaged over three neighbours (two at the ends): how the
/// coefficients are smoothed.
pub fn smooth3(x: &[f64]) -> Vec<f64> {
    (0..x.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 2).min(x.len()));
            x[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect()
}

/// The response's highest point: its frequency (Hz, a parabola through
/// the highest coefficient and its neighbours where they are adjacent
/// bins) and its height above the curve's median (dB). `None` for fewer
/// than three coefficients.
pub fn peak(freqs_hz: &[f64], coef_db: &[f64]) -> Option<(f64, f64)> {
    if coef_db.len() < 3 || freqs_hz.len() != coef_db.len() {
        return None;
    }
    let (i, &top) = coef_db
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    let mut sorted = coef_db.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let mut f = freqs_hz[i];
    if i > 0 && i + 1 < coef_db.len() {
        let (df0, df1) = (f - freqs_hz[i - 1], freqs_hz[i + 1] - f);
        let (a, b) = (coef_db[i - 1], coef_db[i + 1]);
        let den = a - 2.0 * top + b;
        if (df0 - df1).abs() < 1e-9 * df0 && den < 0.0 {
            f += 0.5 * (a - b) / den * df0;
        }
    }
    Some((f, top - median))
}
