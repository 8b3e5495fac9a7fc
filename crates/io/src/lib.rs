//! Video input and output.
//!
//! Readers for YUV4MPEG2 (`.y4m`, also standard input), Phantom `.cine`,
//! Photron `.mraw` + `.cih`/`.cihx`, and anything else through an `ffmpeg`
//! child process; and a Y4M writer ([`Y4mWriter`]) that keeps each frame's
//! capture timestamp in its frame header (`FRAME Xts=<ns>`).
//!
//! Every reader hands out frames as grey levels, row-major, top row first,
//! into a buffer the caller owns ([`FrameDest`]). Input files are untrusted:
//! every size and offset is checked against the file length before anything
//! is allocated or read, header lines are capped at [`MAX_HEADER_LINE`]
//! bytes, and a damaged file gives a [`VideoError`] naming the file and what
//! is wrong, never a panic.

use std::io::{self, Read};
use std::path::Path;

pub mod atomic;
mod cine;
mod ffmpeg;
pub use ffmpeg::input_arg as ffmpeg_input;
pub mod image;
mod mraw;
pub mod plot;
pub mod uff;
pub mod wav;
mod y4m;

pub use y4m::{cut_to_whole_frames, Y4mReader, Y4mWriter};

/// Longest header line (Y4M stream and frame headers, `.cih` lines) accepted.
pub const MAX_HEADER_LINE: usize = 4096;
/// Largest accepted width or height, in pixels.
pub const MAX_DIMENSION: u32 = 1 << 15;
/// Largest accepted frame, in pixels (8192 x 8192).
pub const MAX_PIXELS: u64 = 1 << 26;

/// Storage depth of pixels in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Depth {
    U8,
    U16,
}

impl Depth {
    /// Largest `bits` this depth holds.
    pub fn max_bits(self) -> u8 {
        match self {
            Depth::U8 => 8,
            Depth::U16 => 16,
        }
    }
}

/// What a reader knows about its video, from the file's header.
#[derive(Clone, Debug, PartialEq)]
pub struct VideoInfo {
    /// "y4m", "cine", "mraw" or "ffmpeg".
    pub format_name: &'static str,
    pub width: u32,
    pub height: u32,
    /// How pixels are stored in memory (the [`FrameDest`] variant to pass).
    pub depth: Depth,
    /// Bit depth as the file declares it (e.g. 8, 10, 12, 16).
    pub bits: u8,
    /// Number of frames, when known (not for standard input or ffmpeg).
    pub frame_count: Option<u64>,
    /// Declared frame rate in Hz (for mraw: record rate / save step).
    pub fps: Option<f64>,
    /// True when per-frame capture timestamps are in the file.
    pub has_timestamps: bool,
    /// Exposure time in seconds, when the header says.
    pub exposure_s: Option<f64>,
    /// Human-readable remarks for `probe`.
    pub notes: Vec<String>,
}

