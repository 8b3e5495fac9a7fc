//! Physical units (issue 18 part 2) against the forward model: a simulated
//! object moving a known sub-pixel amplitude, reported by `spectrum` in µm
//! with a given scale (within 2%), and the scale measured by
//! `--known-length` on a rendered ruler whose tick spacing in pixels the
//! simulator defines (within 1%); bad scales exit 2 naming the flag, with
//! no output.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::*;
use std::path::Path;
use vibroscope::math::numeric::fit_tone;
use vibroscope::pipeline::{self, PipelineOptions};
use vibroscope::sim::texture::ruler_tick_px;

const FPS: f64 = 1000.0;
const FRAMES: usize = 1000;
const TONE_HZ: f64 = 120.0;
const AMPLITUDE_PX: f64 = 0.05;

/// The `--set` overrides of the render pipeline for a scene.
fn scene_sets(extra: &[&str]) -> Vec<String> {
    let mut v = vec![
        format!("cam.fps={FPS}"),
        format!("cam.frames={FRAMES}"),
        format!("cam.amplitude_px={AMPLITUDE_PX}"),
        format!("cam.signal={{type=\"tones\", freqs_hz=[{TONE_HZ}]}}"),
    ];
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

/// Renders the scene to `dir/name` and returns the true amplitude (px) of
/// its tone, fitted on the simulator's own displacement.
fn render(dir: &Path, name: &str, extra: &[&str]) -> f64 {
    let sets = scene_sets(extra);
    let mut args: Vec<&str> = Vec::new();
    for s in &sets {
        args.push("--set");
        args.push(s);
    }
    render_y4m(dir, name, &args);
    let decl = pipeline::prepare(&PipelineOptions {
        pipeline: "render".into(),
        set: sets,
        replay: None,
        fps: None,
    })
    .unwrap();
    let truth: Vec<f32> = true_motion(&decl, "cam", FRAMES)
        .iter()
        .map(|&v| v as f32)
        .collect();
    fit_tone(&truth, TONE_HZ, FPS, 0..FRAMES).0
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

/// The strongest peak's amplitude and the report's unit.
fn amplitude(doc: &serde_json::Value) -> (f64, String) {
    let peaks = doc["peaks"].as_array().unwrap();
    let p = peaks
        .iter()
        .max_by(|a, b| {
            a["prominence_db"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["prominence_db"].as_f64().unwrap())
        })
        .unwrap();
    let f = p["frequency_hz"].as_f64().unwrap();
    assert!((f - TONE_HZ).abs() < 1.0, "strongest peak at {f} Hz");
    (
        p["amplitude"].as_f64().unwrap(),
        doc["motion"]["unit"].as_str().unwrap().to_string(),
    )
}

#[test]
fn a_given_scale_reports_micrometres_within_2_percent() {
    let dir = tempfile::tempdir().unwrap();
    // Default scene: 256x256, the object the central [64, 64, 128, 128].
    let truth_px = render(dir.path(), "s.y4m", &[]);
    let roi = "72,72,112,112";
    let mm_per_px = 0.02;
    let cases: [(&[&str], &str, f64); 4] = [
        (&[], "px", truth_px),
        (&["--scale", "0.02"], "µm", truth_px * mm_per_px * 1000.0),
        (
            &["--scale", "0.02", "--quantity", "velocity"],
            "µm/s",
            truth_px * mm_per_px * 1000.0 * 2.0 * std::f64::consts::PI * TONE_HZ,
        ),
        (
            &["--scale", "0.02", "--quantity", "acceleration"],
            "mm/s²",
            truth_px * mm_per_px * (2.0 * std::f64::consts::PI * TONE_HZ).powi(2),
        ),
    ];
    for (k, (flags, unit, want)) in cases.iter().enumerate() {
        let out = format!("s{k}.json");
        let mut args = vec![
            "spectrum", "s.y4m", "--roi", roi, "--peaks", "2", "-o", &out,
        ];
        args.extend_from_slice(flags);
        let o = run_in(dir.path(), &args);
        assert_eq!(code(&o), 0, "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(unit), "{}", stderr(&o));
        let (got, got_unit) = amplitude(&json(&dir.path().join(&out)));
        let err = got / want - 1.0;
        eprintln!(
            "{flags:?}: {got:.5} {got_unit} for a true {want:.5} {unit} ({:+.2}%)",
            100.0 * err
        );
        assert_eq!(&got_unit, unit);
        assert!(
            err.abs() < 0.02,
            "{flags:?}: {got} {got_unit}, truth {want}"
        );
    }
}

#[test]
fn known_length_on_a_ruler_gives_the_scale_within_1_percent() {
    let dir = tempfile::tempdir().unwrap();
    // A ruler object with ticks 11.3 px apart, each tick 1 mm.
    let (ox, oy, period) = (40.0, 40.0, 11.3);
    let truth_px = render(
        dir.path(),
        "r.y4m",
        &[
            "cam.width=320",
            "cam.height=240",
            "cam.object=[40, 40, 240, 160]",
            &format!("cam.ruler_period_px={period}"),
        ],
    );
    let true_scale = 1.0 / period;
    // Ticks 0 and 19, read off a frame as a user would: whole pixels, the
    // second a row lower (the ruler's top half spans y 40..120).
    let (k0, k1) = (0, 19);
    let x0 = (ox + ruler_tick_px(period, k0)).round();
    let x1 = (ox + ruler_tick_px(period, k1)).round();
    let (y0, y1) = (oy + 20.0, oy + 21.0);
    let known = format!("{x0},{y0},{x1},{y1}={}", k1 - k0);
    let o = run_in(
        dir.path(),
        &[
            "spectrum",
            "r.y4m",
            "--roi",
            "48,48,224,144",
            "--peaks",
            "2",
            "--known-length",
            &known,
            "-o",
            "r.json",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let doc = json(&dir.path().join("r.json"));
    let scale = doc["motion"]["scale"]["mm_per_px"].as_f64().unwrap();
    let err = scale / true_scale - 1.0;
    eprintln!(
        "--known-length {known}: {scale:.6} mm/px, true {true_scale:.6} ({:+.3}%)",
        100.0 * err
    );
    assert!(err.abs() < 0.01, "scale {scale} against {true_scale}");
    // And the displacement in µm with it, against the truth at the true scale.
    let (got, unit) = amplitude(&doc);
    let want = truth_px * true_scale * 1000.0;
    eprintln!("amplitude {got:.4} {unit}, true {want:.4} µm");
    assert_eq!(unit, "µm");
    assert!((got / want - 1.0).abs() < 0.02, "{got} against {want}");
}

#[test]
fn bad_scales_exit_2_naming_the_flag_with_no_output() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(
        dir.path(),
        "b.y4m",
        &[
            "--set",
            "cam.frames=64",
            "--set",
            "cam.width=96",
            "--set",
            "cam.height=64",
        ],
    );
    let cases: [(&str, &str, &str); 8] = [
        ("--known-length", "10,10,60,10=0", "positive"),
        ("--known-length", "10,10,60,10=-5", "-5"),
        ("--known-length", "10,10,10,10=5", "apart"),
        (
            "--known-length",
            "10,10,200,10=5",
            "outside the 96x64 frame",
        ),
        ("--known-length", "10,10,60=5", "X1,Y1,X2,Y2=LENGTH_MM"),
        ("--scale", "0", "positive"),
        ("--scale", "-0.1", "-0.1"),
        ("--scale", "NaN", "NaN"),
    ];
    for (flag, value, says) in cases {
        let o = run_in(
            dir.path(),
            &["spectrum", "b.y4m", flag, value, "-o", "b.json"],
        );
        let e = stderr(&o);
        assert_eq!(code(&o), 2, "{flag} {value}: {e}");
        assert!(e.contains(flag) && e.contains(says), "{flag} {value}: {e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(
            !dir.path().join("b.json").exists(),
            "{flag} {value} wrote output"
        );
    }
}
