//! `csv`: writes signals or spectra as CSV.
//!
//! Audio: `t_s,value`; samples: `t_s,ch0,ch1,...`; spectra: one row per bin,
//! `t_s,freq_hz,power`. The file is created on the first item (a run that
//! fails before any data arrives leaves no empty file behind); rows are
//! written as they arrive, and the buffer is
//! flushed on finish (end of stream, Ctrl-C or an upstream error).

use crate::*;
use serde::Deserialize;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    path: PathBuf,
}

const PARAMS: &[ParamSpec] =
    &[ParamSpec::new("path", ParamType::Path, Def::Required).doc("the CSV file")];

pub const KIND: KindSpec = KindSpec {
    name: "csv",
    summary: "writes audio, samples or spectra as CSV rows",
    inputs: &[InPort::one(&[
        PortType::Audio,
        PortType::Samples,
        PortType::Spectrum,
    ])],
    outputs: NO_OUTPUTS,
    params: PARAMS,
    plan: |p| {
        let v: P = p.resolve(PARAMS)?;
        Ok(Box::new(Csv {
            path: v.path,
            out: None,
        }))
    },
};

struct Csv {
    path: PathBuf,
    out: Option<BufWriter<std::fs::File>>,
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
            Item::Frame(_) | Item::Pyramid(_) => {}
        }
        Ok(())
    }
}

impl Stage for Csv {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let header = self.out.is_none();
        if header {
            self.out = Some(BufWriter::new(super::create(&self.path)?));
        }
        self.write_rows(&item, header)
            .map_err(|e| StageError::file("write", &self.path, e))
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        if let Some(mut o) = self.out.take() {
            o.flush()
                .map_err(|e| StageError::file("write", &self.path, e))?;
        }
        Ok(())
    }
}
