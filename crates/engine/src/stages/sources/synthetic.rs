//! `synthetic`: the built-in scene — a textured object moving sub-pixel with
//! a known signal over a still background, with sensor noise and 8/16-bit
//! quantisation — rendered by the forward model in [`vibroscope_sim`], which the
//! tests use as ground truth. Deterministic from `seed`. With
//! `realtime = true` it behaves like a live camera: paced by the wall clock,
//! and its edges drop the oldest frame when downstream lags.

use super::{check_fps, nominal_frame, Pacer};
use crate::spec::default_of;
use crate::*;
use serde::{Deserialize, Serialize};
use vibroscope_sim::{self as sim, Scene, SceneSpec, Signal, SignalSpec};

params! {
    /// Parameters of the synthetic scene (also used by `vibroscope demo`,
    /// `simulate` and tests). Declared here: their defaults (also
    /// [`SyntheticParams::default`], used when a scene file omits a field),
    /// ranges, units and docs ([`KindParams::PARAMS`]).
    #[derive(PartialEq)]
    #[serde(default)]
    pub struct SyntheticParams for "synthetic" {
        width: u32 = super::side_param("width", 256, "frame width"),
        height: u32 = super::side_param("height", 256, "frame height"),
        fps: f64 = super::fps_param(Def::Float(2200.0), "frame rate"),
        duration_s: f64 = ParamSpec::of(ParamType::Float, Def::Float(1.0))
            .at_least(0.0)
            .unit("s")
            .doc("length (`frames` wins when both are given)"),
        frames: Option<u64> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(0, i64::MAX)
            .doc("frames captured; default duration_s * fps"),
        object: Option<[u32; 4]> = ParamSpec::of(ParamType::Ints, Def::Optional)
            .ints(0, u32::MAX as i64)
            .unit("px")
            .doc("moving object [x, y, w, h]; default: the central half of the frame"),
        amplitude_px: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.05))
            .floats(-sim::MAX_AMPLITUDE_PX, sim::MAX_AMPLITUDE_PX)
            .unit("px")
            .doc("peak displacement of the object for a signal of 1"),
        direction_deg: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.0))
            .unit("deg")
            .doc("direction of the motion (0 = +x, 90 = +y)"),
        noise_std: f64 = ParamSpec::of(ParamType::Float, Def::Float(2.0))
            .at_least(0.0)
            .unit("DN")
            .doc("sensor noise, standard deviation"),
        bits: u8 = super::BITS,
        contrast: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .unit("DN")
            .doc("texture contrast (std); default 15% of full scale"),
        seed: u64 = ParamSpec::of(ParamType::Int, Def::Int(1))
            .ints(0, i64::MAX)
            .doc("random seed: the scene is deterministic from it"),
        signal: SignalSpec = ParamSpec::of(
            ParamType::Table,
            Def::Toml("{ type = \"tone\", freq_hz = 440.0 }"),
        )
        .doc("the motion's waveform: { type = \"tone\" | \"tones\" | ..., ... } (see vibroscope_sim)"),
        realtime: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("pace frames by the wall clock like a live camera"),
        line_delay_us: Option<f64> = crate::stages::transform::rows::LINE_DELAY_US
            .doc("rolling shutter (Eq. 4.4): row y of frame n at n/fps + y*d; absent = global shutter"),
        frame_delay_us: Option<f64> = crate::stages::transform::rows::FRAME_DELAY_US
            .doc("stated frame delay, checked against 1/fps - height * line_delay"),
        exposure_us: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .floats(0.0, 1e7)
            .unit("µs")
            .doc("each row averages the motion over this exposure (a boxcar)"),
        resonances: Vec<sim::Resonance> = ParamSpec::of(ParamType::Tables, Def::Toml("[]"))
            .doc("sound-to-motion transfer: peaking resonances [{ freq_hz, q, gain_db }]; none = flat"),
        interference: Vec<Interference> = ParamSpec::of(ParamType::Tables, Def::Toml("[]"))
            .doc("narrowband motion added to the object's: [{ freq_hz, amplitude_px }]"),
        clock_error_ppm: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.0))
            .floats(-1e5, 1e5)
            .unit("ppm")
            .doc("true frame rate is fps * (1 + e*1e-6) while frames are stamped at fps"),
        drop_frames: Vec<u64> = ParamSpec::of(ParamType::Ints, Def::Toml("[]"))
            .ints(0, i64::MAX)
            .doc("captured frames the camera loses (0-based capture indices)"),
        duplicate_frames: Vec<u64> = ParamSpec::of(ParamType::Ints, Def::Toml("[]"))
            .ints(0, i64::MAX)
            .doc("captured frames the camera delivers twice"),
        texture: Option<std::path::PathBuf> = ParamSpec::of(ParamType::Path, Def::Optional)
            .doc("a picture (PGM/PNG) for the object's texture, resized to the object"),
        object_mask: Option<std::path::PathBuf> = ParamSpec::of(ParamType::Path, Def::Optional)
            .doc("the object's silhouette (PGM/PNG, frame size; gray = fraction of object)"),
        ruler_period_px: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .floats(2.0, 1e4)
            .unit("px")
            .doc("the object's texture is a ruler: ticks this far apart across its top half (at object x = P (k + 0.5) + 0.37), random texture below"),
        modal: Option<sim::ModalSpec> = ParamSpec::of(ParamType::Table, Def::Optional).doc(
            "the object as a vibrating cantilever: { modes = [{ freq_hz, amplitude_px, shape, ... }] }",
        ),
        fabric: Option<sim::FabricSpec> = ParamSpec::of(ParamType::Table, Def::Optional).doc(
            "the object as a hanging fabric: { stiffness_nm, area_weight_kg_m2, excitation = \"ambient\" | \"sound\" | \"kick\", ... } (docs/learning.md)",
        ),
        soft_clip_px: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .unit("px")
            .doc("excursion saturates softly: L tanh(d / L) with L = soft_clip_px"),
        response_poly: Vec<f64> = ParamSpec::of(ParamType::Floats, Def::Toml("[]"))
            .floats(-10.0, 10.0)
            .doc("static nonlinear response [c2, c3, ...]: x + c2 x² + c3 x³ + ... with x in units of amplitude_px (before soft_clip_px; even terms make even harmonics)"),
        gain_decay_s: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .floats(1e-3, 1e6)
            .unit("s")
            .doc("the motion decays as exp(-t / gain_decay_s) over the recording (a struck object ringing down); interference does not"),
        row_lag_rows: Vec<u64> = ParamSpec::of(ParamType::Ints, Def::Toml("[]"))
            .ints(0, 16383)
            .unit("row")
            .doc("first rows of regions whose motion lags (two objects stacked vertically, a non-rigid one), strictly ascending; each region ends at the next (or the frame's end), rows above the first have no lag"),
        row_lag_us: Vec<f64> = ParamSpec::of(ParamType::Floats, Def::Toml("[]"))
            .floats(-MAX_ROW_LAG_US, MAX_ROW_LAG_US)
            .unit("µs")
            .doc("the lag of each region of row_lag_rows: its rows show amplitude_px * signal(t - lag) at their capture time t (with a rolling shutter too); frames are then rendered row by row"),
        row_gain: Vec<f64> = ParamSpec::of(ParamType::Floats, Def::Toml("[]"))
            .floats(-1.0, 1.0)
            .doc("the gain of each region of row_lag_rows (with row_lag_us): its rows move gain times as far, negative in antiphase (a non-rigid object's mode); empty: 1"),
        camera_motion: Option<sim::MotionSpec> = ParamSpec::of(ParamType::Table, Def::Optional)
            .doc("the whole image moves (the camera or its mount): { signal = {...}, amplitude_px, direction_deg }; the object moves with it"),
        background_motion: Vec<sim::MoverSpec> = ParamSpec::of(ParamType::Tables, Def::Toml("[]"))
            .doc("other things in view that vibrate: [{ rect = [x, y, w, h], signal = {...}, amplitude_px, direction_deg }], the background inside rect (default the whole frame) moving behind the object"),
        light: Option<sim::LightSpec> = ParamSpec::of(ParamType::Table, Def::Optional)
            .doc("a light that changes across the image: { signal = {...}, depth, direction_deg, uniform }; pixels times 1 + depth * signal(t) * (r + uniform), r from -1 to 1 along direction_deg"),
        row_noise_dn: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.0))
            .at_least(0.0)
            .unit("DN")
            .doc("the sensor's rows: each row takes an offset per frame, this standard deviation"),
        column_noise_dn: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.0))
            .at_least(0.0)
            .unit("DN")
            .doc("the sensor's columns: each column takes an offset per frame, this standard deviation"),
    }
}

