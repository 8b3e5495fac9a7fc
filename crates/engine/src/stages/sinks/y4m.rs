//! `y4m`: records frames to a Y4M file (`Cmono`/`Cmono16`) with each frame's
//! capture timestamp and sequence number in its frame header
//! (`FRAME Xts=<ns> Xseq=<n>`), so a replay uses the true capture times and
//! a camera's dropped frames show as gaps in `Xseq`. `path = "-"` writes to standard output
//! (to pipe into another process).
//!
//! A file is written under a unique temporary sibling (`.NAME.PID-N.partial`)
//! and renamed to its path on finish (end of stream, a signal, an error
//! anywhere): two runs writing one path cannot splice, and the path holds
//! whole frames only (after a write error, such as a full disk, the
//! partial last frame is cut off first).

use crate::*;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use vibroscope_io::atomic::Pending;
use vibroscope_io::{FrameDestRef, Y4mWriter};

params! {
    /// `y4m`'s parameters.
    pub struct Y4mParams for "y4m" {
        path: PathBuf = ParamSpec::of(ParamType::Path, Def::Required)
            .doc("the Y4M file (`-` for standard output)"),
    }
}

type P = Y4mParams;

pub const KIND: KindSpec = KindSpec {
    name: "y4m",
    summary: "records frames to Y4M with per-frame capture timestamps",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        Ok(Box::new(Rec {
            path: v.path,
            w: None,
            pending: None,
        }))
    },
};

struct Rec {
    path: PathBuf,
    w: Option<Y4mWriter<BufWriter<Box<dyn Write + Send>>>>,
    /// The temporary file (not for standard output), renamed on finish.
    pending: Option<Pending>,
}

impl Plan for Rec {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(self))
    }
}

impl Stage for Rec {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        let path = &self.path;
        let io = |e: std::io::Error| StageError::file("write", path, e);
        if self.w.is_none() {
            let fmt = f.format();
            let file: Box<dyn Write + Send> = if path.as_os_str() == "-" {
                Box::new(std::io::stdout())
            } else {
                let (pending, file) = super::create_pending(path)?;
                self.pending = Some(pending);
                Box::new(file)
            };
            self.w = Some(
                Y4mWriter::new(
                    BufWriter::new(file),
                    fmt.width,
                    fmt.height,
                    fmt.depth,
                    fmt.fps,
                )
                .map_err(io)?,
            );
        }
        let Some(w) = self.w.as_mut() else {
            return Ok(());
        };
        let px = match f.pixels() {
            PixelsRef::U8(p) => FrameDestRef::U8(p),
            PixelsRef::U16(p) => FrameDestRef::U16(p),
        };
        w.write_frame_seq(px, Some(f.meta().t_ns), Some(f.meta().seq))
            .map_err(io)
    }

    /// Looks at its ring every 2 ms, or when the ring is half full,
    /// instead of being woken per frame: a writer woken per frame took a
    /// core from the stage before it for every frame (on a 2-core machine,
    /// 6% of `magnify`'s time). The ring holds what comes meanwhile (16
    /// frames: 7 ms at 2200 fps); a live stream to standard output leaves
    /// at most 2 ms later. (Woken only by the period, a writer of 24x24
    /// frames held its producer to 16 frames every 3 ms.)
    fn poll_period(&self) -> Option<std::time::Duration> {
        Some(std::time::Duration::from_millis(2))
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        let io = |e: std::io::Error| StageError::file("write", &self.path, e);
        let flushed = match self.w.take() {
            Some(w) => w.into_inner().flush().map_err(io),
            None => Ok(()),
        };
        let Some(pending) = self.pending.take() else {
            return flushed;
        };
        if flushed.is_err() {
            // A full disk: keep the whole frames that fitted.
            let _ = vibroscope_io::cut_to_whole_frames(pending.temp_path());
        }
        flushed.and(pending.commit().map_err(io))
    }
}
