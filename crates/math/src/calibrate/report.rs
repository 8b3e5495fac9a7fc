//! The report's typed parts (each effect's parameters and uncertainty, the
//! unexplained residual) as they serialise into `REPORT.json`, and the
//! reusable corrections read back from a stored report.
//!
//! Fields are declared in alphabetical order: the JSON keys come out in the
//! order they always had.

use super::{Correction, EffectKind};
use serde::{Deserialize, Deserializer, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// A frame event as reported.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EventReport {
    pub count: u32,
    pub frame: usize,
    /// `"dropped"` or `"duplicated"`.
    pub kind: &'static str,
}

/// An interference line as reported (amplitude in reference units).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LineReport {
    pub amplitude: f64,
    pub freq_hz: f64,
}

/// One effect's parameters as reported (and read back by
/// [`reusable_from_report`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Parameters {
    TimeBase {
        clock_error_ppm: f64,
        declared_fps: f64,
        true_fps: f64,
    },
    Frames {
        events: Vec<EventReport>,
    },
    Exposure {
        exposure_us: f64,
        fraction_of_frame: f64,
    },
    Interference {
        lines: Vec<LineReport>,
    },
    /// The measured response (`k` scales it when applied), its highest
    /// point (frequency, and height above the curve's median), and the
    /// band its rows were measured over (the rows outside it are not
    /// measurements; a report without it was measured over the whole
    /// table).
    Transfer {
        coefficients_db: Vec<f64>,
        frequencies_hz: Vec<f64>,
        k: f64,
        measured_hz: [f64; 2],
        peak_db: f64,
        peak_hz: f64,
        phase_deg: Vec<f64>,
    },
    /// The inverse `u (1 + a3 u² + a5 u⁴)` in the recovery's units, the
    /// saturation level the forward model fitted, and the high-pass it
    /// undoes.
    SoftClip {
        a3: f64,
        a5: f64,
        highpass_hz: Option<f64>,
        highpass_order: Option<usize>,
        level_in_reference_units: f64,
        range: f64,
    },
    /// The inverse `u + a2 u² + …` in the recovery's units (what
    /// `listen --calibration` applies), the same in the reference's units
    /// (`ak g^(k-1)`, g the recovery's gain: to first order the object's
    /// forward response is `x - a2 x² - …` there), the order and the
    /// recovery's range it was fitted over; the high-pass it undoes.
    /// The gain's trend over the recording, relative to its mean: Legendre
    /// coefficients over the recording's span (`samples` long), and its
    /// change from start to end.
    GainDrift {
        coefficients: Vec<f64>,
        samples: usize,
        start_to_end_db: f64,
    },
    /// Strips of rows (first and end row each), each advanced by its
    /// delay and weighted before they are summed; the fitted time per row
    /// and whether the delays are in proportion to it (`linear`) or each
    /// strip's own (`per_region`).
    CaptureTime {
        axis: &'static str,
        delays_us: Vec<f64>,
        end_rows: Vec<u32>,
        first_rows: Vec<u32>,
        line_delay_us: f64,
        member: &'static str,
        weights: Vec<f64>,
    },
    /// Strips of rows (first and end row each) summed at one time with
    /// these weights (negative: the strip moved against the strongest).
    RegionGain {
        axis: &'static str,
        end_rows: Vec<u32>,
        first_rows: Vec<u32>,
        weights: Vec<f64>,
    },
    /// `fitted`: `"response"` where the inverse was derived from the
    /// object's fitted response (since session 62), absent where it was
    /// fitted on the calibration's own amplitudes (reports before).
    Polynomial {
        coefficients: Vec<f64>,
        #[serde(skip_serializing_if = "Option::is_none")]
        fitted: Option<&'static str>,
        highpass_hz: Option<f64>,
        highpass_order: Option<usize>,
        inverse_in_reference_units: Vec<f64>,
        order: usize,
        range: f64,
    },
}

fn list(f: &mut fmt::Formatter<'_>, v: &[f64]) -> fmt::Result {
    write!(f, "[")?;
    for (i, x) in v.iter().enumerate() {
        write!(f, "{}{x}", if i > 0 { ", " } else { "" })?;
    }
    write!(f, "]")
}

