//! Pipelines as values: load one (a file or a shipped name), edit it with
//! typed operations (replay a recording, set the frame rate, add or rewire
//! stages), and run it.

use crate::engine::config::{self, ConfigError, InputDecl, Origin, PipelineDecl, StageDecl};
use crate::engine::spec::{Key, KindParams, StageId};
use crate::engine::{self, Control, RunReport};
use crate::error::{Error, Result, UsageError};
use crate::stages;
use crate::stages::params::{
    BandParams, FileParams, ModesParams, NokhwaParams, PatternParams, PhaseParams,
    SpectralSubtractionParams, SpeechEnhanceParams, TileMotionParams, V4l2Params, WienerParams,
};
use crate::stages::sources::synthetic::SyntheticParams;
use crate::stages::transform::roi::RoiParam;
use crate::{io, pipelines};
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use toml::Value;

/// A shipped pipeline or a pipeline file, with command-line changes.
#[derive(Clone, Debug, Default)]
pub struct PipelineOptions {
    /// Pipeline file, or a shipped pipeline's name.
    pub pipeline: String,
    /// `STAGE.KEY=VALUE` overrides (VALUE is TOML).
    pub set: Vec<String>,
    /// Replace the source with this recording.
    pub replay: Option<PathBuf>,
    /// The source's capture rate (Hz).
    pub fps: Option<f64>,
}

/// A pipeline file, or a shipped pipeline by name.
pub fn load(pipeline: &str) -> Result<PipelineDecl, ConfigError> {
    let path = Path::new(pipeline);
    if path.exists() {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            file: pipeline.to_string(),
            origin: None,
            stage: None,
            field: None,
            message: format!("cannot read: {e}"),
        })?;
        return config::parse(pipeline, &text);
    }
    if let Some(s) = pipelines::find(pipeline) {
        return config::parse(&format!("pipelines/{}.toml (shipped)", s.name), s.text);
    }
    let names: Vec<&str> = pipelines::SHIPPED.iter().map(|s| s.name).collect();
    Err(ConfigError {
        file: pipeline.to_string(),
        origin: None,
        stage: None,
        field: None,
        message: format!(
            "no such file, and no shipped pipeline of that name (shipped: {})",
            names.join(", ")
        ),
    })
}

/// Loads a pipeline and applies `set`, `replay` and `fps`, in that order.
pub fn prepare(o: &PipelineOptions) -> Result<PipelineDecl> {
    let mut decl = load(&o.pipeline)?;
    for s in &o.set {
        config::apply_set(&mut decl, s)?;
    }
    if let Some(path) = &o.replay {
        apply_replay(&mut decl, path)?;
    }
    if let Some(f) = o.fps {
        apply_fps(&mut decl, f)?;
    }
    Ok(decl)
}

/// The one source of `decl`, for an option (`what`) that changes it.
fn one_source(decl: &PipelineDecl, what: &str) -> Result<usize> {
    let src: Vec<usize> = decl
        .stages
        .iter()
        .enumerate()
        .filter(|(_, s)| stages::kind(&s.kind).is_some_and(|k| k.is_source()))
        .map(|(i, _)| i)
        .collect();
    let message = match src.as_slice() {
        [i] => return Ok(*i),
        [] => "the pipeline has no source stage".to_string(),
        many => {
            let ids: Vec<&str> = many.iter().map(|&i| decl.stages[i].id.as_str()).collect();
            format!(
                "the pipeline has several sources ({}); use --set ID.path=... instead",
                ids.join(", ")
            )
        }
    };
    Err(Error::input(&decl.file, format!("{what}: {message}")))
}

/// The id of `decl`'s one source (none when it has none or several).
pub fn source_id(decl: &PipelineDecl) -> Option<&str> {
    one_source(decl, "")
        .ok()
        .map(|i| decl.stages[i].id.as_str())
}

/// Replay: the source becomes a `file` source of the same id, feeding the
/// same stages; every edge blocks (a replay never drops).
pub fn apply_replay(decl: &mut PipelineDecl, path: &Path) -> Result<()> {
    let i = one_source(decl, "--replay")?;
    let origin = Origin::Builtin(format!("--replay {}", path.display()));
    let file = decl.file.clone();
    let st = &mut decl.stages[i];
    st.kind = FileParams::KINDS[0].into();
    st.kind_origin = origin.clone();
    st.clear_params();
    st.set(&file, FileParams::path, path.to_path_buf(), origin)?;
    block_every_edge(decl);
    Ok(())
}

