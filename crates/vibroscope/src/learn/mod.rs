//! Learning material properties from motion spectra (thesis 5.5): a
//! dataset of videos with known properties ([`Dataset`], a TOML file),
//! the feature vectors ([`features`]), PLSR / PCR models ([`model`]) fitted
//! with leave-one-object-out cross-validation, and the recipes
//! [`generate`] (a synthetic fabric dataset from the simulator), [`fit`],
//! [`predict`] and [`evaluate`] (Table 5.3's train/test conditions).
//!
//! Dataset file (paths relative to the file):
//!
//! ```toml
//! version = 1
//! [features]            # optional: 0-15 Hz, N = 150, thesis smoothing
//! min_hz = 0.0
//! max_hz = 15.0
//! n = 150
//! [[video]]
//! path = "videos/m00-A-L-0.y4m"  # or scene = "scenes/m00-A-L-0.toml": a
//!                       # scene file rendered in memory (`learn generate`)
//! object = "m00"        # all videos of one object are held out together
//! condition = "A/L"     # excitation/viewpoint label
//! fps = 40.0            # optional: the capture rate when the file lies (videos only)
//! properties = { stiffness_nm = 1.2e-5, area_weight_kg_m2 = 0.11 }
//! ```

pub mod features;
pub mod generate;
pub mod model;

use crate::error::{Error, Result};
use crate::pipeline::{Region, Roi, RunSettings};
use features::VideoFeatures;
pub use features::{FeatureParams, Normalise};
use model::{Distance, Linear, Method, Metrics};
use ndarray::Array2;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The dataset file's format version.
pub const DATASET_VERSION: u32 = 1;
/// The model file's format name and version.
pub const MODEL_FORMAT: &str = "vibroscope-learn-model";
/// Version 2: one model per property (version 1 fitted both jointly).
pub const MODEL_VERSION: u32 = 2;
/// The prediction interval's coverage (normal quantile 1.96: 95%).
pub const INTERVAL_Z: f64 = 1.96;

/// One video of a dataset: a recording (`path`) or a scene file
/// (`scene`) rendered in memory through the forward model, the frames
/// `vibroscope simulate` would write (one of the two).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Entry {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<PathBuf>,
    pub object: String,
    pub condition: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roi: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<PathBuf>,
    pub properties: BTreeMap<String, f64>,
    /// Its place in the dataset file (`video[index]` in messages, also
    /// once `evaluate` has left out the conditions it was not asked).
    #[serde(skip)]
    pub index: usize,
}

impl Entry {
    /// What the entry is measured from (as written, relative to the dataset).
    pub fn source(&self) -> features::Source<'_> {
        match (&self.path, &self.scene) {
            (Some(p), _) => features::Source::Video(p),
            (None, Some(s)) => features::Source::Scene(s),
            // Dataset::load refuses an entry with neither.
            (None, None) => features::Source::Video(Path::new("")),
        }
    }
}

/// A dataset file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Dataset {
    pub version: u32,
    #[serde(default)]
    pub features: FeatureParams,
    pub video: Vec<Entry>,
    /// The directory paths are relative to (not in the file).
    #[serde(skip)]
    pub dir: PathBuf,
}

/// When entry `i`'s measurement failed: a usage error naming the entry
/// if its `roi` does not fit its frame (the engine, which finds that
/// out once frames arrive, names neither), `None` otherwise.
fn roi_outside(i: usize, source: features::Source, fps: Option<f64>, r: Roi) -> Option<Error> {
    let (w, h) = match source {
        features::Source::Scene(p) => {
            let s = crate::pipeline::SceneFile::read(p).ok()?.synthetic().ok()?;
            (s.width, s.height)
        }
        features::Source::Video(p) => {
            let v = crate::probe::probe(p, fps).ok()?;
            (v.width, v.height)
        }
    };
    let fits = r.x.checked_add(r.w)? <= w && r.y.checked_add(r.h)? <= h;
    (!fits).then(|| {
        Error::input(
            source.path(),
            format!("video[{i}]: roi = \"{r}\" does not fit its {w} x {h} frame"),
        )
    })
}