/// One line for logs: `key value` pairs.
impl fmt::Display for Parameters {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Parameters::TimeBase {
                clock_error_ppm,
                declared_fps,
                true_fps,
            } => write!(
                f,
                "clock_error_ppm {clock_error_ppm}, declared_fps {declared_fps}, true_fps {true_fps}"
            ),
            Parameters::Frames { events } => {
                write!(f, "events [")?;
                for (i, e) in events.iter().enumerate() {
                    let sep = if i > 0 { ", " } else { "" };
                    write!(f, "{sep}{} {} at frame {}", e.count, e.kind, e.frame)?;
                }
                write!(f, "]")
            }
            Parameters::Exposure {
                exposure_us,
                fraction_of_frame,
            } => write!(
                f,
                "exposure_us {exposure_us}, fraction_of_frame {fraction_of_frame}"
            ),
            Parameters::Interference { lines } => {
                write!(f, "lines [")?;
                for (i, l) in lines.iter().enumerate() {
                    let sep = if i > 0 { ", " } else { "" };
                    write!(f, "{sep}{} Hz amplitude {}", l.freq_hz, l.amplitude)?;
                }
                write!(f, "]")
            }
            Parameters::Transfer {
                coefficients_db,
                frequencies_hz,
                k,
                measured_hz: [lo, hi],
                peak_db,
                peak_hz,
                phase_deg,
            } => {
                write!(
                    f,
                    "k {k}, peak {peak_hz} Hz {peak_db} dB, measured {lo}-{hi} Hz, frequencies_hz "
                )?;
                list(f, frequencies_hz)?;
                write!(f, ", coefficients_db ")?;
                list(f, coefficients_db)?;
                write!(f, ", phase_deg ")?;
                list(f, phase_deg)
            }
            Parameters::SoftClip {
                a3,
                a5,
                level_in_reference_units,
                ..
            } => write!(
                f,
                "a3 {a3}, a5 {a5}, level_in_reference_units {level_in_reference_units}"
            ),
            Parameters::GainDrift {
                coefficients,
                start_to_end_db,
                ..
            } => {
                write!(f, "start_to_end_db {start_to_end_db}, coefficients ")?;
                list(f, coefficients)
            }
            Parameters::CaptureTime {
                delays_us,
                first_rows,
                line_delay_us,
                member,
                ..
            } => {
                write!(f, "{member}, line_delay_us {line_delay_us}, first_rows ")?;
                let rows: Vec<f64> = first_rows.iter().map(|&r| r as f64).collect();
                list(f, &rows)?;
                write!(f, ", delays_us ")?;
                list(f, delays_us)
            }
            Parameters::RegionGain {
                first_rows,
                weights,
                ..
            } => {
                write!(f, "first_rows ")?;
                let rows: Vec<f64> = first_rows.iter().map(|&r| r as f64).collect();
                list(f, &rows)?;
                write!(f, ", weights ")?;
                list(f, weights)
            }
            Parameters::Polynomial {
                inverse_in_reference_units,
                order,
                range,
                ..
            } => {
                write!(f, "order {order}, inverse_in_reference_units ")?;
                list(f, inverse_in_reference_units)?;
                write!(f, ", range {range}")
            }
        }
    }
}

/// The uncertainty of a line's frequency.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LineUncertainty {
    pub freq_hz: f64,
}

/// One standard deviation of each fitted parameter (keys as in
/// [`Parameters`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Uncertainty {
    TimeBase {
        clock_error_ppm: f64,
    },
    /// Of each event's position, frames.
    Frames {
        frame: Vec<f64>,
    },
    Exposure {
        exposure_us: f64,
    },
    Interference {
        lines: Vec<LineUncertainty>,
    },
    /// Of `k` (from the fit's curvature) and of the peak's frequency and
    /// height (a delete-one-block jackknife).
    Transfer {
        k: f64,
        peak_db: f64,
        peak_hz: f64,
    },
    SoftClip {
        a3: f64,
        a5: f64,
        level_in_reference_units: f64,
    },
    /// Of each coefficient, recovery units.
    Polynomial {
        coefficients: Vec<f64>,
    },
    /// Of each coefficient of the gain's trend (relative to its mean).
    GainDrift {
        coefficients: Vec<f64>,
    },
    /// Of each strip's delay and of the time per row, µs.
    CaptureTime {
        delays_us: Vec<f64>,
        line_delay_us: f64,
    },
    /// Of each strip's weight (from its gain's).
    RegionGain {
        weights: Vec<f64>,
    },
}

/// A structure of the residual no accepted effect explains; `kind` names
/// the variant in the JSON.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Unexplained {
    /// Energy at a harmonic `order` of the reference's frequency.
    Harmonics {
        description: String,
        frequencies_hz: Vec<f64>,
        kind: UnexplainedKind,
        level_db: f64,
        order: usize,
        reference_hz: [f64; 2],
    },
    /// Coherent energy where the reference has none.
    CoherentWithoutReference {
        description: String,
        frequencies_hz: Vec<f64>,
        kind: UnexplainedKind,
        level_db: f64,
    },
    /// A lag that changes with frequency.
    LagVsFrequency {
        at_hz: f64,
        description: String,
        frequencies_hz: [f64; 2],
        kind: UnexplainedKind,
        lag_samples_at: f64,
        max_phase_deg: f64,
    },
    /// A gain that changes over time.
    GainOverTime {
        description: String,
        frequencies_hz: [f64; 0],
        gain_range_db: [f64; 2],
        kind: UnexplainedKind,
        /// The trend's power over the level chance reaches (> 1).
        significance: f64,
        start_to_end_db: f64,
    },
    /// A lag that changes across the image (`axis`: "rows"): each
    /// strip's delay about their mean (µs; null where a strip holds no
    /// usable signal) at its central row.
    LagAcrossImage {
        axis: &'static str,
        description: String,
        frequencies_hz: [f64; 0],
        kind: UnexplainedKind,
        lags_us: Vec<f64>,
        rows: Vec<f64>,
        /// The spread's chi-square over the level chance reaches (> 1).
        significance: f64,
    },
    /// Strips that move in antiphase with the strongest: each strip's gain
    /// relative to the strongest's (null where a strip holds no usable
    /// signal) at its central row, and what summing them as one rigid
    /// object loses against summing them with their own signs (dB).
    GainAcrossImage {
        axis: &'static str,
        description: String,
        frequencies_hz: [f64; 0],
        gains: Vec<f64>,
        kind: UnexplainedKind,
        loss_db: f64,
        rows: Vec<f64>,
    },
    /// Frequencies where the gain a sweep measures holds only at its level:
    /// the recovery's harmonics there imply a gain error beyond the rest
    /// of the band's by more than [`super::transfer::LEVEL_DB`]; the
    /// transfer table leaves them out.
    LevelDependent {
        description: String,
        /// The bins left out, each with its harmonics-to-fundamental ratio.
        frequencies_hz: Vec<f64>,
        harmonics_db: Vec<f64>,
        kind: UnexplainedKind,
        /// The largest implied gain error over the band's median.
        max_error_db: f64,
    },
    /// The object's static response stops rising within the sweep.
    ResponseFolds {
        description: String,
        frequencies_hz: [f64; 0],
        kind: UnexplainedKind,
        /// Where it turns, as a share of the sweep's peak motion (signed).
        fold_at: f64,
        /// The response fitted forward, `u + c2 u² + …` with `u` the
        /// motion over the sweep's peak: `[c2, …]`.
        response: Vec<f64>,
        /// How much better it explains the recovery than any response
        /// that rises (dB, held out within the fit blocks).
        better_db: f64,
    },
    /// A lag that changes over time.
    LagOverTime {
        description: String,
        drift_ppm: f64,
        frequencies_hz: [f64; 0],
        kind: UnexplainedKind,
        lag_range_samples: [f64; 2],
    },
}