/// Every edge blocks: a recording (or a scene rendered as fast as it can
/// be) is never dropped from.
fn block_every_edge(decl: &mut PipelineDecl) {
    for s in &mut decl.stages {
        s.policy = None;
        for inp in &mut s.inputs {
            inp.policy = None;
        }
    }
}

/// A scene file: the `synthetic` source's parameters at its top level
/// (`vibroscope simulate`'s input, `learn generate`'s takes).
#[derive(Clone, Debug)]
pub struct SceneFile {
    pub path: PathBuf,
    text: String,
    table: toml::Table,
}

impl SceneFile {
    /// Reads and parses a scene file (errors name the file and the line).
    pub fn read(path: &Path) -> Result<SceneFile> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
        let table: toml::Table = toml::from_str(&text)
            .map_err(|e| config::toml_error(&path.display().to_string(), &text, &e))?;
        Ok(SceneFile {
            path: path.to_path_buf(),
            text,
            table,
        })
    }

    /// The scene as the `synthetic` source reads it: its declared
    /// defaults for what the file omits, its ranges and its checks; errors
    /// name the file, the line and the field.
    pub fn synthetic(&self) -> Result<SyntheticParams> {
        let file = self.path.display().to_string();
        let mut decl = config::parse(&file, "[[stage]]\nid = \"cam\"\nkind = \"synthetic\"\n")?;
        self.fill(&mut decl, "cam")?;
        let p = config::Params {
            file: &file,
            stage: &decl.stages[0],
        };
        // The `synthetic` kind's own plan: resolve, then check.
        let resolved = p
            .resolve_typed::<SyntheticParams>()
            .and_then(|v| v.check().map(|()| v).map_err(|(f, m)| p.error(f, m)));
        resolved.map_err(|e| self.told(Error::Config(e), "cam"))
    }

    /// The scene's parameters become stage `id`'s (which is made a
    /// `synthetic` source), each with its line in the file.
    pub fn fill(&self, decl: &mut PipelineDecl, id: &str) -> Result<()> {
        let st = stage_mut(decl, id)?;
        st.kind = SyntheticParams::KINDS[0].into();
        st.kind_origin = Origin::Builtin(format!("scene {}", self.path.display()));
        config::read_table(st, &self.table, |k| {
            let line = self
                .text
                .lines()
                .position(|l| {
                    l.trim_start()
                        .strip_prefix(k)
                        .is_some_and(|r| r.trim_start().starts_with('='))
                })
                .map_or(0, |i| i + 1);
            Origin::Line(line)
        });
        Ok(())
    }

    /// A configuration error about stage `id` (filled by [`Self::fill`]),
    /// told against the scene file: its line when the field is in the
    /// file, no line when the field took its default.
    pub fn told(&self, e: Error, id: &str) -> Error {
        match e {
            Error::Config(mut c) if c.stage.as_deref() == Some(id) => {
                let given = c
                    .field
                    .as_deref()
                    .is_some_and(|f| self.table.contains_key(f));
                c.origin = match c.origin {
                    Some(Origin::Line(n)) if given && n > 0 => Some(Origin::Line(n)),
                    Some(Origin::Set(s)) => Some(Origin::Set(s)),
                    _ => None,
                };
                c.file = self.path.display().to_string();
                c.stage = None;
                Error::Config(c)
            }
            e => e,
        }
    }
}

/// Scene replay: the source becomes the `synthetic` source of `scene`,
/// rendering the frames `vibroscope simulate` would write to a file, and
/// every edge blocks, as on a replay.
pub fn apply_scene(decl: &mut PipelineDecl, scene: &SceneFile) -> Result<()> {
    let i = one_source(decl, "a scene")?;
    let id = decl.stages[i].id.clone();
    scene.fill(decl, &id)?;
    block_every_edge(decl);
    Ok(())
}

/// Sets the source's capture rate (Hz).
pub fn apply_fps(decl: &mut PipelineDecl, fps: f64) -> Result<()> {
    let i = one_source(decl, "--fps")?;
    let file = decl.file.clone();
    let o = Origin::Set(format!("--fps {fps}"));
    let st = &mut decl.stages[i];
    if st.is::<FileParams>() {
        st.set(&file, FileParams::fps, Some(fps), o)?;
    } else if st.is::<SyntheticParams>() {
        st.set(&file, SyntheticParams::fps, fps, o)?;
    } else if st.is::<PatternParams>() {
        st.set(&file, PatternParams::fps, fps, o)?;
    } else if st.is::<V4l2Params>() {
        st.set(&file, V4l2Params::fps, Some(fps), o)?;
    } else if st.is::<NokhwaParams>() {
        // nokhwa asks the camera for a whole number of frames a second.
        if fps.fract() != 0.0 || !(1.0..=f64::from(u32::MAX)).contains(&fps) {
            return Err(Error::usage(
                "--fps",
                format!("the `nokhwa` source takes a whole number of frames a second, got {fps}"),
            ));
        }
        st.set(&file, NokhwaParams::fps, Some(fps as u32), o)?;
    } else {
        return Err(Error::input(
            &file,
            format!(
                "--fps: the source `{}` (a `{}`) has no frame rate to set",
                st.id, st.kind
            ),
        ));
    }
    Ok(())
}

