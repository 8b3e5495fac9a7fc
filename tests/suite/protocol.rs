//! Issue 50, item 5: the held-out protocol. Each case is an effect the
//! calibration loop should carry from one recording to the next: a
//! recording of the chirp (texture seed 1) is calibrated with the whole
//! catalog and the explainer, and the report is applied by `listen
//! --calibration` to a second recording of speech, with another texture
//! (seed 2), the opposite polarity (the object moves along 180°) and,
//! where the effect is driven by noise, another draw of it. Three
//! recoveries of the speech are scored as `calibrate` scores (held-out
//! SNR, [`crate::calibrate::held_out_snr`]):
//! - `none`: the second recording with an empty report;
//! - `with`: the second recording with the chirp's report;
//! - `ceiling`: the same speech recording without the effect, its
//!   object where the case puts it ([`framing`]; what a
//!   perfect correction would reach).
//!
//! Every case: `with` at most 0.3 dB below `none` (the transfer bar:
//! nothing found on the chirp makes the next recording worse). The
//! held-out cases also: `with - none` at least 3 dB, or 1 dB where the
//! effect is weak, which the test decides by measurement, not by name:
//! weak when it costs the speech less than 4 dB (`ceiling - none`), so
//! that 3 dB could only be gained by a correction within 1 dB of perfect.
//! The held-out exposure may instead meet the acceptance's other branch
//! (the report says what it cannot correct, and why), checked by
//! measurement: see [`held_out_exposure`]. So may an effect wholly outside
//! the object (a shaking camera, movers in view) whose correction its own
//! observables bound: `listen --calibration` says how much of each pooled
//! motion is its tiles' noise, checked against the recording rendered
//! without the sensor's noise, and the best correction made from the kept
//! observables, fitted with the truth's help, gains less than the bar
//! asks (since session 76: see [`gain_or_bounded`]).
//!
//! Which cases were looked at while the explainer and the carrying of
//! corrections were designed and tuned (`seen`), and which are run only
//! by this test, their scenes written down before any of them was run and
//! their figures reported as they came (`held_out`): see [`SEEN`] and
//! [`HELD_OUT`]. The seen half reuses the scenes of tests/suite/explain.rs
//! and of the catalog's tests; the held-out half moves each effect
//! somewhere new (another place, axis, frequency or family).
//!
//! Once run, [`HELD_OUT`]'s misses were looked at, so since session 53
//! the unseen half is a second set, [`FRESH`] (`fresh_*` tests), written
//! down and committed before it was run. [`HELD_OUT`]'s cases stay as
//! they are, each with its mark where it misses a bar.
//!
//! Later sets, each written down and committed before it ran: [`THIRD`]
//! and [`FOURTH`] (session 54, static responses), [`FIFTH`] (session 55,
//! resonances, dips, a drift and a clock, after the transfer table's ends
//! and the minimum-phase judgement of confounds), [`SIXTH`] (session 56,
//! movers inside the region, after the explainer began to observe the
//! tiles there that move on their own), [`SEVENTH`] (session 56, a shaking
//! camera with movers in view, after the tiles that move least were
//! pooled for it), [`EIGHTH`] and [`NINTH`] (session 62, static
//! responses, before and after the inverse was derived from the object's
//! fitted response), [`TENTH`] (session 62, responses that fold back
//! within the sweep: all four missed when first run), [`ELEVENTH`]
//! (session 63, resonances that drive a static response into its
//! nonlinear range), [`TWELFTH`] (session 63, more of them, written for a
//! change that was not kept and first run on the code as kept),
//! [`THIRTEENTH`] (session 64, more of them, for a change that leaves the
//! sweep's level-dependent stretch out of every linear fit), [`FOURTEENTH`]
//! (session 67, linear responses at the top of the sweep and above it,
//! for a change to the transfer table's upper end and phase), [`FIFTEENTH`]
//! (session 71, faint effects outside the object, after the explainer
//! began to keep a weak term it fits again on the next recording when it
//! lies beyond chance), [`SIXTEENTH`] (session 71, shakes of the camera
//! with movers, a light or the ring in view, for a change that weighs each
//! tile's motion by its noise when tiles are pooled), [`SEVENTEENTH`]
//! (session 74, linear responses between the last bin the fit part
//! measures and the top of the sweep, for a change, not kept, that
//! measured the stored transfer table on the whole recording once the
//! effects were chosen), [`EIGHTEENTH`] (session 74, more of them and
//! static responses at a resonance, for that change as narrowed: the
//! table extended above the fit part's last bin; not kept either),
//! [`NINETEENTH`] (session 75, dips and resonances over the band and
//! beside static responses, for a change to how `listen --calibration`
//! applies the table: a Wiener inverse against what folds into the band
//! from above the Nyquist frequency), [`TWENTIETH`] (session 76, faint
//! shakes of the camera with movers in view, for the gain bar's branch on
//! a correction bounded by its observables' noise), [`TWENTY_FIRST`]
//! (session 76, strips of the ring moving inside the region, written for a
//! change to the refitted terms' FIR length that was not kept and first
//! run on the code as kept).
//!
//! The catalog's families outside that set ([`FAMILIES`]: dropped frames,
//! the gain's drift, the region's gain) are held to the transfer bar only,
//! so that every family and the explainer has a transfer test here.
//!
//! Two scenes. `Object`: 64x64, 0.1 DN of noise, the object the central
//! half of the frame ([16, 16, 32, 32], the simulator's default) moving
//! 0.2 px at the peak (the catalog's tests), calibrated and heard over the
//! whole frame. `Site`: 128x128, 2 DN of noise, the
//! object [48, 48, 32, 32] moving 0.05 px with the chirp and 0.2 px with
//! speech, calibrated and heard on the region [32, 32, 64, 64], with the
//! rest of the frame around it for the explainer to look at.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::calibrate::{band_limited, held_out_snr, listen_video, speech_wav, write_chirp};
use crate::common::{code, run_in, stderr};
use std::path::Path;

#[derive(Clone, Copy, PartialEq)]
enum Scene {
    Object,
    Site,
}

/// One effect: where it is rendered, its keys on the chirp's recording
/// and on the speech's (the same effect; another noise draw where it is
/// driven by noise).
struct Case {
    name: &'static str,
    scene: Scene,
    chirp: &'static str,
    speech: &'static str,
    /// The speech's peak motion, px (0.2 unless said: [`speech_at`]).
    speech_px: f64,
}

const fn case(name: &'static str, scene: Scene, chirp: &'static str, speech: &'static str) -> Case {
    speech_at(name, scene, chirp, speech, 0.2)
}

/// A case whose speech peaks at `speech_px`: the simulator's static
/// response (`response_poly`) is written against each signal's own peak,
/// so a response meant to be the same in pixels on both recordings needs
/// the speech at the chirp's amplitude.
const fn speech_at(
    name: &'static str,
    scene: Scene,
    chirp: &'static str,
    speech: &'static str,
    speech_px: f64,
) -> Case {
    Case {
        name,
        scene,
        chirp,
        speech,
        speech_px,
    }
}

/// Looked at while the explainer and the carrying of corrections were
/// designed and tuned (issue 50's first part and this one).
const SEEN: [Case; 9] = [
    case(
        "camera",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2200.0, duration_s = 3.0, seed = 7 }, amplitude_px = 0.03 }"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2200.0, duration_s = 3.0, seed = 9 }, amplitude_px = 0.06 }"#,
    ),
    case(
        "light",
        Scene::Site,
        r#"light = { signal = { type = "noise", rate_hz = 400.0, duration_s = 3.0, seed = 3 }, depth = 0.3 }"#,
        r#"light = { signal = { type = "noise", rate_hz = 400.0, duration_s = 3.0, seed = 13 }, depth = 0.3 }"#,
    ),
    case(
        "other_object",
        Scene::Site,
        r#"background_motion = [{ rect = [0, 80, 128, 48], signal = { type = "noise", rate_hz = 1500.0, duration_s = 3.0, seed = 11 }, amplitude_px = 0.3 }]"#,
        r#"background_motion = [{ rect = [0, 80, 128, 48], signal = { type = "noise", rate_hz = 1500.0, duration_s = 3.0, seed = 12 }, amplitude_px = 0.3 }]"#,
    ),
    // The same object in image coordinates: along +x it moves `x + 0.25
    // x²` of what it hears; driven the other way round on the second
    // recording, that is `s + 0.25 s²` with `s` minus the speech.
    case(
        "square_law",
        Scene::Object,
        "response_poly = [0.25]",
        "response_poly = [-0.25]",
    ),
    case(
        "soft_clip",
        Scene::Object,
        "soft_clip_px = 0.12",
        "soft_clip_px = 0.12",
    ),
    case(
        "rolling_readout",
        Scene::Object,
        "line_delay_us = 6.8",
        "line_delay_us = 6.8",
    ),
    case(
        "interference",
        Scene::Object,
        "interference = [{ freq_hz = 137.0, amplitude_px = 0.03 }]",
        "interference = [{ freq_hz = 137.0, amplitude_px = 0.03 }]",
    ),
    // Added in issue 50's fourth part, to design the sensor's lines as
    // observables on: the columns, then the rows. The row noise was in
    // the held-out half; its one held-out run (+0.00 dB of the 16.09 dB
    // it costs: nothing kept, the explainer then observed only tiles) is
    // its held-out figure. It was looked at while the lines were designed
    // (the bands' lags were found on it), so it moved here.
    case(
        "column_noise",
        Scene::Site,
        "column_noise_dn = 3.0",
        "column_noise_dn = 3.0",
    ),
    case(
        "row_noise",
        Scene::Site,
        "row_noise_dn = 3.0",
        "row_noise_dn = 3.0",
    ),
];

/// Run only by this test: written down before any was run, figures as
/// they came.
const HELD_OUT: [Case; 16] = [
    case(
        "clock",
        Scene::Object,
        "clock_error_ppm = 1500.0",
        "clock_error_ppm = 1500.0",
    ),
    case(
        "exposure",
        Scene::Object,
        "exposure_us = 400.0",
        "exposure_us = 400.0",
    ),
    case(
        "resonance",
        Scene::Object,
        "resonances = [{ freq_hz = 350.0, q = 4.0, gain_db = 12.0 }]",
        "resonances = [{ freq_hz = 350.0, q = 4.0, gain_db = 12.0 }]",
    ),
    case(
        "mover_left",
        Scene::Site,
        r#"background_motion = [{ rect = [0, 0, 28, 128], signal = { type = "noise", rate_hz = 1000.0, duration_s = 3.0, seed = 5 }, amplitude_px = 0.3, direction_deg = 90.0 }]"#,
        r#"background_motion = [{ rect = [0, 0, 28, 128], signal = { type = "noise", rate_hz = 1000.0, duration_s = 3.0, seed = 6 }, amplitude_px = 0.3, direction_deg = 90.0 }]"#,
    ),
    case(
        "light_vertical",
        Scene::Site,
        r#"light = { signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 4 }, depth = 0.2, direction_deg = 90.0 }"#,
        r#"light = { signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 8 }, depth = 0.2, direction_deg = 90.0 }"#,
    ),
    case(
        "camera_tone",
        Scene::Site,
        r#"camera_motion = { signal = { type = "tone", freq_hz = 240.0 }, amplitude_px = 0.04, direction_deg = 60.0 }"#,
        r#"camera_motion = { signal = { type = "tone", freq_hz = 240.0 }, amplitude_px = 0.04, direction_deg = 60.0 }"#,
    ),
    case(
        "clock_and_resonance",
        Scene::Object,
        "clock_error_ppm = -1000.0\nresonances = [{ freq_hz = 600.0, q = 3.0, gain_db = -9.0 }]",
        "clock_error_ppm = -1000.0\nresonances = [{ freq_hz = 600.0, q = 3.0, gain_db = -9.0 }]",
    ),
    case(
        "light_and_mover",
        Scene::Site,
        r#"light = { signal = { type = "noise", rate_hz = 300.0, duration_s = 3.0, seed = 21 }, depth = 0.2, uniform = 1.0 }
background_motion = [{ rect = [100, 0, 28, 128], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 22 }, amplitude_px = 0.3 }]"#,
        r#"light = { signal = { type = "noise", rate_hz = 300.0, duration_s = 3.0, seed = 23 }, depth = 0.2, uniform = 1.0 }
background_motion = [{ rect = [100, 0, 28, 128], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 24 }, amplitude_px = 0.3 }]"#,
    ),
    // Added after the eight above had run (three of them turned out to
    // cost the speech under 1 dB: nothing in the region sees them), and
    // written down before these two were run.
    case(
        "mover_in_region",
        Scene::Site,
        r#"background_motion = [{ rect = [32, 32, 64, 12], signal = { type = "noise", rate_hz = 1200.0, duration_s = 3.0, seed = 31 }, amplitude_px = 0.2 }]"#,
        r#"background_motion = [{ rect = [32, 32, 64, 12], signal = { type = "noise", rate_hz = 1200.0, duration_s = 3.0, seed = 32 }, amplitude_px = 0.2 }]"#,
    ),
    case(
        "camera_vertical",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2200.0, duration_s = 3.0, seed = 33 }, amplitude_px = 0.04, direction_deg = 90.0 }"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2200.0, duration_s = 3.0, seed = 34 }, amplitude_px = 0.04, direction_deg = 90.0 }"#,
    ),
    // Added in issue 50's third part, written down before any of them was
    // run: four of the ten above cost the speech under 1 dB (nothing in the
    // region sees them), so these each reach the region: the camera along
    // a third direction, a mover across the region's columns, a catalog
    // effect and a shake at once, two narrowband lines, and the sensor's
    // row noise (which the explainer was known not to explain; it has
    // since moved to the seen half, above).
    case(
        "camera_diagonal",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 1800.0, duration_s = 3.0, seed = 41 }, amplitude_px = 0.04, direction_deg = 30.0 }"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 1800.0, duration_s = 3.0, seed = 42 }, amplitude_px = 0.04, direction_deg = 30.0 }"#,
    ),
    case(
        "mover_columns",
        Scene::Site,
        r#"background_motion = [{ rect = [84, 0, 44, 128], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 43 }, amplitude_px = 0.4, direction_deg = 90.0 }]"#,
        r#"background_motion = [{ rect = [84, 0, 44, 128], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 44 }, amplitude_px = 0.4, direction_deg = 90.0 }]"#,
    ),
    case(
        "resonance_and_camera",
        Scene::Site,
        r#"resonances = [{ freq_hz = 420.0, q = 5.0, gain_db = 10.0 }]
camera_motion = { signal = { type = "noise", rate_hz = 2200.0, duration_s = 3.0, seed = 45 }, amplitude_px = 0.03 }"#,
        r#"resonances = [{ freq_hz = 420.0, q = 5.0, gain_db = 10.0 }]
camera_motion = { signal = { type = "noise", rate_hz = 2200.0, duration_s = 3.0, seed = 46 }, amplitude_px = 0.03 }"#,
    ),
    case(
        "interference_pair",
        Scene::Object,
        "interference = [{ freq_hz = 95.0, amplitude_px = 0.02 }, { freq_hz = 610.0, amplitude_px = 0.015 }]",
        "interference = [{ freq_hz = 95.0, amplitude_px = 0.02 }, { freq_hz = 610.0, amplitude_px = 0.015 }]",
    ),
    // Added in issue 50's sixth part, written down (and committed) before
    // either was run, once `listen --calibration` decides by itself
    // whether to unfold a readout: a readout over most of a larger frame
    // heard on a region, and a slower one over part of the small frame.
    case(
        "readout_site",
        Scene::Site,
        "line_delay_us = 3.5",
        "line_delay_us = 3.5",
    ),
    case(
        "readout_partial",
        Scene::Object,
        "line_delay_us = 4.0",
        "line_delay_us = 4.0",
    ),
];

