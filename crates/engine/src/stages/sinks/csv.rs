//! `csv`: writes signals or spectra as CSV.
//!
//! Audio: `t_s,value`; samples: `t_s,ch0,ch1,...`; spectra: one row per bin,
//! `t_s,freq_hz,power`; peak sets: one row per resonance, `t_s,rank,frequency_hz,
//! frequency_std_hz,power_db,prominence_db,damping_ratio,damping_ratio_std`.
//! The file is created on the first item (a run that
//! fails before any data arrives leaves no empty file behind); rows are
//! written as they arrive to a unique temporary sibling
//! (`.NAME.PID-N.partial`), flushed and renamed to the path on finish (end
//! of stream, a signal or an error anywhere): two runs writing one path
//! cannot splice; after a write error (a full disk) the partial last row is
//! cut off first.

use crate::*;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use vibroscope_io::atomic::Pending;

params! {
    /// `csv`'s parameters.
    pub struct CsvParams for "csv" {
        path: PathBuf = ParamSpec::of(ParamType::Path, Def::Required).doc("the CSV file"),
    }
}

type P = CsvParams;

pub const KIND: KindSpec = KindSpec {
    name: "csv",
    summary: "writes audio, samples, spectra or peak sets as CSV rows",
    inputs: &[InPort::one(&[
        PortType::Audio,
        PortType::Samples,
        PortType::Spectrum,
        PortType::Peaks,
    ])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        Ok(Box::new(Csv {
            path: v.path,
            out: None,
            pending: None,
        }))
    },
};

struct Csv {
    path: PathBuf,
    out: Option<BufWriter<std::fs::File>>,
    /// The temporary file `out` writes, renamed on finish.
    pending: Option<Pending>,
}

impl Plan for Csv {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(self))
    }
}

impl Csv {
    fn write_rows(&mut self, item: &Item, header: bool) -> std::io::Result<()> {
        let Some(o) = self.out.as_mut() else {
            return Ok(());
        };
        match item {
            Item::Audio(a) => {
                if header {
                    writeln!(o, "t_s,value")?;
                }
                for (i, s) in a.samples.iter().enumerate() {
                    writeln!(o, "{:.9},{}", a.time_s(i), s)?;
                }
            }
            Item::Samples(s) => {
                let ch = s.channels.max(1);
                if header {
                    write!(o, "t_s")?;
                    for c in 0..ch {
                        write!(o, ",ch{c}")?;
                    }
                    writeln!(o)?;
                }
                for (i, row) in s.data.chunks_exact(ch).enumerate() {
                    let t = match &s.times_ns {
                        Some(t) => t.get(i).copied().unwrap_or(0) as f64 * 1e-9,
                        None => s.t0_ns as f64 * 1e-9 + i as f64 / s.rate_hz,
                    };
                    write!(o, "{t:.9}")?;
                    for v in row {
                        write!(o, ",{v}")?;
                    }
                    writeln!(o)?;
                }
            }
            Item::Spectrum(s) => {
                if header {
                    writeln!(o, "t_s,freq_hz,power")?;
                }
                let t = s.t_ns as f64 * 1e-9;
                for (k, p) in s.power.iter().enumerate() {
                    writeln!(o, "{t:.9},{},{p}", s.f0_hz + k as f64 * s.resolution_hz)?;
                }
            }
            Item::Peaks(ps) => {
                if header {
                    writeln!(o, "t_s,rank,frequency_hz,frequency_std_hz,power_db,prominence_db,damping_ratio,damping_ratio_std")?;
                }
                let t = ps.t_ns as f64 * 1e-9;
                for (k, r) in ps.peaks.iter().enumerate() {
                    writeln!(
                        o,
                        "{t:.9},{k},{},{},{},{},{},{}",
                        r.frequency_hz,
                        r.frequency_std_hz,
                        r.power_db,
                        r.prominence_db,
                        r.damping_ratio,
                        r.damping_ratio_std
                    )?;
                }
            }
            Item::Frame(_) | Item::Pyramid(_) => {}
        }
        Ok(())
    }
}

impl Stage for Csv {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let header = self.out.is_none();
        if header {
            let (pending, file) = super::create_pending(&self.path)?;
            self.pending = Some(pending);
            self.out = Some(BufWriter::new(file));
        }
        self.write_rows(&item, header)
            .map_err(|e| StageError::file("write", &self.path, e))
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        let io = |e: std::io::Error| StageError::file("write", &self.path, e);
        let flushed = match self.out.take() {
            Some(mut o) => o.flush().map_err(io),
            None => Ok(()),
        };
        let Some(pending) = self.pending.take() else {
            return flushed;
        };
        if flushed.is_err() {
            let _ = cut_to_whole_lines(pending.temp_path());
        }
        flushed.and(pending.commit().map_err(io))
    }
}

/// Cuts a text file after its last `\n` (shortening needs no new space).
fn cut_to_whole_lines(path: &Path) -> std::io::Result<()> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)?;
    let mut end = f.metadata()?.len();
    let mut buf = vec![0u8; 64 * 1024];
    while end > 0 {
        let start = end.saturating_sub(buf.len() as u64);
        let chunk = &mut buf[..(end - start) as usize];
        f.seek(SeekFrom::Start(start))?;
        f.read_exact(chunk)?;
        if let Some(i) = chunk.iter().rposition(|&b| b == b'\n') {
            return f.set_len(start + i as u64 + 1);
        }
        end = start;
    }
    f.set_len(0)
}
