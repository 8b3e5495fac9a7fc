//! Universal File Format (UFF) writer, ASCII: data set 15 (nodes), 164
//! (units) and 58 (a function at a nodal degree of freedom: a time
//! response or a spectrum). pyuff, ME'scope and most modal packages read
//! these; the record layouts are the I-DEAS ones (fixed columns: a field
//! never touches its neighbour, and numbers are Fortran `E` formatted).
//!
//! Data set 58 is written with even abscissa spacing only: the uneven
//! layout keeps the abscissa in `E13.5` (six digits), too coarse for the
//! times of a long high-speed recording.

use std::fmt::Write as _;

/// A node: its label and coordinates (data set 15, in the file's length
/// unit; the definition and displacement coordinate systems are the
/// global one, 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    pub label: u32,
    pub xyz: [f64; 3],
}

/// The file's unit system (data set 164): code, description and the
/// factors that take the file's units to SI by division.
#[derive(Clone, Debug, PartialEq)]
pub struct Units {
    /// 1 SI (m, N), 5 MM (mm, mN), ...
    pub code: u32,
    pub description: String,
    pub length_factor: f64,
    pub force_factor: f64,
}

impl Units {
    /// Millimetres (code 5: mm and mN; to SI divide by 1000).
    pub fn millimetre() -> Units {
        Units {
            code: 5,
            description: "MM (mm, mN)".into(),
            length_factor: 1000.0,
            force_factor: 1000.0,
        }
    }
}

/// What a function is (data set 58, record 6 field 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FunctionType {
    /// 1: a time response.
    TimeResponse,
    /// 12: a (linear) spectrum.
    Spectrum,
}

impl FunctionType {
    pub fn code(self) -> u32 {
        match self {
            FunctionType::TimeResponse => 1,
            FunctionType::Spectrum => 12,
        }
    }
}

/// An axis's data characteristics (records 8 to 11).
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    /// Specific data type: 0 unknown, 8 displacement, 11 velocity,
    /// 12 acceleration, 17 time, 18 frequency.
    pub data_type: u32,
    /// Length units exponent (1 for a displacement, a velocity or an
    /// acceleration: time is implicit).
    pub length_exp: i32,
    /// Axis label and unit label, at most 20 characters each.
    pub label: String,
    pub units: String,
}

impl Axis {
    /// The unused denominator and z axes.
    pub fn none() -> Axis {
        Axis {
            data_type: 0,
            length_exp: 0,
            label: "NONE".into(),
            units: "NONE".into(),
        }
    }
}

/// Data set 58: real ordinates at evenly spaced abscissae.
#[derive(Clone, Debug, PartialEq)]
pub struct Function {
    /// Records 1 to 5 (80 characters each: a name, a source, a date, ...).
    pub ids: [String; 5],
    pub kind: FunctionType,
    pub function_id: u32,
    /// Response entity name (10 characters), node and direction
    /// (1 +X, 2 +Y, 3 +Z, negative for -X...).
    pub response_name: String,
    pub response_node: u32,
    pub response_dir: i32,
    pub abscissa_min: f64,
    pub abscissa_step: f64,
    pub abscissa: Axis,
    pub ordinate: Axis,
    pub data: Vec<f64>,
}

/// The file as text: units (when given), then nodes (when any), then
/// each function, each as a `-1` delimited data set.
pub fn to_string(units: Option<&Units>, nodes: &[Node], functions: &[Function]) -> String {
    let mut s = String::new();
    if let Some(u) = units {
        write_164(&mut s, u);
    }
    if !nodes.is_empty() {
        write_15(&mut s, nodes);
    }
    for f in functions {
        write_58(&mut s, f);
    }
    s
}

