//! Motion magnification of a recording (Wadhwa et al. 2013, 2014): the
//! shipped `magnify` pipeline (`magnify` stage, then the `y4m` sink)
//! replayed on a video. The Y4M is written to a temporary sibling and
//! renamed when complete; any other extension goes through `ffmpeg`
//! (Y4M in, the container the name asks for out), also via a temporary
//! sibling. Nothing is left behind on an error.

use crate::engine::RunReport;
use crate::error::{Error, Result};
use crate::io;
use crate::math::magnify::{MagnifyError, MagnifyParams};
use crate::pipeline::{self, by, int, path_value, PipelineOptions, Pyramid, Roi, RunSettings};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::Command;
use toml::Value;

/// What `magnify` is asked.
#[derive(Clone, Debug, Default)]
pub struct MagnifyOptions {
    pub video: PathBuf,
    /// `.y4m`, or any container ffmpeg writes (`.mp4`, `.mkv`, ...).
    pub output: PathBuf,
    /// Band edges, Hz.
    pub lo_hz: f64,
    pub hi_hz: f64,
    /// Motion in the band is multiplied by this (0 removes it).
    pub factor: f64,
    /// Capture frame rate (Hz) when the file states the wrong one.
    pub fps: Option<f64>,
    /// Process and write only this region.
    pub roi: Option<Roi>,
    pub pyramid: Pyramid,
    /// Pyramid scales (default 4).
    pub scales: Option<usize>,
    /// Original (left) and magnified (right) in one frame.
    pub side_by_side: bool,
    pub run: RunSettings,
}

/// What `magnify` wrote.
#[derive(Debug, Serialize)]
pub struct MagnifyReport {
    pub output: PathBuf,
    /// Frames written and their size.
    pub frames: u64,
    pub width: u32,
    pub height: u32,
    /// The frame rate used, Hz.
    pub fps: f64,
    /// Where the temporal band-pass has unit gain and zero phase, Hz.
    pub centre_hz: f64,
    pub notes: Vec<String>,
    #[serde(skip)]
    pub run: Option<RunReport>,
}

/// Checks the request against the video (rate, band, factor) before
/// anything runs; every error names its flag.
fn check(o: &MagnifyOptions, fps: f64) -> Result<MagnifyParams> {
    let p = MagnifyParams::new(fps, o.lo_hz, o.hi_hz, o.factor as f32);
    if !(o.factor.is_finite() && o.factor >= 0.0) {
        return Err(Error::usage(
            "--factor",
            format!("must be a number >= 0, got {}", o.factor),
        ));
    }
    p.check().map_err(|e| match e {
        MagnifyError::Param { field, message } => {
            let flag = match field {
                "band" => "--band",
                "factor" => "--factor",
                "fps" => "--fps",
                _ => "magnify",
            };
            Error::usage(flag, message)
        }
        MagnifyError::Pyramid(e) => Error::Math(e.into()),
    })?;
    Ok(p)
}

/// Whether the output needs ffmpeg (anything but `.y4m`).
pub(crate) fn needs_ffmpeg(output: &Path) -> bool {
    !output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("y4m"))
}

/// A sibling of `path` that keeps its extension (ffmpeg picks the
/// container from it): `.STEM.PID-N.partial.EXT`.
fn temp_with_ext(path: &Path) -> PathBuf {
    let t = io::atomic::temp_sibling(path);
    match path.extension() {
        Some(e) => {
            let mut s = t.into_os_string();
            s.push(".");
            s.push(e);
            PathBuf::from(s)
        }
        None => t,
    }
}

/// The graph `file -> magnify -> y4m` with the options set.
pub fn magnify_pipeline(o: &MagnifyOptions, y4m: &Path) -> Result<crate::engine::PipelineDecl> {
    let mut decl = pipeline::prepare(&PipelineOptions {
        pipeline: "magnify".into(),
        set: Vec::new(),
        replay: Some(o.video.clone()),
        fps: o.fps,
    })?;
    pipeline::set(&mut decl, "out", "path", path_value(y4m), by("-o"))?;
    let band = format!("--band {},{}", o.lo_hz, o.hi_hz);
    pipeline::set(&mut decl, "mag", "lo_hz", Value::Float(o.lo_hz), by(&band))?;
    pipeline::set(&mut decl, "mag", "hi_hz", Value::Float(o.hi_hz), by(&band))?;
    pipeline::set(
        &mut decl,
        "mag",
        "factor",
        Value::Float(o.factor),
        by("--factor"),
    )?;
    pipeline::set(
        &mut decl,
        "mag",
        "pyramid",
        Value::String(o.pyramid.name().into()),
        by("--pyramid"),
    )?;
    if let Some(s) = o.scales {
        pipeline::set(&mut decl, "mag", "scales", int(s), by("--scales"))?;
    }
    if let Some(r) = &o.roi {
        pipeline::set(
            &mut decl,
            "mag",
            "roi",
            r.value(),
            by(&format!("--roi {r}")),
        )?;
    }
    if o.side_by_side {
        pipeline::set(
            &mut decl,
            "mag",
            "side_by_side",
            Value::Boolean(true),
            by("--side-by-side"),
        )?;
    }
    Ok(decl)
}

