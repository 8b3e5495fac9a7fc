//! WAV files: the one reader every command and the simulator share.

use std::path::{Path, PathBuf};

/// A WAV file that could not be read or written, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum WavError {
    #[error("{}: not a readable WAV file: {source}", path.display())]
    Open {
        path: PathBuf,
        #[source]
        source: hound::Error,
    },
    #[error("{}: bad samples: {source}", path.display())]
    Samples {
        path: PathBuf,
        #[source]
        source: hound::Error,
    },
    #[error("{}: cannot encode WAV: {source}", path.display())]
    Encode {
        path: PathBuf,
        #[source]
        source: hound::Error,
    },
    #[error(transparent)]
    Write(#[from] crate::atomic::WriteError),
}

impl WavError {
    /// `WavError::Open` for `path`, as a `map_err` argument.
    fn open(path: &Path) -> impl Fn(hound::Error) -> WavError + Copy + '_ {
        move |source| WavError::Open {
            path: path.to_path_buf(),
            source,
        }
    }

    /// `WavError::Samples` for `path`, as a `map_err` argument.
    fn samples(path: &Path) -> impl Fn(hound::Error) -> WavError + Copy + '_ {
        move |source| WavError::Samples {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// A WAV file's sample rate (Hz) and length (samples per channel), from
/// its header alone: to check them before reading or resampling.
pub fn info(path: &Path) -> Result<(u32, u64), WavError> {
    let r = hound::WavReader::open(path).map_err(WavError::open(path))?;
    Ok((r.spec().sample_rate, u64::from(r.duration())))
}

/// Makes a WAV file's header agree with what is on disk: the `data`
/// chunk's size becomes the whole sample frames the file holds (a partial
/// frame at the end is cut off) and the RIFF size the file's length - 8.
/// For a file whose writer failed part way (a full disk): rewriting eight
/// header bytes in place needs no new space. Returns the sample frames.
pub fn repair_header(path: &Path) -> std::io::Result<u64> {
    use std::io::{Read, Seek, SeekFrom, Write};
    let bad = |m: &str| std::io::Error::new(std::io::ErrorKind::InvalidData, m.to_string());
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)?;
    let len = f.metadata()?.len();
    let mut head = [0u8; 12];
    f.read_exact(&mut head)?;
    if &head[0..4] != b"RIFF" || &head[8..12] != b"WAVE" {
        return Err(bad("not a RIFF/WAVE file"));
    }
    let (mut pos, mut align) = (12u64, 0u64);
    loop {
        let mut ch = [0u8; 8];
        f.seek(SeekFrom::Start(pos))?;
        f.read_exact(&mut ch)?;
        let size = u64::from(u32::from_le_bytes([ch[4], ch[5], ch[6], ch[7]]));
        if &ch[0..4] == b"fmt " {
            let mut fmt = [0u8; 14];
            f.read_exact(&mut fmt)?;
            align = u64::from(u16::from_le_bytes([fmt[12], fmt[13]]));
        } else if &ch[0..4] == b"data" {
            if align == 0 {
                return Err(bad("no fmt chunk before the data"));
            }
            let start = pos + 8;
            let frames = len.saturating_sub(start) / align;
            let data = frames * align;
            let data32 = u32::try_from(data).map_err(|_| bad("data over 4 GB"))?;
            f.set_len(start + data)?;
            f.seek(SeekFrom::Start(pos + 4))?;
            f.write_all(&data32.to_le_bytes())?;
            let riff = u32::try_from(start + data - 8).map_err(|_| bad("file over 4 GB"))?;
            f.seek(SeekFrom::Start(4))?;
            f.write_all(&riff.to_le_bytes())?;
            f.sync_all()?;
            return Ok(frames);
        }
        pos += 8 + size + (size & 1);
        if pos + 8 > len {
            return Err(bad("no data chunk"));
        }
    }
}

