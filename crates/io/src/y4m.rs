//! YUV4MPEG2 (`.y4m`): reader (luma plane of any planar 8- or 16-bit
//! colour space) and writer (`Cmono` / `Cmono16`, with `Xts=<ns>` frame
//! timestamps).
//!
//! Stream header: `YUV4MPEG2 W<w> H<h> F<n>:<d> [I<i>] [A<n>:<d>] [C<cs>] [X<...>]`,
//! then frames, each `FRAME [params]\n` and the planes. Samples wider than
//! 8 bits take 2 bytes, little-endian.

use super::{
    check_dest, check_dimensions, display_name, io_error, preview, read_full, skip_bytes, Depth,
    FrameDest, FrameDestRef, FrameRead, VideoError, VideoInfo, VideoReader, MAX_HEADER_LINE,
    STDIN_NAME,
};
use std::fs::File;
use std::io::{self, BufRead, BufReader, Seek, SeekFrom, Write};
use std::path::Path;

const MAGIC: &[u8] = b"YUV4MPEG2";
/// Size of the scratch buffer for 16-bit samples and of file read buffers.
const CHUNK: usize = 64 * 1024;
/// The buffer of a seekable file of large mono frames (see [`Y4mReader::open`]).
const HEADER_CHUNK: usize = 4 * 1024;

/// How one line read with [`read_line_bounded`] ended.
#[derive(Debug, PartialEq, Eq)]
enum Line {
    /// A whole line (without its `\n`) is in the buffer.
    Complete,
    /// The source ended before any byte.
    Eof,
    /// The source ended in the middle of a line (the part is in the buffer).
    Partial,
    /// The line is longer than the limit (nothing more was consumed than the limit).
    TooLong,
}

/// Reads one `\n`-terminated line of at most `max` bytes into `buf`.
fn read_line_bounded<R: BufRead + ?Sized>(
    src: &mut R,
    buf: &mut Vec<u8>,
    max: usize,
) -> io::Result<Line> {
    buf.clear();
    loop {
        let avail = match src.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if avail.is_empty() {
            return Ok(if buf.is_empty() {
                Line::Eof
            } else {
                Line::Partial
            });
        }
        if let Some(i) = avail.iter().position(|&b| b == b'\n') {
            if buf.len() + i > max {
                return Ok(Line::TooLong);
            }
            buf.extend_from_slice(&avail[..i]);
            src.consume(i + 1);
            return Ok(Line::Complete);
        }
        let n = avail.len();
        if buf.len() + n > max {
            return Ok(Line::TooLong);
        }
        buf.extend_from_slice(avail);
        src.consume(n);
    }
}

/// Layout of one frame, from the stream header.
#[derive(Clone, Copy, Debug)]
struct Layout {
    /// Bytes per sample: 1 or 2.
    sample_bytes: usize,
    /// Bytes of the luma plane.
    luma_bytes: u64,
    /// Bytes after the luma plane (chroma and alpha planes), skipped.
    skip_bytes: u64,
}

impl Layout {
    fn frame_bytes(&self) -> u64 {
        self.luma_bytes + self.skip_bytes
    }
}

/// Sample bits and the number of non-luma samples per frame for a colour space.
fn colour_space(cs: &str, w: u64, h: u64) -> Option<(u8, u64)> {
    let half_w = w.div_ceil(2);
    let half_h = h.div_ceil(2);
    match cs {
        "mono" => return Some((8, 0)),
        "mono9" => return Some((9, 0)),
        "mono10" => return Some((10, 0)),
        "mono12" => return Some((12, 0)),
        "mono14" => return Some((14, 0)),
        "mono16" => return Some((16, 0)),
        "420" | "420jpeg" | "420paldv" | "420mpeg2" => return Some((8, 2 * half_w * half_h)),
        "411" => return Some((8, 2 * w.div_ceil(4) * h)),
        "444alpha" => return Some((8, 3 * w * h)),
        _ => {}
    }
    let (sub, rest) = cs.split_at_checked(3)?;
    let plane = match sub {
        "420" => half_w * half_h,
        "422" => half_w * h,
        "444" => w * h,
        _ => return None,
    };
    let bits = match rest {
        "" => 8,
        "p9" => 9,
        "p10" => 10,
        "p12" => 12,
        "p14" => 14,
        "p16" => 16,
        _ => return None,
    };
    Some((bits, 2 * plane))
}

/// The parsed stream header.
struct StreamHeader {
    width: u32,
    height: u32,
    fps_num: u64,
    fps_den: u64,
    bits: u8,
    colour: String,
    layout: Layout,
}

fn parse_stream_header(name: &str, line: &[u8]) -> Result<StreamHeader, VideoError> {
    let err = |message: String| VideoError::Header {
        path: name.to_string(),
        message,
    };
    let rest = line
        .strip_prefix(MAGIC)
        .filter(|r| r.is_empty() || r[0] == b' ')
        .ok_or_else(|| {
            err(format!(
                "not a YUV4MPEG2 stream (starts with {})",
                preview(line)
            ))
        })?;
    let text =
        std::str::from_utf8(rest).map_err(|_| err("header is not ASCII text".to_string()))?;
    let mut width = None;
    let mut height = None;
    let mut rate = None;
    let mut colour = None;
    for tok in text.split(' ').filter(|t| !t.is_empty()) {
        let Some((tag, value)) = tok.split_at_checked(1) else {
            tracing::debug!(
                path = name,
                token = tok,
                "ignoring non-ASCII Y4M header parameter"
            );
            continue;
        };
        match tag {
            "W" => {
                width = Some(
                    parse_dim(value)
                        .ok_or_else(|| err(format!("width W{value} is not a positive number")))?,
                )
            }
            "H" => {
                height = Some(
                    parse_dim(value)
                        .ok_or_else(|| err(format!("height H{value} is not a positive number")))?,
                )
            }
            "F" => {
                let (n, d) = parse_ratio(value)
                    .ok_or_else(|| err(format!("frame rate F{value} is not of the form n:d")))?;
                if n == 0 {
                    return Err(err(format!("frame rate F{value} is zero")));
                }
                if d == 0 {
                    return Err(err(format!("frame rate F{value} has a zero denominator")));
                }
                rate = Some((n, d));
            }
            "C" => colour = Some(value.to_string()),
            // Interlacing, pixel aspect and extensions do not change the luma plane.
            "I" | "A" | "X" => {}
            _ => tracing::debug!(
                path = name,
                token = tok,
                "ignoring unknown Y4M header parameter"
            ),
        }
    }
    let width = width.ok_or_else(|| err("missing width (W)".to_string()))?;
    let height = height.ok_or_else(|| err("missing height (H)".to_string()))?;
    let (fps_num, fps_den) = rate.ok_or_else(|| err("missing frame rate (F)".to_string()))?;
    let pixels = check_dimensions(name, u64::from(width), u64::from(height))?;
    let colour = colour.unwrap_or_else(|| "420jpeg".to_string());
    let (bits, extra) = colour_space(&colour, u64::from(width), u64::from(height))
        .ok_or_else(|| err(format!("unknown colour space C{colour}")))?;
    let sample_bytes: usize = if bits > 8 { 2 } else { 1 };
    let layout = Layout {
        sample_bytes,
        luma_bytes: pixels as u64 * sample_bytes as u64,
        skip_bytes: extra * sample_bytes as u64,
    };
    Ok(StreamHeader {
        width,
        height,
        fps_num,
        fps_den,
        bits,
        colour,
        layout,
    })
}