// ------------------------------------------------------------------ edits

/// A value set by an option of a recipe (errors name the option).
pub fn by(option: &str) -> Origin {
    Origin::Set(option.to_string())
}

/// The stage `id` of `decl` (an error names the pipeline when it lacks it).
pub fn stage_mut<'a>(decl: &'a mut PipelineDecl, id: &str) -> Result<&'a mut StageDecl> {
    let file = decl.file.clone();
    decl.stages
        .iter_mut()
        .find(|s| s.id == id)
        .ok_or_else(|| no_stage(&file, id))
}

/// Position of stage `id`.
pub fn position(decl: &PipelineDecl, id: &str) -> Result<usize> {
    decl.stages
        .iter()
        .position(|s| s.id == id)
        .ok_or_else(|| no_stage(&decl.file, id))
}

/// A pipeline that lacks a stage a recipe edits (a pipeline file given
/// with `--pipeline` that is not shaped like the shipped one).
pub fn no_stage(file: &str, id: &str) -> Error {
    Error::Config(crate::engine::spec::no_stage(file, id))
}

/// A count as the TOML integer a parameter holds it in (at most
/// `i64::MAX`).
pub fn count(n: usize) -> usize {
    n.min(i64::MAX as usize)
}

/// Sets the parameter `key` of the shipped stage `id` to `v` (`None`
/// unsets an optional one): the stage, the parameter and the value's type
/// are checked by the compiler; a `--pipeline` file whose stage of that id
/// is another kind is an error naming it.
pub fn set<K: KindParams, T: serde::Serialize>(
    decl: &mut PipelineDecl,
    id: StageId<K>,
    key: Key<K, T>,
    v: T,
    origin: Origin,
) -> Result<()> {
    Ok(decl.set(id, key, v, origin)?)
}

/// Sets the parameter `key` of `st`, a stage this recipe made.
pub fn put<K: KindParams, T: serde::Serialize>(
    st: &mut StageDecl,
    key: Key<K, T>,
    v: T,
    origin: Origin,
) -> Result<()> {
    Ok(st.set("vibroscope", key, v, origin)?)
}

/// A new stage `id` of `K`'s kind reading from `inputs`, without parameters.
pub fn new_stage<K: KindParams>(id: &str, inputs: &[&str], origin: Origin) -> StageDecl {
    StageDecl::new_of::<K>(id, inputs, origin)
}

/// An empty pipeline named `name`.
pub fn empty(name: &str, description: &str) -> PipelineDecl {
    PipelineDecl {
        file: format!("vibroscope {name}"),
        name: name.into(),
        description: description.into(),
        stages: Vec::new(),
    }
}

/// Every stage reading from `from` reads from `to` instead.
pub fn rewire(decl: &mut PipelineDecl, consumer: &str, to: &str) -> Result<()> {
    for inp in &mut stage_mut(decl, consumer)?.inputs {
        inp.from = to.into();
    }
    Ok(())
}

/// Inserts `st` (its input and id already set) just before the stage
/// `consumer`: it reads what `consumer` read, and `consumer` reads `st`.
pub fn insert_before(decl: &mut PipelineDecl, consumer: &str, mut st: StageDecl) -> Result<()> {
    let at = position(decl, consumer)?;
    let inputs = std::mem::take(&mut decl.stages[at].inputs);
    st.inputs = inputs
        .into_iter()
        .map(|mut i| {
            i.origin = st.origin.clone();
            i
        })
        .collect();
    let id = st.id.clone();
    decl.stages.insert(at, st);
    decl.stages[at + 1].inputs = vec![InputDecl {
        from: id,
        capacity: None,
        policy: None,
        origin: decl.stages[at].origin.clone(),
    }];
    Ok(())
}

// ------------------------------------------------------------ option types

/// A rectangle of the frame, in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Roi {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

