//! A stored calibration (REPORT.json of `calibrate`) applied to a finished
//! recovery (`listen --calibration`).

use crate::error::{Error, Result};
use crate::math::calibrate::{self as cal, Correction};
use crate::pipeline::Denoise;
use std::path::Path;

/// A stored report, parsed (errors name the file).
fn read_report(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    serde_json::from_str(&text).map_err(|e| Error::input(path, format!("not JSON: {e}")))
}

/// A stored calibration (`listen --calibration`), its file read once.
pub struct Stored {
    /// The reusable corrections (`effects`).
    pub corrections: Vec<Correction>,
    /// The recovery's frame (`pixel_frame`), if any.
    pub frame: Option<cal::PixelFrame>,
    /// What the explainer kept (`explained`): each term's observable,
    /// tiles and FIR.
    pub explained: Vec<cal::StoredTerm>,
    /// What the run's notes say of the stored effects, one sentence each:
    /// kept effects the report's own identifiability check cannot tell
    /// from none ([`cal::Unsettled`]: applied, and said), and a static
    /// response's inverse left out because the calibration's residual
    /// still holds harmonics ([`cal::harmonics_left_from_report`]),
    /// where a transfer function's inverse boosts ([`boost_note`]), and
    /// linear corrections measured on a sweep that drove the object into
    /// its nonlinear range ([`cal::level_dependent_from_report`]).
    pub notes: Vec<String>,
}

/// Reads a stored report (errors name the file and the field).
pub fn load(path: &Path) -> Result<Stored> {
    let v = read_report(path)?;
    let named = |m: cal::ReportError| Error::input(path, m.to_string());
    let mut corrections = cal::reusable_from_report(&v).map_err(named)?;
    // A static response's inverse fitted on the calibration's own
    // amplitudes is carried only when it explained the harmonics it was
    // kept for: one that leaves them is a compromise over those
    // amplitudes, which another recording does not share. One derived
    // from the object's fitted response (`"fitted": "response"`) is meant
    // for other amplitudes and leaves some of the sweep's harmonics by
    // design (it trades the sweep's peaks for the amplitudes speech spends
    // its time at), so it is carried.
    let left = cal::harmonics_left_from_report(&v).map_err(named)?;
    let mut notes = Vec::new();
    if !left.is_empty() {
        let (dropped, kept): (Vec<Correction>, Vec<Correction>) =
            corrections.into_iter().partition(|c| {
                c.needs_frame()
                    && !matches!(
                        c,
                        Correction::Polynomial {
                            from_response: true,
                            ..
                        }
                    )
            });
        corrections = kept;
        if !dropped.is_empty() {
            let names: Vec<&str> = dropped.iter().map(|c| c.kind().name()).collect();
            let orders: Vec<String> = left.iter().map(u32::to_string).collect();
            notes.push(format!(
                "{} left out: its calibration's residual still holds the reference's harmonics (order {}), so the inverse it fitted is a compromise over that recording's amplitudes, not the object's response, and on a recording whose amplitudes spread otherwise it would part from it; calibrate on a signal whose level varies, or lower the level",
                names.join(" and "),
                orders.join(", ")
            ));
        }
    }
    // A kept effect its calibration cannot tell from none is applied (the
    // other explanation is no safer: a single sweep confounds a true clock
    // error with a resonance's phase as well as a false one), and said.
    notes.extend(
        cal::unsettled_from_report(&v)
            .map_err(named)?
            .into_iter()
            .filter(|u| corrections.iter().any(|c| c.kind().name() == u.effect))
            .map(|u| u.why),
    );
    notes.extend(corrections.iter().filter_map(boost_note));
    // A sweep that drove the object into its nonlinear range: the table
    // leaves those frequencies out, but a phase or gain measured around
    // them may still carry the level's effect (issue 50, session 63: a
    // clock error read from a compressed resonance's phase).
    let level = cal::level_dependent_from_report(&v).map_err(named)?;
    let linear: Vec<&str> = corrections
        .iter()
        .filter(|c| matches!(c, Correction::Transfer { .. } | Correction::TimeBase { .. }))
        .map(|c| c.kind().name())
        .collect();
    if let (Some(lo), Some(hi), false) = (
        level.iter().copied().reduce(f64::min),
        level.iter().copied().reduce(f64::max),
        linear.is_empty(),
    ) {
        notes.push(format!(
            "the calibration's sweep drove the object into its nonlinear range at {lo:.0}-{hi:.0} Hz (its report's level_dependent): the transfer table leaves those frequencies out, but {} {} measured on a sweep whose gain and phase there change with its level; if this recording comes out worse with the calibration than without, that is the likely cause: calibrate again at a lower level",
            linear.join(" and "),
            if linear.len() > 1 { "were" } else { "was" }
        ));
    }
    Ok(Stored {
        corrections,
        frame: cal::frame_from_report(&v).map_err(named)?,
        explained: cal::explained_from_report(&v).map_err(named)?,
        notes,
    })
}