impl Dataset {
    /// Reads and checks a dataset file: every entry's video exists, every
    /// property is > 0 and every entry has the same properties.
    pub fn load(path: &Path) -> Result<Dataset> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::input(path, format!("cannot read the dataset: {e}")))?;
        let mut d: Dataset = toml::from_str(&text)
            .map_err(|e| Error::input(path, format!("not a dataset file: {e}")))?;
        if d.version != DATASET_VERSION {
            return Err(Error::input(
                path,
                format!(
                    "dataset version {} (this vibroscope reads version {DATASET_VERSION})",
                    d.version
                ),
            ));
        }
        d.dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        d.features
            .validate(&format!("{} [features]", path.display()))?;
        if d.video.is_empty() {
            return Err(Error::input(path, "lists no [[video]]"));
        }
        for (i, e) in d.video.iter_mut().enumerate() {
            e.index = i;
        }
        let names: Vec<String> = d.video[0].properties.keys().cloned().collect();
        if names.is_empty() {
            return Err(Error::input(path, "video[0] has no properties"));
        }
        for (i, e) in d.video.iter().enumerate() {
            if e.path.is_some() == e.scene.is_some() {
                return Err(Error::input(
                    path,
                    format!(
                        "video[{i}]: needs `path` (a recording) or `scene` (a scene file), {}",
                        if e.path.is_some() {
                            "not both"
                        } else {
                            "and has neither"
                        }
                    ),
                ));
            }
            let at = format!("video[{i}] ({})", e.source().path().display());
            let keys: Vec<&String> = e.properties.keys().collect();
            if keys != names.iter().collect::<Vec<_>>() {
                return Err(Error::input(
                    path,
                    format!("{at}: properties {keys:?}, video[0] has {names:?}"),
                ));
            }
            for (k, v) in &e.properties {
                if !(v.is_finite() && *v > 0.0) {
                    return Err(Error::input(
                        path,
                        format!("{at}: property {k} = {v}: must be > 0 (its log is the target)"),
                    ));
                }
            }
            let p = d.resolve(e.source().path());
            if !p.is_file() {
                return Err(Error::input(
                    path,
                    format!(
                        "{at}: the {} {} does not exist",
                        e.source().noun(),
                        p.display()
                    ),
                ));
            }
            if let (features::Source::Scene(_), Some(f)) = (e.source(), e.fps) {
                return Err(Error::input(
                    path,
                    format!("{at}: fps = {f}: a scene renders at its own `fps`; an entry's fps states a recording's true rate"),
                ));
            }
            if let Some(r) = &e.roi {
                r.parse::<Roi>()
                    .map_err(|m| Error::input(path, format!("{at}: roi: {m}")))?;
            }
        }
        Ok(d)
    }

    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.dir.join(p)
        }
    }

    /// The property names (targets), sorted.
    pub fn targets(&self) -> Vec<String> {
        self.video
            .first()
            .map(|e| e.properties.keys().cloned().collect())
            .unwrap_or_default()
    }

    /// The conditions present, sorted.
    pub fn conditions(&self) -> Vec<String> {
        let mut c: Vec<String> = self.video.iter().map(|e| e.condition.clone()).collect();
        c.sort();
        c.dedup();
        c
    }

    /// Features of every entry (cached beside the videos), `progress(i, n, video)` before each.
    pub fn features(
        &self,
        run: RunSettings,
        progress: &mut dyn FnMut(usize, usize, &Path),
    ) -> Result<Vec<VideoFeatures>> {
        let n = self.video.len();
        let mut out = Vec::with_capacity(n);
        for (i, e) in self.video.iter().enumerate() {
            let p = self.resolve(e.source().path());
            progress(i, n, &p);
            let region = Region {
                roi: match &e.roi {
                    Some(r) => Some(r.parse::<Roi>().map_err(Error::Usage)?),
                    None => None,
                },
                mask: e.mask.as_ref().map(|m| self.resolve(m)),
                ..Region::default()
            };
            let source = e.source().at(&p);
            let f = features::cached(source, e.fps, &region, &self.features, run);
            out.push(f.map_err(|err| match region.roi {
                Some(r) => roi_outside(e.index, source, e.fps, r).unwrap_or(err),
                None => err,
            })?);
        }
        Ok(out)
    }

    /// The scene file the generator wrote for entry `e`: its `scene`, or
    /// `DIR/scenes/NAME.toml` for `DIR/videos/NAME.y4m`.
    pub fn scene_of(&self, e: &Entry) -> PathBuf {
        if let Some(s) = &e.scene {
            return self.resolve(s);
        }
        let video = self.resolve(e.source().path());
        let stem = video.file_stem().unwrap_or_default().to_os_string();
        let dir = video
            .parent()
            .and_then(Path::parent)
            .map(Path::to_path_buf)
            .unwrap_or_default();
        dir.join("scenes").join(stem).with_extension("toml")
    }

    /// The features of every entry computed from the scene file the
    /// generator wrote (`learn evaluate`'s `--exact` or `--true-motion`),
    /// `progress(i, n, scene)` before each. An entry without its scene is
    /// named.
    pub fn scene_features(
        &self,
        from: SceneMeasure,
        progress: &mut dyn FnMut(usize, usize, &Path),
    ) -> Result<Array2<f64>> {
        let flag = from.flag();
        let mut rows = Vec::with_capacity(self.video.len());
        for (i, e) in self.video.iter().enumerate() {
            let scene = self.scene_of(e);
            progress(i, self.video.len(), &scene);
            if !scene.is_file() {
                return Err(Error::input(
                    &scene,
                    format!(
                        "video[{}] ({}): {flag} needs the scene file `learn generate` wrote beside it, and it does not exist",
                        e.index,
                        e.source().path().display()
                    ),
                ));
            }
            rows.push(match from {
                SceneMeasure::Expected => features::exact_features(&scene, &self.features)?,
                SceneMeasure::TrueMotion => features::true_motion_features(&scene, &self.features)?,
            });
        }
        let p = rows.first().map_or(0, Vec::len);
        Ok(Array2::from_shape_fn((rows.len(), p), |(i, j)| rows[i][j]))
    }

    /// The log targets, n × targets.
    pub fn log_targets(&self) -> Array2<f64> {
        let t = self.targets();
        Array2::from_shape_fn((self.video.len(), t.len()), |(i, k)| {
            self.video[i].properties[&t[k]].ln()
        })
    }
}