/// Runs `magnify`.
pub fn magnify(o: &MagnifyOptions) -> Result<MagnifyReport> {
    pipeline::check_fps(o.fps)?;
    if !(o.factor.is_finite() && o.factor >= 0.0) {
        return Err(Error::usage(
            "--factor",
            format!("must be a number >= 0, got {}", o.factor),
        ));
    }
    let ffmpeg = needs_ffmpeg(&o.output);
    if ffmpeg && Command::new("ffmpeg").arg("-version").output().is_err() {
        return Err(Error::usage(
            "-o",
            format!(
                "{}: writing anything but .y4m needs ffmpeg, which is not installed (write a .y4m, or install ffmpeg)",
                o.output.display()
            ),
        ));
    }
    let (reader, fps) = open_video(&o.video, o.fps)?;
    let info = reader.info().clone();
    drop(reader);
    let params = check(o, fps)?;
    if let Some(r) = &o.roi {
        if r.w == 0 || r.h == 0 || r.x + r.w > info.width || r.y + r.h > info.height {
            return Err(Error::usage(
                "--roi",
                format!(
                    "{r} does not fit in the {}x{} frame",
                    info.width, info.height
                ),
            ));
        }
    }
    let mut notes = Vec::new();
    if info.notes.iter().any(|n| n.contains("luma plane only")) || info.format_name == "ffmpeg" {
        notes.push("colour is not kept: the luma is magnified and written as grey".to_string());
    }
    let y4m = if ffmpeg {
        io::atomic::temp_sibling(&o.output.with_extension("y4m"))
    } else {
        io::atomic::temp_sibling(&o.output)
    };
    let decl = magnify_pipeline(o, &y4m)?;
    let result = pipeline::run(&decl, o.run);
    let run = match result {
        Ok(r) => r,
        Err(e) => {
            let _ = std::fs::remove_file(&y4m);
            return Err(e);
        }
    };
    finish_output(&y4m, &o.output, ffmpeg)?;
    let (w, h) = match &o.roi {
        Some(r) => (r.w, r.h),
        None => (info.width, info.height),
    };
    let frames = run
        .stages
        .iter()
        .find(|s| s.id == "out")
        .map(|s| s.items_in)
        .unwrap_or(0);
    let design = crate::math::magnify::temporal::design(
        params.order,
        params.lo_hz,
        params.hi_hz,
        params.fps,
    );
    Ok(MagnifyReport {
        output: o.output.clone(),
        frames,
        width: if o.side_by_side { 2 * w } else { w },
        height: h,
        fps,
        centre_hz: design.centre_hz,
        notes,
        run: Some(run),
    })
}

/// Opens `video` and its capture rate (`fps`, else the file's): an input
/// error for a file the reader cannot use, a usage error naming `--fps`
/// when the file states no rate.
pub(crate) fn open_video(
    video: &Path,
    fps: Option<f64>,
) -> Result<(Box<dyn io::VideoReader>, f64)> {
    let reader = io::open(video, io::Format::Auto).map_err(|e| match e {
        io::VideoError::Io { .. } => Error::from(e),
        // A header, colour format or structure this reader cannot use.
        other => Error::input(video, other.to_string()),
    })?;
    let Some(fps) = fps.or(reader.info().fps) else {
        return Err(Error::usage(
            "--fps",
            format!(
                "{}: the file states no frame rate; give it with --fps",
                video.display()
            ),
        ));
    };
    Ok((reader, fps))
}

/// Moves the finished Y4M `y4m` to `output`: renamed, or with `ffmpeg`
/// encoded into a temporary sibling that is then renamed; `y4m` is
/// removed either way and a failed encode leaves nothing behind.
pub(crate) fn finish_output(y4m: &Path, output: &Path, ffmpeg: bool) -> Result<()> {
    if ffmpeg {
        let tmp = temp_with_ext(output);
        let done = encode(y4m, &tmp).and_then(|()| {
            std::fs::rename(&tmp, output).map_err(|source| {
                Error::from(io::atomic::WriteError {
                    path: output.to_path_buf(),
                    source,
                })
            })
        });
        let _ = std::fs::remove_file(y4m);
        if done.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        done
    } else {
        std::fs::rename(y4m, output).map_err(|source| {
            let _ = std::fs::remove_file(y4m);
            Error::from(io::atomic::WriteError {
                path: output.to_path_buf(),
                source,
            })
        })
    }
}

/// `ffmpeg -i Y4M OUT` (yuv420p, which every player takes).
fn encode(y4m: &Path, out: &Path) -> Result<()> {
    let o = Command::new("ffmpeg")
        .args(["-v", "error", "-nostdin", "-y", "-i"])
        .arg(y4m)
        .args(["-pix_fmt", "yuv420p"])
        .arg(out)
        .output()
        .map_err(|e| Error::Program {
            program: "ffmpeg",
            message: format!("cannot run it: {e}"),
        })?;
    if !o.status.success() {
        let msg = String::from_utf8_lossy(&o.stderr);
        return Err(Error::Program {
            program: "ffmpeg",
            message: format!("could not write {}: {}", out.display(), msg.trim()),
        });
    }
    Ok(())
}
