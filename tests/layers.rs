//! The workspace's layering, checked (issue 13): crates depend only on
//! crates below them, the binary only on the recipes, and no two modules of
//! a crate import each other through a circle.
//!
//!     cargo test --release --test layers -- --nocapture
//!
//! prints the crate graph and each crate's module-import graph summary.
//!
//! Layers, bottom first: `vibroscope-math` (no threads, no I/O), then
//! `vibroscope-io`, `vibroscope-sim`, `vibroscope-core` (the engine's
//! runtime: no stage kinds, no device drivers), `vibroscope-engine` (the
//! kinds on computation and files), `vibroscope-devices` (the kinds on
//! live devices), `vibroscope-net` (the kinds on the network), `vibroscope`
//! (typed recipes, which assemble the registry), `vibroscope-studio` (the web application), `vibroscope-cli` (the binary). A new crate must be
//! placed in [`LAYERS`].
//!
//! A module import is any path `crate::…`, `super::…`, `self::…` (in a
//! `use` or inline) that names another module of the same crate. A module
//! and its own submodules are one unit here (a parent registering its
//! children and the children using the parent's helpers is not a circle);
//! every other circle fails the test, naming the modules on it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Workspace crates, bottom layer first.
const LAYERS: &[&str] = &[
    "vibroscope-math",
    "vibroscope-io",
    "vibroscope-sim",
    "vibroscope-core",
    "vibroscope-engine",
    "vibroscope-devices",
    "vibroscope-net",
    "vibroscope",
    "vibroscope-studio",
    "vibroscope-python",
    "vibroscope-cli",
];

/// The binary may depend on the recipes and on the studio (a server over them) only.
const BINARY: &str = "vibroscope-cli";
const RECIPES: &str = "vibroscope";
const STUDIO: &str = "vibroscope-studio";

struct Package {
    name: String,
    /// Workspace crates it depends on (normal, dev and build), with the kind.
    deps: Vec<(String, String)>,
    /// `src/lib.rs` or `src/main.rs` directory.
    src: PathBuf,
    roots: Vec<PathBuf>,
}

/// The package's directory, read when the test runs (cargo sets it and
/// runs tests there), not compiled in: a build at another path stays
/// reusable.
fn manifest_dir() -> PathBuf {
    std::env::var_os("CARGO_MANIFEST_DIR").map_or_else(
        || std::env::current_dir().unwrap_or_default(),
        std::path::PathBuf::from,
    )
}

