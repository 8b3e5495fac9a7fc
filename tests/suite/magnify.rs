//! `vibroscope magnify` against the forward model's ground truth: an object
//! moving with two tones, one inside the band and one outside; the motion
//! is measured in the magnified video by the engine's own estimator
//! (`gradient_motion`, pixels) and compared with the simulator's truth.
//! Also its bad input (exit 2, nothing written).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use std::f64::consts::PI;
use std::path::Path;
use vibroscope::magnify::{magnify, MagnifyOptions};
use vibroscope::pipeline::{self, BandFilter, PipelineOptions, Pyramid, RunSettings};
use vibroscope_math::magnify::temporal;

const FPS: f64 = 500.0;
const BAND: (f64, f64) = (35.0, 45.0);
const OUT_HZ: f64 = 150.0;
/// Peak displacement of each tone, px (the two tones share `amplitude_px`).
const TONE_PX: f64 = 0.02;
const FRAMES: usize = 500;
/// Frames left out of the fit while the band-pass settles.
const SETTLE: usize = 150;

/// The in-band tone: the band-pass's centre (unit gain, zero phase).
fn in_hz() -> f64 {
    temporal::design(2, BAND.0, BAND.1, FPS).centre_hz
}

/// Renders the two-tone scene to `dir/scene.y4m`.
fn render(dir: &Path) {
    let signal = format!(
        "cam.signal={{type=\"tones\", freqs_hz=[{}, {OUT_HZ}]}}",
        in_hz()
    );
    let set: Vec<String> = vec![
        signal,
        format!("cam.fps={FPS}"),
        format!("cam.frames={FRAMES}"),
        format!("cam.amplitude_px={}", 2.0 * TONE_PX),
        "cam.noise_std=0".into(),
        format!("out.path={}", dir.join("scene.y4m").display()),
    ];
    let decl = pipeline::prepare(&PipelineOptions {
        pipeline: "render".into(),
        set,
        replay: None,
        fps: None,
    })
    .unwrap();
    pipeline::run(&decl, RunSettings::default()).unwrap();
}

/// Amplitudes (px) of the tones `freqs` in the motion of `video`'s object,
/// measured by the `motion` pipeline (gradient least squares) and fitted
/// by least squares (sine, cosine and an offset per tone) after `SETTLE`.
fn measured(dir: &Path, video: &Path, roi: &str) -> Vec<f64> {
    let wav = dir.join("motion.wav");
    let decl = pipeline::prepare(&PipelineOptions {
        pipeline: "motion".into(),
        set: vec![
            format!("src.path={}", video.display()),
            format!("src.fps={FPS}"),
            format!("motion.roi={roi}"),
            format!("out.path={}", wav.display()),
        ],
        replay: None,
        fps: None,
    })
    .unwrap();
    pipeline::run(&decl, RunSettings::default()).unwrap();
    let (_, x) = read_wav(&wav);
    tone_amplitudes(&x[SETTLE..], SETTLE, &[in_hz(), OUT_HZ])
}

/// Least-squares amplitudes of sinusoids at `freqs` (plus an offset and a
/// linear drift) in `x`, whose first sample is frame `k0`.
#[allow(clippy::needless_range_loop)]
fn tone_amplitudes(x: &[f32], k0: usize, freqs: &[f64]) -> Vec<f64> {
    let basis = |k: usize| -> Vec<f64> {
        let t = (k + k0) as f64 / FPS;
        let mut b = vec![1.0, t];
        for f in freqs {
            b.push((2.0 * PI * f * t).sin());
            b.push((2.0 * PI * f * t).cos());
        }
        b
    };
    let m = 2 + 2 * freqs.len();
    let mut ata = vec![vec![0.0; m]; m];
    let mut atb = vec![0.0; m];
    for (k, &v) in x.iter().enumerate() {
        let b = basis(k);
        for i in 0..m {
            atb[i] += b[i] * v as f64;
            for j in 0..m {
                ata[i][j] += b[i] * b[j];
            }
        }
    }
    // Gaussian elimination (small, well-conditioned system).
    for c in 0..m {
        let p = (c..m)
            .max_by(|&a, &b| ata[a][c].abs().total_cmp(&ata[b][c].abs()))
            .unwrap();
        ata.swap(c, p);
        atb.swap(c, p);
        for r in 0..m {
            if r != c {
                let f = ata[r][c] / ata[c][c];
                for j in 0..m {
                    ata[r][j] -= f * ata[c][j];
                }
                atb[r] -= f * atb[c];
            }
        }
    }
    let coef: Vec<f64> = (0..m).map(|i| atb[i] / ata[i][i]).collect();
    (0..freqs.len())
        .map(|i| coef[2 + 2 * i].hypot(coef[3 + 2 * i]))
        .collect()
}