fn matrix(f: &[VideoFeatures]) -> Array2<f64> {
    let p = f.first().map_or(0, |v| v.features.len());
    Array2::from_shape_fn((f.len(), p), |(i, j)| f[i].features[j])
}

/// Whether `condition` is among `conds` (none given: every condition).
fn asked(conds: &[String], condition: &str) -> bool {
    conds.is_empty() || conds.iter().any(|c| c == condition)
}

/// Rows whose condition is one of `conds` (all rows when empty).
fn rows_of(d: &Dataset, conds: &[String]) -> Vec<usize> {
    (0..d.video.len())
        .filter(|&i| asked(conds, &d.video[i].condition))
        .collect()
}

/// Leaves out the entries of conditions in none of `sets`, so that only
/// what is asked is measured (an empty set asks for every condition).
fn keep_asked(d: &mut Dataset, sets: &[&[String]]) {
    d.video
        .retain(|e| sets.iter().any(|s| asked(s, &e.condition)));
}

fn check_conditions(d: &Dataset, conds: &[String], flag: &str) -> Result<()> {
    let have = d.conditions();
    for c in conds {
        if !have.contains(c) {
            return Err(Error::usage(
                flag,
                format!("no video has condition {c:?}; the dataset has {have:?}"),
            ));
        }
    }
    Ok(())
}

/// The cross-validated component sweep (Fig. 5-9): for each number of
/// components, R of each target; and the chosen number.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Sweep {
    pub components: Vec<usize>,
    /// `r[a][k]`: R of target k with `components[a]` components (`null`: undefined).
    pub r: Vec<Vec<Option<f64>>>,
    pub chosen: usize,
}