/// What `cargo ARGS` prints, run in the workspace (a failure panics with
/// its message).
fn cargo(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO"))
        .args(args)
        .current_dir(manifest_dir())
        .output()
        .unwrap_or_else(|e| panic!("run cargo {}: {e}", args.join(" ")));
    assert!(
        out.status.success(),
        "cargo {} failed: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn metadata() -> Vec<Package> {
    let out = cargo(&[
        "metadata",
        "--format-version",
        "1",
        "--no-deps",
        "--offline",
    ]);
    let doc: serde_json::Value = serde_json::from_str(&out).expect("metadata JSON");
    let members: BTreeSet<String> = doc["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .map(|p| p["name"].as_str().expect("name").to_string())
        .collect();
    doc["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .map(|p| {
            let name = p["name"].as_str().expect("name").to_string();
            let deps = p["dependencies"]
                .as_array()
                .expect("dependencies")
                .iter()
                .filter_map(|d| {
                    let n = d["name"].as_str()?.to_string();
                    let kind = d["kind"].as_str().unwrap_or("normal").to_string();
                    members.contains(&n).then_some((n, kind))
                })
                .collect();
            let manifest = PathBuf::from(p["manifest_path"].as_str().expect("manifest"));
            let dir = manifest.parent().expect("manifest dir").to_path_buf();
            let roots: Vec<PathBuf> = p["targets"]
                .as_array()
                .expect("targets")
                .iter()
                .filter(|t| {
                    t["kind"]
                        .as_array()
                        .is_some_and(|k| k.iter().any(|k| k == "lib" || k == "bin"))
                })
                .map(|t| PathBuf::from(t["src_path"].as_str().expect("src_path")))
                .collect();
            Package {
                name,
                deps,
                src: dir.join("src"),
                roots,
            }
        })
        .collect()
}

#[test]
fn crates_depend_only_on_crates_below_them() {
    let pkgs = metadata();
    let layer = |n: &str| LAYERS.iter().position(|l| *l == n);
    let mut bad = Vec::new();
    for p in &pkgs {
        let Some(me) = layer(&p.name) else {
            bad.push(format!(
                "{} is not placed in the layer list (tests/layers.rs)",
                p.name
            ));
            continue;
        };
        let mut below = Vec::new();
        for (d, kind) in &p.deps {
            match layer(d) {
                Some(l) if l < me => below.push(d.as_str()),
                Some(_) => bad.push(format!(
                    "{} ({kind}) depends on {d}, which is not below it",
                    p.name
                )),
                None => bad.push(format!("{} depends on {d}, which is not placed", p.name)),
            }
            // The narrow faces (issue 49): the binary's code reaches the
            // layers only through the recipes (and the studio over them),
            // the studio's only through the recipes. Their tests and
            // benchmarks (dev-dependencies) may check the layers directly.
            if kind == "normal" && p.name == BINARY && d != RECIPES && d != STUDIO {
                bad.push(format!(
                    "the binary depends on {d}; it may use only the recipes ({RECIPES}) and {STUDIO}"
                ));
            }
            if kind == "normal" && p.name == STUDIO && d != RECIPES {
                bad.push(format!(
                    "the studio depends on {d}; it may use only the recipes ({RECIPES})"
                ));
            }
        }
        below.sort_unstable();
        below.dedup();
        println!("{:<18} (layer {me}) -> {}", p.name, below.join(", "));
    }
    assert!(bad.is_empty(), "layering broken:\n  {}", bad.join("\n  "));
    for l in LAYERS {
        assert!(
            pkgs.iter().any(|p| p.name == *l),
            "{l} is in the layer list but not in the workspace"
        );
    }
}

/// A crate's modules: module path (`a::b`) -> file.
fn modules(root: &Path, src: &Path) -> BTreeMap<String, PathBuf> {
    let mut m = BTreeMap::new();
    m.insert(String::new(), root.to_path_buf());
    let mut stack = vec![(String::new(), root.to_path_buf())];
    while let Some((path, file)) = stack.pop() {
        let text = std::fs::read_to_string(&file).expect("read module");
        let dir = if path.is_empty() {
            src.to_path_buf()
        } else if file.file_name().is_some_and(|f| f == "mod.rs") {
            file.parent().expect("dir").to_path_buf()
        } else {
            file.with_extension("")
        };
        let code = strip(&text);
        for line in code.lines() {
            let t = line.trim();
            let t = t
                .strip_prefix("pub(crate) ")
                .or_else(|| t.strip_prefix("pub "))
                .unwrap_or(t);
            let Some(rest) = t.strip_prefix("mod ") else {
                continue;
            };
            let Some(name) = rest.strip_suffix(';') else {
                continue; // inline module: part of this file
            };
            let name = name.trim();
            let child = if path.is_empty() {
                name.to_string()
            } else {
                format!("{path}::{name}")
            };
            let a = dir.join(format!("{name}.rs"));
            let b = dir.join(name).join("mod.rs");
            let f = if a.exists() { a } else { b };
            if f.exists() {
                m.insert(child.clone(), f.clone());
                stack.push((child, f));
            }
        }
    }
    m
}

/// Code without comments and string literals (doc links are not imports).
fn strip(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = String::with_capacity(s.len());
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            i += 2;
            while i < b.len() && !b[i..].starts_with(b"*/") {
                i += 1;
            }
            i += 2;
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
        } else if b[i] == b'\'' && i + 2 < b.len() && (b[i + 2] == b'\'' || b[i + 1] == b'\\') {
            // a char literal ('"', '\n'); lifetimes fall through
            i += 1;
            while i < b.len() && b[i] != b'\'' {
                if b[i] == b'\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
        } else {
            out.push(b[i] as char);
            i += 1;
        }
    }
    out
}