/// Reads the first channel of a WAV file: integers scaled to [-1, 1),
/// floats as stored. Returns the sample rate in Hz and the samples.
pub fn read_mono(path: &Path) -> Result<(u32, Vec<f64>), WavError> {
    let f = std::fs::File::open(path).map_err(|e| WavError::Open {
        path: path.to_path_buf(),
        source: hound::Error::IoError(e),
    })?;
    read_mono_from(std::io::BufReader::new(f), path)
}

/// [`read_mono`] of WAV bytes from any reader; `path` names them in errors.
pub fn read_mono_from<R: std::io::Read>(src: R, path: &Path) -> Result<(u32, Vec<f64>), WavError> {
    let open = WavError::open(path);
    let bad = WavError::samples(path);
    let mut r = hound::WavReader::new(src).map_err(open)?;
    let spec = r.spec();
    let ch = spec.channels.max(1) as usize;
    // The header's length is a claim: reserve at most 1 Mi samples for it.
    let mut out = Vec::with_capacity((r.len() as usize / ch).min(1 << 20));
    match spec.sample_format {
        hound::SampleFormat::Float => {
            for (i, s) in r.samples::<f32>().enumerate() {
                let s = s.map_err(bad)?;
                if i % ch == 0 {
                    out.push(f64::from(s));
                }
            }
        }
        hound::SampleFormat::Int => {
            let scale = 1.0 / (1u64 << (spec.bits_per_sample.clamp(1, 32) - 1)) as f64;
            for (i, s) in r.samples::<i32>().enumerate() {
                let s = s.map_err(bad)?;
                if i % ch == 0 {
                    out.push(s as f64 * scale);
                }
            }
        }
    }
    Ok((spec.sample_rate, out))
}

/// Sample encoding of a WAV the project writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// 32-bit IEEE float: `WAVE_FORMAT_IEEE_FLOAT` with an 18-byte `fmt `
    /// chunk (cbSize = 0) and the `fact` chunk that every non-PCM WAV must
    /// carry (its sample count). sox warns about float WAVs without them
    /// ("wave header missing extended part of fmt chunk").
    F32,
    /// 16-bit PCM (`WAVE_FORMAT_PCM`, 16-byte `fmt `), values clipped to [-1, 1].
    I16,
}

/// A mono WAV written as it goes: the header's sizes are rewritten by
/// [`MonoWavWriter::flush`] and [`MonoWavWriter::finalize`], so the file is
/// a valid WAV after each (up to the samples flushed).
pub struct MonoWavWriter<W: std::io::Write + std::io::Seek> {
    w: W,
    enc: Encoding,
    frames: u64,
}

impl<W: std::io::Write + std::io::Seek> MonoWavWriter<W> {
    /// Writes the header of an empty file at `rate` Hz.
    pub fn new(mut w: W, rate: u32, enc: Encoding) -> std::io::Result<Self> {
        let (tag, bytes, fmt_len): (u16, u16, u32) = match enc {
            Encoding::F32 => (3, 4, 18),
            Encoding::I16 => (1, 2, 16),
        };
        let mut h = Vec::with_capacity(58);
        h.extend_from_slice(b"RIFF\0\0\0\0WAVEfmt ");
        h.extend_from_slice(&fmt_len.to_le_bytes());
        h.extend_from_slice(&tag.to_le_bytes());
        h.extend_from_slice(&1u16.to_le_bytes());
        h.extend_from_slice(&rate.to_le_bytes());
        h.extend_from_slice(&(rate.saturating_mul(u32::from(bytes))).to_le_bytes());
        h.extend_from_slice(&bytes.to_le_bytes());
        h.extend_from_slice(&(8 * bytes).to_le_bytes());
        if enc == Encoding::F32 {
            h.extend_from_slice(&0u16.to_le_bytes());
            h.extend_from_slice(b"fact\x04\0\0\0\0\0\0\0");
        }
        h.extend_from_slice(b"data\0\0\0\0");
        w.write_all(&h)?;
        let mut me = Self { w, enc, frames: 0 };
        me.patch()?;
        Ok(me)
    }

