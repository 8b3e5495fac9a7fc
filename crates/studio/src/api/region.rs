//! The region endpoints: a selected region's motion (waveform, spectrum and peaks), its
//! damping view and its image-space modal basis, each answered from the cache or computed
//! once and kept.

use axum::body::Bytes;
use axum::extract::State;
use axum::http::StatusCode;
use serde::Deserialize;
use serde_json::{json, Value};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use vibroscope::spectrum::{DisplacementTap, SpectrumOptions};

use super::cache::{answer, cached, region_key, remember, PRIVATE_MOTION, PRIVATE_NO_CACHE};
use super::idv;
use super::selection::{select, Selection};
use super::units::{scale_of, with_units};
use super::{body, fps_of, ApiError, ApiResult, App};
use crate::guard;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MotionRequest {
    video: String,
    /// `[x, y, w, h]`; none: the whole frame.
    roi: Option<[u32; 4]>,
    fps: Option<f64>,
    /// Millimetres per pixel on the object: the motion is then also given
    /// in µm or mm (as `--scale`).
    scale_mm_per_px: Option<f64>,
    /// A mask painted on the frame: a PNG the frame's size (a `data:` URL
    /// or bare base64), pixels > 0 inside; with `roi`, both must hold.
    mask: Option<String>,
}

pub(super) async fn motion(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    let r: MotionRequest = body(&b)?;
    let scale = scale_of(r.scale_mm_per_px)?;
    let axum::Json(mut v) = region_answer(app, &b, "motion", region_motion).await?;
    with_units(&mut v, scale.as_ref());
    Ok(axum::Json(v))
}

/// A recipe over a region: (video, fps, region as requested, region or the
/// whole frame, the video's probe) to its JSON answer.
type RegionRecipe = fn(&Path, Option<f64>, &Selection) -> ApiResult<Value>;

/// A region's answer (`what`: its cache key's tag) for a [`MotionRequest`]:
/// from the cache, or `compute(path, fps, roi as given, roi or the whole
/// frame, probe)` once the region is checked against the frame.
pub(super) async fn region_answer(
    app: Arc<App>,
    b: &Bytes,
    what: &'static str,
    compute: RegionRecipe,
) -> ApiResult<axum::Json<Value>> {
    let t0 = Instant::now();
    let r: MotionRequest = body(b)?;
    let path = guard::resolve(&app.root, &r.video)?;
    let fps = fps_of(&app, r.fps)?;
    let key = region_key(what, &path, r.roi, r.mask.as_deref(), fps);
    let queue = app.clone();
    let (v, was_cached) = queue
        .analyses
        .run(move || {
            region_cached(
                &app,
                key,
                &path,
                fps,
                (r.roi, r.mask.as_deref()),
                compute,
                |_| Ok(()),
            )
        })
        .await?;
    Ok(answer(&v, was_cached, t0.elapsed().as_secs_f64() * 1e3))
}

/// A region's answer kept under `key` (and whether it was), else computed
/// by `compute` over the selection (`roi`, `mask`) once `check` accepts
/// it, and kept. Blocking: call it through [`blocking`](super::blocking).
fn region_cached(
    app: &App,
    key: String,
    path: &Path,
    fps: Option<f64>,
    (roi, mask): (Option<[u32; 4]>, Option<&str>),
    compute: impl FnOnce(&Path, Option<f64>, &Selection) -> ApiResult<Value>,
    check: impl FnOnce(&Selection) -> ApiResult<()>,
) -> ApiResult<(Arc<Value>, bool)> {
    if let Some(v) = cached(app, &key) {
        return Ok((v, true));
    }
    let sel = select(path, fps, roi, mask, app.max_pixel_frames)?;
    check(&sel)?;
    let mut v = compute(path, fps, &sel)?;
    sel.describe(&mut v);
    if let Some(o) = v.as_object_mut() {
        if o.remove(PRIVATE_NO_CACHE).is_some() {
            return Ok((Arc::new(v), false));
        }
    }
    Ok((remember(app, key, v), false))
}

/// The damping request's fields that name its range, in its errors.
const RANGE_FIELDS: &str = "lo_hz/hi_hz";

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DampingRequest {
    video: String,
    roi: Option<[u32; 4]>,
    mask: Option<String>,
    fps: Option<f64>,
    lo_hz: f64,
    hi_hz: f64,
}

