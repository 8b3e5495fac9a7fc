//! Deterministic elementary functions.
//!
//! The platform `libm` behind `f64::exp`, `ln`, `sin`, ... may differ in the
//! last bit between targets and library versions, which would make rendered
//! frames differ bit-wise across machines. Everything the forward model
//! computes goes through these instead: they use only IEEE-754 basic
//! operations (`+ - * /`, `sqrt`, `floor`, `round`, bit manipulation), which
//! are correctly rounded everywhere, and no fused multiply-add. Accuracy is a
//! few ulps over the ranges used here (checked against `std` in the tests).

/// ln 2 split for Cody–Waite reduction (fdlibm): `LN2_HI` has trailing zero
/// bits, so `k * LN2_HI` is exact for |k| < 2^11.
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000); // 6.93147180369123816490e-01
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76); // 1.90821492927058770002e-10
const INV_LN2: f64 = std::f64::consts::LOG2_E;
const SQRT2: f64 = std::f64::consts::SQRT_2;
const TWO_PI: f64 = std::f64::consts::TAU;

/// 2^k as an f64 for -1022 <= k <= 1023.
fn pow2i(k: i64) -> f64 {
    f64::from_bits(((k + 1023) as u64) << 52)
}

/// x * 2^k without overflow in the intermediate steps.
fn ldexp(x: f64, k: i64) -> f64 {
    if k > 1023 {
        x * pow2i(1023) * pow2i((k - 1023).min(1023))
    } else if k < -1022 {
        x * pow2i(-1022) * pow2i((k + 1022).max(-1022))
    } else {
        x * pow2i(k)
    }
}

/// e^x.
pub fn exp(x: f64) -> f64 {
    exp_many(&[x])[0]
}

/// e^x of `N` values side by side, each by the same operations whatever
/// `N` (the same bits as [`exp`]): the series' steps run in vector lanes.
/// Cody–Waite reduction by ln 2 to |r| <= ~0.3466, then the Taylor series
/// to r^14 (truncation error < 1e-18).
pub fn exp_many<const N: usize>(x: &[f64; N]) -> [f64; N] {
    let mut k = [0.0f64; N];
    let mut r = [0.0f64; N];
    for ((k, r), &x) in k.iter_mut().zip(&mut r).zip(x) {
        // Outside [-745.2, 709.8] (or NaN) the value is set below; a finite
        // stand-in keeps the lanes' arithmetic plain.
        let x = if (-745.2..=709.8).contains(&x) {
            x
        } else {
            0.0
        };
        *k = round_half_away(x * INV_LN2);
        *r = (x - *k * LN2_HI) - *k * LN2_LO;
    }
    let mut p = [EXP_C[14]; N];
    for &c in EXP_C[..14].iter().rev() {
        for (p, &r) in p.iter_mut().zip(&r) {
            *p = *p * r + c;
        }
    }
    let mut out = [0.0f64; N];
    for (((o, &p), &k), &x) in out.iter_mut().zip(&p).zip(&k).zip(x) {
        *o = if x.is_nan() {
            x
        } else if x > 709.8 {
            f64::INFINITY
        } else if x < -745.2 {
            0.0
        } else {
            ldexp(p, k as i64)
        };
    }
    out
}

/// `v.round()` (halves away from zero) for |v| < 2^52, without a call: the
/// value less its integer part is exact there.
fn round_half_away(v: f64) -> f64 {
    let t = v as i64 as f64;
    let d = v - t;
    if d >= 0.5 {
        t + 1.0
    } else if d <= -0.5 {
        t - 1.0
    } else {
        t
    }
}

/// The series of [`exp`]: 1/n! for n = 0..=14.
const EXP_C: [f64; 15] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
    1.0 / 6_227_020_800.0,
    1.0 / 87_178_291_200.0,
];

/// Natural logarithm; NaN for x < 0, -inf for 0.
pub fn ln(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return f64::NEG_INFINITY;
    }
    if x.is_infinite() {
        return x;
    }
    let mut x = x;
    let mut e: i64 = 0;
    if x < f64::MIN_POSITIVE {
        x *= pow2i(54);
        e -= 54;
    }
    let bits = x.to_bits();
    e += ((bits >> 52) & 0x7ff) as i64 - 1023;
    let mut m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | (1023u64 << 52)); // [1, 2)
    if m > SQRT2 {
        m *= 0.5;
        e += 1;
    }
    // ln m = 2 atanh(s), s = (m-1)/(m+1), |s| <= 0.1716.
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let mut p = 1.0 / 23.0;
    let mut k = 21.0;
    while k > 0.0 {
        p = p * s2 + 1.0 / k;
        k -= 2.0;
    }
    let lnm = 2.0 * s * p;
    let ef = e as f64;
    ef * LN2_HI + (ef * LN2_LO + lnm)
}

