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
    fn a_missing_file_names_itself() {
        let e = read_mono(Path::new("/nonexistent/x.wav")).expect_err("missing");
        assert!(e.to_string().contains("/nonexistent/x.wav"), "{e}");
    }
}