/// The boost (dB) from which a transfer function's inverse is said.
const BOOST_NOTE_DB: f64 = 6.0;

/// Where a stored transfer function's inverse boosts by [`BOOST_NOTE_DB`]
/// or more over its median gain (the object's response is weak there): a
/// sentence saying what else it boosts. Measured in session 55 on the
/// protocol's `resonance_dip` (a -10 dB dip at 800 Hz, a camera at 2200
/// fps): the inverse calibrated on the chirp took speech whose content
/// reaches past 1100 Hz from 10.07 to 6.20 dB (the dip's exact inverse
/// lowered it too), and speech with nothing above 1 kHz from 13.81 to
/// 19.86 dB.
fn boost_note(c: &Correction) -> Option<String> {
    let Correction::Transfer { freqs_hz, .. } = c else {
        return None;
    };
    let gain = |f: f64| {
        c.response(f)
            .map_or(0.0, |g| 20.0 * g.norm().max(1e-300).log10())
    };
    let all: Vec<(f64, f64)> = freqs_hz.iter().map(|&f| (f, gain(f))).collect();
    // Against the table's median gain: a gain common to all frequencies is
    // the recovery's scale, not a boost.
    let mut sorted: Vec<f64> = all.iter().map(|&(_, g)| g).collect();
    sorted.sort_by(f64::total_cmp);
    let median = *sorted.get(sorted.len() / 2)?;
    let over: Vec<(f64, f64)> = all
        .into_iter()
        .map(|(f, g)| (f, g - median))
        .filter(|&(_, b)| b >= BOOST_NOTE_DB)
        .collect();
    let (lo, hi) = (over.first()?.0, over.last()?.0);
    let most = over.iter().map(|&(_, b)| b).fold(f64::MIN, f64::max);
    Some(format!(
        "transfer_function boosts by up to {most:.1} dB (against its median) at {lo:.0}-{hi:.0} Hz, where the object's response is weak: whatever else this recording holds there is boosted with it (content above the camera's Nyquist frequency folded back into that band, noise, another vibration), which its calibration on a sweep below that frequency cannot see; if this recording comes out worse with the calibration than without, that is the likely cause"
    ))
}

/// A new recording's observables, measured in the run that recovers it:
/// the region's motion and its tiles' (the recovery's frame) and the
/// tiles a stored calibration's explained terms average.
pub struct Observe {
    tiles: Tiles,
    temp: crate::io::atomic::TempPath,
}

/// The tiles a new recording's observables are measured on
/// ([`Observe::tiles`]).
#[derive(Clone, Debug, Default)]
pub struct Tiles {
    /// The region first, then its own tiles, then each explained term's
    /// tiles not already among them.
    pub rects: Vec<[u32; 4]>,
    /// How many of `rects` after the region are the region's own tiles
    /// (those `calibrate` reads the recovery's frame on:
    /// [`crate::calibrate::observation_tiles`] overlapping the region).
    pub region_tiles: usize,
}

