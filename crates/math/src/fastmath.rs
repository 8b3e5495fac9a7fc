//! Fast, accurate elementary functions for per-pixel hot loops.

/// Coefficients of atan(x) ≈ x Σ a_k x^(2k) on [0, 1]
/// (Abramowitz & Stegun 4.4.47, |error| ≤ 2e-8).
/// Stored as f64 literals (the published digits) and rounded once to f32.
const ATAN_F64: [f64; 9] = [
    1.0,
    -0.333_331_452_8,
    0.199_935_508_5,
    -0.142_088_994_4,
    0.106_562_639_3,
    -0.075_289_640_0,
    0.042_909_613_8,
    -0.016_165_736_7,
    0.002_866_225_7,
];
/// The same coefficients rounded to f32 (shared with the SIMD kernels).
pub(crate) const ATAN_COEFFS: [f32; 9] = ATAN;
const ATAN: [f32; 9] = {
    let mut out = [0.0f32; 9];
    let mut i = 0;
    while i < 9 {
        out[i] = ATAN_F64[i] as f32;
        i += 1;
    }
    out
};

/// atan2(y, x) in (-π, π], within about 1e-6 rad of `f32::atan2` (f32
/// rounding dominates the polynomial's 2e-8), several times faster, and
/// branch-light enough to vectorise. atan2(0, 0) = 0.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (num, den) = if ay > ax { (ax, ay) } else { (ay, ax) };
    if den == 0.0 {
        return 0.0;
    }
    let t = num / den;
    let t2 = t * t;
    let mut p = ATAN[8];
    for &c in ATAN[..8].iter().rev() {
        p = p * t2 + c;
    }
    let mut r = t * p;
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        -r
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_std_atan2_everywhere() {
        let mut worst = 0.0f32;
        let n = 2000;
        for i in 0..n {
            let a = i as f32 / n as f32 * 2.0 * std::f32::consts::PI;
            for &r in &[1e-6f32, 0.3, 1.0, 7.5, 1e4] {
                let (y, x) = (r * a.sin(), r * a.cos());
                let e = (atan2(y, x) - y.atan2(x)).abs();
                // Across the ±π cut both answers are right.
                let e = e.min((e - 2.0 * std::f32::consts::PI).abs());
                worst = worst.max(e);
            }
        }
        assert!(worst < 2e-6, "worst error {worst}");
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert_eq!(atan2(0.0, 1.0), 0.0);
        assert!((atan2(1.0, 0.0) - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert!((atan2(0.0, -1.0) - std::f32::consts::PI).abs() < 1e-6);
    }
}