/// Leave-one-object-out sweep over 1..=max components on `train` rows,
/// tested on `test` rows; chooses the fewest components whose mean R is
/// within 0.01 of the best.
fn sweep(
    method: Method,
    max: usize,
    x: &Array2<f64>,
    y: &Array2<f64>,
    objects: &[String],
    train: &[usize],
    test: &[usize],
) -> Result<Sweep> {
    let mut comps = Vec::new();
    let mut r = Vec::new();
    for a in 1..=max {
        let held = model::leave_one_object_out(method, a, x, y, objects, train, test)
            .map_err(Error::Analysis)?;
        let rs: Vec<f64> = (0..y.ncols())
            .map(|k| {
                let p: Vec<f64> = held.iter().map(|h| h.0[k]).collect();
                let t: Vec<f64> = test.iter().map(|&i| y[[i, k]]).collect();
                model::pearson(&p, &t)
            })
            .collect();
        comps.push(a);
        r.push(rs);
    }
    let mean = |v: &Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let rr: Vec<Vec<Option<f64>>> = r
        .iter()
        .map(|v| v.iter().map(|x| x.is_finite().then_some(*x)).collect())
        .collect();
    let best = r.iter().map(mean).fold(f64::NEG_INFINITY, f64::max);
    let chosen = comps
        .iter()
        .zip(&r)
        .find(|(_, v)| mean(v) >= best - 0.01)
        .map_or(1, |(a, _)| *a);
    Ok(Sweep {
        components: comps,
        r: rr,
        chosen,
    })
}

/// Distinct objects among `rows`.
fn n_objects(d: &Dataset, rows: &[usize]) -> usize {
    let mut o: Vec<&String> = rows.iter().map(|&i| &d.video[i].object).collect();
    o.sort();
    o.dedup();
    o.len()
}

/// What `learn fit` is asked.
#[derive(Clone, Debug)]
pub struct FitOptions {
    pub dataset: PathBuf,
    pub output: PathBuf,
    pub method: Method,
    /// Train on these conditions only (all when empty).
    pub conditions: Vec<String>,
    /// Largest number of components tried (`--components` fixes it instead).
    pub max_components: usize,
    pub components: Option<usize>,
    pub run: RunSettings,
}

/// One property's model. Each property has its own (thesis 5.5.1 maps
/// the spectra to the log of stiffness *or* of area weight), with its own
/// number of components: fitted jointly, the components that serve one
/// property well are a compromise for the other (on the simulated
/// fabrics, stiffness R 0.72 at best jointly, against 0.84 alone).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TargetModel {
    pub target: String,
    pub model: Linear,
    pub sweep: Sweep,
    /// Cross-validated metrics at the chosen components.
    pub cv: Metrics,
    /// Limits of T² and Q (the held-out objects' 99th percentile in CV).
    #[serde(deserialize_with = "model::nan_or")]
    pub t2_limit: f64,
    #[serde(deserialize_with = "model::nan_or")]
    pub q_limit: f64,
}

/// The model file.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ModelFile {
    pub format: String,
    pub version: u32,
    pub features: FeatureParams,
    pub targets: Vec<String>,
    pub conditions: Vec<String>,
    pub objects: usize,
    pub videos: usize,
    /// One per target, in the order of `targets`.
    pub models: Vec<TargetModel>,
}

/// Column `k` of `y` as a one-column matrix.
fn column(y: &Array2<f64>, k: usize) -> Array2<f64> {
    y.column(k).to_owned().insert_axis(ndarray::Axis(1))
}

fn percentile(mut v: Vec<f64>, p: f64) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::INFINITY;
    }
    v.sort_by(f64::total_cmp);
    let k = ((v.len() - 1) as f64 * p).round() as usize;
    v[k.min(v.len() - 1)]
}