impl Tiles {
    pub fn is_empty(&self) -> bool {
        self.rects.is_empty()
    }
}

impl Observe {
    /// The tiles a new recording's observables are measured on: the
    /// region first, then the region's own tiles (as `calibrate` observes
    /// them), then each term's tiles (each once). A term's tile
    /// outside `video`'s frame, or more tiles than one stage measures, is
    /// an error naming `calibration` (the report was fitted on another
    /// camera or frame size, or is damaged).
    pub fn tiles(
        (video, region): (&Path, &crate::pipeline::Region),
        calibration: &Path,
        terms: &[cal::StoredTerm],
    ) -> Result<Tiles> {
        let layout = crate::calibrate::strip_rows(video, region)?;
        let (w, h) = (u64::from(layout.width), u64::from(layout.height));
        let mut rects = vec![layout.region()];
        rects.extend(
            crate::calibrate::observation_tiles(layout.width, layout.height, layout.region())
                .into_iter()
                .filter_map(|(r, inside)| inside.then_some(r)),
        );
        let region_tiles = rects.len() - 1;
        for (k, t) in terms.iter().enumerate() {
            for r in &t.tiles {
                let [x, y, rw, rh] = r.map(u64::from);
                if x + rw > w || y + rh > h {
                    return Err(Error::input(
                        calibration,
                        format!(
                            "explained[{k}].tiles: {r:?} (x, y, w, h) lies outside the {w}x{h} frame of {}: it was fitted on another camera or frame size",
                            video.display()
                        ),
                    ));
                }
                if !rects[1..].contains(r) {
                    rects.push(*r);
                }
            }
        }
        let most = crate::stages::transform::displacement::MAX_REGIONS;
        if rects.len() > most {
            return Err(Error::input(
                calibration,
                format!(
                    "explained: its terms and the region's own tiles measure {} tiles; at most {}",
                    rects.len() - 1,
                    most - 1
                ),
            ));
        }
        Ok(Tiles {
            rects,
            region_tiles,
        })
    }

    /// Adds the measuring branch to `decl` (on the listen pipeline's
    /// source), on [`Observe::tiles`].
    pub fn add(
        decl: &mut crate::engine::config::PipelineDecl,
        (video, region): (&Path, &crate::pipeline::Region),
        calibration: &Path,
        terms: &[cal::StoredTerm],
    ) -> Result<Observe> {
        let tiles = Self::tiles((video, region), calibration, terms)?;
        let temp = crate::io::atomic::TempPath::new("observed.csv");
        crate::calibrate::add_observe(decl, &tiles.rects, temp.path())?;
        Ok(Observe { tiles, temp })
    }

    /// After the run: the recovery in the WAV at `path` brought to the
    /// calibration's frame. Its scale against the region's motion along
    /// the stored direction, over the stored scale, gives the ratio; the
    /// explained terms' parts (on the tiles measured here: through their
    /// taps times the ratio, or fitted to this recording where the
    /// calibration says so, [`cal::Explanation::refit`]) are subtracted,
    /// then `corrections` rescaled by the
    /// ratio apply as in [`apply_to_wav`] (with `denoise`); the WAV is
    /// rewritten once. Returns notes: what was done, then what the
    /// corrections say of this recording ([`apply_to_wav`]'s).
    pub fn apply(
        &self,
        path: &Path,
        (corrections, denoise): (&[Correction], Denoise),
        frame: cal::PixelFrame,
        terms: &[cal::StoredTerm],
    ) -> Result<Vec<String>> {
        let observed = crate::calibrate::read_observed(self.temp.path())?;
        apply_observed(
            path,
            (&self.tiles, &observed),
            (corrections, denoise),
            frame,
            terms,
        )
    }
}

