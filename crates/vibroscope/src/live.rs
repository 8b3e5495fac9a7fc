//! A live view of a running pipeline (the studio's): the tap stage's
//! parameters, the slots and observers its frames and items arrive
//! through, the items themselves, and the region mask a page draws.

pub use vibroscope_engine::config::{Origin, PipelineDecl};
pub use vibroscope_engine::stages::params::TapParams;
pub use vibroscope_engine::stages::transform::roi::Mask;
pub use vibroscope_engine::{
    thousands, Latest, Next, Observer, PortType, Spectrum, TapFrame, TapSlot,
};
#[cfg(feature = "net")]
pub use vibroscope_net::session as net;
