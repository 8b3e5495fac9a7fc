//! A resonance is a resonance (issue 51): drift is never listed as a mode,
//! and what the resonance test turns away is listed apart with its reason.
//! - simulated: a lightly damped mode plus a random walk 20 dB stronger
//!   at 1 Hz than the mode's peak, two seeds: nothing below 10 Hz is a
//!   resonance, and the walk's low peak is turned away as drift (whether
//!   the mode itself stands out is printed: not in every seed);
//! - bad cases: a pure drift, a still object (a flat spectrum), a 3-frame
//!   video: no resonance claimed, a clear message;
//! - the shared 64 Hz fork at 250, 500 and 1000 fps: the strongest
//!   resonance within 0.1 Hz of 64 Hz, no drift among the resonances;
//! - the shared guitar through `idv` with the auto basis: no basis mode
//!   damped beyond the test's bound, and the rendered video's strongest
//!   resonance is a string;
//! - simulated: a 0.2 Hz sway with 2.5 cycles in the record and sensor
//!   noise (three phases): its frequency within 5% and inside its stated
//!   uncertainty (read as 2σ), from the time-domain fit;
//! - simulated: a 12 Hz mode struck and ringing down (ζ 0.01): its
//!   free-decay damping within 10%.
//!
//!     cargo test --release --test suite resonances:: -- --nocapture

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use serde_json::Value;
use std::path::Path;

const FPS: f64 = 200.0;
const SECONDS: f64 = 20.0;
const MODE_HZ: f64 = 70.0;

/// Gaussian-ish draws (the sum of four uniforms), deterministic per seed.
fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..n).map(|_| next() + next() + next() + next()).collect()
}

/// A noise-driven oscillator at `f` Hz with damping ratio `zeta`, sampled
/// at `rate` (the exact discrete impulse-invariant recursion).
fn mode(n: usize, rate: f64, f: f64, zeta: f64, seed: u64) -> Vec<f64> {
    let w = 2.0 * std::f64::consts::PI * f / rate;
    let r = (-zeta * w).exp();
    let (a1, a2) = (2.0 * r * (w * (1.0 - zeta * zeta).sqrt()).cos(), -r * r);
    let e = noise(n, seed);
    let mut y = vec![0.0; n];
    for i in 2..n {
        y[i] = a1 * y[i - 1] + a2 * y[i - 2] + e[i];
    }
    y
}

/// A random walk (1/f² above 0.1 Hz; leaky below, so that twenty
/// seconds of it wander about as far as a few of its steps at 1 Hz, not a
/// hundred times farther: a camera's motion estimate stays linear).
fn walk(n: usize, seed: u64) -> Vec<f64> {
    let leak = 1.0 - 2.0 * std::f64::consts::PI * 0.1 / 1000.0;
    let mut s = 0.0;
    noise(n, seed)
        .into_iter()
        .map(|e| {
            s = leak * s + e;
            s
        })
        .collect()
}

/// The signal's periodogram (f32 Hann, full length): its power at `f` Hz,
/// the median over ±20% of `f` (a drift's level there) or the maximum
/// within 0.5 Hz (a mode's peak).
fn level(x: &[f64], rate: f64, f: f64, peak: bool) -> f64 {
    let x32: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    let n = x.len().next_power_of_two();
    let (p, df) = power_spectrum(&x32, rate, n);
    let bin = |h: f64| ((h / df).round() as usize).min(p.len() - 1);
    if peak {
        p[bin(f - 0.5)..=bin(f + 0.5)]
            .iter()
            .copied()
            .fold(0.0, f64::max)
    } else {
        let mut v = p[bin(0.8 * f)..=bin(1.2 * f)].to_vec();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }
}

/// Renders a 64x64 textured object moved by `motion` (samples at 1 kHz,
/// peak `amplitude_px`; sensor noise 0.1 grey levels) at [`FPS`] for
/// [`SECONDS`] in `dir`; its path.
fn render(dir: &Path, name: &str, motion: &[f64], amplitude_px: f64, seed: u64) -> String {
    render_at(dir, name, motion, amplitude_px, seed, (FPS, SECONDS), 0.1)
}

