//! Small numeric helpers shared across the crate (and by the command line):
//! the greatest common divisor, the median, the delete-one jackknife's
//! spread, the modified Bessel function `I0` (Kaiser windows), and
//! zeroed buffers whose pages are mapped at once.

/// `n` zeros, every page of them written now. `vec![0.0; n]` takes the
/// allocator's lazily mapped zero pages: a streaming kernel's state that
/// is read before it is written (a filter's state, the previous frame's
/// band) then costs, on its first frame, a read fault mapping the shared
/// zero page and a copy-on-write fault per page, whose TLB flush
/// interrupts the process's other core (in a VM, an exit each). Measured
/// on `magnify --pyramid riesz`, 4 frames of 256x256: 957 copy-on-write
/// faults and 20.4 ms against 16 and 13.9 ms with the magnifier's
/// buffers made here.
pub fn zeros_touched<T: Copy + Default>(n: usize) -> Vec<T> {
    let mut v = vec![T::default(); n];
    let per_page = (4096 / std::mem::size_of::<T>().max(1)).max(1);
    for x in v.iter_mut().step_by(per_page) {
        *x = std::hint::black_box(T::default());
    }
    if let Some(x) = v.last_mut() {
        *x = std::hint::black_box(T::default());
    }
    v
}

/// Greatest common divisor (`gcd(a, 0) = a`).
pub fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// The median of `v` (sorted in place, `total_cmp` order; the mean of the
/// two middle values for an even length); NaN when empty.
pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The delete-one jackknife's standard deviation of the estimates `loo`
/// (each made with one part of the data left out).
pub fn jackknife_std(loo: impl Iterator<Item = f64> + Clone) -> f64 {
    let k = loo.clone().count() as f64;
    let mean = loo.clone().sum::<f64>() / k;
    ((k - 1.0) / k * loo.map(|v| (v - mean).powi(2)).sum::<f64>()).sqrt()
}

/// Modified Bessel function of the first kind, order 0 (power series).
pub fn bessel_i0(x: f64) -> f64 {
    let half = x / 2.0;
    let mut term = 1.0;
    let mut sum = 1.0;
    for k in 1..200 {
        let f = half / k as f64;
        term *= f * f;
        sum += term;
        if term < sum * 1e-17 {
            break;
        }
    }
    sum
}

/// Least-squares fit of `y[n] ≈ a sin(w n) + b cos(w n)`, w = 2 pi f / rate,
/// over the samples `range` of `y`: the amplitude and the phase (radians,
/// positive = leads the sine). For tests and measurements of a tone.
pub fn fit_tone(y: &[f32], f_hz: f64, rate_hz: f64, range: std::ops::Range<usize>) -> (f64, f64) {
    let w = 2.0 * std::f64::consts::PI * f_hz / rate_hz;
    let end = range.end.min(y.len());
    let samples = (range.start..end).map(|n| (n, f64::from(y[n])));
    match fit_cos_sin(samples, w) {
        Some((c, s)) => (s.hypot(c), c.atan2(s)),
        None => (0.0, 0.0),
    }
}

/// Least-squares fit of `y ≈ a cos(w n) + b sin(w n)` (w in radians per
/// sample) to the samples `(n, y)`: `(a, b)`, or `None` when the samples
/// cannot separate the two (too few, or w a multiple of pi).
pub fn fit_cos_sin(samples: impl IntoIterator<Item = (usize, f64)>, w: f64) -> Option<(f64, f64)> {
    let (mut cc, mut ss, mut cs, mut yc, mut ys) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (n, v) in samples {
        let (s, c) = (w * n as f64).sin_cos();
        cc += c * c;
        ss += s * s;
        cs += c * s;
        yc += v * c;
        ys += v * s;
    }
    let det = cc * ss - cs * cs;
    // Relative test: a sum of rounding errors is not a fit.
    if det <= 1e-12 * (cc * ss).max(f64::MIN_POSITIVE) {
        return None;
    }
    Some(((yc * ss - ys * cs) / det, (ys * cc - yc * cs) / det))
}

/// Least-squares line through `pts` (x, y): the means of x and y and the
/// slope (0 where every x is the same); `None` for no points.
pub fn line_fit(pts: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    if pts.is_empty() {
        return None;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    Some((mx, my, if sxx > 0.0 { sxy / sxx } else { 0.0 }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Zeros of the length asked, whatever the length against a page (a
    /// page is 1024 f32 or 512 complex values).
    #[test]
    fn zeros_touched_are_zeros_of_the_length_asked() {
        for n in [0, 1, 1023, 1024, 1025, 5000, 70_001] {
            let v: Vec<f32> = zeros_touched(n);
            assert_eq!(v.len(), n);
            assert!(v.iter().all(|x| x.to_bits() == 0), "n {n}");
            let c: Vec<crate::pyramid::Complex32> = zeros_touched(n);
            assert_eq!(c.len(), n);
            assert!(c.iter().all(|x| x.re.to_bits() == 0 && x.im.to_bits() == 0));
        }
    }

    #[test]
    fn gcd_median_i0() {
        assert_eq!(gcd(48_000, 2200), 200);
        assert_eq!(gcd(7, 0), 7);
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(&mut []).is_nan());
        assert_eq!(bessel_i0(0.0), 1.0);
        assert!((bessel_i0(1.0) - 1.266_065_877_752_008_4).abs() < 1e-15);
    }
}