impl FromStr for Roi {
    type Err = UsageError;
    /// `X,Y,W,H`: four whole numbers >= 0.
    fn from_str(r: &str) -> Result<Roi, UsageError> {
        let v: std::result::Result<Vec<u32>, _> =
            r.split(',').map(|v| v.trim().parse::<u32>()).collect();
        match v.as_deref() {
            Ok([x, y, w, h]) => Ok(Roi {
                x: *x,
                y: *y,
                w: *w,
                h: *h,
            }),
            _ => Err(UsageError::new(
                "--roi",
                format!("expected X,Y,W,H (four whole numbers >= 0), got `{r}`"),
            )),
        }
    }
}

impl fmt::Display for Roi {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{},{},{}", self.x, self.y, self.w, self.h)
    }
}

impl Roi {
    /// As a stage's `roi` parameter.
    pub fn param(&self) -> RoiParam {
        RoiParam([self.x, self.y, self.w, self.h])
    }
}

/// A Butterworth band filter asked for on the command line: `--band LO,HI`
/// (band-pass) or `--notch F[,WIDTH]` (band-stop from F - WIDTH/2 to
/// F + WIDTH/2; WIDTH defaults to F/10).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BandFilter {
    Pass { lo_hz: f64, hi_hz: f64 },
    Notch { f_hz: f64, width_hz: f64 },
}

fn numbers(flag: &str, text: &str, what: &str) -> Result<Vec<f64>, UsageError> {
    text.split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<std::result::Result<Vec<f64>, _>>()
        .ok()
        .filter(|v| v.iter().all(|x| x.is_finite()))
        .ok_or_else(|| {
            UsageError::new(flag, format!("expected {what} (numbers, Hz), got `{text}`"))
        })
}

impl BandFilter {
    /// `--band LO,HI`: 0 < LO < HI.
    pub fn band(text: &str) -> Result<BandFilter, UsageError> {
        match numbers("--band", text, "LO,HI")?.as_slice() {
            [lo, hi] if *lo > 0.0 && lo < hi => Ok(BandFilter::Pass {
                lo_hz: *lo,
                hi_hz: *hi,
            }),
            [lo, hi] => Err(UsageError::new(
                "--band",
                format!("LO,HI = `{text}`: need 0 < LO < HI (got LO {lo} Hz, HI {hi} Hz)"),
            )),
            _ => Err(UsageError::new(
                "--band",
                format!("expected LO,HI (two numbers, Hz), got `{text}`"),
            )),
        }
    }

    /// `--notch F[,WIDTH]`: F > 0, WIDTH > 0, F - WIDTH/2 > 0.
    pub fn notch(text: &str) -> Result<BandFilter, UsageError> {
        let v = numbers("--notch", text, "F[,WIDTH]")?;
        let (f, w) = match v.as_slice() {
            [f] => (*f, *f / 10.0),
            [f, w] => (*f, *w),
            _ => {
                return Err(UsageError::new(
                    "--notch",
                    format!("expected F[,WIDTH] (one or two numbers, Hz), got `{text}`"),
                ))
            }
        };
        if f <= 0.0 {
            return Err(UsageError::new(
                "--notch",
                format!("`{text}`: the frequency must be above 0 Hz, got {f}"),
            ));
        }
        if w <= 0.0 {
            return Err(UsageError::new(
                "--notch",
                format!("`{text}`: the width must be above 0 Hz, got {w}"),
            ));
        }
        if f - w / 2.0 <= 0.0 {
            return Err(UsageError::new(
                "--notch",
                format!(
                    "`{text}`: the band {} to {} Hz reaches 0 Hz; use a narrower width or --band",
                    f - w / 2.0,
                    f + w / 2.0
                ),
            ));
        }
        Ok(BandFilter::Notch {
            f_hz: f,
            width_hz: w,
        })
    }

    /// Its flag, as typed, for messages.
    pub fn flag(&self) -> String {
        match *self {
            BandFilter::Pass { lo_hz, hi_hz } => {
                format!("--band {},{}", short(lo_hz), short(hi_hz))
            }
            BandFilter::Notch { f_hz, width_hz } => {
                format!("--notch {},{}", short(f_hz), short(width_hz))
            }
        }
    }

    /// Stage kind and edges (Hz).
    pub fn stage(&self) -> (&'static str, f64, f64) {
        match *self {
            BandFilter::Pass { lo_hz, hi_hz } => ("bandpass", lo_hz, hi_hz),
            BandFilter::Notch { f_hz, width_hz } => {
                ("bandstop", f_hz - width_hz / 2.0, f_hz + width_hz / 2.0)
            }
        }
    }