fn magnified(dir: &Path, factor: f64, pyramid: Pyramid, name: &str) -> std::path::PathBuf {
    let out = dir.join(name);
    magnify(&MagnifyOptions {
        video: dir.join("scene.y4m"),
        output: out.clone(),
        lo_hz: BAND.0,
        hi_hz: BAND.1,
        factor,
        fps: Some(FPS),
        pyramid,
        ..Default::default()
    })
    .unwrap();
    out
}

/// The object is the central half of the frame; its interior, away from
/// the edges that the background does not share.
const ROI: &str = "[96,96,64,64]";

#[test]
fn magnified_motion_is_the_factor_times_the_truth_in_band_only() {
    let dir = tempfile::tempdir().unwrap();
    render(dir.path());
    // The estimator on the original recovers the truth.
    let orig = measured(dir.path(), &dir.path().join("scene.y4m"), ROI);
    eprintln!(
        "original: in-band {:.5} px, out-of-band {:.5} px (truth {TONE_PX} each)",
        orig[0], orig[1]
    );
    for a in &orig {
        assert!(
            (a / TONE_PX - 1.0).abs() < 0.10,
            "estimator on the original: {orig:?}"
        );
    }
    for (pyramid, factors) in [
        (Pyramid::Csp, &[0.5, 10.0, 20.0][..]),
        (Pyramid::Riesz, &[0.5, 10.0][..]),
    ] {
        for &factor in factors {
            let v = magnified(dir.path(), factor, pyramid, "m.y4m");
            let m = measured(dir.path(), &v, ROI);
            // Gains against the estimator's own reading of the original (its
            // bias, about +6% on this texture, cancels).
            let (gain_in, gain_out) = (m[0] / orig[0], m[1] / orig[1]);
            eprintln!(
                "{pyramid:?} factor {factor}: in-band x{gain_in:.3} (want {factor}), out-of-band x{gain_out:.3} (want 1)"
            );
            // The Riesz magnifier is the fast approximation (its Laplacian
            // levels span two octaves; README): held to its measured
            // figures, x0.66 for 0.5 and x7.2 for 10, within 10% (set with
            // the exact pair by FFT: x0.658, x7.154; the 7x7 pair gives
            // x0.662, x7.097).
            let want = match pyramid {
                Pyramid::Csp => factor,
                Pyramid::Riesz if factor < 1.0 => 0.66,
                Pyramid::Riesz => 7.2,
            };
            assert!(
                (gain_in / want - 1.0).abs() < 0.10,
                "{pyramid:?} {factor}: in-band x{gain_in} (want x{want})"
            );
            assert!(
                (gain_out - 1.0).abs() < 0.10,
                "{pyramid:?} {factor}: out-of-band x{gain_out}"
            );
        }
    }
}

#[test]
fn factor_zero_removes_the_in_band_motion() {
    let dir = tempfile::tempdir().unwrap();
    render(dir.path());
    for pyramid in [Pyramid::Csp, Pyramid::Riesz] {
        let v = magnified(dir.path(), 0.0, pyramid, "still.y4m");
        let m = measured(dir.path(), &v, ROI);
        let db = 20.0 * (m[0] / TONE_PX).log10();
        eprintln!(
            "{pyramid:?} factor 0: in-band {db:.1} dB, out-of-band x{:.3}",
            m[1] / TONE_PX
        );
        // The Riesz magnifier's measured figure is -9.2 dB (README; -9.4
        // with the exact pair by FFT).
        let want = if pyramid == Pyramid::Csp { -20.0 } else { -8.0 };
        assert!(
            db <= want,
            "{pyramid:?}: in-band motion only {db:.1} dB down"
        );
        assert!(
            (m[1] / TONE_PX - 1.0).abs() < 0.10,
            "{pyramid:?}: out-of-band x{}",
            m[1] / TONE_PX
        );
    }
}

