//! What a scene is: its parameters ([`SceneSpec`]) and their checks with the limits they
//! apply, what happens at the object's outline ([`EdgeMode`]) and the object's look
//! ([`Look`]: a picture and a silhouette).

use crate::SimError;
use vibroscope_io::Depth;

/// Texture scale of the background (also how the surroundings interpolate
/// it when it moves).
pub const BACKGROUND_SIGMA_PX: f64 = 2.5;
/// Largest accepted `|amplitude_px|` (bounds the padded texture's size).
pub const MAX_AMPLITUDE_PX: f64 = 1000.0;
/// Most regions of [`SceneSpec::row_lag_s`].
pub const MAX_ROW_LAGS: usize = 64;
/// Largest accepted `|lag|` of [`SceneSpec::row_lag_s`], in seconds.
pub const MAX_ROW_LAG_S: f64 = 1.0;
/// Largest frame, in pixels.
const MAX_PIXELS: u64 = 1 << 28;

/// What happens at the object's outline (see the [module docs](super)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EdgeMode {
    /// The texture moves inside the fixed rest rectangle (default; keeps the
    /// Eq. 4.3 SNR law exact).
    #[default]
    Fixed,
    /// The whole patch translates; edge pixels are area-weighted blends.
    Moving,
}

/// Parameters of a [`Scene`](super::Scene).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSpec {
    /// Frame size in pixels.
    pub width: u32,
    pub height: u32,
    /// `[x, y, w, h]`: the moving textured object's rectangle at rest.
    pub object: [u32; 4],
    /// Peak displacement in pixels.
    pub amplitude_px: f64,
    /// Direction of motion: 0 = +x (rightwards), 90 = +y (downwards).
    pub direction_deg: f64,
    /// Gaussian sensor noise std in DN (at the output depth), before quantisation.
    pub noise_std: f64,
    /// Storage depth of the output.
    pub depth: Depth,
    /// Significant bits: 1..=8 for U8, 1..=16 for U16; values clamp to [0, 2^bits - 1].
    pub bits: u8,
    /// Std of the object's texture in DN (usually [`SceneSpec::default_contrast`]).
    pub contrast: f64,
    pub seed: u64,
    /// Regions of rows whose motion lags (a part that hears the sound
    /// later moves later): `(first_row, lag_s)` pairs, first rows strictly
    /// ascending and inside the frame, `|lag_s|` at most
    /// [`MAX_ROW_LAG_S`], at most [`MAX_ROW_LAGS`] pairs. Rows from
    /// `first_row` up to the next pair's (or the frame's end) show
    /// `amplitude_px · signal(t - lag_s)` at their capture time `t`; rows
    /// above the first pair have no lag. Empty: the object moves as one.
    /// Non-empty, frames are rendered row by row even with a global
    /// shutter (see [`Scene::row_displacement_px`](super::Scene::row_displacement_px)).
    pub row_lag_s: Vec<(u32, f64)>,
    /// The gain of each region of [`SceneSpec::row_lag_s`]: its rows show
    /// `gain · amplitude_px · signal(t - lag_s)`, `gain` in `[-1, 1]`
    /// (negative: the part moves in antiphase, as the two halves of a
    /// plate's second mode do). Empty: 1 for every region; else one per
    /// region.
    pub row_gain: Vec<f64>,
}

impl SceneSpec {
    /// `2^bits - 1` (0 for invalid `bits`).
    pub fn full_scale(&self) -> f64 {
        if (1..=16).contains(&self.bits) {
            ((1u32 << self.bits) - 1) as f64
        } else {
            0.0
        }
    }

