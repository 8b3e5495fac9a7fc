use super::super::tests::{alloc_count, fft2, noise, texture, Texture};
use super::super::MAX_SCALES;
use super::*;
use proptest::prelude::*;
use rustfft::num_complex::Complex64;

fn rel_l2(a: &[f32], b: &[f32]) -> f64 {
    let num: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum();
    let den: f64 = b.iter().map(|y| f64::from(*y).powi(2)).sum();
    (num / den.max(1e-300)).sqrt()
}

fn roundtrip(w: usize, h: usize, scales: usize, k: usize, img: &[f32]) -> f64 {
    let mut p = ComplexSteerablePyramid::new(w, h, scales, k).unwrap();
    let mut c = p.alloc_coeffs();
    p.analyze(img, &mut c).unwrap();
    let mut out = vec![0.0f32; w * h];
    p.synthesize(&c, &mut out).unwrap();
    rel_l2(&out, img)
}

#[test]
fn reconstruction_is_tight() {
    let cases = [
        (96, 64, 4, 2),
        (100, 75, 4, 2),
        (64, 64, 4, 4),
        (100, 75, 3, 3),
        (33, 17, 3, 1),
        (256, 256, 5, 2),
    ];
    for (i, &(w, h, s, k)) in cases.iter().enumerate() {
        for (j, kind) in [Texture::BandLimited, Texture::Natural]
            .into_iter()
            .enumerate()
        {
            let img = texture(w, h, 7 + i as u64 * 10 + j as u64, kind, 0.0, 0.0);
            let e = roundtrip(w, h, s, k, &img);
            println!("CSP reconstruction {w}x{h} S={s} K={k} {kind:?}: rel L2 error {e:.2e}");
            assert!(e < 1e-4, "{w}x{h} S={s} K={k} {kind:?}: {e}");
        }
        let img = noise(w * h, 99 + i as u64);
        let e = roundtrip(w, h, s, k, &img);
        println!("CSP reconstruction {w}x{h} S={s} K={k} white noise: rel L2 error {e:.2e}");
        assert!(e < 1e-4, "{w}x{h} noise: {e}");
    }
}

#[test]
fn tiny_and_odd_sizes_do_not_panic_and_reconstruct() {
    for &(w, h) in &[(1, 1), (3, 7), (1, 5), (5, 1), (2, 2), (2, 3), (7, 3)] {
        for s in [1, 4, MAX_SCALES] {
            for k in [1, 2, 5] {
                let img = noise(w * h, (w * 31 + h) as u64);
                let e = roundtrip(w, h, s, k, &img);
                assert!(e < 1e-4, "{w}x{h} S={s} K={k}: {e}");
            }
        }
    }
}

#[test]
fn bad_arguments_are_errors() {
    assert!(matches!(
        ComplexSteerablePyramid::new(0, 5, 4, 2),
        Err(PyramidError::InvalidSize { .. })
    ));
    assert!(matches!(
        ComplexSteerablePyramid::new(5, 0, 4, 2),
        Err(PyramidError::InvalidSize { .. })
    ));
    assert!(matches!(
        ComplexSteerablePyramid::new(usize::MAX, 2, 4, 2),
        Err(PyramidError::InvalidSize { .. })
    ));
    assert_eq!(
        ComplexSteerablePyramid::new(8, 8, 0, 2).unwrap_err(),
        PyramidError::InvalidScales(0)
    );
    assert_eq!(
        ComplexSteerablePyramid::new(8, 8, 2, 0).unwrap_err(),
        PyramidError::InvalidOrientations(0)
    );
    let mut p = ComplexSteerablePyramid::new(8, 6, 2, 2).unwrap();
    let mut c = p.alloc_coeffs();
    assert_eq!(
        p.analyze(&[0.0; 47], &mut c).unwrap_err(),
        PyramidError::LengthMismatch {
            expected: 48,
            got: 47
        }
    );
    let other = ComplexSteerablePyramid::new(6, 8, 2, 2).unwrap();
    let mut c2 = other.alloc_coeffs();
    assert_eq!(
        p.analyze(&[0.0; 48], &mut c2).unwrap_err(),
        PyramidError::LayoutMismatch
    );
    let mut out = vec![0.0; 10];
    assert!(p.synthesize(&c, &mut out).is_err());
    p.analyze(&[1.0; 48], &mut c).unwrap();
    let mut a = vec![0.0; 3];
    assert!(c.amplitude_into(0, &mut a).is_err());
    assert!(c.phase_into(99, &mut a).is_err());
    assert!(c.band(99).is_none());
    assert_eq!(c.band_index(1, 1), Some(3));
    assert_eq!(c.band_index(2, 0), None);
}

#[test]
fn tight_frame_identity() {
    for &(w, h) in &[(16, 16), (33, 17), (100, 75), (64, 48), (1, 1), (2, 5)] {
        for k in 1..=4 {
            let p = ComplexSteerablePyramid::new(w, h, 4, k).unwrap();
            let r = p.tight_frame_response();
            let worst = r.iter().map(|v| (v - 1.0).abs()).fold(0.0, f64::max);
            assert!(worst < 2e-6, "{w}x{h} K={k}: max |sum - 1| = {worst}");
        }
    }
    // The band masks alone are not trivially 1: the high-pass residual
    // and the bands overlap in the transition r in [1/2, 1].
    let p = ComplexSteerablePyramid::new(64, 64, 4, 2).unwrap();
    assert!(p.hi_mask.iter().any(|&m| m > 0.1 && m < 0.9));
}

// ----- slow reference: direct DFT, masks from independent formulas -----

struct RefCsp {
    bands: Vec<Vec<Complex64>>,
    highpass: Vec<f64>,
    lowpass: Vec<f64>,
}