/// A narrowband motion added to the object's.
#[derive(Deserialize, Serialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Interference {
    pub freq_hz: f64,
    pub amplitude_px: f64,
}

/// Largest `|row_lag_us|` (1 s, the simulator's [`sim::scene::MAX_ROW_LAG_S`]).
const MAX_ROW_LAG_US: f64 = sim::scene::MAX_ROW_LAG_S * 1e6;

impl Default for SyntheticParams {
    /// The declared defaults ([`KindParams::PARAMS`]).
    fn default() -> Self {
        let d = |name| default_of::<toml::Value>(Self::PARAMS, name);
        let num = |name| d(name).and_then(|v| v.as_float().or(v.as_integer().map(|i| i as f64)));
        let int = |name| d(name).and_then(|v| v.as_integer()).unwrap_or(0);
        Self {
            width: int("width") as u32,
            height: int("height") as u32,
            fps: num("fps").unwrap_or(0.0),
            duration_s: num("duration_s").unwrap_or(0.0),
            frames: None,
            object: None,
            amplitude_px: num("amplitude_px").unwrap_or(0.0),
            direction_deg: num("direction_deg").unwrap_or(0.0),
            noise_std: num("noise_std").unwrap_or(0.0),
            bits: int("bits") as u8,
            contrast: None,
            seed: int("seed") as u64,
            signal: Self::signal.default_value().unwrap_or(SignalSpec::Tone {
                freq_hz: 0.0,
                phase_rad: 0.0,
            }),
            realtime: false,
            line_delay_us: None,
            frame_delay_us: None,
            exposure_us: None,
            resonances: Vec::new(),
            interference: Vec::new(),
            clock_error_ppm: num("clock_error_ppm").unwrap_or(0.0),
            drop_frames: Vec::new(),
            duplicate_frames: Vec::new(),
            texture: None,
            object_mask: None,
            ruler_period_px: None,
            modal: None,
            fabric: None,
            soft_clip_px: None,
            response_poly: Vec::new(),
            gain_decay_s: None,
            row_lag_rows: Vec::new(),
            row_lag_us: Vec::new(),
            row_gain: Vec::new(),
            camera_motion: None,
            background_motion: Vec::new(),
            light: None,
            row_noise_dn: 0.0,
            column_noise_dn: 0.0,
        }
    }
}