    /// A usage error when the upper edge is not below the Nyquist frequency
    /// of a signal at `rate_hz`.
    pub fn check_rate(&self, rate_hz: f64) -> Result<(), UsageError> {
        let (_, _, hi) = self.stage();
        let nyq = rate_hz / 2.0;
        if hi >= nyq {
            let (flag, value) = self
                .flag()
                .split_once(' ')
                .map_or((String::new(), String::new()), |(a, b)| {
                    (a.to_string(), b.to_string())
                });
            return Err(UsageError::new(
                flag,
                format!(
                    "{value}: the band reaches {} Hz, not below the Nyquist frequency {} Hz of a signal sampled at {} Hz",
                    short(hi),
                    short(nyq),
                    short(rate_hz)
                ),
            ));
        }
        Ok(())
    }

    /// Inserts this filter's stage, `id`, just before the stage `before`.
    pub fn insert(&self, decl: &mut PipelineDecl, id: &str, before: &str) -> Result<()> {
        let (kind, lo, hi) = self.stage();
        let origin = by(&self.flag());
        let mut st = StageDecl::new_kind_of::<BandParams>(id, kind, &[], origin.clone())
            .ok_or_else(|| Error::input(&decl.file, format!("no band filter kind `{kind}`")))?;
        put(&mut st, BandParams::lo_hz, lo, origin.clone())?;
        put(&mut st, BandParams::hi_hz, hi, origin)?;
        insert_before(decl, before, st)
    }
}

/// The pyramid of the local-phase stage: complex steerable (quality) or
/// Riesz (speed).
pub use crate::math::pyramid::PyramidKind as Pyramid;

/// A pipeline checked against the registry of stage kinds (ports, types,
/// parameters), before anything runs: its stages in order with their
/// inputs, or the error naming the stage and field.
pub fn validate(decl: &PipelineDecl) -> std::result::Result<engine::graph::Graph, ConfigError> {
    engine::graph::validate(decl, stages::registry())
}

/// Denoising after the high-pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Denoise {
    #[default]
    None,
    /// Spectral subtraction.
    Subtract,
    /// Speech enhancement.
    Enhance,
    /// MMSE (Wiener) estimation: the least squared error.
    Wiener,
}

impl Denoise {
    /// Its stage `id` reading from `inputs`, if any.
    pub fn stage(self, id: &str, inputs: &[&str], origin: Origin) -> Option<StageDecl> {
        match self {
            Denoise::None => None,
            Denoise::Subtract => Some(new_stage::<SpectralSubtractionParams>(id, inputs, origin)),
            Denoise::Enhance => Some(new_stage::<SpeechEnhanceParams>(id, inputs, origin)),
            Denoise::Wiener => Some(new_stage::<WienerParams>(id, inputs, origin)),
        }
    }
}

/// The region of the object: a rectangle and/or a mask image, and the pyramid.
#[derive(Clone, Debug, Default)]
pub struct Region {
    pub roi: Option<Roi>,
    /// An image the size of the frame (PGM or PNG; pixels > 0 count).
    pub mask: Option<PathBuf>,
    pub pyramid: Pyramid,
}

/// A kind that reads a region of the frame (`roi`, `mask`).
pub trait RegionKind: KindParams {
    const ROI: Key<Self, Option<RoiParam>>;
    const MASK: Key<Self, Option<PathBuf>>;
}

/// A region kind that also builds a pyramid (`pyramid`).
pub trait PyramidRegionKind: RegionKind {
    const PYRAMID: Key<Self, Pyramid>;
}

macro_rules! region_kinds {
    ($($k:ty $(, $pyramid:ident)?);*) => {$(
        impl RegionKind for $k {
            const ROI: Key<Self, Option<RoiParam>> = <$k>::roi;
            const MASK: Key<Self, Option<PathBuf>> = <$k>::mask;
        }
        $(impl PyramidRegionKind for $k {
            const PYRAMID: Key<Self, Pyramid> = <$k>::$pyramid;
        })?
    )*};
}
region_kinds!(PhaseParams, pyramid; ModesParams, pyramid; TileMotionParams);

impl Region {
    /// Sets `roi`, `mask` and `pyramid` on the stage `id`.
    pub fn apply<K: PyramidRegionKind>(
        &self,
        decl: &mut PipelineDecl,
        id: StageId<K>,
    ) -> Result<()> {
        set(decl, id, K::PYRAMID, self.pyramid, by("--pyramid"))?;
        self.apply_region(decl, id)
    }

    /// Sets `roi` and `mask` (not the pyramid) on the stage `id`.
    pub fn apply_region<K: RegionKind>(
        &self,
        decl: &mut PipelineDecl,
        id: StageId<K>,
    ) -> Result<()> {
        if let Some(r) = &self.roi {
            set(decl, id, K::ROI, Some(r.param()), by(&format!("--roi {r}")))?;
        }
        if let Some(m) = &self.mask {
            let origin = by(&format!("--mask {}", m.display()));
            set(decl, id, K::MASK, Some(m.clone()), origin)?;
        }
        Ok(())
    }

