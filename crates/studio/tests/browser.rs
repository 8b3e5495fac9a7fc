//! The studio end to end in headless Chromium (issue 16): a simulated
//! cantilever beam whose mode frequencies and shapes the simulator knows is
//! opened in the page; a click on the spectrum near each true mode
//! frequency must show the modal image the library computes at the
//! frequency clicked (the canvas's pixels read back through the page and
//! compared with the `modes` recipe's PNG; the amplitudes the page holds
//! with the recipe's `.npy`); a listed peak snaps; a region drawn with the
//! mouse gets a spectrum whose top peak is the mode the simulator says
//! dominates there; a drag over each mode's spike of a second recording
//! (the damping view) fits the library's Lorentzian for that range, its
//! damping within 3σ of the simulator's, and SSI's stabilisation diagram
//! finds the mode. A live synthetic pipeline run by the studio must get
//! at least 10 spectrum updates a second to the page for 10 s with no
//! frame dropped anywhere in the pipeline, its peaks at the scene's tones;
//! a dropped WebSocket shows an error and the page reconnects.
//! Interactive dynamic video (issue 17): a drag on the beam's free end,
//! held, moves the rendered texture there the way dragged (little near
//! the clamp) with an arrow drawn; let go, it swings through rest and dies
//! away; the page renderer's frame rate for a 512x512 basis of 8 modes is
//! measured and printed. The live magnified view (issue 52): a 640x480
//! replay at 60 fps through `live-magnify` shows magnified frames on the
//! page with its drops reported (the rate is printed; `cargo bench -p
//! vibroscope-studio --bench live_view` measures it against its bar), and a
//! band set on the page gives the `magnify` command's frames.
//! Screenshots go to `docs/img/studio-*.png`.
//!
//! Needs Debian's `chromium` and `chromium-driver`; skips with a printed
//! reason when they are missing.
//!
//!     cargo test --release -p vibroscope-studio --test browser -- --nocapture

#![allow(clippy::unwrap_used, clippy::expect_used)]

use fantoccini::actions::{InputSource, MouseActions, PointerAction, MOUSE_BUTTON_LEFT};
use fantoccini::{Client, Locator};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use vibroscope::modes::ModesOptions;
use vibroscope_math::modal::read_npy_complex64;
use vibroscope_sim::modal::cantilever_shape;
use vibroscope_studio::{Studio, StudioOptions};

mod chromium;
mod common;

use chromium::{
    browser_missing, in_browser, js, live, magnified_clip, magnified_rate, magnified_studio,
    open_live, render, MAG_FRAMES,
};

const FPS: f64 = 300.0;
const W: u32 = 160;
const H: u32 = 64;
/// The beam: x, y, w, h.
const OBJECT: [u32; 4] = [16, 16, 128, 32];
/// (frequency Hz, amplitude px, shape): thesis Table 5.5's frequencies.
const MODES: [(f64, f64, u32); 3] = [(7.3, 0.3, 1), (58.3, 0.15, 2), (128.0, 0.1, 3)];

fn scene() -> String {
    format!(
        "width = {W}\nheight = {H}\nfps = {FPS}\nframes = 600\nobject = {OBJECT:?}\n\
         noise_std = 2.0\nseed = 7\nmodal = {{ modes = [\n\
         {{ freq_hz = {}, amplitude_px = {}, shape = {}, damping = 0.02 }},\n\
         {{ freq_hz = {}, amplitude_px = {}, shape = {}, drive = \"tone\" }},\n\
         {{ freq_hz = {}, amplitude_px = {}, shape = {}, damping = 0.005 }},\n] }}\n",
        MODES[0].0,
        MODES[0].1,
        MODES[0].2,
        MODES[1].0,
        MODES[1].1,
        MODES[1].2,
        MODES[2].0,
        MODES[2].1,
        MODES[2].2
    )
}

/// Waits until `window.studio[counter]` passes `after`; panics with the
/// page's error message if the page shows one instead.
async fn wait_for(c: &Client, counter: &str, after: u64, errors_before: u64) {
    let t0 = Instant::now();
    loop {
        let v = js(
            c,
            &format!("return [window.studio ? window.studio.{counter} : 0, window.studio ? window.studio.errorSeq : 0, window.studio ? window.studio.lastError : null]"),
        )
        .await;
        if v[0].as_u64().unwrap_or(0) > after {
            return;
        }
        if v[1].as_u64().unwrap_or(0) > errors_before {
            panic!("the page shows an error: {}", v[2]);
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "timed out waiting for {counter}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

async fn counter(c: &Client, name: &str) -> u64 {
    js(c, &format!("return window.studio.{name}"))
        .await
        .as_u64()
        .unwrap()
}

/// Clicks the element at an offset from its centre (CSS pixels).
async fn click_at(c: &Client, el: &fantoccini::elements::Element, x: f64, y: f64) {
    let m = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: el.clone(),
            duration: None,
            x,
            y,
        })
        .then(PointerAction::Down {
            button: MOUSE_BUTTON_LEFT,
        })
        .then(PointerAction::Up {
            button: MOUSE_BUTTON_LEFT,
        });
    c.perform_actions(m).await.unwrap();
    c.release_actions().await.unwrap();
}

/// Drags the mouse over `el` from one offset from its centre to another
/// (CSS pixels).
async fn drag(c: &Client, el: &fantoccini::elements::Element, from: (f64, f64), to: (f64, f64)) {
    let m = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: el.clone(),
            duration: None,
            x: from.0,
            y: from.1,
        })
        .then(PointerAction::Down {
            button: MOUSE_BUTTON_LEFT,
        })
        .then(PointerAction::MoveToElement {
            element: el.clone(),
            duration: Some(Duration::from_millis(200)),
            x: to.0,
            y: to.1,
        })
        .then(PointerAction::Up {
            button: MOUSE_BUTTON_LEFT,
        });
    c.perform_actions(m).await.unwrap();
    c.release_actions().await.unwrap();
}

/// Runs `script` on the page and waits for it to show an error; its text.
async fn error_after(c: &Client, script: &str) -> String {
    let errors = counter(c, "errorSeq").await;
    js(c, script).await;
    let t0 = Instant::now();
    while counter(c, "errorSeq").await == errors {
        assert!(t0.elapsed() < Duration::from_secs(30), "no error shown");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    js(c, "return document.getElementById('error').textContent")
        .await
        .as_str()
        .unwrap()
        .to_string()
}

/// A JSON array of unsigned integers.
fn u64s(v: &Value) -> Vec<u64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect()
}

/// The strongest of a page's peaks: its frequency.
fn top_peak_hz(peaks: &Value) -> f64 {
    peaks
        .as_array()
        .unwrap()
        .iter()
        .max_by(|a, b| {
            a["power_db"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["power_db"].as_f64().unwrap())
        })
        .expect("peaks")["frequency_hz"]
        .as_f64()
        .unwrap()
}

/// The library's modal image at `f`: the recipe's PNG (RGB) and the complex
/// image's amplitudes.
fn library_mode(video: &Path, dir: &Path, f: f64) -> (Vec<u8>, Vec<f32>) {
    let png = dir.join(format!("lib-{f}.png"));
    let npy = dir.join(format!("lib-{f}.npy"));
    vibroscope::modes::modes(&ModesOptions {
        video: video.to_path_buf(),
        at_hz: f,
        output: png.clone(),
        npy: Some(npy.clone()),
        ..ModesOptions::default()
    })
    .unwrap();
    let rgb = image::open(&png).unwrap().to_rgb8().into_raw();
    let (_, _, data) = read_npy_complex64(&std::fs::read(&npy).unwrap()).unwrap();
    (rgb, data.iter().map(|c| c.norm()).collect())
}

fn img_dir() -> PathBuf {
    // Read when the test runs (cargo sets it), not compiled in: a build
    // at another path stays reusable.
    std::env::var_os("CARGO_MANIFEST_DIR")
        .map_or_else(
            || std::env::current_dir().unwrap_or_default(),
            std::path::PathBuf::from,
        )
        .join("../../docs/img")
}

/// The simulated beam of [`scene`] rendered in `dir` (`beam.y4m`).
fn beam_video(dir: &Path) -> PathBuf {
    render(dir, "beam", &scene())
}

/// One browser test at a time: the live test measures a real-time
/// pipeline, which the other test's computations would slow on two cores.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

#[test]
fn recording_view_modal_images_and_a_region_in_headless_chromium() {
    if browser_missing() {
        return;
    }
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let video = beam_video(dir.path());
    let studio = Studio::start(&StudioOptions {
        video: Some(video.clone()),
        ..StudioOptions::default()
    })
    .unwrap();
    let (s, v, d) = (&studio, &video, dir.path());
    in_browser(|c| async move {
        drive(&c, s, v, d).await;
        c
    });
}