impl SyntheticParams {
    /// Frames the camera captures (before drops and duplicates).
    pub fn frame_count(&self) -> u64 {
        self.frames
            .unwrap_or((self.duration_s * self.fps).round().max(0.0) as u64)
    }

    /// The camera's true frame rate (see `clock_error_ppm`).
    pub fn true_fps(&self) -> f64 {
        self.fps * (1.0 + self.clock_error_ppm * 1e-6)
    }

    /// Frames delivered: captured, minus drops, plus duplicates.
    pub fn delivered_count(&self) -> u64 {
        let n = self.frame_count();
        let count = |v: &[u64]| {
            let mut v: Vec<u64> = v.iter().copied().filter(|&i| i < n).collect();
            v.sort_unstable();
            v.dedup();
            v.len() as u64
        };
        n - count(&self.drop_frames) + count(&self.duplicate_frames)
    }

    pub fn depth(&self) -> vibroscope_io::Depth {
        if self.bits > 8 {
            vibroscope_io::Depth::U16
        } else {
            vibroscope_io::Depth::U8
        }
    }

    /// The object's rectangle `[x, y, w, h]`: `object`, or by default the
    /// middle half of the frame.
    pub fn object_rect(&self) -> [u32; 4] {
        let (w, h) = (self.width, self.height);
        self.object
            .unwrap_or([w / 4, h / 4, (w / 2).max(1), (h / 2).max(1)])
    }

    /// The `modal` key with the recording's length filled in (a noise-driven
    /// mode needs more lines the longer it is watched; see
    /// `sim::modal::noise_lines`).
    fn modal_spec(&self) -> Option<sim::ModalSpec> {
        self.modal.clone().map(|mut m| {
            if self.fps > 0.0 {
                m.duration_s = self.frame_count() as f64 / self.fps;
            }
            m
        })
    }

    /// The forward model for these parameters.
    pub fn scene(&self) -> Result<Scene, String> {
        let (spec, signal, look) = self.parts(true)?;
        match (&self.modal_spec(), &self.fabric) {
            (Some(m), _) => Scene::with_modal(spec, signal, m, look),
            (None, Some(f)) => Scene::with_fabric(spec, signal, f, look),
            (None, None) => Scene::with_look(spec, signal, look),
        }
        .and_then(|s| s.with_surroundings(&self.surroundings()))
        .map_err(|e| e.to_string())
    }

    /// What changes in the image besides the object.
    pub fn surroundings(&self) -> sim::SurroundSpec {
        sim::SurroundSpec {
            camera: self.camera_motion.clone(),
            movers: self.background_motion.clone(),
            light: self.light.clone(),
            row_noise_dn: self.row_noise_dn,
            column_noise_dn: self.column_noise_dn,
        }
    }