    /// Sets `roi` and `mask` on `st`.
    pub fn put_region<K: RegionKind>(&self, st: &mut StageDecl) -> Result<()> {
        if let Some(r) = &self.roi {
            put(st, K::ROI, Some(r.param()), by(&format!("--roi {r}")))?;
        }
        if let Some(m) = &self.mask {
            put(
                st,
                K::MASK,
                Some(m.clone()),
                by(&format!("--mask {}", m.display())),
            )?;
        }
        Ok(())
    }
}

/// Checks a frame rate option.
pub fn check_fps(fps: Option<f64>) -> Result<()> {
    if let Some(f) = fps {
        stages::sources::check_fps(f).map_err(|m| Error::usage("--fps", m))?;
    }
    Ok(())
}

/// A warning when the frame rate will come from a container (the ffmpeg
/// path: MP4, AVI, MKV, ...) and looks like a playback rate (23.976-60 fps):
/// high-speed clips are usually stored that way, and every frequency would
/// come out scaled down. `None` with `fps` given, or for other formats.
pub fn playback_rate_warning(video: &Path, fps: Option<f64>) -> Option<String> {
    if fps.is_some() || !matches!(io::format_by_extension(video), io::Format::Ffmpeg) {
        return None;
    }
    let stated = io::open(video, io::Format::Ffmpeg).ok()?.info().fps?;
    (23.9..=60.01).contains(&stated).then(|| {
        format!(
            "warning: {} states {} fps, a playback rate: if it was filmed at a \
             higher rate, pass the capture rate with --fps (every frequency scales with it)",
            video.display(),
            short(stated)
        )
    })
}

