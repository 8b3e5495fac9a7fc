//! Line-delay calibration of a rolling-shutter camera from a video of a
//! known tone (a vibrating object) or a flickering light (thesis ch. 4.5
//! and its web page: "by measuring the slope of a line"; Meingast, Geyer &
//! Sastry 2005).
//!
//! Row y of frame n sees s(t_n + y d) = A cos(2π f0 (t_n + y d) + φ): down
//! a frame the tone's phase advances by 2π f0 d per row, a straight line in
//! y whose slope gives d. Rather than unwrap phases, each frame is fitted
//! by least squares with a_n cos(2π κ y) + b_n sin(2π κ y) + c_n (free
//! amplitude, phase and offset per frame) and the spatial frequency κ (cycles
//! per row) maximising the energy explained over all frames is taken, so
//! d = κ / f0. This is the maximum-likelihood slope for a sinusoid in white
//! noise, unbiased by the tone's negative-frequency image that a plain
//! periodogram peak suffers with only a few cycles per frame.
//! Identifiable while f0 d < 1/2 (one tone cycle spans more than two rows).

/// The result of [`estimate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Line delay, seconds.
    pub line_delay_s: f64,
    /// Fraction of the per-row signals' energy the fitted tone explains.
    pub explained: f64,
}

/// Energy of `frames` explained by the best per-frame fit of
/// {cos 2πκy, sin 2πκy, 1}.
fn explained_energy(frames: &[Vec<f64>], kappa: f64, cs: &mut Vec<(f64, f64)>) -> f64 {
    let rows = frames.first().map_or(0, Vec::len);
    cs.clear();
    cs.extend((0..rows).map(|y| {
        let a = 2.0 * std::f64::consts::PI * kappa * y as f64;
        (a.cos(), a.sin())
    }));
    // Gram matrix of the basis (same for every frame).
    let mut g = [[0.0f64; 3]; 3];
    for &(c, s) in cs.iter() {
        let v = [c, s, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                g[i][j] += v[i] * v[j];
            }
        }
    }
    // Singular (or nearly: the tone too slow to tell from the offset): nothing.
    let g = nalgebra::Matrix3::from_fn(|i, j| g[i][j]);
    let scale = g[(0, 0)].abs().max(g[(1, 1)].abs()).max(g[(2, 2)].abs());
    let det = g.determinant();
    if !(det.is_finite() && det.abs() > 1e-12 * scale * scale * scale) {
        return 0.0;
    }
    let Some(inv) = g.lu().try_inverse() else {
        return 0.0;
    };
    let mut total = 0.0;
    for f in frames {
        let mut b = [0.0f64; 3];
        for (&x, &(c, s)) in f.iter().zip(cs.iter()) {
            b[0] += x * c;
            b[1] += x * s;
            b[2] += x;
        }
        // Projection energy b^T G^-1 b.
        for i in 0..3 {
            for j in 0..3 {
                total += b[i] * inv[(i, j)] * b[j];
            }
        }
    }
    total
}

/// Estimates the line delay from per-row signals `frames[n][y]` (all of one
/// length, each row's mean over frames removed) of a tone at `tone_hz`,
/// searching delays up to `max_line_delay_s` (the frame period over the
/// row count). None when there is too little to fit.
pub fn estimate(frames: &[Vec<f64>], tone_hz: f64, max_line_delay_s: f64) -> Option<Estimate> {
    let rows = frames.first().map_or(0, Vec::len);
    if rows < 8 || frames.iter().any(|f| f.len() != rows) {
        return None;
    }
    if !(tone_hz.is_finite() && tone_hz > 0.0 && max_line_delay_s > 0.0) {
        return None;
    }
    let hi = (tone_hz * max_line_delay_s).min(0.5);
    // Below a quarter cycle per frame the tone is indistinguishable from the offset.
    let lo = 0.25 / rows as f64;
    if hi <= lo {
        return None;
    }
    let step = 0.125 / rows as f64;
    let mut cs = Vec::with_capacity(rows);
    let n = ((hi - lo) / step).ceil() as usize + 1;
    let (mut best_k, mut best_e) = (lo, f64::NEG_INFINITY);
    for i in 0..n {
        let k = (lo + i as f64 * step).min(hi);
        let e = explained_energy(frames, k, &mut cs);
        if e > best_e {
            best_e = e;
            best_k = k;
        }
    }
    // Golden-section refinement within one grid step either side.
    let (mut a, mut b) = ((best_k - step).max(lo), (best_k + step).min(hi));
    let gr = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - gr * (b - a);
    let mut d = a + gr * (b - a);
    let (mut fc, mut fd) = (
        explained_energy(frames, c, &mut cs),
        explained_energy(frames, d, &mut cs),
    );
    for _ in 0..60 {
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - gr * (b - a);
            fc = explained_energy(frames, c, &mut cs);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + gr * (b - a);
            fd = explained_energy(frames, d, &mut cs);
        }
    }
    let k = 0.5 * (a + b);
    let e = explained_energy(frames, k, &mut cs);
    let total: f64 = frames.iter().flat_map(|f| f.iter()).map(|x| x * x).sum();
    Some(Estimate {
        line_delay_s: k / tone_hz,
        explained: if total > 0.0 { e / total } else { 0.0 },
    })
}

/// Removes each row's mean over frames (the static scene, fixed patterns).
pub fn remove_row_means(frames: &mut [Vec<f64>]) {
    let Some(rows) = frames.first().map(Vec::len) else {
        return;
    };
    let n = frames.len() as f64;
    for y in 0..rows {
        let m = frames
            .iter()
            .map(|f| f.get(y).copied().unwrap_or(0.0))
            .sum::<f64>()
            / n;
        for f in frames.iter_mut() {
            if let Some(v) = f.get_mut(y) {
                *v -= m;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Xoshiro256;

    #[test]
    fn recovers_the_slope_of_a_noisy_tone() {
        // 47 fps: not a divisor of the tone, so frames see different phases.
        let (f0, d, rows, fps) = (300.0, 21.7e-6, 400, 47.0);
        let mut rng = Xoshiro256::new(5);
        let mut frames: Vec<Vec<f64>> = (0..20)
            .map(|n| {
                (0..rows)
                    .map(|y| {
                        let t = n as f64 / fps + y as f64 * d;
                        (2.0 * std::f64::consts::PI * f0 * t).sin() + (rng.next_f64() - 0.5)
                    })
                    .collect()
            })
            .collect();
        remove_row_means(&mut frames);
        let e = estimate(&frames, f0, 1.0 / (fps * rows as f64)).unwrap();
        assert!((e.line_delay_s / d - 1.0).abs() < 0.01, "{e:?}");
        assert!(e.explained > 0.5, "{e:?}");
    }

    #[test]
    fn too_little_data_is_none() {
        assert!(estimate(&[], 100.0, 1e-5).is_none());
        assert!(estimate(&[vec![0.0; 4]], 100.0, 1e-5).is_none());
        assert!(estimate(&[vec![0.0; 100]], 0.0, 1e-5).is_none());
    }
}