    /// Every check [`SyntheticParams::scene`] makes, without its work in
    /// proportion to the frame, the excursion and the length (textures,
    /// a ruler picture, a resonance's filtered signal): validating a graph
    /// costs the same for a 64x64 second and a 4096x4096 hour. The
    /// excursion with resonances is checked at their steady-state gain
    /// here; the filtered signal's exact peak, when a transient exceeds
    /// that, is checked by `scene`.
    fn check_model(&self) -> Result<(), String> {
        let (spec, signal, look) = self.parts(false)?;
        Scene::check(
            &spec,
            &signal,
            self.modal_spec().as_ref(),
            self.fabric.as_ref(),
            &look,
        )
        .and_then(|_| self.surroundings().check((self.width, self.height)))
        .map_err(|e| e.to_string())
    }

    /// The model's spec, signal and look; with `sampled` false the
    /// resonances are checked (and bound the peak) but not applied, and a
    /// ruler is not drawn.
    fn parts(&self, sampled: bool) -> Result<(SceneSpec, Signal, sim::Look), String> {
        if self.modal.is_some() && self.fabric.is_some() {
            return Err(sim::SimError::Invalid {
                field: "fabric".into(),
                msg: "a scene has either `modal` or `fabric`, not both".into(),
            }
            .to_string());
        }
        // Also here: `scene` may run without `check`, and the pairs must match.
        self.check_row_lag()
            .map_err(|(f, m)| format!("invalid {f}: {m}"))?;
        // A region that moves early (a negative lag) reads the signal later.
        let early_us = self.row_lag_us.iter().fold(0.0f64, |m, &l| m.max(-l));
        let span = self.frame_count().saturating_add(2) as f64 / self.true_fps()
            + (self.exposure_us.unwrap_or(0.0) + early_us) * 1e-6
            + 0.01;
        let rate = (16.0 * self.fps).max(96_000.0);
        let unit = if self.amplitude_px != 0.0 {
            1.0 / self.amplitude_px
        } else {
            0.0
        };
        let tones: Vec<(f64, f64)> = self
            .interference
            .iter()
            .map(|i| (i.freq_hz, i.amplitude_px * unit))
            .collect();
        let signal = Signal::new(&self.signal)
            .and_then(|s| {
                if sampled {
                    s.through(&self.resonances, rate, span)
                } else {
                    s.through_checked(&self.resonances, rate, span)
                }
            })
            .and_then(|s| s.with_polynomial(&self.response_poly))
            .and_then(|s| match self.soft_clip_px {
                Some(l) => s.soft_clipped(l * unit),
                None => Ok(s),
            })
            .and_then(|s| match self.gain_decay_s {
                Some(d) => s.decaying(d),
                None => Ok(s),
            })
            .and_then(|s| s.plus_tones(&tones))
            .map_err(|e| e.to_string())?;
        let (w, h) = (self.width, self.height);
        let object = self.object_rect();
        let full = ((1u32 << self.bits.clamp(1, 16)) - 1) as f64;
        let spec = SceneSpec {
            width: w,
            height: h,
            object,
            amplitude_px: self.amplitude_px,
            direction_deg: self.direction_deg,
            noise_std: self.noise_std,
            depth: self.depth(),
            bits: self.bits,
            contrast: self.contrast.unwrap_or(0.15 * full),
            seed: self.seed,
            row_lag_s: self.row_lags(),
            row_gain: self.row_gain.clone(),
        };
        // Frame, object and amplitudes first: a picture is resized to the
        // object, so an object past the frame must fail before that.
        spec.validate().map_err(|e| e.to_string())?;
        let look = sim::Look {
            texture: match (&self.texture, self.ruler_period_px) {
                (Some(p), _) => Some(texture_picture(p, object[2], object[3])?),
                (None, Some(period)) if sampled => {
                    let (w, h) = (object[2] as usize, object[3] as usize);
                    Some((sim::texture::ruler_picture(w, h, period, self.seed), w, h))
                }
                (None, _) => None,
            },
            mask: match &self.object_mask {
                Some(p) => Some(silhouette(p, w, h)?),
                None => None,
            },
        };
        Ok((spec, signal, look))
    }