/// The `kind` key of an [`Unexplained`] entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UnexplainedKind {
    Harmonics,
    CoherentWithoutReference,
    LagVsFrequency,
    LagOverTime,
    GainOverTime,
    LagAcrossImage,
    GainAcrossImage,
    LevelDependent,
    ResponseFolds,
}

impl Unexplained {
    /// Its `kind`.
    pub fn kind(&self) -> UnexplainedKind {
        match self {
            Unexplained::Harmonics { kind, .. }
            | Unexplained::CoherentWithoutReference { kind, .. }
            | Unexplained::LagVsFrequency { kind, .. }
            | Unexplained::LagOverTime { kind, .. }
            | Unexplained::GainOverTime { kind, .. }
            | Unexplained::LagAcrossImage { kind, .. }
            | Unexplained::GainAcrossImage { kind, .. }
            | Unexplained::LevelDependent { kind, .. }
            | Unexplained::ResponseFolds { kind, .. } => *kind,
        }
    }

    /// What it is and what may cause it, in a sentence.
    pub fn description(&self) -> &str {
        match self {
            Unexplained::Harmonics { description, .. }
            | Unexplained::CoherentWithoutReference { description, .. }
            | Unexplained::LagVsFrequency { description, .. }
            | Unexplained::LagOverTime { description, .. }
            | Unexplained::GainOverTime { description, .. }
            | Unexplained::LagAcrossImage { description, .. }
            | Unexplained::GainAcrossImage { description, .. }
            | Unexplained::LevelDependent { description, .. }
            | Unexplained::ResponseFolds { description, .. } => description,
        }
    }
}

impl Correction {
    /// The parameters as reported (and read back by
    /// [`super::reusable_from_report`]).
    pub fn parameters(&self, fs: f64, gain: f64) -> Parameters {
        match self {
            Correction::TimeBase { ppm } => Parameters::TimeBase {
                clock_error_ppm: *ppm,
                declared_fps: fs,
                true_fps: fs * (1.0 + ppm * 1e-6),
            },
            Correction::Frames { events } => Parameters::Frames {
                events: events
                    .iter()
                    .map(|e| EventReport {
                        count: e.delta.unsigned_abs(),
                        frame: e.index,
                        kind: if e.delta > 0 { "dropped" } else { "duplicated" },
                    })
                    .collect(),
            },
            Correction::Exposure { exposure_s } => Parameters::Exposure {
                exposure_us: exposure_s * 1e6,
                fraction_of_frame: exposure_s * fs,
            },
            Correction::Interference { lines } => Parameters::Interference {
                lines: lines
                    .iter()
                    .map(|l| LineReport {
                        amplitude: l.a.hypot(l.b) / gain.abs().max(1e-300),
                        freq_hz: l.freq_hz,
                    })
                    .collect(),
            },
            // Refitted on each recording: no amplitude of its own.
            Correction::Lines { freqs_hz } => Parameters::Interference {
                lines: freqs_hz
                    .iter()
                    .map(|&freq_hz| LineReport {
                        amplitude: f64::NAN,
                        freq_hz,
                    })
                    .collect(),
            },
            Correction::Transfer {
                freqs_hz,
                coef_db,
                phase_deg,
                k,
                measured_hz,
            } => {
                let (peak_hz, peak_db) =
                    super::signal::peak(freqs_hz, coef_db).unwrap_or((f64::NAN, f64::NAN));
                Parameters::Transfer {
                    coefficients_db: coef_db.clone(),
                    frequencies_hz: freqs_hz.clone(),
                    k: *k,
                    measured_hz: *measured_hz,
                    peak_db,
                    peak_hz,
                    phase_deg: phase_deg.clone(),
                }
            }
            Correction::SoftClip {
                a3,
                a5,
                level,
                range,
                highpass,
            } => Parameters::SoftClip {
                a3: *a3,
                a5: *a5,
                highpass_hz: highpass.map(|h| h.1),
                highpass_order: highpass.map(|h| h.0),
                level_in_reference_units: *level,
                range: *range,
            },
            Correction::GainDrift {
                coefs,
                samples,
                start_to_end_db,
            } => Parameters::GainDrift {
                coefficients: coefs.clone(),
                samples: *samples,
                start_to_end_db: *start_to_end_db,
            },
            Correction::CaptureTime {
                rows,
                delays_s,
                weights,
                line_delay_s,
                per_region,
            } => Parameters::CaptureTime {
                axis: "rows",
                delays_us: delays_s.iter().map(|d| d * 1e6).collect(),
                end_rows: rows.iter().map(|r| r.1).collect(),
                first_rows: rows.iter().map(|r| r.0).collect(),
                line_delay_us: line_delay_s * 1e6,
                member: if *per_region { "per_region" } else { "linear" },
                weights: weights.clone(),
            },
            Correction::RegionGain { rows, weights } => Parameters::RegionGain {
                axis: "rows",
                end_rows: rows.iter().map(|r| r.1).collect(),
                first_rows: rows.iter().map(|r| r.0).collect(),
                weights: weights.clone(),
            },
            Correction::Polynomial {
                coefs,
                range,
                highpass,
                from_response,
            } => Parameters::Polynomial {
                coefficients: coefs.clone(),
                fitted: from_response.then_some("response"),
                highpass_hz: highpass.map(|h| h.1),
                highpass_order: highpass.map(|h| h.0),
                inverse_in_reference_units: coefs
                    .iter()
                    .enumerate()
                    .map(|(i, a)| a * gain.powi(i as i32 + 1))
                    .collect(),
                order: coefs.len() + 1,
                range: *range,
            },
        }
    }
}

