//! Comparing a recovered signal with the ground truth the simulator knows.

/// SNR in dB of `est` against `truth`, after removing each one's mean and
/// fitting the best gain (the method's scale and sign are arbitrary):
/// 10 log10(|g t|^2 / |e - g t|^2).
pub fn snr_db_fit(truth: &[f64], est: &[f64]) -> f64 {
    let n = truth.len().min(est.len());
    if n == 0 {
        return f64::NAN;
    }
    let mt = truth[..n].iter().sum::<f64>() / n as f64;
    let me = est[..n].iter().sum::<f64>() / n as f64;
    let (mut tt, mut te) = (0.0, 0.0);
    for i in 0..n {
        let t = truth[i] - mt;
        tt += t * t;
        te += t * (est[i] - me);
    }
    if tt == 0.0 {
        return f64::NAN;
    }
    let g = te / tt;
    let (mut sig, mut err) = (0.0, 0.0);
    for i in 0..n {
        let s = g * (truth[i] - mt);
        sig += s * s;
        let d = (est[i] - me) - s;
        err += d * d;
    }
    10.0 * (sig / err.max(1e-300)).log10()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snr_of_scaled_copy_plus_known_noise() {
        let t: Vec<f64> = (0..1000).map(|i| (i as f64 * 0.1).sin()).collect();
        let e: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, v)| -3.0 * v + 5.0 + if i % 2 == 0 { 0.03 } else { -0.03 })
            .collect();
        // Signal power 9 * 0.5, noise power 0.03^2 (nearly orthogonal to the sine).
        let expect = 10.0 * (4.5f64 / 0.0009).log10();
        assert!(
            (snr_db_fit(&t, &e) - expect).abs() < 0.2,
            "{}",
            snr_db_fit(&t, &e)
        );
    }
}