    /// Checks every field; the message names the field.
    ///
    /// (`texture` and `object_mask` are read by the model's checks, which
    /// `check` runs last; they do not build the model.)
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        check_fps(self.fps).map_err(|m| ("fps", m))?;
        if !(self.duration_s.is_finite() && self.duration_s >= 0.0) {
            return Err((
                "duration_s",
                format!("must be >= 0 seconds, got {}", self.duration_s),
            ));
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err((
                "width",
                format!(
                    "frame size must be 1..=16384 each, got {}x{}",
                    self.width, self.height
                ),
            ));
        }
        if !(1..=16).contains(&self.bits) {
            return Err(("bits", format!("must be 1..=16, got {}", self.bits)));
        }
        if !(self.noise_std.is_finite() && self.noise_std >= 0.0) {
            return Err(("noise_std", format!("must be >= 0, got {}", self.noise_std)));
        }
        if !self.amplitude_px.is_finite() {
            return Err(("amplitude_px", "must be a finite number".into()));
        }
        self.check_rolling()?;
        self.check_row_lag()?;
        let e = self.clock_error_ppm;
        if !(e.is_finite() && e.abs() <= 1e5) {
            return Err((
                "clock_error_ppm",
                format!("must be within ±100000 ppm, got {e}"),
            ));
        }
        for (k, i) in self.interference.iter().enumerate() {
            if !(i.freq_hz.is_finite() && i.freq_hz > 0.0) {
                return Err((
                    "interference",
                    format!(
                        "[{k}].freq_hz must be a finite frequency > 0 Hz, got {}",
                        i.freq_hz
                    ),
                ));
            }
            let max = sim::MAX_AMPLITUDE_PX;
            if !(i.amplitude_px.is_finite() && i.amplitude_px.abs() <= max) {
                return Err((
                    "interference",
                    format!(
                        "[{k}].amplitude_px must be finite and at most {max} px in magnitude, got {}",
                        i.amplitude_px
                    ),
                ));
            }
        }
        if !self.interference.is_empty() && self.amplitude_px == 0.0 {
            return Err((
                "interference",
                "needs amplitude_px != 0 (it is scaled with the signal)".into(),
            ));
        }
        if self.drop_frames.len() + self.duplicate_frames.len() > 1 << 20 {
            return Err((
                "drop_frames",
                "at most 1048576 dropped and duplicated frames".into(),
            ));
        }
        if self.modal.is_some() && self.row_timing().is_some() {
            return Err((
                "modal",
                "needs a global shutter (no line_delay_us or exposure_us)".into(),
            ));
        }
        if self.fabric.is_some() && self.row_timing().is_some() {
            return Err((
                "fabric",
                "needs a global shutter (no line_delay_us or exposure_us)".into(),
            ));
        }
        if self.camera_motion.is_some() && (self.modal.is_some() || self.fabric.is_some()) {
            return Err((
                "camera_motion",
                "needs a rigid object (no modal or fabric)".into(),
            ));
        }
        if !self.row_lag_rows.is_empty() && (self.modal.is_some() || self.fabric.is_some()) {
            return Err((
                "row_lag_rows",
                "needs a rigid object (no modal or fabric)".into(),
            ));
        }
        self.check_model().map_err(|m| {
            // The model names its field: `invalid FIELD: ...`.
            let named = m
                .strip_prefix("invalid ")
                .and_then(|r| r.split([':', '[', '.', ' ']).next())
                .and_then(|f| SyntheticParams::PARAMS.iter().find(|p| p.name == f))
                .map(|p| p.name);
            let field = if let Some(f) = named {
                f
            } else if m.starts_with("texture") {
                "texture"
            } else if m.starts_with("object_mask") {
                "object_mask"
            } else if m.contains("fabric") {
                "fabric"
            } else if m.contains("modal") {
                "modal"
            } else if m.contains("soft_clip_px") {
                "soft_clip_px"
            } else if m.contains("response_poly") {
                "response_poly"
            } else if m.contains("gain_decay_s") {
                "gain_decay_s"
            } else if m.contains("row_gain") {
                "row_gain"
            } else if m.contains("row_lag") {
                "row_lag_us"
            } else if m.contains("resonances") {
                "resonances"
            } else if m.contains("interference") {
                "interference"
            } else {
                "signal"
            };
            (field, m)
        })
    }

    /// Rolling-shutter fields: positive line delay, rows that fit in the
    /// frame period, a stated frame delay that agrees with both.
    fn check_rolling(&self) -> Result<(), (&'static str, String)> {
        use crate::stages::transform::rows::{check_line_delay_us, check_time_us, frame_delay_us};
        if let Some(e) = self.exposure_us {
            check_time_us(e).map_err(|m| ("exposure_us", m))?;
        }
        match (self.line_delay_us, self.frame_delay_us) {
            (Some(d), g) => {
                check_line_delay_us(d).map_err(|m| ("line_delay_us", m))?;
                if let Some(g) = g {
                    check_time_us(g).map_err(|m| ("frame_delay_us", m))?;
                }
                frame_delay_us(self.height as usize, d, self.fps, g).map(|_| ())
            }
            (None, Some(_)) => Err((
                "frame_delay_us",
                "needs line_delay_us (a frame delay only exists with a rolling shutter)".into(),
            )),
            (None, None) => Ok(()),
        }
    }

    /// Row lags: as many lags as first rows, at most
    /// [`sim::scene::MAX_ROW_LAGS`] regions, first rows strictly ascending
    /// and inside the frame, lags finite and within ±1 s. Errors name the
    /// entry, `row_lag_us[2]`.
    fn check_row_lag(&self) -> Result<(), (&'static str, String)> {
        let (rows, lags) = (&self.row_lag_rows, &self.row_lag_us);
        if rows.len() != lags.len() {
            return Err((
                "row_lag_us",
                format!(
                    "needs one lag per first row in row_lag_rows: {} lags for {} rows",
                    lags.len(),
                    rows.len()
                ),
            ));
        }
        if !self.row_gain.is_empty() && self.row_gain.len() != rows.len() {
            return Err((
                "row_gain",
                format!(
                    "needs one gain per first row in row_lag_rows: {} gains for {} rows",
                    self.row_gain.len(),
                    rows.len()
                ),
            ));
        }
        let max = sim::scene::MAX_ROW_LAGS;
        if rows.len() > max {
            return Err((
                "row_lag_rows",
                format!("at most {max} regions, got {}", rows.len()),
            ));
        }
        for (k, (&r, &l)) in rows.iter().zip(lags).enumerate() {
            if r >= self.height as u64 {
                return Err((
                    "row_lag_rows",
                    format!(
                        "row_lag_rows[{k}] = {r} must be below the frame height {}",
                        self.height
                    ),
                ));
            }
            if k > 0 && r <= rows[k - 1] {
                return Err((
                    "row_lag_rows",
                    format!(
                        "row_lag_rows[{k}] = {r} must be above row_lag_rows[{}] = {} (strictly ascending)",
                        k - 1,
                        rows[k - 1]
                    ),
                ));
            }
            if !(l.is_finite() && l.abs() <= MAX_ROW_LAG_US) {
                return Err((
                    "row_lag_us",
                    format!("row_lag_us[{k}] must be finite and within ±1e6 µs (1 s), got {l}"),
                ));
            }
        }
        Ok(())
    }

    /// The row lags as the simulator takes them: `(first_row, lag_s)`.
    fn row_lags(&self) -> Vec<(u32, f64)> {
        self.row_lag_rows
            .iter()
            .zip(&self.row_lag_us)
            .map(|(&r, &l)| (r.min(u32::MAX as u64) as u32, l * 1e-6))
            .collect()
    }

    /// Row timing of the simulated camera, if it has a rolling shutter or an exposure.
    pub fn row_timing(&self) -> Option<RowTiming> {
        if self.line_delay_us.is_none() && self.exposure_us.is_none() {
            return None;
        }
        Some(RowTiming {
            line_delay_ns: self.line_delay_us.unwrap_or(0.0) * 1e3,
            exposure_ns: self.exposure_us.unwrap_or(0.0) * 1e3,
        })
    }
}