/// Every path a piece of code names: `use` trees expanded, and inline
/// `crate::`/`super::`/`self::` paths.
fn paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let toks = tokens(code);
    let mut i = 0;
    while i < toks.len() {
        if toks[i] == "use" {
            let end = toks[i..]
                .iter()
                .position(|t| t == ";")
                .map_or(toks.len(), |p| i + p);
            let mut j = i + 1;
            use_tree(&toks[..end], &mut j, Vec::new(), &mut out);
            i = end + 1;
        } else if matches!(toks[i].as_str(), "crate" | "super" | "self")
            && toks.get(i + 1).is_some_and(|t| t == "::")
        {
            let mut p = vec![toks[i].clone()];
            let mut j = i + 1;
            while toks.get(j).is_some_and(|t| t == "::")
                && toks.get(j + 1).is_some_and(|t| is_ident(t))
            {
                p.push(toks[j + 1].clone());
                j += 2;
            }
            out.push(p);
            i = j;
        } else {
            i += 1;
        }
    }
    out
}

fn is_ident(t: &str) -> bool {
    t.chars()
        .next()
        .is_some_and(|c| c.is_alphabetic() || c == '_')
}

fn tokens(code: &str) -> Vec<String> {
    let mut t = Vec::new();
    let c: Vec<char> = code.chars().collect();
    let mut i = 0;
    while i < c.len() {
        if c[i].is_alphanumeric() || c[i] == '_' {
            let s = i;
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            t.push(c[s..i].iter().collect());
        } else if c[i] == ':' && c.get(i + 1) == Some(&':') {
            t.push("::".into());
            i += 2;
        } else if c[i].is_whitespace() {
            i += 1;
        } else {
            t.push(c[i].to_string());
            i += 1;
        }
    }
    t
}

/// Expands one use tree starting at `toks[*j]` with `prefix`.
fn use_tree(toks: &[String], j: &mut usize, mut prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
    while *j < toks.len() {
        let t = &toks[*j];
        if t == "{" {
            *j += 1;
            loop {
                use_tree(toks, j, prefix.clone(), out);
                match toks.get(*j).map(String::as_str) {
                    Some(",") => *j += 1,
                    Some("}") => {
                        *j += 1;
                        return;
                    }
                    _ => return,
                }
                if toks.get(*j).is_some_and(|t| t == "}") {
                    *j += 1;
                    return;
                }
            }
        } else if t == "::" {
            *j += 1;
        } else if t == "as" {
            *j += 2;
        } else if t == "," || t == "}" {
            break;
        } else if is_ident(t) || t == "*" {
            if t != "*" {
                prefix.push(t.clone());
            }
            *j += 1;
        } else {
            *j += 1;
        }
    }
    if !prefix.is_empty() {
        out.push(prefix);
    }
}

/// The module (of `mods`) a path names, from module `me`.
fn resolve(me: &str, p: &[String], mods: &BTreeMap<String, PathBuf>) -> Option<String> {
    let mut base: Vec<String> = if me.is_empty() {
        Vec::new()
    } else {
        me.split("::").map(String::from).collect()
    };
    let mut rest = p;
    match p.first().map(String::as_str) {
        Some("crate") => {
            base.clear();
            rest = &p[1..];
        }
        Some("self") => rest = &p[1..],
        Some("super") => {
            while rest.first().is_some_and(|s| s == "super") {
                base.pop();
                rest = &rest[1..];
            }
        }
        Some(first) => {
            // a child module named without a prefix
            let mut c = base.clone();
            c.push(first.to_string());
            if !mods.contains_key(&c.join("::")) {
                return None;
            }
        }
        None => return None,
    }
    let mut best = None;
    let mut cur = base;
    if mods.contains_key(&cur.join("::")) {
        best = Some(cur.join("::"));
    }
    for s in rest {
        cur.push(s.clone());
        let k = cur.join("::");
        if mods.contains_key(&k) {
            best = Some(k);
        } else {
            break;
        }
    }
    best
}