fn parse_dim(s: &str) -> Option<u32> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse::<u32>().ok().filter(|&v| v > 0)
}

fn parse_ratio(s: &str) -> Option<(u64, u64)> {
    let (n, d) = s.split_once(':')?;
    let num = |t: &str| {
        if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit()) {
            None
        } else {
            t.parse::<u32>().ok().map(u64::from)
        }
    };
    Some((num(n)?, num(d)?))
}

/// What the next frame header said.
enum Peek {
    /// Nothing peeked.
    Nothing,
    /// A frame header with its timestamp, pixels not yet read.
    Frame(Option<i64>),
    /// The stream ended cleanly.
    End,
    /// The frame header was bad.
    Error(VideoError),
}

/// Reads Y4M from any buffered source: a file, standard input, a pipe.
pub struct Y4mReader<R: BufRead> {
    src: R,
    name: String,
    info: VideoInfo,
    layout: Layout,
    /// Byte length of the stream header line, with its newline.
    header_len: u64,
    line: Vec<u8>,
    /// Scratch for 16-bit samples (empty for 8-bit video).
    scratch: Vec<u8>,
    peek: Peek,
    next_frame: u64,
    done: bool,
}

impl Y4mReader<BufReader<File>> {
    /// Opens a Y4M file; counts its frames by seeking over their pixels.
    pub fn open(path: &Path) -> Result<Self, VideoError> {
        let name = display_name(path);
        let file = File::open(path).map_err(|e| io_error(&name, e))?;
        let file_len = file.metadata().map_err(|e| io_error(&name, e))?.len();
        let mut r = Self::from_reader(BufReader::with_capacity(CHUNK, file), &name)?;
        r.count_frames(file_len)?;
        // Frames of 32 KiB and more with nothing to skip (mono): a small
        // buffer for the frame headers, so that most of each frame's pixels
        // are read straight into the frame (`BufReader` bypasses its buffer
        // for a read at least as long as it, once the buffer is empty)
        // rather than into the buffer and copied again: 20% of the source's
        // CPU time at 256x256. The counting's seek left the buffer empty,
        // so nothing is lost by the swap.
        if r.layout.skip_bytes == 0 && r.layout.luma_bytes >= 32 * 1024 && r.src.buffer().is_empty()
        {
            r.src = BufReader::with_capacity(HEADER_CHUNK, r.src.into_inner());
        }
        Ok(r)
    }

    /// Scans the frame headers of a seekable file, then returns to where it
    /// was. Returns where the last whole frame ends (the header's end when
    /// there is none).
    fn count_frames(&mut self, file_len: u64) -> Result<u64, VideoError> {
        let frame_bytes = self.layout.frame_bytes();
        let mut pos = self.header_len;
        let mut end = self.header_len;
        let resume = match &self.peek {
            Peek::Frame(_) => {
                pos += self.line.len() as u64 + 1;
                pos
            }
            _ => {
                // Nothing to count beyond an end or a bad first frame header.
                self.info.frame_count = Some(0);
                return Ok(end);
            }
        };
        let mut count = 0u64;
        let mut line = Vec::new();
        loop {
            // `pos` is at the start of a frame's pixels.
            if file_len.saturating_sub(pos) < frame_bytes {
                self.info.notes.push(format!(
                    "the file ends inside frame {count} ({} of {frame_bytes} bytes present)",
                    file_len.saturating_sub(pos)
                ));
                break;
            }
            count += 1;
            pos += frame_bytes;
            end = pos;
            // Small direct reads: the buffered reader would fetch 64 KiB per frame.
            match line_at(self.src.get_mut(), pos, &mut line)
                .map_err(|e| io_error(&self.name, e))?
            {
                Line::Eof => break,
                Line::Complete if parse_frame_header(&line).is_ok() => pos += line.len() as u64 + 1,
                _ => {
                    self.info.notes.push(format!(
                        "frame header {count} is damaged; frames from there on cannot be read"
                    ));
                    break;
                }
            }
        }
        self.info.frame_count = Some(count);
        self.src
            .seek(SeekFrom::Start(resume))
            .map_err(|e| io_error(&self.name, e))?;
        Ok(end)
    }
}

/// Cuts a Y4M file after its last whole frame (a write that failed part way,
/// on a full disk, may leave part of a frame): shortening a file needs no
/// new space. Returns the whole frames kept.
pub fn cut_to_whole_frames(path: &Path) -> Result<u64, VideoError> {
    let name = display_name(path);
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
        .map_err(|e| io_error(&name, e))?;
    let file_len = file.metadata().map_err(|e| io_error(&name, e))?.len();
    let mut r = Y4mReader::from_reader(BufReader::with_capacity(CHUNK, file), &name)?;
    let end = r.count_frames(file_len)?;
    if end < file_len {
        r.src
            .get_mut()
            .set_len(end)
            .map_err(|e| io_error(&name, e))?;
    }
    Ok(r.info.frame_count.unwrap_or(0))
}