pub const KIND: KindSpec = KindSpec {
    name: "synthetic",
    summary:
        "built-in scene: a textured object moving sub-pixel with a known signal (ground truth)",
    inputs: NO_INPUTS,
    outputs: &[OutPort::out(PortType::Frames)],
    params: SyntheticParams::PARAMS,
    plan: |p| {
        let v: SyntheticParams = p.resolve_typed()?;
        v.check().map_err(|(field, m)| p.error(field, m))?;
        Ok(Box::new(v))
    },
};

impl Plan for SyntheticParams {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let scene = self.scene().map_err(StageError::dsp)?;
        let format = FrameFormat {
            width: self.width,
            height: self.height,
            depth: self.depth(),
            bits: self.bits,
            fps: self.fps,
            row_timing: self.row_timing(),
        };
        Ok(Node::Source(Box::new(Synthetic {
            pool: FramePool::new(format, ctx.pool_frames),
            scene,
            seq: 0,
            total: self.delivered_count(),
            fps: self.fps,
            true_fps: self.true_fps(),
            capture: 0,
            captured: self.frame_count(),
            drops: sorted(&self.drop_frames),
            dups: sorted(&self.duplicate_frames),
            repeat: false,
            pacer: self.realtime.then(|| Pacer::new(self.fps)),
            rows: self.row_timing(),
        })))
    }

    fn is_live(&self) -> bool {
        self.realtime
    }
}

fn sorted(v: &[u64]) -> std::collections::VecDeque<u64> {
    let mut v = v.to_vec();
    v.sort_unstable();
    v.dedup();
    v.into()
}

struct Synthetic {
    pool: FramePool,
    scene: Scene,
    /// Frames delivered so far (the stamp index).
    seq: u64,
    total: u64,
    fps: f64,
    true_fps: f64,
    /// Next capture index, captures in all, and the pending drops and
    /// duplicates (sorted capture indices).
    capture: u64,
    captured: u64,
    drops: std::collections::VecDeque<u64>,
    dups: std::collections::VecDeque<u64>,
    /// The last capture is to be delivered once more.
    repeat: bool,
    pacer: Option<Pacer>,
    rows: Option<RowTiming>,
}