    /// The default texture contrast: 15% of full scale.
    pub fn default_contrast(bits: u8) -> f64 {
        0.15 * ((1u32 << bits.clamp(1, 16)) - 1) as f64
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |field: &str, msg: String| {
            Err(SimError::Invalid {
                field: field.to_string(),
                msg,
            })
        };
        let (w, h) = (self.width as u64, self.height as u64);
        if w == 0 || h == 0 {
            return bad(
                "width",
                format!("frame size must be at least 1x1, got {w}x{h}"),
            );
        }
        if w * h > MAX_PIXELS {
            return bad(
                "width",
                format!("frame {w}x{h} has more than {MAX_PIXELS} pixels"),
            );
        }
        let [x, y, ow, oh] = self.object.map(u64::from);
        if ow == 0 || oh == 0 {
            return bad(
                "object",
                format!(
                    "size must be at least 1x1, got {ow}x{oh} in {:?}",
                    self.object
                ),
            );
        }
        if x + ow > w || y + oh > h {
            return bad(
                "object",
                format!(
                    "rectangle {:?} (x, y, w, h) extends past the {w}x{h} frame (x + w = {}, y + h = {})",
                    self.object,
                    x + ow,
                    y + oh
                ),
            );
        }
        if !(self.amplitude_px.is_finite() && self.amplitude_px.abs() <= MAX_AMPLITUDE_PX) {
            return bad(
                "amplitude_px",
                format!(
                    "must be finite and at most {MAX_AMPLITUDE_PX} px in magnitude, got {}",
                    self.amplitude_px
                ),
            );
        }
        if !self.direction_deg.is_finite() {
            return bad(
                "direction_deg",
                format!("must be finite, got {}", self.direction_deg),
            );
        }
        if !(self.noise_std.is_finite() && self.noise_std >= 0.0) {
            return bad(
                "noise_std",
                format!("must be a finite std >= 0 DN, got {}", self.noise_std),
            );
        }
        let max_bits = self.depth.max_bits();
        if !(1..=max_bits).contains(&self.bits) {
            return bad(
                "bits",
                format!(
                    "must be 1..={max_bits} for {:?} output, got {}",
                    self.depth, self.bits
                ),
            );
        }
        if !(self.contrast.is_finite() && self.contrast >= 0.0) {
            return bad(
                "contrast",
                format!("must be a finite std >= 0 DN, got {}", self.contrast),
            );
        }
        if self.row_lag_s.len() > MAX_ROW_LAGS {
            return bad(
                "row_lag_s",
                format!(
                    "at most {MAX_ROW_LAGS} regions, got {}",
                    self.row_lag_s.len()
                ),
            );
        }
        let mut prev: Option<u32> = None;
        for (k, &(row, lag)) in self.row_lag_s.iter().enumerate() {
            let field = format!("row_lag_s[{k}]");
            if row as u64 >= h {
                return bad(
                    &field,
                    format!("first row {row} must be below the frame height {h}"),
                );
            }
            if let Some(p) = prev.filter(|&p| row <= p) {
                return bad(
                    &field,
                    format!("first rows must ascend strictly, got {row} after {p}"),
                );
            }
            if !(lag.is_finite() && lag.abs() <= MAX_ROW_LAG_S) {
                return bad(
                    &field,
                    format!(
                        "lag must be finite and at most {MAX_ROW_LAG_S} s in magnitude, got {lag}"
                    ),
                );
            }
            prev = Some(row);
        }
        if !self.row_gain.is_empty() && self.row_gain.len() != self.row_lag_s.len() {
            return bad(
                "row_gain",
                format!(
                    "needs one gain per region of row_lag_s: {} gains for {} regions",
                    self.row_gain.len(),
                    self.row_lag_s.len()
                ),
            );
        }
        for (k, &g) in self.row_gain.iter().enumerate() {
            if !(g.is_finite() && g.abs() <= 1.0) {
                return bad(
                    &format!("row_gain[{k}]"),
                    format!("must be finite and within [-1, 1], got {g}"),
                );
            }
        }
        Ok(())
    }
}

impl Default for SceneSpec {
    /// 256x256, central-half object, 0.05 px along +x, noise 2 DN, 8 bits.
    fn default() -> Self {
        Self {
            width: 256,
            height: 256,
            object: [64, 64, 128, 128],
            amplitude_px: 0.05,
            direction_deg: 0.0,
            noise_std: 2.0,
            depth: Depth::U8,
            bits: 8,
            contrast: Self::default_contrast(8),
            seed: 1,
            row_lag_s: Vec::new(),
            row_gain: Vec::new(),
        }
    }
}

/// What the object looks like, beyond the procedural default.
#[derive(Clone, Debug, Default)]
pub struct Look {
    /// A picture for the object's texture: `(pixels, width, height)`, gray,
    /// row-major. It is low-passed by the object texture's Gaussian
    /// (σ = [`OBJECT_SIGMA_PX`](super::OBJECT_SIGMA_PX)) so sub-pixel shifts stay exact, mirrored
    /// beyond its edges, and scaled to the spec's `contrast`. Size it to the
    /// object's rectangle to see it whole.
    pub texture: Option<(Vec<f64>, usize, usize)>,
    /// The object's silhouette: per frame pixel (`width × height`,
    /// row-major), the fraction in [0, 1] that belongs to the object. Within
    /// the object's rectangle, a pixel shows `m·object + (1 - m)·background`;
    /// the silhouette stays put (like the rectangle's outline in
    /// [`EdgeMode::Fixed`]) while the texture moves behind it.
    pub mask: Option<Vec<f32>>,
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::super::tests::{spec16, tone};
    use super::super::Scene;
    use super::{Depth, Look, SceneSpec};

