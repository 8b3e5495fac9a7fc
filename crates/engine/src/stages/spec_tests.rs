//! The declarations of every registered kind, checked (they moved here
//! from `vibroscope-core`'s `spec` with the kinds).

#[cfg(test)]
mod tests {
    use crate::spec::*;
    use toml::Value;

    // That every kind of the registry (this crate's, the devices', the
    // network's) builds its plan from its declared defaults and is listed
    // is tested where the registry is assembled: the recipes' `stages`.

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