/// The damping view (thesis 5.4.2) over a dragged range of a region's
/// spectrum: the region's answer (cached, or computed and kept), then the
/// Lorentzian over the range and SSI's poles for it
/// ([`vibroscope::damping::damping_over`]).
pub(super) async fn damping(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    let t0 = Instant::now();
    let r: DampingRequest = body(&b)?;
    let path = guard::resolve(&app.root, &r.video)?;
    let fps = fps_of(&app, r.fps)?;
    let key = region_key("motion", &path, r.roi, r.mask.as_deref(), fps);
    let queue = app.clone();
    let v = queue
        .analyses
        .run(move || {
            // A range the recording cannot have is refused before the work.
            let check = |sel: &Selection| match sel.probe.fps {
                Some(rate) => Ok(vibroscope::damping::check_range(
                    (r.lo_hz, r.hi_hz),
                    rate,
                    RANGE_FIELDS,
                )?),
                None => Ok(()),
            };
            let sel = (r.roi, r.mask.as_deref());
            let (m, _) = region_cached(&app, key, &path, fps, sel, region_motion, check)?;
            let internal = |what: &str| {
                ApiError::new(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    format!("the region's {what} is missing"),
                )
            };
            let sp: vibroscope::peaks::SpectrumDb =
                serde_json::from_value(m["spectrum"].clone()).map_err(|_| internal("spectrum"))?;
            let motion: Vec<f64> = serde_json::from_value(m[PRIVATE_MOTION].clone())
                .map_err(|_| internal("motion"))?;
            let fs = m["sample_rate_hz"]
                .as_f64()
                .ok_or_else(|| internal("sample rate"))?;
            let d = vibroscope::damping::damping_over(
                &sp,
                fs,
                m["taper"].as_str(),
                &motion,
                (r.lo_hz, r.hi_hz),
                RANGE_FIELDS,
            )?;
            Ok(json!({ "roi": r.roi, "sample_rate_hz": fs, "damping": d }))
        })
        .await?;
    Ok(answer(&v, false, t0.elapsed().as_secs_f64() * 1e3))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BasisRequest {
    video: String,
    roi: Option<[u32; 4]>,
    mask: Option<String>,
    fps: Option<f64>,
    /// `auto` (default) or `F1,F2,LO-HI` (Hz), as `vibroscope idv --modes`.
    modes: Option<String>,
    /// At most this many modes with `auto` (default 8).
    max_modes: Option<usize>,
}

/// The region's image-space modal basis ([`idv`]): cached per
/// video, region, rate and modes like the other region answers; a basis
/// whose answer would be too large is refused before the work.
pub(super) async fn idv_basis(
    State(app): State<Arc<App>>,
    b: Bytes,
) -> ApiResult<axum::Json<Value>> {
    let t0 = Instant::now();
    let r: BasisRequest = body(&b)?;
    let path = guard::resolve(&app.root, &r.video)?;
    let fps = fps_of(&app, r.fps)?;
    let choice = idv::Choice::parse(r.modes.as_deref(), r.max_modes)?;
    let tag = format!("idv-basis|{}|{}", choice.text, choice.max_modes);
    let key = region_key(&tag, &path, r.roi, r.mask.as_deref(), fps);
    let queue = app.clone();
    let (v, was_cached) = queue
        .analyses
        .run(move || {
            let c2 = choice.clone();
            let name = r.video.clone();
            region_cached(
                &app,
                key,
                &path,
                fps,
                (r.roi, r.mask.as_deref()),
                move |p, f, sel| {
                    let mut v = idv::basis_answer(&name, p, f, sel, &c2)?;
                    if v["payload_bytes"].as_u64().unwrap_or(u64::MAX) > idv::MAX_CACHED_PAYLOAD {
                        v[PRIVATE_NO_CACHE] = json!(true);
                    }
                    Ok(v)
                },
                |sel| choice.check_size(sel),
            )
        })
        .await?;
    Ok(answer(&v, was_cached, t0.elapsed().as_secs_f64() * 1e3))
}

/// The spectrum recipe (its peaks with damping and uncertainty) and the
/// region's displacement, from one run over the recording.
fn region_motion(path: &Path, fps: Option<f64>, sel: &Selection) -> ApiResult<Value> {
    let mut o = SpectrumOptions::new(path, "studio-unused.json");
    o.fps = fps;
    o.peaks = 8;
    o.include_spectrum = true;
    o.region = sel.region();
    // The motion the spectrum came from, kept for the damping view's SSI.
    let wav = vibroscope::files::TempPath::new("studio-motion.wav");
    o.motion_wav = Some(wav.path().to_path_buf());
    let tap = DisplacementTap::new(vec![sel.whole]).with_mask(sel.mask_path());
    let (report, _run) = vibroscope::spectrum::run_spectrum_with(&o, true, Some(&tap))?;
    let (_, signal) = vibroscope::files::read_wav_mono(wav.path()).map_err(|e| {
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("the region's motion WAV: {e}"),
        )
    })?;
    let regions = tap.read()?;
    let m = regions.into_iter().next().unwrap_or_default();
    let freqs: Vec<f64> = report.peaks.iter().map(|p| p.frequency_hz).collect();
    let (amps, _) = vibroscope::motion::peak_amplitudes(
        &freqs,
        report.resolution_hz,
        &m,
        None,
        vibroscope::units::Quantity::Displacement,
    );
    let peaks: Vec<Value> = report
        .peaks
        .iter()
        .zip(amps)
        .map(|(p, a)| {
            json!({
                "frequency_hz": p.frequency_hz,
                "frequency_std_hz": p.frequency_std_hz,
                "damping_ratio": p.damping_ratio,
                "damping_ratio_std": p.damping_ratio_std,
                "damping_method": p.damping_method,
                "prominence_db": p.prominence_db,
                "false_alarm": p.false_alarm,
                "floor_db": p.floor_db,
                "power_db": p.power_db,
                "resolved": p.resolved,
                "amplitude_px": a,
            })
        })
        .collect();
    let mut v = json!({
        "sample_rate_hz": report.sample_rate_hz,
        "resolution_hz": report.resolution_hz,
        "spectrum": report.spectrum,
        "taper": report.taper,
        "peaks": peaks,
        // What the resonance test turned away, with why (issue 51).
        "others": report.others.iter().map(|p| json!({
            "frequency_hz": p.frequency_hz,
            "class": p.class,
            "class_reason": p.class_reason,
        })).collect::<Vec<Value>>(),
        "waveform": { "rate_hz": m.rate_hz, "t_s": m.t_s, "x_px": m.x, "y_px": m.y },
    });
    // Kept on the server, not sent (see `answer`).
    v[PRIVATE_MOTION] = json!(signal);
    Ok(v)
}
