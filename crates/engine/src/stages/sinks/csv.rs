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
            line: String::new(),
        }))
    },
};

struct Csv {
    path: PathBuf,
    out: Option<BufWriter<std::fs::File>>,
    /// The temporary file `out` writes, renamed on finish.
    pending: Option<Pending>,
    /// A row of samples, made before it is written.
    line: String,
}

/// Whether `v`'s exact decimal value has at most 10 significant digits
/// (ryu's shortest digits for an `f32` are at most 9: a tie between two
/// of them needs an exact value one digit longer, ending in 5).
fn few_exact_digits(v: f32) -> bool {
    let bits = v.to_bits() & 0x7fff_ffff;
    let (biased, frac) = (bits >> 23, bits & 0x7f_ffff);
    let (mut m, mut e) = match biased {
        0 => (frac, -149i32),
        _ => (frac | 0x80_0000, biased as i32 - 150),
    };
    if m == 0 {
        return true;
    }
    let tz = m.trailing_zeros();
    m >>= tz;
    e += tz as i32;
    // v = m 2^e, m odd. For e >= 0 the digits less their trailing zeros
    // (at most 10 of them: m < 2^24 holds at most 5^10) are at least
    // 2^(e - 10); for e < 0, v = m 5^-e / 10^-e and m 5^-e, odd, has no
    // trailing zeros and is at least 5^-e.
    let mut n: u128 = if e >= 0 {
        if e >= 44 {
            return false;
        }
        (m as u128) << e
    } else {
        if e <= -15 {
            return false;
        }
        m as u128 * 5u128.pow((-e) as u32)
    };
    while n.is_multiple_of(10) {
        n /= 10;
    }
    n < 10_000_000_000
}

/// Appends `v` as `format!("{v}")` writes it (the shortest digits that
/// read back as `v`, never an exponent: `0.000012`, `-0`, `1`, `NaN`),
/// through `ryu`, which finds the same digits several times faster than
/// the formatting machinery (a sample block of the calibration's
/// observables is hundreds of channels).
fn push_display_f32(out: &mut String, v: f32) {
    // The two choose the same shortest digits but for a tie (a value
    // exactly halfway between two shortest candidates, 1765629.25): ryu
    // rounds it to even, the formatting machinery up. A tie needs a value
    // whose exact decimal has few digits; those take the slow path.
    if !v.is_finite() || few_exact_digits(v) {
        use std::fmt::Write as _;
        let _ = write!(out, "{v}");
        return;
    }
    let mut buf = ryu::Buffer::new();
    let text = buf.format_finite(v);
    // ryu writes `[-]int[.frac][e[-]exp]`; read off the digits and where
    // the decimal point falls among them.
    let (sign, body) = match text.strip_prefix('-') {
        Some(b) => ("-", b),
        None => ("", text),
    };
    let (mantissa, exp) = match body.split_once('e') {
        Some((m, e)) => (m, e.parse::<i32>().unwrap_or(0)),
        None => (body, 0),
    };
    let (int, frac) = mantissa.split_once('.').unwrap_or((mantissa, ""));
    let frac = frac.trim_end_matches('0');
    let int = int.trim_start_matches('0');
    // The significant digits are `int` then `frac` (or `frac` less its
    // leading zeros when the integer part is 0), the point after `point`
    // of them.
    let (digits, mut point) = if int.is_empty() {
        let rest = frac.trim_start_matches('0');
        (("", rest), exp - (frac.len() - rest.len()) as i32)
    } else {
        ((int, frac), int.len() as i32 + exp)
    };
    out.push_str(sign);
    let n = digits.0.len() + digits.1.len();
    if n == 0 {
        out.push('0');
        return;
    }
    // Digits `a..b` of the two parts, in order.
    let put = |out: &mut String, a: usize, b: usize| {
        let k = digits.0.len();
        out.push_str(&digits.0[a.min(k)..b.min(k)]);
        out.push_str(&digits.1[a.max(k) - k..b.max(k) - k]);
    };
    if point <= 0 {
        out.push_str("0.");
        while point < 0 {
            out.push('0');
            point += 1;
        }
        put(out, 0, n);
    } else if point as usize >= n {
        put(out, 0, n);
        for _ in n..point as usize {
            out.push('0');
        }
    } else {
        put(out, 0, point as usize);
        out.push('.');
        put(out, point as usize, n);
    }
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
                let line = &mut self.line;
                for (i, row) in s.data.chunks_exact(ch).enumerate() {
                    let t = match &s.times_ns {
                        Some(t) => t.get(i).copied().unwrap_or(0) as f64 * 1e-9,
                        None => s.t0_ns as f64 * 1e-9 + i as f64 / s.rate_hz,
                    };
                    line.clear();
                    std::fmt::Write::write_fmt(line, format_args!("{t:.9}"))
                        .map_err(std::io::Error::other)?;
                    for &v in row {
                        line.push(',');
                        push_display_f32(line, v);
                    }
                    line.push('\n');
                    o.write_all(line.as_bytes())?;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The fast path writes every value as `format!("{v}")` does: random
    /// bit patterns over the whole range, every power of two and ten, the
    /// neighbours of each, zeros, subnormals and the non-finite values.
    #[test]
    fn samples_are_written_as_display_writes_them() {
        let mut rng = vibroscope_math::rng::Xoshiro256::new(7);
        let mut values: Vec<f32> = (0..400_000)
            .map(|_| f32::from_bits((rng.next_u64() >> 32) as u32))
            .collect();
        for e in -45..39 {
            let p = 10f32.powi(e);
            values.extend([p, p.next_up(), p.next_down(), -p, 1.5 * p, 0.123 * p]);
        }
        for e in -149..128 {
            let p = 2f32.powi(e);
            values.extend([p, p.next_up(), p.next_down(), -p]);
        }
        values.extend([
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            123_456_790.0,
            // A tie: ryu's digits end 2, the formatting machinery's 3.
            1_765_629.2,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
            f32::MAX,
            f32::MIN,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ]);
        let mut line = String::new();
        for v in values {
            line.clear();
            push_display_f32(&mut line, v);
            assert_eq!(line, format!("{v}"), "bits {:#010x}", v.to_bits());
        }
    }
}