/// The second held-out set (session 53), written down and committed before
/// any of it was run. By then every case of [`HELD_OUT`] had been run, and
/// those that missed a bar were looked at while the explainer and the
/// carrying of corrections changed: that set is no longer unseen. These
/// ten are, and are run only by this test, their figures reported as they
/// come. Each is meant to reach what the recovery hears (the object, or
/// the whole image): of the first set, six cost the speech under 1 dB,
/// where no gain of 1 dB can be measured. The rule for such a case was
/// also written down before these ran: an effect that costs the speech
/// under 1 dB (`ceiling - none`) is held to the transfer bar alone and
/// reported as not measurable (see [`fresh`]).
const FRESH: [Case; 10] = [
    case(
        "camera_steep",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 1500.0, duration_s = 3.0, seed = 51 }, amplitude_px = 0.05, direction_deg = 120.0 }"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 1500.0, duration_s = 3.0, seed = 52 }, amplitude_px = 0.05, direction_deg = 120.0 }"#,
    ),
    case(
        "camera_and_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 53 }, amplitude_px = 0.04 }
background_motion = [{ rect = [0, 0, 128, 28], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 55 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 54 }, amplitude_px = 0.04 }
background_motion = [{ rect = [0, 0, 128, 28], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 56 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "camera_tone_low",
        Scene::Site,
        r#"camera_motion = { signal = { type = "tone", freq_hz = 170.0 }, amplitude_px = 0.05 }"#,
        r#"camera_motion = { signal = { type = "tone", freq_hz = 170.0 }, amplitude_px = 0.05 }"#,
    ),
    case(
        "mover_around_object",
        Scene::Site,
        r#"background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 1000.0, duration_s = 3.0, seed = 57 }, amplitude_px = 0.3 }]"#,
        r#"background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 1000.0, duration_s = 3.0, seed = 58 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "row_and_column_noise",
        Scene::Site,
        "row_noise_dn = 1.5\ncolumn_noise_dn = 1.5",
        "row_noise_dn = 1.5\ncolumn_noise_dn = 1.5",
    ),
    case(
        "interference_triple",
        Scene::Object,
        "interference = [{ freq_hz = 70.0, amplitude_px = 0.02 }, { freq_hz = 260.0, amplitude_px = 0.015 }, { freq_hz = 830.0, amplitude_px = 0.01 }]",
        "interference = [{ freq_hz = 70.0, amplitude_px = 0.02 }, { freq_hz = 260.0, amplitude_px = 0.015 }, { freq_hz = 830.0, amplitude_px = 0.01 }]",
    ),
    case(
        "resonance_dip",
        Scene::Object,
        "resonances = [{ freq_hz = 800.0, q = 2.5, gain_db = -10.0 }]",
        "resonances = [{ freq_hz = 800.0, q = 2.5, gain_db = -10.0 }]",
    ),
    case(
        "resonances_and_clock",
        Scene::Object,
        "clock_error_ppm = -800.0\nresonances = [{ freq_hz = 300.0, q = 5.0, gain_db = 8.0 }, { freq_hz = 900.0, q = 3.0, gain_db = -6.0 }]",
        "clock_error_ppm = -800.0\nresonances = [{ freq_hz = 300.0, q = 5.0, gain_db = 8.0 }, { freq_hz = 900.0, q = 3.0, gain_db = -6.0 }]",
    ),
    // Odd: the same on the speech's recording, whose object moves the
    // other way.
    case(
        "cubic",
        Scene::Object,
        "response_poly = [0.0, -0.3]",
        "response_poly = [0.0, -0.3]",
    ),
    case(
        "readout_mid",
        Scene::Object,
        "line_delay_us = 5.5",
        "line_delay_us = 5.5",
    ),
];

/// The third held-out set (session 54), written down and committed before
/// any of it was run. Session 54 changed how the recovery's scale in
/// pixels is read (on the region's tiles that move with it, not on the
/// whole region) after looking at [`FRESH`]'s `cubic`, so that set's
/// static responses are seen. These six carry a static response to
/// another recording where the region holds still background around the
/// object (`Site`: the region [32, 32, 64, 64] around the object [48, 48,
/// 32, 32]; `Object`: the whole frame around the central half), with
/// other terms and signs, alone or beside another effect. Their figures
/// are reported as they come, under [`fresh`]'s rules (an effect costing
/// the speech under 1 dB is held to the transfer bar alone).
const THIRD: [Case; 6] = [
    speech_at(
        "site_cubic",
        Scene::Site,
        "response_poly = [0.0, -0.3]",
        "response_poly = [0.0, -0.3]",
        0.05,
    ),
    // The even terms of the two cases below are negated on the speech's
    // recording, whose object moves the other way: the same response in
    // the image. Their first run (session 54) wrote them unnegated, a
    // response that differs between the two recordings: site_square
    // cost the speech 0.07 dB with nothing kept; mixed_poly kept
    // static_nonlinearity on the chirp (19.63 -> 30.05 dB) and took the
    // speech from 21.30 to 18.03 dB (-3.27) on that other response.
    speech_at(
        "site_square",
        Scene::Site,
        "response_poly = [0.3]",
        "response_poly = [-0.3]",
        0.05,
    ),
    case(
        "mixed_poly",
        Scene::Object,
        "response_poly = [0.15, -0.2]",
        "response_poly = [-0.15, -0.2]",
    ),
    speech_at(
        "cubic_and_camera",
        Scene::Site,
        r#"response_poly = [0.0, -0.3]
camera_motion = { signal = { type = "noise", rate_hz = 1500.0, duration_s = 3.0, seed = 61 }, amplitude_px = 0.02 }"#,
        r#"response_poly = [0.0, -0.3]
camera_motion = { signal = { type = "noise", rate_hz = 1500.0, duration_s = 3.0, seed = 62 }, amplitude_px = 0.02 }"#,
        0.05,
    ),
    case(
        "quintic",
        Scene::Object,
        "response_poly = [0.0, 0.0, 0.0, -0.4]",
        "response_poly = [0.0, 0.0, 0.0, -0.4]",
    ),
    case(
        "cubic_weak",
        Scene::Object,
        "response_poly = [0.0, -0.1]",
        "response_poly = [0.0, -0.1]",
    ),
];

/// The fourth held-out set (session 54), written down and committed
/// before any of it was run, after the third set's run had been looked at
/// (soft clips carried since, and a static response left out where its
/// calibration left harmonics). Four static responses on the `Object`
/// scene (the speech heard well), the object moved or resized so that the
/// whole-frame region holds another share of still background, one with a
/// resonance beside it. Even terms negated on the speech's recording
/// (its object moves the other way). Figures reported as they come, under
/// [`fresh`]'s rules.
const FOURTH: [Case; 4] = [
    case(
        "soft_clip_offcentre",
        Scene::Object,
        "object = [8, 20, 40, 32]\nsoft_clip_px = 0.2",
        "object = [8, 20, 40, 32]\nsoft_clip_px = 0.2",
    ),
    case(
        "cubic_offcentre",
        Scene::Object,
        "object = [20, 8, 32, 44]\nresponse_poly = [0.0, -0.25]",
        "object = [20, 8, 32, 44]\nresponse_poly = [0.0, -0.25]",
    ),
    case(
        "square_small_object",
        Scene::Object,
        "object = [22, 22, 20, 20]\nresponse_poly = [0.3]",
        "object = [22, 22, 20, 20]\nresponse_poly = [-0.3]",
    ),
    case(
        "soft_clip_and_resonance",
        Scene::Object,
        "soft_clip_px = 0.15\nresonances = [{ freq_hz = 400.0, q = 4.0, gain_db = 6.0 }]",
        "soft_clip_px = 0.15\nresonances = [{ freq_hz = 400.0, q = 4.0, gain_db = 6.0 }]",
    ),
];

/// The fifth held-out set (session 55), written down and committed before
/// any of it was run, after the transfer table's ends were held and
/// confounds involving a transfer function were judged with its phase made
/// from its gain (minimum phase), both found on `resonance_dip`. Four
/// linear effects on the `Object` scene: a dip low in the speech's band
/// (where little folds from above the camera's Nyquist frequency), a
/// resonance with a true gain drift on both recordings (the case the
/// judgement could get wrong: a drift read as a transfer function or the
/// other way), a dip with a true clock error, and two dips. Figures
/// reported as they come, under [`fresh`]'s rules. First run (session
/// 55): all four meet both bars (speech +11.76, +5.32, +3.57, +5.27 dB);
/// `resonance_and_drift` keeps no drift, `dip_and_clock` a false
/// `explained:light` beside its time base and transfer function (a tile's
/// brightness inside the region that follows the reference: named
/// `explained:object` since session 65, and not carried). With
/// the minimum-phase judgement switched off (a temporary edit), every
/// figure is the same: no confound of this set is decided by it.
const FIFTH: [Case; 4] = [
    case(
        "dip_low",
        Scene::Object,
        "resonances = [{ freq_hz = 450.0, q = 3.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 450.0, q = 3.0, gain_db = -8.0 }]",
    ),
    case(
        "resonance_and_drift",
        Scene::Object,
        "gain_decay_s = 3.0\nresonances = [{ freq_hz = 350.0, q = 4.0, gain_db = 8.0 }]",
        "gain_decay_s = 3.0\nresonances = [{ freq_hz = 350.0, q = 4.0, gain_db = 8.0 }]",
    ),
    case(
        "dip_and_clock",
        Scene::Object,
        "clock_error_ppm = 500.0\nresonances = [{ freq_hz = 600.0, q = 2.0, gain_db = -8.0 }]",
        "clock_error_ppm = 500.0\nresonances = [{ freq_hz = 600.0, q = 2.0, gain_db = -8.0 }]",
    ),
    case(
        "two_dips",
        Scene::Object,
        "resonances = [{ freq_hz = 300.0, q = 3.0, gain_db = -6.0 }, { freq_hz = 700.0, q = 3.0, gain_db = -6.0 }]",
        "resonances = [{ freq_hz = 300.0, q = 3.0, gain_db = -6.0 }, { freq_hz = 700.0, q = 3.0, gain_db = -6.0 }]",
    ),
];

/// The sixth held-out set (session 56), written down and committed before
/// any of it was run, after the explainer began to observe the tiles
/// inside the region that move on their own (found on
/// `mover_around_object`, which was looked at). Four effects inside the
/// region but off the object, on the `Site` scene: the ring around the
/// object moving across (along y), only a strip of it moving (left of the
/// object), the ring moving while the camera shakes, and a small patch
/// moving below the object. Figures reported as they come, under
/// [`fresh`]'s rules. First run (session 56): `ring_along_y` +4.87 dB of
/// the 5.52 it costs (kept explained:other_object), `ring_and_camera`
/// +4.01 of 5.25 (kept explained:camera), both met; `ring_left_strip`
/// +0.98 of 1.17 (weak, 1 dB asked: short by 0.02, marked);
/// `patch_below_object` costs 0.55 dB, under 1 dB, nothing kept (+0.00;
/// the transfer bar alone).
const SIXTH: [Case; 4] = [
    case(
        "ring_along_y",
        Scene::Site,
        r#"background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 1000.0, duration_s = 3.0, seed = 61 }, amplitude_px = 0.3, direction_deg = 90.0 }]"#,
        r#"background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 1000.0, duration_s = 3.0, seed = 62 }, amplitude_px = 0.3, direction_deg = 90.0 }]"#,
    ),
    case(
        "ring_left_strip",
        Scene::Site,
        r#"background_motion = [{ rect = [32, 32, 16, 64], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 63 }, amplitude_px = 0.3 }]"#,
        r#"background_motion = [{ rect = [32, 32, 16, 64], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 64 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "ring_and_camera",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 65 }, amplitude_px = 0.03 }
background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 67 }, amplitude_px = 0.2 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 66 }, amplitude_px = 0.03 }
background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 68 }, amplitude_px = 0.2 }]"#,
    ),
    case(
        "patch_below_object",
        Scene::Site,
        r#"background_motion = [{ rect = [40, 84, 48, 12], signal = { type = "noise", rate_hz = 1100.0, duration_s = 3.0, seed = 69 }, amplitude_px = 0.3 }]"#,
        r#"background_motion = [{ rect = [40, 84, 48, 12], signal = { type = "noise", rate_hz = 1100.0, duration_s = 3.0, seed = 70 }, amplitude_px = 0.3 }]"#,
    ),
];