/// Where a `#[cfg(test)] mod …` starts, if the file has one.
fn test_module(code: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(i) = code[from..].find("#[cfg(test)]") {
        let at = from + i;
        let after = code[at + "#[cfg(test)]".len()..].trim_start();
        if after.starts_with("mod ") {
            return Some(at);
        }
        from = at + 1;
    }
    None
}

fn nested(a: &str, b: &str) -> bool {
    a.is_empty()
        || b.is_empty()
        || a == b
        || b.starts_with(&format!("{a}::"))
        || a.starts_with(&format!("{b}::"))
}

/// The imports between sibling modules that an import between their
/// descendants makes: `a::x::f -> a::y::g` is also `a::x -> a::y`, so two
/// folders whose files import each other's form a circle even when no two
/// files do. An import of a module's own ancestor or descendant adds none.
fn folder_edges(edges: &BTreeMap<String, BTreeSet<String>>) -> BTreeMap<String, BTreeSet<String>> {
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (from, tos) in edges {
        for to in tos {
            let (a, b): (Vec<&str>, Vec<&str>) =
                (from.split("::").collect(), to.split("::").collect());
            let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
            if common < a.len() && common < b.len() && !from.is_empty() && !to.is_empty() {
                out.entry(a[..=common].join("::"))
                    .or_default()
                    .insert(b[..=common].join("::"));
            }
        }
    }
    out
}

#[test]
fn the_checker_sees_a_circle_between_folders() {
    // No two files import each other, but the folders do.
    let mut e: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    e.entry("stages::sinks::modes".into())
        .or_default()
        .insert("stages::transform::roi".into());
    e.entry("stages::transform::resonances".into())
        .or_default()
        .insert("stages::sinks::peaks".into());
    assert!(circles(&e).is_empty());
    assert_eq!(
        circles(&folder_edges(&e)),
        vec![vec![
            "stages::sinks".to_string(),
            "stages::transform".into()
        ]]
    );
}

/// Circles in a directed graph (strongly connected components of size > 1).
fn circles(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    // Tarjan's algorithm, iterative enough for a few hundred modules.
    struct T<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<String, usize>,
        low: BTreeMap<String, usize>,
        on: BTreeSet<String>,
        stack: Vec<String>,
        n: usize,
        out: Vec<Vec<String>>,
    }
    fn visit(t: &mut T<'_>, v: &str) {
        t.index.insert(v.to_string(), t.n);
        t.low.insert(v.to_string(), t.n);
        t.n += 1;
        t.stack.push(v.to_string());
        t.on.insert(v.to_string());
        let next: Vec<String> = t
            .edges
            .get(v)
            .map(|s| s.iter().cloned().collect())
            .unwrap_or_default();
        for w in next {
            if !t.index.contains_key(&w) {
                visit(t, &w);
                let lw = t.low[&w];
                let lv = t.low[v];
                t.low.insert(v.to_string(), lv.min(lw));
            } else if t.on.contains(&w) {
                let iw = t.index[&w];
                let lv = t.low[v];
                t.low.insert(v.to_string(), lv.min(iw));
            }
        }
        if t.low[v] == t.index[v] {
            let mut c = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(&w);
                let done = w == v;
                c.push(w);
                if done {
                    break;
                }
            }
            if c.len() > 1 {
                c.sort();
                t.out.push(c);
            }
        }
    }
    let mut t = T {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        on: BTreeSet::new(),
        stack: Vec::new(),
        n: 0,
        out: Vec::new(),
    };
    let nodes: Vec<String> = edges.keys().cloned().collect();
    for v in nodes {
        if !t.index.contains_key(&v) {
            visit(&mut t, &v);
        }
    }
    t.out
}

