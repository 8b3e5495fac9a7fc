//! Pipelines that ship inside the binary (the files under this crate's
//! `pipelines/`, which the repository's top-level `pipelines/` links to).
//! `vibroscope run NAME` runs one by name; `vibroscope pipelines` lists them.

/// A shipped pipeline: its name (file stem) and TOML text.
pub struct Shipped {
    pub name: &'static str,
    pub text: &'static str,
}

pub static SHIPPED: &[Shipped] = &[
    Shipped {
        name: "demo",
        text: include_str!("../pipelines/demo.toml"),
    },
    Shipped {
        name: "visual-microphone",
        text: include_str!("../pipelines/visual-microphone.toml"),
    },
    Shipped {
        name: "tile-microphone",
        text: include_str!("../pipelines/tile-microphone.toml"),
    },
    Shipped {
        name: "live-microphone",
        text: include_str!("../pipelines/live-microphone.toml"),
    },
    Shipped {
        name: "live-demo",
        text: include_str!("../pipelines/live-demo.toml"),
    },
    Shipped {
        name: "live-pitch",
        text: include_str!("../pipelines/live-pitch.toml"),
    },
    Shipped {
        name: "rolling-shutter",
        text: include_str!("../pipelines/rolling-shutter.toml"),
    },
    Shipped {
        name: "motion",
        text: include_str!("../pipelines/motion.toml"),
    },
    Shipped {
        name: "intensity",
        text: include_str!("../pipelines/intensity.toml"),
    },
    Shipped {
        name: "render",
        text: include_str!("../pipelines/render.toml"),
    },
    Shipped {
        name: "live-spectrum",
        text: include_str!("../pipelines/live-spectrum.toml"),
    },
    Shipped {
        name: "magnify",
        text: include_str!("../pipelines/magnify.toml"),
    },
    Shipped {
        name: "live-magnify",
        text: include_str!("../pipelines/live-magnify.toml"),
    },
    Shipped {
        name: "camera-node",
        text: include_str!("../pipelines/camera-node.toml"),
    },
    Shipped {
        name: "sim-node",
        text: include_str!("../pipelines/sim-node.toml"),
    },
    Shipped {
        name: "passthrough",
        text: include_str!("../pipelines/passthrough.toml"),
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

/// Declares the typed ids of a shipped pipeline's stages (one module per
/// pipeline, one constant per stage a recipe edits) and lists them for the
/// test that checks each against the file.
macro_rules! stage_ids {
    ($(
        $(#[$doc:meta])*
        $module:ident = $pipeline:literal {
            $($name:ident: $params:ty = $id:literal),* $(,)?
        }
    )*) => {
        $(
            $(#[$doc])*
            pub mod $module {
                #[allow(unused_imports)]
                use crate::stages::params::*;
                use crate::spec::StageId;
                /// The shipped pipeline's name.
                pub const PIPELINE: &str = $pipeline;
                $(
                    #[doc = concat!("Stage `", $id, "` of `", $pipeline, "`.")]
                    pub const $name: StageId<$params> = StageId::new($id);
                )*
            }
        )*
        /// Every typed id: (pipeline, stage id, the kinds its parameters fit).
        pub fn typed_ids() -> Vec<(&'static str, &'static str, &'static [&'static str])> {
            #[allow(unused_imports)]
            use crate::spec::KindParams;
            #[allow(unused_imports)]
            use crate::stages::params::*;
            vec![$($(($pipeline, $id, <$params as KindParams>::KINDS)),*),*]
        }
    };
}

/// The stages of the shipped pipelines that recipes edit, as typed ids: a
/// recipe sets `magnify::MAG`'s `MagnifyParams::factor`, and the compiler
/// checks that the parameter exists, belongs to that kind and takes that
/// type; `typed_ids_match_the_files` checks each id and kind against the
/// TOML file.
pub mod stage {
    stage_ids! {
        magnify = "magnify" {
            MAG: MagnifyParams = "mag",
            OUT: Y4mParams = "out",
        }
        visual_microphone = "visual-microphone" {
            PHASE: PhaseParams = "phase",
            ALIGN: AlignParams = "align",
            HIGHPASS: HighpassParams = "highpass",
            OUT: WavParams = "out",
        }
        tile_microphone = "tile-microphone" {
            MOTION: TileMotionParams = "motion",
            ALIGN: AlignParams = "align",
            HIGHPASS: HighpassParams = "highpass",
            OUT: WavParams = "out",
        }
        live_microphone = "live-microphone" {
            PHASE: PhaseParams = "phase",
            ALIGN: AlignParams = "align",
            HIGHPASS: HighpassParams = "highpass",
            OUT: WavParams = "out",
        }
        rolling_shutter = "rolling-shutter" {
            ROWS: RowsParams = "rows",
            FILL: GapFillParams = "fill",
            EXPOSURE: ExposureParams = "exposure",
            OUT: WavParams = "out",
        }
        live_spectrum = "live-spectrum" {
            PHASE: PhaseParams = "phase",
            SPECTRUM: SpectrumParams = "spectrum",
            OUT: PeaksParams = "out",
        }
        render = "render" {
            OUT: Y4mParams = "out",
        }
        demo = "demo" {
            MOTION: GradientMotionParams = "motion",
            OUT: WavParams = "out",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each typed stage id names a stage of its pipeline whose kind takes
    /// the id's parameters.
    #[test]
    fn typed_ids_match_the_files() {
        let ids = stage::typed_ids();
        assert!(ids.len() >= 20, "{} typed ids", ids.len());
        for (pipeline, id, kinds) in ids {
            let s = find(pipeline).unwrap_or_else(|| panic!("no shipped pipeline {pipeline}"));
            let decl = crate::config::parse(s.name, s.text).unwrap_or_else(|e| panic!("{e}"));
            let st = decl
                .stages
                .iter()
                .find(|st| st.id == id)
                .unwrap_or_else(|| panic!("{pipeline} has no stage `{id}`"));
            assert!(
                kinds.contains(&st.kind.as_str()),
                "{pipeline}: stage `{id}` is a `{}`, its typed id says {kinds:?}",
                st.kind
            );
        }
    }

    /// Every file under `pipelines/` is shipped and parses. That each one
    /// validates against the whole registry (kinds, declared parameters,
    /// ports; devices and network included) is tested where the registry
    /// is assembled: the recipes' `stages`.
    #[test]
    fn every_pipeline_file_is_shipped_and_parses() {
        // Read when the test runs (cargo sets it), not compiled in.
        let dir = std::env::var_os("CARGO_MANIFEST_DIR")
            .map_or_else(
                || std::env::current_dir().unwrap_or_default(),
                std::path::PathBuf::from,
            )
            .join("pipelines");
        let files: Vec<_> = std::fs::read_dir(dir)
            .map(|d| d.filter_map(Result::ok).collect())
            .unwrap_or_default();
        assert_eq!(
            files.len(),
            SHIPPED.len(),
            "a file in pipelines/ is not shipped"
        );
        for s in SHIPPED {
            crate::config::parse(s.name, s.text).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}