    #[test]
    fn bad_row_lags_are_refused_naming_the_field() {
        let ok = SceneSpec::default(); // 256 rows
        type Lags = Vec<(u32, f64)>;
        let cases: Vec<(Lags, &str, &str)> = vec![
            (
                vec![(10, 0.0), (256, 1e-3)],
                "row_lag_s[1]",
                "below the frame height",
            ),
            (
                vec![(10, 0.0), (30, 1e-3), (20, 0.0)],
                "row_lag_s[2]",
                "ascend",
            ),
            (vec![(10, 0.0), (10, 1e-3)], "row_lag_s[1]", "ascend"),
            (vec![(0, f64::NAN)], "row_lag_s[0]", "finite"),
            (vec![(0, 0.0), (5, f64::INFINITY)], "row_lag_s[1]", "finite"),
            (vec![(3, -1.5)], "row_lag_s[0]", "at most 1 s"),
            (
                (0..65).map(|r| (r, 0.0)).collect(),
                "row_lag_s",
                "at most 64",
            ),
        ];
        for (lags, field, what) in cases {
            let spec = SceneSpec {
                row_lag_s: lags.clone(),
                ..ok.clone()
            };
            let e = match Scene::new(spec, tone(1.0)) {
                Ok(_) => panic!("{lags:?} accepted"),
                Err(e) => e,
            };
            assert_eq!(e.field(), field, "{e}");
            assert!(
                e.to_string().contains(field) && e.to_string().contains(what),
                "{e}"
            );
        }
        // The limits themselves are fine.
        let spec = SceneSpec {
            row_lag_s: (0..64)
                .map(|r| (r * 4, if r % 2 == 0 { 1.0 } else { -1.0 }))
                .collect(),
            ..ok.clone()
        };
        assert!(Scene::new(spec, tone(1.0)).is_ok());
        // A modal beam or a fabric moves on its own: no row lags.
        let modal = crate::ModalSpec {
            duration_s: 0.0,
            modes: vec![crate::modal::ModeSpec {
                freq_hz: 50.0,
                amplitude_px: 0.2,
                shape: 1,
                across: 0,
                damping: 0.02,
                drive: crate::modal::Drive::Tone,
                phase_rad: 0.0,
            }],
        };
        let spec = SceneSpec {
            row_lag_s: vec![(100, 1e-3)],
            ..ok
        };
        let e = Scene::with_modal(spec, tone(1.0), &modal, Look::default())
            .err()
            .unwrap();
        assert_eq!(e.field(), "row_lag_s", "{e}");
    }

    #[test]
    fn invalid_specs_are_errors_naming_the_field() {
        let ok = SceneSpec::default();
        let cases: Vec<(SceneSpec, &str)> = vec![
            (
                SceneSpec {
                    object: [200, 0, 100, 10],
                    ..ok.clone()
                },
                "object",
            ),
            (
                SceneSpec {
                    object: [0, 250, 10, 10],
                    ..ok.clone()
                },
                "object",
            ),
            (
                SceneSpec {
                    object: [0, 0, 0, 10],
                    ..ok.clone()
                },
                "object",
            ),
            (
                SceneSpec {
                    width: 0,
                    ..ok.clone()
                },
                "width",
            ),
            (
                SceneSpec {
                    bits: 0,
                    ..ok.clone()
                },
                "bits",
            ),
            (
                SceneSpec {
                    bits: 9,
                    ..ok.clone()
                },
                "bits",
            ),
            (
                SceneSpec {
                    bits: 17,
                    depth: Depth::U16,
                    ..ok.clone()
                },
                "bits",
            ),
            (
                SceneSpec {
                    noise_std: -1.0,
                    ..ok.clone()
                },
                "noise_std",
            ),
            (
                SceneSpec {
                    noise_std: f64::NAN,
                    ..ok.clone()
                },
                "noise_std",
            ),
            (
                SceneSpec {
                    amplitude_px: f64::INFINITY,
                    ..ok.clone()
                },
                "amplitude_px",
            ),
            (
                SceneSpec {
                    amplitude_px: 1e9,
                    ..ok.clone()
                },
                "amplitude_px",
            ),
            (
                SceneSpec {
                    direction_deg: f64::NAN,
                    ..ok.clone()
                },
                "direction_deg",
            ),
            (
                SceneSpec {
                    contrast: -3.0,
                    ..ok.clone()
                },
                "contrast",
            ),
        ];
        for (spec, field) in cases {
            let e = match Scene::new(spec.clone(), tone(1.0)) {
                Ok(_) => panic!("{spec:?} accepted"),
                Err(e) => e,
            };
            assert_eq!(e.field(), field, "{e}");
            assert!(e.to_string().contains(field), "{e}");
        }
        // U8 with fewer bits, U16 with 16 and tiny objects are fine.
        assert!(Scene::new(
            SceneSpec {
                bits: 6,
                ..ok.clone()
            },
            tone(1.0)
        )
        .is_ok());
        assert!(Scene::new(spec16(8, 8, [7, 7, 1, 1], 0.5, 0.0), tone(1.0)).is_ok());
    }
}