/// [`render`] at `(fps, seconds)` with sensor noise `noise_std` grey levels.
fn render_at(
    dir: &Path,
    name: &str,
    motion: &[f64],
    amplitude_px: f64,
    seed: u64,
    (fps, seconds): (f64, f64),
    noise_std: f64,
) -> String {
    let wav = dir.join(format!("{name}.wav"));
    let s: Vec<f32> = motion.iter().map(|&v| v as f32).collect();
    write_wav_f32(&wav, 1000, &s);
    let scene = format!(
        "width = 64\nheight = 64\nfps = {fps}\nduration_s = {seconds}\nnoise_std = {noise_std}\nseed = {seed}\n\
         amplitude_px = {amplitude_px}\nsignal = {{ type = \"wav\", path = {:?} }}\n",
        wav.display().to_string()
    );
    let toml = dir.join(format!("{name}.toml"));
    std::fs::write(&toml, scene).unwrap();
    let video = format!("{name}.y4m");
    let o = run_in(dir, &["simulate", toml.to_str().unwrap(), "-o", &video]);
    assert!(o.status.success(), "simulate: {}", stderr(&o));
    video
}

/// `vibroscope spectrum VIDEO` in `dir`: its report and what it printed.
fn spectrum(dir: &Path, video: &str, extra: &[&str]) -> (Value, String) {
    // The report in `dir`, whatever directory the video is in.
    let name = Path::new(video).file_name().unwrap().to_string_lossy();
    let out = format!("{name}.json");
    let mut args = vec!["spectrum", video, "-o", &out];
    args.extend_from_slice(extra);
    let o = run_in(dir, &args);
    assert!(o.status.success(), "spectrum {video}: {}", stderr(&o));
    let v: Value = serde_json::from_slice(&std::fs::read(dir.join(&out)).unwrap()).unwrap();
    (v, stderr(&o))
}

fn freqs(v: &Value, list: &str) -> Vec<f64> {
    v[list]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["frequency_hz"].as_f64().unwrap())
        .collect()
}

/// The resonance strongest above its own floor.
fn strongest(v: &Value) -> Option<f64> {
    v["peaks"]
        .as_array()
        .unwrap()
        .iter()
        .max_by(|a, b| {
            let above = |p: &Value| {
                p["power_db"].as_f64().unwrap() - p["floor_db"].as_f64().unwrap_or(f64::NAN)
            };
            above(a).total_cmp(&above(b))
        })
        .map(|p| p["frequency_hz"].as_f64().unwrap())
}

#[test]
fn a_random_walk_over_a_mode_is_never_a_resonance() {
    let n = (SECONDS * 1000.0) as usize;
    let mut turned_away = 0;
    for seed in [3u64, 11] {
        let dir = tempfile::tempdir().unwrap();
        let m = mode(n, 1000.0, MODE_HZ, 0.002, seed);
        let w = walk(n, seed + 100);
        // The walk 20 dB (power) above the mode's peak at 1 Hz.
        let k = (100.0 * level(&m, 1000.0, MODE_HZ, true) / level(&w, 1000.0, 1.0, false)).sqrt();
        let x: Vec<f64> = m.iter().zip(&w).map(|(a, b)| a + k * b).collect();
        let ratio_db = 10.0
            * (level(&w, 1000.0, 1.0, false) * k * k / level(&m, 1000.0, MODE_HZ, true)).log10();
        let video = render(dir.path(), "walk", &x, 2.0, seed);
        let (v, said) = spectrum(dir.path(), &video, &[]);
        let (res, others) = (freqs(&v, "peaks"), freqs(&v, "others"));
        println!("seed {seed}: walk {ratio_db:.1} dB over the mode at 1 Hz; resonances {res:?}; others {others:?}\n{said}");
        assert!(
            res.iter().all(|&f| f > 10.0),
            "seed {seed}: drift listed as a resonance: {res:?}"
        );
        for p in v["others"].as_array().unwrap() {
            let f = p["frequency_hz"].as_f64().unwrap();
            if f < 10.0 {
                assert_eq!(p["class"], "drift", "{p}");
                turned_away += 1;
            }
        }
        // Printed, not asserted: whether the mode, 20 dB under the walk at
        // 1 Hz, stood out of this seed's spectrum (seed 3: found at 69.9
        // Hz, the strongest; seed 11: not a candidate at all).
        let found = res.iter().any(|f| (f - MODE_HZ).abs() < 0.5);
        println!(
            "seed {seed}: the {MODE_HZ} Hz mode found: {found}; strongest {:?}",
            strongest(&v)
        );
    }
    // The walk made a low peak that the resonance test turned away as
    // drift (the 0.5 Hz "resonance").
    assert!(turned_away > 0, "no low-frequency peak was met at all");
}

