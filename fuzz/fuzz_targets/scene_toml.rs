//! A scene file (`vibroscope simulate SCENE.toml`): its fields fill the
//! `synthetic` source of the shipped `render` pipeline, as `simulate`
//! does, and the graph is validated (which builds the forward model).
#![no_main]

use libfuzzer_sys::fuzz_target;
use vibroscope_engine::config::{self, Origin};
use vibroscope_engine::stages::params::Y4mParams;
use vibroscope_engine::{graph, pipelines, stages};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(table) = toml::from_str::<toml::Table>(text) else {
        return;
    };
    let render = pipelines::find("render").expect("shipped render pipeline");
    let mut decl = config::parse("render.toml", render.text).expect("render parses");
    let Some(cam) = decl.stages.iter_mut().find(|s| s.id == "cam") else {
        panic!("render has no `cam` stage");
    };
    // The scene file's reader, as `simulate` uses it.
    config::read_table(cam, &table, |_| Origin::Line(1));
    // Output to /dev/null: validation must not write anything.
    let out = pipelines::stage::render::OUT;
    let null = std::path::PathBuf::from("/dev/null");
    decl.set(out, Y4mParams::path, null, Origin::Line(1))
        .expect("render's `out` is a y4m sink");
    let _ = graph::validate(&decl, stages::KINDS);
});