/// The paths of a piece of code's `pub use` and `pub(…) use` items
/// (re-exports), `use` trees expanded.
fn reexport_paths(code: &str) -> Vec<Vec<String>> {
    let toks = tokens(code);
    let mut out = Vec::new();
    for i in 0..toks.len() {
        if toks[i] != "use" || i == 0 {
            continue;
        }
        let public = toks[i - 1] == "pub"
            || (toks[i - 1] == ")" && i >= 4 && toks[i - 4] == "pub" && toks[i - 3] == "(");
        if !public {
            continue;
        }
        let end = toks[i..]
            .iter()
            .position(|t| t == ";")
            .map_or(toks.len(), |p| i + p);
        let mut j = i + 1;
        use_tree(&toks[..end], &mut j, Vec::new(), &mut out);
    }
    out
}

/// The import edges between the modules of one crate (`codes`: module
/// path -> its code without comments, strings and test module). A path
/// that names an item one module re-exports from another (`pub use
/// fabric::Fabric` in the root, named as `super::Fabric`) is an import of
/// the module that defines it: a circle hidden behind a re-export is a
/// circle.
fn module_edges(
    codes: &BTreeMap<String, String>,
    mods: &BTreeMap<String, PathBuf>,
) -> BTreeMap<String, BTreeSet<String>> {
    // (module, name it re-exports) -> the module the name comes from
    let mut reexports: BTreeMap<(String, String), String> = BTreeMap::new();
    for (me, code) in codes {
        for path in reexport_paths(code) {
            let Some(name) = path.last().filter(|n| *n != "self") else {
                continue;
            };
            if let Some(target) = resolve(me, &path, mods) {
                if &target != me {
                    reexports.insert((me.clone(), name.clone()), target);
                }
            }
        }
    }
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (me, code) in codes {
        for path in paths(code) {
            let Some(mut target) = resolve(me, &path, mods) else {
                continue;
            };
            if !nested(me, &target) {
                edges.entry(me.clone()).or_default().insert(target.clone());
            }
            // Through re-exports, a few levels deep.
            for _ in 0..4 {
                let through = path
                    .iter()
                    .find_map(|seg| reexports.get(&(target.clone(), seg.clone())));
                let Some(t) = through.cloned() else { break };
                if !nested(me, &t) {
                    edges.entry(me.clone()).or_default().insert(t.clone());
                }
                target = t;
            }
        }
        edges.entry(me.clone()).or_default();
    }
    edges
}

#[test]
fn no_module_import_circle() {
    let mut found = Vec::new();
    for p in metadata() {
        for root in &p.roots {
            let mods = modules(root, &p.src);
            let codes: BTreeMap<String, String> = mods
                .iter()
                .map(|(me, file)| {
                    let code = strip(&std::fs::read_to_string(file).expect("read"));
                    // Test modules may reach anywhere; they are not part of the layering.
                    let code = match test_module(&code) {
                        Some(i) => code[..i].to_string(),
                        None => code,
                    };
                    (me.clone(), code)
                })
                .collect();
            let edges = module_edges(&codes, &mods);
            let n_edges: usize = edges.values().map(BTreeSet::len).sum();
            let mut cs = circles(&edges);
            // Folders too: `stages::transform` and `stages::sinks` must
            // not import each other through any of their files.
            cs.extend(circles(&folder_edges(&edges)));
            cs.sort();
            cs.dedup();
            println!(
                "{:<18} {:>3} modules, {:>3} imports between them, {} circle(s)",
                p.name,
                mods.len(),
                n_edges,
                cs.len()
            );
            for c in cs {
                found.push(format!("{}: {}", p.name, c.join(" <-> ")));
            }
        }
    }
    assert!(
        found.is_empty(),
        "module import circles:\n  {}",
        found.join("\n  ")
    );
}