/// The seventh held-out set (session 56), written down and committed
/// before any of it was run, after the explainer began to pool the tiles
/// that move least for a motion of the whole image (found on
/// `camera_and_mover`, which was looked at). Four shakes of the camera
/// with something else moving in view, on the `Site` scene: a mover in
/// the left columns, a vertical shake with a mover in the bottom rows,
/// two movers in opposite corners, and a weaker shake with a mover in
/// the right columns. Figures reported as they come, under [`fresh`]'s
/// rules. First run (session 56): `camera_and_side_mover` +3.14 dB of
/// the 5.01 it costs, `camera_and_two_movers` +3.72 of 4.74, both met;
/// `camera_y_and_mover` +1.77 of 1.95 (weak, 1 dB asked: met);
/// `camera_weak_and_mover` +0.00 of 1.61 (weak: nothing kept on the
/// chirp; marked). Each kept one term, explained:camera.
const SEVENTH: [Case; 4] = [
    case(
        "camera_and_side_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 71 }, amplitude_px = 0.04 }
background_motion = [{ rect = [0, 0, 28, 128], signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 73 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 72 }, amplitude_px = 0.04 }
background_motion = [{ rect = [0, 0, 28, 128], signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 74 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "camera_y_and_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 75 }, amplitude_px = 0.04, direction_deg = 90.0 }
background_motion = [{ rect = [0, 100, 128, 28], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 77 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 76 }, amplitude_px = 0.04, direction_deg = 90.0 }
background_motion = [{ rect = [0, 100, 128, 28], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 78 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "camera_and_two_movers",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 79 }, amplitude_px = 0.04 }
background_motion = [{ rect = [96, 0, 32, 32], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 81 }, amplitude_px = 0.3 }, { rect = [0, 96, 32, 32], signal = { type = "noise", rate_hz = 500.0, duration_s = 3.0, seed = 83 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 80 }, amplitude_px = 0.04 }
background_motion = [{ rect = [96, 0, 32, 32], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 82 }, amplitude_px = 0.3 }, { rect = [0, 96, 32, 32], signal = { type = "noise", rate_hz = 500.0, duration_s = 3.0, seed = 84 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "camera_weak_and_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 85 }, amplitude_px = 0.02 }
background_motion = [{ rect = [100, 0, 28, 128], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 87 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 86 }, amplitude_px = 0.02 }
background_motion = [{ rect = [100, 0, 28, 128], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 88 }, amplitude_px = 0.3 }]"#,
    ),
];

/// The eighth held-out set (session 62), written down and committed
/// before any of it was run, after `mixed_poly` (third set, looked at)
/// showed that an inverse polynomial fitted on a sweep of constant
/// amplitude is right at that amplitude only. Four static responses on
/// the `Object` scene, even terms negated on the speech's recording (its
/// object moves the other way): a square and a cubic term of other signs,
/// a hardening cubic, a strong square term on an object moved off
/// centre, and a response with a fifth-power term. Figures reported as
/// they come, under [`fresh`]'s rules. Run three times (session 62,
/// docs/calibration.md): on the fit before the change (gains +4.83,
/// +2.03, +6.97, +1.68: all met), once with a first version that inverted
/// the fitted response exactly (+0.00, +2.03, +0.00, +0.00: three left
/// out by `listen`, their sweep's harmonics left; seen), and with the
/// change as kept (+5.35, +2.03, +8.05, +3.02: all met).
const EIGHTH: [Case; 4] = [
    case(
        "square_and_cubic",
        Scene::Object,
        "response_poly = [-0.2, -0.15]",
        "response_poly = [0.2, -0.15]",
    ),
    case(
        "hardening",
        Scene::Object,
        "response_poly = [0.0, 0.25]",
        "response_poly = [0.0, 0.25]",
    ),
    case(
        "square_offcentre",
        Scene::Object,
        "object = [12, 16, 36, 30]\nresponse_poly = [0.4]",
        "object = [12, 16, 36, 30]\nresponse_poly = [-0.4]",
    ),
    case(
        "fifth_power_mix",
        Scene::Object,
        "response_poly = [0.1, -0.15, 0.0, -0.05]",
        "response_poly = [-0.1, -0.15, 0.0, -0.05]",
    ),
];

/// The ninth held-out set (session 62), written down and committed
/// before any of it was run, after the static response's inverse began to
/// be derived from the object's fitted response (designed on `mixed_poly`
/// and checked on the other static responses already looked at; the
/// eighth set had run once before, with a first version of it). Four
/// static responses on the `Object` scene, even terms negated on the
/// speech's recording: beside a resonance, a square term of the other
/// sign, a stiffening response with a square term, and a softening cubic
/// on a small object off centre. Figures reported as they come, under
/// [`fresh`]'s rules. First run (session 62): `cubic_and_resonance` +3.74
/// dB of 17.55 (kept transfer_function alone), `square_minus` +6.34 of
/// 6.48, `stiffening_square` +4.12 of 4.03, all met;
/// `cubic_small_offcentre` +0.73 of 0.94 (under 1 dB: transfer bar
/// alone, met). The fit before the change, run on it afterwards, met them
/// too (+3.74, +6.32, +4.04, +0.73).
const NINTH: [Case; 4] = [
    case(
        "cubic_and_resonance",
        Scene::Object,
        "response_poly = [0.0, -0.2]\nresonances = [{ freq_hz = 500.0, q = 3.0, gain_db = 6.0 }]",
        "response_poly = [0.0, -0.2]\nresonances = [{ freq_hz = 500.0, q = 3.0, gain_db = 6.0 }]",
    ),
    case(
        "square_minus",
        Scene::Object,
        "response_poly = [-0.25]",
        "response_poly = [0.25]",
    ),
    case(
        "stiffening_square",
        Scene::Object,
        "response_poly = [0.15, 0.2]",
        "response_poly = [-0.15, 0.2]",
    ),
    case(
        "cubic_small_offcentre",
        Scene::Object,
        "object = [24, 20, 18, 24]\nresponse_poly = [0.0, -0.2]",
        "object = [24, 20, 18, 24]\nresponse_poly = [0.0, -0.2]",
    ),
];

/// The tenth held-out set (session 62), written down and committed before
/// any of it was run, for a change that derived the inverse where the
/// fitted response rises, so that a response that folds back within the
/// sweep would be inverted short of the fold (designed on `quintic`,
/// third set, looked at; not kept). Four responses that fold back before the chirp's
/// peak (0.9 of the unit peak), on the `Object` scene, even terms negated
/// on the speech's recording. Figures reported as they come, under
/// [`fresh`]'s rules. First run (session 62), with that change: all four
/// missed (+0.00, +0.00, +0.00, -13.44 dB). The change was then left out
/// (it gained nothing on `quintic` either), and the set run again on the
/// code kept: `fold_one_side` +2.60 of 6.35 (static_nonlinearity), the
/// others as before. None met its gain bar, and `fold_and_resonance`
/// broke the transfer bar. Since session 63 (after they had run, so not
/// held-out figures): the three folding responses meet the gain bar by
/// the report's `response_folds` words, and `fold_and_resonance` (the case
/// the table's level-dependent bins were designed on) meets the transfer
/// bar (+0.04 dB) and the gain bar by its `level_dependent` words
/// (+0.35 since session 64).
const TENTH: [Case; 4] = [
    case(
        "fold_cubic",
        Scene::Object,
        "response_poly = [0.0, -0.45]",
        "response_poly = [0.0, -0.45]",
    ),
    case(
        "fold_one_side",
        Scene::Object,
        "response_poly = [0.2, 0.0, 0.0, -0.4]",
        "response_poly = [-0.2, 0.0, 0.0, -0.4]",
    ),
    case(
        "fold_offcentre",
        Scene::Object,
        "object = [10, 14, 36, 34]\nresponse_poly = [0.0, 0.0, 0.0, -0.45]",
        "object = [10, 14, 36, 34]\nresponse_poly = [0.0, 0.0, 0.0, -0.45]",
    ),
    case(
        "fold_and_resonance",
        Scene::Object,
        "response_poly = [0.0, -0.42]\nresonances = [{ freq_hz = 300.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [0.0, -0.42]\nresonances = [{ freq_hz = 300.0, q = 3.0, gain_db = 5.0 }]",
    ),
];

/// The eleventh held-out set (session 63), written down and committed
/// before any of it was run, for a change that leaves out of the transfer
/// table the bins where the recovery's harmonics say the gain measured
/// there holds only at the sweep's level (designed on `fold_and_resonance`,
/// tenth set, looked at from then on). Four resonances that drive a
/// static response into its nonlinear range, on the `Object` scene, even
/// terms negated on the speech's recording: a softer fold at another
/// frequency, one high in the band, a one-sided response at a resonance,
/// and a response that stiffens (its gain rises with level) at one.
/// Figures reported as they come, under [`fresh`]'s rules with the gain
/// bar's other branch ([`gain_or_level_named`]). First run (session 63):
/// +0.36 (by the report's words), -8.89 (the transfer bar missed), +1.59
/// (by the words), +9.47 dB; the session-62 code, run on them afterwards:
/// -12.89, -17.03, -2.32, +9.47. Since session 64 (the level-dependent
/// stretch left out of every fit; not held-out figures): +0.84, -1.29
/// (the transfer bar still missed), +2.82, +9.47. Since session 66 (the
/// table holds the band's median gain at the level-dependent bins):
/// +1.17, +0.06 (met), +2.42, +9.47.
const ELEVENTH: [Case; 4] = [
    case(
        "soft_fold_at_resonance",
        Scene::Object,
        "response_poly = [0.0, -0.35]\nresonances = [{ freq_hz = 450.0, q = 4.0, gain_db = 6.0 }]",
        "response_poly = [0.0, -0.35]\nresonances = [{ freq_hz = 450.0, q = 4.0, gain_db = 6.0 }]",
    ),
    case(
        "fold_at_high_resonance",
        Scene::Object,
        "response_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 700.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 700.0, q = 3.0, gain_db = 5.0 }]",
    ),
    case(
        "one_sided_at_resonance",
        Scene::Object,
        "response_poly = [0.25, -0.35]\nresonances = [{ freq_hz = 350.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [-0.25, -0.35]\nresonances = [{ freq_hz = 350.0, q = 3.0, gain_db = 5.0 }]",
    ),
    case(
        "stiffening_at_resonance",
        Scene::Object,
        "response_poly = [0.0, 0.3]\nresonances = [{ freq_hz = 400.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [0.0, 0.3]\nresonances = [{ freq_hz = 400.0, q = 3.0, gain_db = 5.0 }]",
    ),
];

/// The twelfth held-out set (session 63), written down and committed
/// before any of it was run, after the eleventh set's first run led the
/// table to leave out the flanks of a level-dependent response too. Five
/// cases on the `Object` scene, even terms negated on the speech's
/// recording: a fold at a low resonance, a compressive response at two
/// resonances, a fold at a resonance on an object off the centre, a
/// quintic at a resonance, and a square law at a resonance (its second
/// harmonic does not change the fundamental's gain, so the report's
/// words do not count there: the gain bar alone). Figures reported as
/// they come, under the eleventh set's rule. The change it was written
/// for was not kept (it made `fold_at_high_resonance`, `soft_fold_at_resonance`
/// and `cubic_and_resonance` worse), so its first run was on the code as
/// kept: +0.00 (by the words), -3.91, -1.89, -15.20, -4.48 dB, the last
/// four missing the transfer bar; the session-62 code, run on them
/// afterwards: -11.16, -2.89, -2.23, -14.32, -4.48. Since session 64
/// (the level-dependent stretch left out of every fit; not held-out
/// figures): -0.97 (the transfer bar now missed), +1.21 and +0.44 (now
/// met), -0.43 (still missed) and -4.48 (as before: no level-dependent
/// bins). Since session 66 (the table holds the band's median gain at the
/// level-dependent bins): +0.00, +1.20, +1.70, +1.76 (met) and +11.02
/// (session 65's change).
const TWELFTH: [Case; 5] = [
    case(
        "fold_low_resonance",
        Scene::Object,
        "response_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 200.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 200.0, q = 3.0, gain_db = 5.0 }]",
    ),
    case(
        "compress_two_resonances",
        Scene::Object,
        "response_poly = [0.0, -0.3]\nresonances = [{ freq_hz = 350.0, q = 4.0, gain_db = 5.0 }, { freq_hz = 650.0, q = 4.0, gain_db = 5.0 }]",
        "response_poly = [0.0, -0.3]\nresonances = [{ freq_hz = 350.0, q = 4.0, gain_db = 5.0 }, { freq_hz = 650.0, q = 4.0, gain_db = 5.0 }]",
    ),
    case(
        "fold_at_resonance_offcentre",
        Scene::Object,
        "object = [10, 14, 36, 34]\nresponse_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 500.0, q = 3.0, gain_db = 5.0 }]",
        "object = [10, 14, 36, 34]\nresponse_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 500.0, q = 3.0, gain_db = 5.0 }]",
    ),
    case(
        "quintic_at_resonance",
        Scene::Object,
        "response_poly = [0.0, 0.0, 0.0, -0.35]\nresonances = [{ freq_hz = 600.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [0.0, 0.0, 0.0, -0.35]\nresonances = [{ freq_hz = 600.0, q = 3.0, gain_db = 5.0 }]",
    ),
    case(
        "square_at_resonance",
        Scene::Object,
        "response_poly = [0.3]\nresonances = [{ freq_hz = 450.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [-0.3]\nresonances = [{ freq_hz = 450.0, q = 3.0, gain_db = 5.0 }]",
    ),
];

/// The thirteenth held-out set (session 64), written down and committed
/// before any of it was run, for a change that leaves the stretch of the
/// sweep where the gain holds only at its level out of every linear fit
/// and of the held-out score (not only the transfer table's bins), so a
/// clock error or gain read there is not carried to the speech (designed
/// on the tenth, eleventh and twelfth sets' resonances, looked at from
/// then on). Five resonances that drive a static response into its
/// nonlinear range, on the `Object` scene, even terms negated on the
/// speech's recording: a fold at a sharper resonance, a fold at a milder
/// one, a fold at a resonance beside a plain resonance that stays linear,
/// a quintic at a low resonance, and a fold at a resonance on a smaller
/// object. Figures reported as they come, under the eleventh set's rule
/// ([`gain_or_level_named`] at the resonances driving the response).
/// First run (session 64): +2.11, +0.55, +1.59, +0.38, +1.29 dB, each
/// meeting the transfer bar, and the gain bar by the report's words.
/// Since session 66 (the table holds the band's median gain at the
/// level-dependent bins; not held-out figures): +2.20, +0.67, +1.21,
/// +0.56, +1.85.
const THIRTEENTH: [Case; 5] = [
    case(
        "fold_at_sharp_resonance",
        Scene::Object,
        "response_poly = [0.0, -0.38]\nresonances = [{ freq_hz = 550.0, q = 5.0, gain_db = 6.0 }]",
        "response_poly = [0.0, -0.38]\nresonances = [{ freq_hz = 550.0, q = 5.0, gain_db = 6.0 }]",
    ),
    case(
        "fold_at_mild_resonance",
        Scene::Object,
        "response_poly = [0.0, -0.42]\nresonances = [{ freq_hz = 250.0, q = 2.5, gain_db = 4.0 }]",
        "response_poly = [0.0, -0.42]\nresonances = [{ freq_hz = 250.0, q = 2.5, gain_db = 4.0 }]",
    ),
    case(
        "fold_beside_linear_resonance",
        Scene::Object,
        "response_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 320.0, q = 3.0, gain_db = 5.0 }, { freq_hz = 750.0, q = 4.0, gain_db = -4.0 }]",
        "response_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 320.0, q = 3.0, gain_db = 5.0 }, { freq_hz = 750.0, q = 4.0, gain_db = -4.0 }]",
    ),
    case(
        "quintic_low_resonance",
        Scene::Object,
        "response_poly = [0.0, 0.0, 0.0, -0.3]\nresonances = [{ freq_hz = 300.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [0.0, 0.0, 0.0, -0.3]\nresonances = [{ freq_hz = 300.0, q = 3.0, gain_db = 5.0 }]",
    ),
    case(
        "fold_at_resonance_small_object",
        Scene::Object,
        "object = [18, 18, 28, 28]\nresponse_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 420.0, q = 3.0, gain_db = 5.0 }]",
        "object = [18, 18, 28, 28]\nresponse_poly = [0.0, -0.4]\nresonances = [{ freq_hz = 420.0, q = 3.0, gain_db = 5.0 }]",
    ),
];

/// The fourteenth held-out set (session 67), written down and committed
/// before any of it was run, for a change to the transfer table's upper
/// end and phase: above the highest frequency the sweep reached, the
/// table returns to the band's median gain (it held the last row's value,
/// a resonance's or a dip's, up to the Nyquist frequency), and its phase
/// carries no pure delay (designed on `resonance_dip`, looked at since
/// session 53, and the transfer tables of the sets before). Six linear
/// responses on the `Object` scene, at or beyond the top of the sweep
/// (the chirp's fit frames reach about 870 Hz of its 1000 Hz, as written
/// before the run; its whole recording about 920 Hz) or broad
/// enough to reach it: a dip and a resonance near the top, a dip and a
/// resonance above it, a resonance low with a dip near the top, and a
/// broad dip high in the band. Figures reported as they come, under
/// [`fresh`]'s rules. First run (session 67, on the change as first
/// written: the table returned to the median from the last bin of the fit
/// frames): +1.34, +4.85, +0.00, -0.21, +8.78, +6.30 dB, every case
/// meeting the transfer bar; the gain bar met by three and missed by the
/// dip near the top and by both effects above the sweep's band, which no
/// measurement on this sweep reaches. The change was then moved (the
/// table holds its last row to the last bin the sweep reaches over the
/// whole recording; the chirp's own held-out score had dropped by up to
/// 12 dB on cases of earlier sets, whose held-out frames at the sweep's
/// end lie above the fit frames' last bin), with this set seen: +2.51,
/// +4.98, -0.09, -0.20, +8.52, +6.18 dB (not held-out figures).
const FOURTEENTH: [Case; 6] = [
    case(
        "dip_near_top",
        Scene::Object,
        "resonances = [{ freq_hz = 860.0, q = 3.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 860.0, q = 3.0, gain_db = -8.0 }]",
    ),
    case(
        "resonance_near_top",
        Scene::Object,
        "resonances = [{ freq_hz = 880.0, q = 4.0, gain_db = 6.0 }]",
        "resonances = [{ freq_hz = 880.0, q = 4.0, gain_db = 6.0 }]",
    ),
    case(
        "dip_above_sweep",
        Scene::Object,
        "resonances = [{ freq_hz = 1000.0, q = 2.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 1000.0, q = 2.0, gain_db = -8.0 }]",
    ),
    case(
        "resonance_above_sweep",
        Scene::Object,
        "resonances = [{ freq_hz = 980.0, q = 3.0, gain_db = 6.0 }]",
        "resonances = [{ freq_hz = 980.0, q = 3.0, gain_db = 6.0 }]",
    ),
    case(
        "resonance_low_dip_top",
        Scene::Object,
        "resonances = [{ freq_hz = 350.0, q = 4.0, gain_db = 6.0 }, { freq_hz = 820.0, q = 3.0, gain_db = -6.0 }]",
        "resonances = [{ freq_hz = 350.0, q = 4.0, gain_db = 6.0 }, { freq_hz = 820.0, q = 3.0, gain_db = -6.0 }]",
    ),
    case(
        "broad_dip_high",
        Scene::Object,
        "resonances = [{ freq_hz = 720.0, q = 1.5, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 720.0, q = 1.5, gain_db = -8.0 }]",
    ),
];

/// The fifteenth held-out set (session 71), written down and committed
/// before any of it was run, after the explainer began to keep a weak
/// term (a held-out gain under `min_gain_db` but at least 0.1 dB) when
/// `listen --calibration` fits it again on the next recording and its
/// held-out removal lies beyond chance, against the same observable
/// shifted in time (found on `camera_weak_and_mover`, seventh set, then
/// looked at). Five faint effects outside the object on the `Site` scene,
/// each weak beside the sensor's 2 DN: a 0.02 px shake along y, a 0.015
/// px shake at 45°, a light varying by 4% across the image, the ring
/// around the object inside the region moving 0.08 px, and a 0.015 px
/// shake with a mover in the bottom rows. Figures reported as they come,
/// under [`fresh`]'s rules. First run (session 71): four of the five
/// cost the speech under 1 dB (`faint_shake_y` 0.66, +0.34 kept
/// explained:camera; `faint_shake_diagonal` 0.17, nothing kept;
/// `faint_light` 0.02, nothing kept; `faint_ring` 0.70, +0.65 kept
/// explained:other_object), held to the transfer bar alone, which all
/// meet; `faint_shake_and_mover` costs 1.24 dB and gains +0.05 (marked).
const FIFTEENTH: [Case; 5] = [
    case(
        "faint_shake_y",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 151 }, amplitude_px = 0.02, direction_deg = 90.0 }"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 152 }, amplitude_px = 0.02, direction_deg = 90.0 }"#,
    ),
    case(
        "faint_shake_diagonal",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 1800.0, duration_s = 3.0, seed = 153 }, amplitude_px = 0.015, direction_deg = 45.0 }"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 1800.0, duration_s = 3.0, seed = 154 }, amplitude_px = 0.015, direction_deg = 45.0 }"#,
    ),
    case(
        "faint_light",
        Scene::Site,
        r#"light = { signal = { type = "noise", rate_hz = 500.0, duration_s = 3.0, seed = 155 }, depth = 0.04 }"#,
        r#"light = { signal = { type = "noise", rate_hz = 500.0, duration_s = 3.0, seed = 156 }, depth = 0.04 }"#,
    ),
    case(
        "faint_ring",
        Scene::Site,
        r#"background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 157 }, amplitude_px = 0.08 }]"#,
        r#"background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 158 }, amplitude_px = 0.08 }]"#,
    ),
    case(
        "faint_shake_and_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 159 }, amplitude_px = 0.015 }
background_motion = [{ rect = [0, 100, 128, 28], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 161 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 160 }, amplitude_px = 0.015 }
background_motion = [{ rect = [0, 100, 128, 28], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 162 }, amplitude_px = 0.3 }]"#,
    ),
];

/// The sixteenth held-out set (session 71), written down and committed
/// before any of it was run, for a change that pools the tiles' motion
/// weighed by each tile's noise (its motion's power about the tiles'
/// mean) instead of their plain mean, in `calibrate` and again in
/// `listen --calibration` (found on `faint_shake_and_mover`, fifteenth
/// set, then looked at). Five shakes of the camera on the `Site` scene,
/// each with something else in view: a mover along the top, a mover in a
/// corner with a diagonal shake, a light with a vertical shake, movers on
/// both sides, and the ring around the object moving. Figures reported as
/// they come, under [`fresh`]'s rules. First run (session 71, on the
/// change): `shake_and_top_mover` +2.59 dB of the 3.35 it costs,
/// `diagonal_shake_and_corner_mover` +1.61 of 2.30, `shake_and_side_movers`
/// +1.78 of 2.62, `shake_and_ring` +2.85 of 3.55 (all weak, 1 dB asked:
/// met); `vertical_shake_and_light` +0.90 of 1.10 (missed by 0.10,
/// marked). All meet the transfer bar.
const SIXTEENTH: [Case; 5] = [
    case(
        "shake_and_top_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 171 }, amplitude_px = 0.03 }
background_motion = [{ rect = [0, 0, 128, 24], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 173 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 172 }, amplitude_px = 0.03 }
background_motion = [{ rect = [0, 0, 128, 24], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 174 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "diagonal_shake_and_corner_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 1800.0, duration_s = 3.0, seed = 175 }, amplitude_px = 0.03, direction_deg = 30.0 }
background_motion = [{ rect = [100, 100, 28, 28], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 177 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 1800.0, duration_s = 3.0, seed = 176 }, amplitude_px = 0.03, direction_deg = 30.0 }
background_motion = [{ rect = [100, 100, 28, 28], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 178 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "vertical_shake_and_light",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 179 }, amplitude_px = 0.025, direction_deg = 90.0 }
light = { signal = { type = "noise", rate_hz = 400.0, duration_s = 3.0, seed = 181 }, depth = 0.1 }"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 180 }, amplitude_px = 0.025, direction_deg = 90.0 }
light = { signal = { type = "noise", rate_hz = 400.0, duration_s = 3.0, seed = 182 }, depth = 0.1 }"#,
    ),
    case(
        "shake_and_side_movers",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 183 }, amplitude_px = 0.025 }
background_motion = [{ rect = [0, 0, 24, 128], signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 185 }, amplitude_px = 0.3 }, { rect = [104, 0, 24, 128], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 187 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 184 }, amplitude_px = 0.025 }
background_motion = [{ rect = [0, 0, 24, 128], signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 186 }, amplitude_px = 0.3 }, { rect = [104, 0, 24, 128], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 188 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "shake_and_ring",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 189 }, amplitude_px = 0.03 }
background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 750.0, duration_s = 3.0, seed = 191 }, amplitude_px = 0.1, direction_deg = 90.0 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 190 }, amplitude_px = 0.03 }
background_motion = [{ rect = [32, 32, 64, 64], signal = { type = "noise", rate_hz = 750.0, duration_s = 3.0, seed = 192 }, amplitude_px = 0.1, direction_deg = 90.0 }]"#,
    ),
];

/// The seventeenth held-out set (session 74), written down and committed
/// before any of it ran: linear responses of the object between the last
/// bin the fit part of the chirp's recording measures (about 851 Hz: the
/// sweep's last stretch, 862-920 Hz, falls in a held-out block) and the
/// top of the sweep, for a change that measures the transfer table kept
/// in the report on the whole recording once the effects are chosen (the
/// held-out scores stay those of the table fitted on the fit part).
/// Figures reported as they come, under [`fresh`]'s rules. First run
/// (session 74, on that change): `dip_at_875` +2.00 dB of 11.11 and
/// `dip_at_895` +2.49 of 10.17 (both marked), `resonance_at_870` +6.28,
/// `sharp_resonance_at_855` +4.55, `mid_resonance_top_dip` +6.58,
/// `resonance_at_910` +4.45. The change was not kept (docs/calibration.md,
/// session 74); on the code as kept: +1.70, +2.91, +6.19, +4.21, +6.97,
/// +4.47. All meet the transfer bar on both.
const SEVENTEENTH: [Case; 6] = [
    case(
        "dip_at_875",
        Scene::Object,
        "resonances = [{ freq_hz = 875.0, q = 4.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 875.0, q = 4.0, gain_db = -8.0 }]",
    ),
    case(
        "resonance_at_870",
        Scene::Object,
        "resonances = [{ freq_hz = 870.0, q = 3.0, gain_db = 6.0 }]",
        "resonances = [{ freq_hz = 870.0, q = 3.0, gain_db = 6.0 }]",
    ),
    case(
        "dip_at_895",
        Scene::Object,
        "resonances = [{ freq_hz = 895.0, q = 3.0, gain_db = -6.0 }]",
        "resonances = [{ freq_hz = 895.0, q = 3.0, gain_db = -6.0 }]",
    ),
    case(
        "sharp_resonance_at_855",
        Scene::Object,
        "resonances = [{ freq_hz = 855.0, q = 6.0, gain_db = 8.0 }]",
        "resonances = [{ freq_hz = 855.0, q = 6.0, gain_db = 8.0 }]",
    ),
    case(
        "mid_resonance_top_dip",
        Scene::Object,
        "resonances = [{ freq_hz = 420.0, q = 3.0, gain_db = 5.0 }, { freq_hz = 880.0, q = 3.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 420.0, q = 3.0, gain_db = 5.0 }, { freq_hz = 880.0, q = 3.0, gain_db = -8.0 }]",
    ),
    case(
        "resonance_at_910",
        Scene::Object,
        "resonances = [{ freq_hz = 910.0, q = 4.0, gain_db = 6.0 }]",
        "resonances = [{ freq_hz = 910.0, q = 4.0, gain_db = 6.0 }]",
    ),
];