fn ref_signed(i: usize, n: usize) -> i64 {
    // Signed index by the "centred crop" rule: [-floor(n/2), ceil(n/2)-1].
    let half_up = n.div_ceil(2) as i64;
    let i = i as i64;
    if i < half_up {
        i
    } else {
        i - n as i64
    }
}

/// (hi, lo) of a raised cosine whose transition spans `[edge/2, edge]`.
fn ref_pair(r: f64, edge: f64) -> (f64, f64) {
    let hi = if r >= edge {
        1.0
    } else if r <= edge / 2.0 {
        0.0
    } else {
        (std::f64::consts::FRAC_PI_2 * (edge / r).log2()).cos()
    };
    (hi, (1.0 - hi * hi).max(0.0).sqrt())
}

fn ref_angular(ux: f64, uy: f64, b: usize, k: usize) -> f64 {
    use std::f64::consts::PI;
    if ux == 0.0 && uy == 0.0 {
        return 0.0;
    }
    let theta = PI * b as f64 / k as f64;
    let mut a = uy.atan2(ux) - theta;
    while a > PI {
        a -= 2.0 * PI;
    }
    while a <= -PI {
        a += 2.0 * PI;
    }
    let n = k - 1;
    let fact = |m: usize| (1..=m).map(|i| i as f64).product::<f64>();
    let c = 2f64.powi(2 * n as i32) * fact(n).powi(2) / (k as f64 * fact(2 * n));
    if a.abs() < PI / 2.0 - 1e-12 {
        2.0 * c.sqrt() * a.cos().powi(n as i32)
    } else {
        0.0
    }
}

fn reference_csp(img: &[f32], w: usize, h: usize, scales: usize, k: usize) -> RefCsp {
    use std::f64::consts::PI;
    let e = |num: i64, pos: usize, n: usize, sign: f64| {
        Complex64::from_polar(
            1.0,
            sign * 2.0 * PI * (num as f64) * (pos as f64) / n as f64,
        )
    };
    // Direct DFT of the image, indexed by storage index (kx mod w).
    let mut f = vec![Complex64::default(); w * h];
    for ky in 0..h {
        for kx in 0..w {
            let mut acc = Complex64::default();
            for y in 0..h {
                for x in 0..w {
                    acc += f64::from(img[y * w + x])
                        * e(kx as i64, x, w, -1.0)
                        * e(ky as i64, y, h, -1.0);
                }
            }
            f[ky * w + kx] = acc;
        }
    }
    let at = |kx: i64, ky: i64| {
        f[ky.rem_euclid(h as i64) as usize * w + kx.rem_euclid(w as i64) as usize]
    };
    let norm = 1.0 / (w * h) as f64;
    // Inverse direct DFT of a masked crop onto a gw x gh grid.
    let synth = |gw: usize, gh: usize, mask: &dyn Fn(f64, f64) -> f64| -> Vec<Complex64> {
        let mut out = vec![Complex64::default(); gw * gh];
        for yp in 0..gh {
            for xp in 0..gw {
                let mut acc = Complex64::default();
                for j in 0..gh {
                    let ky = ref_signed(j, gh);
                    for i in 0..gw {
                        let kx = ref_signed(i, gw);
                        let ux = 2.0 * kx as f64 / w as f64;
                        let uy = 2.0 * ky as f64 / h as f64;
                        let m = mask(ux, uy);
                        if m != 0.0 {
                            acc += at(kx, ky) * m * e(kx, xp, gw, 1.0) * e(ky, yp, gh, 1.0);
                        }
                    }
                }
                out[yp * gw + xp] = acc * norm;
            }
        }
        out
    };
    let lowchain = |r: f64, s: usize| -> f64 {
        // L0 (edge 1), then the low parts of scales 0..s (edges 2^-(j+1)).
        let mut v = ref_pair(r, 1.0).1;
        for j in 0..s {
            v *= ref_pair(r, 0.5f64.powi(j as i32 + 1)).1;
        }
        v
    };
    let mut bands = Vec::new();
    let (mut gw, mut gh) = (w, h);
    for s in 0..scales {
        for b in 0..k {
            let mask = |ux: f64, uy: f64| {
                let r = ux.hypot(uy);
                lowchain(r, s)
                    * ref_pair(r, 0.5f64.powi(s as i32 + 1)).0
                    * ref_angular(ux, uy, b, k)
            };
            bands.push(synth(gw, gh, &mask));
        }
        gw = gw.div_ceil(2);
        gh = gh.div_ceil(2);
    }
    let lowpass = synth(gw, gh, &|ux: f64, uy: f64| lowchain(ux.hypot(uy), scales))
        .iter()
        .map(|c| c.re)
        .collect();
    let highpass = synth(w, h, &|ux: f64, uy: f64| ref_pair(ux.hypot(uy), 1.0).0)
        .iter()
        .map(|c| c.re)
        .collect();
    RefCsp {
        bands,
        highpass,
        lowpass,
    }
}

fn max_abs_err<A: Copy, B: Copy>(
    a: &[A],
    b: &[B],
    d: impl Fn(A, B) -> f64,
    m: impl Fn(B) -> f64,
) -> (f64, f64) {
    let err = a.iter().zip(b).map(|(x, y)| d(*x, *y)).fold(0.0, f64::max);
    let mag = b.iter().map(|y| m(*y)).fold(0.0, f64::max);
    (err, mag)
}

