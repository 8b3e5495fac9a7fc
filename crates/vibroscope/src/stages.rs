//! The registry: every stage kind this build knows, assembled from the
//! crates that hold them (issue 49): `vibroscope-engine` (computation and
//! files), `vibroscope-devices` (live cameras and the speaker) and, with
//! the `net` feature, `vibroscope-net` (zenoh). A pipeline is validated
//! and `vibroscope kinds` lists against [`registry`]; the recipes edit a
//! stage through the typed parameters in [`params`].

pub use vibroscope_engine::stages::{sinks, sources, transform};
use vibroscope_engine::KindSpec;

/// The typed parameters of the kinds the recipes edit, by struct name
/// (`MagnifyParams::factor`); the network's (`vibroscope_net::params`) no
/// recipe edits.
pub mod params {
    pub use vibroscope_devices::params::*;
    pub use vibroscope_engine::stages::params::*;
}

/// Every kind of this build: sources, then transforms, then sinks, each
/// group in its crates' order (computation and files, devices, network).
pub fn registry() -> &'static [KindSpec] {
    static REGISTRY: std::sync::OnceLock<Vec<KindSpec>> = std::sync::OnceLock::new();
    REGISTRY.get_or_init(|| {
        let crates: &[&[KindSpec]] = &[
            vibroscope_engine::stages::KINDS,
            vibroscope_devices::KINDS,
            #[cfg(feature = "net")]
            vibroscope_net::KINDS,
        ];
        let mut all: Vec<KindSpec> = crates.iter().flat_map(|c| c.iter().copied()).collect();
        // Stable: within a role, the crates' own order.
        all.sort_by_key(role);
        all
    })
}

/// 0 for a source, 1 for a transform, 2 for a sink.
fn role(k: &KindSpec) -> u8 {
    match (k.is_source(), k.output()) {
        (true, _) => 0,
        (false, vibroscope_engine::Output::None) => 2,
        _ => 1,
    }
}

/// Looks a kind up by name.
pub fn kind(name: &str) -> Option<&'static KindSpec> {
    registry().iter().find(|k| k.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use toml::Value;
    use vibroscope_engine::config::{parse, Params};
    use vibroscope_engine::spec::*;

    /// A value for a required parameter, for the defaults test; required
    /// floats grow with their position `i` (a band's `lo_hz` < `hi_hz`).
    fn sample(spec: &ParamSpec, i: usize) -> Value {
        match spec.ty {
            ParamType::Path => Value::String("/tmp/vibroscope-kinds-test/out.x".into()),
            ParamType::Str => Value::String("x".into()),
            ParamType::Bool => Value::Boolean(false),
            ParamType::Int => Value::Integer(match spec.range {
                Range::Int(lo, _) => lo,
                _ => 1,
            }),
            ParamType::Float => Value::Float(1.0 + i as f64),
            ParamType::Choice(c) => Value::String(c[0].into()),
            _ => Value::Array(Vec::new()),
        }
    }

    /// Every kind builds its plan from its declared defaults (required
    /// parameters given a value), and every declared default is itself
    /// within the declared range.
    #[test]
    fn declared_defaults_pass_validation() {
        for k in registry() {
            let mut text = format!("[[stage]]\nid = \"s\"\nkind = \"{}\"\n", k.name);
            for (i, p) in k.params.iter().enumerate() {
                if let Some(v) = p.default.value() {
                    assert!(
                        p.check(&v).is_ok(),
                        "{}.{}: default {v} fails",
                        k.name,
                        p.name
                    );
                    assert!(!p.doc.is_empty(), "{}.{} has no doc", k.name, p.name);
                }
                if p.default == Def::Required {
                    text.push_str(&format!("{} = {}\n", p.name, sample(p, i)));
                }
            }
            let decl = parse("t.toml", &text).unwrap();
            let params = Params {
                file: "t.toml",
                stage: &decl.stages[0],
            };
            if let Err(e) = (k.plan)(&params) {
                panic!("kind `{}` rejects its own defaults: {e}", k.name);
            }
            assert!(k.inputs.len() <= 1 && k.outputs.len() <= 1, "{}", k.name);
            let d = k.describe();
            for p in k.params {
                assert!(d.contains(p.name), "{}: {d}", k.name);
            }
        }
    }

    #[test]
    fn listing_names_every_kind() {
        let l = listing(registry());
        assert_eq!(l.lines().count(), registry().len());
        for k in registry() {
            assert!(
                l.lines()
                    .any(|line| line.split_whitespace().next() == Some(k.name)),
                "{} missing: {l}",
                k.name
            );
        }
    }

    /// Every shipped pipeline validates (kinds, declared parameters,
    /// ports) against the registry.
    #[test]
    fn shipped_pipelines_validate() {
        for s in vibroscope_engine::pipelines::SHIPPED {
            if cfg!(not(feature = "net")) && s.text.contains("kind = \"zenoh_") {
                eprintln!("skipping {}: built without the `net` feature", s.name);
                continue;
            }
            let decl =
                vibroscope_engine::config::parse(s.name, s.text).unwrap_or_else(|e| panic!("{e}"));
            if let Err(e) = vibroscope_engine::graph::validate(&decl, registry()) {
                panic!("{e}");
            }
        }
    }

    /// Each crate's kinds are in the registry once, by a name no other
    /// kind has, sources before transforms before sinks.
    #[test]
    fn the_registry_holds_every_crate_s_kinds_once() {
        let r = registry();
        let mut names: Vec<_> = r.iter().map(|k| k.name).collect();
        let n = names.len();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), n, "a kind name twice");
        for k in vibroscope_engine::stages::KINDS
            .iter()
            .chain(vibroscope_devices::KINDS)
        {
            assert!(kind(k.name).is_some(), "{} missing", k.name);
        }
        #[cfg(feature = "net")]
        for k in vibroscope_net::KINDS {
            assert!(kind(k.name).is_some(), "{} missing", k.name);
        }
        assert!(r.windows(2).all(|w| role(&w[0]) <= role(&w[1])));
    }
}