/// Reads the line starting at `pos` of a file (at most [`MAX_HEADER_LINE`] bytes).
fn line_at(file: &mut File, pos: u64, buf: &mut Vec<u8>) -> io::Result<Line> {
    #[cfg(not(unix))]
    file.seek(SeekFrom::Start(pos))?;
    buf.clear();
    // Most frame headers are short: try a small read first.
    let mut want = 128;
    loop {
        let start = buf.len();
        buf.resize(start + want, 0);
        // One positioned read where the system has it (a seek and a read
        // otherwise): the count reads every frame's header.
        #[cfg(unix)]
        let got = {
            use std::os::unix::fs::FileExt;
            let at = pos + start as u64;
            super::fill_with(&mut buf[start..], |rest, got| {
                file.read_at(rest, at + got as u64)
            })?
        };
        #[cfg(not(unix))]
        let got = read_full(file, &mut buf[start..])?;
        buf.truncate(start + got);
        if let Some(i) = buf[start..].iter().position(|&b| b == b'\n') {
            buf.truncate(start + i);
            return Ok(if buf.len() > MAX_HEADER_LINE {
                Line::TooLong
            } else {
                Line::Complete
            });
        }
        if buf.len() > MAX_HEADER_LINE {
            return Ok(Line::TooLong);
        }
        if got < want {
            return Ok(if buf.is_empty() {
                Line::Eof
            } else {
                Line::Partial
            });
        }
        want = MAX_HEADER_LINE + 1 - buf.len();
    }
}

impl Y4mReader<BufReader<io::Stdin>> {
    /// Reads Y4M from standard input.
    pub fn stdin() -> Result<Self, VideoError> {
        Self::from_reader(BufReader::with_capacity(CHUNK, io::stdin()), STDIN_NAME)
    }
}

impl<R: BufRead> Y4mReader<R> {
    /// Parses the stream header and peeks at the first frame header.
    /// `name` appears in error messages. The frame count stays unknown.
    pub fn from_reader(mut src: R, name: &str) -> Result<Self, VideoError> {
        let mut line = Vec::new();
        let header_err = |message: &str| VideoError::Header {
            path: name.to_string(),
            message: message.to_string(),
        };
        match read_line_bounded(&mut src, &mut line, MAX_HEADER_LINE)
            .map_err(|e| io_error(name, e))?
        {
            Line::Complete => {}
            Line::Eof => return Err(header_err("the stream is empty")),
            Line::Partial => {
                if line.starts_with(MAGIC) || MAGIC.starts_with(&line) {
                    return Err(header_err("the stream ends inside the header line"));
                }
                return Err(header_err(&format!(
                    "not a YUV4MPEG2 stream (starts with {})",
                    preview(&line)
                )));
            }
            Line::TooLong => {
                return Err(header_err(&format!(
                    "header line longer than {MAX_HEADER_LINE} bytes"
                )));
            }
        }
        let header_len = line.len() as u64 + 1;
        let h = parse_stream_header(name, &line)?;
        let mut notes = Vec::new();
        if h.colour != "mono" && h.colour != "mono16" {
            notes.push(format!(
                "colour space C{}: reading the luma plane only",
                h.colour
            ));
        }
        notes.push(format!("frame rate F{}:{}", h.fps_num, h.fps_den));
        let info = VideoInfo {
            format_name: "y4m",
            width: h.width,
            height: h.height,
            depth: if h.layout.sample_bytes == 2 {
                Depth::U16
            } else {
                Depth::U8
            },
            bits: h.bits,
            frame_count: None,
            fps: Some(h.fps_num as f64 / h.fps_den as f64),
            has_timestamps: false,
            exposure_s: None,
            notes,
        };
        let scratch = if h.layout.sample_bytes == 2 {
            vec![0u8; CHUNK]
        } else {
            Vec::new()
        };
        let mut reader = Y4mReader {
            src,
            name: name.to_string(),
            info,
            layout: h.layout,
            header_len,
            line,
            scratch,
            peek: Peek::Nothing,
            next_frame: 0,
            done: false,
        };
        reader.peek = match reader.read_frame_header() {
            Ok(Some(ts)) => Peek::Frame(ts),
            Ok(None) => Peek::End,
            Err(e) => Peek::Error(e),
        };
        reader.info.has_timestamps = matches!(reader.peek, Peek::Frame(Some(_)));
        Ok(reader)
    }

    /// Reads the next frame header: Some(timestamp) or None at a clean end.
    fn read_frame_header(&mut self) -> Result<Option<Option<i64>>, VideoError> {
        let frame = self.next_frame;
        let bad = |name: &str, message: String| VideoError::BadFrame {
            path: name.to_string(),
            frame,
            message,
        };
        match read_line_bounded(&mut self.src, &mut self.line, MAX_HEADER_LINE)
            .map_err(|e| io_error(&self.name, e))?
        {
            Line::Eof => Ok(None),
            Line::Complete => parse_frame_header(&self.line)
                .map(Some)
                .map_err(|m| bad(&self.name, m)),
            Line::Partial => Err(VideoError::Truncated {
                path: self.name.clone(),
                frame,
                got: 0,
                expected: self.layout.frame_bytes(),
            }),
            Line::TooLong => Err(bad(
                &self.name,
                format!("frame header longer than {MAX_HEADER_LINE} bytes"),
            )),
        }
    }

    fn read_pixels(&mut self, dst: FrameDest<'_>) -> Result<(), VideoError> {
        let frame = self.next_frame;
        let expected = self.layout.frame_bytes();
        let truncated = |name: &str, got: u64| VideoError::Truncated {
            path: name.to_string(),
            frame,
            got,
            expected,
        };
        let mut got: u64 = 0;
        match dst {
            FrameDest::U8(px) => {
                let n = read_full(&mut self.src, px).map_err(|e| io_error(&self.name, e))?;
                got += n as u64;
                if n < px.len() {
                    return Err(truncated(&self.name, got));
                }
            }
            FrameDest::U16(px) => {
                let mut done = 0;
                while done < px.len() {
                    let want = ((px.len() - done) * 2).min(self.scratch.len());
                    let buf = &mut self.scratch[..want];
                    let n = read_full(&mut self.src, buf).map_err(|e| io_error(&self.name, e))?;
                    got += n as u64;
                    for (d, s) in px[done..].iter_mut().zip(buf[..n].chunks_exact(2)) {
                        *d = u16::from_le_bytes([s[0], s[1]]);
                    }
                    if n < want {
                        return Err(truncated(&self.name, got));
                    }
                    done += want / 2;
                }
            }
        }
        let skipped = skip_bytes(&mut self.src, self.layout.skip_bytes)
            .map_err(|e| io_error(&self.name, e))?;
        got += skipped;
        if skipped < self.layout.skip_bytes {
            return Err(truncated(&self.name, got));
        }
        Ok(())
    }

