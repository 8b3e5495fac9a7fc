//! `vibroscope learn` (issue 19, thesis 5.5): material properties of
//! simulated hanging fabrics from their motion spectra, and bad input.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;
use std::path::Path;
use vibroscope::learn::model::pearson;

/// Generates a dataset in `dir/ds` (`more`: further flags).
fn generate(dir: &Path, materials: &str, conditions: &str, more: &[&str]) {
    let mut args = vec![
        "learn",
        "generate",
        "-o",
        "ds",
        "--materials",
        materials,
        "--conditions",
        conditions,
    ];
    args.extend_from_slice(more);
    let o = run_in(dir, &args);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
}

/// The figure `R x.xxx` of `target` on the PLSR line of `evaluate`'s output.
fn r_of(out: &str, target: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.contains("PLSR") && l.contains(target))
        .unwrap_or_else(|| panic!("no PLSR line for {target} in {out}"));
    let after = line.split(" R ").nth(1).unwrap();
    after.split_whitespace().next().unwrap().parse().unwrap()
}

/// `learn evaluate` trained and tested on A/L (`more`: further flags).
fn evaluate_al(dir: &Path, more: &[&str]) -> std::process::Output {
    let mut args = vec![
        "learn",
        "evaluate",
        "ds/DATASET.toml",
        "--train-on",
        "A/L",
        "--test-on",
        "A/L",
    ];
    args.extend_from_slice(more);
    run_in(dir, &args)
}