/// Why a stored report gives no corrections.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReportError {
    /// The text is not a report's shape (the parser's message).
    #[error("{0}")]
    Parse(String),
    #[error("no `effects` list")]
    NoEffects,
    #[error("effects[{index}]: no `name`")]
    NoName { index: usize },
    #[error("effects[{index}] ({name}): no `parameters`")]
    NoParameters { index: usize, name: String },
    #[error("effects[{index}]: effect `{name}`: parameters.{key} must be {expected}")]
    Field {
        index: usize,
        name: String,
        key: &'static str,
        /// `"a finite number"` or `"a list of numbers"`.
        expected: &'static str,
    },
    #[error(
        "effects[{index}]: effect `exposure`: parameters.exposure_us must be > 0 and at most {MAX_EXPOSURE_US} (one second: frame rates are at least 1 Hz), got {value}"
    )]
    Exposure { index: usize, value: f64 },
    #[error("effects[{index}]: effect `{name}`: parameters.{key} must be {range}, got {value}")]
    OutOfRange {
        index: usize,
        name: String,
        key: &'static str,
        range: &'static str,
        value: f64,
    },
    #[error("effects[{index}]: effect `{name}`: frequencies_hz ({freqs}) must increase and match coefficients_db ({coefs})")]
    TransferTable {
        index: usize,
        name: String,
        freqs: usize,
        coefs: usize,
    },
    #[error(
        "effects[{index}]: effect `{name}`: phase_deg has {phases} entries, frequencies_hz {freqs}"
    )]
    TransferPhase {
        index: usize,
        name: String,
        phases: usize,
        freqs: usize,
    },
    #[error("effects[{index}]: unknown effect `{name}`")]
    UnknownEffect { index: usize, name: String },
    #[error("effects[{index}]: effect `time_base`: parameters.clock_error_ppm must be within ±{MAX_CLOCK_ERROR_PPM} ppm, got {value}")]
    ClockError { index: usize, value: f64 },
}

/// The largest clock error a stored report may hold: ten times the ±1%
/// (10000 ppm) that `calibrate` searches. Beyond it a report is damaged or
/// hand-made (-1e6 ppm would resample a recovery to nothing).
pub const MAX_CLOCK_ERROR_PPM: f64 = 1e5;
/// The longest exposure a stored report may hold, µs (a frame's exposure
/// is at most its period, and frame rates below 1 Hz are refused).
pub const MAX_EXPOSURE_US: f64 = 1e6;
/// The largest transfer-function strength `k` a stored report may hold
/// (the fit searches 0 to 3).
pub const MAX_TRANSFER_K: f64 = 10.0;
/// The most terms a stored static nonlinearity may hold (the fit uses at
/// most four; the simulator renders up to x⁹).
pub const MAX_POLYNOMIAL_TERMS: usize = 8;
/// The largest recovery range a stored static nonlinearity may hold.
pub const MAX_POLYNOMIAL_RANGE: f64 = 1e9;
/// The most strips a stored capture time may hold.
pub const MAX_STRIPS: usize = 64;
/// The largest row a stored capture time may name.
pub const MAX_ROW: u32 = 1 << 20;
/// The largest delay of a strip a stored capture time may hold, µs.
pub const MAX_CAPTURE_DELAY_US: f64 = 1e6;
/// The most lines a stored interference may hold (the fit finds at most
/// a handful).
pub const MAX_LINES: usize = 16;

/// A value in a stored report's `parameters`, as loosely as it may come.
#[derive(Deserialize)]
#[serde(untagged)]
enum Stored {
    Num(f64),
    List(Vec<Stored>),
    Map(BTreeMap<String, Stored>),
    Str(String),
    Other(serde::de::IgnoredAny),
}

#[derive(Deserialize)]
struct StoredEffect {
    name: Option<StoredName>,
    parameters: Option<BTreeMap<String, Stored>>,
}

/// A name: a string, or anything else (then missing).
#[derive(Deserialize)]
#[serde(untagged)]
enum StoredName {
    Str(String),
    Other(serde::de::IgnoredAny),
}

