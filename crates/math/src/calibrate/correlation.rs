//! Correlation of the recovery with the target: the global peak (with a
//! band-limited refinement) and local lags over time.

use super::signal::sample_at;

/// The window [`local_lags`] reads a lag on (about 0.2 s, a power of two
/// in 64..=1024 samples); it searches a quarter of it either way.
pub(super) fn local_window(fs: f64) -> usize {
    ((0.2 * fs) as usize).next_power_of_two().clamp(64, 1024)
}

/// Local lags (samples, `z[n] ≈ g T[n - lag]`) in windows over
/// `[0, end)`: `(centre, lag, correlation)` for windows that correlate.
pub(super) fn local_lags(
    z: &[f64],
    t_ext: &[f64],
    pre: usize,
    g: f64,
    end: usize,
    fs: f64,
) -> Vec<(f64, f64, f64)> {
    let w = local_window(fs);
    let m = (w / 4) as isize;
    let mut out = Vec::new();
    let mut s = 0usize;
    while s + w <= end {
        let seg = &z[s..s + w];
        let zz: f64 = seg.iter().map(|v| v * v).sum();
        let xc = |l: isize| -> f64 {
            let mut acc = 0.0;
            for (i, v) in seg.iter().enumerate() {
                let k = (s + i + pre) as isize - l;
                if k >= 0 && (k as usize) < t_ext.len() {
                    acc += v * t_ext[k as usize];
                }
            }
            acc * g.signum()
        };
        let vals: Vec<f64> = (-m..=m).map(xc).collect();
        let (bi, &bv) = vals
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap_or((0, &0.0));
        let tt: f64 = {
            let lag = bi as isize - m;
            (0..w)
                .map(|i| {
                    let k = (s + i + pre) as isize - lag;
                    if k >= 0 && (k as usize) < t_ext.len() {
                        t_ext[k as usize].powi(2)
                    } else {
                        0.0
                    }
                })
                .sum()
        };
        let rho = if zz > 0.0 && tt > 0.0 {
            bv / (zz * tt).sqrt()
        } else {
            0.0
        };
        if bi > 0 && bi + 1 < vals.len() && rho > 0.5 {
            let (a, b, c) = (vals[bi - 1], vals[bi], vals[bi + 1]);
            let den = a - 2.0 * b + c;
            let d = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
            out.push((s as f64 + w as f64 / 2.0, (bi as isize - m) as f64 + d, rho));
        }
        s += w / 2;
    }
    out
}

/// The first lag (samples, `1..=max`) at which `t` resembles itself
/// again: a local peak of at least 0.8 of its normalised autocorrelation
/// (of its magnitude with `either_sign`, where a delay of half a period
/// with the sign flipped is as good). A periodic reference's delay is only
/// known modulo that lag (refined between samples by a parabola).
pub(super) fn recurrence(t: &[f64], max: usize, either_sign: bool) -> Option<f64> {
    let acf = |l: usize| -> f64 { t.iter().zip(&t[l.min(t.len())..]).map(|(a, b)| a * b).sum() };
    let a0 = acf(0);
    if a0 <= 0.0 {
        return None;
    }
    let r: Vec<f64> = (0..=max + 1)
        .map(|l| {
            let v = acf(l) / a0;
            if either_sign {
                v.abs()
            } else {
                v
            }
        })
        .collect();
    let l = (1..=max).find(|&l| r[l] >= 0.8 && r[l] >= r[l - 1] && r[l] >= r[l + 1])?;
    let den = r[l - 1] - 2.0 * r[l] + r[l + 1];
    let d = if den < 0.0 {
        (0.5 * (r[l - 1] - r[l + 1]) / den).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    Some(l as f64 + d)
}

/// Normalised correlation of `z` with `t` at integer lags `-k..=k`
/// (`z[n] ≈ g t[n - l]`), the peak of its magnitude refined by a
/// parabola: `(lag, |value|)`.
pub(super) fn corr_peak(z: &[f64], t: &[f64], k: usize) -> (f64, f64) {
    let n = z.len().min(t.len());
    let zz: f64 = z[..n].iter().map(|v| v * v).sum();
    let tt: f64 = t[..n].iter().map(|v| v * v).sum();
    let norm = (zz * tt).sqrt().max(1e-300);
    let ki = k as isize;
    let vals: Vec<f64> = (-ki..=ki)
        .map(|l| {
            // Σ z[i] t[i - l] over i in k..n - k, as two slices.
            let end = n.saturating_sub(k).max(k);
            let zs = &z[k..end];
            let from = (k as isize - l) as usize;
            let ts = &t[from..from + zs.len()];
            let acc: f64 = zs.iter().zip(ts).map(|(a, b)| a * b).sum();
            acc / norm
        })
        .collect();
    let (bi, _) = vals
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap_or((0, &0.0));
    let sign = if vals.get(bi).is_some_and(|v| *v < 0.0) {
        -1.0
    } else {
        1.0
    };
    let vals: Vec<f64> = vals.iter().map(|v| v * sign).collect();
    let (bi, &bv) = vals
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((0, &0.0));
    // The correlation of band-limited signals is band-limited: refine the
    // peak by interpolating it, in twentieths of a sample. (A parabola
    // through integer lags misreads a correlation that oscillates every two
    // or three samples, as a chirp's does near fs/2, by up to a third of
    // its height depending on the fractional lag: enough to rank a wrong
    // rate above the right one.)
    let fine = sample_at(&vals, 1.0, (-20..=20).map(|j| bi as f64 + j as f64 / 20.0));
    let (j, &v) = fine
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((20, &bv));
    ((bi as isize - ki) as f64 + (j as f64 - 20.0) / 20.0, v)
}