/// [`evaluate_al`] with `flag` (features from the scene files, not the
/// videos): its output, which says `header`.
fn evaluate_from_scenes(dir: &Path, flag: &str, header: &str) -> String {
    let o = evaluate_al(dir, &[flag]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let out = stdout(&o);
    println!("{out}");
    assert!(out.contains(header), "{out}");
    out
}

/// Leave-one-fabric-out on unseen fabrics, same condition: the default
/// dataset's A/L part with one take a fabric in place of three (60
/// fabrics x 1 take, 60 s, 128 px; about 2 min on 2 cores; the takes are
/// scene files rendered in memory: as videos they would fill 2.4 GB).
/// Area weight and stiffness R >= 0.9, issue 19's bar (measured 0.982
/// and 0.913 with each tile counted alike, `normalise = "channel"`;
/// 0.889 for stiffness before, when tiles weighed by their texture; this
/// draw of fabrics only, the generator's seed 1; docs/learning.md has the
/// full dataset's tables).
/// Stiffness shows only in the upper modes, near the noise floor: with
/// 64 px, 30 s videos it was 0.60-0.79, and it needs many fabrics (30
/// fabrics x 2 takes: 0.876, its bound 0.922).
#[test]
fn same_condition_leave_one_out_predicts_both_properties() {
    let d = tempfile::tempdir().unwrap();
    generate(d.path(), "60", "A/L", &["--per-condition", "1"]);
    let o = evaluate_al(d.path(), &[]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let out = stdout(&o);
    println!("{out}");
    assert!(r_of(&out, "area_weight") >= 0.9, "{out}");
    assert!(r_of(&out, "stiffness") >= 0.9, "{out}");
    // Cached features: a second run renders nothing and agrees.
    let o2 = evaluate_al(d.path(), &[]);
    assert_eq!(stdout(&o2), out);
    // The bound: the same learning on the videos' expected spectra (no
    // texture, sensor, pyramid or estimation noise). Under ambient forcing
    // it carries stiffness (0.979 here; 0.92-0.94 with 30 fabrics).
    let bound = evaluate_from_scenes(d.path(), "--exact", "exact expected spectra");
    assert!(r_of(&bound, "stiffness") >= 0.95, "{bound}");
    // Each take's true motion through the videos' estimator (no texture,
    // sensor or pyramid): what one 60 s take holds (0.963 here).
    let taken = evaluate_from_scenes(d.path(), "--true-motion", "true motion");
    assert!(r_of(&taken, "stiffness") >= 0.9, "{taken}");

    // A model of these takes predicts one of them inside its training
    // distribution (T2 5-6 against limits of 15-18, Q 0.13-0.15 against
    // 0.64-0.74), and flags a rigid object swaying at one frequency (T2
    // over 1500, Q over 33).
    let dir = d.path();
    let o = run_in(dir, &["learn", "fit", "ds/DATASET.toml", "-o", "m.json"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let dataset = std::fs::read_to_string(dir.join("ds/DATASET.toml")).unwrap();
    let roi = dataset
        .split("roi = \"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .unwrap();
    let o = run_in(
        dir,
        &[
            "learn",
            "predict",
            "m.json",
            "ds/scenes/m000-AL-0.toml",
            "--roi",
            roi,
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(!stdout(&o).contains("OUTSIDE"), "{}", stdout(&o));
    write(
        dir,
        "tone.toml",
        "width = 128\nheight = 128\nfps = 40.0\nduration_s = 60.0\nseed = 9\n\
         amplitude_px = 0.3\nsignal = { type = \"tone\", freq_hz = 7.0 }\n",
    );
    let o = run_in(dir, &["learn", "predict", "m.json", "tone.toml"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let flagged = stdout(&o);
    assert_eq!(
        flagged.matches("OUTSIDE the training distribution").count(),
        2,
        "{flagged}"
    );
}

/// Thesis ch. 3: the motion spectrum is a property of the object, not of
/// the view. Features of one fabric from two viewpoints correlate more
/// than features of two fabrics from one viewpoint (averaged over pairs).
#[test]
fn features_are_more_alike_across_views_than_across_fabrics() {
    let d = tempfile::tempdir().unwrap();
    let small = [
        "--per-condition",
        "2",
        "--seconds",
        "20",
        "--size",
        "64",
        "--segments",
        "4",
    ];
    generate(d.path(), "6", "A/L,A/R", &small);
    let ds = vibroscope::learn::Dataset::load(&d.path().join("ds/DATASET.toml")).unwrap();
    let f = ds.features(Default::default(), &mut |_, _, _| {}).unwrap();
    let pick = |obj: &str, cond: &str| -> Vec<f64> {
        let i = ds
            .video
            .iter()
            .position(|e| e.object == obj && e.condition == cond)
            .unwrap();
        f[i].features.clone()
    };
    let objs: Vec<String> = (0..6).map(|i| format!("m{i:03}")).collect();
    let same: f64 = objs
        .iter()
        .map(|o| pearson(&pick(o, "A/L"), &pick(o, "A/R")))
        .sum::<f64>()
        / 6.0;
    let mut diff = 0.0;
    let mut n = 0.0;
    for a in 0..6 {
        for b in a + 1..6 {
            diff += pearson(&pick(&objs[a], "A/L"), &pick(&objs[b], "A/L"));
            n += 1.0;
        }
    }
    let diff = diff / n;
    println!("same fabric, two views: {same:.3}; two fabrics, one view: {diff:.3}");
    assert!(same > diff, "{same} <= {diff}");
}

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).unwrap();
}

/// A dataset of three tiny videos (rendered once), as TOML entries.
fn tiny(dir: &Path) -> String {
    let mut s = String::from("version = 1\n");
    for i in 0..3 {
        write(
            dir,
            &format!("s{i}.toml"),
            &format!(
                "width = 32\nheight = 32\nfps = 40.0\nduration_s = 3.0\nseed = {}\n\
                 fabric = {{ stiffness_nm = 1e-5, area_weight_kg_m2 = 0.{} }}\n",
                i + 1,
                i + 1
            ),
        );
        let o = run_in(
            dir,
            &[
                "simulate",
                &format!("s{i}.toml"),
                "-o",
                &format!("v{i}.y4m"),
            ],
        );
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        s.push_str(&format!(
            "[[video]]\npath = \"v{i}.y4m\"\nobject = \"o{i}\"\ncondition = \"A/L\"\n\
             properties = {{ stiffness_nm = 1e-5, area_weight_kg_m2 = 0.{} }}\n",
            i + 1
        ));
    }
    s
}

/// `vibroscope ARGS` exits 2, without a panic, with every one of
/// `needles` in its message.
fn refused(dir: &Path, args: &[&str], needles: &[&str]) {
    let o = run_in(dir, args);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    let e = stderr(&o);
    assert!(needles.iter().all(|n| e.contains(n)), "{e}");
    assert!(!e.contains("panicked"), "{e}");
}

/// `learn fit DATASET -o m2.json [MORE]` is [`refused`] and writes no model.
fn fit_refused(dir: &Path, dataset: &str, more: &[&str], needles: &[&str]) {
    let mut args = vec!["learn", "fit", dataset, "-o", "m2.json"];
    args.extend_from_slice(more);
    refused(dir, &args, needles);
    assert!(!dir.join("m2.json").exists());
}

/// Bad input: a clear message naming the entry, exit 2, no panic.
#[test]
fn bad_datasets_and_models_are_refused_by_name() {
    let d = tempfile::tempdir().unwrap();
    let dir = d.path();
    let good = tiny(dir);

    write(dir, "missing.toml", &good.replace("v1.y4m", "nothere.y4m"));
    fit_refused(dir, "missing.toml", &[], &["video[1]", "nothere.y4m"]);

    write(
        dir,
        "zero.toml",
        &good.replace("area_weight_kg_m2 = 0.3", "area_weight_kg_m2 = 0.0"),
    );
    fit_refused(dir, "zero.toml", &[], &["video[2]", "area_weight_kg_m2"]);

    write(dir, "few.toml", &good);
    fit_refused(
        dir,
        "few.toml",
        &["--components", "2"],
        &["3 objects for 2 components"],
    );

    // A model of another version.
    let o = run_in(
        dir,
        &[
            "learn",
            "fit",
            "few.toml",
            "-o",
            "m.json",
            "--components",
            "1",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("m.json")).unwrap();
    write(
        dir,
        "old.json",
        &text.replacen("\"version\": 2", "\"version\": 0", 1),
    );
    refused(
        dir,
        &["learn", "predict", "old.json", "v0.y4m"],
        &["old.json", "version 0"],
    );
    // The current model predicts, with an interval; from the scene file
    // (rendered in memory) exactly as from the video it renders to.
    let o = run_in(dir, &["learn", "predict", "m.json", "v0.y4m"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(stdout(&o).contains("95% interval"), "{}", stdout(&o));
    let o2 = run_in(dir, &["learn", "predict", "m.json", "s0.toml"]);
    assert_eq!(code(&o2), 0, "{}", stderr(&o2));
    assert_eq!(
        stdout(&o2).replace("s0.toml", "v0.y4m"),
        stdout(&o),
        "{}",
        stdout(&o2)
    );

    // A region that parses but does not fit the frame (32 x 32).
    let outside = good.replacen(
        "condition = \"A/L\"",
        "condition = \"A/L\"\nroi = \"30,0,8,8\"",
        1,
    );
    write(dir, "outside.toml", &outside);
    fit_refused(
        dir,
        "outside.toml",
        &[],
        &["video[0]", "v0.y4m", "30,0,8,8", "32 x 32"],
    );

    // `evaluate` and `fit` measure only the conditions they are asked: an entry of
    // another condition whose video is no video is left alone, and is
    // named once it is asked for.
    write(dir, "junk.y4m", "not a video");
    let other = format!(
        "{good}[[video]]\npath = \"junk.y4m\"\nobject = \"o9\"\ncondition = \"S/R\"\n\
         properties = {{ stiffness_nm = 1e-5, area_weight_kg_m2 = 0.5 }}\n"
    );
    write(dir, "other.toml", &other);
    let asked = |test_on: &str| {
        let args = [
            "learn",
            "evaluate",
            "other.toml",
            "--train-on",
            "A/L",
            "--test-on",
            test_on,
        ];
        run_in(dir, &args)
    };
    let o = asked("A/L");
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(stdout(&o).contains("3 test videos"), "{}", stdout(&o));
    let o = run_in(
        dir,
        &[
            "learn",
            "fit",
            "other.toml",
            "--condition",
            "A/L",
            "-o",
            "m3.json",
            "--components",
            "1",
        ],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    assert!(dir.join("m3.json").exists());
    let o = asked("S/R");
    assert_ne!(code(&o), 0, "{}", stdout(&o));
    assert!(stderr(&o).contains("junk.y4m"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    // An entry is named by its place in the file, also after the
    // conditions not asked are left out (video[3], not the third A/L).
    let junk_first = format!(
        "version = 1\n[[video]]\npath = \"junk.y4m\"\nobject = \"o9\"\ncondition = \"S/R\"\n\
         properties = {{ stiffness_nm = 1e-5, area_weight_kg_m2 = 0.5 }}\n{}",
        good.trim_start_matches("version = 1\n").replace(
            "path = \"v2.y4m\"",
            "path = \"v2.y4m\"\nroi = \"0,20,8,16\"",
        )
    );
    write(dir, "shifted.toml", &junk_first);
    refused(
        dir,
        &[
            "learn",
            "evaluate",
            "shifted.toml",
            "--train-on",
            "A/L",
            "--test-on",
            "A/L",
        ],
        &["video[3]", "v2.y4m", "0,20,8,16", "32 x 32"],
    );

    // Scene entries: one of `path` and `scene`, the scene must exist, and
    // a mistake in it is told against the scene file and its key.
    let scenes = good
        .replace("path = \"v", "scene = \"s")
        .replace(".y4m", ".toml");
    let both = good.replacen(
        "path = \"v0.y4m\"",
        "path = \"v0.y4m\"\nscene = \"s0.toml\"",
        1,
    );
    write(dir, "both.toml", &both);
    fit_refused(dir, "both.toml", &[], &["video[0]", "not both"]);
    write(dir, "gone.toml", &scenes.replace("s2.toml", "s9.toml"));
    fit_refused(
        dir,
        "gone.toml",
        &[],
        &["video[2]", "scene file", "s9.toml"],
    );
    let rate = scenes.replacen("condition = \"A/L\"", "condition = \"A/L\"\nfps = 30.0", 1);
    write(dir, "rate.toml", &rate);
    fit_refused(
        dir,
        "rate.toml",
        &[],
        &["video[0]", "fps = 30", "its own `fps`"],
    );
    refused(
        dir,
        &["learn", "predict", "m.json", "s0.toml", "--fps", "30"],
        &["its own `fps`"],
    );
    let bad = std::fs::read_to_string(dir.join("s1.toml")).unwrap();
    write(dir, "s1.toml", &bad.replace("fps = 40.0", "fps = -40.0"));
    write(dir, "scenes.toml", &scenes);
    fit_refused(dir, "scenes.toml", &[], &["s1.toml:3", "field `fps`"]);

    // The bound needs the scene each video was rendered from.
    refused(
        dir,
        &["learn", "evaluate", "few.toml", "--exact"],
        &["video[0]", "scenes", "--exact"],
    );
    refused(
        dir,
        &["learn", "evaluate", "few.toml", "--true-motion"],
        &["video[0]", "scenes", "--true-motion"],
    );
    refused(
        dir,
        &["learn", "evaluate", "few.toml", "--exact", "--true-motion"],
        &["--true-motion", "--exact"],
    );

    // The generator's sound: a kick level out of range; a scene's kick
    // that would start after the forcing repeats.
    refused(
        dir,
        &["learn", "generate", "-o", "g", "--kick-db", "99"],
        &["--kick-db", "99"],
    );
    assert!(!dir.join("g").exists());
    let kick = std::fs::read_to_string(dir.join("s2.toml"))
        .unwrap()
        .replace(
            "fabric = {",
            "fabric = { excitation = \"kick\", kick_at_s = 49.5,",
        );
    write(dir, "s2.toml", &kick);
    write(dir, "s1.toml", &bad);
    fit_refused(dir, "scenes.toml", &[], &["s2.toml", "kick_at_s"]);
}