    fn header_len(&self) -> u64 {
        match self.enc {
            Encoding::F32 => 58,
            Encoding::I16 => 44,
        }
    }

    fn data_bytes(&self) -> u64 {
        self.frames
            * match self.enc {
                Encoding::F32 => 4,
                Encoding::I16 => 2,
            }
    }

    /// Appends samples (`gain * x`; 16-bit clips at ±1).
    pub fn write(&mut self, x: &[f32], gain: f32) -> std::io::Result<()> {
        let per = match self.enc {
            Encoding::F32 => 4,
            Encoding::I16 => 2,
        };
        if self.header_len() + self.data_bytes() + per * x.len() as u64 > u64::from(u32::MAX) {
            return Err(std::io::Error::other("a WAV file holds at most 4 GiB"));
        }
        for &v in x {
            let v = v * gain;
            match self.enc {
                Encoding::F32 => self.w.write_all(&v.to_le_bytes())?,
                Encoding::I16 => self
                    .w
                    .write_all(&(((v.clamp(-1.0, 1.0)) * 32767.0).round() as i16).to_le_bytes())?,
            }
        }
        self.frames += x.len() as u64;
        Ok(())
    }

    /// Samples written.
    pub fn len(&self) -> u64 {
        self.frames
    }

    pub fn is_empty(&self) -> bool {
        self.frames == 0
    }

    /// Rewrites the sizes in the header (RIFF, `fact`, `data`).
    fn patch(&mut self) -> std::io::Result<()> {
        use std::io::SeekFrom;
        let data = self.data_bytes() as u32;
        let riff = (self.header_len() - 8) as u32 + data;
        self.w.seek(SeekFrom::Start(4))?;
        self.w.write_all(&riff.to_le_bytes())?;
        if self.enc == Encoding::F32 {
            self.w.seek(SeekFrom::Start(46))?;
            self.w.write_all(&(self.frames as u32).to_le_bytes())?;
        }
        self.w.seek(SeekFrom::Start(self.header_len() - 4))?;
        self.w.write_all(&data.to_le_bytes())?;
        self.w.seek(SeekFrom::End(0))?;
        Ok(())
    }

    /// Makes what is written so far a valid file on disk.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.patch()?;
        self.w.flush()
    }

    /// Finishes the file, giving back the writer.
    pub fn finalize(mut self) -> std::io::Result<W> {
        self.flush()?;
        Ok(self.w)
    }
}

/// Encodes a whole mono WAV in memory.
fn encode(rate: u32, x: &[f64], enc: Encoding, gain: f32) -> std::io::Result<Vec<u8>> {
    let cur = std::io::Cursor::new(Vec::with_capacity(58 + 4 * x.len()));
    let mut w = MonoWavWriter::new(cur, rate, enc)?;
    let y: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    w.write(&y, gain)?;
    Ok(w.finalize()?.into_inner())
}

/// Writes a mono 32-bit float WAV atomically (a temporary sibling, then a
/// rename), so an interrupted run never leaves half a file.
pub fn write_mono_f32(path: &Path, rate: u32, x: &[f64]) -> Result<(), WavError> {
    let bytes = encode(rate, x, Encoding::F32, 1.0).map_err(|e| WavError::Encode {
        path: path.to_path_buf(),
        source: hound::Error::IoError(e),
    })?;
    Ok(crate::atomic::write_atomic(path, &bytes)?)
}

/// Writes a mono 16-bit PCM WAV of `gain * x` (clipped to ±1) atomically.
pub fn write_mono_i16(path: &Path, rate: u32, x: &[f64], gain: f64) -> Result<(), WavError> {
    let bytes = encode(rate, x, Encoding::I16, gain as f32).map_err(|e| WavError::Encode {
        path: path.to_path_buf(),
        source: hound::Error::IoError(e),
    })?;
    Ok(crate::atomic::write_atomic(path, &bytes)?)
}