/// Destination for one frame's pixels, row-major, top row first, len = width*height.
pub enum FrameDest<'a> {
    U8(&'a mut [u8]),
    U16(&'a mut [u16]),
}

/// Pixels of one frame to write, row-major, top row first, len = width*height.
pub enum FrameDestRef<'a> {
    U8(&'a [u8]),
    U16(&'a [u16]),
}

/// What [`VideoReader::read_frame`] learnt about the frame besides its pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRead {
    /// Capture time in nanoseconds from the file when present (relative to
    /// the first frame for cine), else None.
    pub timestamp_ns: Option<i64>,
}

/// A source of frames.
pub trait VideoReader: Send {
    fn info(&self) -> &VideoInfo;
    /// Reads the next frame into `dst` (whose variant matches info().depth and length is width*height).
    /// Ok(None) at a clean end of stream. A frame cut short is an error (VideoError::Truncated), not None.
    /// After an error (other than a wrong `dst`) the reader is finished: later calls return Ok(None).
    fn read_frame(&mut self, dst: FrameDest<'_>) -> Result<Option<FrameRead>, VideoError>;
}

/// Every error of this crate, one variant per kind of file: video, WAV,
/// whole-file writes, pictures, plots. Each function returns its own typed
/// error; this enum gathers them for callers that handle any of them.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Video(#[from] VideoError),
    #[error(transparent)]
    Wav(#[from] wav::WavError),
    #[error(transparent)]
    Write(#[from] atomic::WriteError),
    #[error(transparent)]
    Image(#[from] crate::image::ImageError),
    #[error(transparent)]
    Plot(#[from] plot::PlotError),
}

/// Everything that can go wrong reading video. Every message starts with the
/// file's path (or `<stdin>`) and says what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum VideoError {
    /// The operating system refused (missing file, permission, read error).
    #[error("{path}: {}", io_summary(.source))]
    Io { path: String, source: io::Error },
    /// The file's header is malformed or incomplete.
    #[error("{path}: header: {message}")]
    Header { path: String, message: String },
    /// The file is not of the expected format, or its structure is damaged.
    #[error("{path}: {message}")]
    Malformed { path: String, message: String },
    /// A valid file using a feature this reader does not handle.
    #[error("{path}: unsupported: {message}")]
    Unsupported { path: String, message: String },
    /// A frame ended before all its bytes were there.
    #[error("{path}: frame {frame} is truncated (got {got} of {expected} bytes)")]
    Truncated {
        path: String,
        frame: u64,
        got: u64,
        expected: u64,
    },
    /// A frame's own header or framing is damaged.
    #[error("{path}: frame {frame}: {message}")]
    BadFrame {
        path: String,
        frame: u64,
        message: String,
    },
    /// The `ffmpeg` program is not on this machine.
    #[error("{path}: ffmpeg not installed (install Debian package `ffmpeg`)")]
    FfmpegNotInstalled { path: String },
    /// ffmpeg ran but failed; `stderr` is what it printed (bounded).
    #[error("{path}: ffmpeg failed ({status}): {stderr}")]
    FfmpegFailed {
        path: String,
        status: String,
        stderr: String,
    },
    /// The caller's buffer does not fit the video (a programming error).
    #[error("{path}: destination buffer: {message}")]
    Destination { path: String, message: String },
}

fn io_summary(e: &io::Error) -> &'static str {
    match e.kind() {
        io::ErrorKind::NotFound => "file not found",
        io::ErrorKind::PermissionDenied => "permission denied",
        io::ErrorKind::UnexpectedEof => "unexpected end of file",
        io::ErrorKind::IsADirectory => "is a directory",
        _ => "I/O error",
    }
}

impl VideoError {
    /// The file (or `<stdin>`) the error is about.
    pub fn path(&self) -> &str {
        match self {
            VideoError::Io { path, .. }
            | VideoError::Header { path, .. }
            | VideoError::Malformed { path, .. }
            | VideoError::Unsupported { path, .. }
            | VideoError::Truncated { path, .. }
            | VideoError::BadFrame { path, .. }
            | VideoError::FfmpegNotInstalled { path }
            | VideoError::FfmpegFailed { path, .. }
            | VideoError::Destination { path, .. } => path,
        }
    }
}

/// Which reader to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Format {
    /// By extension: .y4m, .cine, .cih/.cihx/.mraw; anything else through ffmpeg.
    #[default]
    Auto,
    Y4m,
    Cine,
    Mraw,
    Ffmpeg,
}

/// Open by path ("-" = stdin, always Y4M). Auto picks by extension: .y4m -> Y4m, .cine -> Cine,
/// .cih/.cihx/.mraw -> Mraw (either file of the pair may be given; the sibling is found),
/// anything else -> Ffmpeg.
pub fn open(path: &Path, format: Format) -> Result<Box<dyn VideoReader>, VideoError> {
    if path.as_os_str() == "-" {
        return match format {
            Format::Auto | Format::Y4m => Ok(Box::new(Y4mReader::stdin()?)),
            other => Err(VideoError::Unsupported {
                path: STDIN_NAME.to_string(),
                message: format!("standard input is read as Y4M only, not as {other:?}"),
            }),
        };
    }
    let format = match format {
        Format::Auto => format_by_extension(path),
        f => f,
    };
    tracing::debug!(path = %path.display(), ?format, "opening video");
    match format {
        Format::Y4m => Ok(Box::new(Y4mReader::open(path)?)),
        Format::Cine => Ok(Box::new(cine::CineReader::open(path)?)),
        Format::Mraw => Ok(Box::new(mraw::MrawReader::open(path)?)),
        Format::Ffmpeg | Format::Auto => Ok(Box::new(ffmpeg::FfmpegReader::open(path)?)),
    }
}

/// The reader [`Format::Auto`] picks for `path`.
pub fn format_by_extension(path: &Path) -> Format {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("y4m") => Format::Y4m,
        Some("cine") => Format::Cine,
        Some("cih") | Some("cihx") | Some("mraw") => Format::Mraw,
        _ => Format::Ffmpeg,
    }
}

pub(crate) const STDIN_NAME: &str = "<stdin>";

pub(crate) fn display_name(path: &Path) -> String {
    path.display().to_string()
}

pub(crate) fn io_error(path: &str, source: io::Error) -> VideoError {
    VideoError::Io {
        path: path.to_string(),
        source,
    }
}

/// Checks the dimensions a header declares; returns the pixel count.
pub(crate) fn check_dimensions(path: &str, width: u64, height: u64) -> Result<usize, VideoError> {
    let header = |message: String| VideoError::Header {
        path: path.to_string(),
        message,
    };
    if width == 0 || height == 0 {
        return Err(header(format!("image size {width}x{height} is empty")));
    }
    if width > u64::from(MAX_DIMENSION) || height > u64::from(MAX_DIMENSION) {
        return Err(header(format!(
            "image size {width}x{height} exceeds the limit of {MAX_DIMENSION} pixels a side"
        )));
    }
    let pixels = width * height;
    if pixels > MAX_PIXELS {
        return Err(header(format!(
            "image size {width}x{height} exceeds the limit of {MAX_PIXELS} pixels"
        )));
    }
    usize::try_from(pixels).map_err(|_| {
        header(format!(
            "image size {width}x{height} is too large for this machine"
        ))
    })
}

/// Checks that `dst` fits `info`; returns its length.
pub(crate) fn check_dest(
    path: &str,
    info: &VideoInfo,
    dst: &FrameDest<'_>,
) -> Result<(), VideoError> {
    let expected = u64::from(info.width) * u64::from(info.height);
    let (depth, len) = match dst {
        FrameDest::U8(p) => (Depth::U8, p.len()),
        FrameDest::U16(p) => (Depth::U16, p.len()),
    };
    if depth != info.depth {
        return Err(VideoError::Destination {
            path: path.to_string(),
            message: format!("got a {depth:?} buffer for {:?} video", info.depth),
        });
    }
    if len as u64 != expected {
        return Err(VideoError::Destination {
            path: path.to_string(),
            message: format!(
                "length {len} does not match {}x{} = {expected} pixels",
                info.width, info.height
            ),
        });
    }
    Ok(())
}

/// Reads until `buf` is full or the source ends; returns the bytes read.
pub(crate) fn read_full<R: Read + ?Sized>(src: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    fill_with(buf, |rest, _| src.read(rest))
}

/// Fills `buf` through `read(rest, got)` (`rest` the unfilled part, `got`
/// the bytes already read) until it is full or `read` gives 0, retrying
/// an interrupted read; returns the bytes read.
pub(crate) fn fill_with(
    buf: &mut [u8],
    mut read: impl FnMut(&mut [u8], usize) -> io::Result<usize>,
) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match read(&mut buf[got..], got) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// Reads and discards up to `n` bytes; returns how many were there.
pub(crate) fn skip_bytes<R: Read + ?Sized>(src: &mut R, n: u64) -> io::Result<u64> {
    io::copy(&mut src.take(n), &mut io::sink())
}

/// Flips the rows of a row-major image in place (bottom-up to top-down).
pub(crate) fn flip_rows<T>(pixels: &mut [T], width: usize) {
    if width == 0 {
        return;
    }
    let rows = pixels.len() / width;
    for r in 0..rows / 2 {
        let (top, bottom) = pixels.split_at_mut((rows - 1 - r) * width);
        top[r * width..(r + 1) * width].swap_with_slice(&mut bottom[..width]);
    }
}

/// Shows a few bytes of untrusted input in a message, escaped and shortened.
pub(crate) fn preview(bytes: &[u8]) -> String {
    const MAX: usize = 32;
    let shown: String = bytes
        .iter()
        .take(MAX)
        .flat_map(|b| std::ascii::escape_default(*b))
        .map(char::from)
        .collect();
    if bytes.len() > MAX {
        format!("\"{shown}...\"")
    } else {
        format!("\"{shown}\"")
    }
}

#[cfg(test)]
pub(crate) mod test_util {
    use std::path::PathBuf;

    /// The shared real recordings (`shared/data` beside the repository), if
    /// present. The package's directory is read when the test runs (cargo
    /// sets it), not compiled in: a build at another path stays reusable.
    pub fn data_file(name: &str) -> Option<PathBuf> {
        let p = std::env::var_os("CARGO_MANIFEST_DIR")
            .map_or_else(
                || std::env::current_dir().unwrap_or_default(),
                std::path::PathBuf::from,
            )
            .join("../../../shared/data")
            .join(name);
        if p.is_file() {
            Some(p)
        } else {
            eprintln!("skipping: {} not found", p.display());
            None
        }
    }

    /// A small deterministic pseudo-random generator (xorshift64*).
    pub struct Rng(pub u64);
    impl Rng {
        pub fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }
        pub fn below(&mut self, n: u64) -> u64 {
            if n == 0 {
                0
            } else {
                self.next() % n
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extension_picks_reader() {
        assert_eq!(format_by_extension(Path::new("a/b.Y4M")), Format::Y4m);
        assert_eq!(format_by_extension(Path::new("x.cine")), Format::Cine);
        assert_eq!(format_by_extension(Path::new("x.cih")), Format::Mraw);
        assert_eq!(format_by_extension(Path::new("x.CIHX")), Format::Mraw);
        assert_eq!(format_by_extension(Path::new("x.mraw")), Format::Mraw);
        assert_eq!(format_by_extension(Path::new("x.mp4")), Format::Ffmpeg);
        assert_eq!(format_by_extension(Path::new("noext")), Format::Ffmpeg);
    }

    #[test]
    fn flip_rows_reverses_row_order() {
        let mut p = [1, 2, 3, 4, 5, 6, 7, 8, 9];
        flip_rows(&mut p, 3);
        assert_eq!(p, [7, 8, 9, 4, 5, 6, 1, 2, 3]);
        let mut q = [1u16, 2, 3, 4];
        flip_rows(&mut q, 2);
        assert_eq!(q, [3, 4, 1, 2]);
    }

    #[test]
    fn missing_file_is_io_error_naming_path() {
        for (name, fmt) in [
            ("/nonexistent/dir/missing.y4m", Format::Auto),
            ("/nonexistent/dir/missing.cine", Format::Auto),
            ("/nonexistent/dir/missing.cih", Format::Auto),
            ("/nonexistent/dir/missing.mp4", Format::Auto),
        ] {
            let e = open(Path::new(name), fmt).err();
            let e = match e {
                Some(e) => e,
                None => panic!("{name} opened"),
            };
            let msg = e.to_string();
            assert!(msg.starts_with(name), "{msg}");
            assert_eq!(e.path(), name);
            if !name.ends_with(".cih") {
                assert!(matches!(e, VideoError::Io { .. }), "{name}: {e:?}");
                assert!(msg.contains("not found"), "{msg}");
            }
        }
    }

    #[test]
    fn stdin_only_as_y4m() {
        let e = open(Path::new("-"), Format::Cine).err();
        assert!(matches!(e, Some(VideoError::Unsupported { .. })), "{e:?}");
    }

    #[test]
    fn dest_checks() {
        let info = VideoInfo {
            format_name: "y4m",
            width: 4,
            height: 2,
            depth: Depth::U8,
            bits: 8,
            frame_count: None,
            fps: None,
            has_timestamps: false,
            exposure_s: None,
            notes: vec![],
        };
        let mut a = [0u8; 8];
        assert!(check_dest("p", &info, &FrameDest::U8(&mut a)).is_ok());
        let mut b = [0u8; 7];
        assert!(check_dest("p", &info, &FrameDest::U8(&mut b)).is_err());
        let mut c = [0u16; 8];
        assert!(check_dest("p", &info, &FrameDest::U16(&mut c)).is_err());
    }
}