/// (sin 2πu, cos 2πu): the angle is given in turns, which keeps the range
/// reduction exact for the large phases of long signals.
pub fn sin_cos_turns(u: f64) -> (f64, f64) {
    if !u.is_finite() {
        return (f64::NAN, f64::NAN);
    }
    let u = u - u.round(); // [-0.5, 0.5], exact
    let q = (u * 4.0).round(); // quadrant -2..=2
    let r = u - q * 0.25; // [-1/8, 1/8], exact
    let th = r * TWO_PI; // |th| <= π/4
    let t2 = th * th;
    // Taylor series; truncation error < 1e-17 for |th| <= π/4.
    const S: [f64; 9] = [
        1.0,
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
        1.0 / 6_227_020_800.0,
        -1.0 / 1_307_674_368_000.0,
        1.0 / 355_687_428_096_000.0,
    ];
    const CC: [f64; 9] = [
        1.0,
        -1.0 / 2.0,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
        -1.0 / 87_178_291_200.0,
        1.0 / 20_922_789_888_000.0,
    ];
    let mut ps = S[8];
    let mut pc = CC[8];
    for i in (0..8).rev() {
        ps = ps * t2 + S[i];
        pc = pc * t2 + CC[i];
    }
    let s = th * ps;
    let c = pc;
    // +0.0 turns a -0.0 into +0.0 so exact axis directions stay clean.
    match (q as i64).rem_euclid(4) {
        0 => (s + 0.0, c + 0.0),
        1 => (c + 0.0, -s + 0.0),
        2 => (-s + 0.0, -c + 0.0),
        _ => (-c + 0.0, s + 0.0),
    }
}

/// sin 2πu (u in turns).
pub fn sin_turns(u: f64) -> f64 {
    sin_cos_turns(u).0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Many values at once give each one's own `exp` (the value alone), to
    /// the bit: over the range, at its ends and beyond, halves of ln 2
    /// (where the reduction rounds), zeros and NaN.
    #[test]
    fn exp_of_many_values_is_each_ones_exp() {
        let mut rng = crate::rng::Xoshiro256::new(7);
        let mut xs: Vec<f64> = (0..4000).map(|_| (rng.next_f64() - 0.5) * 1600.0).collect();
        for k in -40..40 {
            let h = (k as f64 + 0.5) * std::f64::consts::LN_2;
            xs.extend([h, h.next_up(), h.next_down(), -h]);
        }
        xs.extend([0.0, -0.0, 709.8, 709.81, -745.2, -745.3, 1e300, -1e300]);
        xs.extend([f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -1e-300]);
        while !xs.len().is_multiple_of(8) {
            xs.push(1.0);
        }
        for chunk in xs.chunks_exact(8) {
            let chunk: [f64; 8] = chunk.try_into().unwrap();
            for (x, got) in chunk.iter().zip(exp_many(&chunk)) {
                assert_eq!(got.to_bits(), exp(*x).to_bits(), "{x}");
            }
        }
    }

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(1e-300)
    }

    #[test]
    fn ln2_split_is_exact() {
        assert_eq!(LN2_HI + LN2_LO, std::f64::consts::LN_2);
        assert_eq!(
            LN2_HI.to_bits() & 0x1f_ffff,
            0,
            "LN2_HI needs trailing zeros"
        );
    }

    #[test]
    fn exp_matches_std() {
        let mut worst = 0.0f64;
        let mut x = -700.0;
        while x < 700.0 {
            worst = worst.max(rel(exp(x), x.exp()));
            x += 0.137_713;
        }
        for x in [-1e-300, 0.0, 1e-10, -0.5, 0.5, 1.0, -1.0, 20.0] {
            worst = worst.max(rel(exp(x), x.exp()));
        }
        assert!(worst < 4e-16, "exp rel err {worst}");
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-800.0), 0.0);
        assert!(exp(800.0).is_infinite());
        assert!(exp(f64::NAN).is_nan());
        assert!(exp(-740.0) > 0.0); // subnormal range
    }

    #[test]
    fn ln_matches_std() {
        let mut worst = 0.0f64;
        let mut x = 1e-300;
        while x < 1e300 {
            let d = (ln(x) - x.ln()).abs() / x.ln().abs().max(1.0);
            worst = worst.max(d);
            x *= 1.317_3;
        }
        let mut x = 0.5;
        while x < 2.0 {
            worst = worst.max((ln(x) - x.ln()).abs());
            x += 0.000_731;
        }
        assert!(worst < 4e-16, "ln err {worst}");
        assert_eq!(ln(1.0), 0.0);
        assert!(ln(-1.0).is_nan());
        assert_eq!(ln(0.0), f64::NEG_INFINITY);
        assert!((ln(4.9e-324) - 4.9e-324f64.ln()).abs() < 1e-12);
    }

    #[test]
    fn sin_cos_match_std() {
        let mut worst = 0.0f64;
        let mut u = -3.0;
        while u < 3.0 {
            let (s, c) = sin_cos_turns(u);
            let a = u * TWO_PI;
            worst = worst.max((s - a.sin()).abs()).max((c - a.cos()).abs());
            u += 0.000_917_3;
        }
        // The reference itself rounds `u * 2π` (~1e-15 at |u| = 3).
        assert!(worst < 6e-15, "sincos err {worst}");
        assert_eq!(sin_cos_turns(0.25), (1.0, 0.0));
        assert_eq!(sin_cos_turns(0.5), (0.0, -1.0));
        assert_eq!(sin_cos_turns(-0.25), (-1.0, 0.0));
        assert_eq!(sin_cos_turns(1.0), (0.0, 1.0));
        assert!(sin_turns(f64::NAN).is_nan());
    }
}