/// Fits a model on a dataset (see [`FitOptions`]).
pub fn fit(o: &FitOptions, progress: &mut dyn FnMut(usize, usize, &Path)) -> Result<ModelFile> {
    crate::error::check_outputs(&[&o.dataset], &[&o.output])?;
    let mut d = Dataset::load(&o.dataset)?;
    check_conditions(&d, &o.conditions, "--condition")?;
    keep_asked(&mut d, &[&o.conditions]);
    let rows = rows_of(&d, &o.conditions);
    let objs = n_objects(&d, &rows);
    let need = o.components.unwrap_or(1);
    if objs < need + 2 {
        return Err(Error::input(
            &o.dataset,
            format!(
                "{objs} objects for {need} components: leave-one-object-out needs at least components + 2 objects"
            ),
        ));
    }
    let f = d.features(o.run, progress)?;
    let x = matrix(&f);
    let y = d.log_targets();
    let objects: Vec<String> = d.video.iter().map(|e| e.object.clone()).collect();
    let max = o
        .components
        .unwrap_or(o.max_components.min(objs - 2))
        .min(x.ncols())
        .max(1);
    let xt = x.select(ndarray::Axis(0), &rows);
    let mut models = Vec::with_capacity(y.ncols());
    for (k, target) in d.targets().into_iter().enumerate() {
        let yk = column(&y, k);
        let mut sw = sweep(o.method, max, &x, &yk, &objects, &rows, &rows)?;
        if let Some(a) = o.components {
            sw.chosen = a;
        }
        let held =
            model::leave_one_object_out(o.method, sw.chosen, &x, &yk, &objects, &rows, &rows)
                .map_err(Error::Analysis)?;
        let p: Vec<f64> = held.iter().map(|h| h.0[0]).collect();
        let t: Vec<f64> = rows.iter().map(|&i| y[[i, k]]).collect();
        let dist: Vec<Distance> = held.iter().map(|h| h.1).collect();
        let ob: Vec<String> = rows.iter().map(|&i| objects[i].clone()).collect();
        let yt = yk.select(ndarray::Axis(0), &rows);
        let m = model::fit(o.method, sw.chosen, &xt, &yt).map_err(Error::Analysis)?;
        models.push(TargetModel {
            target,
            model: m,
            sweep: sw,
            cv: model::metrics(&p, &t, Some(&ob)),
            t2_limit: percentile(dist.iter().map(|d| d.t2).collect(), 0.99),
            q_limit: percentile(dist.iter().map(|d| d.q).collect(), 0.99),
        });
    }
    let file = ModelFile {
        format: MODEL_FORMAT.into(),
        version: MODEL_VERSION,
        features: d.features,
        targets: d.targets(),
        conditions: if o.conditions.is_empty() {
            d.conditions()
        } else {
            o.conditions.clone()
        },
        objects: objs,
        videos: rows.len(),
        models,
    };
    crate::json::write(&o.output, &file)?;
    Ok(file)
}

/// Reads a model file, refusing another format or version.
pub fn load_model(path: &Path) -> Result<ModelFile> {
    let text = std::fs::read(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    let v: serde_json::Value = serde_json::from_slice(&text)
        .map_err(|e| Error::input(path, format!("not a model file (JSON): {e}")))?;
    let format = v.get("format").and_then(|f| f.as_str()).unwrap_or("");
    let version = v.get("version").and_then(|f| f.as_u64());
    if format != MODEL_FORMAT || version != Some(MODEL_VERSION as u64) {
        return Err(Error::input(
            path,
            format!(
                "format {format:?} version {}: this vibroscope reads {MODEL_FORMAT:?} version {MODEL_VERSION} (refit with `vibroscope learn fit`)",
                version.map_or("none".into(), |v| v.to_string())
            ),
        ));
    }
    serde_json::from_value(v).map_err(|e| Error::input(path, format!("not a model file: {e}")))
}

/// One property's prediction.
#[derive(Clone, Debug, Serialize)]
pub struct PropertyPrediction {
    pub name: String,
    pub value: f64,
    /// 95% interval from the cross-validation residuals.
    pub low: f64,
    pub high: f64,
    /// Hotelling T² and Q residual of the features in this property's
    /// model, and their limits.
    pub t2: f64,
    pub q: f64,
    pub t2_limit: f64,
    pub q_limit: f64,
    /// Outside this model's training distribution (T² or Q above its limit).
    pub out_of_distribution: bool,
}

/// What `learn predict` found.
#[derive(Clone, Debug, Serialize)]
pub struct Prediction {
    pub video: PathBuf,
    pub properties: Vec<PropertyPrediction>,
    /// Outside the training distribution of any property's model.
    pub out_of_distribution: bool,
}

/// What `learn predict` is asked.
#[derive(Clone, Debug)]
pub struct PredictOptions {
    pub model: PathBuf,
    /// A video, a scene file (`.toml`, rendered in memory), or a spectrum
    /// JSON (`vibroscope spectrum --include-spectrum`).
    pub input: PathBuf,
    pub fps: Option<f64>,
    pub region: Region,
    pub json: Option<PathBuf>,
    pub run: RunSettings,
}

/// Predicts the properties of one video with the model.
pub fn predict(o: &PredictOptions) -> Result<Prediction> {
    let m = load_model(&o.model)?;
    let ext = |x: &str| {
        o.input
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case(x))
    };
    let x = if ext("json") {
        features::from_spectrum_json(&o.input, &m.features)?
    } else {
        let source = if ext("toml") {
            features::Source::Scene(&o.input)
        } else {
            features::Source::Video(&o.input)
        };
        features::measure(source, o.fps, &o.region, &m.features, o.run)?.features
    };
    let properties: Vec<PropertyPrediction> = m
        .models
        .iter()
        .map(|tm| {
            let v = tm.model.predict(&x).first().copied().unwrap_or(f64::NAN);
            let dist = tm.model.distance(&x);
            let sd = tm.cv.resid_sd;
            PropertyPrediction {
                name: tm.target.clone(),
                value: v.exp(),
                low: (v - INTERVAL_Z * sd).exp(),
                high: (v + INTERVAL_Z * sd).exp(),
                t2: dist.t2,
                q: dist.q,
                t2_limit: tm.t2_limit,
                q_limit: tm.q_limit,
                out_of_distribution: dist.t2 > tm.t2_limit || dist.q > tm.q_limit,
            }
        })
        .collect();
    let p = Prediction {
        video: o.input.clone(),
        out_of_distribution: properties.iter().any(|p| p.out_of_distribution),
        properties,
    };
    if let Some(j) = &o.json {
        crate::json::write(j, &p)?;
    }
    Ok(p)
}

