//! `synthetic`: the built-in scene — a textured object moving sub-pixel with
//! a known signal over a still background, with sensor noise and 8/16-bit
//! quantisation — rendered by the forward model in [`vibroscope_sim`], which the
//! tests use as ground truth. Deterministic from `seed`. With
//! `realtime = true` it behaves like a live camera: paced by the wall clock,
//! and its edges drop the oldest frame when downstream lags.

use super::{check_fps, nominal_frame, Pacer};
use crate::*;
use serde::Deserialize;
use vibroscope_sim::{self as sim, Scene, SceneSpec, Signal, SignalSpec};

/// Parameters of the synthetic scene (also used by `vibroscope demo` and tests).
#[derive(Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SyntheticParams {
    #[serde(default = "d_size")]
    pub width: u32,
    #[serde(default = "d_size")]
    pub height: u32,
    #[serde(default = "d_fps")]
    pub fps: f64,
    /// Length in seconds (`frames` wins when both are given).
    #[serde(default = "d_duration")]
    pub duration_s: f64,
    pub frames: Option<u64>,
    /// Moving object `[x, y, w, h]`; default: the central half of the frame.
    pub object: Option<[u32; 4]>,
    #[serde(default = "d_amp")]
    pub amplitude_px: f64,
    #[serde(default)]
    pub direction_deg: f64,
    #[serde(default = "d_noise")]
    pub noise_std: f64,
    #[serde(default = "d_bits")]
    pub bits: u8,
    /// Texture contrast (std, in DN); default 15% of full scale.
    pub contrast: Option<f64>,
    #[serde(default = "d_seed")]
    pub seed: u64,
    #[serde(default = "d_signal")]
    pub signal: SignalSpec,
    /// Pace frames by the wall clock like a live camera.
    #[serde(default)]
    pub realtime: bool,
    /// Rolling shutter (thesis Eq. 4.4): row y of frame n is captured at
    /// n/fps + y·line_delay; absent = global shutter.
    pub line_delay_us: Option<f64>,
    /// Stated frame delay, checked against 1/fps - height·line_delay.
    pub frame_delay_us: Option<f64>,
    /// Each row averages the motion over this exposure (a boxcar).
    pub exposure_us: Option<f64>,
    /// The object's transfer function from sound to motion: peaking
    /// resonances in series (`[{ freq_hz, q, gain_db }]`); none = flat.
    #[serde(default)]
    pub resonances: Vec<sim::Resonance>,
    /// Narrowband motion added to the object's (camera shake, a machine):
    /// `[{ freq_hz, amplitude_px }]`.
    #[serde(default)]
    pub interference: Vec<Interference>,
    /// The camera's true frame rate is `fps · (1 + clock_error_ppm·1e-6)`
    /// while its frames are stamped at the stated `fps`.
    #[serde(default)]
    pub clock_error_ppm: f64,
    /// Captured frames the camera loses (0-based capture indices): the
    /// stream skips them and later frames are stamped as if nothing was lost.
    #[serde(default)]
    pub drop_frames: Vec<u64>,
    /// Captured frames the camera delivers twice (identical copies).
    #[serde(default)]
    pub duplicate_frames: Vec<u64>,
    /// A picture (PGM or PNG) for the object's texture instead of the
    /// procedural one, resized to the object's rectangle.
    pub texture: Option<std::path::PathBuf>,
    /// The object's silhouette (PGM or PNG, the frame's size): a pixel's
    /// gray level over the brightest pixel's is the fraction of it that
    /// belongs to the object (0 = background).
    pub object_mask: Option<std::path::PathBuf>,
    /// The object as a vibrating cantilever beam, column by column, instead
    /// of a rigid motion (`{ modes = [{ freq_hz, amplitude_px, shape, ... }] }`,
    /// see [`vibroscope_sim::modal`]); global shutter only.
    pub modal: Option<sim::ModalSpec>,
    /// The object's excursion saturates softly: displacement `L tanh(d /
    /// L)` with `L = soft_clip_px` (a nonlinear object or loudspeaker; odd
    /// harmonics); before interference, which is not clipped.
    pub soft_clip_px: Option<f64>,
}