/// Which of a tile's three channels of observables (motion x, y,
/// intensity, as the `displacement` stage writes them) an observable is
/// read from (a line's intensity from its tiles' intensity).
pub fn observed_channel(o: cal::Observable) -> usize {
    match o {
        cal::Observable::MotionX => 0,
        cal::Observable::MotionY => 1,
        cal::Observable::Intensity
        | cal::Observable::RowIntensity
        | cal::Observable::ColumnIntensity => 2,
    }
}

/// [`Observe::apply`] with the observables already read: `observed` holds
/// three channels (motion x, y, intensity) for each tile of `tiles`
/// ([`Observe::tiles`]), one value per frame.
pub fn apply_observed(
    path: &Path,
    (tiles, observed): (&Tiles, &[Vec<f64>]),
    (corrections, denoise): (&[Correction], Denoise),
    frame: cal::PixelFrame,
    terms: &[cal::StoredTerm],
) -> Result<Vec<String>> {
    let (rate, y) = crate::io::wav::read_mono(path)?;
    let fs = f64::from(rate);
    if observed.len() != 3 * tiles.rects.len() || tiles.rects.is_empty() {
        return Err(Error::Analysis(format!(
            "{} channels of observables for {} tiles",
            observed.len(),
            tiles.rects.len()
        )));
    }
    let n = y.len().min(observed[0].len());
    let hp = cal::Options::for_rate(fs).highpass;
    // The region's own tiles, read as `calibrate` read them; a frame
    // stored before tiles were read (0) is met by the region's motion.
    let own: Vec<(&[f64], &[f64])> = match frame.tiles {
        0 => Vec::new(),
        _ => (1..=tiles.region_tiles)
            .filter(|k| observed.len() >= 3 * k + 2)
            .map(|k| (&observed[3 * k][..n], &observed[3 * k + 1][..n]))
            .collect(),
    };
    let here = cal::pixel_frame_on_tiles(
            &y[..n],
            (&observed[0][..n], &observed[1][..n]),
            &own,
            fs,
            hp,
            Some(frame.direction_deg),
        )
        .ok_or_else(|| {
            Error::Analysis(format!(
                "{}: the region does not move measurably along {:.1}°, so the calibration cannot be brought to this recording's scale",
                path.display(),
                frame.direction_deg
            ))
        })?;
    let ratio = here.recovery_per_px / frame.recovery_per_px;
    // Carried through its stored taps: only a tile's motion, which is in
    // pixels. A line's weights belong to each reference frame of the
    // recording they were fitted on; a tile's brightness that follows the
    // reference is motion (inside the region, the object's own) seen
    // through the texture under that tile, in DN per pixel of motion that
    // another texture (or the same one lit otherwise) does not share
    // (issue 50, session 65: on the protocol's `square_at_resonance`, such
    // a term subtracted through its taps took the speech from 20.71 to
    // 5.22 dB). Either is carried only where fitted again here.
    let (terms, stranded): (Vec<&cal::StoredTerm>, Vec<&cal::StoredTerm>) = terms
        .iter()
        .partition(|t| t.refit || t.observable.is_motion());
    // Each weighed term's tiles' own noise on this recording, which bounds
    // what subtracting it can remove here (said in the note).
    let mut noisy: Vec<String> = Vec::new();
    let measured: Vec<cal::Measured> = terms
        .iter()
        .map(|t| {
            // A tile's channel of the run, by its rectangle.
            let of = |i: usize| -> &[f64] {
                let k = tiles
                    .rects
                    .iter()
                    .skip(1)
                    .position(|x| *x == t.tiles[i])
                    .map_or(0, |k| k + 1);
                &observed[3 * k + observed_channel(t.observable)][..n]
            };
            let channels = if t.observable.is_line() {
                cal::line_channels(t.observable, &t.tiles, n, of)
            } else {
                // The tiles' mean as the explainer pooled them: weighed
                // each by its noise on this recording, or plain.
                let tiles: Vec<&[f64]> = (0..t.tiles.len()).map(of).collect();
                vec![match t.weighed {
                    true => {
                        let (pooled, share) = cal::pooled_motion_and_share(&tiles, fs, hp);
                        if let Some(q) = share {
                            noisy.push(noise_words(t, q));
                        }
                        pooled
                    }
                    false => cal::mean_of(&tiles),
                }]
            };
            cal::Measured {
                observable: t.observable,
                channels,
                shifts: t.shifts.clone(),
                reach: crate::calibrate::recovery_reach(),
                // This recording's references, as its recovery renewed them.
                spans: cal::reference_spans(
                    n,
                    match t.observable.is_line() {
                        true => crate::calibrate::recovery_renewal(fs),
                        false => None,
                    },
                ),
                taps: (!t.refit).then(|| t.taps.iter().map(|a| a * ratio).collect()),
            }
        })
        .collect();
    let (mut z, removed) = cal::remove_explained(&y[..n], &measured, fs, hp);
    z.extend_from_slice(&y[n..]);
    let rescaled: Vec<Correction> = corrections.iter().map(|c| c.rescaled(ratio)).collect();
    let said = write_corrected(path, (rate, &z), &rescaled, denoise)?;
    let on = |f: &cal::PixelFrame| match f.tiles {
        0 => "the region's motion".to_string(),
        k => format!("{k} of the region's tiles that move with the recovery"),
    };
    let mut note = format!(
            "the recovery reads {:.4e} per px of motion along {:.1}° here (on {}), {:.4e} on the calibration's recording (on {}; ratio {ratio:+.4})",
            here.recovery_per_px, frame.direction_deg, on(&here), frame.recovery_per_px, on(&frame)
        );
    let refit = terms.iter().filter(|t| t.refit).count();
    if refit > 0 {
        note.push_str(&format!(
                "; {refit} explained term(s) measured again here, fitted to this recording and subtracted ({:.1}% of its energy: their observables do not follow the calibration's reference)",
                100.0 * removed
            ));
    }
    if terms.len() > refit {
        note.push_str(&format!(
                "; {} explained term(s) measured again here and subtracted through the stored FIR (their observables follow the calibration's reference: fitted here, they would remove the sound)",
                terms.len() - refit
            ));
    }
    for words in &noisy {
        note.push_str(&format!("; {words}"));
    }
    let lines = stranded.iter().filter(|t| t.observable.is_line()).count();
    if lines > 0 {
        note.push_str(&format!(
            "; {lines} explained term(s) of the sensor's lines left out: their observables follow the calibration's reference, and their weights belong to the reference frames of the calibration's recording"
        ));
    }
    if stranded.len() > lines {
        note.push_str(&format!(
            "; {} explained term(s) of a tile's brightness left out: their observables follow the calibration's reference, so they are motion (the object's own, inside the region) seen through the texture under the tile, and their taps (DN per pixel of motion) belong to the calibration's recording's texture and light",
            stranded.len() - lines
        ));
    }
    if corrections.iter().any(Correction::needs_frame) {
        note.push_str(&format!(
            "; amplitude-dependent corrections rescaled by {ratio:+.4}"
        ));
    }
    Ok(std::iter::once(note).chain(said).collect())
}