impl Source for Synthetic {
    fn next(&mut self, ctx: &SourceCtx<'_>) -> Result<Option<Item>, StageError> {
        if self.seq >= self.total {
            return Ok(None);
        }
        // Which capture this delivery shows: drops are skipped, a
        // duplicate is the previous capture again (same noise, same pixels).
        let c = if self.repeat {
            self.repeat = false;
            self.capture - 1
        } else {
            while self.drops.front() == Some(&self.capture) {
                self.drops.pop_front();
                self.capture += 1;
            }
            if self.capture >= self.captured {
                return Ok(None);
            }
            let c = self.capture;
            self.capture += 1;
            if self.dups.front() == Some(&c) {
                self.dups.pop_front();
                self.repeat = true;
            }
            c
        };
        // Captured on the camera's own clock, stamped on the stated one.
        let t_s = c as f64 / self.true_fps;
        if let Some(p) = &mut self.pacer {
            // Delivered when the last row's exposure ends, as a camera does.
            let readout = self.rows.map_or(0.0, |rt| {
                ((self.pool.format().height.max(1) - 1) as f64 * rt.line_delay_ns + rt.exposure_ns)
                    * 1e-9
            });
            p.wait_after(self.seq, ctx.control.epoch(), readout);
        }
        let Some(mut f) = ctx.acquire(&self.pool) else {
            return Ok(None);
        };
        let dst = match f.pixels_mut() {
            PixelsMut::U8(p) => sim::Dest::U8(p),
            PixelsMut::U16(p) => sim::Dest::U16(p),
        };
        match self.rows {
            Some(rt) => {
                self.scene
                    .render_rows(c, t_s, rt.line_delay_ns * 1e-9, rt.exposure_ns * 1e-9, dst)
            }
            None => self.scene.render(c, t_s, dst),
        }
        let item = nominal_frame(f, self.seq, self.fps);
        self.seq += 1;
        Ok(Some(item))
    }

    fn total_hint(&self) -> Option<u64> {
        Some(self.total)
    }

    fn is_live(&self) -> bool {
        self.pacer.is_some()
    }
}

/// A picture for the object's texture, resized to `w × h` (Catmull-Rom).
fn texture_picture(
    path: &std::path::Path,
    w: u32,
    h: u32,
) -> Result<(Vec<f64>, usize, usize), String> {
    let img = vibroscope_io::image::read_gray16(path).map_err(|m| format!("texture: {m}"))?;
    let img = if img.dimensions() == (w, h) {
        img
    } else {
        image::imageops::resize(&img, w, h, image::imageops::FilterType::CatmullRom)
    };
    let px: Vec<f64> = img.pixels().map(|p| p.0[0] as f64).collect();
    let flat = px.iter().all(|&v| v == px[0]);
    if flat {
        return Err(format!(
            "texture: {}: the picture is flat (no contrast)",
            path.display()
        ));
    }
    Ok((px, w as usize, h as usize))
}