async fn drive(c: &Client, studio: &Studio, video: &Path, dir: &Path) {
    c.set_window_size(1400, 1000).await.unwrap();
    c.goto(&studio.url).await.unwrap();
    // The video opens from the session; the whole frame's spectrum arrives.
    wait_for(c, "motionSeq", 0, 0).await;
    let errors = counter(c, "errorSeq").await;
    let spectrum = c.find(Locator::Css("#spectrum")).await.unwrap();
    let spec_w = js(c, "return document.getElementById('spectrum').width")
        .await
        .as_f64()
        .unwrap();
    let spec_css_w = js(
        c,
        "return document.getElementById('spectrum').getBoundingClientRect().width",
    )
    .await
    .as_f64()
    .unwrap();
    assert!(
        (spec_w - spec_css_w).abs() < 0.5,
        "the spectrum canvas is drawn 1:1"
    );

    for (k, &(f_true, _, shape)) in MODES.iter().enumerate() {
        let x = js(c, &format!("return window.studio.freqToX({f_true})"))
            .await
            .as_f64()
            .unwrap();
        let before = counter(c, "modeSeq").await;
        let t0 = Instant::now();
        click_at(c, &spectrum, x.round() + 0.5 - spec_w / 2.0, 0.0).await;
        wait_for(c, "modeSeq", before, errors).await;
        let click_ms = t0.elapsed().as_secs_f64() * 1e3;
        let m = js(c, "const m = window.studio.mode; return {freq_hz: m.freq_hz, width: m.width, height: m.height, amplitude: m.amplitude_px, elapsed_ms: m.elapsed_ms, cached: m.cached}").await;
        let f = m["freq_hz"].as_f64().unwrap();
        println!(
            "mode {} ({f_true} Hz): clicked {f:.3} Hz; click to image shown {click_ms:.0} ms (server {:.0} ms, cached {})",
            k + 1,
            m["elapsed_ms"].as_f64().unwrap(),
            m["cached"]
        );
        assert!(
            (f - f_true).abs() < 0.75,
            "the click landed at {f} Hz, not near {f_true} Hz"
        );
        assert_eq!(
            (m["width"].as_u64(), m["height"].as_u64()),
            (Some(W as u64), Some(H as u64))
        );
        // The canvas's pixels, read back through the page.
        let px = js(c, "const c = document.getElementById('modal'); return Array.from(c.getContext('2d').getImageData(0, 0, c.width, c.height).data)").await;
        let px: Vec<u8> = px
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as u8)
            .collect();
        let (lib_rgb, lib_amp) = library_mode(video, dir, f);
        assert_eq!(px.len(), lib_rgb.len() / 3 * 4);
        let mut worst = 0i32;
        for (p, l) in px.chunks_exact(4).zip(lib_rgb.chunks_exact(3)) {
            for i in 0..3 {
                worst = worst.max((p[i] as i32 - l[i] as i32).abs());
            }
        }
        assert!(
            worst <= 1,
            "mode {}: the page's modal image differs from the library's by {worst} levels",
            k + 1
        );
        let page_amp: Vec<f64> = m["amplitude"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let max = lib_amp.iter().copied().fold(0.0f32, f32::max) as f64;
        let err = page_amp
            .iter()
            .zip(&lib_amp)
            .map(|(a, b)| (a - *b as f64).abs())
            .fold(0.0, f64::max);
        assert!(err <= 1e-5 * max, "amplitudes differ by {err} (max {max})");
        // And it is the mode: it is bright on the beam and dark away from
        // it (beyond the blur's reach), and its profile along the beam
        // follows the simulator's shape.
        let [ox, oy, ow, oh] = OBJECT.map(|v| v as usize);
        let far = 6usize;
        let (mut on, mut n_on, mut off, mut n_off) = (0.0, 0usize, 0.0, 0usize);
        let mut cols = vec![0.0f64; ow];
        for y in 0..H as usize {
            for x in 0..W as usize {
                let a = page_amp[y * W as usize + x];
                if (ox..ox + ow).contains(&x) && (oy + 8..oy + oh - 8).contains(&y) {
                    on += a;
                    n_on += 1;
                    cols[x - ox] += a;
                } else if !(ox.saturating_sub(far)..ox + ow + far).contains(&x)
                    || !(oy.saturating_sub(far)..oy + oh + far).contains(&y)
                {
                    off += a;
                    n_off += 1;
                }
            }
        }
        let contrast = (on / n_on as f64) / (off / n_off as f64);
        let truth: Vec<f64> = (0..ow)
            .map(|i| cantilever_shape(shape, (i as f64 + 0.5) / ow as f64).abs())
            .collect();
        let dot: f64 = cols.iter().zip(&truth).map(|(a, b)| a * b).sum();
        let corr = dot
            / (cols.iter().map(|a| a * a).sum::<f64>() * truth.iter().map(|b| b * b).sum::<f64>())
                .sqrt();
        println!(
            "  mean amplitude on the beam / {far}+ px away from it {contrast:.1}; |profile| vs |shape {shape}| correlation {corr:.3}"
        );
        assert!(
            contrast > 2.5,
            "mode {}: the image is not brighter on the beam ({contrast:.2})",
            k + 1
        );
        assert!(
            corr > 0.8,
            "mode {}: profile does not follow shape {shape} (corr {corr:.3})",
            k + 1
        );
        if k == 1 {
            std::fs::create_dir_all(img_dir()).unwrap();
            let shot = c.screenshot().await.unwrap();
            std::fs::write(img_dir().join("studio-mode.png"), shot).unwrap();
        }
    }

    // A listed peak snaps: the image is at the peak's own frequency.
    let peaks = js(
        c,
        "return window.studio.motion.peaks.map(p => p.frequency_hz)",
    )
    .await;
    let peaks: Vec<f64> = peaks
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let (row, f_peak) = peaks
        .iter()
        .copied()
        .enumerate()
        .min_by(|a, b| {
            (a.1 - MODES[1].0)
                .abs()
                .total_cmp(&(b.1 - MODES[1].0).abs())
        })
        .unwrap();
    assert!(
        (f_peak - MODES[1].0).abs() < 0.5,
        "no listed peak near {} Hz: {peaks:?}",
        MODES[1].0
    );
    let before = counter(c, "modeSeq").await;
    let tr = c
        .find(Locator::Css(&format!(
            "#peaks tbody tr:nth-child({})",
            row + 1
        )))
        .await
        .unwrap();
    tr.click().await.unwrap();
    wait_for(c, "modeSeq", before, errors).await;
    let f = js(c, "return window.studio.mode.freq_hz")
        .await
        .as_f64()
        .unwrap();
    assert_eq!(f, f_peak, "a listed peak snaps to its frequency");

    // A scale typed in (0.02 mm/px): the waveform, the peak amplitudes and
    // the modal image's scale in µm, the library's conversion of the px
    // numbers; cleared, px again.
    let set_scale = |v: &str| {
        format!("const e = document.getElementById('mmpx'); e.value = '{v}'; e.dispatchEvent(new Event('change')); return 0")
    };
    let (motions, modes) = (counter(c, "motionSeq").await, counter(c, "modeSeq").await);
    js(c, &set_scale("0.02")).await;
    wait_for(c, "motionSeq", motions, errors).await;
    wait_for(c, "modeSeq", modes, errors).await;
    let got = js(
        c,
        "const S = window.studio, w = S.motion.waveform;
         return [w.unit, w.x_px, w.x, S.motion.amplitude_unit, S.motion.peaks.map(p => [p.amplitude_px, p.amplitude]),
                 S.mode.amplitude_unit, S.mode.max_amplitude_px, S.mode.max_amplitude,
                 document.getElementById('ampunit').textContent, document.getElementById('amplabel').textContent]",
    )
    .await;
    println!(
        "scale 0.02 mm/px: waveform in {}, amplitudes in {}, modal image in {}: {}",
        got[0], got[3], got[5], got[9]
    );
    assert_eq!(got[0], json!("µm"));
    let to_um = |v: &Value| v.as_f64().unwrap() * 0.02 * 1e3;
    for (px, um) in got[1]
        .as_array()
        .unwrap()
        .iter()
        .zip(got[2].as_array().unwrap())
    {
        assert!((to_um(px) - um.as_f64().unwrap()).abs() <= 1e-9 * to_um(px).abs().max(1e-9));
    }
    assert_eq!(got[3], json!("µm"));
    for p in got[4].as_array().unwrap() {
        assert!((to_um(&p[0]) - p[1].as_f64().unwrap()).abs() <= 1e-9 * to_um(&p[0]).abs());
    }
    assert_eq!(got[5], json!("µm"));
    assert!((to_um(&got[6]) - got[7].as_f64().unwrap()).abs() <= 1e-9 * to_um(&got[6]));
    assert_eq!(got[8], json!("amplitude (µm)"));
    assert!(got[9].as_str().unwrap().contains(" µm"), "{}", got[9]);
    let (motions, modes) = (counter(c, "motionSeq").await, counter(c, "modeSeq").await);
    js(c, &set_scale("")).await;
    wait_for(c, "motionSeq", motions, errors).await;
    wait_for(c, "modeSeq", modes, errors).await;
    let unit = js(
        c,
        "return [window.studio.motion.waveform.unit, window.studio.mode.amplitude_unit]",
    )
    .await;
    assert_eq!(unit, json!(["px", "px"]));
    // A scale that is not a number, or not above 0, is the page's error.
    let shown = error_after(c, &set_scale("-1")).await;
    assert!(shown.contains("scale_mm_per_px"), "{shown}");
    let shown = error_after(c, &set_scale("abc")).await;
    assert!(shown.contains("not a number"), "{shown}");
    let (motions, modes) = (counter(c, "motionSeq").await, counter(c, "modeSeq").await);
    let errors = counter(c, "errorSeq").await;
    js(c, &set_scale("")).await;
    wait_for(c, "motionSeq", motions, errors).await;
    wait_for(c, "modeSeq", modes, errors).await;

    // A region drawn with the mouse, where the simulator says mode 2
    // dominates: the 24 object columns where its shape's share is largest.
    let [ox, oy, ow, oh] = OBJECT;
    let span = 24usize;
    let dominance = |c0: usize| {
        let amp = |(_, a, n): (f64, f64, u32)| {
            a * ((c0..c0 + span)
                .map(|i| cantilever_shape(n, (i as f64 + 0.5) / ow as f64).powi(2))
                .sum::<f64>()
                / span as f64)
                .sqrt()
        };
        let a: Vec<f64> = MODES.iter().map(|&m| amp(m)).collect();
        a[1] / a[0].max(a[2])
    };
    let c0 = (0..ow as usize - span)
        .max_by(|&a, &b| dominance(a).total_cmp(&dominance(b)))
        .unwrap();
    println!(
        "region: object columns {c0}..{} (mode 2 amplitude {:.1}x the others)",
        c0 + span,
        dominance(c0)
    );
    assert!(
        dominance(c0) > 1.3,
        "precondition: a region where mode 2 dominates"
    );
    let roi = [ox + c0 as u32, oy + 4, span as u32, oh - 8];
    let overlay = c.find(Locator::Css("#overlay")).await.unwrap();
    let scale = js(c, "return window.studio.scale").await.as_f64().unwrap();
    let (ow_css, oh_css) = (W as f64 * scale, H as f64 * scale);
    let at = |x: u32, y: u32| {
        (
            x as f64 * scale + scale / 2.0 - ow_css / 2.0,
            y as f64 * scale + scale / 2.0 - oh_css / 2.0,
        )
    };
    let (x0, y0) = at(roi[0], roi[1]);
    let (x1, y1) = at(roi[0] + roi[2], roi[1] + roi[3]);
    let before = counter(c, "motionSeq").await;
    drag(c, &overlay, (x0, y0), (x1, y1)).await;
    wait_for(c, "motionSeq", before, errors).await;
    let got = js(
        c,
        "return [window.studio.motion.roi, window.studio.motion.peaks]",
    )
    .await;
    assert_eq!(
        u64s(&got[0]),
        roi.map(u64::from).to_vec(),
        "the region drawn"
    );
    let f_top = top_peak_hz(&got[1]);
    println!("region {roi:?}: top peak {f_top:.3} Hz");
    assert!(
        (f_top - MODES[1].0).abs() < 0.5,
        "the region's top peak is {f_top} Hz, not mode 2 ({} Hz)",
        MODES[1].0
    );
    // The same place painted as a mask (a stroke along the region's middle
    // row, 8 px brush): its spectrum's top peak is mode 2 too, over the
    // pixels painted; then back to the rectangle.
    js(
        c,
        "document.getElementById('brush').value = 8; document.getElementById('paint').click(); return 0",
    )
    .await;
    let cy = roi[1] + roi[3] / 2;
    let (px0, py) = at(roi[0] + 8, cy);
    let (px1, _) = at(roi[0] + roi[2] - 8, cy);
    let before = counter(c, "motionSeq").await;
    drag(c, &overlay, (px0, py), (px1, py)).await;
    wait_for(c, "motionSeq", before, errors).await;
    let got = js(
        c,
        "const m = window.studio.motion; return [m.mask_pixels, m.roi, m.peaks, window.studio.sel]",
    )
    .await;
    let painted = got[0].as_u64().expect("a masked answer");
    let bbox = u64s(&got[1]);
    let f_mask = top_peak_hz(&got[2]);
    println!("mask: {painted} px painted, bounding box {bbox:?}; top peak {f_mask:.3} Hz");
    // The stroke: 8 px either side of the row, from 8 px before the first
    // centre to 8 px after the last.
    let want_w = (roi[2] - 16 + 17) as u64;
    assert!(
        (bbox[2] as i64 - want_w as i64).abs() <= 2 && (bbox[3] as i64 - 17).abs() <= 2,
        "bounding box {bbox:?} for a {want_w}x17 stroke"
    );
    assert!(
        painted as f64 > 0.8 * (want_w * 17) as f64 && painted <= want_w * 17,
        "{painted} px painted"
    );
    assert_eq!(got[3], json!(-2), "the mask is selected");
    assert!(
        (f_mask - MODES[1].0).abs() < 0.5,
        "the mask's top peak is {f_mask} Hz, not mode 2"
    );
    // The mask, not only its bounding box, was analysed: the box's own
    // spectrum differs.
    let differs = c
        .execute_async(
            "const done = arguments[arguments.length - 1], S = window.studio;
             fetch('/api/motion', {method: 'POST', headers: {'content-type': 'application/json'},
                                   body: JSON.stringify({video: S.video, roi: S.motion.roi})})
               .then(r => r.json()).then(b => done(b.spectrum.power_db.some((v, k) => Math.abs(v - S.motion.spectrum.power_db[k]) > 0.01)));",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(
        differs,
        json!(true),
        "the mask's spectrum is its bounding box's"
    );
    js(c, "document.getElementById('paint').click(); return 0").await;
    let before = counter(c, "motionSeq").await;
    js(c, "Array.from(document.querySelectorAll('#regions button')).find(b => b.textContent.startsWith('R1')).click(); return 0").await;
    wait_for(c, "motionSeq", before, errors).await;
    // The modal image over the frame with the region drawn, for the README.
    let before = counter(c, "modeSeq").await;
    click_at(
        c,
        &spectrum,
        js(c, &format!("return window.studio.freqToX({})", MODES[0].0))
            .await
            .as_f64()
            .unwrap()
            .round()
            + 0.5
            - spec_w / 2.0,
        0.0,
    )
    .await;
    wait_for(c, "modeSeq", before, errors).await;
    // Listening to the region: the listen recipe's sound, decoded and
    // played by Web Audio, as long as the recording, its spectrogram's
    // strongest line the mode that dominates the region.
    let sounds = counter(c, "soundSeq").await;
    c.find(Locator::Id("listen"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    wait_for(c, "soundSeq", sounds, errors).await;
    let heard = js(
        c,
        "const S = window.studio, sg = S.sound.spectrogram;
         const mean = sg.db[0].map((_, b) => sg.db.reduce((a, col) => a + Math.pow(10, col[b] / 10), 0));
         let best = 1; for (let b = 1; b < mean.length; b++) if (mean[b] > mean[best]) best = b;
         return [S.soundBuffer.duration, S.audioCtx.state, S.soundStarted, best * sg.bin_hz, sg.bin_hz,
                 document.getElementById('audio').src.startsWith('data:audio/wav'), S.sound.sample_rate_hz];",
    )
    .await;
    println!("listen: {heard}");
    let duration = heard[0].as_f64().unwrap();
    let frames_s = 600.0 / FPS;
    assert!(
        (duration - frames_s).abs() < 0.03 * frames_s,
        "the sound lasts {duration} s for {frames_s} s of video"
    );
    assert_eq!(
        heard[1],
        json!("running"),
        "the audio context is not playing"
    );
    assert_eq!(heard[2], json!(true));
    let (f_top, bin) = (heard[3].as_f64().unwrap(), heard[4].as_f64().unwrap());
    assert!(
        (f_top - MODES[1].0).abs() <= 1.5 * bin,
        "the sound's strongest line is {f_top} Hz, not mode 2 at {} Hz",
        MODES[1].0
    );
    assert_eq!(heard[5], json!(true));
    assert_eq!(heard[6], json!(8000));
    let shot = c.screenshot().await.unwrap();
    std::fs::write(img_dir().join("studio-region.png"), shot).unwrap();
    damping_view(c, dir).await;
    // Bad input on the page: a video the server cannot read shows an error.
    error_after(c, "document.getElementById('video').value = 'no-such-file.y4m'; document.getElementById('open').click(); return 0").await;
    let shown = js(c, "return [document.getElementById('error').hidden, document.getElementById('error').textContent]").await;
    assert_eq!(shown[0], json!(false));
    assert!(
        shown[1].as_str().unwrap().contains("no-such-file.y4m"),
        "{shown}"
    );
    println!("screenshots: {}", img_dir().display());
}

/// The damping view's scene: two noise-driven modes of a beam, each line
/// several bins wide in a 6 s recording (thesis 5.4.2 asks a person to
/// drag over such a spike). (frequency Hz, damping ratio, amplitude px).
const RING_MODES: [(f64, f64, f64); 2] = [(40.0, 0.05, 0.3), (96.0, 0.02, 0.2)];

fn ring_scene() -> String {
    let m = RING_MODES;
    format!(
        "width = 96\nheight = 40\nfps = {FPS}\nframes = 1800\nobject = [8, 8, 80, 24]\n\
         noise_std = 2.0\nseed = 11\nmodal = {{ modes = [\n\
         {{ freq_hz = {}, damping = {}, amplitude_px = {}, shape = 1 }},\n\
         {{ freq_hz = {}, damping = {}, amplitude_px = {}, shape = 2 }},\n] }}\n",
        m[0].0, m[0].1, m[0].2, m[1].0, m[1].1, m[1].2
    )
}

/// The library's damping view over `lo..hi` Hz of the whole frame of
/// `video`: the spectrum recipe (its spectrum and motion kept), then
/// [`vibroscope::damping::damping_over`].
fn library_damping(video: &Path, dir: &Path, lo: f64, hi: f64) -> Value {
    let wav = dir.join("lib-motion.wav");
    let mut o = vibroscope::spectrum::SpectrumOptions::new(video, dir.join("lib-peaks.json"));
    o.peaks = 8;
    o.include_spectrum = true;
    o.motion_wav = Some(wav.clone());
    let (report, _) = vibroscope::spectrum::run_spectrum(&o, true).unwrap();
    let (_, y) = vibroscope_io::wav::read_mono(&wav).unwrap();
    let d = vibroscope::damping::damping_over(
        report.spectrum.as_ref().unwrap(),
        report.sample_rate_hz,
        report.taper.as_deref(),
        &y,
        (lo, hi),
        "range",
    )
    .unwrap();
    serde_json::to_value(d).unwrap()
}

/// Pixels of `canvas` close to the colour `rgb` (within 40 per channel).
async fn pixels_like(c: &Client, canvas: &str, rgb: [u8; 3]) -> u64 {
    js(
        c,
        &format!(
            "const c = document.getElementById('{canvas}'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
             let n = 0; for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - {}) < 40 && Math.abs(d[i + 1] - {}) < 40 && Math.abs(d[i + 2] - {}) < 40) n++;
             return n",
            rgb[0], rgb[1], rgb[2]
        ),
    )
    .await
    .as_u64()
    .unwrap()
}

