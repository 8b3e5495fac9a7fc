//! Any other video through an `ffmpeg` child process, which decodes it to
//! grey Y4M on its standard output; that stream is parsed by the Y4M reader.
//!
//! The frame rate is the container's (as ffmpeg states it in the Y4M
//! header), which for high-speed footage is often the playback rate, not
//! the capture rate; callers may override it.

use super::{
    display_name, io_error, FrameDest, FrameRead, VideoError, VideoInfo, VideoReader, Y4mReader,
};
use std::ffi::OsStr;
use std::io::{BufReader, Read};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, ExitStatus, Stdio};
use std::thread::JoinHandle;

/// How much of ffmpeg's standard error is kept for messages.
const STDERR_KEEP: usize = 4096;

/// `path` as an ffmpeg input argument: a ':' in the name would read as a
/// protocol ("clip:1.mp4"), so such a name is said to be a file.
pub fn input_arg(path: &Path) -> std::ffi::OsString {
    if path.as_os_str().as_encoded_bytes().contains(&b':') {
        let mut s = std::ffi::OsString::from("file:");
        s.push(path.as_os_str());
        s
    } else {
        path.as_os_str().to_os_string()
    }
}

pub(crate) struct FfmpegReader {
    name: String,
    info: VideoInfo,
    y4m: Y4mReader<BufReader<ChildStdout>>,
    child: Child,
    stderr: Option<JoinHandle<String>>,
    /// The child has been waited for.
    reaped: bool,
    done: bool,
}

impl FfmpegReader {
    pub(crate) fn open(path: &Path) -> Result<Self, VideoError> {
        Self::open_with(path, OsStr::new("ffmpeg"))
    }

    /// Opens `path` with the ffmpeg binary `program` (tests use a missing one).
    pub(crate) fn open_with(path: &Path, program: &OsStr) -> Result<Self, VideoError> {
        let name = display_name(path);
        // A missing input is reported like for the other readers, not as an ffmpeg failure.
        std::fs::metadata(path).map_err(|e| io_error(&name, e))?;
        let input = input_arg(path);
        let mut child = Command::new(program)
            .args(["-v", "error", "-nostdin", "-i"])
            .arg(&input)
            .args(["-map", "0:v:0", "-an", "-sn", "-dn"])
            .args([
                "-f",
                "yuv4mpegpipe",
                "-pix_fmt",
                "gray",
                "-strict",
                "-1",
                "-",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| match e.kind() {
                std::io::ErrorKind::NotFound => {
                    VideoError::FfmpegNotInstalled { path: name.clone() }
                }
                _ => io_error(&name, e),
            })?;
        let stderr = child.stderr.take().map(|mut err| {
            std::thread::spawn(move || {
                // Keep the start of what ffmpeg says, drain the rest so it never blocks.
                let mut kept = Vec::new();
                let mut buf = [0u8; 1024];
                loop {
                    match err.read(&mut buf) {
                        Ok(0) => break,
                        Ok(n) => {
                            let room = STDERR_KEEP.saturating_sub(kept.len());
                            kept.extend_from_slice(&buf[..n.min(room)]);
                        }
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                        Err(_) => break,
                    }
                }
                String::from_utf8_lossy(&kept).trim().to_string()
            })
        });
        let Some(stdout) = child.stdout.take() else {
            let _ = child.kill();
            let _ = child.wait();
            return Err(io_error(
                &name,
                std::io::Error::other("ffmpeg's standard output is not available"),
            ));
        };
        let y4m = match Y4mReader::from_reader(BufReader::with_capacity(64 * 1024, stdout), &name) {
            Ok(r) => r,
            Err(e) => {
                // Most likely ffmpeg could not decode the input: report what it said.
                let mut failed = Failed {
                    child,
                    stderr,
                    reaped: false,
                };
                return Err(failed.explain(&name, e));
            }
        };
        let mut info = y4m.info().clone();
        info.format_name = "ffmpeg";
        info.frame_count = None;
        info.has_timestamps = false;
        info.notes.retain(|n| !n.starts_with("frame rate F"));
        if let Some(f) = info.fps {
            info.notes.push(format!(
                "decoded by ffmpeg; {f:.3} fps is the container's rate, which may not be the capture rate"
            ));
        }
        Ok(FfmpegReader {
            name,
            info,
            y4m,
            child,
            stderr,
            reaped: false,
            done: false,
        })
    }

    /// Waits for ffmpeg and returns its exit status and standard error.
    fn reap(&mut self, kill: bool) -> (Option<ExitStatus>, String) {
        reap(&mut self.child, &mut self.stderr, &mut self.reaped, kill)
    }
}

fn reap(
    child: &mut Child,
    stderr: &mut Option<JoinHandle<String>>,
    reaped: &mut bool,
    kill: bool,
) -> (Option<ExitStatus>, String) {
    if *reaped {
        return (None, String::new());
    }
    if kill {
        if let Ok(None) = child.try_wait() {
            let _ = child.kill();
        }
    }
    let status = child.wait().ok();
    *reaped = true;
    let text = stderr
        .take()
        .and_then(|h| h.join().ok())
        .unwrap_or_default();
    (status, text)
}

/// A child whose output could not be parsed at all.
struct Failed {
    child: Child,
    stderr: Option<JoinHandle<String>>,
    reaped: bool,
}

impl Failed {
    fn explain(&mut self, name: &str, e: VideoError) -> VideoError {
        // ffmpeg closed its output; wait for it unless our parse failed while it still runs.
        let kill = !matches!(e, VideoError::Header { .. } | VideoError::Truncated { .. });
        let (status, stderr) = reap(&mut self.child, &mut self.stderr, &mut self.reaped, kill);
        failure(name, status, stderr).unwrap_or(e)
    }
}

impl Drop for Failed {
    fn drop(&mut self) {
        reap(&mut self.child, &mut self.stderr, &mut self.reaped, true);
    }
}

/// The error for an unsuccessful ffmpeg run, if it was unsuccessful.
fn failure(name: &str, status: Option<ExitStatus>, stderr: String) -> Option<VideoError> {
    let status = status?;
    if status.success() {
        return None;
    }
    let stderr = if stderr.is_empty() {
        "(it printed nothing)".to_string()
    } else {
        stderr
    };
    Some(VideoError::FfmpegFailed {
        path: name.to_string(),
        status: status.to_string(),
        stderr,
    })
}

impl VideoReader for FfmpegReader {
    fn info(&self) -> &VideoInfo {
        &self.info
    }