#[test]
fn the_checker_sees_a_circle_behind_a_reexport() {
    // lib re-exports fabric's Fabric; scene names it through the root,
    // and fabric uses scene's constant: scene <-> fabric.
    let mods: BTreeMap<String, PathBuf> = ["", "scene", "fabric"]
        .iter()
        .map(|m| (m.to_string(), PathBuf::new()))
        .collect();
    let code = |c: &str| strip(c);
    let mut codes: BTreeMap<String, String> = BTreeMap::new();
    codes.insert(
        "".into(),
        code("pub mod fabric; pub mod scene; pub use fabric::{Fabric, Spec};"),
    );
    codes.insert("scene".into(), code("fn f(x: super::Fabric) {}"));
    codes.insert("fabric".into(), code("const S: f64 = super::scene::SIGMA;"));
    let e = module_edges(&codes, &mods);
    assert_eq!(
        circles(&e),
        vec![vec!["fabric".to_string(), "scene".into()]],
        "{e:?}"
    );
    // Without the constant's import, no circle.
    codes.insert("fabric".into(), code("const S: f64 = 2.0;"));
    assert!(circles(&module_edges(&codes, &mods)).is_empty());
}

#[test]
fn the_checker_sees_a_circle() {
    // The checker itself must be able to fail.
    let mut e: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    e.entry("a".into()).or_default().insert("b".into());
    e.entry("b".into()).or_default().insert("c".into());
    e.entry("c".into()).or_default().insert("a".into());
    e.entry("d".into()).or_default().insert("a".into());
    assert_eq!(
        circles(&e),
        vec![vec!["a".to_string(), "b".into(), "c".into()]]
    );
    let code = strip("use crate::{a::{self, X}, b::Y};\n// crate::c::z\nfn f() { super::d::g(); }");
    let ps = paths(&code);
    assert!(
        ps.contains(&vec!["crate".into(), "a".into(), "self".into()])
            || ps.contains(&vec!["crate".into(), "a".into()]),
        "{ps:?}"
    );
    assert!(
        ps.contains(&vec!["crate".into(), "b".into(), "Y".into()]),
        "{ps:?}"
    );
    assert!(
        ps.contains(&vec!["super".into(), "d".into(), "g".into()]),
        "{ps:?}"
    );
    assert!(!ps.iter().any(|p| p.contains(&"c".to_string())), "{ps:?}");
}

/// What a string-addressed parameter edit looks like in code above the
/// engine, where the API cannot express one any more (`set_param` and
/// `StageDecl`'s parameter list are the engine's own): a `--set`-style
/// literal `"stage.key=value"` handed to `apply_set` or to
/// `PipelineOptions::set`, a table of literal keys handed to the scene
/// reader, or a parameter built by hand. Returns the offending lines.
fn string_edits(code: &str) -> Vec<String> {
    let mut found = Vec::new();
    let stripped = strip(code);
    for word in ["set_param", "Param {", "Param{", "read_table"] {
        // As a word (not `RoiParam {`), and not an enum's variant
        // (`MagnifyError::Param {`): `config::Param {` is one.
        let hit = stripped.match_indices(word).any(|(i, _)| {
            let before = &stripped[..i];
            if before
                .chars()
                .next_back()
                .is_some_and(|c| c.is_alphanumeric() || c == '_')
            {
                return false;
            }
            match before.strip_suffix("::") {
                Some(path) => !path
                    .rsplit(|c: char| !(c.is_alphanumeric() || c == '_'))
                    .next()
                    .is_some_and(|seg| seg.starts_with(|c: char| c.is_ascii_uppercase())),
                None => true,
            }
        });
        if hit {
            found.push(format!("uses `{}`", word.trim_end_matches([' ', '{'])));
        }
    }
    for line in code.lines() {
        let t = line.trim_start();
        if t.starts_with("//") {
            continue;
        }
        // A literal STAGE.KEY=VALUE.
        let mut rest = line;
        while let Some(i) = rest.find('"') {
            let after = &rest[i + 1..];
            let Some(j) = after.find('"') else { break };
            let lit = &after[..j];
            if let Some((lhs, _)) = lit.split_once('=') {
                let parts: Vec<&str> = lhs.split('.').collect();
                let word = |w: &str| {
                    !w.is_empty()
                        && w.chars()
                            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
                };
                if parts.len() == 2 && parts.iter().all(|w| word(w)) {
                    found.push(format!("`{}`: a string-addressed edit", line.trim()));
                }
            }
            rest = &after[j + 1..];
        }
    }
    found
}

