//! Network edges on zenoh, apart from the engine's other kinds so that
//! zenoh is compiled only where the network is used: the `zenoh_pub` sink
//! and the `zenoh_sub` source kinds, and the [`session`] helpers (endpoints,
//! sessions, key checks) they share with `vibroscope monitor`. Items cross
//! in the core's versioned wire encoding (`vibroscope_core::wire`).
//!
//! [`KINDS`] lists them for the layer that assembles a registry (the
//! recipes' `stages`).

pub mod session;
pub mod zenoh_pub;
pub mod zenoh_sub;

use vibroscope_core::KindSpec;

/// The kinds of this crate, sources first.
pub static KINDS: &[KindSpec] = &[zenoh_sub::KIND, zenoh_pub::KIND];

/// Their typed parameters ([`vibroscope_core::params!`]), by struct name.
pub mod params {
    pub use super::zenoh_pub::ZenohPubParams;
    pub use super::zenoh_sub::ZenohSubParams;
}