    fn read_frame(&mut self, dst: FrameDest<'_>) -> Result<Option<FrameRead>, VideoError> {
        if self.done {
            return Ok(None);
        }
        match self.y4m.read_frame(dst) {
            Ok(Some(_)) => Ok(Some(FrameRead { timestamp_ns: None })),
            Ok(None) => {
                self.done = true;
                let (status, stderr) = self.reap(false);
                match failure(&self.name, status, stderr) {
                    Some(e) => Err(e),
                    None => Ok(None),
                }
            }
            Err(e @ VideoError::Destination { .. }) => Err(e),
            Err(e) => {
                self.done = true;
                let kill = !matches!(e, VideoError::Truncated { .. });
                let (status, stderr) = self.reap(kill);
                Err(if kill {
                    e
                } else {
                    failure(&self.name, status, stderr).unwrap_or(e)
                })
            }
        }
    }
}

impl Drop for FfmpegReader {
    fn drop(&mut self) {
        if !self.reaped {
            let (status, _) = self.reap(true);
            tracing::debug!(path = %self.name, ?status, "ffmpeg child stopped");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::data_file;
    use super::super::{open, Depth, Format};
    use super::*;

    fn have_ffmpeg() -> bool {
        let ok = Command::new("ffmpeg")
            .arg("-version")
            .output()
            .is_ok_and(|o| o.status.success());
        if !ok {
            eprintln!("skipping: ffmpeg not installed");
        }
        ok
    }

    #[test]
    fn guitar_mp4_decodes() {
        let Some(path) = data_file("guitar.mp4") else {
            return;
        };
        if !have_ffmpeg() {
            return;
        }
        let mut r = open(&path, Format::Auto).expect("open");
        let info = r.info().clone();
        assert_eq!(info.format_name, "ffmpeg");
        assert_eq!(
            (info.width, info.height, info.depth, info.bits),
            (432, 192, Depth::U8, 8)
        );
        assert_eq!(info.frame_count, None);
        let fps = info.fps.expect("fps");
        assert!((fps - 29.97).abs() < 0.01, "{fps}");
        let mut buf = vec![0u8; 432 * 192];
        let mut n = 0;
        let mut sum = 0u64;
        while let Some(f) = r.read_frame(FrameDest::U8(&mut buf)).expect("frame") {
            assert_eq!(f.timestamp_ns, None);
            sum += buf.iter().map(|&v| u64::from(v)).sum::<u64>();
            n += 1;
        }
        assert_eq!(n, 300);
        assert!(sum > 0);
        eprintln!(
            "guitar.mp4: {n} frames at {fps:.3} fps, mean level {:.1}",
            sum as f64 / (n as f64 * 432.0 * 192.0)
        );
    }

    #[test]
    fn colon_in_file_name() {
        let Some(path) = data_file("guitar.mp4") else {
            return;
        };
        if !have_ffmpeg() {
            return;
        }
        let dir = tempfile::tempdir().expect("tempdir");
        let odd = dir.path().join("take:1.mp4");
        std::fs::copy(&path, &odd).expect("copy");
        let mut r = FfmpegReader::open(&odd).expect("open");
        let mut buf = vec![0u8; 432 * 192];
        assert!(r
            .read_frame(FrameDest::U8(&mut buf))
            .expect("frame")
            .is_some());
    }

    #[test]
    fn dropping_mid_stream_stops_ffmpeg() {
        let Some(path) = data_file("guitar.mp4") else {
            return;
        };
        if !have_ffmpeg() {
            return;
        }
        let mut r = FfmpegReader::open(&path).expect("open");
        let mut buf = vec![0u8; 432 * 192];
        assert!(r
            .read_frame(FrameDest::U8(&mut buf))
            .expect("frame")
            .is_some());
        let pid = r.child.id();
        drop(r);
        // The child was waited for: its /proc entry is gone (Linux).
        assert!(!Path::new(&format!("/proc/{pid}")).exists() || !is_our_ffmpeg(pid));
    }

    fn is_our_ffmpeg(pid: u32) -> bool {
        std::fs::read_to_string(format!("/proc/{pid}/cmdline"))
            .is_ok_and(|c| c.contains("yuv4mpegpipe"))
    }

    #[test]
    fn missing_binary_says_install_ffmpeg() {
        let dir = tempfile::tempdir().expect("tempdir");
        let input = dir.path().join("clip.mp4");
        std::fs::write(&input, b"not really a video").expect("write");
        let e = FfmpegReader::open_with(&input, OsStr::new("/nonexistent/bin/ffmpeg-not-here"))
            .err()
            .expect("error");
        assert!(matches!(e, VideoError::FfmpegNotInstalled { .. }), "{e:?}");
        let msg = e.to_string();
        assert!(msg.starts_with(&input.display().to_string()), "{msg}");
        assert!(
            msg.contains("ffmpeg not installed (install Debian package `ffmpeg`)"),
            "{msg}"
        );
    }

    #[test]
    fn undecodable_input_reports_ffmpeg_stderr() {
        if !have_ffmpeg() {
            return;
        }
        let dir = tempfile::tempdir().expect("tempdir");
        let input = dir.path().join("junk.mp4");
        std::fs::write(&input, vec![0x5au8; 5000]).expect("write");
        let e = FfmpegReader::open(&input).err().expect("error");
        assert!(matches!(e, VideoError::FfmpegFailed { .. }), "{e:?}");
        let msg = e.to_string();
        assert!(msg.starts_with(&input.display().to_string()), "{msg}");
        assert!(msg.len() < 6000, "{msg}");
        eprintln!("ffmpeg failure message: {msg}");
    }

    #[test]
    fn missing_input_is_io_error() {
        let e = FfmpegReader::open(Path::new("/nonexistent/x.mp4"))
            .err()
            .expect("error");
        assert!(matches!(e, VideoError::Io { .. }), "{e:?}");
    }
}
