//! `learn generate`: a dataset of hanging fabrics rendered by the forward
//! model ([`crate::sim::fabric`]): `materials` fabrics whose bending
//! rigidity (1e-6 to 1e-4 N·m) and area weight (30 to 400 g/m²) are spread
//! log-uniformly by a Latin hypercube (independent of each other), each
//! filmed `per_condition` times (new forcing and texture each time) under
//! each condition: excitation `A` (ambient air) or `S` (sound: by default
//! the thesis's one-second 15-100 Hz "kick" at `kick_db` over the ambient
//! forcing, which is present throughout; or a stationary chirp alone),
//! viewpoint `L` or `R` (different framing, crop of the cloth,
//! perspective, frame rate and noise). Writes `scenes/*.toml` and
//! `DATASET.toml`, whose entries are the scenes (rendered in memory when
//! their features are measured: the default dataset's 720 takes would be
//! 32 GB of Y4M), or with `videos` also `videos/*.y4m`, whose entries are
//! the videos, each with its region (`roi`, the cloth's rectangle, as a
//! user marks a real recording); then caches every take's features
//! (unless asked not to).

use super::{Dataset, Entry, DATASET_VERSION};
use crate::error::{Error, Result};
use crate::pipeline::{Roi, RunSettings};
use crate::sim::rng::{hash2, Xoshiro256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Bending rigidity range, N·m.
pub const STIFFNESS_NM: (f64, f64) = (1e-6, 1e-4);
/// Area weight range, kg/m².
pub const AREA_WEIGHT_KG_M2: (f64, f64) = (0.03, 0.4);
/// The four conditions.
pub const CONDITIONS: [&str; 4] = ["A/L", "A/R", "S/L", "S/R"];

/// What the `S` conditions play.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sound {
    /// The thesis's: ambient forcing throughout, plus a one-second
    /// logarithmic sweep from 15 to 100 Hz at a random time (`excitation =
    /// "kick"`).
    Kick,
    /// A stationary logarithmic chirp from 0.3 to 20 Hz alone (`excitation
    /// = "sound"`; the first datasets').
    Chirp,
}

/// The kick's start is drawn in this part of the take (so that a 60 s
/// take holds one kick and its ring-down, and not its repeat 50 s later).
pub const KICK_AT: (f64, f64) = (0.2, 0.55);

/// What `learn generate` is asked.
#[derive(Clone, Debug)]
pub struct GenerateOptions {
    pub dir: PathBuf,
    pub materials: usize,
    pub per_condition: usize,
    pub conditions: Vec<String>,
    pub seconds: f64,
    /// Frame side, px (the viewpoints scale with it).
    pub size: u32,
    pub seed: u64,
    /// Welch segments of each video's spectrum (written to the dataset's [features]).
    pub segments: usize,
    /// Also write each take as a Y4M (the entries are then the videos).
    pub videos: bool,
    /// What the `S` conditions play, and the kick's motion power over the
    /// ambient forcing's, dB.
    pub sound: Sound,
    pub kick_db: f64,
    /// Measure (and cache) every take's features now; otherwise `fit` or
    /// `evaluate` measure them when they first need them (`evaluate
    /// --exact` needs none).
    pub measure: bool,
    pub run: RunSettings,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        Self {
            dir: PathBuf::from("fabrics"),
            materials: 60,
            per_condition: 3,
            conditions: CONDITIONS.iter().map(|c| c.to_string()).collect(),
            seconds: 60.0,
            size: 128,
            seed: 1,
            segments: 16,
            videos: false,
            sound: Sound::Kick,
            kick_db: 0.0,
            measure: true,
            run: RunSettings::default(),
        }
    }
}

/// One viewpoint's camera. Both film sub-pixel motion (0.3 px, √2 x the
/// RMS over the cloth; the thesis's fabrics moved invisibly): at 1.2-1.5
/// px the finest scale's phase distorts and its harmonics of the low modes
/// fill the band where stiffness shows (stiffness R 0.47 against 0.54 with
/// the same features, `docs/learning.md`).
struct View {
    fps: f64,
    /// Object rectangle as fractions of the frame.
    object: [f64; 4],
    crop: [f64; 4],
    perspective: f64,
    noise: f64,
    amplitude: f64,
}

