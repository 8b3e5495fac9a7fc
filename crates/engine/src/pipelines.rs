//! Pipelines that ship inside the binary (the files under `pipelines/`).
//! `vibroscope run NAME` runs one by name; `vibroscope pipelines` lists them.

/// A shipped pipeline: its name (file stem) and TOML text.
pub struct Shipped {
    pub name: &'static str,
    pub text: &'static str,
}

pub static SHIPPED: &[Shipped] = &[
    Shipped {
        name: "demo",
        text: include_str!("../../../pipelines/demo.toml"),
    },
    Shipped {
        name: "visual-microphone",
        text: include_str!("../../../pipelines/visual-microphone.toml"),
    },
    Shipped {
        name: "tile-microphone",
        text: include_str!("../../../pipelines/tile-microphone.toml"),
    },
    Shipped {
        name: "live-microphone",
        text: include_str!("../../../pipelines/live-microphone.toml"),
    },
    Shipped {
        name: "live-demo",
        text: include_str!("../../../pipelines/live-demo.toml"),
    },
    Shipped {
        name: "live-pitch",
        text: include_str!("../../../pipelines/live-pitch.toml"),
    },
    Shipped {
        name: "rolling-shutter",
        text: include_str!("../../../pipelines/rolling-shutter.toml"),
    },
    Shipped {
        name: "motion",
        text: include_str!("../../../pipelines/motion.toml"),
    },
    Shipped {
        name: "intensity",
        text: include_str!("../../../pipelines/intensity.toml"),
    },
    Shipped {
        name: "render",
        text: include_str!("../../../pipelines/render.toml"),
    },
    Shipped {
        name: "live-spectrum",
        text: include_str!("../../../pipelines/live-spectrum.toml"),
    },
    Shipped {
        name: "magnify",
        text: include_str!("../../../pipelines/magnify.toml"),
    },
    Shipped {
        name: "live-magnify",
        text: include_str!("../../../pipelines/live-magnify.toml"),
    },
    Shipped {
        name: "camera-node",
        text: include_str!("../../../pipelines/camera-node.toml"),
    },
    Shipped {
        name: "sim-node",
        text: include_str!("../../../pipelines/sim-node.toml"),
    },
    Shipped {
        name: "passthrough",
        text: include_str!("../../../pipelines/passthrough.toml"),
    },
];

pub fn find(name: &str) -> Option<&'static Shipped> {
    SHIPPED.iter().find(|s| s.name == name)
}

/// The `description` of a shipped pipeline, for listings.
pub fn description(s: &Shipped) -> String {
    crate::config::parse(s.name, s.text)
        .map(|d| d.description)
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every file under `pipelines/` parses and validates (kinds, declared
    /// parameters, ports) against the registry.
    #[test]
    fn shipped_pipelines_validate() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../pipelines");
        let files: Vec<_> = std::fs::read_dir(dir)
            .map(|d| d.filter_map(Result::ok).collect())
            .unwrap_or_default();
        assert_eq!(
            files.len(),
            SHIPPED.len(),
            "a file in pipelines/ is not shipped"
        );
        for s in SHIPPED {
            if cfg!(not(feature = "net")) && s.text.contains("kind = \"zenoh_") {
                eprintln!("skipping {}: built without the `net` feature", s.name);
                continue;
            }
            let decl = crate::config::parse(s.name, s.text).unwrap_or_else(|e| panic!("{e}"));
            if let Err(e) = crate::graph::validate(&decl, crate::stages::REGISTRY) {
                panic!("{e}");
            }
        }
    }
}