/// Bad input: a clear message naming the flag or file, exit 2, no panic,
/// and no output left behind.
#[test]
fn bad_input_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    render_y4m(
        dir.path(),
        "scene.y4m",
        &["--set", "cam.frames=20", "--set", "cam.fps=500"],
    );
    // A Y4M in a colour space no reader handles.
    std::fs::write(
        dir.path().join("rgb.y4m"),
        b"YUV4MPEG2 W4 H4 F25:1 Crgb\nFRAME\n000000000000000000000000000000000000000000000000",
    )
    .unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["scene.y4m", "--band", "200,300"], "Nyquist"),
        (&["scene.y4m", "--band", "45,35"], "inverted"),
        (&["scene.y4m", "--band", "40,40"], "--band"),
        (&["scene.y4m", "--band", "abc"], "--band"),
        (
            &["scene.y4m", "--band", "35,45", "--factor", "-2"],
            "--factor",
        ),
        (
            &["scene.y4m", "--band", "35,45", "--factor", "ten"],
            "--factor",
        ),
        (
            &["scene.y4m", "--band", "35,45", "--factor", "NaN"],
            "--factor",
        ),
        (&["rgb.y4m", "--band", "5,10"], "colour space"),
        (
            &["scene.y4m", "--band", "35,45", "--notch", "300,20"],
            "--notch 300,20",
        ),
        (
            &["scene.y4m", "--band", "35,45", "--notch", "abc"],
            "--notch",
        ),
        (
            &["scene.y4m", "--band", "35,45", "--notch", "5,20"],
            "--notch",
        ),
    ];
    for (args, want) in cases {
        let mut a: Vec<&str> = vec!["magnify"];
        a.extend_from_slice(args);
        if !a.contains(&"--factor") {
            a.extend_from_slice(&["--factor", "10"]);
        }
        a.extend_from_slice(&["-o", "out.y4m"]);
        let o = run_in(dir.path(), &a);
        let err = stderr(&o);
        assert_eq!(code(&o), 2, "{a:?}: {err}");
        assert!(err.contains(want), "{a:?}: `{want}` not in: {err}");
        assert!(!err.contains("panicked"), "{a:?}: {err}");
        let left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n != "scene.y4m" && n != "rgb.y4m")
            .collect();
        assert!(left.is_empty(), "{a:?} left {left:?}");
    }
}

/// A 64x48, 500 fps scene of `frames` frames at `d/name`.
fn render_small(d: &Path, name: &str, frames: usize) {
    let frames = format!("cam.frames={frames}");
    let sets = [
        frames.as_str(),
        "cam.fps=500",
        "cam.width=64",
        "cam.height=48",
    ];
    let args: Vec<&str> = sets.iter().flat_map(|s| ["--set", s]).collect();
    render_y4m(d, name, &args);
}

/// A Y4M's header tags and its frames' planes (8-bit only).
struct Y4m {
    w: usize,
    h: usize,
    colour: String,
    /// Per frame, the planes (luma, then chroma when there is any).
    frames: Vec<Vec<Vec<u8>>>,
}

fn read_y4m(p: &Path) -> Y4m {
    let bytes = std::fs::read(p).unwrap();
    let end = bytes.iter().position(|&b| b == b'\n').unwrap();
    let header = String::from_utf8_lossy(&bytes[..end]).into_owned();
    let tag = |c: char| {
        header
            .split(' ')
            .find_map(|t| t.strip_prefix(c).map(str::to_string))
    };
    let w: usize = tag('W').unwrap().parse().unwrap();
    let h: usize = tag('H').unwrap().parse().unwrap();
    let colour = tag('C').unwrap_or_else(|| "420jpeg".into());
    let planes: Vec<usize> = match colour.as_str() {
        "mono" => vec![w * h],
        "444" => vec![w * h; 3],
        c => panic!(
            "{}: colour space C{c} not handled by this test",
            p.display()
        ),
    };
    let mut frames = Vec::new();
    let mut at = end + 1;
    while at < bytes.len() {
        let line = at + bytes[at..].iter().position(|&b| b == b'\n').unwrap();
        assert!(bytes[at..line].starts_with(b"FRAME"), "{}", p.display());
        at = line + 1;
        let mut f = Vec::new();
        for &n in &planes {
            f.push(bytes[at..at + n].to_vec());
            at += n;
        }
        frames.push(f);
    }
    Y4m {
        w,
        h,
        colour,
        frames,
    }
}