/// A narrowband motion added to the object's.
#[derive(Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Interference {
    pub freq_hz: f64,
    pub amplitude_px: f64,
}
fn d_size() -> u32 {
    256
}
fn d_fps() -> f64 {
    2200.0
}
fn d_duration() -> f64 {
    1.0
}
fn d_amp() -> f64 {
    0.05
}
fn d_noise() -> f64 {
    2.0
}
fn d_bits() -> u8 {
    8
}
fn d_seed() -> u64 {
    1
}
fn d_signal() -> SignalSpec {
    SignalSpec::Tone {
        freq_hz: 440.0,
        phase_rad: 0.0,
    }
}

impl Default for SyntheticParams {
    fn default() -> Self {
        Self {
            width: d_size(),
            height: d_size(),
            fps: d_fps(),
            duration_s: d_duration(),
            frames: None,
            object: None,
            amplitude_px: d_amp(),
            direction_deg: 0.0,
            noise_std: d_noise(),
            bits: d_bits(),
            contrast: None,
            seed: d_seed(),
            signal: d_signal(),
            realtime: false,
            line_delay_us: None,
            frame_delay_us: None,
            exposure_us: None,
            resonances: Vec::new(),
            interference: Vec::new(),
            clock_error_ppm: 0.0,
            drop_frames: Vec::new(),
            duplicate_frames: Vec::new(),
            texture: None,
            object_mask: None,
            modal: None,
            soft_clip_px: None,
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

    /// The forward model for these parameters.
    pub fn scene(&self) -> Result<Scene, String> {
        let span = (self.frame_count() + 2) as f64 / self.true_fps()
            + self.exposure_us.unwrap_or(0.0) * 1e-6
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
            .and_then(|s| s.through(&self.resonances, rate, span))
            .and_then(|s| match self.soft_clip_px {
                Some(l) => s.soft_clipped(l * unit),
                None => Ok(s),
            })
            .and_then(|s| s.plus_tones(&tones))
            .map_err(|e| e.to_string())?;
        let (w, h) = (self.width, self.height);
        let object = self
            .object
            .unwrap_or([w / 4, h / 4, (w / 2).max(1), (h / 2).max(1)]);
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
        };
        let look = sim::Look {
            texture: match &self.texture {
                Some(p) => Some(texture_picture(p, object[2], object[3])?),
                None => None,
            },
            mask: match &self.object_mask {
                Some(p) => Some(silhouette(p, w, h)?),
                None => None,
            },
        };
        match &self.modal {
            Some(m) => Scene::with_modal(spec, signal, m, look),
            None => Scene::with_look(spec, signal, look),
        }
        .map_err(|e| e.to_string())
    }

    /// Checks every field; the message names the field.
    ///
    /// (`texture` and `object_mask` are read by [`SyntheticParams::scene`],
    /// which `check` calls last.)
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
        let e = self.clock_error_ppm;
        if !(e.is_finite() && e.abs() <= 1e5) {
            return Err((
                "clock_error_ppm",
                format!("must be within ±100000 ppm, got {e}"),
            ));
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
        self.scene().map(|_| ()).map_err(|m| {
            let field = if m.starts_with("texture") {
                "texture"
            } else if m.starts_with("object_mask") {
                "object_mask"
            } else if m.contains("modal") {
                "modal"
            } else if m.contains("soft_clip_px") {
                "soft_clip_px"
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
    accepts: &[],
    max_inputs: 0,
    output: Output::Fixed(PortType::Frames),
    plan: |p| {
        let v: SyntheticParams = p.parse()?;
        v.check().map_err(|(field, m)| p.error(field, m))?;
        Ok(Box::new(v))
    },
};

impl Plan for SyntheticParams {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let scene = self.scene().map_err(StageError::msg)?;
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