#[derive(Deserialize)]
struct StoredReport {
    effects: Option<Vec<StoredEffect>>,
}

/// The part of a report [`harmonics_left_from_report`] reads: the kind
/// and order of each finding left unexplained.
#[derive(Deserialize)]
struct StoredUnexplained {
    #[serde(default)]
    unexplained: Vec<StoredFinding>,
}

#[derive(Deserialize)]
struct StoredFinding {
    kind: String,
    #[serde(default)]
    order: Option<u32>,
    #[serde(default)]
    frequencies_hz: Vec<f64>,
}

/// The orders of the harmonics of the reference a stored report leaves in
/// its residual after every kept effect (`unexplained`, kind
/// `harmonics`); empty when none is left or the report has no such list.
/// A static response's inverse fitted on a constant-envelope sweep that
/// leaves harmonics there is a compromise over the sweep's amplitudes,
/// not the object's response: on a recording whose amplitudes spread
/// otherwise (speech) it parts from the response (issue 50's third held-out
/// set: a soft clip kept for an `x - 0.4 x⁵` object, +0.81 dB on the chirp
/// with its third and fifth harmonics left, took the speech 2.26 dB
/// lower). Errors name the field.
pub fn harmonics_left_from_report<'de, D: ?Sized>(report: &'de D) -> Result<Vec<u32>, ReportError>
where
    &'de D: Deserializer<'de>,
{
    let stored = StoredUnexplained::deserialize(report)
        .map_err(|e| ReportError::Parse(format!("unexplained: {e}")))?;
    let mut orders: Vec<u32> = stored
        .unexplained
        .iter()
        .filter(|f| f.kind == "harmonics")
        .map(|f| f.order.unwrap_or(0))
        .collect();
    orders.sort_unstable();
    orders.dedup();
    Ok(orders)
}

/// The frequencies (Hz) where a stored report's sweep measured a gain that
/// holds only at its level (`unexplained`, kind `level_dependent`: the
/// object driven into its nonlinear range there); empty when there are
/// none. Errors name the field.
pub fn level_dependent_from_report<'de, D: ?Sized>(report: &'de D) -> Result<Vec<f64>, ReportError>
where
    &'de D: Deserializer<'de>,
{
    let stored = StoredUnexplained::deserialize(report)
        .map_err(|e| ReportError::Parse(format!("unexplained: {e}")))?;
    Ok(stored
        .unexplained
        .into_iter()
        .filter(|f| f.kind == "level_dependent")
        .flat_map(|f| f.frequencies_hz)
        .collect())
}

/// The part of a report [`unsettled_from_report`] reads: each confound's
/// parameter, its range and the reference that would separate it.
#[derive(Deserialize)]
struct StoredConfounds {
    #[serde(default)]
    confounded: Vec<StoredConfound>,
}

#[derive(Deserialize)]
struct StoredConfound {
    parameter: String,
    range: [f64; 2],
    #[serde(default)]
    effects: Vec<String>,
    #[serde(default)]
    separate_with: String,
}

/// A kept, reusable effect that its calibration cannot tell from none:
/// the report's identifiability check (`confounded`) gives its main
/// parameter a range that holds the value it has when the effect is absent
/// (no clock error, no exposure, no equalising, no square term). On the
/// calibration's recording the two explanations coincide; on another
/// recording they part, and nothing measured says which holds.
/// `listen --calibration` says so when it applies one.
#[derive(Clone, Debug, PartialEq)]
pub struct Unsettled {
    /// The effect's name (`effects[].name`).
    pub effect: String,
    /// Why, in words: the range, what it trades against and what would
    /// separate them.
    pub why: String,
}

/// The kept reusable effects of a stored report that its own
/// identifiability check leaves unsettled ([`Unsettled`]); empty when the
/// report has no `confounded` list. Errors name the field.
pub fn unsettled_from_report<'de, D: ?Sized>(report: &'de D) -> Result<Vec<Unsettled>, ReportError>
where
    &'de D: Deserializer<'de>,
{
    let stored = StoredConfounds::deserialize(report)
        .map_err(|e| ReportError::Parse(format!("confounded: {e}")))?;
    let mut out: Vec<Unsettled> = Vec::new();
    for c in stored.confounded {
        let Some((effect, key)) = c.parameter.split_once('.') else {
            continue;
        };
        // The reusable effects whose absence is the value 0 of their main
        // parameter.
        let neutral_zero = matches!(
            (effect, key),
            ("time_base", "clock_error_ppm")
                | ("exposure", "exposure_us")
                | ("transfer_function", "k")
                | ("static_nonlinearity", "inverse_square_term")
        );
        let [lo, hi] = c.range;
        let holds_zero = lo <= 0.0 && hi >= 0.0;
        if !(neutral_zero && holds_zero) || out.iter().any(|u| u.effect == effect) {
            continue;
        }
        let others: Vec<&str> = c
            .effects
            .iter()
            .map(String::as_str)
            .filter(|e| *e != effect)
            .collect();
        let with = if others.is_empty() {
            String::new()
        } else {
            format!(", trading it against {}", others.join(" and "))
        };
        let separate = if c.separate_with.is_empty() {
            String::new()
        } else {
            format!(". To settle it, calibrate with {}", c.separate_with)
        };
        out.push(Unsettled {
            effect: effect.to_string(),
            why: format!(
                "{effect} applied, but its calibration cannot tell it from none ({} only known to lie in [{lo:.4}, {hi:.4}], which holds 0{with}): on the calibration's recording both explanations fit, on another they part, and nothing measured says which holds; if this recording comes out worse with the calibration than without, that is the likely cause{separate}",
                c.parameter
            ),
        });
    }
    Ok(out)
}

