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
        name: "live-microphone",
        text: include_str!("../../../pipelines/live-microphone.toml"),
    },
    Shipped {
        name: "live-demo",
        text: include_str!("../../../pipelines/live-demo.toml"),
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