/// Rewrites a mono WAV as 16-bit PCM scaled so its peak is at `peak_dbfs`,
/// streaming (two passes over the file: the peak, then the samples, into a
/// temporary sibling renamed over it): memory stays bounded whatever the
/// length. A silent file is written unscaled.
pub fn normalize_to_i16(path: &Path, peak_dbfs: f64) -> Result<(), WavError> {
    let open = WavError::open(path);
    let bad = WavError::samples(path);
    let io_err = |e: std::io::Error| {
        WavError::Write(crate::atomic::WriteError {
            path: path.to_path_buf(),
            source: e,
        })
    };
    let mut peak = 0.0f64;
    let rate = {
        let mut r = hound::WavReader::open(path).map_err(open)?;
        for s in samples_f64(&mut r) {
            peak = peak.max(s.map_err(bad)?.abs());
        }
        r.spec().sample_rate
    };
    let gain = if peak > 0.0 {
        10f64.powf(peak_dbfs / 20.0) / peak
    } else {
        1.0
    } as f32;
    let tmp = crate::atomic::temp_sibling(path);
    let done = (|| -> Result<(), WavError> {
        let mut r = hound::WavReader::open(path).map_err(open)?;
        let file = std::fs::File::create(&tmp).map_err(io_err)?;
        let mut w = MonoWavWriter::new(std::io::BufWriter::new(file), rate, Encoding::I16)
            .map_err(io_err)?;
        let mut buf = Vec::with_capacity(4096);
        for s in samples_f64(&mut r) {
            buf.push(s.map_err(bad)? as f32);
            if buf.len() == buf.capacity() {
                w.write(&buf, gain).map_err(io_err)?;
                buf.clear();
            }
        }
        w.write(&buf, gain).map_err(io_err)?;
        w.finalize().map_err(io_err)?;
        std::fs::rename(&tmp, path).map_err(io_err)
    })();
    if done.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    done
}