/// The part of a report [`explained_from_report`] reads.
#[derive(serde::Deserialize)]
struct StoredExplained {
    #[serde(default)]
    explained: Vec<super::explain::StoredTerm>,
}

/// Most rectangles a stored explained term may measure (the lines of a
/// region up to 128 rows or columns, in two parts each, fit).
pub const MAX_STORED_TILES: usize = 512;

/// What the residual explainer kept, as stored in a report (`explained`
/// of `REPORT.json`: each term's observable, tiles and taps); empty when
/// there is none. Errors name the field.
pub fn explained_from_report<'de, D: ?Sized>(
    report: &'de D,
) -> Result<Vec<super::explain::StoredTerm>, ReportError>
where
    &'de D: Deserializer<'de>,
{
    let stored = StoredExplained::deserialize(report)
        .map_err(|e| ReportError::Parse(format!("explained: {e}")))?;
    for (k, t) in stored.explained.iter().enumerate() {
        if t.tiles.is_empty()
            || t.tiles.len() > MAX_STORED_TILES
            || t.tiles.iter().any(|r| r[2] == 0 || r[3] == 0)
        {
            return Err(ReportError::Parse(format!(
                "explained[{k}].tiles: 1 to {MAX_STORED_TILES} rectangles [x, y, w, h] of at least 1x1 expected"
            )));
        }
        // A tile's FIR is -LAGS..=LAGS about a lag within the lines' reach.
        let (reach, most) = match t.observable.is_line() {
            true => (super::MAX_LINE_REACH, 2 * super::MAX_LINE_REACH + 1),
            false => (super::MAX_LINE_REACH + super::LAGS, 2 * super::LAGS + 1),
        };
        if t.shifts.is_empty()
            || t.shifts.len() > most
            || t.shifts.iter().any(|s| s.unsigned_abs() as usize > reach)
        {
            return Err(ReportError::Parse(format!(
                "explained[{k}].shifts: 1 to {most} lags of -{reach}..={reach} frames expected, got {:?}",
                t.shifts
            )));
        }
        // Lines have one FIR a line and reference of the calibration's
        // recording.
        let channels = super::explain::line_groups(t.observable, &t.tiles).len();
        let taps = channels * t.shifts.len();
        let fits = match t.observable.is_line() {
            true => t.taps.len() % taps == 0 && !t.taps.is_empty(),
            false => t.taps.len() == taps,
        };
        if !fits || t.taps.iter().any(|v| !v.is_finite()) {
            return Err(ReportError::Parse(format!(
                "explained[{k}].taps: {}{taps} finite numbers expected ({channels} channel(s) of {} taps)",
                if t.observable.is_line() { "a multiple of " } else { "" },
                t.shifts.len()
            )));
        }
    }
    Ok(stored.explained)
}

/// The part of a report [`frame_from_report`] reads.
#[derive(serde::Deserialize)]
struct StoredFrame {
    pixel_frame: Option<super::PixelFrame>,
}

/// The recovery's frame stored in a report (`pixel_frame` of
/// `REPORT.json`), if any; an error names the field when it is there but
/// damaged.
pub fn frame_from_report<'de, D: ?Sized>(
    report: &'de D,
) -> Result<Option<super::PixelFrame>, ReportError>
where
    &'de D: Deserializer<'de>,
{
    let stored = StoredFrame::deserialize(report)
        .map_err(|e| ReportError::Parse(format!("pixel_frame: {e}")))?;
    match stored.pixel_frame {
        Some(f)
            if f.direction_deg.is_finite()
                && f.recovery_per_px.is_finite()
                && f.recovery_per_px != 0.0 =>
        {
            Ok(Some(f))
        }
        Some(_) => Err(ReportError::Parse(
            "pixel_frame: direction_deg and recovery_per_px must be finite, recovery_per_px not 0"
                .into(),
        )),
        None => Ok(None),
    }
}

/// The reusable corrections stored in a report (`effects` of
/// `REPORT.json`), from a parsed document any serde deserializer reads by
/// reference (e.g. a `serde_json::Value`); per-recording effects (frames,
/// interference, soft clipping, gain drift) are skipped. Errors name the effect and the
/// field.
pub fn reusable_from_report<'de, D: ?Sized>(report: &'de D) -> Result<Vec<Correction>, ReportError>
where
    &'de D: Deserializer<'de>,
{
    let stored =
        StoredReport::deserialize(report).map_err(|e| ReportError::Parse(e.to_string()))?;
    let effects = stored.effects.ok_or(ReportError::NoEffects)?;
    let mut out = Vec::new();
    for (index, e) in effects.into_iter().enumerate() {
        let Some(StoredName::Str(name)) = e.name else {
            return Err(ReportError::NoName { index });
        };
        let p = e.parameters.ok_or_else(|| ReportError::NoParameters {
            index,
            name: name.clone(),
        })?;
        if let Some(c) = from_report(index, &name, &p)? {
            out.push(c);
        }
    }
    // Lines are subtracted first, from the recovery as delivered (as
    // calibrate fitted them).
    out.sort_by_key(|c| !matches!(c, Correction::Lines { .. }));
    Ok(out)
}