/// The damping view: a second recording opened from the page, a drag over
/// each mode's spike in its spectrum; the fit the page shows is the
/// library's for the range dragged, its damping is the simulator's within
/// its stated uncertainty (3σ), SSI's stabilisation diagram has stable
/// poles there and agrees the same way; a drag narrower than 6 bins shows
/// the error. Screenshot: `docs/img/studio-damping.png`.
async fn damping_view(c: &Client, dir: &Path) {
    let scene = dir.join("ring.toml");
    std::fs::write(&scene, ring_scene()).unwrap();
    let video = dir.join("ring.y4m");
    vibroscope::simulate::simulate(&vibroscope::simulate::SimulateOptions {
        scene,
        output: video.clone(),
        ..Default::default()
    })
    .unwrap();
    let errors = counter(c, "errorSeq").await;
    let before = counter(c, "motionSeq").await;
    js(c, "document.getElementById('video').value = 'ring.y4m'; document.getElementById('open').click(); return 0").await;
    wait_for(c, "motionSeq", before, errors).await;
    let spectrum = c.find(Locator::Css("#spectrum")).await.unwrap();
    let spec_w = js(c, "return document.getElementById('spectrum').width")
        .await
        .as_f64()
        .unwrap();
    for (k, &(f_true, xi_true, _)) in RING_MODES.iter().enumerate() {
        let gamma = xi_true * f_true;
        let (lo, hi) = (f_true - 6.0 * gamma, f_true + 6.0 * gamma);
        let x_of = |f: f64| format!("return window.studio.freqToX({f})");
        let x0 = js(c, &x_of(lo)).await.as_f64().unwrap() - spec_w / 2.0;
        let x1 = js(c, &x_of(hi)).await.as_f64().unwrap() - spec_w / 2.0;
        let before = counter(c, "dampSeq").await;
        drag(c, &spectrum, (x0, 0.0), (x1, 0.0)).await;
        wait_for(c, "dampSeq", before, errors).await;
        let page = js(c, "return window.studio.damp.damping").await;
        let (plo, phi) = (
            page["lo_hz"].as_f64().unwrap(),
            page["hi_hz"].as_f64().unwrap(),
        );
        assert!(
            (plo - lo).abs() < 1.0 && (phi - hi).abs() < 1.0,
            "dragged {plo}..{phi} Hz for {lo}..{hi}"
        );
        let lib = library_damping(&video, dir, plo, phi);
        let fit = &page["fit"];
        let num = |v: &Value, k: &str| v[k].as_f64().unwrap();
        for key in ["f0_hz", "damping_ratio", "damping_ratio_std"] {
            let (a, b) = (num(fit, key), num(&lib["fit"], key));
            assert!(
                (a - b).abs() <= 1e-9 * b.abs().max(1e-12),
                "mode {}: the page's {key} {a} is not the library's {b}",
                k + 1
            );
        }
        let (xi, sd) = (num(fit, "damping_ratio"), num(fit, "damping_ratio_std"));
        let z = (xi - xi_true) / sd;
        let ssi = &page["ssi"];
        let stable = page["poles"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| p["stable"] == json!(true))
            .count();
        println!(
            "damping view, mode {} ({f_true} Hz, ζ {xi_true}): dragged {plo:.2}..{phi:.2} Hz; \
             Lorentzian f0 {:.3} ± {:.3} Hz, ζ {xi:.4} ± {sd:.4} ({z:+.2}σ from the truth); \
             SSI ζ {} ({} poles, {stable} stable); server {:.0} ms",
            k + 1,
            num(fit, "f0_hz"),
            num(fit, "f0_std_hz"),
            if ssi.is_null() {
                "none".to_string()
            } else {
                format!(
                    "{:.4} ± {:.4} at {:.3} Hz",
                    num(ssi, "damping_ratio"),
                    num(ssi, "damping_ratio_std"),
                    num(ssi, "frequency_hz")
                )
            },
            page["poles"].as_array().unwrap().len(),
            js(c, "return window.studio.damp.elapsed_ms")
                .await
                .as_f64()
                .unwrap()
        );
        assert_eq!(fit["resolved"], json!(true));
        assert!(
            z.abs() <= 3.0 && sd <= 0.5 * xi_true,
            "mode {}: ζ {xi} ± {sd} against the simulator's {xi_true}",
            k + 1
        );
        assert!(
            (num(fit, "f0_hz") - f_true).abs() <= 3.0 * num(fit, "f0_std_hz") + 0.1 * gamma,
            "mode {}: f0 {fit}",
            k + 1
        );
        assert!(stable >= 3, "mode {}: {stable} stable poles", k + 1);
        assert!(!ssi.is_null(), "mode {}: SSI found no mode", k + 1);
        let zs = (num(ssi, "damping_ratio") - xi_true) / num(ssi, "damping_ratio_std");
        assert!(
            zs.abs() <= 3.0 && (num(ssi, "frequency_hz") - f_true).abs() < 2.0 * gamma,
            "mode {}: SSI {ssi} against ζ {xi_true} at {f_true} Hz",
            k + 1
        );
        // What is drawn: the fit's orange curve, SSI's green stable poles,
        // and the numbers in the text.
        let orange = pixels_like(c, "dampfit", [0xff, 0x99, 0x33]).await;
        let green = pixels_like(c, "stab", [0x33, 0xcc, 0x66]).await;
        assert!(
            orange > 200 && green > 30,
            "drawn: {orange} fit pixels, {green} pole pixels"
        );
        let text = js(c, "return document.getElementById('damptext').textContent").await;
        assert!(
            text.as_str().unwrap().contains(&format!("{xi:.4}")),
            "{text}"
        );
    }
    // The spectrum with the range dragged, and the panel under it.
    c.set_window_size(1400, 1400).await.unwrap();
    js(
        c,
        "document.getElementById('spectrum').scrollIntoView(); return 0",
    )
    .await;
    let shot = c.screenshot().await.unwrap();
    std::fs::write(img_dir().join("studio-damping.png"), shot).unwrap();
    c.set_window_size(1400, 1000).await.unwrap();
    js(c, "window.scrollTo(0, 0); return 0").await;
    // A drag over fewer than 6 bins shows why.
    let shown = error_after(c, "window.studio.showDamping(60, 60.5); return 0").await;
    assert!(shown.contains("at least 6"), "{shown}");
}