fn view(name: &str) -> View {
    match name {
        "R" => View {
            fps: 50.0,
            object: [0.19, 0.1, 0.62, 0.82],
            crop: [0.1, 0.15, 0.9, 1.0],
            perspective: -0.5,
            noise: 1.0,
            amplitude: 0.3,
        },
        _ => View {
            fps: 40.0,
            object: [0.06, 0.03, 0.88, 0.94],
            crop: [0.0, 0.0, 1.0, 1.0],
            perspective: 0.3,
            noise: 0.7,
            amplitude: 0.3,
        },
    }
}

/// The materials: (stiffness N·m, area weight kg/m²), Latin hypercube in logs.
pub fn materials(n: usize, seed: u64) -> Vec<(f64, f64)> {
    let mut rng = Xoshiro256::new(hash2(seed, 0x6d61_7465));
    let mut perm: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        perm.swap(i, j);
    }
    let lerp = |(a, b): (f64, f64), u: f64| (a.ln() + (b.ln() - a.ln()) * u).exp();
    (0..n)
        .map(|i| {
            let u = (i as f64 + rng.next_f64()) / n as f64;
            let v = (perm[i] as f64 + rng.next_f64()) / n as f64;
            (lerp(STIFFNESS_NM, u), lerp(AREA_WEIGHT_KG_M2, v))
        })
        .collect()
}