/// What a term pooled from tiles weighed by their noise can remove on
/// this recording: `q` is the share of its pooled motion's power that is
/// the tiles' own noise ([`cal::pooled_noise_share`]), so subtracting it
/// removes at most about `1 - q` of what the motion it stands for costs
/// (the best gain on a signal seen through white noise).
fn noise_words(t: &cal::StoredTerm, q: f64) -> String {
    let axis = match t.observable {
        cal::Observable::MotionY => "y",
        _ => "x",
    };
    format!(
        "the motion along {axis} pooled from {} tiles is measured here with their own noise at {:.0}% of its power, so subtracting it removes at most about {:.0}% of what that motion costs this recording",
        t.tiles.len(),
        100.0 * q,
        100.0 * (1.0 - q)
    )
}

/// Applies `corrections` to the WAV at `path` in place (at its own rate).
/// With `denoise` (the recovery was denoised), the same denoiser runs
/// again after the corrections, as in the thesis' Table 4.2: equalising
/// boosts the noise in the bands it lifts, and that noise is removed
/// again. Samples keep their times.
pub fn apply_to_wav(
    path: &Path,
    corrections: &[Correction],
    denoise: Denoise,
) -> Result<Vec<String>> {
    let (rate, y) = crate::io::wav::read_mono(path)?;
    write_corrected(path, (rate, &y), corrections, denoise)
}

