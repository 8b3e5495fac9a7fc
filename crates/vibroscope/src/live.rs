//! A live view of a running pipeline (the studio's): the tap stage's
//! parameters, the slots and observers its frames and items arrive
//! through, the items themselves, and the region mask a page draws.

pub use vibroscope_engine::config::{Origin, PipelineDecl};
pub use vibroscope_engine::stages::params::{MagnifyParams, TapParams};
pub use vibroscope_engine::stages::transform::roi::Mask;
pub use vibroscope_engine::{
    thousands, Latest, Next, Observer, PortType, Spectrum, TapFrame, TapSlot, Tuned, Tuning,
};
#[cfg(feature = "net")]
pub use vibroscope_net::session as net;

/// Checks `v` for the `magnify` stage's parameter `name` against the
/// kind's declaration (its range); the message says what is wrong.
pub fn check_magnify_param(name: &str, v: f64) -> Result<(), String> {
    use vibroscope_engine::spec::KindParams;
    let spec = MagnifyParams::PARAMS
        .iter()
        .find(|s| s.name == name)
        .ok_or_else(|| format!("`magnify` has no parameter `{name}`"))?;
    spec.check(&toml::Value::Float(v))
}