/// The first channel's samples as f64 (integers scaled to [-1, 1)).
fn samples_f64<'a, R: std::io::Read + 'a>(
    r: &'a mut hound::WavReader<R>,
) -> Box<dyn Iterator<Item = Result<f64, hound::Error>> + 'a> {
    let spec = r.spec();
    let ch = spec.channels.max(1) as usize;
    match spec.sample_format {
        hound::SampleFormat::Float => {
            Box::new(r.samples::<f32>().step_by(ch).map(|s| s.map(f64::from)))
        }
        hound::SampleFormat::Int => {
            let scale = 1.0 / (1u64 << (spec.bits_per_sample.clamp(1, 32) - 1)) as f64;
            Box::new(
                r.samples::<i32>()
                    .step_by(ch)
                    .map(move |s| s.map(|v| v as f64 * scale)),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_first_channel_scaled() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("two.wav");
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 8000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(&path, spec).expect("create");
        for (a, b) in [(16384i16, 1i16), (-32768, 2)] {
            w.write_sample(a).expect("write");
            w.write_sample(b).expect("write");
        }
        w.finalize().expect("finalize");
        let (rate, x) = read_mono(&path).expect("read");
        assert_eq!(rate, 8000);
        assert_eq!(x, vec![0.5, -1.0]);
    }

    #[test]
    fn writes_what_it_reads() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("f.wav");
        write_mono_f32(&path, 2200, &[0.25, -0.5, 1.5]).expect("write");
        let (rate, x) = read_mono(&path).expect("read");
        assert_eq!((rate, x), (2200, vec![0.25, -0.5, 1.5]));
    }

    /// Both encodings: the header layout byte by byte (float: format 3,
    /// an 18-byte fmt with cbSize 0, a fact chunk with the sample count;
    /// PCM: format 1, 16-byte fmt), read back by hound.
    #[test]
    fn headers_are_laid_out_as_the_spec_says() {
        let dir = tempfile::tempdir().expect("tempdir");
        let f = dir.path().join("f.wav");
        write_mono_f32(&f, 48000, &[0.5, -0.25, 0.125]).expect("write");
        let b = std::fs::read(&f).expect("read");
        assert_eq!(b.len(), 58 + 12);
        assert_eq!(&b[0..4], b"RIFF");
        assert_eq!(u32::from_le_bytes([b[4], b[5], b[6], b[7]]), 62);
        assert_eq!(&b[12..16], b"fmt ");
        assert_eq!(u32::from_le_bytes([b[16], b[17], b[18], b[19]]), 18);
        assert_eq!(u16::from_le_bytes([b[20], b[21]]), 3);
        assert_eq!(u16::from_le_bytes([b[36], b[37]]), 0, "cbSize");
        assert_eq!(&b[38..42], b"fact");
        assert_eq!(u32::from_le_bytes([b[46], b[47], b[48], b[49]]), 3);
        assert_eq!(&b[50..54], b"data");
        assert_eq!(u32::from_le_bytes([b[54], b[55], b[56], b[57]]), 12);
        let p = dir.path().join("p.wav");
        write_mono_i16(&p, 8000, &[0.5, -2.0, 1e-6], 1.0).expect("write");
        let b = std::fs::read(&p).expect("read");
        assert_eq!(b.len(), 44 + 6);
        assert_eq!(u16::from_le_bytes([b[20], b[21]]), 1);
        let (rate, x) = read_mono(&p).expect("read");
        assert_eq!(rate, 8000);
        assert_eq!(x, vec![16384.0 / 32768.0, -32767.0 / 32768.0, 0.0]);
    }

    /// A float WAV normalised in place: 16-bit PCM, peak at -1 dBFS, same
    /// shape, no temporary file left behind.
    #[test]
    fn normalizes_a_float_wav_to_16_bit() {
        let dir = tempfile::tempdir().expect("tempdir");
        let f = dir.path().join("n.wav");
        let x: Vec<f64> = (0..10_000)
            .map(|i| 0.01 * (i as f64 * 0.01).sin())
            .collect();
        write_mono_f32(&f, 600, &x).expect("write");
        normalize_to_i16(&f, -1.0).expect("normalise");
        let r = hound::WavReader::open(&f).expect("open");
        assert_eq!((r.spec().bits_per_sample, r.spec().sample_rate), (16, 600));
        let (_, y) = read_mono(&f).expect("read");
        assert_eq!(y.len(), x.len());
        let peak = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!((20.0 * peak.log10() + 1.0).abs() < 0.01, "peak {peak}");
        let g = peak / 0.01;
        let err = x
            .iter()
            .zip(&y)
            .map(|(a, b)| (a * g - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1.0 / 32768.0, "{err}");
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 1);
    }

    #[test]
    fn repair_header_matches_the_data_on_disk() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("r.wav");
        write_mono_f32(&path, 8000, &[0.5; 10]).expect("write");
        // A writer that died part way: 2.5 more samples, header not updated.
        let mut bytes = std::fs::read(&path).expect("read");
        bytes.extend_from_slice(&[0u8; 10]);
        std::fs::write(&path, &bytes).expect("write");
        assert_eq!(repair_header(&path).expect("repair"), 12);
        let (rate, x) = read_mono(&path).expect("read");
        assert_eq!((rate, x.len()), (8000, 12));
        let bytes = std::fs::read(&path).expect("read");
        let riff = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]);
        assert_eq!(riff as usize, bytes.len() - 8);
    }

    #[test]
    fn a_missing_file_names_itself() {
        let e = read_mono(Path::new("/nonexistent/x.wav")).expect_err("missing");
        assert!(e.to_string().contains("/nonexistent/x.wav"), "{e}");
    }
}