/// A colour input keeps its colour: the output's luma is what magnifying
/// the grey video gives, bit for bit, and its chroma is the input's (of
/// the region, twice side by side).
#[test]
fn colour_is_kept_beside_the_magnified_luma() {
    if std::process::Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_err()
    {
        eprintln!("skipping: ffmpeg is not installed (it puts the chroma back)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_small(d, "grey.y4m", 30);
    // The same luma with chroma that varies across the frame and in time.
    let st = std::process::Command::new("ffmpeg")
        .current_dir(d)
        .args(["-v", "error", "-nostdin", "-y", "-i", "grey.y4m", "-vf"])
        .arg("format=yuv444p,geq=lum='p(X,Y)':cb='40+2*X+N':cr='200-3*Y'")
        .args(["-f", "yuv4mpegpipe", "-pix_fmt", "yuv444p", "colour.y4m"])
        .status()
        .unwrap();
    assert!(st.success());
    let colour_in = read_y4m(&d.join("colour.y4m"));
    assert_eq!(colour_in.colour, "444");
    // Its luma alone, as a grey Y4M (ffmpeg moved the grey to video range).
    let mut luma = format!(
        "YUV4MPEG2 W{} H{} F500:1 Ip A1:1 Cmono\n",
        colour_in.w, colour_in.h
    )
    .into_bytes();
    for f in &colour_in.frames {
        luma.extend_from_slice(b"FRAME\n");
        luma.extend_from_slice(&f[0]);
    }
    std::fs::write(d.join("luma.y4m"), luma).unwrap();
    for (roi, side) in [(None, false), (Some("9,7,40,30"), true)] {
        let mut common = vec!["--band", "35,45", "--factor", "10", "--fps", "500"];
        if let Some(r) = roi {
            common.extend_from_slice(&["--roi", r]);
        }
        if side {
            common.push("--side-by-side");
        }
        for (input, out) in [("luma.y4m", "g.y4m"), ("colour.y4m", "c.y4m")] {
            let mut a = vec!["magnify", input];
            a.extend_from_slice(&common);
            a.extend_from_slice(&["-o", out]);
            let o = run_in(d, &a);
            assert_eq!(code(&o), 0, "{a:?}: {}", stderr(&o));
            if input == "colour.y4m" {
                assert!(stderr(&o).contains("colour kept"), "{}", stderr(&o));
            }
        }
        let (g, c) = (read_y4m(&d.join("g.y4m")), read_y4m(&d.join("c.y4m")));
        assert_eq!(g.colour, "mono");
        assert_eq!(c.colour, "444", "{roi:?}");
        assert_eq!((c.w, c.h, c.frames.len()), (g.w, g.h, g.frames.len()));
        assert_eq!(g.frames.len(), 30);
        let (x0, y0, rw) = match roi {
            Some(_) => (9, 7, 40),
            None => (0, 0, 64),
        };
        for (k, (gf, cf)) in g.frames.iter().zip(&c.frames).enumerate() {
            assert_eq!(gf[0], cf[0], "{roi:?}: luma of frame {k} differs");
            for (p, plane) in cf.iter().enumerate().skip(1) {
                for y in 0..c.h {
                    for x in 0..c.w {
                        let xs = x0 + x % rw;
                        let want = colour_in.frames[k][p][(y0 + y) * colour_in.w + xs];
                        assert_eq!(
                            plane[y * c.w + x],
                            want,
                            "{roi:?}: plane {p} of frame {k} at ({x}, {y})"
                        );
                    }
                }
            }
        }
        eprintln!(
            "roi {roi:?} side by side {side}: {} frames of {}x{}, luma identical to the grey run, chroma the input's",
            c.frames.len(),
            c.w,
            c.h
        );
    }
}

/// `--notch`: the out-of-band tone is removed (at least 20 dB) after the
/// band is magnified, which keeps its gain; with `--side-by-side` the left
/// half is the input and the right half what the plain run writes.
#[test]
fn a_notch_removes_its_tone_after_the_magnification() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d);
    let scene = d.join("scene.y4m");
    let orig = measured(d, &scene, ROI);
    let run = |name: &str, side_by_side: bool| {
        let out = d.join(name);
        magnify(&MagnifyOptions {
            video: scene.clone(),
            output: out.clone(),
            lo_hz: BAND.0,
            hi_hz: BAND.1,
            factor: 10.0,
            fps: Some(FPS),
            side_by_side,
            notches: vec![BandFilter::notch(&format!("{OUT_HZ},20")).unwrap()],
            ..Default::default()
        })
        .unwrap();
        out
    };
    let plain = run("n.y4m", false);
    let m = measured(d, &plain, ROI);
    let (gain_in, db_out) = (m[0] / orig[0], 20.0 * (m[1] / orig[1]).log10());
    eprintln!("factor 10, notch at {OUT_HZ} Hz: in-band x{gain_in:.3}, out-of-band {db_out:.1} dB");
    assert!((gain_in / 10.0 - 1.0).abs() < 0.10, "in-band x{gain_in}");
    assert!(db_out <= -20.0, "the notched tone only {db_out:.1} dB down");
    let sb = read_y4m(&run("sb.y4m", true));
    let (p, s) = (read_y4m(&plain), read_y4m(&scene));
    assert_eq!(
        (sb.w, sb.h, sb.frames.len()),
        (2 * p.w, p.h, p.frames.len())
    );
    for (k, ((f, pf), sf)) in sb.frames.iter().zip(&p.frames).zip(&s.frames).enumerate() {
        for y in 0..p.h {
            let row = &f[0][y * sb.w..(y + 1) * sb.w];
            assert_eq!(
                &row[..p.w],
                &sf[0][y * p.w..(y + 1) * p.w],
                "left, frame {k} row {y}"
            );
            assert_eq!(
                &row[p.w..],
                &pf[0][y * p.w..(y + 1) * p.w],
                "right, frame {k} row {y}"
            );
        }
    }
}