/// The eighteenth held-out set (session 74), written down and committed
/// before any of it ran, for the change as narrowed after the whole
/// protocol had run on it as first written (the kept table measured again
/// over the whole recording moved the static responses at a resonance,
/// `stiffening_at_resonance` -4.13 dB): the table extended over the
/// whole recording above the fit part's last measured bin only. Linear
/// responses at the sweep's top, and static responses at resonances
/// (where the first version lost). Figures reported as they come, under
/// [`fresh`]'s rules. First run (session 74, on the narrowed change):
/// `dip_at_865` +0.41 dB of 10.08 (marked), `resonance_at_890` +5.89,
/// `wide_dip_at_850` +3.57, `stiffening_at_high_resonance` +7.83,
/// `soft_clip_at_resonance_500` +7.79, `dips_mid_and_top` +6.89. Not kept
/// either; on the code as kept: +0.67, +5.82, +3.58, +10.98, +7.78,
/// +7.07. All meet the transfer bar on both.
const EIGHTEENTH: [Case; 6] = [
    case(
        "dip_at_865",
        Scene::Object,
        "resonances = [{ freq_hz = 865.0, q = 5.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 865.0, q = 5.0, gain_db = -8.0 }]",
    ),
    case(
        "resonance_at_890",
        Scene::Object,
        "resonances = [{ freq_hz = 890.0, q = 3.0, gain_db = 6.0 }]",
        "resonances = [{ freq_hz = 890.0, q = 3.0, gain_db = 6.0 }]",
    ),
    case(
        "wide_dip_at_850",
        Scene::Object,
        "resonances = [{ freq_hz = 850.0, q = 2.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 850.0, q = 2.0, gain_db = -8.0 }]",
    ),
    case(
        "stiffening_at_high_resonance",
        Scene::Object,
        "response_poly = [0.0, 0.3]\nresonances = [{ freq_hz = 600.0, q = 3.0, gain_db = 5.0 }]",
        "response_poly = [0.0, 0.3]\nresonances = [{ freq_hz = 600.0, q = 3.0, gain_db = 5.0 }]",
    ),
    case(
        "soft_clip_at_resonance_500",
        Scene::Object,
        "soft_clip_px = 0.15\nresonances = [{ freq_hz = 500.0, q = 4.0, gain_db = 6.0 }]",
        "soft_clip_px = 0.15\nresonances = [{ freq_hz = 500.0, q = 4.0, gain_db = 6.0 }]",
    ),
    case(
        "dips_mid_and_top",
        Scene::Object,
        "resonances = [{ freq_hz = 350.0, q = 3.0, gain_db = -6.0 }, { freq_hz = 870.0, q = 3.0, gain_db = -6.0 }]",
        "resonances = [{ freq_hz = 350.0, q = 3.0, gain_db = -6.0 }, { freq_hz = 870.0, q = 3.0, gain_db = -6.0 }]",
    ),
];

/// The nineteenth held-out set (session 75), written down and committed
/// before any of it ran, for a change to how `listen --calibration`
/// applies a transfer table to a new recording: not its plain inverse but
/// a Wiener inverse against the content that folds onto each bin from
/// above the Nyquist frequency, its level the recording's own spectrum
/// extrapolated along its trend (the object's response there unmeasured,
/// taken as the table's median). Dips and resonances in the band's
/// middle (where the plain inverse should stay), near its top (where
/// folded speech outweighs the object's own), a broad dip, and a dip
/// beside a static response. Figures reported as they come, under
/// [`fresh`]'s rules. First run (session 75, on the change): `dip_at_600`
/// +8.11 dB, `dip_at_780` +4.46, `deep_dip_at_880` +3.85,
/// `low_resonance_top_dip` +9.36, `broad_dip_at_700` +8.44,
/// `soft_clip_and_top_dip` +3.32; all meet both bars. The change as kept
/// added a guard (a spectrum that does not fall takes the plain inverse;
/// none of these six meets it) and carries the recording's trend no
/// further above the Nyquist frequency than the band it was fitted over
/// is wide: +7.84, +4.31, +3.81, +9.44, +8.29, +3.39. With the plain
/// inverse (the code before): +7.68, +1.73, +0.78, +8.14, +7.86, +2.96.
const NINETEENTH: [Case; 6] = [
    case(
        "dip_at_600",
        Scene::Object,
        "resonances = [{ freq_hz = 600.0, q = 3.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 600.0, q = 3.0, gain_db = -8.0 }]",
    ),
    case(
        "dip_at_780",
        Scene::Object,
        "resonances = [{ freq_hz = 780.0, q = 4.0, gain_db = -8.0 }]",
        "resonances = [{ freq_hz = 780.0, q = 4.0, gain_db = -8.0 }]",
    ),
    case(
        "deep_dip_at_880",
        Scene::Object,
        "resonances = [{ freq_hz = 880.0, q = 6.0, gain_db = -10.0 }]",
        "resonances = [{ freq_hz = 880.0, q = 6.0, gain_db = -10.0 }]",
    ),
    case(
        "low_resonance_top_dip",
        Scene::Object,
        "resonances = [{ freq_hz = 250.0, q = 4.0, gain_db = 6.0 }, { freq_hz = 900.0, q = 3.0, gain_db = -6.0 }]",
        "resonances = [{ freq_hz = 250.0, q = 4.0, gain_db = 6.0 }, { freq_hz = 900.0, q = 3.0, gain_db = -6.0 }]",
    ),
    case(
        "broad_dip_at_700",
        Scene::Object,
        "resonances = [{ freq_hz = 700.0, q = 1.0, gain_db = -6.0 }]",
        "resonances = [{ freq_hz = 700.0, q = 1.0, gain_db = -6.0 }]",
    ),
    case(
        "soft_clip_and_top_dip",
        Scene::Object,
        "soft_clip_px = 0.15\nresonances = [{ freq_hz = 850.0, q = 3.0, gain_db = -6.0 }]",
        "soft_clip_px = 0.15\nresonances = [{ freq_hz = 850.0, q = 3.0, gain_db = -6.0 }]",
    ),
];

/// The twentieth held-out set (session 76), written down and committed
/// before any of it ran, for the gain bar's other branch on effects that
/// lie wholly outside the object: `listen --calibration` says how much of
/// each pooled motion it subtracts is its tiles' own noise on the new
/// recording, and the protocol checks that against the truth (the same
/// recording rendered without the sensor's noise) and asks how much the
/// best correction made from the kept observables could gain, fitted on
/// the effect's own part of the recovery. Five faint shakes of the
/// camera on the `Site` scene, alone or with movers outside the region.
/// Figures reported as they come, under [`fresh`]'s rules. First run
/// (session 76, on the change): `faint_shake_and_left_mover` +0.54 dB of
/// the 1.46 it costs (the best correction from its kept observables
/// +0.53; noise share said 0.49, true 0.46, or 0.47 read through the
/// recovery's own high-pass since session 77) and
/// `faint_shake_and_corner_movers` +0.69 of 1.48 (best +0.73; 0.50 and
/// 0.51): the gain bar met by its branch; `shake_and_bottom_mover` +1.60
/// of 2.56 (met); `faint_shake_at_60` costs 0.10 dB and
/// `faint_vertical_shake_and_top_mover` 0.60 (+0.39 kept): the transfer
/// bar alone. All meet the transfer bar.
const TWENTIETH: [Case; 5] = [
    case(
        "faint_shake_and_left_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 201 }, amplitude_px = 0.018 }
background_motion = [{ rect = [0, 0, 24, 128], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 203 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 202 }, amplitude_px = 0.018 }
background_motion = [{ rect = [0, 0, 24, 128], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 204 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "faint_vertical_shake_and_top_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 205 }, amplitude_px = 0.02, direction_deg = 90.0 }
background_motion = [{ rect = [0, 0, 128, 24], signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 207 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 206 }, amplitude_px = 0.02, direction_deg = 90.0 }
background_motion = [{ rect = [0, 0, 128, 24], signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 208 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "faint_shake_at_60",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 209 }, amplitude_px = 0.02, direction_deg = 60.0 }"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 210 }, amplitude_px = 0.02, direction_deg = 60.0 }"#,
    ),
    case(
        "faint_shake_and_corner_movers",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 211 }, amplitude_px = 0.02 }
background_motion = [{ rect = [0, 0, 28, 28], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 213 }, amplitude_px = 0.3 }, { rect = [100, 100, 28, 28], signal = { type = "noise", rate_hz = 500.0, duration_s = 3.0, seed = 215 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 212 }, amplitude_px = 0.02 }
background_motion = [{ rect = [0, 0, 28, 28], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 214 }, amplitude_px = 0.3 }, { rect = [100, 100, 28, 28], signal = { type = "noise", rate_hz = 500.0, duration_s = 3.0, seed = 216 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "shake_and_bottom_mover",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 217 }, amplitude_px = 0.025 }
background_motion = [{ rect = [0, 104, 128, 24], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 219 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 218 }, amplitude_px = 0.025 }
background_motion = [{ rect = [0, 104, 128, 24], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 220 }, amplitude_px = 0.3 }]"#,
    ),
];

/// The twenty-first held-out set (session 76), written down and committed
/// before any of it ran, for a change to how `listen --calibration` fits
/// an explained tile's term again on the next recording: its FIR's
/// length chosen there by the Bayesian information criterion (wider than
/// -2..=2 frames only where the recording's own gain pays for the taps).
/// Five things moving inside the region beside the object, one with the
/// camera shaking: strips of the ring around it on each side, one faint.
/// Figures reported as they come, under [`fresh`]'s rules. The change
/// was tried and not kept: on the seen cases it was written for
/// (`ring_left_strip`, `cubic_and_camera`) the criterion never widened an
/// FIR (at -6..=6 a wider one removed at most 0.25% more of the
/// recovery's energy, against the criterion's price of 0.38% for every
/// two taps: docs/calibration.md), and no figure moved. First run (session 76), on the code as kept:
/// `ring_bottom_strip` +1.06 dB of the 1.20 it costs and
/// `camera_and_ring_strip` +2.85 of 3.62 (both weak, 1 dB asked: met);
/// `ring_right_strip` costs 0.93 dB (+0.90), `ring_top_strip_along_y`
/// 0.70 (+0.59) and `faint_ring_left_strip` 0.24 (nothing kept): the
/// transfer bar alone. All meet the transfer bar.
const TWENTY_FIRST: [Case; 5] = [
    case(
        "ring_right_strip",
        Scene::Site,
        r#"background_motion = [{ rect = [80, 32, 16, 64], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 221 }, amplitude_px = 0.3 }]"#,
        r#"background_motion = [{ rect = [80, 32, 16, 64], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 222 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "ring_top_strip_along_y",
        Scene::Site,
        r#"background_motion = [{ rect = [32, 32, 64, 16], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 223 }, amplitude_px = 0.25, direction_deg = 90.0 }]"#,
        r#"background_motion = [{ rect = [32, 32, 64, 16], signal = { type = "noise", rate_hz = 700.0, duration_s = 3.0, seed = 224 }, amplitude_px = 0.25, direction_deg = 90.0 }]"#,
    ),
    case(
        "ring_bottom_strip",
        Scene::Site,
        r#"background_motion = [{ rect = [32, 80, 64, 16], signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 225 }, amplitude_px = 0.3 }]"#,
        r#"background_motion = [{ rect = [32, 80, 64, 16], signal = { type = "noise", rate_hz = 600.0, duration_s = 3.0, seed = 226 }, amplitude_px = 0.3 }]"#,
    ),
    case(
        "faint_ring_left_strip",
        Scene::Site,
        r#"background_motion = [{ rect = [32, 32, 16, 64], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 227 }, amplitude_px = 0.1 }]"#,
        r#"background_motion = [{ rect = [32, 32, 16, 64], signal = { type = "noise", rate_hz = 900.0, duration_s = 3.0, seed = 228 }, amplitude_px = 0.1 }]"#,
    ),
    case(
        "camera_and_ring_strip",
        Scene::Site,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 229 }, amplitude_px = 0.03 }
background_motion = [{ rect = [80, 32, 16, 64], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 231 }, amplitude_px = 0.3 }]"#,
        r#"camera_motion = { signal = { type = "noise", rate_hz = 2000.0, duration_s = 3.0, seed = 230 }, amplitude_px = 0.03 }
background_motion = [{ rect = [80, 32, 16, 64], signal = { type = "noise", rate_hz = 800.0, duration_s = 3.0, seed = 232 }, amplitude_px = 0.3 }]"#,
    ),
];

/// The catalog's other families, outside the protocol's set (they were
/// designed on these scenes): only the transfer bar. Dropped frames and
/// the gain's drift belong to one recording and are left out by `listen
/// --calibration`; the region's gain recombines strips of rows.
const FAMILIES: [Case; 3] = [
    case(
        "dropped_frames",
        Scene::Object,
        "drop_frames = [1000, 3000]\nduplicate_frames = [2000]",
        "drop_frames = [1500]\nduplicate_frames = [2500]",
    ),
    case(
        "gain_drift",
        Scene::Object,
        "gain_decay_s = 2.0",
        "gain_decay_s = 2.0",
    ),
    case(
        "region_gain",
        Scene::Object,
        "row_lag_rows = [32]\nrow_lag_us = [0.0]\nrow_gain = [-0.5]",
        "row_lag_rows = [32]\nrow_lag_us = [0.0]\nrow_gain = [-0.5]",
    ),
];

/// The scene's keys for `signal` at `amplitude_px` (the scene's own for
/// the chirp when `None`), then `extra`.
fn scene_text(scene: Scene, wav: &Path, amplitude_px: Option<f64>, extra: &str) -> String {
    let (head, chirp_px) = match scene {
        Scene::Object => ("width = 64\nheight = 64\nnoise_std = 0.1\n", 0.2),
        Scene::Site => (
            "width = 128\nheight = 128\nnoise_std = 2.0\nobject = [48, 48, 32, 32]\n",
            0.05,
        ),
    };
    format!(
        "{head}fps = 2200.0\nduration_s = 2.0\namplitude_px = {}\nsignal = {{ type = \"wav\", path = {:?} }}\n{extra}\n",
        amplitude_px.unwrap_or(chirp_px),
        wav.display().to_string()
    )
}

/// The lines of a case's keys that frame the scene rather than add an
/// effect (`object`: where the object is and how large), each ending in
/// a newline. The recording without the effect (`ceiling`) keeps them:
/// a smaller object is heard worse with or without the effect, and
/// until session 62 the ceiling of [`FOURTH`]'s three moved or resized
/// objects was measured on the default object, so their cost held the
/// framing's share (`square_small_object`: 9.96 dB, of which the
/// object's size took about 5.5).
fn framing(keys: &str) -> String {
    keys.lines()
        .filter(|l| l.split('=').next().is_some_and(|k| k.trim() == "object"))
        .map(|l| format!("{l}\n"))
        .collect()
}

/// The SNR of the speech recorded without the effect (the scene `text`,
/// whose speech is the WAV `speech`), its recovery left in
/// `dir/control-none.wav`. Many cases share one such recording (the same
/// scene, framing and speech): it is rendered and heard once in a run,
/// by the first case that asks, in that case's directory, and the others
/// get its WAV and figure (a sixth of a case's time). Keyed by the scene
/// with the speech's bytes in place of its path, and by the region.
fn ceiling_of(dir: &Path, text: &str, speech: &Path, scene: Scene) -> f64 {
    use std::collections::hash_map::DefaultHasher;
    use std::collections::BTreeMap;
    use std::hash::{Hash, Hasher};
    use std::sync::{Arc, Mutex, OnceLock};
    type Made = (Vec<u8>, f64);
    static MADE: Mutex<BTreeMap<String, Arc<OnceLock<Made>>>> = Mutex::new(BTreeMap::new());
    let mut h = DefaultHasher::new();
    std::fs::read(speech).unwrap().hash(&mut h);
    let key = format!(
        "{}\n{:?}",
        text.replace(
            &*speech.to_string_lossy(),
            &format!("speech {:x}", h.finish())
        ),
        roi(scene)
    );
    let cell = Arc::clone(MADE.lock().unwrap().entry(key).or_default());
    let wav = dir.join("control-none.wav");
    let (bytes, ceiling) = cell.get_or_init(|| {
        render(dir, "control", text);
        // (`none.json`: the empty report, written by the caller.)
        let (snr, _) = listen_video(dir, speech, ("control.y4m", "none.json"), roi(scene));
        (std::fs::read(&wav).unwrap(), snr)
    });
    if !wav.exists() {
        std::fs::write(&wav, bytes).unwrap();
    }
    *ceiling
}

/// Renders `text` to `dir/NAME.y4m`.
fn render(dir: &Path, name: &str, text: &str) {
    let toml = dir.join(format!("{name}.toml"));
    std::fs::write(&toml, text).unwrap();
    let o = vibroscope::simulate::SimulateOptions {
        scene: toml,
        output: dir.join(format!("{name}.y4m")),
        ..Default::default()
    };
    vibroscope::simulate::simulate(&o).unwrap();
}