/// Writes the dataset; `progress(i, n, what)` before each video.
pub fn generate(
    o: &GenerateOptions,
    progress: &mut dyn FnMut(usize, usize, &Path),
) -> Result<PathBuf> {
    if o.materials < 3 || o.materials > 10_000 {
        return Err(Error::usage(
            "--materials",
            format!("must be 3..=10000, got {}", o.materials),
        ));
    }
    if o.per_condition == 0 || o.per_condition > 100 {
        return Err(Error::usage(
            "--per-condition",
            format!("must be 1..=100, got {}", o.per_condition),
        ));
    }
    if !(o.seconds.is_finite() && (2.0..=600.0).contains(&o.seconds)) {
        return Err(Error::usage(
            "--seconds",
            format!("must be 2..=600, got {}", o.seconds),
        ));
    }
    if !(32..=1024).contains(&o.size) {
        return Err(Error::usage(
            "--size",
            format!("must be 32..=1024, got {}", o.size),
        ));
    }
    // The fabric's own check of the level, before anything is written.
    crate::sim::FabricSpec {
        kick_db: o.kick_db,
        ..Default::default()
    }
    .validate()
    .map_err(|e| Error::usage("--kick-db", e.to_string()))?;
    for c in &o.conditions {
        if !CONDITIONS.contains(&c.as_str()) {
            return Err(Error::usage(
                "--conditions",
                format!("unknown condition {c:?}: one of {CONDITIONS:?}"),
            ));
        }
    }
    let mk = |p: &Path| {
        std::fs::create_dir_all(p).map_err(|e| Error::input(p, format!("cannot create: {e}")))
    };
    mk(&o.dir.join("scenes"))?;
    if o.videos {
        mk(&o.dir.join("videos"))?;
    }
    let mats = materials(o.materials, o.seed);
    let total = mats.len() * o.conditions.len() * o.per_condition;
    let mut entries = Vec::with_capacity(total);
    let mut k = 0;
    for (mi, &(b, rho)) in mats.iter().enumerate() {
        for cond in &o.conditions {
            let (exc, vp) = cond.split_once('/').unwrap_or(("A", "L"));
            let v = view(vp);
            for rep in 0..o.per_condition {
                let name = format!("m{mi:03}-{exc}{vp}-{rep}");
                let s = o.size as f64;
                let obj = v.object.map(|f| (f * s).round() as u32);
                let seed = hash2(o.seed, k as u64 + 1) >> 1;
                let excitation = match (exc, o.sound) {
                    ("S", Sound::Chirp) => "excitation = \"sound\"".to_string(),
                    ("S", Sound::Kick) => {
                        // Its start, from the take's seed: within KICK_AT
                        // of the take, and 2 s before the forcing repeats
                        // (every 50 s), so the 1 s sweep fits.
                        let latest = 1.0 / crate::sim::fabric::LINE_SPACING_HZ - 2.0;
                        let u = Xoshiro256::new(hash2(seed, 0x6b69_636b)).next_f64();
                        let d = o.seconds.min(latest / KICK_AT.1);
                        let at = d * (KICK_AT.0 + (KICK_AT.1 - KICK_AT.0) * u);
                        format!(
                            "excitation = \"kick\", kick_db = {:?}, kick_at_s = {at:.3}",
                            o.kick_db
                        )
                    }
                    _ => "excitation = \"ambient\"".to_string(),
                };
                let scene = format!(
                    "# fabric {mi}: B = {b:.4e} N m, rho_A = {rho:.4} kg/m^2, condition {cond}, take {rep}\n\
                     width = {w}\nheight = {w}\nfps = {fps}\nduration_s = {dur}\n\
                     object = [{}, {}, {}, {}]\nnoise_std = {noise}\nseed = {seed}\n\
                     signal = {{ type = \"tone\", freq_hz = 1.0 }}\n\
                     fabric = {{ stiffness_nm = {b:e}, area_weight_kg_m2 = {rho:e}, {excitation}, \
                     amplitude_px = {amp}, view = [{}, {}, {}, {}], perspective = {per} }}\n",
                    obj[0],
                    obj[1],
                    obj[2],
                    obj[3],
                    v.crop[0],
                    v.crop[1],
                    v.crop[2],
                    v.crop[3],
                    w = o.size,
                    fps = v.fps,
                    dur = o.seconds,
                    noise = v.noise,
                    amp = v.amplitude,
                    per = v.perspective,
                );
                let scene_rel = PathBuf::from("scenes").join(format!("{name}.toml"));
                let scene_path = o.dir.join(&scene_rel);
                crate::io::atomic::write_atomic(&scene_path, scene.as_bytes())?;
                let video = if o.videos {
                    let video = PathBuf::from("videos").join(format!("{name}.y4m"));
                    progress(k, total, &video);
                    crate::simulate::simulate(&crate::simulate::SimulateOptions {
                        scene: scene_path,
                        output: o.dir.join(&video),
                        set: Vec::new(),
                        run: o.run,
                    })?;
                    Some(video)
                } else {
                    None
                };
                entries.push(Entry {
                    scene: video.is_none().then_some(scene_rel),
                    path: video,
                    object: format!("m{mi:03}"),
                    condition: cond.clone(),
                    index: entries.len(),
                    fps: None,
                    // The cloth's rectangle, as a user marks the region
                    // of a real recording: the tiles then cut the cloth
                    // (as the bound's do), not the cloth and the wall
                    // beside it (A/R stiffness R 0.898 -> 0.929,
                    // docs/learning.md).
                    roi: Some(
                        Roi {
                            x: obj[0],
                            y: obj[1],
                            w: obj[2],
                            h: obj[3],
                        }
                        .to_string(),
                    ),
                    mask: None,
                    properties: BTreeMap::from([
                        ("area_weight_kg_m2".to_string(), rho),
                        ("stiffness_nm".to_string(), b),
                    ]),
                });
                k += 1;
            }
        }
    }
    let d = Dataset {
        version: DATASET_VERSION,
        features: super::FeatureParams {
            segments: Some(o.segments),
            subtract_floor: true,
            ..Default::default()
        },
        video: entries,
        dir: o.dir.clone(),
    };
    let path = o.dir.join("DATASET.toml");
    let text = toml::to_string(&d).map_err(|e| crate::error::Error::Document {
        path: path.clone(),
        message: format!("cannot encode the dataset: {e}"),
    })?;
    let head = format!(
        "# Generated by `vibroscope learn generate` (seed {}): {} fabrics x {:?} x {} takes, {} s each; sound: {}.\n",
        o.seed,
        o.materials,
        o.conditions,
        o.per_condition,
        o.seconds,
        match o.sound {
            Sound::Kick => format!("a 1 s 15-100 Hz kick at {} dB over ambient air", o.kick_db),
            Sound::Chirp => "a stationary 0.3-20 Hz chirp alone".to_string(),
        }
    );
    crate::io::atomic::write_atomic(&path, format!("{head}{text}").as_bytes())?;
    // Features now, so fit/evaluate read them from the cache.
    if o.measure {
        let d = Dataset::load(&path)?;
        d.features(o.run, progress)?;
    }
    Ok(path)
}