/// The object's silhouette, one coverage in [0, 1] per frame pixel.
fn silhouette(path: &std::path::Path, w: u32, h: u32) -> Result<Vec<f32>, String> {
    let img = vibroscope_io::image::read_gray16(path).map_err(|m| format!("object_mask: {m}"))?;
    if img.dimensions() != (w, h) {
        let (iw, ih) = img.dimensions();
        return Err(format!(
            "object_mask: {} is {iw}x{ih}, the frame {w}x{h}",
            path.display()
        ));
    }
    let max = img.pixels().map(|p| p.0[0]).max().unwrap_or(0);
    if max == 0 {
        return Err(format!(
            "object_mask: {}: the mask is empty (no pixel > 0)",
            path.display()
        ));
    }
    Ok(img.pixels().map(|p| p.0[0] as f32 / max as f32).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Default` (what a scene file that omits a field gets) is the
    /// declared defaults, as a pipeline stage with no parameters resolves them.
    #[test]
    fn default_is_the_declaration() {
        let decl = crate::config::parse("t.toml", "[[stage]]\nid = \"s\"\nkind = \"synthetic\"\n")
            .unwrap_or_else(|e| panic!("{e}"));
        let p = Params {
            file: "t.toml",
            stage: &decl.stages[0],
        };
        let resolved: SyntheticParams = p.resolve_typed().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(resolved, SyntheticParams::default());
        assert_eq!(resolved.fps, 2200.0);
        assert_eq!(resolved.width, 256);
        let from_toml: SyntheticParams =
            toml::from_str("fps = 600.0").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(from_toml.width, 256);
        assert_eq!(from_toml.fps, 600.0);
    }

    /// Issue 15: `row_lag_rows` and `row_lag_us` reach the model (lagged
    /// rows move late, with a global shutter too; the rows above are as
    /// without them), and bad pairs are refused naming the key and entry.
    #[test]
    fn row_lags_reach_the_model_and_bad_ones_are_named() {
        let base = "width = 32\nheight = 32\nfps = 2200.0\nnoise_std = 0.0\namplitude_px = 0.5\n\
                    signal = { type = \"tone\", freq_hz = 500.0 }\n";
        let params = |extra: &str| -> SyntheticParams {
            toml::from_str(&format!("{base}{extra}")).unwrap_or_else(|e| panic!("{e}"))
        };
        let plain = params("");
        // Rows 16.. half a period of 500 Hz late: in antiphase.
        let lagged = params("row_lag_rows = [16]\nrow_lag_us = [1000.0]\n");
        for p in [&plain, &lagged] {
            p.check().unwrap_or_else(|(f, m)| panic!("{f}: {m}"));
        }
        let mut a = plain.scene().unwrap_or_else(|e| panic!("{e}"));
        let mut b = lagged.scene().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((b.row_lag_s(15), b.row_lag_s(16)), (0.0, 1e-3));
        for k in 0..5u64 {
            let t = k as f64 / 2200.0;
            let (want_top, want_bottom) =
                (a.displacement_px(t), b.row_displacement_px(t, 20, 0.0, 0.0));
            assert!(
                (want_top + want_bottom).abs() < 1e-9,
                "{want_top} {want_bottom}"
            );
            let (mut fa, mut fb) = (vec![0u8; 32 * 32], vec![0u8; 32 * 32]);
            a.render(k, t, sim::Dest::U8(&mut fa));
            b.render(k, t, sim::Dest::U8(&mut fb));
            assert_eq!(fa[..16 * 32], fb[..16 * 32], "frame {k}");
            if want_top.abs() > 0.1 {
                assert_ne!(fa[16 * 32..], fb[16 * 32..], "frame {k}");
            }
        }
        let modal = "modal = { modes = [{ freq_hz = 50.0, amplitude_px = 0.2, shape = 1, drive = \"tone\" }] }\n";
        for (extra, field, names) in [
            (
                "row_lag_rows = [16, 8]\nrow_lag_us = [0.0, 1.0]",
                "row_lag_rows",
                "row_lag_rows[1]",
            ),
            (
                "row_lag_rows = [4, 4]\nrow_lag_us = [0.0, 1.0]",
                "row_lag_rows",
                "row_lag_rows[1]",
            ),
            (
                "row_lag_rows = [32]\nrow_lag_us = [1.0]",
                "row_lag_rows",
                "row_lag_rows[0]",
            ),
            (
                "row_lag_rows = [1, 2, 3]\nrow_lag_us = [1.0, 2.0, 2e6]",
                "row_lag_us",
                "row_lag_us[2]",
            ),
            (
                "row_lag_rows = [1]\nrow_lag_us = [nan]",
                "row_lag_us",
                "row_lag_us[0]",
            ),
            (
                "row_lag_rows = [1]\nrow_lag_us = [1.0, 2.0]",
                "row_lag_us",
                "row_lag_rows",
            ),
            ("row_lag_us = [1.0]", "row_lag_us", "row_lag_rows"),
            (
                "row_lag_rows = [16]\nrow_lag_us = [0.0]\nrow_gain = [0.5, 1.0]",
                "row_gain",
                "row_lag_rows",
            ),
            (
                "row_lag_rows = [16]\nrow_lag_us = [0.0]\nrow_gain = [nan]",
                "row_gain",
                "row_gain[0]",
            ),
            (
                &format!("row_lag_rows = [1]\nrow_lag_us = [1.0]\n{modal}"),
                "row_lag_rows",
                "modal",
            ),
        ] {
            let p = params(extra);
            let (f, m) = p
                .check()
                .err()
                .unwrap_or_else(|| panic!("{extra} accepted"));
            assert_eq!(f, field, "{extra}: {m}");
            assert!(m.contains(names), "{extra}: {m}");
            // And the model refuses them too, never panicking.
            assert!(p.scene().is_err(), "{extra}");
        }
        // Declared ranges: a pipeline gets them checked by the declaration.
        let decl = crate::config::parse(
            "t.toml",
            "[[stage]]\nid = \"s\"\nkind = \"synthetic\"\nrow_lag_rows = [1]\nrow_lag_us = [-2e6]\n",
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let p = Params {
            file: "t.toml",
            stage: &decl.stages[0],
        };
        let e = p
            .resolve_typed::<SyntheticParams>()
            .err()
            .unwrap_or_else(|| panic!("-2e6 µs accepted"));
        assert!(e.to_string().contains("row_lag_us"), "{e}");
    }
}
