//! Units: a request's scale (millimetres per pixel), checked as `--scale` is, and the
//! answers' motion and modal amplitudes in µm or mm beside the pixels.

use serde_json::{json, Value};

use super::{ApiError, ApiResult};

/// The request's scale, checked as `--scale` is.
pub(super) fn scale_of(mm_per_px: Option<f64>) -> ApiResult<Option<vibroscope::units::Scale>> {
    mm_per_px
        .map(|v| {
            vibroscope::units::ScaleArg::MmPerPx(v)
                .resolve(u32::MAX, u32::MAX)
                .map_err(|e| ApiError::unprocessable(format!("scale_mm_per_px: {}", e.message)))
        })
        .transpose()
}

/// A unit for values up to `largest_px` pixels and the factor from pixels
/// to it (the library's choice: µm below 1 mm, else mm; px without a
/// scale).
fn unit_for(scale: Option<&vibroscope::units::Scale>, largest_px: f64) -> (String, f64) {
    use vibroscope::units::{px_to, Quantity, Scale};
    let unit = Scale::unit(scale, Quantity::Displacement, largest_px);
    (unit.to_string(), px_to(unit, scale))
}

/// Adds the motion in the scale's unit to a region's answer: the
/// waveform's `x`, `y` and `unit`, each peak's `amplitude` and the peaks'
/// `amplitude_unit` (the same numbers in px without a scale).
pub(super) fn with_units(v: &mut Value, scale: Option<&vibroscope::units::Scale>) {
    let nums = |a: &Value| -> Vec<f64> {
        a.as_array()
            .map(|a| a.iter().filter_map(Value::as_f64).collect())
            .unwrap_or_default()
    };
    let largest = |a: &[f64]| a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (x, y) = (nums(&v["waveform"]["x_px"]), nums(&v["waveform"]["y_px"]));
    let (unit, k) = unit_for(scale, largest(&x).max(largest(&y)));
    let conv = |a: &[f64]| a.iter().map(|p| p * k).collect::<Vec<f64>>();
    v["waveform"]["x"] = json!(conv(&x));
    v["waveform"]["y"] = json!(conv(&y));
    v["waveform"]["unit"] = json!(unit);
    let amps: Vec<f64> = v["peaks"]
        .as_array()
        .map(|p| {
            p.iter()
                .filter_map(|p| p["amplitude_px"].as_f64())
                .collect()
        })
        .unwrap_or_default();
    let (unit, k) = unit_for(scale, largest(&amps));
    if let Some(peaks) = v["peaks"].as_array_mut() {
        for p in peaks {
            if let Some(a) = p["amplitude_px"].as_f64() {
                p["amplitude"] = json!(a * k);
            }
        }
    }
    v["amplitude_unit"] = json!(unit);
    v["scale_mm_per_px"] = json!(scale.map(|s| s.mm_per_px));
}

/// A modal image's largest amplitude in the scale's unit (`max_amplitude`,
/// `amplitude_unit`).
pub(super) fn mode_units(v: &mut Value, scale: Option<&vibroscope::units::Scale>) {
    let max = v["max_amplitude_px"].as_f64().unwrap_or(0.0);
    let (unit, k) = unit_for(scale, max);
    v["max_amplitude"] = json!(max * k);
    v["amplitude_unit"] = json!(unit);
}
