//! The declarations of every registered kind, checked (they moved here
//! from `vibroscope-core`'s `spec` with the kinds).

#[cfg(test)]
mod tests {
    use crate::config::{parse, Params};
    use crate::spec::*;
    use crate::stages::REGISTRY;
    use toml::Value;

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
        for k in REGISTRY {
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
        let l = listing(REGISTRY);
        assert_eq!(l.lines().count(), REGISTRY.len());
        for k in REGISTRY {
            assert!(
                l.lines()
                    .any(|line| line.split_whitespace().next() == Some(k.name)),
                "{} missing: {l}",
                k.name
            );
        }
    }

    #[test]
    fn describe_shows_ports_and_params() {
        let d = crate::stages::kind("spectrum").unwrap().describe();
        assert!(d.contains("input:   in: samples | audio"), "{d}");
        assert!(d.contains("output:  out: spectrum"), "{d}");
        assert!(d.contains("sliding|whole"), "{d}");
        assert!(d.contains("samples"), "{d}");
    }

    #[test]
    fn checks_name_the_value() {
        let s = ParamSpec::new("fps", ParamType::Float, Def::Float(1.0))
            .above(0.0)
            .unit("Hz");
        assert_eq!(
            s.check(&Value::Float(0.0)).unwrap_err(),
            "must be > 0 Hz, got 0"
        );
        assert!(s.check(&Value::Float(f64::NAN)).is_err());
        assert!(s
            .check(&Value::String("x".into()))
            .unwrap_err()
            .contains("invalid type"));
        let c = ParamSpec::new("m", ParamType::Choice(&["a", "b"]), Def::Str("a"));
        assert_eq!(
            c.check(&Value::String("z".into())).unwrap_err(),
            "must be a or b, got `z`"
        );
    }
}
