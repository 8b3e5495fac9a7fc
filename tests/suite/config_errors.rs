//! Every configuration error exits with status 2 and names the file, the
//! line, the stage id and the field; none panics.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;

/// Writes `text` as p.toml, runs it, and checks exit 2 plus each `needle`.
fn check(text: &str, needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("p.toml"), text).unwrap();
    let o = run_in(dir.path(), &["run", "p.toml", "--quiet"]);
    let err = stderr(&o);
    assert_eq!(code(&o), 2, "expected exit 2, got {}: {err}", code(&o));
    assert!(!err.contains("panicked"), "panic: {err}");
    for n in needles {
        assert!(err.contains(n), "message lacks `{n}`: {err}");
    }
}

const SRC: &str = "[[stage]]\nid = \"cam\"\nkind = \"pattern\"\nframes = 3\n";

#[test]
fn unknown_key_names_key_line_and_stage() {
    check(
        &format!("{SRC}fsp = 3\n\n[[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"cam\"\n"),
        &["p.toml:5", "stage `cam`", "`fsp`", "unknown field"],
    );
}

#[test]
fn unknown_input_id() {
    check(
        &format!("{SRC}\n[[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"camm\"\n"),
        &[
            "p.toml:9",
            "stage `n`",
            "`input`",
            "unknown input id `camm`",
        ],
    );
}

#[test]
fn cycle_is_rejected() {
    let text = format!("{SRC}\n[[stage]]\nid = \"a\"\nkind = \"passthrough\"\ninput = [\"b\"]\n\n[[stage]]\nid = \"b\"\nkind = \"passthrough\"\ninput = \"a\"\n\n[[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"b\"\n");
    check(&text, &["p.toml:", "cycle", "`input`"]);
}

#[test]
fn wrong_port_type_frames_into_audio_sink() {
    check(
        &format!(
            "{SRC}\n[[stage]]\nid = \"w\"\nkind = \"wav\"\ninput = \"cam\"\npath = \"x.wav\"\n"
        ),
        &[
            "p.toml:9",
            "stage `w`",
            "`input`",
            "gives frames",
            "takes audio",
        ],
    );
}

#[test]
fn out_of_range_value() {
    check("[[stage]]\nid = \"cam\"\nkind = \"synthetic\"\nfps = 0.0\n\n[[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"cam\"\n", &["p.toml:4", "stage `cam`", "`fps`", "got 0"]);
}

#[test]
fn mistyped_value() {
    check(
        &format!(
            "{SRC}width = \"wide\"\n\n[[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"cam\"\n"
        ),
        &["p.toml:5", "stage `cam`", "`width`", "invalid type"],
    );
}

#[test]
fn missing_required_field() {
    check(&format!("{SRC}\n[[stage]]\nid = \"m\"\nkind = \"mean\"\ninput = \"cam\"\n\n[[stage]]\nid = \"w\"\nkind = \"wav\"\ninput = \"m\"\n"), &["p.toml:12", "stage `w`", "missing field `path`"]);
}

#[test]
fn bad_capacity_and_policy() {
    check(
        &format!("{SRC}\n[[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"cam\"\ncapacity = 0\n"),
        &["p.toml:10", "stage `n`", "`capacity`", "got 0"],
    );
    check(&format!("{SRC}\n[[stage]]\nid = \"n\"\nkind = \"null\"\ninput = \"cam\"\npolicy = \"drop_newest\"\n"), &["p.toml:10", "stage `n`", "`policy`", "drop_newest"]);
}

#[test]
fn unknown_kind_lists_known_ones() {
    check(
        "[[stage]]\nid = \"cam\"\nkind = \"camera9000\"\n",
        &[
            "p.toml:3",
            "stage `cam`",
            "`kind`",
            "unknown kind `camera9000`",
            "synthetic",
        ],
    );
}

#[test]
fn duplicate_id() {
    check(
        &format!("{SRC}\n[[stage]]\nid = \"cam\"\nkind = \"null\"\ninput = \"cam\"\n"),
        &["p.toml:7", "stage `cam`", "duplicate stage id", "line 2"],
    );
}

#[test]
fn toml_syntax_error_has_line() {
    check("[[stage]]\nid = \"cam\"\nkind = \n", &["p.toml:3"]);
}

#[test]
fn unknown_top_level_table() {
    check(
        "[pipelin]\nname = \"x\"\n",
        &["p.toml:1", "unknown field `pipelin`"],
    );
}

#[test]
fn source_with_input_and_sink_without() {
    check(
        &format!("{SRC}input = \"x\"\n"),
        &["stage `cam`", "takes no input"],
    );
    check(
        &format!("{SRC}\n[[stage]]\nid = \"n\"\nkind = \"null\"\n"),
        &["p.toml:7", "stage `n`", "needs an `input`"],
    );
}

#[test]
fn set_override_errors_name_the_override() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(
        dir.path(),
        &["run", "demo", "--set", "cam.fps=0", "--quiet"],
    );
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--set cam.fps=0") && stderr(&o).contains("`fps`"),
        "{}",
        stderr(&o)
    );
    let o = run_in(
        dir.path(),
        &["run", "demo", "--set", "camx.fps=10", "--quiet"],
    );
    assert_eq!(code(&o), 2);
    assert!(stderr(&o).contains("camx"), "{}", stderr(&o));
}

#[test]
fn missing_pipeline_file_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(dir.path(), &["run", "nope.toml"]);
    assert_eq!(code(&o), 2);
    assert!(stderr(&o).contains("nope.toml"), "{}", stderr(&o));
}

#[test]
fn bad_command_line_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(dir.path(), &["run"]);
    assert_eq!(code(&o), 2);
    let o = run_in(dir.path(), &["frobnicate"]);
    assert_eq!(code(&o), 2);
}

/// `kinds` lists every registered kind; `kinds KIND` prints its ports and
/// parameter table; an unknown KIND is a usage error.
#[test]
fn kinds_lists_and_describes_every_kind() {
    let dir = tempfile::tempdir().unwrap();
    let o = run_in(dir.path(), &["kinds"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let list = String::from_utf8_lossy(&o.stdout).to_string();
    let every = vibroscope_engine::stages::KINDS
        .iter()
        .chain(vibroscope_devices::KINDS)
        .chain(vibroscope_net::KINDS);
    for k in every {
        assert!(
            list.lines()
                .any(|l| l.split_whitespace().next() == Some(k.name)),
            "`{}` not listed: {list}",
            k.name
        );
        let o = run_in(dir.path(), &["kinds", k.name]);
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let table = String::from_utf8_lossy(&o.stdout).to_string();
        for p in k.params {
            assert!(table.contains(p.name), "{}: {table}", k.name);
        }
    }
    let o = run_in(dir.path(), &["kinds", "spectrum"]);
    let table = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        table.contains("in: samples | audio") && table.contains("out: spectrum"),
        "{table}"
    );
    let o = run_in(dir.path(), &["kinds", "camera9000"]);
    assert_eq!(code(&o), 2);
    assert!(stderr(&o).contains("camera9000"), "{}", stderr(&o));
}