/// A Fortran `Ew.d` field: `d` decimals, an upper-case `E`, a signed
/// exponent of at least two digits, right-aligned in `w` columns. A
/// value that is not finite is written as `NaN`, `Inf` or `-Inf`.
pub fn fortran_e(v: f64, w: usize, d: usize) -> String {
    if !v.is_finite() {
        let t = if v.is_nan() {
            "NaN"
        } else if v > 0.0 {
            "Inf"
        } else {
            "-Inf"
        };
        return format!("{t:>w$}");
    }
    let r = format!("{v:.d$e}");
    let (mantissa, exp) = r.split_once('e').unwrap_or((&r, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let sign = if exp < 0 { '-' } else { '+' };
    format!("{:>w$}", format!("{mantissa}E{sign}{:02}", exp.abs()))
}

/// Text cut to `n` characters (the fixed fields cannot hold more).
fn cut(t: &str, n: usize) -> String {
    t.chars().take(n).collect()
}

fn header(s: &mut String, set: u32) {
    let _ = writeln!(s, "{:>6}\n{set:>6}", -1);
}

fn footer(s: &mut String) {
    let _ = writeln!(s, "{:>6}", -1);
}

fn write_164(s: &mut String, u: &Units) {
    header(s, 164);
    // Temperature mode 2: relative.
    let _ = writeln!(s, "{:>10}{:<20}{:>10}", u.code, cut(&u.description, 20), 2);
    let _ = writeln!(
        s,
        "{}{}{}\n{}",
        fortran_e(u.length_factor, 25, 16),
        fortran_e(u.force_factor, 25, 16),
        fortran_e(1.0, 25, 16),
        fortran_e(273.15, 25, 16)
    );
    footer(s);
}

fn write_15(s: &mut String, nodes: &[Node]) {
    header(s, 15);
    for n in nodes {
        let _ = writeln!(
            s,
            "{:>10}{:>10}{:>10}{:>10}{}{}{}",
            n.label,
            0,
            0,
            0,
            fortran_e(n.xyz[0], 13, 5),
            fortran_e(n.xyz[1], 13, 5),
            fortran_e(n.xyz[2], 13, 5)
        );
    }
    footer(s);
}

fn axis_line(s: &mut String, a: &Axis) {
    let _ = writeln!(
        s,
        "{:>10}{:>5}{:>5}{:>5} {:<20} {:<20}",
        a.data_type,
        a.length_exp,
        0,
        0,
        cut(&a.label, 20),
        cut(&a.units, 20)
    );
}

fn write_58(s: &mut String, f: &Function) {
    header(s, 58);
    for id in &f.ids {
        let _ = writeln!(s, "{:<80}", cut(id, 80));
    }
    // Record 6: no reference (node 0, direction 0).
    let _ = writeln!(
        s,
        "{:>5}{:>10}{:>5}{:>10} {:<10}{:>10}{:>4} {:<10}{:>10}{:>4}",
        f.kind.code(),
        f.function_id,
        0,
        0,
        cut(&f.response_name, 10),
        f.response_node,
        f.response_dir,
        "NONE",
        0,
        0
    );
    // Record 7: real double (4), n points, even spacing (1).
    let _ = writeln!(
        s,
        "{:>10}{:>10}{:>10}{}{}{}",
        4,
        f.data.len(),
        1,
        fortran_e(f.abscissa_min, 13, 5),
        fortran_e(f.abscissa_step, 13, 5),
        fortran_e(0.0, 13, 5)
    );
    axis_line(s, &f.abscissa);
    axis_line(s, &f.ordinate);
    axis_line(s, &Axis::none());
    axis_line(s, &Axis::none());
    // Record 12: 4E20.12 (11 decimals leave room for a 3-digit exponent).
    for row in f.data.chunks(4) {
        for &v in row {
            s.push_str(&fortran_e(v, 20, 11));
        }
        s.push('\n');
    }
    footer(s);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fortran_fields_are_fixed_width() {
        assert_eq!(fortran_e(1.0 / 2200.0, 13, 5), "  4.54545E-04");
        assert_eq!(fortran_e(-123.456, 13, 5), " -1.23456E+02");
        assert_eq!(fortran_e(0.0, 13, 5), "  0.00000E+00");
        assert_eq!(fortran_e(-1.5e-300, 20, 11), " -1.50000000000E-300");
        assert_eq!(fortran_e(f64::NAN, 13, 5), "          NaN");
    }

    #[test]
    fn a_function_reads_back_by_its_columns() {
        let f = Function {
            ids: ["a".into(), "b".into(), "c".into(), "d".into(), "e".into()],
            kind: FunctionType::TimeResponse,
            function_id: 3,
            response_name: "roi1".into(),
            response_node: 1,
            response_dir: 2,
            abscissa_min: 0.0,
            abscissa_step: 0.5,
            abscissa: Axis {
                data_type: 17,
                length_exp: 0,
                label: "Time".into(),
                units: "s".into(),
            },
            ordinate: Axis {
                data_type: 8,
                length_exp: 1,
                label: "Displacement".into(),
                units: "mm".into(),
            },
            data: vec![1.0, -2.0, 3.5, 4.0, 5.0],
        };
        let text = to_string(Some(&Units::millimetre()), &[], &[f]);
        let lines: Vec<&str> = text.lines().collect();
        // 164 takes 6 lines; 58 starts after it.
        let set = &lines[6..];
        assert_eq!(set[0].trim(), "-1");
        assert_eq!(set[1].trim(), "58");
        let r6 = set[7];
        assert_eq!(r6[0..5].trim(), "1");
        assert_eq!(r6[30..41].trim(), "roi1");
        assert_eq!(r6[41..51].trim(), "1");
        assert_eq!(r6[51..55].trim(), "2");
        let r7 = set[8];
        assert_eq!(r7[10..20].trim(), "5");
        assert_eq!(r7[43..56].trim().parse::<f64>().ok(), Some(0.5));
        let values: Vec<f64> = set[13..15]
            .iter()
            .flat_map(|l| {
                (0..l.len() / 20).map(move |i| l[20 * i..20 * (i + 1)].trim().parse::<f64>())
            })
            .collect::<Result<_, _>>()
            .unwrap_or_default();
        assert_eq!(values, vec![1.0, -2.0, 3.5, 4.0, 5.0]);
        assert_eq!(set[15].trim(), "-1");
    }
}