/// The region both commands use on `scene`.
fn roi(scene: Scene) -> &'static [&'static str] {
    match scene {
        Scene::Object => &[],
        Scene::Site => &["--roi", "32,32,64,64"],
    }
}

/// What one case measured: the held-out SNR (dB) of the speech without a
/// calibration, with the chirp's, and without the effect. Against the
/// reference sampled at each WAV's instants (the suite's scorer), unless
/// the calibration changed the WAV's rate (a readout unfolded, at twice
/// the frame rate): then each against the reference band-limited to its
/// own WAV's Nyquist frequency (`scored`). A reference sampled at the
/// frame's instants holds the speech's aliases as a global shutter folds
/// them, and one sampled at twice the rate folds it otherwise: SNRs
/// against the two are not comparable, and a recovery that removes or
/// unfolds the aliases scores low against either. Band-limited, each is
/// scored against what an ideal microphone at its rate would record.
struct Outcome {
    none: f64,
    with: f64,
    ceiling: f64,
    kept: String,
    scored: &'static str,
    /// The chirp's report, what `listen --calibration` said with it, and
    /// the speech as played (rate, samples).
    report: serde_json::Value,
    notes: String,
    speech: (u32, Vec<f32>),
    /// The second recording's WAV with an empty report (rate, samples).
    recording: (u32, Vec<f32>),
    /// What the kept observables could do at best on the second recording
    /// ([`bounded`]), where asked for.
    bound: Option<Bound>,
}

impl Outcome {
    fn gain(&self) -> f64 {
        self.with - self.none
    }
    fn cost(&self) -> f64 {
        self.ceiling - self.none
    }
    /// The gain asked of a held-out case: 1 dB where the effect is weak
    /// (it costs the speech under 4 dB), else 3 dB.
    fn need(&self) -> f64 {
        if self.cost() < 4.0 {
            1.0
        } else {
            3.0
        }
    }
}

/// Runs `c`: the chirp's calibration, then the speech with an empty
/// report, with the chirp's, and without the effect. `None` (printed)
/// without espeak-ng or sox.
fn run(c: &Case) -> Option<Outcome> {
    run_with(c, false)
}

/// [`run`], and with `with_bound` what the kept observables could do at
/// best on the second recording ([`bounded`]).
fn run_with(c: &Case, with_bound: bool) -> Option<Outcome> {
    // A temporary directory only where the files are not kept.
    let mut temp = None;
    // PROTOCOL_KEEP=1 keeps each case's files (printed) in one directory
    // a case under the system's temporary directory, the last run's
    // replaced: a fresh directory a run filled /tmp (541 of them, 56 GB,
    // by session 72).
    let dir = &if std::env::var_os("PROTOCOL_KEEP").is_some() {
        let kept = std::env::temp_dir()
            .join("vibroscope-protocol")
            .join(c.name);
        let _ = std::fs::remove_dir_all(&kept);
        std::fs::create_dir_all(&kept).unwrap();
        eprintln!("protocol {}: files kept in {}", c.name, kept.display());
        kept
    } else {
        temp.insert(tempfile::tempdir().unwrap())
            .path()
            .to_path_buf()
    };
    let speech = speech_wav(dir)?;
    let chirp = dir.join("chirp.wav");
    write_chirp(&chirp);
    render(
        dir,
        "chirp",
        &scene_text(c.scene, &chirp, None, &format!("{}\nseed = 1", c.chirp)),
    );
    let speech_px = Some(c.speech_px);
    let second = "direction_deg = 180.0\nseed = 2";
    render(
        dir,
        "speech",
        &scene_text(
            c.scene,
            &speech,
            speech_px,
            &format!("{}\n{second}", c.speech),
        ),
    );
    let control = scene_text(
        c.scene,
        &speech,
        speech_px,
        &format!("{}{second}", framing(c.speech)),
    );
    let mut args = vec![
        "calibrate",
        "chirp.y4m",
        "--reference",
        "chirp.wav",
        "--json",
        "report.json",
    ];
    args.extend_from_slice(roi(c.scene));
    let o = run_in(dir, &args);
    assert_eq!(code(&o), 0, "{}: {}", c.name, stderr(&o));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    let mut kept: Vec<String> = report["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["name"].as_str().unwrap().to_string())
        .collect();
    kept.extend(
        report["explained"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|e| format!("explained:{}", e["cause"].as_str().unwrap_or("?"))),
    );
    std::fs::write(dir.join("none.json"), r#"{"effects": []}"#).unwrap();
    let listen =
        |video: &str, report: &str| listen_video(dir, &speech, (video, report), roi(c.scene));
    let (none, _) = listen("speech.y4m", "none.json");
    let (with, notes) = listen("speech.y4m", "report.json");
    let ceiling = ceiling_of(dir, &control, &speech, c.scene);
    let wavs =
        ["speech-none", "speech-report", "control-none"].map(|w| dir.join(format!("{w}.wav")));
    let rates = wavs
        .clone()
        .map(|w| vibroscope_io::wav::read_mono(&w).unwrap().0);
    let mut out = Outcome {
        none,
        with,
        ceiling,
        kept: kept.join(", "),
        scored: "the reference sampled at the WAV's instants",
        report: report.clone(),
        notes: notes.clone(),
        speech: crate::common::read_wav(&speech),
        recording: crate::common::read_wav(&wavs[0]),
        bound: None,
    };
    if rates[1] != rates[0] {
        eprintln!(
            "protocol {}: against the reference sampled at each WAV's instants: speech {none:.2} ({} Hz) -> {with:.2} dB ({} Hz), {ceiling:.2} without the effect",
            c.name, rates[0], rates[1]
        );
        let [n, w, ce] =
            [0, 1, 2].map(|k| held_out_snr(&wavs[k], &band_limited(dir, &speech, rates[k])));
        (out.none, out.with, out.ceiling) = (n, w, ce);
        out.scored = "the reference band-limited to each WAV's Nyquist frequency (the calibration changed the WAV's rate)";
    }
    eprintln!(
        "protocol {}: chirp {:.2} -> {:.2} dB kept [{}]; speech {:.2} -> {:.2} dB ({:+.2}), {:.2} without the effect (it costs {:.2} dB); against {}\n  listen said: {}",
        c.name,
        report["before"]["snr_db"].as_f64().unwrap_or(f64::NAN),
        report["after"]["snr_db"].as_f64().unwrap_or(f64::NAN),
        out.kept,
        out.none,
        out.with,
        out.gain(),
        out.ceiling,
        out.cost(),
        out.scored,
        notes.trim().replace('\n', "\n  ")
    );
    if with_bound {
        out.bound = bounded(dir, c, &report);
    }
    Some(out)
}

/// A bar checked on a case: met, or known to be missed today. A case
/// marked as missing a bar (`Some(why)`: the figure it missed by when it
/// was first run, and the reason where known) must still miss it: a
/// change that meets it fails here, so that the mark is removed and the
/// figure reported. Issue 50 stays open while any mark remains.
fn bar(name: &str, what: &str, met: bool, figure: String, short: Option<&str>) {
    match short {
        None => assert!(met, "{name}: {what} not met: {figure}"),
        Some(why) => {
            assert!(
                !met,
                "{name}: {what} is now met ({figure}): remove its mark ({why}) and report the figure"
            );
            eprintln!("protocol {name}: {what} NOT MET (known: {why}): {figure}");
        }
    }
}

/// The transfer bar, for every case (`short`: see [`bar`]).
fn carries(c: &Case, short: Option<&str>) -> Option<Outcome> {
    carries_with(run(c)?, c, short)
}

/// The transfer bar on an outcome of `c` already run.
fn carries_with(o: Outcome, c: &Case, short: Option<&str>) -> Option<Outcome> {
    bar(
        c.name,
        "the transfer bar (at most 0.3 dB lost)",
        o.gain() >= -0.3,
        format!(
            "the chirp's calibration changes the speech's SNR by {:+.2} dB (kept {}; against {})",
            o.gain(),
            o.kept,
            o.scored
        ),
        short,
    );
    Some(o)
}

fn seen(name: &str, short: Option<&str>) {
    let c = SEEN.iter().find(|c| c.name == name).unwrap();
    carries(c, short);
}

fn family(name: &str) {
    let c = FAMILIES.iter().find(|c| c.name == name).unwrap();
    carries(c, None);
}

/// The gain asked of a held-out case: 3 dB, or 1 dB where the effect is
/// weak ([`Outcome::need`]); `short`: see [`bar`].
fn gain_bar(name: &str, o: &Outcome, short: Option<&str>) {
    let need = o.need();
    bar(
        name,
        &format!("the gain asked of a held-out effect ({need} dB)"),
        o.gain() >= need,
        format!(
            "speech {:.2} -> {:.2} dB ({:+.2}); the effect costs {:.2} dB{} (kept {})",
            o.none,
            o.with,
            o.gain(),
            o.cost(),
            if need < 3.0 { ", weak" } else { "" },
            o.kept
        ),
        short,
    );
}

/// The transfer bar, then the gain asked of a held-out case (each bar's
/// `short`: see [`bar`]).
fn held_out(name: &str, transfer_short: Option<&str>, short: Option<&str>) {
    let c = HELD_OUT.iter().find(|c| c.name == name).unwrap();
    let Some(o) = carries(c, transfer_short) else {
        return;
    };
    gain_bar(c.name, &o, short);
}

/// A case of the second held-out set ([`FRESH`]): the transfer bar, then
/// the gain asked of a held-out effect, unless the effect costs the speech
/// under 1 dB: then no gain of the bar's size can be measured, and the
/// case is reported as such (the rule written down with the set, before
/// it ran). Each bar's `short`: see [`bar`].
fn fresh(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&FRESH, name, transfer_short, short)
}

/// A case of the fourth held-out set, under [`fresh`]'s rules.
fn fourth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&FOURTH, name, transfer_short, short)
}

/// A case of the fifth held-out set, under [`fresh`]'s rules.
fn fifth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&FIFTH, name, transfer_short, short)
}

/// A case of the sixth held-out set, under [`fresh`]'s rules.
fn sixth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&SIXTH, name, transfer_short, short)
}

/// A case of the seventh held-out set, under [`fresh`]'s rules.
fn seventh(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&SEVENTH, name, transfer_short, short)
}

/// A case of the eighth held-out set, under [`fresh`]'s rules.
fn eighth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&EIGHTH, name, transfer_short, short)
}

/// A case of the ninth held-out set, under [`fresh`]'s rules.
fn ninth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&NINTH, name, transfer_short, short)
}

/// A case of the eleventh held-out set: the transfer bar (`transfer_short`:
/// see [`bar`]), then the gain bar or its other branch,
/// [`gain_or_level_named`] at the case's resonance `at_hz` (the rule
/// written down before the set ran).
fn eleventh(
    name: &str,
    at_hz: f64,
    transfer_short: Option<&str>,
    short: Option<&str>,
) -> Option<Outcome> {
    words_case(&ELEVENTH, name, transfer_short, |o| {
        gain_or_level_named(name, o, &[at_hz], short)
    })
}

/// A case of the twelfth held-out set, under the eleventh's rule (`at_hz`
/// empty: the gain bar alone).
fn twelfth(
    name: &str,
    at_hz: &[f64],
    transfer_short: Option<&str>,
    short: Option<&str>,
) -> Option<Outcome> {
    words_case(&TWELFTH, name, transfer_short, |o| {
        gain_or_level_named(name, o, at_hz, short)
    })
}

/// A case of the fourteenth held-out set, under [`fresh`]'s rules.
fn fourteenth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&FOURTEENTH, name, transfer_short, short)
}

/// A case of the fifteenth held-out set, under [`fresh`]'s rules.
fn fifteenth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&FIFTEENTH, name, transfer_short, short)
}

/// A case of the sixteenth held-out set, under [`fresh`]'s rules.
fn sixteenth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&SIXTEENTH, name, transfer_short, short)
}

/// A case of the seventeenth held-out set, under [`fresh`]'s rules.
fn seventeenth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&SEVENTEENTH, name, transfer_short, short)
}

/// A case of the eighteenth held-out set, under [`fresh`]'s rules.
fn eighteenth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&EIGHTEENTH, name, transfer_short, short)
}

/// A case of the nineteenth held-out set, under [`fresh`]'s rules.
fn nineteenth(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&NINETEENTH, name, transfer_short, short)
}

/// A case of the twenty-first held-out set, under [`unseen_bounded`]'s
/// rules.
fn twenty_first(name: &str) -> Option<Outcome> {
    unseen_bounded(&TWENTY_FIRST, name)
}

/// A case of the twentieth held-out set, under [`unseen_bounded`]'s rules.
fn twentieth(name: &str) -> Option<Outcome> {
    unseen_bounded(&TWENTIETH, name)
}

/// A case of the thirteenth held-out set, under the eleventh's rule.
fn thirteenth(name: &str, at_hz: &[f64], transfer_short: Option<&str>) -> Option<Outcome> {
    words_case(&THIRTEENTH, name, transfer_short, |o| {
        gain_or_level_named(name, o, at_hz, None)
    })
}

/// Whether a held-out case is held to the transfer bar alone: its effect
/// costs the speech under 1 dB, so no gain of the bar's size can be
/// measured (said).
fn transfer_alone(name: &str, o: &Outcome) -> bool {
    let alone = o.cost() < 1.0;
    if alone {
        eprintln!(
            "protocol {name}: the effect costs the speech {:.2} dB, under 1 dB: no gain of the bar's size can be measured (speech {:.2} -> {:.2} dB, {:+.2}; kept {}); held to the transfer bar alone",
            o.cost(),
            o.none,
            o.with,
            o.gain(),
            o.kept
        );
    }
    alone
}

/// The case `name` of `set`: the transfer bar, then `gain` (a gain bar
/// with its other branch) where the effect costs the speech 1 dB or more.
fn words_case(
    set: &[Case],
    name: &str,
    transfer_short: Option<&str>,
    gain: impl Fn(&Outcome),
) -> Option<Outcome> {
    let c = set.iter().find(|c| c.name == name).unwrap();
    let o = carries(c, transfer_short)?;
    if transfer_alone(name, &o) {
        return Some(o);
    }
    gain(&o);
    Some(o)
}

/// The descriptions of the chirp's report's `unexplained` entries of
/// `kind` that `keep` accepts.
fn named<'a>(
    o: &'a Outcome,
    kind: &str,
    keep: impl Fn(&serde_json::Value) -> bool,
) -> Vec<&'a str> {
    o.report["unexplained"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|u| u["kind"] == kind && keep(u))
        .filter_map(|u| u["description"].as_str())
        .collect()
}

/// The gain asked of a held-out effect, or the acceptance's other branch:
/// the report says in words that the residual is explained by an
/// observable it cannot correct, and why. Here: a resonance at one of
/// `at_hz` (the case's, known by construction) drives the object's
/// static response into its nonlinear range, and the chirp's report holds
/// a `level_dependent` entry (the recovery's harmonics imply that the
/// gain measured there holds only at the sweep's level) whose frequencies
/// come within two bins of it. A case whose gain meets the bar passes
/// either way; one that meets neither fails (or, marked, must still miss
/// both: see [`bar`]).
fn gain_or_level_named(name: &str, o: &Outcome, at_hz: &[f64], short: Option<&str>) {
    let words = named(o, "level_dependent", |u| {
        u["frequencies_hz"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|f| f.as_f64())
            .any(|f| at_hz.iter().any(|a| (f - a).abs() <= 2.0 * 2200.0 / 256.0))
    });
    gain_or_named(
        name,
        o,
        &format!("a level-dependent gain at {at_hz:?} Hz"),
        &words,
        short,
    );
}

/// The gain asked of a held-out effect, or the other branch for a static
/// response that folds back within the sweep (known by construction): the
/// chirp's report holds a `response_folds` entry.
fn gain_or_fold_named(name: &str, o: &Outcome, short: Option<&str>) {
    let words = named(o, "response_folds", |_| true);
    gain_or_named(name, o, "a response that folds", &words, short);
}

/// The case `name` of `set`, a response built to fold back within the
/// sweep: the transfer bar, then the gain bar or its `response_folds`
/// branch ([`gain_or_fold_named`]).
fn fold_case(set: &[Case], name: &str) -> Option<Outcome> {
    words_case(set, name, None, |o| gain_or_fold_named(name, o, None))
}

/// The gain bar, met by the gain or by the report's `words` for `what`.
fn gain_or_named(name: &str, o: &Outcome, what: &str, words: &[&str], short: Option<&str>) {
    let need = o.need();
    let figure = format!(
        "speech {:.2} -> {:.2} dB ({:+.2}); the effect costs {:.2} dB{} (kept {}); the report names {what}: {}",
        o.none,
        o.with,
        o.gain(),
        o.cost(),
        if need < 3.0 { ", weak" } else { "" },
        o.kept,
        words.first().copied().unwrap_or("no")
    );
    if o.gain() < need && !words.is_empty() && short.is_none() {
        eprintln!("protocol {name}: the gain bar met by its other branch: {figure}");
    }
    bar(
        name,
        &format!("the gain asked of a held-out effect ({need} dB), or the report's words for what it cannot correct"),
        o.gain() >= need || !words.is_empty(),
        figure,
        short,
    );
}

/// How far under the bar the best correction from the kept observables
/// must stay for [`gain_or_bounded`]'s branch, dB: it is the least-squares
/// best on the effect's part, not a strict bound on the held-out SNR (on
/// `faint_shake_and_left_mover` the calibration gains 0.01 dB more).
const BOUND_MARGIN: f64 = 0.1;

/// What the terms the chirp's calibration kept could do at best on the
/// second recording, measured against the truth ([`bounded`]).
struct Bound {
    /// Each pooled motion's share of its own tiles' noise, as `listen
    /// --calibration` estimates it (and says) and as the truth has it.
    shares: Vec<(f64, f64)>,
    /// The second recording's held-out SNR (dB) after the best correction
    /// made from the kept terms' observables as measured there: an FIR of
    /// -12..=12 frames on each, fitted on the effect's own part of the
    /// recovery (the recovery with the effect less the one without it).
    oracle: f64,
}