/// [`apply_to_wav`] on the samples `y` (at `rate`), written to `path`;
/// what it says of `y`: how much of it lies where a transfer table was
/// not measured ([`Correction::outside_measured`]).
fn write_corrected(
    path: &Path,
    (rate, y): (u32, &[f64]),
    corrections: &[Correction],
    denoise: Denoise,
) -> Result<Vec<String>> {
    let mut said: Vec<String> = corrections
        .iter()
        .filter_map(|c| c.outside_measured(y, f64::from(rate)))
        .collect();
    let (mut z, folded) = cal::apply_to_recording(corrections, y, rate as f64);
    said.extend(folded.iter().map(|f| f.note(f64::from(rate))));
    z = denoise_again(&z, rate as f64, denoise)?;
    let peak = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let ypeak = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // Keep the recovery's scale (the equaliser's level is arbitrary).
    let s = if peak > 0.0 { ypeak / peak } else { 1.0 };
    let z: Vec<f64> = z.iter().map(|v| v * s).collect();
    crate::io::wav::write_mono_f32(path, rate, &z)?;
    Ok(said)
}

/// Runs the denoiser (default settings, as the stage's) over `x`; `x`
/// itself for [`Denoise::None`]. Output sample `k` is the estimate of input
/// sample `k` (the denoisers' latency is only in when a sample is
/// released), so the whole signal is fed and finished. The signal is a
/// recording, so each denoiser is first primed on its lead, as the stage
/// does on replay.
fn denoise_again(x: &[f64], rate: f64, kind: Denoise) -> Result<Vec<f64>> {
    use crate::math::denoise::{DenoiseConfig, SpectralSubtraction, SpeechEnhance, Wiener};
    use crate::math::MathError;
    let input: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    // Every default configuration has the same noise window.
    let lead_len = (DenoiseConfig::default().noise_window_s * rate).ceil() as usize;
    let lead = &input[..lead_len.min(input.len())];
    let mut out = Vec::with_capacity(input.len());
    match kind {
        Denoise::None => return Ok(x.to_vec()),
        Denoise::Subtract => {
            let mut d = SpectralSubtraction::with_defaults(rate).map_err(MathError::from)?;
            d.prime(lead);
            d.process(&input, &mut out);
            d.finish(&mut out);
        }
        Denoise::Enhance => {
            let mut d = SpeechEnhance::with_defaults(rate).map_err(MathError::from)?;
            d.prime(lead);
            d.process(&input, &mut out);
            d.finish(&mut out);
        }
        Denoise::Wiener => {
            let mut d = Wiener::with_defaults(rate).map_err(MathError::from)?;
            d.prime(lead);
            d.process(&input, &mut out);
            d.finish(&mut out);
        }
    }
    Ok(out.iter().map(|&v| v as f64).collect())
}