/// The live scene: tones well inside the 250 Hz Nyquist band.
const LIVE_TONES: [f64; 2] = [60.0, 170.0];

#[test]
fn live_view_ten_spectra_a_second_without_drops_in_headless_chromium() {
    if browser_missing() {
        return;
    }
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let json_out = dir.path().join("spectrum.json");
    // The shipped live pipeline, sized for two cores beside a browser:
    // 500 fps of 96x96, a 512-frame window every 25 frames = 20 spectra a
    // second. Headless Chromium's renderer runs at nice -8 and can hold
    // both cores for tens of milliseconds, so the ring before `phase`
    // holds a quarter second (128 frames) rather than 16; the pipeline is
    // the same with and without the page.
    let set = vec![
        "src.fps=500.0".to_owned(),
        "src.width=96".to_owned(),
        "src.height=96".to_owned(),
        "src.duration_s=30.0".to_owned(),
        "src.amplitude_px=0.2".to_owned(),
        format!(
            "src.signal={{ type = \"tones\", freqs_hz = [{:.1}, {:.1}] }}",
            LIVE_TONES[0], LIVE_TONES[1]
        ),
        "spectrum.window=512".to_owned(),
        "spectrum.hop=25".to_owned(),
        "phase.capacity=128".to_owned(),
        format!("out.path=\"{}\"", json_out.display()),
    ];
    let studio = Studio::start(&StudioOptions {
        root: Some(dir.path().to_path_buf()),
        pipeline: Some("live-spectrum".into()),
        set,
        ..StudioOptions::default()
    })
    .unwrap();
    let s = &studio;
    in_browser(|c| async move {
        drive_live(&c, s).await;
        c
    });
    drop(studio);
    // Stopping the studio stopped the pipeline, whose sink finalised.
    let doc: Value = serde_json::from_slice(&std::fs::read(&json_out).unwrap()).unwrap();
    assert!(
        doc["peaks"].as_array().is_some_and(|p| !p.is_empty()),
        "{doc}"
    );
}