/// [`Bound`] for a case whose effect lies wholly outside the object and
/// whose chirp's report kept terms of tiles only (no sensor's lines): the
/// second recording rendered again without the sensor's noise (the
/// truth of every tile's motion), the kept terms' tiles measured on both
/// by a `displacement` stage as `listen --calibration` measures them, and
/// the oracle's correction scored as the protocol scores the speech.
/// `None` (printed) where it does not apply.
fn bounded(dir: &Path, c: &Case, report: &serde_json::Value) -> Option<Bound> {
    use vibroscope_math::calibrate as cal;
    let terms: Vec<cal::StoredTerm> =
        serde_json::from_value(report["explained"].clone()).unwrap_or_default();
    if terms.is_empty() || terms.iter().any(|t| t.observable.is_line()) {
        eprintln!("protocol {}: no bound (no kept term, or a line's)", c.name);
        return None;
    }
    let speech = std::fs::read_to_string(dir.join("speech.toml")).unwrap();
    assert!(speech.contains("noise_std = 2.0\n"), "{}: {speech}", c.name);
    render(
        dir,
        "clean",
        &speech.replace("noise_std = 2.0\n", "noise_std = 0.0\n"),
    );
    let mut rects: Vec<[u32; 4]> = Vec::new();
    for t in &terms {
        for r in &t.tiles {
            if !rects.contains(r) {
                rects.push(*r);
            }
        }
    }
    let rois: Vec<String> = rects.iter().flatten().map(|v| v.to_string()).collect();
    let observed = |video: &str| -> Vec<Vec<f64>> {
        let toml = format!(
            "[pipeline]\nname = \"observe\"\n[[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"{video}.y4m\"\n[[stage]]\nid = \"d\"\nkind = \"displacement\"\ninput = \"src\"\nrois = [{}]\nintensity = true\nuntextured = \"zero\"\n[[stage]]\nid = \"out\"\nkind = \"csv\"\ninput = \"d\"\npath = \"{video}-tiles.csv\"\n",
            rois.join(", ")
        );
        std::fs::write(dir.join(format!("{video}-tiles.toml")), toml).unwrap();
        let o = run_in(dir, &["run", &format!("{video}-tiles.toml")]);
        assert_eq!(code(&o), 0, "{}: {}", c.name, stderr(&o));
        vibroscope::calibrate::read_observed(&dir.join(format!("{video}-tiles.csv"))).unwrap()
    };
    let (noisy, clean) = (observed("speech"), observed("clean"));
    let y: Vec<f64> = crate::common::read_wav(&dir.join("speech-none.wav"))
        .1
        .iter()
        .map(|&v| f64::from(v))
        .collect();
    let (rate, y0) = crate::common::read_wav(&dir.join("control-none.wav"));
    let y0: Vec<f64> = y0.iter().map(|&v| f64::from(v)).collect();
    let fs = f64::from(rate);
    let n = y.len().min(y0.len()).min(noisy[0].len());
    let hp = cal::Options::for_rate(fs).highpass;
    let mut shares = Vec::new();
    let mut measured = Vec::new();
    for t in &terms {
        let of = |set: &[Vec<f64>]| -> Vec<Vec<f64>> {
            t.tiles
                .iter()
                .map(|r| {
                    let k = rects.iter().position(|x| x == r).unwrap();
                    set[3 * k + vibroscope::corrections::observed_channel(t.observable)][..n]
                        .to_vec()
                })
                .collect()
        };
        let (tn, tc) = (of(&noisy), of(&clean));
        let tiles: Vec<&[f64]> = tn.iter().map(|v| v.as_slice()).collect();
        let (pooled, stated) = match t.weighed {
            true => cal::pooled_motion_and_share(&tiles, fs, hp),
            false => (cal::mean_of(&tiles), None),
        };
        if t.weighed && t.observable.is_motion() {
            // The truth: without the sensor's noise every tile of the
            // term moves as the rest of the image does, so their plain
            // mean is the motion the pooled one measures through noise.
            // Both through the recovery's high-pass, as the share said
            // is read.
            let truth = cal::centred_highpass(
                &cal::mean_of(&tc.iter().map(|v| v.as_slice()).collect::<Vec<_>>()),
                fs,
                hp,
            );
            let p = cal::centred_highpass(&pooled, fs, hp);
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
            let r2 = dot(&p, &truth).powi(2) / (dot(&p, &p) * dot(&truth, &truth));
            shares.push((stated.unwrap_or(f64::NAN), 1.0 - r2));
        }
        // Lags -12..=12: five columns of lags -2..=2 about 0, ±5, ±10.
        for k in [-10i64, -5, 0, 5, 10] {
            let moved: Vec<f64> = (0..n as i64)
                .map(|i| pooled.get((i - k) as usize).copied().unwrap_or(0.0))
                .collect();
            measured.push(cal::Measured {
                observable: cal::Observable::Intensity,
                channels: vec![moved],
                reach: 0,
                shifts: (-(cal::LAGS as i64)..=cal::LAGS as i64).collect(),
                spans: cal::reference_spans(n, None),
                taps: None,
            });
        }
    }
    let d: Vec<f64> = (0..n).map(|i| y[i] - y0[i]).collect();
    let (left, _) = cal::remove_explained(&d, &measured, fs, hp);
    let fixed: Vec<f32> = (0..n).map(|i| (y0[i] + left[i]) as f32).collect();
    let path = dir.join("speech-oracle.wav");
    crate::common::write_wav_f32(&path, rate, &fixed);
    let oracle = held_out_snr(&path, &dir.join("speech.wav"));
    Some(Bound { shares, oracle })
}

/// The gain bar, or its branch for a correction its own observables
/// bound: each pooled motion `listen --calibration` subtracts says its
/// tiles' noise on the second recording (its words checked), within 0.1
/// of the truth ([`bounded`]), and the best correction made from the kept
/// observables, fitted with the truth's help, gains less than the bar
/// asks by [`BOUND_MARGIN`] or more: no correction made from them can
/// meet it.
fn gain_or_bounded(name: &str, o: &Outcome) {
    let need = o.need();
    let b = o.bound.as_ref();
    let shares = b.map_or(String::from("-"), |b| {
        b.shares
            .iter()
            .map(|(s, t)| format!("{s:.2} said, {t:.2} true"))
            .collect::<Vec<_>>()
            .join("; ")
    });
    let oracle = b.map_or(f64::NAN, |b| b.oracle - o.none);
    let figure = format!(
        "speech {:.2} -> {:.2} dB ({:+.2}); the effect costs {:.2} dB{} (kept {}); the best correction from the kept observables {:+.2}; their noise share {shares}",
        o.none,
        o.with,
        o.gain(),
        o.cost(),
        if need < 3.0 { ", weak" } else { "" },
        o.kept,
        oracle,
    );
    let said = b.is_some_and(|b| {
        !b.shares.is_empty()
            && b.shares.iter().all(|&(s, t)| {
                (s - t).abs() <= 0.1
                    && o.notes.contains(&format!(
                        "is measured here with their own noise at {:.0}% of its power",
                        100.0 * s
                    ))
            })
    });
    let bounded = said && oracle + BOUND_MARGIN <= need;
    if o.gain() < need && bounded {
        eprintln!("protocol {name}: the gain bar met by its other branch (bounded by the observables' noise): {figure}");
    }
    assert!(
        o.gain() >= need || bounded,
        "{name}: the gain asked of a held-out effect ({need} dB), or a bound by the kept observables' noise, said and {BOUND_MARGIN} dB or more below it: {figure}"
    );
}

/// The case `name` of the unseen `set` whose effect lies wholly outside
/// the object: the transfer bar, then (where it costs the speech 1 dB or
/// more) the gain bar or its branch for a correction bounded by its
/// observables ([`gain_or_bounded`]).
fn unseen_bounded(set: &[Case], name: &str) -> Option<Outcome> {
    let c = set.iter().find(|c| c.name == name).unwrap();
    assert!(
        c.speech
            .lines()
            .all(|l| ["camera_motion", "background_motion"]
                .iter()
                .any(|k| l.starts_with(k))),
        "{name}: an effect on the object"
    );
    let o = carries_with(run_with(c, true)?, c, None)?;
    if transfer_alone(name, &o) {
        return Some(o);
    }
    gain_or_bounded(name, &o);
    Some(o)
}

/// A case of the third held-out set, under [`fresh`]'s rules.
fn third(name: &str, transfer_short: Option<&str>, short: Option<&str>) -> Option<Outcome> {
    unseen(&THIRD, name, transfer_short, short)
}

/// The case `name` of the unseen `set`: the transfer bar, then the gain
/// bar where the effect costs the speech 1 dB or more.
fn unseen(
    set: &[Case],
    name: &str,
    transfer_short: Option<&str>,
    short: Option<&str>,
) -> Option<Outcome> {
    let c = set.iter().find(|c| c.name == name).unwrap();
    let o = carries(c, transfer_short)?;
    if transfer_alone(name, &o) {
        assert!(
            short.is_none(),
            "{name}: a mark on a case with nothing to gain"
        );
        return Some(o);
    }
    gain_bar(c.name, &o, short);
    Some(o)
}

/// The played signal (rate, samples) at the frames' instants `k / fps`
/// (`frames` of them), each frame averaging it over `exposure_s` about its
/// instant (the camera's boxcar; 0: the instant itself).
fn at_frames(
    (rate, played): (u32, &[f32]),
    (fps, frames): (u32, usize),
    exposure_s: f64,
    offset: f64,
) -> Vec<f64> {
    let fr = f64::from(rate);
    let p: Vec<f64> = played.iter().map(|&v| f64::from(v)).collect();
    // The running integral of the played signal at its samples' instants
    // (each sample held for its period).
    let mut cum = vec![0.0];
    for &v in &p {
        cum.push(cum[cum.len() - 1] + v / fr);
    }
    let at = |v: &[f64], t: f64| {
        let x = (t * fr).clamp(0.0, (v.len() - 1) as f64);
        let i = (x.floor() as usize).min(v.len() - 2);
        let f = x - i as f64;
        v[i] * (1.0 - f) + v[i + 1] * f
    };
    (0..frames)
        .map(|k| {
            let t = (k as f64 + offset) / f64::from(fps);
            if exposure_s > 0.0 {
                (at(&cum, t + exposure_s / 2.0) - at(&cum, t - exposure_s / 2.0)) / exposure_s
            } else {
                at(&p, t)
            }
        })
        .collect()
}

/// `v`, one sample a frame at `fps`, through the high-pass `listen
/// --calibration` gives its output and the scorer the reference (4th
/// order, its default cutoff).
fn highpass(v: &[f64], fps: u32) -> Vec<f64> {
    let rate = f64::from(fps);
    let cutoff = vibroscope_math::iir::default_highpass_cutoff_hz(rate);
    let mut sos = vibroscope_math::iir::Sos::butterworth_highpass(4, cutoff, rate).unwrap();
    v.iter().map(|&a| sos.step(a)).collect()
}

/// The held-out SNR (dB) against `reference` (the played signal) of the
/// best that a linear filter applied at the frame rate makes of `x` (one
/// sample a frame at `fps`): an FIR of 49 taps fitted by least squares to
/// the reference at the frames' instants through [`highpass`], scored as
/// the recordings are
/// ([`held_out_snr`]; the filtered WAV written to `dir/NAME.wav`). An
/// oracle: it knows the reference, so no correction at the frame rate
/// reaches further (none that is linear and fixed in time).
fn best_filter(dir: &Path, name: &str, x: &[f64], fps: u32, reference: &Path) -> f64 {
    let played = crate::common::read_wav(reference);
    let frames = x.len();
    const L: usize = 24;
    const M: usize = 2 * L + 1;
    let row = |k: usize| &x[k - L..=k + L];
    // The normal matrix of the filter's inputs, and its Cholesky factor
    // (lower triangle), for every offset below.
    let mut a = vec![0.0f64; M * M];
    for k in L..frames - L {
        let r = row(k);
        for (i, &ri) in r.iter().enumerate() {
            for (aij, &rj) in a[i * M..=i * M + i].iter_mut().zip(r) {
                *aij += ri * rj;
            }
        }
    }
    let ridge = 1e-12 * (0..M).map(|i| a[i * M + i]).sum::<f64>();
    for i in 0..M {
        a[i * M + i] += ridge;
        for j in 0..i {
            let mut s = a[i * M + j];
            for q in 0..j {
                s -= a[i * M + q] * a[j * M + q];
            }
            a[i * M + j] = s / a[j * M + j];
        }
        let d = a[i * M + i] - (0..i).map(|q| a[i * M + q].powi(2)).sum::<f64>();
        assert!(d > 0.0, "the normal equations are singular");
        a[i * M + i] = d.sqrt();
    }
    // The frames' instants are known to within a frame (the recording's
    // own delay; what the frame rate folds depends on it): the offset, in
    // tenths of a frame, whose filter leaves the least error.
    let mut best: Option<(f64, [f64; M])> = None;
    for tenth in -10..10 {
        let y = highpass(
            &at_frames(
                (played.0, &played.1),
                (fps, frames),
                0.0,
                f64::from(tenth) / 10.0,
            ),
            fps,
        );
        let mut h = [0.0f64; M];
        for (k, &yk) in y.iter().enumerate().take(frames - L).skip(L) {
            for (hi, &ri) in h.iter_mut().zip(row(k)) {
                *hi += ri * yk;
            }
        }
        for i in 0..M {
            h[i] = (h[i] - (0..i).map(|q| a[i * M + q] * h[q]).sum::<f64>()) / a[i * M + i];
        }
        for i in (0..M).rev() {
            h[i] = (h[i] - (i + 1..M).map(|q| a[q * M + i] * h[q]).sum::<f64>()) / a[i * M + i];
        }
        let sse: f64 = (L..frames - L)
            .map(|k| (y[k] - row(k).iter().zip(&h).map(|(v, c)| v * c).sum::<f64>()).powi(2))
            .sum();
        if best.as_ref().is_none_or(|(b, _)| sse < *b) {
            best = Some((sse, h));
        }
    }
    let (_, h) = best.unwrap();
    let out: Vec<f32> = (0..frames)
        .map(|k| {
            if k < L || k + L >= frames {
                x[k] as f32
            } else {
                row(k).iter().zip(&h).map(|(v, c)| v * c).sum::<f64>() as f32
            }
        })
        .collect();
    let wav = dir.join(format!("{name}.wav"));
    crate::common::write_wav_f32(&wav, fps, &out);
    held_out_snr(&wav, reference)
}

/// [`best_filter`] of a noise-free recording of the played signal whose
/// every frame averages the motion over `exposure_s` (a recovery equal to
/// the motion): what the exposure alone leaves to a correction at the
/// frame rate.
fn frame_rate_limit(
    dir: &Path,
    reference: &Path,
    (fps, frames): (u32, usize),
    exposure_s: f64,
) -> f64 {
    let played = crate::common::read_wav(reference);
    let x = highpass(
        &at_frames((played.0, &played.1), (fps, frames), exposure_s, 0.0),
        fps,
    );
    let name = format!(
        "limit-{}-{:.0}us",
        reference.file_stem().unwrap().to_string_lossy(),
        exposure_s * 1e6
    );
    best_filter(dir, &name, &x, fps, reference)
}

/// What `listen --calibration` and the report say the exposure leaves.
const FOLDED: &str = "no correction at the frame rate tells the two apart";

/// The held-out exposure, by the acceptance's other branch where its gain
/// falls short of the bar: "the report says in words that the residual is
/// explained by a named observable it cannot correct, and why". Its gain
/// missed the bar on its first run (+1.28 dB of the 7.84 dB it costs),
/// and was then looked at (the case's former mark: the rest of the cost is
/// the speech above the frame rate's Nyquist frequency). This branch was
/// written afterwards, so it is checked by measurement, not taken on
/// trust:
/// - the bar is out of reach: the best fixed filter at the frame rate,
///   fitted to this recording by an oracle that knows the speech
///   ([`best_filter`]), gains less than the bar over the recording without
///   a calibration;
/// - the calibration reaches that oracle within 1 dB;
/// - the exposure explains what is left: the same oracle on a noise-free
///   recording through the same exposure ([`frame_rate_limit`], from the
///   played speech alone), its error added as power to that of the
///   recording without the effect (the ceiling), lands within 1 dB of the
///   oracle on this recording;
/// - the computation can see a correctable recording: the same limit
///   through no exposure, and for the chirp (below 1 kHz) through the same
///   exposure, lies over 20 dB higher;
/// - the chirp's report (`cannot_correct` of its exposure) and `listen
///   --calibration` on the speech say so in words.
///
/// A gain that meets the bar passes as any other case.
#[test]
fn held_out_exposure() {
    let c = HELD_OUT.iter().find(|c| c.name == "exposure").unwrap();
    let Some(o) = carries(c, None) else {
        return;
    };
    let need = o.need();
    let figure = format!(
        "speech {:.2} -> {:.2} dB ({:+.2}); the effect costs {:.2} dB (kept {})",
        o.none,
        o.with,
        o.gain(),
        o.cost(),
        o.kept
    );
    if o.gain() >= need {
        eprintln!("protocol exposure: the gain asked ({need} dB) is met: {figure}");
        return;
    }
    let exposure_s = c
        .speech
        .strip_prefix("exposure_us = ")
        .and_then(|v| v.parse::<f64>().ok())
        .expect("the case's exposure")
        * 1e-6;
    let d = tempfile::tempdir().unwrap();
    let speech = d.path().join("speech.wav");
    let (rate, played) = &o.speech;
    crate::common::write_wav_f32(&speech, *rate, played);
    let chirp = d.path().join("chirp.wav");
    write_chirp(&chirp);
    let frames = (2200, 4400);
    let limit = frame_rate_limit(d.path(), &speech, frames, exposure_s);
    let point = frame_rate_limit(d.path(), &speech, frames, 0.0);
    let chirp_limit = frame_rate_limit(d.path(), &chirp, frames, exposure_s);
    let (fps, recorded) = &o.recording;
    let x: Vec<f64> = recorded.iter().map(|&v| f64::from(v)).collect();
    let oracle = best_filter(d.path(), "oracle", &x, *fps, &speech);
    // The exposure's limit and the errors of the recording without the
    // effect (the ceiling), added as powers: what the two leave together.
    let both = -10.0 * (10f64.powf(-limit / 10.0) + 10f64.powf(-o.ceiling / 10.0)).log10();
    eprintln!(
        "protocol exposure: {figure}. The best fixed filter at the frame rate (an oracle that knows the speech) makes of this recording {oracle:.2} dB ({:+.2} over it without a calibration; the calibration stops {:.2} dB from it). The exposure alone leaves it {limit:.2} dB (a noise-free recording through it; {point:.2} dB through no exposure, {chirp_limit:.2} dB for the chirp through it); with the errors of the recording without the effect ({:.2} dB), {both:.2} dB",
        oracle - o.none,
        oracle - o.with,
        o.ceiling
    );
    assert!(
        point > limit + 20.0 && chirp_limit > limit + 20.0,
        "the exposure's limit must lie far higher for a correctable recording: {point:.2} dB through no exposure, {chirp_limit:.2} dB for the chirp, {limit:.2} dB for the speech"
    );
    assert!(
        oracle - o.none < need,
        "a fixed filter at the frame rate could gain {:+.2} dB on this recording ({oracle:.2} dB): the bar ({need} dB) is within reach, so the case must meet it: {figure}",
        oracle - o.none
    );
    assert!(
        o.with >= oracle - 1.0,
        "the calibration stops {:.2} dB short of the best fixed filter at the frame rate ({oracle:.2} dB): {figure}",
        oracle - o.with
    );
    assert!(
        (both - oracle).abs() < 1.0,
        "the exposure's limit with the recording's other errors ({both:.2} dB) does not account for the best fixed filter's figure ({oracle:.2} dB): something else limits it"
    );
    let said = o.report["effects"]
        .as_array()
        .into_iter()
        .flatten()
        .find(|e| e["name"] == "exposure")
        .and_then(|e| e["cannot_correct"].as_str())
        .unwrap_or_default();
    assert!(
        said.contains(FOLDED),
        "the chirp's report must say what its exposure cannot correct: {}",
        o.report["effects"]
    );
    assert!(
        o.notes.contains(FOLDED),
        "listen --calibration must say what the exposure leaves: {}",
        o.notes
    );
    eprintln!("protocol exposure: the gain asked ({need} dB) is out of reach of any correction at the frame rate, and the report says why: {said}");
}