/// A rate or frequency for messages: at most 3 decimals, no trailing zeros.
pub fn short(v: f64) -> String {
    let s = format!("{v:.3}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

// ------------------------------------------------------------------- runs

/// How a run shows itself.
#[derive(Clone, Copy, Debug, Default)]
pub struct RunSettings {
    /// Count the sources' frames for [`progress`].
    pub progress: bool,
}

/// How far the run under way is: frames out of the source, and how many
/// it will give when known.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    pub frames: u64,
    pub total: Option<u64>,
    /// Runs started in this process (a recipe may run several graphs).
    pub runs: u64,
}

static RUNS: AtomicU64 = AtomicU64::new(0);
static COUNTER: Mutex<Option<Arc<engine::SourceProgress>>> = Mutex::new(None);

/// The progress of the run under way (for a progress bar).
pub fn progress() -> Progress {
    let c = COUNTER.lock().ok().and_then(|g| g.clone());
    Progress {
        frames: c.as_ref().map_or(0, |c| c.frames()),
        total: c.as_ref().and_then(|c| c.total()),
        runs: RUNS.load(Ordering::Relaxed),
    }
}

static CURRENT: Mutex<Option<Arc<Control>>> = Mutex::new(None);

/// Stops the run under way, if any: sources stop, queues drain and sinks
/// finalise (the first Ctrl-C).
pub fn stop_current() -> bool {
    current().map(|c| c.stop()).is_some()
}

/// Stops the run under way at once; sinks still finalise (the second Ctrl-C).
pub fn abort_current() -> bool {
    current().map(|c| c.abort()).is_some()
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);
static STEPS: AtomicU64 = AtomicU64::new(0);

/// While alive, the recipe checks [`check_interrupt`] between its steps
/// (calibrate: recovery, fit, writing), so an interruption with no run
/// under way can wait for the step to end instead of exiting at once.
pub struct Steps(());

impl Steps {
    pub fn begin() -> Steps {
        STEPS.fetch_add(1, Ordering::SeqCst);
        Steps(())
    }
}

impl Drop for Steps {
    fn drop(&mut self) {
        STEPS.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A caller's own stop, apart from the process's Ctrl-C: the runs made
/// on the thread that entered [`Cancel::scope`] stop when [`Cancel::cancel`]
/// is called from anywhere (the studio cancels a request's analysis when
/// its client goes away). A stopped run's recipe returns
/// [`Error::Interrupted`], as on Ctrl-C; the sinks finalise what they had.
/// Runs that a recipe starts on threads of its own are not covered.
#[derive(Default)]
pub struct Cancel {
    cancelled: AtomicBool,
    run: Mutex<Option<Arc<Control>>>,
}

thread_local! {
    static CANCEL: std::cell::RefCell<Option<Arc<Cancel>>> = const { std::cell::RefCell::new(None) };
}

impl Cancel {
    pub fn new() -> Arc<Cancel> {
        Arc::new(Cancel::default())
    }

    /// Stops the run under way in the scope, and every later one.
    pub fn cancel(&self) {
        self.cancelled.store(true, Ordering::SeqCst);
        if let Some(c) = self.run.lock().unwrap_or_else(|p| p.into_inner()).as_ref() {
            c.stop();
        }
    }

    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::SeqCst)
    }

    /// Runs `f` with `this` as the calling thread's cancel scope.
    pub fn scope<T>(this: &Arc<Cancel>, f: impl FnOnce() -> T) -> T {
        struct Restore(Option<Arc<Cancel>>);
        impl Drop for Restore {
            fn drop(&mut self) {
                let old = self.0.take();
                CANCEL.with(|c| *c.borrow_mut() = old);
            }
        }
        let _restore = Restore(CANCEL.with(|c| c.borrow_mut().replace(Arc::clone(this))));
        f()
    }

    fn current() -> Option<Arc<Cancel>> {
        CANCEL.with(|c| c.borrow().clone())
    }

    /// Ties `control` to the scope (stopped at once when already cancelled).
    fn attach(&self, control: &Arc<Control>) {
        *self.run.lock().unwrap_or_else(|p| p.into_inner()) = Some(Arc::clone(control));
        if self.is_cancelled() {
            control.stop();
        }
    }

    fn detach(&self) {
        *self.run.lock().unwrap_or_else(|p| p.into_inner()) = None;
    }
}

/// An interruption that arrived while no run was under way: the next run
/// or [`check_interrupt`] returns [`Error::Interrupted`]. Returns whether a
/// recipe will see it ([`Steps`]); when not, the caller should exit now.
pub fn interrupt() -> bool {
    INTERRUPTED.store(true, Ordering::SeqCst);
    STEPS.load(Ordering::SeqCst) > 0
}

/// `Err(Error::Interrupted)` once [`interrupt`] was called: recipes call it
/// between their steps, before writing their outputs.
pub fn check_interrupt() -> Result<()> {
    if INTERRUPTED.load(Ordering::SeqCst) || Cancel::current().is_some_and(|c| c.is_cancelled()) {
        return Err(interrupted());
    }
    Ok(())
}

/// The error of an interruption with no run report of its own (exit 130,
/// 143 or 129 by the signal).
pub fn interrupted() -> Error {
    Error::Interrupted {
        report: Box::new(engine::RunReport {
            stages: Vec::new(),
            errors: Vec::new(),
            interrupted: true,
            elapsed: std::time::Duration::ZERO,
        }),
    }
}

fn current() -> Option<Arc<Control>> {
    CURRENT.lock().ok().and_then(|g| g.clone())
}

/// `decl` as a graph, once no sink would overwrite a file the pipeline
/// reads (nor its own file), checked before validation, which may open the
/// sinks' files.
fn checked(decl: &PipelineDecl) -> Result<engine::Graph> {
    let inputs = input_files(decl);
    let outs = outputs(decl);
    crate::error::check_outputs(
        &inputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
        &outs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    // Errors name the stages the user's pipeline has: validate it first.
    Ok(engine::graph::validate(decl, stages::registry())?)
}

/// Validates and runs `decl`. A stage error or an interruption is an
/// [`Error`] holding the run's report; with `allow_interrupt`, an
/// interrupted run is returned (its `interrupted` set).
pub fn run_with(decl: &PipelineDecl, s: RunSettings, allow_interrupt: bool) -> Result<RunReport> {
    run_inner(decl, s, allow_interrupt, None)
}

fn run_inner(
    decl: &PipelineDecl,
    s: RunSettings,
    allow_interrupt: bool,
    observer: Option<Arc<engine::Observer>>,
) -> Result<RunReport> {
    let graph = checked(decl)?;
    check_interrupt()?;
    let counter = s
        .progress
        .then(|| Arc::new(engine::SourceProgress::default()));
    if let Some(c) = &counter {
        if let Ok(mut g) = COUNTER.lock() {
            *g = Some(Arc::clone(c));
        }
        RUNS.fetch_add(1, Ordering::Relaxed);
    }
    let control = Control::new();
    if let Ok(mut g) = CURRENT.lock() {
        *g = Some(Arc::clone(&control));
    }
    if INTERRUPTED.load(Ordering::SeqCst) {
        // Interrupted between the check above and now: stop at once.
        control.stop();
    }
    let cancel = Cancel::current();
    if let Some(c) = &cancel {
        c.attach(&control);
    }
    let report = engine::run(
        graph,
        Arc::clone(&control),
        &engine::RunOptions { counter, observer },
    )
    .map_err(|source| Error::Start {
        file: decl.file.clone(),
        source: Box::new(source),
    });
    if let Some(c) = &cancel {
        c.detach();
    }
    if let Ok(mut g) = CURRENT.lock() {
        *g = None;
    }
    let report = report?;
    if !report.interrupted {
        empty_sources(decl, &report)?;
    }
    if !report.errors.is_empty() {
        return Err(Error::Stages {
            report: Box::new(report),
        });
    }
    if report.interrupted && !allow_interrupt {
        return Err(Error::Interrupted {
            report: Box::new(report),
        });
    }
    Ok(report)
}

/// A source that delivered no frame at all (a video with a header and no
/// frames) is an input error: nothing was processed and the sinks wrote
/// nothing, which must not look like success.
fn empty_sources(decl: &PipelineDecl, report: &RunReport) -> Result<()> {
    for s in decl.stages.iter().filter(|s| s.inputs.is_empty()) {
        let Some(r) = report.stages.iter().find(|r| r.id == s.id) else {
            continue;
        };
        if r.items_out > 0 {
            continue;
        }
        let path = s
            .params()
            .iter()
            .find(|p| p.key == "path")
            .and_then(|p| p.value.as_str())
            .map_or_else(|| format!("stage `{}`", s.id), str::to_string);
        return Err(Error::input(
            path,
            "holds no frames: nothing was processed and no output was written",
        ));
    }
    Ok(())
}

/// Runs `decl` watched by `observer` (its stages' counters and the latest
/// item of each `tap` stage, read from other threads while it runs); the
/// run stops early through [`engine::Observer::stop`]. It is the process's
/// run under way, as [`run_with`]'s: Ctrl-C stops it, its sinks finalise,
/// and the report says `interrupted` (which [`engine::Observer::stop`]
/// sets too: the caller knows which it asked for).
pub fn run_observed(decl: &PipelineDecl, observer: &Arc<engine::Observer>) -> Result<RunReport> {
    run_inner(
        decl,
        RunSettings::default(),
        true,
        Some(Arc::clone(observer)),
    )
}

/// [`run_with`], an interruption being an error.
pub fn run(decl: &PipelineDecl, s: RunSettings) -> Result<RunReport> {
    run_with(decl, s, false)
}

/// The shipped pipelines: name and description.
pub fn shipped() -> Vec<(&'static str, String)> {
    pipelines::SHIPPED
        .iter()
        .map(|s| (s.name, pipelines::description(s)))
        .collect()
}

/// Every stage kind, one line each: name, role and what it does.
pub fn kind_listing() -> String {
    engine::spec::listing(stages::registry())
}

/// One kind's declaration as a table: ports, then each parameter's name,
/// type, default, range, unit and doc; `None` for an unknown kind.
pub fn kind_table(name: &str) -> Option<String> {
    stages::kind(name).map(|k| k.describe())
}

/// The existing files `decl` may read: the pipeline's own file and every
/// string parameter naming an existing file (at any depth, e.g. a scene's
/// `signal = { type = "wav", path = ... }`), except the sinks' `path`s.
pub fn input_files(decl: &PipelineDecl) -> Vec<PathBuf> {
    fn walk(v: &Value, out: &mut Vec<PathBuf>) {
        match v {
            Value::String(s) if s != "-" && Path::new(s).is_file() => out.push(PathBuf::from(s)),
            Value::Array(a) => a.iter().for_each(|v| walk(v, out)),
            Value::Table(t) => t.values().for_each(|v| walk(v, out)),
            _ => {}
        }
    }
    let mut out = Vec::new();
    if Path::new(&decl.file).is_file() {
        out.push(PathBuf::from(&decl.file));
    }
    for s in &decl.stages {
        let sink = stages::kind(&s.kind).is_some_and(|k| k.output() == engine::Output::None);
        for p in s.params() {
            if !(sink && p.key == "path") {
                walk(&p.value, &mut out);
            }
        }
    }
    out
}

/// The files the sinks of `decl` write (their `path`, not `-`).
pub fn outputs(decl: &PipelineDecl) -> Vec<PathBuf> {
    decl.stages
        .iter()
        .filter(|s| stages::kind(&s.kind).is_some_and(|k| k.output() == engine::Output::None))
        .filter_map(|s| s.params().iter().find(|p| p.key == "path"))
        .filter_map(|p| p.value.as_str())
        .filter(|p| *p != "-")
        .map(PathBuf::from)
        .collect()
}
