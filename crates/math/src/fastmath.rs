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
/// The same coefficients rounded to f32.
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
/// branch-free (every choice a select), so that a loop over pixels that
/// calls it vectorises. atan2(0, 0) = 0.
#[inline(always)]
pub fn atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let swap = ay > ax;
    let num = if swap { ax } else { ay };
    let den = if swap { ay } else { ax };
    let t = num / den;
    let t2 = t * t;
    let mut p = ATAN[8];
    for &c in ATAN[..8].iter().rev() {
        p = p * t2 + c;
    }
    let mut r = t * p;
    r = if swap { FRAC_PI_2 - r } else { r };
    r = if x < 0.0 { PI - r } else { r };
    r = if y < 0.0 { -r } else { r };
    if den == 0.0 {
        0.0
    } else {
        r
    }
}

/// (sin x, cos x), within 4e-7 of `f32::sin_cos` for |x| up to 200π
/// (3.6e-7 measured; 4.2e-7 up to 2000π, and beyond the f32 reduction
/// loses digits, as any f32 argument does): the argument reduced by multiples of π/2 (two-part
/// constant), then Taylor polynomials on [-π/4, π/4] (degree 7 and 8).
/// Branch-free, several times faster than libm's; vectorises.
#[inline(always)]
pub fn sin_cos(x: f32) -> (f32, f32) {
    use std::f32::consts::FRAC_2_PI;
    // π/2 as a short head (exact times small integers) and its tail.
    const PI_2_HI: f32 = 1.570_312_5;
    const PI_2_LO: f32 = 4.838_268e-4;
    // Round to nearest by adding and removing 1.5·2^23 (exact below 2^22;
    // `f32::round` is a library call without SSE4.1).
    const ROUND: f32 = 12_582_912.0;
    let t = x * FRAC_2_PI + ROUND;
    let q = t - ROUND;
    let r = (x - q * PI_2_HI) - q * PI_2_LO;
    let r2 = r * r;
    let s = r + r * r2 * (-1.0 / 6.0 + r2 * (1.0 / 120.0 + r2 * (-1.0 / 5040.0)));
    let c = 1.0 + r2 * (-0.5 + r2 * (1.0 / 24.0 + r2 * (-1.0 / 720.0 + r2 * (1.0 / 40320.0))));
    // Quadrant by bit operations (no branch: the quadrant of a phase near
    // zero flips at random): odd q swaps sin and cos, q = 2, 3 negate the
    // sine, q = 1, 2 the cosine.
    // The quadrant's integer from `t`'s bits: `t` lies in [2^23, 2^24),
    // where floats are one apart, so its bits less ROUND's are `q` (for
    // |q| < 2^22, every argument the reduction keeps digits of). `q as
    // i32` (saturating) would make the same bits, but its NaN and range
    // checks keep it from vectorising: it ran lane by lane.
    let qi = t.to_bits().wrapping_sub(ROUND.to_bits());
    let swap = 0u32.wrapping_sub(qi & 1);
    let (sb, cb) = (s.to_bits(), c.to_bits());
    let a = sb ^ ((sb ^ cb) & swap);
    let b = cb ^ ((sb ^ cb) & swap);
    (
        f32::from_bits(a ^ ((qi & 2) << 30)),
        f32::from_bits(b ^ ((qi.wrapping_add(1) & 2) << 30)),
    )
}

#[cfg(test)]
mod tests {
    /// The quadrant from the rounded value's bits equals the saturating
    /// conversion of the rounded value (the earlier code) bit for bit,
    /// over the range the reduction keeps digits of.
    #[test]
    fn sin_cos_quadrant_from_bits_equals_the_conversion() {
        use std::f32::consts::FRAC_2_PI;
        let mut n = 0;
        for i in -400_000..=400_000i32 {
            // Up to about 2^21 · π/2 in steps that reach every quadrant.
            let x = i as f32 * 8.237 + (i % 7) as f32 * 0.31;
            let q = (x * FRAC_2_PI + 12_582_912.0) - 12_582_912.0;
            let want = q as i32 as u32;
            let t = x * FRAC_2_PI + 12_582_912.0;
            assert_eq!(
                t.to_bits().wrapping_sub(12_582_912.0f32.to_bits()),
                want,
                "x {x}"
            );
            n += 1;
        }
        assert_eq!(n, 800_001);
    }

    #[test]
    fn sin_cos_matches_libm() {
        let mut worst = 0.0f32;
        for i in -200_000..=200_000 {
            let x = i as f32 * 1e-3 * std::f32::consts::PI;
            let (s, c) = super::sin_cos(x);
            let (s0, c0) = x.sin_cos();
            worst = worst.max((s - s0).abs()).max((c - c0).abs());
        }
        eprintln!("sin_cos: worst {worst:e} against libm for |x| <= 200π");
        assert!(worst < 4e-7, "worst {worst}");
        for x in [-10.0f32, -3.0, -1.0, -0.3, 0.0, 1e-8, 0.5, 2.0, 7.0] {
            let ((s, c), (s0, c0)) = (super::sin_cos(x), x.sin_cos());
            assert!((s - s0).abs() < 4e-7 && (c - c0).abs() < 4e-7, "{x}");
        }
        let (s, c) = super::sin_cos(f32::NAN);
        assert!(s.is_nan() && c.is_nan());
    }

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
