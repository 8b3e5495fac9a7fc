//! A pipeline file: parsed, then validated against every stage kind (each
//! kind's parameters and plan, the graph's wiring and types).
#![no_main]

use libfuzzer_sys::fuzz_target;
use vibroscope_engine::{config, graph, stages};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(decl) = config::parse("fuzz.toml", text) {
        let _ = graph::validate(&decl, stages::REGISTRY);
    }
});
