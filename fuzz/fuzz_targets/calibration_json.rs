//! A stored calibration report (`listen --calibration REPORT.json`): the
//! reusable corrections, the recovery's pixel frame and the explainer's
//! terms (and the confounds it names), each parsed as `listen` parses them, then applied to a short
//! signal (the terms to an observable of their own, as `listen` measures
//! it again).
#![no_main]

use libfuzzer_sys::fuzz_target;
use vibroscope_math::calibrate as cal;

fuzz_target!(|data: &[u8]| {
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(data) else {
        return;
    };
    let y: Vec<f64> = (0..1024).map(|i| (i as f64 * 0.05).sin()).collect();
    // As `listen` brings the report to a recording whose recovery reads
    // 0.37 a pixel.
    let ratio = match cal::frame_from_report(&v) {
        Ok(Some(f)) => 0.37 / f.recovery_per_px,
        _ => 1.0,
    };
    if let Ok(c) = cal::reusable_from_report(&v) {
        let _ = cal::apply_all(&c, &y, 48_000.0);
        let rescaled: Vec<cal::Correction> = c.iter().map(|c| c.rescaled(ratio)).collect();
        let _ = cal::apply_all(&rescaled, &y, 48_000.0);
    }
    // What `listen` says of a kept effect its calibration cannot tell
    // from none.
    let _ = cal::unsettled_from_report(&v);
    // Whether a static response's inverse is carried.
    let _ = cal::harmonics_left_from_report(&v);
    if let Ok(terms) = cal::explained_from_report(&v) {
        let x: Vec<f64> = (0..1024).map(|i| (i as f64 * 0.3).cos()).collect();
        let measured: Vec<cal::Measured> = terms
            .iter()
            .filter(|t| t.refit || !t.observable.is_line())
            .map(|t| {
                let lines = t.observable.is_line();
                cal::Measured {
                    observable: t.observable,
                    channels: match lines {
                        true => cal::line_channels(t.observable, &t.tiles, x.len(), |_| &x),
                        false => vec![x.clone()],
                    },
                    shifts: t.shifts.clone(),
                    reach: 8,
                    spans: cal::reference_spans(x.len(), lines.then_some((400, 32))),
                    taps: (!t.refit).then(|| t.taps.iter().map(|a| a * ratio).collect()),
                }
            })
            .collect();
        let hp = cal::Options::for_rate(2200.0).highpass;
        let _ = cal::remove_explained(&y, &measured, 2200.0, hp);
    }
});