#[test]
fn seen_camera() {
    seen("camera", None);
}
#[test]
fn seen_light() {
    seen("light", None);
}
#[test]
fn seen_other_object() {
    seen("other_object", None);
}
#[test]
fn seen_square_law() {
    seen("square_law", None);
}
#[test]
fn seen_soft_clip() {
    seen("soft_clip", None);
}
/// Marked as missing the transfer bar until issue 50's fifth part: -1.70
/// dB at the frame rate (the strips' delays, applied there, misalign the
/// aliases of the speech above the frame rate's Nyquist frequency, which
/// the reference sampled at the frame's instants holds). Since then
/// `listen --calibration` unfolds a readout by itself (twice the frame
/// rate), and the WAVs are scored against the reference band-limited to
/// each one's Nyquist frequency ([`Outcome`]).
#[test]
fn seen_rolling_readout() {
    seen("rolling_readout", None);
}
#[test]
fn seen_interference() {
    seen("interference", None);
}
#[test]
fn seen_column_noise() {
    seen("column_noise", None);
}
#[test]
fn held_out_clock() {
    held_out("clock", None, None);
}
#[test]
fn held_out_resonance() {
    held_out("resonance", None, None);
}
#[test]
fn held_out_mover_left() {
    held_out(
        "mover_left",
        None,
        Some("first run: the effect costs the speech 0.00 dB (the mover lies outside the region and the recovery does not see it); nothing kept, nothing to gain"),
    );
}
#[test]
fn held_out_light_vertical() {
    held_out(
        "light_vertical",
        None,
        Some("first run: the effect costs 0.17 dB (the phase recovery barely sees the light); nothing kept, nothing to gain"),
    );
}
#[test]
fn held_out_camera_tone() {
    held_out("camera_tone", None, None);
}
#[test]
fn held_out_clock_and_resonance() {
    held_out("clock_and_resonance", None, None);
}
#[test]
fn held_out_light_and_mover() {
    held_out(
        "light_and_mover",
        None,
        Some("first run: the effects cost 0.51 dB; nothing kept, nothing to gain. Since session 71 (weak terms kept beyond chance) explained:light is kept (6.60 -> 7.09 dB on the chirp) and the speech gains +0.47 dB of the 0.51"),
    );
}
#[test]
fn family_dropped_frames() {
    family("dropped_frames");
}
#[test]
fn family_gain_drift() {
    family("gain_drift");
}
#[test]
fn family_region_gain() {
    family("region_gain");
}
#[test]
fn held_out_mover_in_region() {
    held_out(
        "mover_in_region",
        None,
        Some("first run: the effect costs 0.21 dB; nothing kept, nothing to gain. Since session 56 (tiles inside the region that move on their own observed) explained:other_object is kept on the chirp (+0.62 dB there) and the speech moves -0.13 dB"),
    );
}
/// First run -1.19 dB (the stored FIR held the chirp texture's
/// coupling); since the camera term is fitted again on each recording
/// (its observable does not follow the reference), -0.00 dB: fitted on
/// the speech recording, the term explained almost none of it. Looked at
/// in the sixth part: align shifted the bands that see the shake by 5
/// frames on the speech recording (0 on the chirp's), and a tile's motion
/// is now fitted about its best lag: +2.94 dB. Met since session 56
/// (tiles inside the region that move on their own observed: the ring
/// around the object moves with the camera): +3.21 dB.
#[test]
fn held_out_camera_vertical() {
    held_out("camera_vertical", None, None);
}
#[test]
fn held_out_camera_diagonal() {
    held_out("camera_diagonal", None, None);
}
#[test]
fn held_out_mover_columns() {
    held_out("mover_columns", None, None);
}
#[test]
fn held_out_resonance_and_camera() {
    held_out("resonance_and_camera", None, None);
}
#[test]
fn held_out_interference_pair() {
    held_out("interference_pair", None, None);
}
#[test]
fn seen_row_noise() {
    seen("row_noise", None);
}
#[test]
fn held_out_readout_site() {
    held_out(
        "readout_site",
        None,
        Some("first run: nothing kept on the chirp (0.05 px under 2 DN of noise: the strips' lags are not told apart), and the readout costs the speech -0.02 dB; nothing to gain"),
    );
}
#[test]
fn held_out_readout_partial() {
    held_out(
        "readout_partial",
        None,
        Some("first run +0.52 dB, more than the 0.39 dB the readout costs (weak: 1 dB asked); capture_time kept (the object's rows spread over 28% of a frame period, too little to tell a frequency from its alias, as `listen --unfold` says: the recovery stays at the frame rate)"),
    );
}
#[test]
fn fresh_camera_steep() {
    let _ = fresh("camera_steep", None, None);
}
/// First run (session 53): +2.09 dB of the 4.85 dB it costs (kept
/// explained:camera on the bottom row of tiles; the mover in rows 0-27
/// not explained). Session 56: +2.23 once the tiles inside the region
/// that move on their own were observed, then +3.04 (met; this case was
/// looked at) once the tiles that move least are pooled for the camera
/// (24 tiles, the mover's six left out).
#[test]
fn fresh_camera_and_mover() {
    let _ = fresh("camera_and_mover", None, None);
}
#[test]
fn fresh_camera_tone_low() {
    let _ = fresh("camera_tone_low", None, None);
}
/// First run (session 53): +0.66 dB of the 6.08 dB it costs (kept
/// explained:light twice: the background around the object moving was
/// taken for the light). Met since session 56, where the explainer
/// observes the tiles inside the region that move on their own (this
/// case was looked at while that was designed): +5.79 dB, kept
/// explained:other_object.
#[test]
fn fresh_mover_around_object() {
    let _ = fresh("mover_around_object", None, None);
}
#[test]
fn fresh_row_and_column_noise() {
    let _ = fresh("row_and_column_noise", None, None);
}
#[test]
fn fresh_interference_triple() {
    let _ = fresh("interference_triple", None, None);
}
/// First run (session 53): -6.18 dB (kept time_base and transfer_function
/// on the chirp; there is no clock error in this scene), both bars missed.
/// Session 55, first: the transfer table's edge bins (fed by the window's
/// leakage alone) left out and its end values held beyond it, where they
/// stepped to 0 dB: the false clock error went, +0.82 dB, but a gain that
/// falls over the sweep (`gain_drift`, not carried) had taken the dip from
/// the transfer function, whose phase then swung where its gain did not.
/// Then the confounded explanations judged with each transfer function's
/// phase made from its gain (minimum phase): the chirp's calibration is
/// the dip's (transfer_function, a clock error within its uncertainty of
/// none), and its inverse boosts by 8 dB at 730-851 Hz, where the
/// camera folds the speech's content from above 1100 Hz: -3.86 dB. The
/// same calibration on speech with nothing above 1 kHz gains +6.05 dB
/// (13.81 -> 19.86, measured once with a temporary switch, not kept).
/// `listen` says where the inverse boosts and what it boosts with it.
/// Session 65: the 1.3 sd clock error let go (within three of its
/// standard deviations of none), then a -116 ppm one (3.4 sd) fitted
/// first and the table refitted on top judged 0.9 dB better with the
/// tables' phases made from their gains, and kept: -7.13 dB; the
/// explainer's brightness term no longer carried: -7.43 dB.
/// Session 67: the table's phase held a delay of about 80 µs (the dip's
/// group delay had biased the linear model's lag on the sweep), which
/// shifts the speech's content folded from above 1100 Hz as though it
/// were in band, and its last row (the dip's -6.2 dB at 851 Hz) held up
/// to the Nyquist frequency. The table now returns to the band's median
/// gain above the sweep and its phase carries no pure delay: no clock
/// error is kept (transfer_function alone), +3.13 dB, both bars met (not
/// a held-out figure: designed on this case).
#[test]
fn fresh_resonance_dip() {
    let Some(o) = fresh("resonance_dip", None, None) else {
        return;
    };
    assert!(!o.kept.contains("time_base"), "kept {}", o.kept);
    // The gain drift that took the dip before is judged out by the phase.
    assert!(!o.kept.contains("gain_drift"), "kept {}", o.kept);
    assert!(
        o.notes.contains("transfer_function boosts by up to"),
        "listen --calibration must say where the inverse boosts: {}",
        o.notes
    );
}
#[test]
fn fresh_resonances_and_clock() {
    let _ = fresh("resonances_and_clock", None, None);
}
/// First run (session 53): -2.57 dB of the 3.79 dB it costs, both bars
/// missed (static_nonlinearity kept on the chirp, +6.68 dB there, applied
/// to the speech rescaled by 1.1657). Looked at in session 54: the
/// region's motion in pixels held the still background's texture, so the
/// scale carried was 1.17 where the object's motion asked for 1.56; read
/// on the region's tiles that move with the recovery, it is 1.55 and the
/// speech gains +2.92 dB. Seen since, so no longer a held-out figure.
#[test]
fn fresh_cubic() {
    let _ = fresh("cubic", None, None);
}
#[test]
fn fresh_readout_mid() {
    let _ = fresh("readout_mid", None, None);
}
#[test]
fn third_site_cubic() {
    let _ = third("site_cubic", None, None);
}
#[test]
fn third_site_square() {
    let _ = third("site_square", None, None);
}
/// First run with the even term negated (session 54): +2.40 dB of the
/// 4.73 dB it costs, the 3 dB bar missed (kept static_nonlinearity, +10.42
/// dB on the chirp; scale carried 1.551). Looked at in session 62: the
/// inverse fitted on the sweep's constant amplitude was right there
/// only; derived from the fitted response over speech's amplitudes
/// ([`NINTH`]'s note), +4.30. Seen since.
#[test]
fn third_mixed_poly() {
    let _ = third("mixed_poly", None, None);
}
#[test]
fn third_cubic_and_camera() {
    let _ = third(
        "cubic_and_camera",
        None,
        Some("first run (session 54): +0.00 dB of the 2.61 dB it costs (weak: 1 dB asked); nothing kept on the chirp (4.24 dB: 0.05 px under 2 DN of noise and the camera's 0.02 px). Since session 56 (tiles inside the region that move on their own observed) explained:camera is kept (4.24 -> 4.75 dB on the chirp) and the speech gains +0.81 dB"),
    );
}
/// First run (session 54): +0.00 dB, soft_clip kept on the chirp (+0.81
/// dB) and not carried then. Looked at after it: carried (as soft clips
/// are since), it took the speech to -2.26 dB, the chirp's third and
/// fifth harmonics left in its residual; `listen` now leaves out a static
/// response's inverse whose calibration left harmonics, and says so.
#[test]
fn third_quintic() {
    // The gain bar, first run (session 54): +0.00 dB of the 3.14 dB it
    // costs (weak: 1 dB asked); soft_clip kept on the chirp (+0.81 dB, its
    // third and fifth harmonics left), left out by listen --calibration.
    // Session 63: the report names the fold (response_folds), the gain
    // bar's other branch (a case looked at since session 54).
    let Some(o) = fold_case(&THIRD, "quintic") else {
        return;
    };
    assert!(
        o.notes.contains(
            "soft_clip left out: its calibration's residual still holds the reference's harmonics"
        ),
        "listen --calibration must say why the soft clip is left out: {}",
        o.notes
    );
}
#[test]
fn third_cubic_weak() {
    let _ = third("cubic_weak", None, None);
}
#[test]
fn fourth_soft_clip_offcentre() {
    let _ = fourth("soft_clip_offcentre", None, None);
}
#[test]
fn fourth_cubic_offcentre() {
    let _ = fourth("cubic_offcentre", None, None);
}
/// First run (session 54): +2.96 dB of what was then measured as a 9.96
/// dB cost, the 3 dB bar missed (kept static_nonlinearity, 16.35 ->
/// 31.16 dB on the chirp; scale carried 1.320, read on 3 and 2 tiles).
/// That ceiling was the default object's, twice this one's side: with
/// the ceiling framed as the case (session 62, [`framing`]) the effect
/// costs 3.90 dB, weak (1 dB asked), and the same +2.96 meets the bar.
/// Its speech figures did not change.
#[test]
fn fourth_square_small_object() {
    let _ = fourth("square_small_object", None, None);
}
#[test]
fn fourth_soft_clip_and_resonance() {
    let _ = fourth("soft_clip_and_resonance", None, None);
}
#[test]
fn fifth_dip_low() {
    let _ = fifth("dip_low", None, None);
}
#[test]
fn fifth_resonance_and_drift() {
    let _ = fifth("resonance_and_drift", None, None);
}
#[test]
fn fifth_dip_and_clock() {
    let _ = fifth("dip_and_clock", None, None);
}
#[test]
fn fifth_two_dips() {
    let _ = fifth("two_dips", None, None);
}
#[test]
fn sixth_ring_along_y() {
    let _ = sixth("ring_along_y", None, None);
}
#[test]
fn sixth_ring_left_strip() {
    let _ = sixth(
        "ring_left_strip",
        None,
        Some("first run (session 56): +0.98 dB of the 1.17 dB it costs (weak: 1 dB asked; kept explained:other_object, 6.39 -> 7.08 dB on the chirp)"),
    );
}
#[test]
fn sixth_ring_and_camera() {
    let _ = sixth("ring_and_camera", None, None);
}
#[test]
fn sixth_patch_below_object() {
    let _ = sixth("patch_below_object", None, None);
}
#[test]
fn seventh_camera_and_side_mover() {
    let _ = seventh("camera_and_side_mover", None, None);
}
#[test]
fn seventh_camera_y_and_mover() {
    let _ = seventh("camera_y_and_mover", None, None);
}
#[test]
fn seventh_camera_and_two_movers() {
    let _ = seventh("camera_and_two_movers", None, None);
}
/// Marked until session 76 (first run, session 56: +0.00 dB of the 1.61
/// dB it costs, nothing kept; since session 71 +0.39 dB, explained:camera
/// and explained:other_object kept). Since session 76 held to the gain
/// bar or its branch for a correction its own observables bound
/// ([`gain_or_bounded`], designed after this case's figures were known;
/// the twentieth set is its unseen check): `listen --calibration` says
/// the camera's 18 tiles hold their own noise at 35% of its power (0.27
/// true; 0.29 read through the recovery's own high-pass since session
/// 77), and the best correction from the kept observables, fitted on
/// the effect's own part with the truth's help, gains +0.71 dB of the 1
/// asked (the camera's noise, and the mover beside the region leaking
/// into the recovery's coarse bands, which its single tile follows).
#[test]
fn seventh_camera_weak_and_mover() {
    let _ = unseen_bounded(&SEVENTH, "camera_weak_and_mover");
}
#[test]
fn eighth_square_and_cubic() {
    let _ = eighth("square_and_cubic", None, None);
}
#[test]
fn eighth_hardening() {
    let _ = eighth("hardening", None, None);
}
#[test]
fn eighth_square_offcentre() {
    let _ = eighth("square_offcentre", None, None);
}
#[test]
fn eighth_fifth_power_mix() {
    let _ = eighth("fifth_power_mix", None, None);
}
#[test]
fn ninth_cubic_and_resonance() {
    let _ = ninth("cubic_and_resonance", None, None);
}
#[test]
fn ninth_square_minus() {
    let _ = ninth("square_minus", None, None);
}
#[test]
fn ninth_stiffening_square() {
    let _ = ninth("stiffening_square", None, None);
}
#[test]
fn ninth_cubic_small_offcentre() {
    let _ = ninth("cubic_small_offcentre", None, None);
}
#[test]
fn tenth_fold_cubic() {
    // The gain bar's first runs (session 62): +0.00 dB of the 6.39 dB it
    // costs; soft_clip kept on the chirp (15.98 -> 18.55 dB), its 3rd and
    // 5th harmonics left, so listen leaves it out; no static response is
    // fitted where the response folds back within the sweep. Since
    // session 63 the report names the fold (response_folds), the gain
    // bar's other branch (this set had run before: not a held-out figure).
    let _ = fold_case(&TENTH, "fold_cubic");
}
#[test]
fn tenth_fold_one_side() {
    // The gain bar's first run (session 62, with the inverse derived where
    // the response rises, not kept): +0.00 dB, nothing kept; with the
    // change as kept: +2.60 dB of the 6.35 dB it costs
    // (static_nonlinearity, 13.63 -> 14.38 dB on the chirp). Since session
    // 63 the report names the fold (response_folds), the gain bar's other
    // branch (this set had run before: not a held-out figure).
    let _ = fold_case(&TENTH, "fold_one_side");
}
#[test]
fn tenth_fold_offcentre() {
    // The gain bar's first runs (session 62): +0.00 dB of the 4.25 dB it
    // costs; nothing kept on the chirp (14.25 dB). Since session 63 the
    // report names the fold (response_folds), the gain bar's other branch
    // (this set had run before: not a held-out figure).
    let _ = fold_case(&TENTH, "fold_offcentre");
}
#[test]
fn tenth_fold_and_resonance() {
    // First runs (session 62): -13.44 dB (9.63 -> -3.81) of the 16.58 dB
    // it costs; only transfer_function kept on the chirp (8.94 -> 10.14
    // dB), boosting by up to 14.8 dB at 275-327 Hz, where the resonance
    // folds the response and the sweep measured a dip. Session 63 designed
    // the table's level-dependent bins on this case (so it is seen from
    // then on): the transfer bar is met, and the gain bar by its other
    // branch ([`gain_or_level_named`]).
    let _ = words_case(&TENTH, "fold_and_resonance", None, |o| {
        gain_or_level_named("fold_and_resonance", o, &[300.0], None)
    });
}
#[test]
fn eleventh_soft_fold_at_resonance() {
    let _ = eleventh("soft_fold_at_resonance", 450.0, None, None);
}
/// First run (session 63): -8.89 dB (10.75 -> 1.87) of the 15.45 dB it
/// costs; time_base (110 ppm, confounded with the table) and
/// transfer_function kept: the resonance's phase where the response
/// compresses reads as a clock error. Session 64 (the level-dependent
/// stretch left out of every fit): -1.29 dB, transfer_function and
/// static_nonlinearity, no clock error; the table interpolated its gain
/// across the level-dependent bins from flanks measured part-way into the
/// compression, and its inverse boosted the resonance the speech sees.
/// Session 66 (the table holds the band's median gain there): +0.06 dB,
/// the transfer bar met.
#[test]
fn eleventh_fold_at_high_resonance() {
    let Some(o) = eleventh("fold_at_high_resonance", 700.0, None, None) else {
        return;
    };
    assert!(
        o.notes.contains("drove the object into its nonlinear range"),
        "listen --calibration must say what the sweep's level did to the corrections it applies: {}",
        o.notes
    );
}
#[test]
fn eleventh_one_sided_at_resonance() {
    let _ = eleventh("one_sided_at_resonance", 350.0, None, None);
}
#[test]
fn eleventh_stiffening_at_resonance() {
    let _ = eleventh("stiffening_at_resonance", 400.0, None, None);
}
/// First run (session 63): +0.00 dB. Session 64 (the level-dependent
/// stretch left out of every fit): -0.97 dB (12.09 -> 11.13), soft_clip
/// and a -35 ppm time_base kept (the resonance's phase on either side of
/// the stretch left out read as a clock error), the transfer bar missed.
/// Session 65 (an effect within three standard deviations of none let
/// go; the clock error stood at 2.8): soft_clip alone, +0.00 dB, met.
#[test]
fn twelfth_fold_low_resonance() {
    let _ = twelfth("fold_low_resonance", &[200.0], None, None);
}
#[test]
fn twelfth_compress_two_resonances() {
    let _ = twelfth(
        "compress_two_resonances",
        &[350.0, 650.0],
        // First run (session 63): -3.91 dB (9.81 -> 5.90) of the 16.39 dB
        // it costs; time_base and transfer_function kept. Since session 64
        // (not a held-out figure): +1.21, transfer_function alone.
        None,
        None,
    );
}
#[test]
fn twelfth_fold_at_resonance_offcentre() {
    let _ = twelfth(
        "fold_at_resonance_offcentre",
        &[500.0],
        // First run (session 63): -1.89 dB (9.48 -> 7.59) of the 17.83 dB
        // it costs; transfer_function kept. Since session 64 (not a
        // held-out figure): +0.44, transfer_function and soft_clip.
        None,
        None,
    );
}
/// First run (session 63): -15.20 dB (10.18 -> -5.03) of the 16.03 dB it
/// costs; time_base, transfer_function and dropped_frames kept on the
/// chirp (-3.72 -> 2.21 dB). Session 64: -0.43 dB, transfer_function
/// alone, its gain interpolated across the level-dependent bins. Session
/// 66 (the table holds the band's median gain there): +1.76 dB, the
/// transfer bar met.
#[test]
fn twelfth_quintic_at_resonance() {
    let _ = twelfth("quintic_at_resonance", &[600.0], None, None);
}
/// First run (session 63): -4.48 dB (9.70 -> 5.22) of the 16.50 dB it
/// costs, both bars missed; transfer_function, static_nonlinearity and
/// the explainer's light kept. Session 65 (not a held-out figure): the
/// explainer's term was a tile's brightness inside the region that
/// follows the reference (0.90), the object's motion seen through the
/// chirp's texture, subtracted from the speech's recording (another
/// texture) through its stored taps; `listen --calibration` no longer
/// carries such a term: +11.02 dB (9.70 -> 20.71), both bars met.
#[test]
fn twelfth_square_at_resonance() {
    let Some(o) = twelfth("square_at_resonance", &[], None, None) else {
        return;
    };
    assert!(
        o.notes.contains("of a tile's brightness left out"),
        "listen --calibration must say it left the brightness term out: {}",
        o.notes
    );
}
#[test]
fn thirteenth_fold_at_sharp_resonance() {
    let _ = thirteenth("fold_at_sharp_resonance", &[550.0], None);
}
#[test]
fn thirteenth_fold_at_mild_resonance() {
    let _ = thirteenth("fold_at_mild_resonance", &[250.0], None);
}
#[test]
fn thirteenth_fold_beside_linear_resonance() {
    let _ = thirteenth("fold_beside_linear_resonance", &[320.0], None);
}
#[test]
fn thirteenth_quintic_low_resonance() {
    let _ = thirteenth("quintic_low_resonance", &[300.0], None);
}
#[test]
fn thirteenth_fold_at_resonance_small_object() {
    let _ = thirteenth("fold_at_resonance_small_object", &[420.0], None);
}
/// First run: +1.34 dB of the 12.79 dB it costs (transfer_function,
/// exposure and explained:object kept), on the change as first written
/// (the table returned to the median from the fit frames' last bin, 868
/// Hz). On the change as kept (from the last bin the sweep reaches over
/// the whole recording; this set had been seen by then): +2.51 dB. In
/// session 74 the kept table measured again on the whole recording (or
/// extended over it above the fit part's last bin) gave +3.21 (+3.20);
/// not kept (docs/calibration.md, session 74). Since session 75 `listen
/// --calibration` applies the table as a Wiener inverse against what
/// folds from above the Nyquist frequency: +5.00 dB, the bar met, the
/// mark removed.
#[test]
fn fourteenth_dip_near_top() {
    let _ = fourteenth("dip_near_top", None, None);
}
#[test]
fn fourteenth_resonance_near_top() {
    let _ = fourteenth("resonance_near_top", None, None);
}
/// First run: +0.00 dB of the 13.28 dB it costs (gain_drift kept, which
/// `listen --calibration` does not carry; no table). The dip (1000 Hz)
/// lies above the highest frequency the sweep reaches (about 920 Hz on
/// this recording): nothing measured it. On the change as kept: -0.09 dB
/// (a table kept beside the drift).
///
/// Since session 68 the chirp's report and `listen --calibration` on the
/// speech say that the table was not measured above the sweep's band, and
/// how much of the speech's recovery lies there (checked below). That is
/// not counted as the gain bar's other branch: the words follow from the
/// sweep's band alone, and every case that keeps a table below the
/// Nyquist frequency gets them, whether or not an effect lies there.
#[test]
fn fourteenth_dip_above_sweep() {
    let o = fourteenth(
        "dip_above_sweep",
        None,
        Some("first run (session 67): +0.00 dB of the 13.28 dB it costs (the dip lies above the sweep's band); on the change as kept: -0.09 dB"),
    );
    says_unmeasured(o.as_ref());
}