/// Issue 49: the recipes, the studio and the binary set a stage's
/// parameters only through the typed keys its kind declares
/// (`pipeline::set(&mut decl, MAG, MagnifyParams::factor, 5.0, ..)`); the
/// TOML reader (pipeline files, scene files, the user's own `--set`) is
/// the one place a parameter is named by a string. Test modules are
/// exempt (they check the readers' errors).
#[test]
fn parameters_are_set_only_through_typed_keys() {
    let root = manifest_dir();
    let root = root.as_path();
    let mut found = Vec::new();
    let mut files = 0;
    for dir in ["crates/vibroscope/src", "crates/studio/src", "src"] {
        let mut stack = vec![root.join(dir)];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).expect("read_dir").flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                    continue;
                }
                if p.extension().is_none_or(|x| x != "rs") {
                    continue;
                }
                let code = std::fs::read_to_string(&p).expect("read");
                let code = match test_module(&code) {
                    Some(i) => &code[..i],
                    None => &code[..],
                };
                files += 1;
                let rel = p.strip_prefix(root).unwrap_or(&p).display().to_string();
                for f in string_edits(code) {
                    // The scene file's reader is the TOML reader.
                    if rel == "crates/vibroscope/src/pipeline/mod.rs" && f == "uses `read_table`" {
                        continue;
                    }
                    found.push(format!("{rel}: {f}"));
                }
            }
        }
    }
    println!("{files} files of recipes, studio and binary: parameters set through typed keys only");
    assert!(
        files > 50,
        "only {files} files found under {}",
        root.display()
    );
    assert!(
        found.is_empty(),
        "string-addressed parameter edits:\n  {}",
        found.join("\n  ")
    );
}

#[test]
fn the_string_edit_checker_sees_one() {
    assert!(string_edits("pipeline::set(&mut d, MAG, MagnifyParams::factor, 5.0, o)?;").is_empty());
    assert_eq!(
        string_edits("apply_set(&mut d, \"mag.factor=5\")?;").len(),
        1
    );
    assert_eq!(
        string_edits("let o = PipelineOptions { set: vec![\"out.path=x.wav\".into()], ..d };")
            .len(),
        1
    );
    assert_eq!(string_edits("config::set_param(st, k, v, o);").len(), 1);
    assert_eq!(
        string_edits("let p = config::Param { key: k, value: v, origin: o };").len(),
        1
    );
    assert_eq!(
        string_edits("st.push(Param { key: k, value: v, origin: o });").len(),
        1
    );
    assert!(string_edits("fn param(&self) -> RoiParam { x }").is_empty());
    assert!(string_edits("MagnifyError::Param { field, message } => 1,").is_empty());
    assert!(string_edits("// \"a.b=c\" in a comment").is_empty());
    assert!(string_edits("format!(\"{k}={v}\")").is_empty());
}

