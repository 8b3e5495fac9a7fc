//! A stored calibration report (`listen --calibration REPORT.json`): the
//! reusable corrections, then applied to a short signal.
#![no_main]

use libfuzzer_sys::fuzz_target;
use vibroscope_math::calibrate as cal;

fuzz_target!(|data: &[u8]| {
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(data) else {
        return;
    };
    if let Ok(c) = cal::reusable_from_report(&v) {
        let y: Vec<f64> = (0..1024).map(|i| (i as f64 * 0.05).sin()).collect();
        let _ = cal::apply_all(&c, &y, 48_000.0);
    }
});
