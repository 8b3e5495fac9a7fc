//! A pipeline file: parsed, then validated against every stage kind but
//! the network's (each kind's parameters and plan, the graph's wiring and
//! types).
#![no_main]

use libfuzzer_sys::fuzz_target;
use vibroscope_engine::{config, graph, stages, KindSpec};

/// The engine's kinds and the devices'.
fn kinds() -> &'static [KindSpec] {
    static K: std::sync::OnceLock<Vec<KindSpec>> = std::sync::OnceLock::new();
    K.get_or_init(|| [stages::KINDS, vibroscope_devices::KINDS].concat())
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(decl) = config::parse("fuzz.toml", text) {
        let _ = graph::validate(&decl, kinds());
    }
});