/// Where a case keeps a transfer table measured short of the Nyquist
/// frequency, the chirp's report says where it was not measured, and
/// `listen --calibration` on the speech how much of the recording lies
/// there (whatever the share: on `dip_above_sweep` the dip itself makes
/// it small, 0.9% of the recovery's power above 851 Hz).
fn says_unmeasured(o: Option<&Outcome>) {
    let Some(o) = o else { return };
    let band = o.report["effects"]
        .as_array()
        .into_iter()
        .flatten()
        .find(|e| e["name"] == "transfer_function")
        .and_then(|e| e["parameters"]["measured_hz"][1].as_f64());
    let Some(hi) = band else { return };
    if hi >= (1.0 - vibroscope_math::calibrate::UNMEASURED_EDGE) * 1100.0 {
        return;
    }
    let calibrate = o.report["notes"].to_string();
    assert!(
        calibrate.contains("transfer_function measured the object's response at"),
        "the chirp's report does not say where its table was measured: {calibrate}"
    );
    assert!(
        o.notes
            .contains(&format!("of its power above {hi:.0} Hz and")),
        "listen --calibration does not say how much of the speech lies above {hi:.0} Hz: {}",
        o.notes
    );
}
/// First run: -0.21 dB of the 11.55 dB it costs (gain_drift and
/// transfer_function kept). The resonance (980 Hz) lies above the
/// highest frequency the sweep reaches: nothing measured it. On the
/// change as kept: -0.20 dB.
///
/// The words of session 68: as for `dip_above_sweep`.
#[test]
fn fourteenth_resonance_above_sweep() {
    let o = fourteenth(
        "resonance_above_sweep",
        None,
        Some("first run (session 67): -0.21 dB of the 11.55 dB it costs (the resonance lies above the sweep's band); on the change as kept: -0.20 dB"),
    );
    says_unmeasured(o.as_ref());
}
#[test]
fn fourteenth_resonance_low_dip_top() {
    let _ = fourteenth("resonance_low_dip_top", None, None);
}
#[test]
fn fourteenth_broad_dip_high() {
    let _ = fourteenth("broad_dip_high", None, None);
}
#[test]
fn fifteenth_faint_shake_y() {
    let _ = fifteenth("faint_shake_y", None, None);
}
#[test]
fn fifteenth_faint_shake_diagonal() {
    let _ = fifteenth("faint_shake_diagonal", None, None);
}
#[test]
fn fifteenth_faint_light() {
    let _ = fifteenth("faint_light", None, None);
}
#[test]
fn fifteenth_faint_ring() {
    let _ = fifteenth("faint_ring", None, None);
}
/// First run: +0.05 dB of the 1.24 dB it costs (weak: 1 dB asked). The
/// chirp kept explained:camera as a weak term (+0.13 dB there, 12.5
/// standard deviations beyond chance); on the speech the term fitted
/// again removes 0.5% of the recovery's energy. The cost is the shake's
/// alone: the speech rendered with the mover and without the shake scores
/// as without either (`vibroscope score`, 9.53 dB both). Measured after
/// the run (numpy over the tiles' `displacement`): the shake rendered
/// without noise (the true motion) would remove 2.37% of the speech
/// recovery's energy, the kept term's 16 tiles remove 0.63%, and weighed
/// by each tile's noise 0.80%: the image's own tiles hold this shake at
/// about -6 dB under their noise. Marked until session 76 (+0.11 dB with
/// the tiles weighed); since then held to the gain bar or its branch for
/// a correction its own observables bound ([`gain_or_bounded`], designed
/// after this case's figures were known; the twentieth set is its unseen
/// check): `listen --calibration` says the 16 tiles hold their own noise
/// at 63% of the pooled motion's power (0.59 true; 0.61 read through the
/// recovery's own high-pass since session 77), and the best
/// correction from them, fitted with the truth's help, gains +0.20 dB.
#[test]
fn fifteenth_faint_shake_and_mover() {
    let _ = unseen_bounded(&FIFTEENTH, "faint_shake_and_mover");
}
#[test]
fn sixteenth_shake_and_top_mover() {
    let _ = sixteenth("shake_and_top_mover", None, None);
}
#[test]
fn sixteenth_diagonal_shake_and_corner_mover() {
    let _ = sixteenth("diagonal_shake_and_corner_mover", None, None);
}
/// First run: +0.90 dB of the 1.10 dB it costs (weak: 1 dB asked),
/// explained:light kept alone; the 0.025 px vertical shake was not kept
/// on the chirp.
#[test]
fn sixteenth_vertical_shake_and_light() {
    let _ = sixteenth(
        "vertical_shake_and_light",
        None,
        Some("first run (session 71): +0.90 dB of the 1.10 dB it costs (weak: 1 dB asked; explained:light kept alone)"),
    );
}
#[test]
fn sixteenth_shake_and_side_movers() {
    let _ = sixteenth("shake_and_side_movers", None, None);
}
#[test]
fn sixteenth_shake_and_ring() {
    let _ = sixteenth("shake_and_ring", None, None);
}
/// First run (session 74, on a change not kept: the kept table measured
/// again on the whole recording): +2.00 dB of the 11.11 dB it costs
/// (transfer_function and explained:object kept); on the code as kept
/// +1.70. Since session 75 (the table applied as a Wiener inverse
/// against what folds from above the Nyquist frequency): +4.34, the bar
/// met, the mark removed.
#[test]
fn seventeenth_dip_at_875() {
    let _ = seventeenth("dip_at_875", None, None);
}
#[test]
fn seventeenth_resonance_at_870() {
    let _ = seventeenth("resonance_at_870", None, None);
}
/// First run (session 74, on a change not kept): +2.49 dB of the 10.17 dB
/// it costs (transfer_function and gain_drift kept); on the code as kept
/// +2.91. (Session 74 read that change's table as broader than the dip,
/// against the object's response computed at the frame rate; the
/// simulator filters at 96 kHz, and against that the table is not
/// broader: docs/calibration.md, session 75.) Since session 75 (the
/// table applied as a Wiener inverse against what folds from above the
/// Nyquist frequency): +4.49, the bar met, the mark removed.
#[test]
fn seventeenth_dip_at_895() {
    let _ = seventeenth("dip_at_895", None, None);
}
#[test]
fn seventeenth_sharp_resonance_at_855() {
    let _ = seventeenth("sharp_resonance_at_855", None, None);
}
#[test]
fn seventeenth_mid_resonance_top_dip() {
    let _ = seventeenth("mid_resonance_top_dip", None, None);
}
#[test]
fn seventeenth_resonance_at_910() {
    let _ = seventeenth("resonance_at_910", None, None);
}
/// First run (session 74, on the narrowed change, not kept): +0.41 dB
/// of the 10.08 dB it costs (transfer_function kept); on the code as kept
/// +0.67. Since session 75 (the table applied as a Wiener inverse
/// against what folds from above the Nyquist frequency): +3.54, the bar
/// met, the mark removed.
#[test]
fn eighteenth_dip_at_865() {
    let _ = eighteenth("dip_at_865", None, None);
}
#[test]
fn eighteenth_resonance_at_890() {
    let _ = eighteenth("resonance_at_890", None, None);
}
#[test]
fn eighteenth_wide_dip_at_850() {
    let _ = eighteenth("wide_dip_at_850", None, None);
}
#[test]
fn eighteenth_stiffening_at_high_resonance() {
    let _ = eighteenth("stiffening_at_high_resonance", None, None);
}
#[test]
fn eighteenth_soft_clip_at_resonance_500() {
    let _ = eighteenth("soft_clip_at_resonance_500", None, None);
}
#[test]
fn eighteenth_dips_mid_and_top() {
    let _ = eighteenth("dips_mid_and_top", None, None);
}
#[test]
fn nineteenth_dip_at_600() {
    let _ = nineteenth("dip_at_600", None, None);
}
#[test]
fn nineteenth_dip_at_780() {
    let _ = nineteenth("dip_at_780", None, None);
}
#[test]
fn nineteenth_deep_dip_at_880() {
    let _ = nineteenth("deep_dip_at_880", None, None);
}
#[test]
fn nineteenth_low_resonance_top_dip() {
    let _ = nineteenth("low_resonance_top_dip", None, None);
}
#[test]
fn nineteenth_broad_dip_at_700() {
    let _ = nineteenth("broad_dip_at_700", None, None);
}
#[test]
fn nineteenth_soft_clip_and_top_dip() {
    let _ = nineteenth("soft_clip_and_top_dip", None, None);
}

/// First run (session 76): +0.54 dB of the 1.46 it costs; the best from
/// its kept observables +0.53 (the branch).
#[test]
fn twentieth_faint_shake_and_left_mover() {
    let _ = twentieth("faint_shake_and_left_mover");
}
/// First run (session 76): costs 0.60 dB (+0.39 kept): the transfer bar
/// alone.
#[test]
fn twentieth_faint_vertical_shake_and_top_mover() {
    let _ = twentieth("faint_vertical_shake_and_top_mover");
}
/// First run (session 76): costs 0.10 dB, nothing kept: the transfer bar
/// alone.
#[test]
fn twentieth_faint_shake_at_60() {
    let _ = twentieth("faint_shake_at_60");
}
/// First run (session 76): +0.69 dB of the 1.48 it costs; the best from
/// its kept observables +0.73 (the branch).
#[test]
fn twentieth_faint_shake_and_corner_movers() {
    let _ = twentieth("faint_shake_and_corner_movers");
}
/// First run (session 76): +1.60 dB of the 2.56 it costs (met).
#[test]
fn twentieth_shake_and_bottom_mover() {
    let _ = twentieth("shake_and_bottom_mover");
}
/// First run (session 76): costs 0.93 dB (+0.90): the transfer bar alone.
#[test]
fn twenty_first_ring_right_strip() {
    let _ = twenty_first("ring_right_strip");
}
/// First run (session 76): costs 0.70 dB (+0.59): the transfer bar alone.
#[test]
fn twenty_first_ring_top_strip_along_y() {
    let _ = twenty_first("ring_top_strip_along_y");
}
/// First run (session 76): +1.06 dB of the 1.20 it costs (met).
#[test]
fn twenty_first_ring_bottom_strip() {
    let _ = twenty_first("ring_bottom_strip");
}
/// First run (session 76): costs 0.24 dB, nothing kept: the transfer bar
/// alone.
#[test]
fn twenty_first_faint_ring_left_strip() {
    let _ = twenty_first("faint_ring_left_strip");
}
/// First run (session 76): +2.85 dB of the 3.62 it costs (met).
#[test]
fn twenty_first_camera_and_ring_strip() {
    let _ = twenty_first("camera_and_ring_strip");
}
