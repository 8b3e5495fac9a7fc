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

/// A WAV file's sample rate (Hz) and length (samples per channel), from
/// its header alone: to check them before reading or resampling.
pub fn info(path: &Path) -> Result<(u32, u64), WavError> {
    let r = hound::WavReader::open(path).map_err(|source| WavError::Open {
        path: path.to_path_buf(),
        source,
    })?;
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
    let open = |source| WavError::Open {
        path: path.to_path_buf(),
        source,
    };
    let bad = |source| WavError::Samples {
        path: path.to_path_buf(),
        source,
    };
    let mut r = hound::WavReader::open(path).map_err(open)?;
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

/// Writes a mono 32-bit float WAV atomically (a temporary sibling, then a
/// rename), so an interrupted run never leaves half a file.
pub fn write_mono_f32(path: &Path, rate: u32, x: &[f64]) -> Result<(), WavError> {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let encode = || -> Result<Vec<u8>, hound::Error> {
        let mut bytes = std::io::Cursor::new(Vec::with_capacity(44 + 4 * x.len()));
        let mut w = hound::WavWriter::new(&mut bytes, spec)?;
        for &v in x {
            w.write_sample(v as f32)?;
        }
        w.finalize()?;
        Ok(bytes.into_inner())
    };
    let bytes = encode().map_err(|source| WavError::Encode {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(crate::atomic::write_atomic(path, &bytes)?)
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