/// The shipped live graph (`pipelines/live-magnify.toml`: camera ->
/// magnify, side by side -> Y4M on standard output) replayed from a file:
/// standard output is one Y4M stream of every frame, original left.
#[test]
fn the_live_graph_writes_a_side_by_side_stream_to_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_small(d, "scene.y4m", 40);
    let o = run_in(
        d,
        &[
            "run",
            "live-magnify",
            "--replay",
            "scene.y4m",
            "--fps",
            "500",
            "--set",
            "mag.lo_hz=35",
            "--set",
            "mag.hi_hz=45",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    std::fs::write(d.join("stdout.y4m"), &o.stdout).unwrap();
    let (out, src) = (
        read_y4m(&d.join("stdout.y4m")),
        read_y4m(&d.join("scene.y4m")),
    );
    assert_eq!((out.w, out.h, out.frames.len()), (128, 48, 40));
    for (f, s) in out.frames.iter().zip(&src.frames) {
        for y in 0..48 {
            assert_eq!(&f[0][y * 128..y * 128 + 64], &s[0][y * 64..(y + 1) * 64]);
        }
    }
}

/// A band and factor changed while the run goes on (the studio's magnified
/// view, through the run's observer): the stage starts its magnifier over
/// at its next frame with them, so a change asked for before the first
/// frame gives the frames of a run started with those settings, bit for
/// bit; a band the frame rate refuses is refused with the stage's reason,
/// and the frames stay those of the settings it had.
#[test]
fn a_band_changed_while_running_starts_the_magnifier_over_with_it() {
    let dir = tempfile::tempdir().unwrap();
    render(dir.path());
    let scene = dir.path().join("scene.y4m");
    type Request = Vec<(String, f64)>;
    let run = |name: &str, (lo, hi, factor): (f64, f64, f64), request: Option<Request>| {
        let out = dir.path().join(name);
        let decl = pipeline::prepare(&PipelineOptions {
            pipeline: "magnify".into(),
            set: vec![
                format!("mag.lo_hz={lo:?}"),
                format!("mag.hi_hz={hi:?}"),
                format!("mag.factor={factor:?}"),
                "mag.pyramid=\"riesz\"".into(),
                format!("out.path={:?}", out.display().to_string()),
            ],
            replay: Some(scene.clone()),
            fps: None,
        })
        .unwrap();
        let observer = vibroscope::live::Observer::new();
        if let Some(r) = request {
            assert_eq!(observer.tuning("mag").request(r), 1);
        }
        pipeline::run_observed(&decl, &observer).unwrap();
        (
            std::fs::read(&out).unwrap(),
            observer.tuning("mag").outcome(),
        )
    };
    let ask = |lo: f64, hi: f64, factor: f64| -> Option<Request> {
        Some(vec![
            ("lo_hz".into(), lo),
            ("hi_hz".into(), hi),
            ("factor".into(), factor),
        ])
    };
    let (start, none) = run("start.y4m", (BAND.0, BAND.1, 10.0), None);
    assert_eq!(none, None, "no change was asked for");
    let (direct, _) = run("direct.y4m", (140.0, 160.0, 5.0), None);
    let (changed, answer) = run(
        "changed.y4m",
        (BAND.0, BAND.1, 10.0),
        ask(140.0, 160.0, 5.0),
    );
    let answer = answer.expect("the stage answered");
    assert_eq!((answer.version, answer.result), (1, Ok(0)));
    assert!(
        changed == direct,
        "a change at frame 0 is not a run started with it"
    );
    assert!(changed != start, "the change changed nothing");
    // Above half the frame rate (250 Hz): refused, the frames unchanged.
    let (refused, answer) = run(
        "refused.y4m",
        (BAND.0, BAND.1, 10.0),
        ask(140.0, 300.0, 5.0),
    );
    let answer = answer.expect("the stage answered");
    let why = answer.result.expect_err("a band above Nyquist was taken");
    assert!(why.contains("300") && why.contains("Nyquist"), "{why}");
    assert!(refused == start, "a refused change changed the frames");
}

/// The Riesz magnifier on two threads keeps two frames in flight: each
/// frame leaves when the next comes, the last at the end. Its frames are
/// the bytes one thread writes, as many and in order, in every layout
/// (the whole frame, a region, a region beside its input, a region
/// inside the whole frame), on frames large enough for its passes to be
/// split in halves and on ones too small for it.
#[test]
fn two_frames_in_flight_write_the_bytes_of_one_at_a_time() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (size, rois) in [
        ((112, 96), ["[8, 6, 96, 88]", "[0, 40, 112, 56]"]),
        ((64, 48), ["[4, 4, 40, 30]", "[0, 0, 64, 48]"]),
    ] {
        let scene = d.join(format!("s{}.y4m", size.0));
        let (w, h) = (
            format!("cam.width={}", size.0),
            format!("cam.height={}", size.1),
        );
        let sets = ["cam.frames=30", "cam.fps=500", w.as_str(), h.as_str()];
        let args: Vec<&str> = sets.iter().flat_map(|s| ["--set", s]).collect();
        render_y4m(d, scene.to_str().unwrap(), &args);
        let mut layouts: Vec<Vec<String>> = vec![vec![]];
        for roi in rois {
            let r = format!("mag.roi={roi}");
            layouts.push(vec![r.clone()]);
            layouts.push(vec![r.clone(), "mag.side_by_side=true".into()]);
            layouts.push(vec![r, "mag.whole_frame=true".into()]);
        }
        for (k, layout) in layouts.iter().enumerate() {
            let run = |threads: usize| {
                let out = d.join(format!("m{}-{k}-{threads}.y4m", size.0));
                let mut set = vec![
                    "mag.lo_hz=35.0".to_string(),
                    "mag.hi_hz=45.0".into(),
                    "mag.factor=20.0".into(),
                    "mag.pyramid=\"riesz\"".into(),
                    format!("mag.threads={threads}"),
                    format!("out.path={:?}", out.display().to_string()),
                ];
                set.extend(layout.iter().cloned());
                let decl = pipeline::prepare(&PipelineOptions {
                    pipeline: "magnify".into(),
                    set,
                    replay: Some(scene.clone()),
                    fps: None,
                })
                .unwrap();
                pipeline::run(&decl, RunSettings::default()).unwrap();
                read_y4m(&out)
            };
            let (one, two) = (run(1), run(2));
            assert_eq!(two.frames.len(), 30, "{size:?} {layout:?}: frames written");
            assert_eq!((one.w, one.h), (two.w, two.h), "{size:?} {layout:?}");
            for (t, (a, b)) in one.frames.iter().zip(&two.frames).enumerate() {
                assert!(
                    a == b,
                    "{size:?} {layout:?}: frame {t} differs between one thread and two"
                );
            }
            // The input's own frames differ from the magnified ones (the
            // comparison above is not between two copies of the input).
            let input = read_y4m(&scene);
            assert!(input.frames[20][0] != two.frames[20][0] || !layout.is_empty());
        }
    }
}