    fn next(&mut self, dst: FrameDest<'_>) -> Result<Option<FrameRead>, VideoError> {
        let timestamp_ns = match std::mem::replace(&mut self.peek, Peek::Nothing) {
            Peek::Frame(ts) => ts,
            Peek::End => return Ok(None),
            Peek::Error(e) => return Err(e),
            Peek::Nothing => match self.read_frame_header()? {
                Some(ts) => ts,
                None => return Ok(None),
            },
        };
        self.read_pixels(dst)?;
        self.next_frame += 1;
        Ok(Some(FrameRead { timestamp_ns }))
    }
}

impl<R: BufRead + Send> VideoReader for Y4mReader<R> {
    fn info(&self) -> &VideoInfo {
        &self.info
    }

    fn read_frame(&mut self, dst: FrameDest<'_>) -> Result<Option<FrameRead>, VideoError> {
        check_dest(&self.name, &self.info, &dst)?;
        if self.done {
            return Ok(None);
        }
        let r = self.next(dst);
        if !matches!(r, Ok(Some(_))) {
            self.done = true;
        }
        r
    }
}

/// Parses a frame header line: `FRAME` then optional space-separated params.
/// Returns the `Xts=<ns>` timestamp if there is one.
fn parse_frame_header(line: &[u8]) -> Result<Option<i64>, String> {
    let rest = line
        .strip_prefix(b"FRAME")
        .filter(|r| r.is_empty() || r[0] == b' ')
        .ok_or_else(|| {
            format!(
                "frame header does not start with FRAME (found {})",
                preview(line)
            )
        })?;
    let mut ts = None;
    for tok in rest.split(|&b| b == b' ').filter(|t| !t.is_empty()) {
        if let Some(v) = tok.strip_prefix(b"Xts=") {
            let parsed = std::str::from_utf8(v)
                .ok()
                .and_then(|s| s.parse::<i64>().ok());
            ts = Some(parsed.ok_or_else(|| format!("bad timestamp {}", preview(tok)))?);
        }
    }
    Ok(ts)
}

/// Best rational `n/d` for a frame rate: exact for integers, `k*1000/1001`
/// for NTSC-style rates (29.97 -> 30000/1001), else a continued-fraction
/// approximation with a denominator up to 1 000 000.
pub(crate) fn fps_rational(fps: f64) -> Option<(u32, u32)> {
    if !fps.is_finite() || fps <= 0.0 || fps > f64::from(u32::MAX) {
        return None;
    }
    if fps.fract() == 0.0 {
        return Some((fps as u32, 1));
    }
    let k = (fps * 1.001).round();
    if k >= 1.0
        && k * 1000.0 <= f64::from(u32::MAX)
        && ((k * 1000.0 / 1001.0) - fps).abs() <= fps * 1e-5
    {
        return Some(((k * 1000.0) as u32, 1001));
    }
    // Continued fraction convergents h/k of fps.
    let (mut h0, mut h1) = (0u64, 1u64);
    let (mut k0, mut k1) = (1u64, 0u64);
    let mut x = fps;
    let mut best = None;
    for _ in 0..64 {
        let a = x.floor();
        if a > f64::from(u32::MAX) {
            break;
        }
        let a = a as u64;
        let h2 = a.checked_mul(h1).and_then(|v| v.checked_add(h0));
        let k2 = a.checked_mul(k1).and_then(|v| v.checked_add(k0));
        let (Some(h2), Some(k2)) = (h2, k2) else {
            break;
        };
        if h2 > u64::from(u32::MAX) || k2 > 1_000_000 {
            break;
        }
        best = Some((h2 as u32, k2 as u32));
        (h0, h1, k0, k1) = (h1, h2, k1, k2);
        if ((h2 as f64 / k2 as f64) - fps).abs() <= fps * 1e-12 {
            break;
        }
        let f = x - x.floor();
        if f < 1e-12 {
            break;
        }
        x = 1.0 / f;
    }
    best.filter(|&(n, d)| n > 0 && d > 0)
}

/// Writes frames as Y4M: `Cmono` (8-bit) or `Cmono16` (16-bit little-endian).
pub struct Y4mWriter<W: Write> {
    out: W,
    width: u32,
    height: u32,
    depth: Depth,
    /// Scratch for 16-bit samples.
    scratch: Vec<u8>,
}

impl<W: Write> Y4mWriter<W> {
    /// depth U8 -> "Cmono", U16 -> "Cmono16" (little-endian 16-bit). fps written as a rational
    /// (2200 -> F2200:1, 29.97 -> F30000:1001).
    pub fn new(
        mut out: W,
        width: u32,
        height: u32,
        depth: Depth,
        fps: f64,
    ) -> Result<Self, io::Error> {
        let invalid = |m: String| io::Error::new(io::ErrorKind::InvalidInput, m);
        if width == 0 || height == 0 {
            return Err(invalid(format!("Y4M frame size {width}x{height} is empty")));
        }
        let (n, d) = fps_rational(fps)
            .ok_or_else(|| invalid(format!("Y4M frame rate {fps} is not a positive number")))?;
        let cs = match depth {
            Depth::U8 => "mono",
            Depth::U16 => "mono16",
        };
        writeln!(
            out,
            "YUV4MPEG2 W{width} H{height} F{n}:{d} Ip A1:1 C{cs} XCOLORRANGE=FULL"
        )?;
        let scratch = match depth {
            Depth::U8 => Vec::new(),
            Depth::U16 => vec![0u8; CHUNK],
        };
        Ok(Y4mWriter {
            out,
            width,
            height,
            depth,
            scratch,
        })
    }