/// What a take's features are computed from in place of its video, from
/// the scene file the generator wrote (no texture, sensor or pyramid).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneMeasure {
    /// The expected spectrum ([`features::exact_features`]).
    Expected,
    /// The take's own motion ([`features::true_motion_features`]).
    TrueMotion,
}

impl SceneMeasure {
    /// `learn evaluate`'s flag for it, for messages.
    pub fn flag(self) -> &'static str {
        match self {
            SceneMeasure::Expected => "--exact",
            SceneMeasure::TrueMotion => "--true-motion",
        }
    }
}

/// What `learn evaluate` is asked.
#[derive(Clone, Debug)]
pub struct EvaluateOptions {
    pub dataset: PathBuf,
    pub train_on: Vec<String>,
    pub test_on: Vec<String>,
    pub methods: Vec<Method>,
    pub max_components: usize,
    /// Learn from what the generator's scenes say instead of the videos:
    /// the expected spectra (the bound: what perfect measurement would
    /// reach) or each take's true motion (what one take holds).
    pub from: Option<SceneMeasure>,
    pub png: Option<PathBuf>,
    pub json: Option<PathBuf>,
    pub run: RunSettings,
}

/// One method's evaluation (one model per target).
#[derive(Clone, Debug, Serialize)]
pub struct MethodEvaluation {
    pub method: Method,
    /// Per target, chosen by its sweep on the training condition alone.
    pub components: Vec<usize>,
    pub sweep: Vec<Sweep>,
    pub metrics: Vec<Metrics>,
    /// Held-out predictions (logs), per target, in test-row order.
    pub predicted: Vec<Vec<f64>>,
}

/// What `learn evaluate` found.
#[derive(Clone, Debug, Serialize)]
pub struct Evaluation {
    pub targets: Vec<String>,
    pub train_on: Vec<String>,
    pub test_on: Vec<String>,
    pub objects: usize,
    pub test_videos: usize,
    /// True logs per target, in test-row order; the test rows' objects.
    pub truth: Vec<Vec<f64>>,
    pub test_objects: Vec<String>,
    pub methods: Vec<MethodEvaluation>,
    #[serde(skip)]
    pub written: Vec<PathBuf>,
}