#[test]
fn drift_a_still_object_and_three_frames_claim_no_resonance() {
    let n = (SECONDS * 1000.0) as usize;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A pure random walk, and an object that does not move.
    let drift = render(d, "drift", &walk(n, 7), 0.5, 7);
    let still = render(d, "still", &vec![0.0; n], 0.5, 8);
    for video in [&drift, &still] {
        let (v, said) = spectrum(d, video, &[]);
        let res = freqs(&v, "peaks");
        println!(
            "{video}: resonances {res:?}, others {:?}\n{said}",
            freqs(&v, "others")
        );
        assert!(res.is_empty(), "{video}: resonances claimed: {res:?}");
        assert!(said.contains("no resonance stands out"), "{video}: {said}");
        for p in v["others"].as_array().unwrap() {
            assert_ne!(p["class"], "resonance", "{p}");
            assert!(!p["class_reason"].as_str().unwrap().is_empty(), "{p}");
        }
    }
    // Three frames: refused or nothing claimed, with a message either way.
    let mut y4m = b"YUV4MPEG2 W32 H32 F200:1 Ip A1:1 Cmono\n".to_vec();
    for i in 0..3u8 {
        y4m.extend_from_slice(b"FRAME\n");
        y4m.extend((0..1024u32).map(|k| (k as u8).wrapping_mul(13).wrapping_add(i)));
    }
    std::fs::write(d.join("three.y4m"), y4m).unwrap();
    let o = run_in(d, &["spectrum", "three.y4m", "-o", "three.json"]);
    let said = stderr(&o);
    println!("three frames: exit {}\n{said}", code(&o));
    assert!(!said.contains("panicked"), "{said}");
    if o.status.success() {
        let v: Value =
            serde_json::from_slice(&std::fs::read(d.join("three.json")).unwrap()).unwrap();
        assert!(freqs(&v, "peaks").is_empty(), "{v}");
        assert!(said.contains("no resonance stands out"), "{said}");
    } else {
        // Refused: the message says what is too short.
        assert!(said.contains("got 3"), "says why: {said}");
    }
}