#[test]
fn fast_path_matches_direct_dft_reference() {
    for &(w, h, s, k, seed) in &[
        (16, 16, 3, 2, 1u64),
        (32, 24, 3, 4, 2),
        (15, 9, 2, 2, 3),
        (7, 12, 3, 3, 4),
    ] {
        let img = noise(w * h, seed);
        let r = reference_csp(&img, w, h, s, k);
        let mut p = ComplexSteerablePyramid::new(w, h, s, k).unwrap();
        let mut c = p.alloc_coeffs();
        p.analyze(&img, &mut c).unwrap();
        assert_eq!(c.num_bands(), r.bands.len());
        let mut nonempty = 0;
        for (i, (band, rb)) in c.bands().iter().zip(&r.bands).enumerate() {
            assert_eq!(band.data().len(), rb.len());
            let (err, mag) = max_abs_err(
                band.data(),
                rb,
                |a, b| (Complex64::new(a.re.into(), a.im.into()) - b).norm(),
                |b| b.norm(),
            );
            // Some coarse bands of tiny grids are legitimately empty
            // (e.g. a 2-pixel-wide grid has no positive x frequency).
            nonempty += usize::from(mag > 1e-3);
            assert!(
                err <= 1e-4 * mag + 1e-7,
                "{w}x{h} band {i}: err {err:e} vs max {mag:e}"
            );
        }
        assert!(
            nonempty * 4 >= c.num_bands() * 3,
            "{w}x{h}: {nonempty} non-empty bands"
        );
        let (err, mag) = max_abs_err(
            c.highpass(),
            &r.highpass,
            |a, b| (f64::from(a) - b).abs(),
            f64::abs,
        );
        assert!(err <= 1e-4 * mag, "{w}x{h} highpass: {err:e} vs {mag:e}");
        let (err, mag) = max_abs_err(
            c.lowpass(),
            &r.lowpass,
            |a, b| (f64::from(a) - b).abs(),
            f64::abs,
        );
        assert!(
            err <= 1e-4 * mag.max(1e-6),
            "{w}x{h} lowpass: {err:e} vs {mag:e}"
        );
    }
}