/// A reusable correction back from effect `index` of a report; `None` for
/// per-recording effects (frames, gain drift) and for soft clipping
/// stored without its high-pass (reports before session 54). A stored
/// interference comes back as its lines' frequencies
/// ([`Correction::Lines`]).
fn from_report(
    index: usize,
    name: &str,
    p: &BTreeMap<String, Stored>,
) -> Result<Option<Correction>, ReportError> {
    let field = |key: &'static str, expected: &'static str| ReportError::Field {
        index,
        name: name.to_string(),
        key,
        expected,
    };
    let num = |key: &'static str| match p.get(key) {
        Some(Stored::Num(v)) if v.is_finite() => Ok(*v),
        _ => Err(field(key, "a finite number")),
    };
    let list = |key: &'static str| -> Result<Vec<f64>, ReportError> {
        match p.get(key) {
            Some(Stored::List(a)) => a
                .iter()
                .map(|v| match v {
                    Stored::Num(x) if x.is_finite() => Some(*x),
                    _ => None,
                })
                .collect::<Option<Vec<f64>>>()
                .ok_or_else(|| field(key, "a list of numbers")),
            _ => Err(field(key, "a list of numbers")),
        }
    };
    // The high-pass a static response's inverse undoes: both keys
    // numbers, or both absent/null.
    let highpass = || match (p.get("highpass_order"), p.get("highpass_hz")) {
        (Some(Stored::Num(o)), Some(Stored::Num(hz))) => {
            if !(o.fract() == 0.0 && (1.0..=16.0).contains(o)) {
                return Err(field("highpass_order", "a whole number 1 to 16"));
            }
            if !(hz.is_finite() && *hz > 0.0) {
                return Err(field("highpass_hz", "a frequency > 0"));
            }
            Ok(Some((*o as usize, *hz)))
        }
        (None | Some(Stored::Other(_)), None | Some(Stored::Other(_))) => Ok(None),
        _ => Err(field("highpass_hz", "given with highpass_order")),
    };
    // A static response's range: the recovery's peak it was fitted over.
    let poly_range = || {
        let range = num("range")?;
        if !(range > 0.0 && range <= MAX_POLYNOMIAL_RANGE) {
            return Err(ReportError::OutOfRange {
                index,
                name: name.to_string(),
                key: "range",
                range: "> 0 and at most 1e9",
                value: range,
            });
        }
        Ok(range)
    };
    // Each term `a u^(k+2)` of a static response's inverse (`coefs[k]`) at
    // the range's edge within 1000x the signal there: a report that would
    // multiply the recovery beyond that is damaged.
    let poly_terms =
        |coefs: &[f64], range: f64| match coefs.iter().enumerate().position(|(k, a)| {
            (a.abs() * range.powi(k as i32 + 2)).partial_cmp(&(1e3 * range))
                != Some(std::cmp::Ordering::Less)
        }) {
            Some(k) => Err(ReportError::OutOfRange {
                index,
                name: name.to_string(),
                key: if name == "soft_clip" {
                    ["a3", "a5"][k / 2]
                } else {
                    "coefficients"
                },
                range: "such that each term at the range's edge is under 1000x the signal there",
                value: coefs[k],
            }),
            None => Ok(()),
        };
    let kind = [
        EffectKind::TimeBase,
        EffectKind::Exposure,
        EffectKind::Interference,
        EffectKind::Transfer,
        EffectKind::Polynomial,
        EffectKind::SoftClip,
        EffectKind::CaptureTime,
        EffectKind::RegionGain,
    ]
    .into_iter()
    .find(|k| k.name() == name);
    Ok(match kind {
        Some(EffectKind::TimeBase) => {
            let ppm = num("clock_error_ppm")?;
            if ppm.abs() > MAX_CLOCK_ERROR_PPM {
                return Err(ReportError::ClockError { index, value: ppm });
            }
            Some(Correction::TimeBase { ppm })
        }
        Some(EffectKind::Exposure) => {
            let e = num("exposure_us")?;
            if !(e > 0.0 && e <= MAX_EXPOSURE_US) {
                return Err(ReportError::Exposure { index, value: e });
            }
            Some(Correction::Exposure {
                exposure_s: e * 1e-6,
            })
        }
        // The lines' frequencies; their level and phase belong to one
        // recording and are fitted again on the next.
        Some(EffectKind::Interference) => {
            let expected = "a list of 1 to 16 lines, each with freq_hz, a frequency > 0";
            let freqs = match p.get("lines") {
                Some(Stored::List(a)) if !a.is_empty() && a.len() <= MAX_LINES => a
                    .iter()
                    .map(|l| match l {
                        Stored::Map(m) => match m.get("freq_hz") {
                            Some(Stored::Num(f)) if f.is_finite() && *f > 0.0 => Some(*f),
                            _ => None,
                        },
                        _ => None,
                    })
                    .collect::<Option<Vec<f64>>>(),
                _ => None,
            };
            Some(Correction::Lines {
                freqs_hz: freqs.ok_or_else(|| field("lines", expected))?,
            })
        }
        Some(EffectKind::Transfer) => {
            let (f, c) = (list("frequencies_hz")?, list("coefficients_db")?);
            if f.len() != c.len() || f.windows(2).any(|w| w[1] <= w[0]) {
                return Err(ReportError::TransferTable {
                    index,
                    name: name.to_string(),
                    freqs: f.len(),
                    coefs: c.len(),
                });
            }
            let phase = match p.get("phase_deg") {
                None => vec![0.0; f.len()],
                Some(_) => list("phase_deg")?,
            };
            if phase.len() != f.len() {
                return Err(ReportError::TransferPhase {
                    index,
                    name: name.to_string(),
                    phases: phase.len(),
                    freqs: f.len(),
                });
            }
            let out_of_range = |key, range, value| ReportError::OutOfRange {
                index,
                name: name.to_string(),
                key,
                range,
                value,
            };
            if let Some(&lo) = f.iter().find(|&&v| v < 0.0) {
                return Err(out_of_range("frequencies_hz", "0 Hz or more", lo));
            }
            let k = num("k")?;
            if !(0.0..=MAX_TRANSFER_K).contains(&k) {
                return Err(out_of_range("k", "within 0..=10", k));
            }
            // Written since session 68; a report before it measured
            // every row it holds.
            let measured_hz = match p.get("measured_hz") {
                None => [
                    f.first().copied().unwrap_or(0.0),
                    f.last().copied().unwrap_or(0.0),
                ],
                Some(_) => match list("measured_hz")?[..] {
                    [a, b] if a.is_finite() && b.is_finite() && 0.0 <= a && a <= b => [a, b],
                    _ => {
                        return Err(field(
                            "measured_hz",
                            "two frequencies [low, high] in Hz, 0 <= low <= high",
                        ))
                    }
                },
            };
            Some(Correction::Transfer {
                freqs_hz: f,
                coef_db: c,
                phase_deg: phase,
                k,
                measured_hz,
            })
        }
        // Carried since session 54 (brought to the next recording by the
        // pixel frame read on the tiles that move). A report written
        // before it stored the high-pass it undoes: not carried, as then.
        Some(EffectKind::SoftClip) => match highpass()? {
            None => None,
            Some(h) => {
                let (a3, a5) = (num("a3")?, num("a5")?);
                let level = num("level_in_reference_units")?;
                let range = poly_range()?;
                poly_terms(&[0.0, a3, 0.0, a5], range)?;
                Some(Correction::SoftClip {
                    a3,
                    a5,
                    level,
                    range,
                    highpass: Some(h),
                })
            }
        },
        Some(EffectKind::Polynomial) => {
            let coefs = list("coefficients")?;
            if coefs.is_empty() || coefs.len() > MAX_POLYNOMIAL_TERMS {
                return Err(ReportError::OutOfRange {
                    index,
                    name: name.to_string(),
                    key: "coefficients",
                    range: "1 to 8 numbers (x² to x⁹)",
                    value: coefs.len() as f64,
                });
            }
            let range = poly_range()?;
            poly_terms(&coefs, range)?;
            let highpass = highpass()?;
            let from_response = match p.get("fitted") {
                None => false,
                Some(Stored::Str(s)) if s == "response" => true,
                Some(_) => return Err(field("fitted", "\"response\" or absent")),
            };
            Some(Correction::Polynomial {
                coefs,
                range,
                highpass,
                from_response,
            })
        }
        Some(kind @ (EffectKind::CaptureTime | EffectKind::RegionGain)) => {
            let timed = kind == EffectKind::CaptureTime;
            let (first, end, weights) = (list("first_rows")?, list("end_rows")?, list("weights")?);
            let k = first.len();
            let delays = if timed {
                list("delays_us")?
            } else {
                vec![0.0; k]
            };
            if k == 0 || k > MAX_STRIPS || [end.len(), delays.len(), weights.len()] != [k; 3] {
                return Err(ReportError::OutOfRange {
                    index,
                    name: name.to_string(),
                    key: "first_rows",
                    range: if timed {
                        "1 to 64 strips, as many as end_rows, delays_us and weights"
                    } else {
                        "1 to 64 strips, as many as end_rows and weights"
                    },
                    value: k as f64,
                });
            }
            let row = |v: f64| v.fract() == 0.0 && (0.0..=f64::from(MAX_ROW)).contains(&v);
            if (0..k).any(|i| !(row(first[i]) && row(end[i]) && first[i] < end[i])) {
                return Err(field(
                    "first_rows",
                    "whole rows, each strip's first row before its end row (end_rows)",
                ));
            }
            if let Some(&d) = delays.iter().find(|d| d.abs() > MAX_CAPTURE_DELAY_US) {
                return Err(ReportError::OutOfRange {
                    index,
                    name: name.to_string(),
                    key: "delays_us",
                    range: "within ±1e6 µs (1 s)",
                    value: d,
                });
            }
            if weights.iter().all(|w| *w == 0.0) {
                return Err(field("weights", "a list of numbers, not all zero"));
            }
            let rows = first
                .iter()
                .zip(&end)
                .map(|(&a, &b)| (a as u32, b as u32))
                .collect();
            Some(if timed {
                Correction::CaptureTime {
                    rows,
                    delays_s: delays.iter().map(|d| d * 1e-6).collect(),
                    weights,
                    line_delay_s: match p.get("line_delay_us") {
                        Some(Stored::Num(v)) if v.is_finite() => v * 1e-6,
                        _ => 0.0,
                    },
                    per_region: false,
                }
            } else {
                Correction::RegionGain { rows, weights }
            })
        }
        // Per recording: frame events and the gain's trend belong to one
        // recording.
        _ if ["dropped_frames", "gain_drift"].contains(&name) => None,
        _ => {
            return Err(ReportError::UnknownEffect {
                index,
                name: name.to_string(),
            })
        }
    })
}