#[test]
fn the_shared_fork_rings_at_64_hz_at_every_rate() {
    for rate in [250, 500, 1000] {
        let Some(video) = shared_data(&format!("forks/fork64hz_{rate}fps.mp4")) else {
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let (v, said) = spectrum(
            dir.path(),
            video.to_str().unwrap(),
            &["--fps", &rate.to_string()],
        );
        let res = freqs(&v, "peaks");
        println!(
            "{rate} fps: resonances {res:?}, others {:?}\n{said}",
            freqs(&v, "others")
        );
        let top = strongest(&v).expect("a resonance");
        assert!((top - 64.0).abs() <= 0.1, "{rate} fps: strongest {top}");
        assert!(
            res.iter().all(|&f| f > 5.0),
            "{rate} fps: drift among {res:?}"
        );
        assert!(!said.contains("n/a"), "{rate} fps: {said}");
    }
}

#[test]
fn the_guitars_interactive_video_rings_a_string() {
    let Some(guitar) = guitar_with_ffmpeg() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = run_in(
        d,
        &[
            "idv",
            guitar.to_str().unwrap(),
            "--fps",
            "600",
            "--poke",
            "0.05,300,60,0,3",
            "-o",
            "out.y4m",
        ],
    );
    let said = stderr(&o);
    assert!(o.status.success(), "{said}");
    println!("{said}");
    let mut modes = 0;
    for line in said.lines().filter(|l| l.starts_with("mode ")) {
        let zeta: f64 = line
            .rsplit("damping ratio ")
            .next()
            .and_then(|z| z.trim().parse().ok())
            .unwrap_or_else(|| panic!("no damping in {line:?}"));
        assert!(
            zeta <= vibroscope_math::peaks::MAX_MODE_DAMPING,
            "a basis mode damped beyond the resonance test's bound: {line}"
        );
        modes += 1;
    }
    assert!(modes > 0, "no basis modes printed: {said}");
    let (v, out) = spectrum(d, "out.y4m", &[]);
    println!("{out}");
    let top = strongest(&v).expect("a resonance in the rendered video");
    assert!(
        (top - 80.8).abs() <= 3.0 || (top - 108.4).abs() <= 3.0,
        "the rendered video's strongest resonance is {top} Hz, not a string"
    );
}

/// The estimates of `method` among the peak's.
fn estimate(p: &Value, method: &str) -> Option<(f64, f64)> {
    p["damping_estimates"]
        .as_array()?
        .iter()
        .find(|e| e["method"] == method)
        .map(|e| {
            (
                e["damping_ratio"].as_f64().unwrap_or(f64::NAN),
                e["damping_ratio_std"].as_f64().unwrap_or(f64::NAN),
            )
        })
}

/// The resonance nearest `f` Hz.
fn nearest(v: &Value, f: f64) -> Option<&Value> {
    v["peaks"].as_array().unwrap().iter().min_by(|a, b| {
        let d = |p: &Value| (p["frequency_hz"].as_f64().unwrap() - f).abs();
        d(a).total_cmp(&d(b))
    })
}

#[test]
fn a_few_cycle_sway_is_measured_within_its_uncertainty() {
    // A crane's sway: 0.2 Hz, 12.5 s at 24 fps (two and a half cycles),
    // sensor noise 0.5 grey levels, three phases. The spectrum's bin is
    // 0.08 Hz (40% of the line); the time-domain fit must do far better.
    let (fps, secs, f) = (24.0, 12.5, 0.2);
    let n = (secs * 1000.0) as usize;
    for seed in [1u64, 2, 3] {
        let dir = tempfile::tempdir().unwrap();
        let phase = seed as f64 * 2.1;
        let x: Vec<f64> = (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * f * i as f64 / 1000.0 + phase).sin())
            .collect();
        let video = render_at(dir.path(), "sway", &x, 0.5, seed, (fps, secs), 0.5);
        let (v, said) = spectrum(dir.path(), &video, &["--fps", "24"]);
        println!("seed {seed}:\n{said}");
        let p = nearest(&v, f).unwrap_or_else(|| panic!("seed {seed}: no resonance: {v}"));
        let (got, std) = (
            p["frequency_hz"].as_f64().unwrap(),
            p["frequency_std_hz"].as_f64().unwrap(),
        );
        println!(
            "seed {seed}: {got:.4} ± {std:.4} Hz (truth {f}; error {:.2} sigma), damping {} ({})",
            (got - f).abs() / std,
            p["damping_ratio"],
            p["damping_method"]
        );
        assert!((got - f).abs() <= 0.05 * f, "seed {seed}: {got} Hz");
        // Inside the stated uncertainty, read as the 95% interval (2σ):
        // one standard deviation holds the truth only 68% of the time.
        assert!(
            (got - f).abs() <= 2.0 * std,
            "seed {seed}: {got} ± {std} Hz misses {f}"
        );
        assert!(std < 0.1 * f, "seed {seed}: ± {std} Hz is no measurement");
        assert!(estimate(p, "time_fit").is_some(), "{p}");
    }
}

#[test]
fn a_struck_object_rings_down_with_its_damping() {
    // A 12 Hz mode with damping ratio 0.01, struck at 2 s and left to ring
    // (200 fps, 20 s, sensor noise 0.1 grey levels, 1 px at the strike).
    let (f, zeta) = (12.0, 0.01);
    let n = (SECONDS * 1000.0) as usize;
    let w = 2.0 * std::f64::consts::PI * f;
    let x: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / 1000.0 - 2.0;
            if t < 0.0 {
                0.0
            } else {
                (-zeta * w * t).exp() * (w * (1.0 - zeta * zeta).sqrt() * t).sin()
            }
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let video = render(dir.path(), "struck", &x, 1.0, 5);
    let (v, said) = spectrum(dir.path(), &video, &[]);
    println!("{said}");
    let p = nearest(&v, f).expect("the struck mode");
    assert!((p["frequency_hz"].as_f64().unwrap() - f).abs() < 0.1, "{p}");
    let (got, std) = estimate(p, "free_decay").unwrap_or_else(|| panic!("no ring-down fit: {p}"));
    println!(
        "free decay {got:.5} ± {std:.5} (truth {zeta}); beside it: main {} ({}), ssi {:?}",
        p["damping_ratio"],
        p["damping_method"],
        estimate(p, "ssi_cov")
    );
    assert!((got / zeta - 1.0).abs() <= 0.10, "ring-down damping {got}");
}