/// The names of the corrections a report holds, for messages.
pub fn describe(corrections: &[Correction]) -> String {
    if corrections.is_empty() {
        return "none (the report keeps no object or camera effect)".into();
    }
    corrections
        .iter()
        .map(|c| c.kind().name())
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// A report whose residual still holds the reference's harmonics: a
    /// static response's inverse fitted on the calibration's own
    /// amplitudes is left out (and said), one derived from the fitted
    /// response (`"fitted": "response"`) is carried.
    #[test]
    fn a_static_response_derived_from_the_fitted_response_is_carried() {
        let dir = tempfile::tempdir().unwrap();
        let report = |fitted: Option<&str>| {
            let mut p = serde_json::json!({"coefficients": [-2.0, 30.0], "range": 0.02});
            if let Some(f) = fitted {
                p["fitted"] = serde_json::json!(f);
            }
            serde_json::json!({
                "effects": [{"name": "static_nonlinearity", "parameters": p}],
                "unexplained": [{"kind": "harmonics", "order": 3}]
            })
        };
        for (fitted, carried) in [(None, false), (Some("response"), true)] {
            let path = dir.path().join("report.json");
            std::fs::write(&path, report(fitted).to_string()).unwrap();
            let s = load(&path).unwrap();
            assert_eq!(s.corrections.len(), usize::from(carried), "{fitted:?}");
            assert_eq!(
                s.notes
                    .iter()
                    .any(|n| n.contains("static_nonlinearity left out")),
                !carried,
                "{fitted:?}: {:?}",
                s.notes
            );
        }
    }

    /// Issue 50 (session 63): a report whose sweep drove the object into
    /// its nonlinear range (`level_dependent`) makes `listen` say so when
    /// it applies a clock error or a transfer function, and not otherwise;
    /// a `level_dependent` entry whose frequencies are not numbers is
    /// refused, naming the field.
    #[test]
    fn linear_corrections_from_a_sweep_past_the_linear_range_are_said() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("report.json");
        let level =
            serde_json::json!({"kind": "level_dependent", "frequencies_hz": [627.0, 700.0, 799.0]});
        let clock =
            serde_json::json!({"name": "time_base", "parameters": {"clock_error_ppm": 110.0}});
        for (effects, unexplained, said) in [
            (vec![clock.clone()], vec![level.clone()], true),
            (vec![clock.clone()], vec![], false),
            (vec![], vec![level.clone()], false),
        ] {
            let report = serde_json::json!({"effects": effects, "unexplained": unexplained});
            std::fs::write(&path, report.to_string()).unwrap();
            let s = load(&path).unwrap();
            let note = s.notes.iter().find(|n| n.contains("nonlinear range"));
            assert_eq!(note.is_some(), said, "{report}: {:?}", s.notes);
            if let Some(n) = note {
                assert!(
                    n.contains("627-799 Hz") && n.contains("time_base was"),
                    "{n}"
                );
            }
        }
        let bad = serde_json::json!({"effects": [clock], "unexplained": [{"kind": "level_dependent", "frequencies_hz": ["x"]}]});
        std::fs::write(&path, bad.to_string()).unwrap();
        let Err(e) = load(&path) else {
            panic!("a bad level_dependent entry was read");
        };
        assert!(e.to_string().contains("unexplained"), "{e}");
    }

    /// Denoising again after a calibration keeps every sample at its time:
    /// a chirp in noise comes out at lag 0, as long as it went in.
    #[test]
    fn denoising_again_keeps_sample_times() {
        let fs = 2200.0;
        let mut s = 12345u64;
        let x: Vec<f64> = (0..4400)
            .map(|i| {
                let t = i as f64 / fs;
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
                let noise = ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.05;
                (2.0 * std::f64::consts::PI * (100.0 * t + 100.0 * t * t)).sin() + noise
            })
            .collect();
        for kind in [Denoise::Subtract, Denoise::Enhance] {
            let y = denoise_again(&x, fs, kind).unwrap();
            assert_eq!(y.len(), x.len(), "{kind:?}");
            let (lag, _) = crate::math::metrics::best_lag_gain(&x, &y, 500);
            assert_eq!(lag, 0, "{kind:?}");
        }
    }
}