async fn drive_live(c: &Client, studio: &Studio) {
    // The first spectrum needs 512 frames (about 1 s).
    open_live(c, studio, "spectra", 3, "live spectrum").await;
    // 10 s of updates, counted by the page: distinct spectra received,
    // on the page's own clock.
    let a = live(c, "[window.studio.live.spectra, performance.now(), window.studio.live.specSeq, window.studio.live.last]").await;
    tokio::time::sleep(Duration::from_secs(10)).await;
    let b = live(c, "[window.studio.live.spectra, performance.now(), window.studio.live.specSeq, window.studio.live.framesShown]").await;
    let n = b[0].as_f64().unwrap() - a[0].as_f64().unwrap();
    let secs = (b[1].as_f64().unwrap() - a[1].as_f64().unwrap()) / 1e3;
    let rate = n / secs;
    let seqs = b[2].as_f64().unwrap() - a[2].as_f64().unwrap();
    println!(
        "live: {n} spectra in {secs:.2} s on the page = {rate:.1}/s (the pipeline made {seqs} in that time); {} frames shown",
        b[3]
    );
    assert!(secs >= 9.5, "measured over {secs:.2} s");
    assert!(
        rate >= 10.0,
        "{rate:.1} spectrum updates a second reached the page"
    );
    // No frame or item dropped anywhere in the pipeline over those 10 s
    // with the page on (Chromium's own start-up, on the same two cores,
    // is before them).
    let u = live(c, "window.studio.live.last").await;
    assert_eq!(u["state"], json!("running"), "{}", u["message"]);
    let dropped = |v: &Value| -> Vec<(String, u64)> {
        v["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| (s["id"].to_string(), s["dropped"].as_u64().unwrap()))
            .collect()
    };
    let (d0, d1) = (dropped(&a[3]), dropped(&u));
    println!("dropped per stage before the 10 s: {d0:?}; after: {d1:?}");
    assert_eq!(d0, d1, "items dropped while the page was watching");
    // The live peaks are the scene's tones.
    let peaks: Vec<f64> = u["spectrum"]["peaks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["frequency_hz"].as_f64().unwrap())
        .collect();
    let res = u["spectrum"]["resolution_hz"].as_f64().unwrap();
    for f in LIVE_TONES {
        assert!(
            peaks.iter().take(2).any(|p| (p - f).abs() <= 2.0 * res),
            "no top peak at {f} Hz: {peaks:?}"
        );
    }
    // The frame and the spectrogram are drawn (the image's size reads 0
    // while its next frame loads: look again then).
    let t0 = Instant::now();
    let shown = loop {
        let shown = live(
            c,
            "[window.studio.live.framesShown, document.getElementById('liveframe').naturalWidth]",
        )
        .await;
        if shown[1] != json!(0) || t0.elapsed() > Duration::from_secs(5) {
            break shown;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    assert!(shown[0].as_u64().unwrap() >= 10, "{shown}");
    assert_eq!(shown[1], json!(96));
    std::fs::create_dir_all(img_dir()).unwrap();
    let shot = c.screenshot().await.unwrap();
    std::fs::write(img_dir().join("studio-live.png"), shot).unwrap();
    // A dropped WebSocket: the page says so, reconnects, and updates resume
    // (the server kept running).
    let errors = counter(c, "errorSeq").await;
    let before = live(c, "window.studio.live.spectra")
        .await
        .as_u64()
        .unwrap();
    live(c, "(window.studio.live.ws.close(), 0)").await;
    let t0 = Instant::now();
    while counter(c, "errorSeq").await == errors {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "no error shown for the dropped socket"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let msg = js(c, "return window.studio.lastError").await;
    assert!(
        msg.as_str().unwrap().contains("live connection was lost"),
        "{msg}"
    );
    while live(c, "window.studio.live.spectra")
        .await
        .as_u64()
        .unwrap()
        < before + 5
    {
        assert!(
            t0.elapsed() < Duration::from_secs(15),
            "updates did not resume"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let hidden = js(c, "return document.getElementById('error').hidden").await;
    assert_eq!(hidden, json!(true), "the error stays after reconnecting");
    // A click on the live spectrum at the first tone (it snaps to the
    // listed peak): the modal image from the last seconds of frames,
    // bright on the moving object (the central half of the frame) and dark
    // around it.
    let spec = c.find(Locator::Css("#livespec")).await.unwrap();
    let w = js(c, "return document.getElementById('livespec').width")
        .await
        .as_f64()
        .unwrap();
    let x = live(c, &format!("window.studio.live.freqToX({})", LIVE_TONES[0]))
        .await
        .as_f64()
        .unwrap();
    let errors = counter(c, "errorSeq").await;
    let before = live(c, "window.studio.live.modeSeq")
        .await
        .as_u64()
        .unwrap();
    click_at(c, &spec, x.round() + 0.5 - w / 2.0, 0.0).await;
    let t0 = Instant::now();
    while live(c, "window.studio.live.modeSeq")
        .await
        .as_u64()
        .unwrap()
        == before
    {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no live modal image"
        );
        assert_eq!(
            counter(c, "errorSeq").await,
            errors,
            "{}",
            js(c, "return window.studio.lastError").await
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let m = live(c, "(({freq_hz, width, height, frames, span_s, fps, elapsed_ms, amplitude_px}) => ({freq_hz, width, height, frames, span_s, fps, elapsed_ms, amplitude_px}))(window.studio.live.mode)").await;
    let num = |k: &str| m[k].as_f64().unwrap();
    let amp: Vec<f64> = m["amplitude_px"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let (mut on, mut n_on, mut off, mut n_off) = (0.0, 0usize, 0.0, 0usize);
    for y in 0..96usize {
        for x in 0..96usize {
            let a = amp[y * 96 + x];
            if (28..68).contains(&x) && (28..68).contains(&y) {
                on += a;
                n_on += 1;
            } else if !(18..78).contains(&x) || !(18..78).contains(&y) {
                off += a;
                n_off += 1;
            }
        }
    }
    let contrast = (on / n_on as f64) / (off / n_off as f64).max(1e-30);
    println!(
        "live modal image at {:.2} Hz: {} frames over {:.2} s at {:.1} fps, {:.0} ms; on the object / around it {contrast:.1}; largest amplitude {:.4} px",
        num("freq_hz"),
        num("frames"),
        num("span_s"),
        num("fps"),
        num("elapsed_ms"),
        amp.iter().copied().fold(0.0, f64::max)
    );
    assert!(
        (num("freq_hz") - LIVE_TONES[0]).abs() < 1.0,
        "{}",
        num("freq_hz")
    );
    assert_eq!((num("width"), num("height")), (96.0, 96.0));
    assert!(
        (num("fps") - 500.0).abs() < 10.0,
        "frames came at {} fps",
        num("fps")
    );
    assert!(num("frames") >= 1000.0 && num("span_s") > 2.0, "{m}");
    assert!(
        contrast > 2.5,
        "the modal image is not brighter on the object ({contrast:.2})"
    );
    let shot = c.screenshot().await.unwrap();
    std::fs::write(img_dir().join("studio-live.png"), shot).unwrap();
}

/// Interactive dynamic video's scene (issue 17): the cantilever of
/// `docs/img/idv-beam.toml` on the studio's frame, clamped on the left,
/// free on the right, its three modes noise-driven for 4 s.
const IDV_MODES: [(f64, f64, f64, u32); 3] = [
    (7.3, 0.02, 0.3, 1),
    (45.8, 0.01, 0.15, 2),
    (128.0, 0.005, 0.1, 3),
];

fn idv_scene() -> String {
    let m = IDV_MODES;
    format!(
        "width = {W}\nheight = {H}\nfps = {FPS}\nframes = 1200\nobject = {OBJECT:?}\n\
         noise_std = 2.0\nseed = 3\nmodal = {{ modes = [\n\
         {{ freq_hz = {}, damping = {}, amplitude_px = {}, shape = {} }},\n\
         {{ freq_hz = {}, damping = {}, amplitude_px = {}, shape = {} }},\n\
         {{ freq_hz = {}, damping = {}, amplitude_px = {}, shape = {} }},\n] }}\n",
        m[0].0,
        m[0].1,
        m[0].2,
        m[0].3,
        m[1].0,
        m[1].1,
        m[1].2,
        m[1].3,
        m[2].0,
        m[2].1,
        m[2].2,
        m[2].3
    )
}

/// The vertical shift s (px, + down) that best explains `now` as `rest`
/// moved: now[y] ≈ rest[y - s] over the object's inner rows, searched in
/// steps of 0.05 px over ±10 px (rest linearly interpolated).
fn vertical_shift(rest: &[f64], now: &[f64]) -> f64 {
    let rows = (OBJECT[1] + 6) as usize..(OBJECT[1] + OBJECT[3] - 6) as usize;
    let at = |y: f64| {
        let y = y.clamp(0.0, (rest.len() - 1) as f64);
        let y0 = y.floor() as usize;
        let y1 = (y0 + 1).min(rest.len() - 1);
        rest[y0] + (rest[y1] - rest[y0]) * (y - y0 as f64)
    };
    let mut best = (f64::INFINITY, 0.0);
    for k in -200..=200 {
        let s = k as f64 * 0.05;
        let e: f64 = rows
            .clone()
            .map(|y| (now[y] - at(y as f64 - s)).powi(2))
            .sum();
        if e < best.0 {
            best = (e, s);
        }
    }
    best.1
}

/// Columns `xs` of the page's rendered frame (the `#frame` canvas), grey.
async fn frame_columns(c: &Client, xs: &[u32]) -> Vec<Vec<f64>> {
    let v = js(
        c,
        &format!(
            "const c = document.getElementById('frame'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
             return {xs:?}.map(x => {{ const col = []; for (let y = 0; y < c.height; y++) col.push(d[4 * (y * c.width + x)]); return col; }})"
        ),
    )
    .await;
    v.as_array()
        .unwrap()
        .iter()
        .map(|col| {
            col.as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect()
        })
        .collect()
}

/// Renders the page's current modal state once and compares the frame
/// with `math::idv::Renderer` (Eq. 6.10 and the warp) over the library's
/// basis of `region` (`extract_basis`, its shapes zero outside the
/// region's box as the page has them) at the same modal coordinates.
async fn same_as_library(c: &Client, video: &Path, region: [u32; 4]) {
    let v = js(
        c,
        "const S = window.studio, E = S.idv.engine; S.idvRender();
         const cv = document.getElementById('frame'), d = cv.getContext('2d').getImageData(0, 0, cv.width, cv.height).data;
         const grey = []; for (let i = 0; i < d.length; i += 4) grey.push(d[i]);
         return [Array.from(E.rho), Array.from(E.vel), Array.from(E.omega), grey]",
    )
    .await;
    let nums = |v: &Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (rho, vel, omega, page) = (nums(&v[0]), nums(&v[1]), nums(&v[2]), nums(&v[3]));
    let mut o = vibroscope::idv::BasisOptions::new(video);
    o.region = vibroscope::pipeline::Region {
        roi: Some(vibroscope::pipeline::Roi {
            x: region[0],
            y: region[1],
            w: region[2],
            h: region[3],
        }),
        ..Default::default()
    };
    o.modes = IDV_MODES
        .map(|m| m.0.to_string())
        .join(",")
        .parse()
        .unwrap();
    let basis = vibroscope::idv::extract_basis(&o).unwrap();
    let (w, h) = (basis.width, basis.height);
    let [bx, by, bw, bh] = region.map(|v| v as usize);
    let zero = vibroscope_math::idv::Complex32::new(0.0, 0.0);
    let shapes: Vec<_> = basis
        .modes
        .iter()
        .map(|m| {
            let mut s = m.shape.clone();
            for i in 0..w * h {
                let (x, y) = (i % w, i / w);
                if !(bx..bx + bw).contains(&x) || !(by..by + bh).contains(&y) {
                    s.x[i] = zero;
                    s.y[i] = zero;
                }
            }
            s
        })
        .collect();
    let q: Vec<_> = (0..rho.len())
        .map(|i| vibroscope_math::idv::Complex64::new(rho[i], -vel[i] / omega[i]))
        .collect();
    let mut r = vibroscope_math::idv::Renderer::new(w, h);
    r.displacement(&shapes, &q);
    let mut out = vec![0u8; w * h];
    r.warp(&basis.rest, &mut out);
    let largest = r.dy.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let diffs: Vec<f64> = page
        .iter()
        .zip(&out)
        .map(|(p, l)| (p - *l as f64).abs())
        .collect();
    let off = diffs.iter().filter(|d| **d > 1.0).count();
    let worst = diffs.iter().copied().fold(0.0, f64::max);
    println!(
        "page vs library renderer (|D| up to {largest:.2} px): {off} of {} pixels differ by more than 1 level (worst {worst})",
        diffs.len()
    );
    assert!(largest > 2.0, "the state held moves the beam");
    assert!(
        off * 1000 <= diffs.len(),
        "{off} pixels differ from the library's rendering"
    );
}

/// The overlay's RGBA at frame point (x, y) (the centre of that frame pixel).
async fn arrow_pixel(c: &Client, x: f64, y: f64, scale: f64) -> [u8; 4] {
    let v = js(
        c,
        &format!(
            "const o = document.getElementById('overlay'); return Array.from(o.getContext('2d').getImageData({}, {}, 1, 1).data)",
            ((x + 0.5) * scale).floor(),
            ((y + 0.5) * scale).floor()
        ),
    )
    .await;
    let v: Vec<u8> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as u8)
        .collect();
    [v[0], v[1], v[2], v[3]]
}

#[test]
fn dragging_the_object_bends_it_and_it_rings_when_let_go_in_headless_chromium() {
    if browser_missing() {
        return;
    }
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("idv-beam.toml");
    std::fs::write(&scene_path, idv_scene()).unwrap();
    let video = dir.path().join("idv-beam.y4m");
    vibroscope::simulate::simulate(&vibroscope::simulate::SimulateOptions {
        scene: scene_path,
        output: video.clone(),
        ..Default::default()
    })
    .unwrap();
    let studio = Studio::start(&StudioOptions {
        video: Some(video.clone()),
        ..StudioOptions::default()
    })
    .unwrap();
    let (s, v) = (&studio, &video);
    in_browser(|c| async move {
        drive_idv(&c, s, v).await;
        c
    });
}

/// The IDV panel end to end: load the basis of the three listed modes,
/// drag the free end up (then down) and hold: the rendered beam's texture
/// near the free end moves the way dragged, most there and little near the
/// clamp, with the arrow drawn; let go: it swings through rest to the
/// other side and dies away. Then the renderer's frame rate for a
/// synthetic 512x512 basis of 8 modes, measured in the page.
/// Screenshot: `docs/img/studio-idv.png`.
async fn drive_idv(c: &Client, studio: &Studio, video: &Path) {
    c.set_window_size(1400, 1000).await.unwrap();
    c.goto(&studio.url).await.unwrap();
    wait_for(c, "motionSeq", 0, 0).await;
    let errors = counter(c, "errorSeq").await;
    let modes = IDV_MODES.map(|m| m.0.to_string()).join(",");
    // The object with a 4 px margin as the selected region: the basis is
    // measured there and sent for its box only.
    let [ox, oy, ow, oh] = OBJECT;
    let region = [ox - 4, oy - 4, ow + 8, oh + 8];
    let overlay = c.find(Locator::Css("#overlay")).await.unwrap();
    let scale = js(c, "return window.studio.scale").await.as_f64().unwrap();
    let (ow_css, oh_css) = (W as f64 * scale, H as f64 * scale);
    let at = |x: f64, y: f64| {
        (
            x * scale + scale / 2.0 - ow_css / 2.0,
            y * scale + scale / 2.0 - oh_css / 2.0,
        )
    };
    let before = counter(c, "motionSeq").await;
    drag(
        c,
        &overlay,
        at(region[0] as f64, region[1] as f64),
        at(
            (region[0] + region[2]) as f64,
            (region[1] + region[3]) as f64,
        ),
    )
    .await;
    wait_for(c, "motionSeq", before, errors).await;
    js(
        c,
        &format!("document.getElementById('idvmodes').value = '{modes}'; document.getElementById('idvload').click(); return 0"),
    )
    .await;
    wait_for(c, "idv.seq", 0, errors).await;
    let b = js(c, "const b = window.studio.idv.basis; return [b.width, b.height, b.box, b.modes, b.payload_bytes, b.elapsed_ms, window.studio.idv.on]").await;
    println!(
        "basis: {}x{} box {} in {:.0} ms, {} bytes; modes {}",
        b[0],
        b[1],
        b[2],
        b[5].as_f64().unwrap(),
        b[4],
        b[3]
    );
    assert_eq!(
        (b[0].as_u64(), b[1].as_u64()),
        (Some(W as u64), Some(H as u64))
    );
    assert_eq!(
        b[6],
        json!(true),
        "interaction is on once the basis is loaded"
    );
    assert_eq!(
        u64s(&b[2]),
        region.map(u64::from).to_vec(),
        "the region's box"
    );
    let got: Vec<f64> = b[3]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["freq_hz"].as_f64().unwrap())
        .collect();
    assert_eq!(got, IDV_MODES.map(|m| m.0).to_vec(), "the modes asked for");

    let free_x = ox + ow - 8;
    let clamp_x = ox + 6;
    let grab = (free_x as f64, (oy + oh / 2) as f64);
    // At rest the rendered frame is the rest frame.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let rest = frame_columns(c, &[free_x, clamp_x]).await;
    let mouse = |x: f64, y: f64, dur: Option<Duration>| PointerAction::MoveToElement {
        element: overlay.clone(),
        duration: dur,
        x,
        y,
    };
    for dy in [-5.0, 5.0] {
        let (gx, gy) = at(grab.0, grab.1);
        let (tx, ty) = at(grab.0, grab.1 + dy);
        let hold = MouseActions::new("mouse".into())
            .then(mouse(gx, gy, None))
            .then(PointerAction::Down {
                button: MOUSE_BUTTON_LEFT,
            })
            .then(mouse(tx, ty, Some(Duration::from_millis(250))));
        c.perform_actions(hold).await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
        let held = js(
            c,
            "const I = window.studio.idv; return [I.engine.held, I.engine.d, I.grabs]",
        )
        .await;
        let now = frame_columns(c, &[free_x, clamp_x]).await;
        let (s_free, s_clamp) = (
            vertical_shift(&rest[0], &now[0]),
            vertical_shift(&rest[1], &now[1]),
        );
        println!(
            "held, dragged {dy:+} px at ({}, {}): pointer offset {}, texture shift at the free end {s_free:+.2} px, near the clamp {s_clamp:+.2} px",
            grab.0, grab.1, held[1]
        );
        assert_eq!(held[0], json!(true), "the grab was taken");
        assert!(
            s_free * dy.signum() > 2.5,
            "dragged {dy:+} px: the free end moved {s_free:+.2} px"
        );
        assert!(
            s_clamp.abs() < 0.5 * s_free.abs(),
            "near the clamp the beam moved {s_clamp:+.2} px, at the free end {s_free:+.2} px"
        );
        // The page's frame for the state held is the library's renderer's
        // (math::idv::Renderer over the library's basis of the same region).
        if dy < 0.0 {
            same_as_library(c, video, region).await;
        }
        // The arrow is on the overlay: opaque yellow halfway along the drag.
        let mid = arrow_pixel(c, grab.0, grab.1 + dy / 2.0, scale).await;
        assert_eq!(mid, [255, 204, 51, 255], "no arrow halfway along the drag");
        let releases = counter(c, "idv.releases").await;
        let up = MouseActions::new("mouse".into()).then(PointerAction::Up {
            button: MOUSE_BUTTON_LEFT,
        });
        c.perform_actions(up).await.unwrap();
        c.release_actions().await.unwrap();
        // Free motion: the free end's column at every animation frame for 3 s.
        let trace = c
            .execute_async(
                &format!(
                    "const done = arguments[arguments.length - 1], c = document.getElementById('frame'), g = c.getContext('2d');
                     const out = [], t0 = performance.now();
                     const tick = (ts) => {{
                       const d = g.getImageData({free_x}, 0, 1, c.height).data, col = [];
                       for (let y = 0; y < c.height; y++) col.push(d[4 * y]);
                       out.push([ts - t0, col]);
                       if (ts - t0 < 3000) requestAnimationFrame(tick); else done([out, window.studio.idv.fps, window.studio.idv.releases]);
                     }};
                     requestAnimationFrame(tick);"
                ),
                vec![],
            )
            .await
            .unwrap();
        assert!(
            trace[2].as_u64().unwrap() > releases,
            "the release was seen"
        );
        let mid = arrow_pixel(c, grab.0, grab.1 + dy / 2.0, scale).await;
        assert_eq!(mid[3], 0, "the arrow is gone once let go");
        let samples: Vec<(f64, f64)> = trace[0]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| {
                let col: Vec<f64> = s[1]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect();
                (s[0].as_f64().unwrap(), vertical_shift(&rest[0], &col))
            })
            .collect();
        let rms = |lo: f64, hi: f64| {
            let v: Vec<f64> = samples
                .iter()
                .filter(|s| s.0 >= lo && s.0 < hi)
                .map(|s| s.1)
                .collect();
            (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
        };
        let early = &samples[..samples.iter().take_while(|s| s.0 < 500.0).count()];
        let other_side = early
            .iter()
            .map(|s| -s.1 * dy.signum())
            .fold(f64::MIN, f64::max);
        let (first, last) = (rms(0.0, 500.0), rms(2500.0, 3000.0));
        println!(
            "released: {} frames in 3 s (page shows {:.1} frames/s); swings {other_side:.2} px to the other side within 0.5 s; rms shift {first:.2} px over the first 0.5 s, {last:.2} px over 2.5-3 s",
            samples.len(),
            trace[1].as_f64().unwrap()
        );
        assert!(
            other_side > 1.0,
            "let go, the free end did not swing through rest ({other_side:.2} px)"
        );
        assert!(
            last < 0.5 * first,
            "the motion did not die away: rms {first:.2} then {last:.2} px"
        );
    }

    // For the README: the free end pulled up 8 px and held, the arrow drawn.
    let (gx, gy) = at(grab.0, grab.1);
    let (tx, ty) = at(grab.0, grab.1 - 8.0);
    let hold = MouseActions::new("mouse".into())
        .then(mouse(gx, gy, None))
        .then(PointerAction::Down {
            button: MOUSE_BUTTON_LEFT,
        })
        .then(mouse(tx, ty, Some(Duration::from_millis(250))));
    c.perform_actions(hold).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    std::fs::create_dir_all(img_dir()).unwrap();
    let shot = c.screenshot().await.unwrap();
    std::fs::write(img_dir().join("studio-idv.png"), shot).unwrap();
    c.release_actions().await.unwrap();

    // The renderer's speed for 512x512 with 8 modes (issue 17 asks >= 30
    // rendered frames a second): printed, not asserted beyond > 0.
    let bench = c
        .execute_async(
            "const done = arguments[arguments.length - 1]; window.studio.idvBench(512, 512, 8, 30, 3000).then(done);",
            vec![],
        )
        .await
        .unwrap();
    println!(
        "IDV renderer, 512x512, 8 modes, in headless Chromium (software canvas): {:.1} ms a frame back to back = {:.1} frames/s; {:.1} frames/s rendered at requestAnimationFrame ({} frames)",
        bench["loop_ms_per_frame"].as_f64().unwrap(),
        bench["loop_fps"].as_f64().unwrap(),
        bench["raf_fps"].as_f64().unwrap(),
        bench["raf_frames"]
    );
    assert!(bench["loop_fps"].as_f64().unwrap() > 0.0);
    assert!(bench["raf_fps"].as_f64().unwrap() > 0.0);
    assert_eq!(counter(c, "errorSeq").await, errors, "no error shown");
}

/// Serves `page` (HTML) at every path of a second local origin
/// (127.0.0.1, another port) until the process ends; its port.
fn serve_page(page: String) -> u16 {
    use std::io::{Read, Write};
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = l.local_addr().unwrap().port();
    std::thread::spawn(move || {
        for s in l.incoming() {
            let Ok(mut s) = s else { continue };
            let _ = s.set_read_timeout(Some(Duration::from_secs(5)));
            let mut buf = [0u8; 4096];
            let _ = s.read(&mut buf);
            let _ = write!(
                s,
                "HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{page}",
                page.len()
            );
        }
    });
    port
}

/// Issue 54: a page of another local origin (another port of 127.0.0.1:
/// the same site, so the studio's `SameSite=Strict` cookie goes along)
/// tries to read the studio with `fetch`, a no-cors `fetch`, an image and
/// a WebSocket, after the same browser opened the studio with its token.
/// Every one fails in the page, and the studio's log names each refusal.
/// The studio's own page, opened through its URL, still works (the
/// cookie, not the URL, carries the token once the page is open).
#[test]
fn another_local_origin_cannot_reach_the_studio_in_headless_chromium() {
    if browser_missing() {
        return;
    }
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let video = beam_video(dir.path());
    // A live pipeline too, so that its WebSocket would open if let in.
    let studio = Studio::start(&StudioOptions {
        video: Some(video),
        ..common::live_options(dir.path())
    })
    .unwrap();
    let token = studio.token.clone().expect("a token by default");
    let sp = studio.addr.port();
    let page = format!(
        r#"<!doctype html><title>elsewhere</title><script>
window.result = {{}};
const S = "http://127.0.0.1:{sp}";
fetch(S + "/api/session", {{ credentials: "include" }})
  .then(r => r.text().then(t => {{ window.result.fetch = "read " + r.status + " " + t; }}))
  .catch(e => {{ window.result.fetch = "failed: " + e; }});
fetch(S + "/api/info?video=beam.y4m", {{ mode: "no-cors", credentials: "include" }})
  .then(r => {{ window.result.nocors = "opaque " + r.type; }})
  .catch(e => {{ window.result.nocors = "failed: " + e; }});
const img = new Image();
img.onload = () => {{ window.result.img = "loaded " + img.width; }};
img.onerror = () => {{ window.result.img = "failed"; }};
img.src = S + "/api/frame?video=beam.y4m&i=0";
const ws = new WebSocket("ws://127.0.0.1:{sp}/api/live/ws");
ws.onopen = () => {{ window.result.ws = "open"; }};
ws.onerror = () => {{ window.result.ws = "failed"; }};
</script>"#
    );
    let other = serve_page(page);
    let s = &studio;
    in_browser(|c| async move {
        // The studio's own page, through its URL: the token becomes a cookie
        // and leaves the address bar; the page opens the video.
        c.goto(&s.url).await.unwrap();
        wait_for(&c, "motionSeq", 0, 0).await;
        let here = c.current_url().await.unwrap();
        assert!(!here.as_str().contains("token"), "{here}");
        assert_eq!(here.port(), Some(sp));
        let cookie = js(&c, "return document.cookie;").await;
        assert_eq!(cookie, json!(""), "the token's cookie is HttpOnly");
        // The other origin's page, in the same browser.
        c.goto(&format!("http://127.0.0.1:{other}/")).await.unwrap();
        let t0 = Instant::now();
        let result = loop {
            let r = js(&c, "return window.result;").await;
            let done = ["fetch", "nocors", "img", "ws"]
                .iter()
                .all(|k| r[k].is_string());
            if done {
                break r;
            }
            assert!(t0.elapsed() < Duration::from_secs(20), "no outcome: {r}");
            tokio::time::sleep(Duration::from_millis(100)).await;
        };
        println!("the other origin's page saw: {result}");
        let fetch = result["fetch"].as_str().unwrap();
        assert!(fetch.starts_with("failed"), "{fetch}");
        assert_eq!(result["img"], "failed", "{result}");
        assert_eq!(result["ws"], "failed", "{result}");
        c
    });
    let log = studio.log();
    println!("the studio's log:\n{}", log.join("\n"));
    let origin = format!("Origin: http://127.0.0.1:{other}");
    for path in ["/api/session", "/api/live/ws"] {
        assert!(
            log.iter()
                .any(|l| l.contains(&format!("refused GET {path} (403)")) && l.contains(&origin)),
            "{path}: {log:?}"
        );
    }
    for path in ["/api/info", "/api/frame"] {
        assert!(
            log.iter()
                .any(|l| l.contains(&format!("refused GET {path} (403)"))
                    && (l.contains(&origin) || l.contains("Sec-Fetch-Site: same-site"))),
            "{path}: {log:?}"
        );
    }
    assert!(
        log.iter().all(|l| !l.contains(&token)),
        "the log never holds the token"
    );
}

/// A Y4M clip (`Cmono`): its header line and each frame's record (the
/// `FRAME` line and the pixels), as bytes.
fn y4m_records(bytes: &[u8]) -> (Vec<u8>, Vec<Vec<u8>>, usize, usize) {
    let line_end = |from: usize| from + bytes[from..].iter().position(|&b| b == b'\n').unwrap() + 1;
    let h_end = line_end(0);
    let header = String::from_utf8_lossy(&bytes[..h_end]).to_string();
    assert!(header.contains("Cmono"), "{header}");
    let field = |c: char| -> usize {
        header
            .split_whitespace()
            .find_map(|t| t.strip_prefix(c))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (w, h) = (field('W'), field('H'));
    let mut frames = Vec::new();
    let mut at = h_end;
    while at < bytes.len() {
        let end = line_end(at) + w * h;
        frames.push(bytes[at..end].to_vec());
        at = end;
    }
    (bytes[..h_end].to_vec(), frames, w, h)
}

#[test]
fn live_magnified_view_shows_its_drops_and_equals_the_magnify_command_in_headless_chromium() {
    if browser_missing() {
        return;
    }
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let clip = magnified_clip(dir.path());
    let studio = magnified_studio(dir.path(), &clip);
    let shown = std::sync::Mutex::new(Vec::new());
    let (s, sh) = (&studio, &shown);
    in_browser(|c| async move {
        let got = drive_magnified(&c, s).await;
        *sh.lock().unwrap() = got;
        c
    });
    // Stopping the studio finalises the pipeline's own output, which holds
    // every frame the magnifier made, each with its number (`Xseq`).
    drop(studio);
    same_as_the_command(dir.path(), &clip, &shown.into_inner().unwrap());
}

/// One change of band and factor made on the page: the frame it took
/// effect at, and a later frame the page drew (its number and pixels).
struct Shown {
    k: u64,
    m: u64,
    page: Vec<u8>,
}

/// The band and factor the page sets.
const MAG_CHANGE: (f64, f64, f64) = (10.0, 14.0, 8.0);

/// The first change is compared: the page's frame M is the pipeline's own
/// frame M, bit for bit, and that is the `magnify` command's output on the
/// frames K..=M the magnifier got (those in the pipeline's output: a frame
/// dropped before the magnifier is not in it, and the magnifier's
/// band-pass steps once a frame it gets) with the same band and factor,
/// within the dither's one level (the dither is keyed on the frame number,
/// which starts at 0 in the cut clip), and not the command's with the band
/// the pipeline started with. On a machine where the magnifier keeps up
/// with the replay, no frame is missing from the cut.
fn same_as_the_command(dir: &Path, clip: &Path, shown: &[Shown]) {
    let (header, records, w, h) = y4m_records(&std::fs::read(clip).unwrap());
    let (_, out, ow, oh) = y4m_records(&std::fs::read(dir.join("out.y4m")).unwrap());
    assert_eq!((ow, oh), (2 * w, h));
    let seq_of = |r: &[u8]| -> u64 {
        let line =
            String::from_utf8_lossy(&r[..r.iter().position(|&b| b == b'\n').unwrap()]).to_string();
        line.split_whitespace()
            .find_map(|t| t.strip_prefix("Xseq="))
            .unwrap_or_else(|| panic!("no Xseq in {line:?}"))
            .parse()
            .unwrap()
    };
    let by_seq: std::collections::HashMap<u64, &[u8]> = out
        .iter()
        .map(|r| (seq_of(r), &r[r.len() - ow * oh..]))
        .collect();
    println!(
        "the pipeline's output: {} frames of {} in the clip",
        out.len(),
        records.len()
    );
    for s in shown {
        let missing: Vec<u64> = (s.k..=s.m).filter(|i| !by_seq.contains_key(i)).collect();
        println!(
            "  change at frame {}, page's frame {}: the magnifier dropped {missing:?}",
            s.k, s.m
        );
    }
    let Shown { k, m, page } = &shown[0];
    let (k, m) = (*k, *m);
    assert!(
        by_seq.contains_key(&k),
        "frame {k}, where the change took effect, is not in the pipeline's output"
    );
    assert!(
        by_seq.contains_key(&m),
        "the page's frame {m} is not in the pipeline's output"
    );
    assert_eq!(page.len(), ow * oh, "the magnified frame's size");
    assert!(
        page == by_seq[&m],
        "the page's frame {m} is not the pipeline's frame {m}"
    );
    let got: Vec<u64> = (k..=m).filter(|i| by_seq.contains_key(i)).collect();
    let cut = dir.join("cut.y4m");
    let mut bytes = header.clone();
    for &i in &got {
        bytes.extend_from_slice(&records[i as usize]);
    }
    std::fs::write(&cut, bytes).unwrap();
    let command = |(lo, hi, factor): (f64, f64, f64), name: &str| -> Vec<u8> {
        let output = dir.join(name);
        vibroscope::magnify::magnify(&vibroscope::magnify::MagnifyOptions {
            video: cut.clone(),
            output: output.clone(),
            lo_hz: lo,
            hi_hz: hi,
            factor,
            pyramid: vibroscope::pipeline::Pyramid::Riesz,
            side_by_side: true,
            ..Default::default()
        })
        .unwrap();
        let (_, frames, _, _) = y4m_records(&std::fs::read(&output).unwrap());
        let last = frames.last().unwrap();
        last[last.len() - ow * oh..].to_vec()
    };
    let diff = |a: &[u8], b: &[u8]| -> (u32, usize) {
        let d: Vec<u32> = a
            .iter()
            .zip(b)
            .map(|(x, y)| x.abs_diff(*y) as u32)
            .collect();
        (
            *d.iter().max().unwrap(),
            d.iter().filter(|&&v| v > 0).count(),
        )
    };
    let (max_same, n_same) = diff(page, &command(MAG_CHANGE, "same.y4m"));
    let (max_other, n_other) = diff(page, &command((3.0, 5.0, 20.0), "other.y4m"));
    println!(
        "frame {m} (band changed on the page at frame {k}; the magnifier got {} of its {} frames): \
         the page's frame is the pipeline's, bit for bit; \
         against the command with the same band and factor on those frames: largest difference {max_same} \
         ({n_same} of {} pixels differ); with the band it started with: {max_other} ({n_other} differ)",
        got.len(),
        m - k + 1,
        page.len()
    );
    assert!(max_same <= 1, "the page's frame is not the command's");
    assert!(max_other > 1, "the comparison cannot tell bands apart");
}

/// The page's magnified canvas: the last frame's number and its grey
/// values (the canvas's red channel, as the page drew it).
async fn magnified_on_page(c: &Client) -> (u64, Vec<u8>) {
    let v = live(
        c,
        "(() => { const cv = document.getElementById('livemag'); \
         const d = cv.getContext('2d').getImageData(0, 0, cv.width, cv.height).data; \
         const r = new Uint8Array(d.length / 4); for (let i = 0; i < r.length; i++) r[i] = d[4 * i]; \
         let s = ''; for (let i = 0; i < r.length; i += 32768) s += String.fromCharCode.apply(null, r.subarray(i, i + 32768)); \
         return [window.studio.live.magFrame, btoa(s)]; })()",
    )
    .await;
    let px = vibroscope_studio::api::base64_decode(v[1].as_str().unwrap()).unwrap();
    (v[0].as_u64().unwrap(), px)
}

async fn drive_magnified(c: &Client, studio: &Studio) -> Vec<Shown> {
    // 10 s of magnified frames drawn on the page, on its own clock. The
    // rate is printed, not asserted (the brief: speed targets live in
    // benchmarks): `cargo bench -p vibroscope-studio --bench live_view`
    // measures it against issue 52's 30 frames a second. Here the view
    // must be live (a frame at least every second: the replay gives 60)
    // and say what it dropped.
    let r = magnified_rate(c, studio).await;
    println!("{r}");
    assert!(r.secs >= 9.5, "measured over {:.2} s", r.secs);
    assert!(
        r.shown >= r.secs,
        "the magnified view is not live: {:.1} frames a second on the page",
        r.rate()
    );
    assert!(
        r.info.contains("frames shown") && r.info.contains("dropped before the magnifier"),
        "{}",
        r.info
    );
    std::fs::create_dir_all(img_dir()).unwrap();
    let shot = c.screenshot().await.unwrap();
    std::fs::write(img_dir().join("studio-magnified.png"), shot).unwrap();

    // A band and factor set on the page: the stage starts over at frame K
    // with them; twice, 30 frames apart (the second: a change made on a
    // magnifier that was started over already). The first is compared
    // (`same_as_the_command`).
    let (lo, hi, factor) = MAG_CHANGE;
    let mut shown = Vec::new();
    for _ in 0..2 {
        js(
            c,
            &format!(
                "for (const [id, v] of [['maglo', '{lo}'], ['maghi', '{hi}'], ['magfactor', '{factor}']]) {{ \
                   const e = document.getElementById(id); e.value = v; \
                   e.dispatchEvent(new Event('input', {{ bubbles: true }})); }} \
                 window.studio.live.magApplied = null; return 0"
            ),
        )
        .await;
        c.find(Locator::Id("magapply"))
            .await
            .unwrap()
            .click()
            .await
            .unwrap();
        let t0 = Instant::now();
        let applied = loop {
            let a = live(c, "window.studio.live.magApplied").await;
            if !a.is_null() {
                break a;
            }
            let e = js(c, "return window.studio.lastError").await;
            assert!(e.is_null(), "the page shows an error: {e}");
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "the change was not applied"
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        };
        assert_eq!(
            ["lo_hz", "hi_hz", "factor"].map(|k| applied[k].as_f64()),
            [Some(lo), Some(hi), Some(factor)],
            "the page sent what was typed: {applied}"
        );
        let k = applied["since_frame"].as_u64().unwrap();
        // 30 frames on: the band-pass has settled into the new band.
        let t0 = Instant::now();
        while live(c, "window.studio.live.magFrame")
            .await
            .as_u64()
            .unwrap()
            < k + 30
        {
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "no magnified frame 30 frames after the change at frame {k} within 10 s (the clip has {MAG_FRAMES})"
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let (m, page) = magnified_on_page(c).await;
        let info = js(
            c,
            "return document.getElementById('livemaginfo').textContent",
        )
        .await;
        assert!(
            info.as_str().unwrap().contains(&format!("since frame {k}")),
            "{info}"
        );
        shown.push(Shown { k, m, page });
    }
    shown
}