/// Issue 49: the engine's core (runtime, configuration, typed parameters)
/// and the kinds on computation and files build without the device
/// drivers' and the network's crates; only the crates of the kinds that use
/// them (`vibroscope-devices`, `vibroscope-net`) pull them in. `cargo tree`
/// of their normal dependencies, printed.
#[test]
fn the_core_builds_without_device_or_network_crates() {
    let deps = |p: &str| {
        let tree = cargo(&[
            "tree",
            "-p",
            p,
            "-e",
            "normal",
            "--prefix",
            "none",
            "--offline",
        ]);
        let crates: BTreeSet<String> = tree
            .lines()
            .filter_map(|l| l.split_whitespace().next())
            .map(String::from)
            .collect();
        println!(
            "{p}: {} crates in its dependency tree: {}",
            crates.len(),
            crates.iter().cloned().collect::<Vec<_>>().join(" ")
        );
        assert!(crates.contains(p), "{tree}");
        crates
    };
    const HEAVY: &[&str] = &[
        "cpal",
        "v4l",
        "v4l2-sys-mit",
        "nokhwa",
        "zenoh",
        "alsa-sys",
        "bindgen",
    ];
    for light in ["vibroscope-core", "vibroscope-engine"] {
        let crates = deps(light);
        for heavy in HEAVY {
            assert!(!crates.contains(*heavy), "{light} depends on {heavy}");
        }
    }
    // The kinds on devices and the network do pull them in (the check can
    // fail), and each only its own.
    let devices = deps("vibroscope-devices");
    assert!(devices.contains("cpal") && !devices.contains("zenoh"));
    let net = deps("vibroscope-net");
    assert!(net.contains("zenoh") && !net.contains("cpal"));
}

/// Issue 49: the recipe crate's face is its recipes, their report types
/// and the few items it names on purpose (`files`, `live`, re-exports
/// beside the recipe that uses them); it re-exports no layer below whole
/// (`pub use vibroscope_math as math`, `pub use vibroscope_io::*`), so
/// the binary and the studio cannot reach past it. Returns the offending
/// lines.
fn whole_layer_reexports(code: &str) -> Vec<String> {
    let layers = [
        "vibroscope_math",
        "vibroscope_io",
        "vibroscope_sim",
        "vibroscope_core",
        "vibroscope_engine",
    ];
    let mut out = Vec::new();
    for path in reexport_paths(code) {
        let Some(first) = path.first() else { continue };
        let whole_crate = path.len() == 1 || path.last().is_some_and(|l| l == "*" || l == "self");
        let layer_module = path.len() == 2
            && matches!(first.as_str(), "crate" | "self")
            && matches!(path[1].as_str(), "math" | "io" | "sim" | "engine" | "core");
        if (layers.contains(&first.as_str()) && whole_crate) || layer_module {
            out.push(path.join("::"));
        }
    }
    out
}

#[test]
fn the_recipes_reexport_no_layer_whole() {
    let pkgs = metadata();
    let recipes = pkgs
        .iter()
        .find(|p| p.name == RECIPES)
        .expect("the recipe crate");
    let mut bad = Vec::new();
    for root in &recipes.roots {
        for (me, file) in modules(root, &recipes.src) {
            let code = strip(&std::fs::read_to_string(&file).expect("read"));
            for l in whole_layer_reexports(&code) {
                bad.push(format!("{} ({me}): pub use {l}", file.display()));
            }
        }
    }
    println!(
        "{RECIPES}: no layer below re-exported whole ({} found)",
        bad.len()
    );
    assert!(
        bad.is_empty(),
        "the recipes re-export a layer whole:\n  {}",
        bad.join("\n  ")
    );
    // The checker sees one, and lets a named item or a private alias pass.
    let seen = whole_layer_reexports(&strip(
        "pub use vibroscope_math as math;\npub use vibroscope_io::*;\npub use crate::engine;",
    ));
    assert_eq!(seen.len(), 3, "{seen:?}");
    let passed = whole_layer_reexports(&strip(
        "use vibroscope_math as math;\npub use vibroscope_io::atomic::write_atomic;\npub use crate::math::rod::Measured;",
    ));
    assert!(passed.is_empty(), "{passed:?}");
}