    /// Writes "FRAME Xts=<ns>\n" (when timestamp_ns is Some) then the pixels.
    pub fn write_frame(
        &mut self,
        pixels: FrameDestRef<'_>,
        timestamp_ns: Option<i64>,
    ) -> Result<(), io::Error> {
        self.write_frame_seq(pixels, timestamp_ns, None)
    }

    /// Like [`Y4mWriter::write_frame`], adding the source's sequence number
    /// (`FRAME Xts=<ns> Xseq=<n>`): a camera's gaps stay visible in the file.
    /// Readers ignore the field.
    pub fn write_frame_seq(
        &mut self,
        pixels: FrameDestRef<'_>,
        timestamp_ns: Option<i64>,
        seq: Option<u64>,
    ) -> Result<(), io::Error> {
        let expected = u64::from(self.width) * u64::from(self.height);
        let (depth, len) = match pixels {
            FrameDestRef::U8(p) => (Depth::U8, p.len()),
            FrameDestRef::U16(p) => (Depth::U16, p.len()),
        };
        if depth != self.depth || len as u64 != expected {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "Y4M writer: got {len} {depth:?} pixels, expected {}x{} = {expected} {:?} pixels",
                    self.width, self.height, self.depth
                ),
            ));
        }
        match (timestamp_ns, seq) {
            (Some(ts), Some(n)) => writeln!(self.out, "FRAME Xts={ts} Xseq={n}")?,
            (Some(ts), None) => writeln!(self.out, "FRAME Xts={ts}")?,
            (None, Some(n)) => writeln!(self.out, "FRAME Xseq={n}")?,
            (None, None) => self.out.write_all(b"FRAME\n")?,
        }
        match pixels {
            FrameDestRef::U8(p) => self.out.write_all(p)?,
            FrameDestRef::U16(p) => {
                for chunk in p.chunks(self.scratch.len() / 2) {
                    let bytes = &mut self.scratch[..chunk.len() * 2];
                    for (d, s) in bytes.chunks_exact_mut(2).zip(chunk) {
                        d.copy_from_slice(&s.to_le_bytes());
                    }
                    self.out.write_all(bytes)?;
                }
            }
        }
        Ok(())
    }

    /// Flushes and returns the output.
    pub fn finish(mut self) -> Result<W, io::Error> {
        self.out.flush()?;
        Ok(self.out)
    }

    /// Returns the output after flushing it (a flush error is logged; use
    /// [`Y4mWriter::finish`] to get it).
    pub fn into_inner(mut self) -> W {
        if let Err(e) = self.out.flush() {
            tracing::warn!(error = %e, "Y4M writer: flush failed");
        }
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::Rng;
    use super::*;
    use std::io::Cursor;

    /// Frames read back, with their timestamps.
    type Frames<T> = Vec<(Vec<T>, Option<i64>)>;

    fn reader(bytes: &[u8]) -> Result<Y4mReader<Cursor<&[u8]>>, VideoError> {
        Y4mReader::from_reader(Cursor::new(bytes), "mem.y4m")
    }

    fn read_all_u8(r: &mut dyn VideoReader) -> Result<Frames<u8>, VideoError> {
        let n = (r.info().width * r.info().height) as usize;
        let mut out = Vec::new();
        loop {
            let mut buf = vec![0u8; n];
            match r.read_frame(FrameDest::U8(&mut buf))? {
                Some(f) => out.push((buf, f.timestamp_ns)),
                None => return Ok(out),
            }
        }
    }

    /// A file cut inside its third frame (or its third frame's header)
    /// keeps two whole frames; a whole file is left as it is.
    #[test]
    fn cut_to_whole_frames_drops_a_partial_frame() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("a.y4m");
        let whole =
            b"YUV4MPEG2 W2 H1 F25:1 Cmono\nFRAME Xts=0\nabFRAME\ncdFRAME Xts=9\nef".to_vec();
        for cut in [whole.len() - 1, whole.len() - 3, whole.len() - 8] {
            std::fs::write(&p, &whole[..cut]).expect("write");
            assert_eq!(cut_to_whole_frames(&p).expect("cut"), 2, "cut at {cut}");
            let kept = std::fs::read(&p).expect("read");
            assert_eq!(kept, &whole[..whole.len() - 14], "cut at {cut}");
        }
        std::fs::write(&p, &whole).expect("write");
        assert_eq!(cut_to_whole_frames(&p).expect("cut"), 3);
        assert_eq!(std::fs::read(&p).expect("read"), whole);
    }

    fn read_all_u16(r: &mut dyn VideoReader) -> Result<Frames<u16>, VideoError> {
        let n = (r.info().width * r.info().height) as usize;
        let mut out = Vec::new();
        loop {
            let mut buf = vec![0u16; n];
            match r.read_frame(FrameDest::U16(&mut buf))? {
                Some(f) => out.push((buf, f.timestamp_ns)),
                None => return Ok(out),
            }
        }
    }

    fn sample_u8(frames: usize, w: u32, h: u32, with_ts: bool) -> (Vec<u8>, Vec<Vec<u8>>) {
        let mut wr = Y4mWriter::new(Vec::new(), w, h, Depth::U8, 2200.0).expect("writer");
        let mut all = Vec::new();
        for f in 0..frames {
            let px: Vec<u8> = (0..w * h)
                .map(|i| (i as usize * 7 + f * 13) as u8)
                .collect();
            wr.write_frame(FrameDestRef::U8(&px), with_ts.then_some(f as i64 * 454_545))
                .expect("write");
            all.push(px);
        }
        (wr.into_inner(), all)
    }

    #[test]
    fn round_trip_u8_with_timestamps() {
        let (bytes, frames) = sample_u8(5, 7, 3, true);
        assert!(bytes.starts_with(b"YUV4MPEG2 W7 H3 F2200:1 "));
        let mut r = reader(&bytes).expect("open");
        assert_eq!(r.info().depth, Depth::U8);
        assert_eq!(r.info().bits, 8);
        assert_eq!(r.info().fps, Some(2200.0));
        assert!(r.info().has_timestamps);
        let got = read_all_u8(&mut r).expect("read");
        assert_eq!(got.len(), 5);
        for (i, (px, ts)) in got.iter().enumerate() {
            assert_eq!(px, &frames[i]);
            assert_eq!(*ts, Some(i as i64 * 454_545));
        }
        // Finished readers stay finished.
        let mut buf = vec![0u8; 21];
        assert!(matches!(r.read_frame(FrameDest::U8(&mut buf)), Ok(None)));
    }

    #[test]
    fn round_trip_u16_with_timestamps_through_a_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("deep.y4m");
        let (w, h) = (300u32, 200u32); // > one 64 KiB scratch chunk per frame
        let mut frames = Vec::new();
        {
            let file = std::io::BufWriter::new(File::create(&path).expect("create"));
            let mut wr = Y4mWriter::new(file, w, h, Depth::U16, 29.97).expect("writer");
            for f in 0..4u32 {
                let px: Vec<u16> = (0..w * h)
                    .map(|i| (i.wrapping_mul(2654435761) >> 16) as u16 ^ f as u16)
                    .collect();
                wr.write_frame(FrameDestRef::U16(&px), Some(-5 + i64::from(f) * 33_366_667))
                    .expect("write");
                frames.push(px);
            }
            wr.finish().expect("finish");
        }
        let head = std::fs::read(&path).expect("read back");
        assert!(head.starts_with(b"YUV4MPEG2 W300 H200 F30000:1001 Ip A1:1 Cmono16"));
        let mut r = super::super::open(&path, super::super::Format::Auto).expect("open");
        let info = r.info().clone();
        assert_eq!(
            (info.width, info.height, info.depth, info.bits),
            (300, 200, Depth::U16, 16)
        );
        assert_eq!(info.frame_count, Some(4));
        assert!(info.has_timestamps);
        let got = read_all_u16(r.as_mut()).expect("read");
        assert_eq!(got.len(), 4);
        for (i, (px, ts)) in got.iter().enumerate() {
            assert!(px == &frames[i], "frame {i} differs");
            assert_eq!(*ts, Some(-5 + i as i64 * 33_366_667));
        }
    }

    #[test]
    fn without_timestamps() {
        let (bytes, _) = sample_u8(2, 4, 4, false);
        let mut r = reader(&bytes).expect("open");
        assert!(!r.info().has_timestamps);
        let got = read_all_u8(&mut r).expect("read");
        assert_eq!(got.len(), 2);
        assert!(got.iter().all(|(_, ts)| ts.is_none()));
    }

    #[test]
    fn luma_of_420_and_422_and_444() {
        // 5x3: chroma planes of 420 are ceil(5/2)*ceil(3/2) = 6 samples each.
        let luma: Vec<u8> = (10..25).collect();
        for (cs, chroma) in [
            ("", 12usize),
            (" C420jpeg", 12),
            (" C420mpeg2", 12),
            (" C422", 18),
            (" C444", 30),
        ] {
            let mut s = format!("YUV4MPEG2 W5 H3 F25:1 Ip{cs}\n").into_bytes();
            for f in 0..2u8 {
                s.extend_from_slice(b"FRAME\n");
                s.extend(luma.iter().map(|v| v + f));
                s.extend(std::iter::repeat_n(128u8, chroma));
            }
            let mut r = reader(&s).expect("open");
            let got = read_all_u8(&mut r).expect("read");
            assert_eq!(got.len(), 2, "{cs}");
            assert_eq!(got[0].0, luma, "{cs}");
            assert_eq!(
                got[1].0,
                luma.iter().map(|v| v + 1).collect::<Vec<_>>(),
                "{cs}"
            );
        }
    }

    #[test]
    fn luma_of_420p10() {
        let mut s = b"YUV4MPEG2 W3 H2 F30:1 C420p10 XYSCSS=420P10\n".to_vec();
        s.extend_from_slice(b"FRAME\n");
        for v in [1u16, 2, 3, 1020, 1021, 1023] {
            s.extend_from_slice(&v.to_le_bytes());
        }
        s.extend(std::iter::repeat_n(0u8, 2 * 2 * 2)); // two 2x1 chroma planes, 2 bytes each
        let mut r = reader(&s).expect("open");
        assert_eq!((r.info().depth, r.info().bits), (Depth::U16, 10));
        let got = read_all_u16(&mut r).expect("read");
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].0, vec![1, 2, 3, 1020, 1021, 1023]);
    }

    #[test]
    fn truncated_frame_is_an_error_naming_counts() {
        let (bytes, _) = sample_u8(3, 8, 4, false);
        let cut = &bytes[..bytes.len() - 10];
        let mut r = reader(cut).expect("open");
        let mut buf = vec![0u8; 32];
        assert!(r
            .read_frame(FrameDest::U8(&mut buf))
            .expect("frame 0")
            .is_some());
        assert!(r
            .read_frame(FrameDest::U8(&mut buf))
            .expect("frame 1")
            .is_some());
        let e = r
            .read_frame(FrameDest::U8(&mut buf))
            .expect_err("truncated");
        assert!(
            matches!(
                e,
                VideoError::Truncated {
                    frame: 2,
                    got: 22,
                    expected: 32,
                    ..
                }
            ),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "mem.y4m: frame 2 is truncated (got 22 of 32 bytes)"
        );
        assert!(matches!(r.read_frame(FrameDest::U8(&mut buf)), Ok(None)));
    }

    #[test]
    fn truncated_file_counts_whole_frames() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("cut.y4m");
        let (bytes, _) = sample_u8(3, 8, 4, true);
        std::fs::write(&path, &bytes[..bytes.len() - 5]).expect("write");
        let mut r = Y4mReader::open(&path).expect("open");
        assert_eq!(r.info().frame_count, Some(2));
        assert!(
            r.info()
                .notes
                .iter()
                .any(|n| n.contains("ends inside frame 2")),
            "{:?}",
            r.info().notes
        );
        let mut buf = vec![0u8; 32];
        assert!(r.read_frame(FrameDest::U8(&mut buf)).expect("0").is_some());
        assert!(r.read_frame(FrameDest::U8(&mut buf)).expect("1").is_some());
        let e = r
            .read_frame(FrameDest::U8(&mut buf))
            .expect_err("truncated");
        assert!(matches!(e, VideoError::Truncated { frame: 2, .. }), "{e:?}");
        assert!(e.to_string().starts_with(&path.display().to_string()));
    }

    /// Large mono frames from a file go past the small buffer `open`
    /// gives them: the same pixels and times, and a cut last frame still
    /// named; small frames keep the large buffer.
    #[test]
    fn large_frames_from_a_file_read_past_the_small_buffer() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("large.y4m");
        // 33127 bytes a frame: more than 32 KiB, not a multiple of the buffer.
        let (bytes, frames) = sample_u8(4, 211, 157, true);
        std::fs::write(&path, &bytes[..bytes.len() - 5]).expect("write");
        let mut r = Y4mReader::open(&path).expect("open");
        assert_eq!(r.src.capacity(), HEADER_CHUNK);
        assert_eq!(r.info().frame_count, Some(3));
        let mut buf = vec![0u8; 211 * 157];
        for (i, want) in frames.iter().take(3).enumerate() {
            let got = r.read_frame(FrameDest::U8(&mut buf)).expect("frame");
            assert_eq!(got.map(|f| f.timestamp_ns), Some(Some(i as i64 * 454_545)));
            assert!(&buf == want, "frame {i}");
        }
        let e = r
            .read_frame(FrameDest::U8(&mut buf))
            .expect_err("truncated");
        assert!(matches!(e, VideoError::Truncated { frame: 3, .. }), "{e:?}");

        let small = dir.path().join("small.y4m");
        std::fs::write(&small, sample_u8(2, 64, 64, true).0).expect("write");
        let r = Y4mReader::open(&small).expect("open");
        assert_eq!(r.src.capacity(), CHUNK);
    }

    #[test]
    fn damaged_frame_header_mid_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("damaged.y4m");
        let (mut bytes, _) = sample_u8(3, 4, 2, false);
        // Frame headers are at header_len + k * (6 + 8): break the third one.
        let at = bytes.iter().position(|&b| b == b'\n').expect("header") + 1 + 2 * 14;
        assert_eq!(&bytes[at..at + 5], b"FRAME");
        bytes[at] = b'X';
        std::fs::write(&path, &bytes).expect("write");
        let mut r = Y4mReader::open(&path).expect("open");
        assert_eq!(r.info().frame_count, Some(2));
        assert!(
            r.info()
                .notes
                .iter()
                .any(|n| n.contains("frame header 2 is damaged")),
            "{:?}",
            r.info().notes
        );
        let mut buf = [0u8; 8];
        assert!(r.read_frame(FrameDest::U8(&mut buf)).expect("0").is_some());
        assert!(r.read_frame(FrameDest::U8(&mut buf)).expect("1").is_some());
        let e = r.read_frame(FrameDest::U8(&mut buf)).expect_err("damaged");
        assert!(
            e.to_string()
                .contains("frame 2: frame header does not start with FRAME (found \"XRAME\")"),
            "{e}"
        );
    }

    #[test]
    fn cut_frame_header_is_truncated() {
        let (bytes, _) = sample_u8(1, 2, 2, false);
        let mut s = bytes.clone();
        s.extend_from_slice(b"FRA");
        let mut r = reader(&s).expect("open");
        let mut buf = vec![0u8; 4];
        assert!(r.read_frame(FrameDest::U8(&mut buf)).expect("0").is_some());
        assert!(matches!(
            r.read_frame(FrameDest::U8(&mut buf)),
            Err(VideoError::Truncated { frame: 1, .. })
        ));
    }

    #[test]
    fn zero_frame_rate_names_value() {
        let e = reader(b"YUV4MPEG2 W2 H2 F0:1 Cmono\nFRAME\n\0\0\0\0")
            .err()
            .expect("error");
        assert_eq!(e.to_string(), "mem.y4m: header: frame rate F0:1 is zero");
        let e = reader(b"YUV4MPEG2 W2 H2 F25:0 Cmono\n")
            .err()
            .expect("error");
        assert!(
            e.to_string().contains("F25:0 has a zero denominator"),
            "{e}"
        );
    }

    #[test]
    fn malformed_headers() {
        let cases: &[(&[u8], &str)] = &[
            (b"", "empty"),
            (b"YUV4MPEG2 W2 H2 F25:1", "ends inside the header"),
            (b"RIFF....WAVEfmt \n", "not a YUV4MPEG2 stream"),
            (b"YUV4MPEG2X W2 H2 F25:1\n", "not a YUV4MPEG2 stream"),
            (b"YUV4MPEG2 H2 F25:1\n", "missing width (W)"),
            (b"YUV4MPEG2 W2 F25:1\n", "missing height (H)"),
            (b"YUV4MPEG2 W2 H2\n", "missing frame rate (F)"),
            (b"YUV4MPEG2 W0 H2 F25:1\n", "width W0"),
            (b"YUV4MPEG2 Wx H2 F25:1\n", "width Wx"),
            (b"YUV4MPEG2 W2 H-2 F25:1\n", "height H-2"),
            (
                b"YUV4MPEG2 W2 H2 F25\n",
                "frame rate F25 is not of the form",
            ),
            (b"YUV4MPEG2 W2 H2 F25:1 Crgb\n", "unknown colour space Crgb"),
            (b"YUV4MPEG2 W99999 H2 F25:1\n", "exceeds the limit"),
            (b"YUV4MPEG2 W30000 H30000 F25:1\n", "exceeds the limit"),
        ];
        for (bytes, want) in cases {
            let e = reader(bytes)
                .err()
                .unwrap_or_else(|| panic!("{} opened", String::from_utf8_lossy(bytes)));
            assert!(matches!(e, VideoError::Header { .. }), "{e:?}");
            assert!(e.to_string().contains(want), "{e} (wanted {want})");
        }
        let long = [b"YUV4MPEG2 W2 H2 F1:1 X".as_slice(), &[b'a'; 5000], b"\n"].concat();
        let e = reader(&long).err().expect("error");
        assert!(e.to_string().contains("longer than 4096"), "{e}");
    }

    #[test]
    fn bad_frame_headers() {
        let e = {
            let mut r = reader(b"YUV4MPEG2 W1 H1 F1:1 Cmono\nFRAMX\n\0").expect("open");
            let mut b = [0u8; 1];
            r.read_frame(FrameDest::U8(&mut b)).expect_err("error")
        };
        assert!(
            e.to_string()
                .contains("frame 0: frame header does not start with FRAME"),
            "{e}"
        );
        let e = {
            let mut r = reader(b"YUV4MPEG2 W1 H1 F1:1 Cmono\nFRAME Xts=12x\n\0").expect("open");
            let mut b = [0u8; 1];
            r.read_frame(FrameDest::U8(&mut b)).expect_err("error")
        };
        assert!(e.to_string().contains("bad timestamp"), "{e}");
    }

    #[test]
    fn wrong_destination_is_an_error() {
        let (bytes, _) = sample_u8(1, 4, 4, false);
        let mut r = reader(&bytes).expect("open");
        let mut small = vec![0u8; 3];
        assert!(matches!(
            r.read_frame(FrameDest::U8(&mut small)),
            Err(VideoError::Destination { .. })
        ));
        let mut deep = vec![0u16; 16];
        assert!(matches!(
            r.read_frame(FrameDest::U16(&mut deep)),
            Err(VideoError::Destination { .. })
        ));
        // The frame is still there for a correct buffer.
        let mut ok = vec![0u8; 16];
        assert!(r
            .read_frame(FrameDest::U8(&mut ok))
            .expect("read")
            .is_some());
    }

    #[test]
    fn empty_stream_after_header_has_no_frames() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("empty.y4m");
        std::fs::write(&path, b"YUV4MPEG2 W2 H2 F1:1 Cmono\n").expect("write");
        let mut r = Y4mReader::open(&path).expect("open");
        assert_eq!(r.info().frame_count, Some(0));
        let mut b = [0u8; 4];
        assert!(matches!(r.read_frame(FrameDest::U8(&mut b)), Ok(None)));
    }

    #[test]
    fn garbage_never_panics() {
        let (good, _) = sample_u8(3, 5, 3, true);
        let mut rng = Rng(0x1234_5678_9abc_def1);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("fuzz.y4m");
        for i in 0..600 {
            let mut bytes = match i % 3 {
                0 => good[..rng.below(good.len() as u64 + 1) as usize].to_vec(),
                1 => {
                    let mut b = good.clone();
                    for _ in 0..1 + rng.below(4) {
                        let at = rng.below(b.len() as u64) as usize;
                        b[at] = rng.next() as u8;
                    }
                    b
                }
                _ => (0..rng.below(200)).map(|_| rng.next() as u8).collect(),
            };
            if i % 7 == 0 {
                bytes.truncate(rng.below(bytes.len() as u64 + 1) as usize);
            }
            // In memory...
            if let Ok(mut r) = reader(&bytes) {
                let n = (r.info().width * r.info().height) as usize;
                drain(&mut r, n);
            }
            // ...and as a file (frame counting with seeks).
            std::fs::write(&path, &bytes).expect("write");
            if let Ok(mut r) = Y4mReader::open(&path) {
                let n = (r.info().width * r.info().height) as usize;
                drain(&mut r, n);
            }
        }
    }

    fn drain(r: &mut dyn VideoReader, n: usize) {
        for _ in 0..10 {
            let res = match r.info().depth {
                Depth::U8 => r.read_frame(FrameDest::U8(&mut vec![0u8; n])),
                Depth::U16 => r.read_frame(FrameDest::U16(&mut vec![0u16; n])),
            };
            match res {
                Ok(Some(_)) => {}
                Ok(None) => return,
                Err(e) => {
                    assert!(!e.to_string().is_empty());
                    return;
                }
            }
        }
    }

    #[test]
    fn rational_frame_rates() {
        assert_eq!(fps_rational(2200.0), Some((2200, 1)));
        assert_eq!(fps_rational(29.97), Some((30000, 1001)));
        assert_eq!(fps_rational(30000.0 / 1001.0), Some((30000, 1001)));
        assert_eq!(fps_rational(23.976), Some((24000, 1001)));
        assert_eq!(fps_rational(59.94), Some((60000, 1001)));
        assert_eq!(fps_rational(12.5), Some((25, 2)));
        assert_eq!(fps_rational(0.5), Some((1, 2)));
        let (n, d) = fps_rational(std::f64::consts::PI * 1000.0).expect("pi");
        assert!((f64::from(n) / f64::from(d) - std::f64::consts::PI * 1000.0).abs() < 1e-6);
        assert_eq!(fps_rational(0.0), None);
        assert_eq!(fps_rational(-1.0), None);
        assert_eq!(fps_rational(f64::NAN), None);
        assert_eq!(fps_rational(f64::INFINITY), None);
        assert!(fps_rational(1e-9).is_some() || fps_rational(1e-9).is_none()); // no panic
    }

    #[test]
    fn writer_rejects_wrong_frames() {
        let mut w = Y4mWriter::new(Vec::new(), 2, 2, Depth::U8, 10.0).expect("writer");
        assert!(w.write_frame(FrameDestRef::U8(&[0; 3]), None).is_err());
        assert!(w.write_frame(FrameDestRef::U16(&[0; 4]), None).is_err());
        assert!(Y4mWriter::new(Vec::new(), 2, 2, Depth::U8, 0.0).is_err());
        assert!(Y4mWriter::new(Vec::new(), 0, 2, Depth::U8, 10.0).is_err());
    }

    #[test]
    fn ffmpeg_reads_what_we_write() {
        // Our Cmono16 output must be readable by ffmpeg too (when installed).
        if std::process::Command::new("ffmpeg")
            .arg("-version")
            .output()
            .is_err()
        {
            eprintln!("skipping: ffmpeg not installed");
            return;
        }
        let dir = tempfile::tempdir().expect("tempdir");
        for depth in [Depth::U8, Depth::U16] {
            let path = dir.path().join("w.y4m");
            let mut w = Y4mWriter::new(File::create(&path).expect("create"), 4, 2, depth, 2200.0)
                .expect("writer");
            for f in 0..3 {
                match depth {
                    Depth::U8 => w.write_frame(FrameDestRef::U8(&[f as u8; 8]), Some(f)),
                    Depth::U16 => w.write_frame(FrameDestRef::U16(&[f as u16 * 1000; 8]), Some(f)),
                }
                .expect("write");
            }
            w.finish().expect("finish");
            let out = std::process::Command::new("ffmpeg")
                .args(["-v", "error", "-nostdin", "-i"])
                .arg(&path)
                .args(["-f", "null", "-"])
                .output()
                .expect("ffmpeg");
            assert!(
                out.status.success(),
                "{depth:?}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
}
