//! Stage kinds on live devices, apart from the engine's other kinds so that
//! their drivers' dependencies (v4l and its bindgen, nokhwa, cpal) are
//! compiled only where a device is used: the `v4l2` and `nokhwa` camera
//! sources and the `speaker` sink. Each kind exists in every build (a
//! pipeline naming it validates); one built without its driver's feature
//! fails when the stage opens, saying which feature to enable.
//!
//! [`KINDS`] lists them for the layer that assembles a registry (the
//! recipes' `stages`).

pub mod nokhwa;
pub mod speaker;
pub mod v4l2;

use vibroscope_core::KindSpec;

/// The kinds of this crate, sources first.
pub static KINDS: &[KindSpec] = &[v4l2::KIND, nokhwa::KIND, speaker::KIND];

/// Their typed parameters ([`vibroscope_core::params!`]), by struct name.
pub mod params {
    pub use super::nokhwa::NokhwaParams;
    pub use super::speaker::SpeakerParams;
    pub use super::v4l2::V4l2Params;
}