/// Leave-one-object-out evaluation: train on `train_on` rows without the
/// held-out object, test on its `test_on` rows (Table 5.3's setting).
pub fn evaluate(
    o: &EvaluateOptions,
    progress: &mut dyn FnMut(usize, usize, &Path),
) -> Result<Evaluation> {
    let mut outs: Vec<&Path> = Vec::new();
    outs.extend(o.png.as_deref());
    outs.extend(o.json.as_deref());
    crate::error::check_outputs(&[&o.dataset], &outs)?;
    let mut d = Dataset::load(&o.dataset)?;
    check_conditions(&d, &o.train_on, "--train-on")?;
    check_conditions(&d, &o.test_on, "--test-on")?;
    keep_asked(&mut d, &[&o.train_on, &o.test_on]);
    let train = rows_of(&d, &o.train_on);
    let test = rows_of(&d, &o.test_on);
    let objs = n_objects(&d, &train);
    if objs < 3 {
        return Err(Error::input(
            &o.dataset,
            format!("{objs} objects in the training rows: leave-one-object-out needs at least 3"),
        ));
    }
    let x = match o.from {
        Some(from) => d.scene_features(from, progress)?,
        None => matrix(&d.features(o.run, progress)?),
    };
    let y = d.log_targets();
    let objects: Vec<String> = d.video.iter().map(|e| e.object.clone()).collect();
    let max = o.max_components.min(objs - 2).min(x.ncols()).max(1);
    let test_objects: Vec<String> = test.iter().map(|&i| objects[i].clone()).collect();
    let mut methods = Vec::new();
    for &method in &o.methods {
        let (mut sweeps, mut predicted) = (Vec::new(), Vec::new());
        for k in 0..y.ncols() {
            let yk = column(&y, k);
            // Components chosen on the training condition only.
            let sw = sweep(method, max, &x, &yk, &objects, &train, &train)?;
            let held =
                model::leave_one_object_out(method, sw.chosen, &x, &yk, &objects, &train, &test)
                    .map_err(Error::Analysis)?;
            predicted.push(held.iter().map(|h| h.0[0]).collect::<Vec<f64>>());
            sweeps.push(sw);
        }
        let metrics = (0..y.ncols())
            .map(|k| {
                let t: Vec<f64> = test.iter().map(|&i| y[[i, k]]).collect();
                model::metrics(&predicted[k], &t, Some(&test_objects))
            })
            .collect();
        methods.push(MethodEvaluation {
            method,
            components: sweeps.iter().map(|s| s.chosen).collect(),
            sweep: sweeps,
            metrics,
            predicted,
        });
    }
    let mut e = Evaluation {
        targets: d.targets(),
        train_on: o.train_on.clone(),
        test_on: o.test_on.clone(),
        objects: objs,
        test_videos: test.len(),
        truth: (0..y.ncols())
            .map(|k| test.iter().map(|&i| y[[i, k]]).collect())
            .collect(),
        test_objects,
        methods,
        written: Vec::new(),
    };
    if let Some(p) = &o.png {
        let png = correlation_plot(&e).map_err(Error::Analysis)?;
        crate::io::atomic::write_atomic(p, &png)?;
        e.written.push(p.clone());
    }
    if let Some(j) = &o.json {
        crate::json::write(j, &e)?;
        e.written.push(j.clone());
    }
    Ok(e)
}

/// Fig. 5-10: predicted against true log property, one panel per target,
/// of the first method; colour by object.
fn correlation_plot(e: &Evaluation) -> std::result::Result<Vec<u8>, String> {
    let m = e.methods.first().ok_or("no method")?;
    let panels: Vec<crate::io::plot::Scatter> = e
        .targets
        .iter()
        .enumerate()
        .map(|(k, name)| crate::io::plot::Scatter {
            title: format!(
                "{name}: {} ({} comp.), R = {:.3}",
                m.method.name(),
                m.components[k],
                m.metrics[k].r
            ),
            x_label: format!("true ln({name})"),
            y_label: format!("predicted ln({name})"),
            x: e.truth[k].clone(),
            y: m.predicted[k].clone(),
            group: e.test_objects.clone(),
        })
        .collect();
    crate::io::plot::scatter_panels(&panels).map_err(|e| e.to_string())
}
