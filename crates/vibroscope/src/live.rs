//! A live view of a running pipeline (the studio's): the tap stage's
//! parameters, the slots and observers its frames and items arrive
//! through, the items themselves, and the region mask a page draws.

pub use vibroscope_engine::config::{Origin, PipelineDecl};
pub use vibroscope_engine::stages::params::{MagnifyParams, TapParams};
/// The `magnify` stage's own checks of a band and of a parameter's value,
/// for a change asked while it runs.
pub use vibroscope_engine::stages::transform::magnify::{
    check_band as check_magnify_band, check_param as check_magnify_param,
};
pub use vibroscope_engine::stages::transform::roi::Mask;
pub use vibroscope_engine::{
    thousands, Latest, Next, Observer, PortType, Spectrum, TapFrame, TapSlot, Tuned, Tuning,
};
#[cfg(feature = "net")]
pub use vibroscope_net::session as net;