#[test]
fn band_metadata() {
    let p = ComplexSteerablePyramid::new(100, 75, 4, 2).unwrap();
    let c = p.alloc_coeffs();
    let sizes: Vec<(usize, usize)> = c.bands().iter().map(|b| (b.width(), b.height())).collect();
    assert_eq!(
        sizes,
        vec![
            (100, 75),
            (100, 75),
            (50, 38),
            (50, 38),
            (25, 19),
            (25, 19),
            (13, 10),
            (13, 10)
        ]
    );
    assert_eq!(c.lowpass_size(), (7, 5));
    let b = c.band(3).unwrap();
    assert_eq!(b.scale(), 1);
    assert!((b.angle() - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
    assert!((b.info().step_x - 2.0).abs() < 1e-6);
    assert!((b.info().centre_frequency - 0.125).abs() < 1e-7);
}

/// Per band: amplitude-weighted mean local phase change / (2π · the
/// band's |coefficient|²-weighted mean x frequency) = shift estimate.
pub(crate) struct ShiftRow {
    pub band: usize,
    pub angle_deg: f32,
    pub fx: f64,
    pub nominal_fx: f64,
    pub d_est: f64,
    /// Same estimate with plain `A(t0)²` weights.
    pub d_est_a0: f64,
}

/// |B(k)|²-weighted mean x frequency (cycles per input pixel) of a
/// complex band on its grid.
fn mean_fx(data: &[Complex32], gw: usize, gh: usize, step_x: f64) -> f64 {
    let mut spec: Vec<Complex64> = data
        .iter()
        .map(|c| Complex64::new(c.re.into(), c.im.into()))
        .collect();
    fft2(&mut spec, gw, gh, false);
    let (mut num, mut den) = (0.0, 0.0);
    for y in 0..gh {
        for x in 0..gw {
            let p = spec[y * gw + x].norm_sqr();
            num += p * signed_index(x, gw) as f64 / gw as f64 / step_x;
            den += p;
        }
    }
    num / den
}

fn csp_shift_rows(w: usize, h: usize, k: usize, d: f64, seed: u64) -> Vec<ShiftRow> {
    let img0 = texture(w, h, seed, Texture::Natural, 0.0, 0.0);
    let img1 = texture(w, h, seed, Texture::Natural, d, 0.0);
    let mut p = ComplexSteerablePyramid::new(w, h, 4, k).unwrap();
    let (mut c0, mut c1) = (p.alloc_coeffs(), p.alloc_coeffs());
    p.analyze(&img0, &mut c0).unwrap();
    p.analyze(&img1, &mut c1).unwrap();
    let mut rows = Vec::new();
    for i in 0..c0.num_bands() {
        let info = c0.band_info(i).unwrap().clone();
        let n = info.len();
        let (mut dphi, mut a0, mut a1) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        c1.phase_delta_into(&c0, i, &mut dphi).unwrap();
        c0.amplitude_into(i, &mut a0).unwrap();
        c1.amplitude_into(i, &mut a1).unwrap();
        // A² weighting (Eq. 3.3), with A² taken as A(t0)·A(t) so that the
        // estimate is symmetric in the two frames.
        let (mut num, mut den) = (0.0f64, 0.0f64);
        let (mut num0, mut den0) = (0.0f64, 0.0f64);
        for j in 0..n {
            let wgt = f64::from(a0[j]) * f64::from(a1[j]);
            num += wgt * f64::from(dphi[j]);
            den += wgt;
            let w0 = f64::from(a0[j]).powi(2);
            num0 += w0 * f64::from(dphi[j]);
            den0 += w0;
        }
        let fx = mean_fx(
            c0.band(i).unwrap().data(),
            info.width,
            info.height,
            info.step_x.into(),
        );
        let mean_dphi = num / den;
        rows.push(ShiftRow {
            band: i,
            angle_deg: info.angle.to_degrees(),
            fx,
            nominal_fx: f64::from(info.centre_frequency) * f64::from(info.angle).cos(),
            d_est: -mean_dphi / (2.0 * std::f64::consts::PI * fx),
            d_est_a0: -(num0 / den0) / (2.0 * std::f64::consts::PI * fx),
        });
    }
    rows
}

#[test]
fn local_phase_tracks_subpixel_translation() {
    for &(w, h, k) in &[(128, 128, 2), (128, 128, 4), (100, 75, 2)] {
        for &d in &[0.05, 0.2, 0.5] {
            let rows = csp_shift_rows(w, h, k, d, 1234);
            let mut tested = 0;
            for r in &rows {
                let has_x = r.fx.abs() > 0.3 * r.nominal_fx.abs().max(0.25 * 0.25f64.powi(3));
                let err = r.d_est / d - 1.0;
                let err0 = r.d_est_a0 / d - 1.0;
                println!(
                    "CSP {w}x{h} K={k} d={d}: band {} ({:5.1} deg) mean fx {:.4} c/px (f_c cos θ = {:.4}) -> d_est {:.4} ({:+.3}%), A0²-weighted {:+.3}%",
                    r.band,
                    r.angle_deg,
                    r.fx,
                    r.nominal_fx,
                    r.d_est,
                    100.0 * err,
                    100.0 * err0
                );
                if has_x && r.angle_deg.to_radians().cos().abs() > 0.1 {
                    tested += 1;
                    assert!(
                        err.abs() < 0.02,
                        "{w}x{h} K={k} d={d} band {}: {:+.3}%",
                        r.band,
                        100.0 * err
                    );
                    assert!(
                        err0.abs() < 0.02,
                        "{w}x{h} K={k} d={d} band {} (A0²): {:+.3}%",
                        r.band,
                        100.0 * err0
                    );
                }
            }
            assert!(tested >= 4, "too few bands tested: {tested}");
        }
    }
}

#[test]
fn analyze_and_synthesize_allocate_nothing() {
    let (w, h) = (100, 75);
    let img = texture(w, h, 5, Texture::Natural, 0.0, 0.0);
    let mut p = ComplexSteerablePyramid::new(w, h, 4, 2).unwrap();
    let mut c = p.alloc_coeffs();
    let mut out = vec![0.0f32; w * h];
    let caps: Vec<usize> = c.bands().iter().map(|b| b.data.capacity()).collect();
    p.analyze(&img, &mut c).unwrap();
    p.synthesize(&c, &mut out).unwrap();
    let before = alloc_count::allocations();
    for _ in 0..5 {
        p.analyze(&img, &mut c).unwrap();
        p.synthesize(&c, &mut out).unwrap();
    }
    let after = alloc_count::allocations();
    assert_eq!(after - before, 0, "allocations per call");
    let caps2: Vec<usize> = c.bands().iter().map(|b| b.data.capacity()).collect();
    assert_eq!(caps, caps2);
}

#[test]
fn speed_report() {
    let (w, h) = (256, 256);
    let img = texture(w, h, 11, Texture::Natural, 0.0, 0.0);
    let mut p = ComplexSteerablePyramid::new(w, h, 4, 2).unwrap();
    let mut c = p.alloc_coeffs();
    let mut out = vec![0.0f32; w * h];
    let iters = if cfg!(debug_assertions) { 1 } else { 40 };
    p.analyze(&img, &mut c).unwrap();
    // Best of 9 batches: the machine is shared, the minimum is the cost.
    let best = |f: &mut dyn FnMut()| {
        (0..9)
            .map(|_| {
                let t = std::time::Instant::now();
                for _ in 0..iters {
                    f();
                }
                t.elapsed().as_secs_f64() / iters as f64
            })
            .fold(f64::INFINITY, f64::min)
    };
    let ta = best(&mut || p.analyze(&img, &mut c).unwrap());
    let ts = best(&mut || p.synthesize(&c, &mut out).unwrap());
    let mpix = (w * h) as f64 / 1e6;
    println!(
        "SPEED CSP 256x256 (4 scales, 2 orientations): analyze {:.3} ms = {:.1} Mpix/s, synthesize {:.3} ms = {:.1} Mpix/s{}",
        ta * 1e3,
        mpix / ta,
        ts * 1e3,
        mpix / ts,
        if cfg!(debug_assertions) { " (debug build)" } else { "" }
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn any_size_roundtrips(w in 1usize..40, h in 1usize..40, s in 1usize..7, k in 1usize..7, seed in 0u64..1000) {
        let img = noise(w * h, seed);
        let e = roundtrip(w, h, s, k, &img);
        prop_assert!(e < 1e-4, "{}x{} S={} K={}: {}", w, h, s, k, e);
    }
}

/// A part (orientations 2..4 of 4) holds and computes only its own bands:
/// their coefficients are the whole pyramid's, bit for bit; the others get
/// no storage, and the part cannot be widened to them.
#[test]
fn a_part_holds_only_its_bands_and_computes_them_as_the_whole_does() {
    let (w, h, scales, k) = (40, 36, 3, 4);
    let img = texture(w, h, 5, Texture::Natural, 0.0, 0.0);
    let mut whole = ComplexSteerablePyramid::new(w, h, scales, k).unwrap();
    let mut cw = whole.alloc_coeffs();
    whole.analyze(&img, &mut cw).unwrap();
    let mut part = ComplexSteerablePyramid::new_part(w, h, scales, k, 2..4).unwrap();
    part.set_residuals(false);
    part.set_orientations(0..k);
    let mut cp = part.alloc_coeffs();
    part.analyze(&img, &mut cp).unwrap();
    for (bi, (a, b)) in cw.bands.iter().zip(&cp.bands).enumerate() {
        if (2..4).contains(&(bi % k)) {
            assert!(part.band_active(bi), "band {bi}");
            assert!(a.data == b.data, "band {bi} differs from the whole's");
        } else {
            assert!(!part.band_active(bi), "band {bi} was widened to");
            assert!(b.data.is_empty(), "band {bi} has storage");
        }
    }
    // A whole pyramid's coefficients do not fit a part's, nor the reverse.
    assert!(whole.analyze(&img, &mut cp).is_err());
}

/// Compact bands ([`ComplexSteerablePyramid::new_compact`]) are the full
/// bands at every second column (orientation 0) or row (orientation K/2),
/// to float rounding, at every scale, on even and odd sizes; the other
/// orientations' bands are the full ones; and the compact pyramid still
/// reconstructs the frame.
#[test]
fn compact_bands_are_the_full_bands_sampled_more_coarsely() {
    let cases = [
        (64, 48, 4, 2),
        (64, 64, 3, 4),
        (45, 38, 3, 2),
        (37, 29, 4, 3),
        (20, 21, 5, 1),
    ];
    for (i, &(w, h, scales, k)) in cases.iter().enumerate() {
        let img = texture(w, h, 11 + i as u64, Texture::Natural, 0.0, 0.0);
        let mut full = ComplexSteerablePyramid::new(w, h, scales, k).unwrap();
        let mut cf = full.alloc_coeffs();
        full.analyze(&img, &mut cf).unwrap();
        let mut comp = ComplexSteerablePyramid::new_compact(w, h, scales, k).unwrap();
        let mut cc = comp.alloc_coeffs();
        comp.analyze(&img, &mut cc).unwrap();
        let mut halved = 0;
        for (bi, (f, c)) in cf.bands.iter().zip(&cc.bands).enumerate() {
            let (o, (gw, gh)) = (bi % k, (f.width(), f.height()));
            let (sx, sy) = if o == 0 && gw >= 2 {
                (2, 1)
            } else if 2 * o == k && gh >= 2 {
                (1, 2)
            } else {
                (1, 1)
            };
            assert_eq!(
                (c.width(), c.height()),
                (gw.div_ceil(sx), gh.div_ceil(sy)),
                "{w}x{h} K={k} band {bi}"
            );
            if sx * sy > 1 {
                halved += 1;
            }
            // The compact step is the full one times 2 only where the
            // grid is even; on an odd grid the samples fall between.
            let exact_x = sx == 1 || gw % 2 == 0;
            let exact_y = sy == 1 || gh % 2 == 0;
            assert!(
                (c.info().step_x / f.info().step_x - (gw as f32 / c.width() as f32)).abs() < 1e-6
                    && (c.info().step_y / f.info().step_y - (gh as f32 / c.height() as f32)).abs()
                        < 1e-6,
                "{w}x{h} K={k} band {bi}: steps"
            );
            let peak = f.data().iter().map(|v| v.norm()).fold(0.0f32, f32::max);
            if exact_x && exact_y {
                for y in 0..c.height() {
                    for x in 0..c.width() {
                        let a = c.data()[y * c.width() + x];
                        let b = f.data()[y * sy * gw + x * sx];
                        assert!(
                            (a - b).norm() <= 1e-5 * peak.max(1e-6),
                            "{w}x{h} K={k} band {bi} ({x},{y}): {a} against {b}"
                        );
                    }
                }
            }
        }
        if k == 2 {
            // Both orientations' bands halved at every scale.
            assert_eq!(halved, 2 * scales, "{w}x{h} K={k}");
        }
        assert!(halved >= 1, "{w}x{h} K={k}: no band halved");
        let mut out = vec![0.0f32; w * h];
        comp.synthesize(&cc, &mut out).unwrap();
        let e = rel_l2(&out, &img);
        println!(
            "compact CSP {w}x{h} S={scales} K={k}: {halved} bands halved, reconstruction {e:.2e}"
        );
        assert!(e < 1e-4, "{w}x{h} S={scales} K={k}: {e}");
        // The full pyramid's coefficients do not fit the compact one's.
        assert!(comp.analyze(&img, &mut cf).is_err());
    }
}

/// What the `phase` stage reads from compact bands: the A²-weighted phase
/// change of a band under a sub-pixel shift, summed over its half grid, is
/// half the full grid's sum (the same band-limited image sampled half as
/// densely); and one region for all of a scale's orientations is refused,
/// since they no longer share a grid.
#[test]
fn compact_sums_are_half_the_full_sums() {
    let (w, h, scales, k) = (64, 64, 3, 2);
    let sums = |compact: bool| {
        let new = if compact {
            ComplexSteerablePyramid::new_compact
        } else {
            ComplexSteerablePyramid::new
        };
        let mut p = new(w, h, scales, k).unwrap();
        let (mut c0, mut c1) = (p.alloc_coeffs(), p.alloc_coeffs());
        p.analyze(&texture(w, h, 3, Texture::Natural, 0.0, 0.0), &mut c0)
            .unwrap();
        p.analyze(&texture(w, h, 3, Texture::Natural, 0.07, 0.05), &mut c1)
            .unwrap();
        let mut out = Vec::new();
        for bi in 0..c0.num_bands() {
            let b = c0.band(bi).unwrap();
            let wt: Vec<f32> = b.data().iter().map(|v| v.norm_sqr()).collect();
            out.push(
                c1.weighted_phase_delta_sum(&c0, bi, &wt, 0..b.height(), 0..b.width())
                    .unwrap(),
            );
        }
        let wts: Vec<Vec<f32>> = (0..k)
            .map(|o| vec![1.0; c0.band(o).unwrap().data().len()])
            .collect();
        let wts: Vec<&[f32]> = wts.iter().map(|v| &v[..]).collect();
        let refused = c1
            .scale_phase_delta_sums(&c0, 0, &wts, 0..1, 0..1, &mut [0.0; 2])
            .is_err();
        (out, refused)
    };
    let ((full, full_refused), (comp, comp_refused)) = (sums(false), sums(true));
    assert!(!full_refused && comp_refused);
    for (bi, (f, c)) in full.iter().zip(&comp).enumerate() {
        println!("band {bi}: full {f:.5e}, compact x2 {:.5e}", 2.0 * c);
        assert!(
            (2.0 * c / f - 1.0).abs() < 0.02,
            "band {bi}: full {f}, compact {c}"
        );
    }
}

/// Band-at-a-time analysis and synthesis (`stream_begin`, `stream_band`,
/// `stream_band_back`, `stream_end`, one buffer for every band) give the
/// bits of `analyze`, the same change of each band, then `synthesize`:
/// whole pyramids and parts (with and without the residuals), even and
/// odd sizes; a band of the wrong size or outside the part is refused.
#[test]
fn streamed_bands_give_the_bits_of_analyze_then_synthesize() {
    for (w, h, scales, k) in [
        (64usize, 48usize, 3usize, 4usize),
        (37, 29, 2, 3),
        (32, 32, 4, 8),
    ] {
        let img = noise(w * h, 17);
        for (part, residuals) in [(0..k, true), (0..k / 2, true), (k / 2..k, false)] {
            let change = |bi: usize, d: &mut [Complex32]| {
                let turn = Complex32::from_polar(1.0 + 0.1 * bi as f32, 0.2 * bi as f32);
                for (i, v) in d.iter_mut().enumerate() {
                    *v *= turn * (1.0 + 0.001 * (i % 5) as f32);
                }
            };
            let mut p = ComplexSteerablePyramid::new_part(w, h, scales, k, part.clone()).unwrap();
            p.set_residuals(residuals);
            let mut c = p.alloc_coeffs();
            p.analyze(&img, &mut c).unwrap();
            for bi in 0..c.num_bands() {
                if p.band_active(bi) {
                    change(bi, c.band_mut(bi).unwrap().data_mut());
                }
            }
            let mut want = vec![0.0f32; w * h];
            p.synthesize(&c, &mut want).unwrap();

            let mut q = ComplexSteerablePyramid::new_part(w, h, scales, k, part.clone()).unwrap();
            q.set_residuals(residuals);
            // The residuals only (the bands come through `buf`), and the
            // whole storage: both are taken.
            let mut c2 = if residuals {
                q.alloc_residuals()
            } else {
                q.alloc_coeffs()
            };
            let most = q.band_infos().iter().map(|b| b.len()).max().unwrap();
            let mut buf = vec![Complex32::default(); most];
            q.stream_begin(&img, &mut c2).unwrap();
            for (bi, b) in q.band_infos().to_vec().iter().enumerate() {
                if !q.band_active(bi) {
                    assert!(q.stream_band(bi, &mut buf[..b.len()]).is_err());
                    continue;
                }
                assert!(q.stream_band(bi, &mut buf[..b.len() - 1]).is_err());
                let d = &mut buf[..b.len()];
                q.stream_band(bi, d).unwrap();
                let got = c.band(bi).unwrap().data();
                change(bi, d);
                assert!(
                    got.iter().zip(d.iter()).all(|(x, y)| x == y),
                    "{w}x{h}, part {part:?}: band {bi} differs"
                );
                q.stream_band_back(bi, d).unwrap();
            }
            let mut out = vec![0.0f32; w * h];
            q.stream_end(&c2, &mut out).unwrap();
            // Whole-pyramid calls need the bands' storage.
            let mut bare = q.alloc_residuals();
            assert!(q.analyze(&img, &mut bare).is_err());
            assert!(q.synthesize(&bare, &mut vec![0.0; w * h]).is_err());
            assert!(
                out.iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{w}x{h}, part {part:?}, residuals {residuals}: the frames differ"
            );
        }
    }
}

/// [`gather`] and [`scatter_sym`] as they were, a bin at a time through
/// the row indices (the reference for the runs, and for the columns left
/// out).
fn gather_per_bin(
    spec: &[Complex32],
    h: usize,
    grid: &Grid,
    mask: &[f32],
    norm: f32,
) -> Vec<Complex32> {
    let gh = grid.h;
    let mut dst = vec![Complex32::default(); grid.w * gh];
    for kxp in 0..grid.w {
        let kx = grid.kx[kxp];
        for kyp in 0..gh {
            let m = mask[kxp * gh + kyp] * norm;
            dst[kxp * gh + kyp] = if kx >= 0 {
                spec[kx as usize * h + grid.uy_pos[kyp]] * m
            } else {
                spec[(-kx) as usize * h + grid.uy_neg[kyp]].conj() * m
            };
        }
    }
    dst
}

fn scatter_per_bin(
    src: &[Complex32],
    grid: &Grid,
    mask: &[f32],
    scale: f32,
    (w, h): (usize, usize),
    acc: &mut [Complex32],
) {
    let gh = grid.h;
    for kxp in 0..grid.w {
        let (px, nx) = (grid.ux_pos[kxp], grid.ux_neg[kxp]);
        for (x, conj) in [(px, false), (nx, true)] {
            if x > w / 2 {
                continue;
            }
            for kyp in 0..gh {
                let v = src[kxp * gh + kyp];
                let uy = if conj {
                    grid.uy_neg[kyp]
                } else {
                    grid.uy_pos[kyp]
                };
                let v = if conj { v.conj() } else { v };
                acc[x * h + uy] += v * (mask[kxp * gh + kyp] * scale);
            }
        }
    }
}

/// The runs of rows and the columns left out (orientation 0's half
/// plane) give the per-bin values: equal (`==`: a column left out is
/// +0 where the product with a zero mask may be -0) on every band of
/// full and compact pyramids, even and odd sizes; and the runs cover
/// each grid's rows once, in order.
#[test]
fn gather_and_scatter_by_runs_give_the_per_bin_values() {
    let mut checked_out = 0;
    for (w, h) in [(16, 16), (15, 9), (32, 20), (7, 33), (64, 64)] {
        for k in 1..=4 {
            for compact in [false, true] {
                let mut p = if compact {
                    ComplexSteerablePyramid::new_compact(w, h, 3, k).unwrap()
                } else {
                    ComplexSteerablePyramid::new(w, h, 3, k).unwrap()
                };
                let re = noise(p.spec.len(), (w * 100 + h + k) as u64);
                let im = noise(p.spec.len(), (w * 100 + h + k + 7) as u64);
                for (s, (a, b)) in p.spec.iter_mut().zip(re.iter().zip(&im)) {
                    *s = Complex32::new(*a, *b);
                }
                for g in &p.grids {
                    for (idx, runs) in [(&g.uy_pos, &g.pos_runs), (&g.uy_neg, &g.neg_runs)] {
                        let mut flat = Vec::new();
                        for r in runs {
                            for j in 0..r.len {
                                flat.push(if r.rev { r.src - j } else { r.src + j });
                            }
                        }
                        assert_eq!(&flat, idx);
                    }
                }
                for bi in 0..p.band_masks.len() {
                    let grid = &p.grids[p.band_grid[bi]];
                    let n = grid.w * grid.h;
                    let mask = &p.band_masks[bi];
                    let live = &p.band_live[bi];
                    let want = gather_per_bin(&p.spec, h, grid, mask, 0.25);
                    let mut got = vec![Complex32::new(9.0, 9.0); n];
                    gather(&p.spec, h, grid, (mask, 0.25), live, &mut got);
                    assert!(got == want, "{w}x{h} k {k} compact {compact} band {bi}");
                    let kept: usize = live.iter().map(|r| r.len()).sum();
                    checked_out += grid.w - kept;
                    let src: Vec<Complex32> = want.iter().map(|v| v * 3.0).collect();
                    let mut a = p.spec.clone();
                    let mut b = p.spec.clone();
                    scatter_per_bin(&src, grid, mask, 0.5, (w, h), &mut a);
                    scatter_sym(&src, (grid, live), mask, 0.5, (w, h), &mut b);
                    assert!(a == b, "scatter {w}x{h} k {k} compact {compact} band {bi}");
                }
            }
        }
    }
    // Orientation 0's half plane was left out somewhere (the test covers
    // the pruning, not only the runs).
    assert!(checked_out > 0);
}

#[test]
fn runs_split_rising_and_falling_rows() {
    assert_eq!(runs(&[]), vec![]);
    assert_eq!(
        runs(&[0, 1, 2, 13, 14, 15]),
        vec![
            Run {
                dst: 0,
                src: 0,
                len: 3,
                rev: false
            },
            Run {
                dst: 3,
                src: 13,
                len: 3,
                rev: false
            },
        ]
    );
    assert_eq!(
        runs(&[0, 15, 14, 13, 2, 1]),
        vec![
            Run {
                dst: 0,
                src: 0,
                len: 1,
                rev: false
            },
            Run {
                dst: 1,
                src: 15,
                len: 3,
                rev: true
            },
            Run {
                dst: 4,
                src: 2,
                len: 2,
                rev: true
            },
        ]
    );
    assert_eq!(
        live_columns(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 3.0], 2),
        vec![1..2, 3..4]
    );
}

/// The band masks as `build` made them until session 78, a bin at a
/// time: the low-pass chain, the scale's high-pass edge and the angular
/// mask each from the bin's frequency (every constant, `log2 r` and each
/// raised cosine's sine or cosine computed again at every bin and for
/// every orientation).
fn mask_per_bin(ux: f64, uy: f64, s: usize, theta: f64, orientations: usize) -> f32 {
    use std::f64::consts::PI;
    let r = ux.hypot(uy);
    let t = |p: f64| (p - r.log2()).clamp(0.0, 1.0);
    let radial_hi = |p: f64| {
        if r <= 0.0 {
            0.0
        } else {
            (0.5 * PI * t(p)).cos()
        }
    };
    let chain = chain_per_bin(r, s);
    let angular = {
        let order = orientations - 1;
        let mut fact = 1.0f64;
        for i in 1..=order {
            fact *= i as f64;
        }
        let mut fact2 = 1.0f64;
        for i in 1..=(2 * order) {
            fact2 *= i as f64;
        }
        let c = 4f64.powi(order as i32) * fact * fact / (orientations as f64 * fact2);
        let cosa = (ux * theta.cos() + uy * theta.sin()) / r;
        if r <= 0.0 {
            0.0
        } else if cosa > 1e-12 {
            2.0 * c.sqrt() * cosa.powi(order as i32)
        } else if cosa >= -1e-12 && order == 0 {
            (2.0 * c).sqrt()
        } else {
            0.0
        }
    };
    (chain * radial_hi(-(s as f64) - 1.0) * angular) as f32
}

/// The low-pass chain down to scale `s` as `build` made it until session
/// 78, `log2 r` and each raised cosine's sine computed again for every
/// factor (also the low-pass residual's mask, at `s = scales`).
fn chain_per_bin(r: f64, s: usize) -> f64 {
    use std::f64::consts::PI;
    let radial_lo = |p: f64| {
        if r <= 0.0 {
            1.0
        } else {
            (0.5 * PI * (p - r.log2()).clamp(0.0, 1.0)).sin()
        }
    };
    let mut chain = radial_lo(0.0);
    for j in 0..s {
        chain *= radial_lo(-(j as f64) - 1.0);
    }
    chain
}

/// The masks made once a grid's radial part (shared by a scale's
/// orientations) and once an orientation's constants, and the low-pass
/// residual's mask, hold the per-bin code's bits, on full and compact
/// pyramids, even and odd sizes, 1 to 8 orientations; and some bins
/// lie outside every annulus (the skip is exercised).
#[test]
fn masks_made_a_grid_at_a_time_give_the_per_bin_bits() {
    let mut outside = 0;
    for (w, h) in [(16, 16), (15, 9), (32, 20), (7, 33), (64, 48)] {
        for k in [1, 2, 3, 4, 8] {
            for compact in [false, true] {
                let p = if compact {
                    ComplexSteerablePyramid::new_compact(w, h, 3, k).unwrap()
                } else {
                    ComplexSteerablePyramid::new(w, h, 3, k).unwrap()
                };
                for (bi, mask) in p.band_masks.iter().enumerate() {
                    let grid = &p.grids[p.band_grid[bi]];
                    let (s, b) = (bi / k, bi % k);
                    let theta = std::f64::consts::PI * b as f64 / k as f64;
                    for kxp in 0..grid.w {
                        for kyp in 0..grid.h {
                            let ux = 2.0 * grid.kx[kxp] as f64 / w as f64;
                            let uy = 2.0 * grid.ky[kyp] as f64 / h as f64;
                            let want = mask_per_bin(ux, uy, s, theta, k);
                            let got = mask[kxp * grid.h + kyp];
                            assert_eq!(
                                got.to_bits(),
                                want.to_bits(),
                                "{w}x{h} k {k} compact {compact} band {bi} bin ({kxp}, {kyp})"
                            );
                            outside += usize::from(band_radial(ux.hypot(uy), s) == 0.0);
                        }
                    }
                }
                // The low-pass residual's mask: the chain down to the
                // last scale.
                let low = &p.grids[3];
                for kxp in 0..low.w {
                    for kyp in 0..low.h {
                        let ux = 2.0 * low.kx[kxp] as f64 / w as f64;
                        let uy = 2.0 * low.ky[kyp] as f64 / h as f64;
                        let want = chain_per_bin(ux.hypot(uy), 3) as f32;
                        assert_eq!(
                            p.low_mask[kxp * low.h + kyp].to_bits(),
                            want.to_bits(),
                            "{w}x{h} k {k} compact {compact} low-pass bin ({kxp}, {kyp})"
                        );
                    }
                }
            }
        }
    }
    assert!(outside > 0);
}

/// The ends of the raised cosines are the library's values, so that
/// leaving out their calls keeps the masks' bits.
#[test]
fn quarter_ends_are_the_library_values() {
    use std::f64::consts::PI;
    for t in [0.0f64, 1.0] {
        assert_eq!(quarter_sin(t).to_bits(), (0.5 * PI * t).sin().to_bits());
        assert_eq!(quarter_cos(t).to_bits(), (0.5 * PI * t).cos().to_bits());
    }
    for t in [1e-9, 0.25, 0.5, 0.999] {
        assert_eq!(quarter_sin(t).to_bits(), (0.5 * PI * t).sin().to_bits());
        assert_eq!(quarter_cos(t).to_bits(), (0.5 * PI * t).cos().to_bits());
    }
}

/// A frame of bytes analysed as bytes gives the bits of the same frame
/// widened to `f32`: every band and both residuals, full and compact
/// pyramids, even and odd sizes. Fails if a row is read from the wrong
/// place or widened otherwise.
#[test]
fn frames_of_bytes_give_the_bits_of_their_f32() {
    let mut seed = 11u64;
    let mut ran = 0;
    for (w, h) in [(1, 1), (5, 3), (16, 16), (33, 20), (64, 48)] {
        let bytes: Vec<u8> = (0..w * h)
            .map(|_| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (seed >> 56) as u8
            })
            .collect();
        let floats: Vec<f32> = bytes.iter().map(|&b| f32::from(b)).collect();
        for compact in [false, true] {
            let make = || {
                if compact {
                    ComplexSteerablePyramid::new_compact(w, h, 3, 2)
                } else {
                    ComplexSteerablePyramid::new(w, h, 3, 4)
                }
            };
            let Ok(mut p) = make() else { continue };
            ran += 1;
            let (mut a, mut b) = (p.alloc_coeffs(), p.alloc_coeffs());
            p.analyze(&floats, &mut a).unwrap();
            p.analyze_u8(&bytes, &mut b).unwrap();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(a.highpass()), bits(b.highpass()), "{w}x{h}");
            assert_eq!(bits(a.lowpass()), bits(b.lowpass()), "{w}x{h}");
            for (x, y) in a.bands().iter().zip(b.bands()) {
                let re = |v: &[Complex32]| {
                    v.iter()
                        .flat_map(|c| [c.re.to_bits(), c.im.to_bits()])
                        .collect::<Vec<_>>()
                };
                assert_eq!(re(x.data()), re(y.data()), "{w}x{h} compact {compact}");
            }
        }
    }
    assert!(ran >= 8, "only {ran} pyramids made");
    let mut p = ComplexSteerablePyramid::new(8, 8, 2, 2).unwrap();
    let mut c = p.alloc_coeffs();
    assert!(p.analyze_u8(&[0u8; 63], &mut c).is_err());
}
