//! The forward model of object and camera: the ground truth that the
//! synthetic source, the simulator and the signal-quality tests share.
//!
//! A textured object translates sub-pixel along a fixed direction with a
//! known waveform ([`Signal`], unit peak, scaled by `amplitude_px`) in front
//! of a still, lower-contrast background; a camera samples it with a global
//! or a rolling shutter ([`Scene::render`], [`Scene::render_rows`], thesis
//! ch. 4.5, Eq. 4.4), adds Gaussian sensor noise and quantises to 8 or 16
//! bits. Everything is deterministic from the seed, bit for bit on every
//! platform: own PRNG ([`rng`]) and own elementary functions ([`detmath`]);
//! frame `k`'s noise depends only on `(seed, k)`.
//!
//! The texture is band-limited (Gaussian-filtered white noise, σ = 2 px) and
//! shifted with a 16-tap separable Wiener interpolator designed for its
//! spectrum ([`texture`]): rendered shifts match the continuous texture to
//! within 4e-6 of its contrast (0.04 DN at 16 bits, 0.0002 DN at 8 bits), so
//! the motion in the video is the signal, not interpolation artefacts, and
//! the SNR law of Eq. 4.3 (`SNR ∝ |D_p| √n_p / σ_n`) holds for what the
//! renderer produces (see [`EdgeMode`] for the one way to bend it).
//!
//! Speed (release, one core of the 2-core dev machine, 256x256 u8 with a
//! 128x128 object): ~240 Mpix/s (3,600 fps) with noise, ~900 Mpix/s without,
//! ~75 Mpix/s for a diagonal rolling-shutter frame with exposure averaging.

pub use vibroscope_math::detmath;
pub mod fabric;
pub mod modal;
pub use vibroscope_math::rng;
pub mod scene;
pub mod signal;
pub mod texture;

pub use fabric::{Excitation, Fabric, FabricSpec};
pub use modal::{ModalBeam, ModalSpec};
pub use scene::{
    Depth, Dest, EdgeMode, LightSpec, Look, MotionSpec, MoverSpec, Scene, SceneSpec, SurroundSpec,
    MAX_AMPLITUDE_PX,
};
pub use signal::{Resonance, Signal, SignalSpec};

/// Errors of the forward model: invalid parameters (naming the field) and
/// unreadable WAV files.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("invalid {field}: {msg}")]
    Invalid { field: String, msg: String },
    #[error("cannot read WAV file {0}")]
    Wav(#[from] vibroscope_io::wav::WavError),
}

impl SimError {
    /// The parameter an [`SimError::Invalid`] is about (`"path"` for WAV errors).
    pub fn field(&self) -> &str {
        match self {
            SimError::Invalid { field, .. } => field,
            SimError::Wav(_) => "path",
        }
    }
}
