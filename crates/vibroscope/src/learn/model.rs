//! Regression from features to the logs of material properties (thesis
//! 5.5.1): Partial Least Squares (`linfa-pls`) or Principal Components
//! Regression (PCA by nalgebra's SVD, then least squares on the scores),
//! the number of components chosen by leave-one-object-out
//! cross-validation; metrics of Table 5.4 (Pearson R, mean % error,
//! Kendall τ); a prediction interval from the cross-validation residuals;
//! an out-of-distribution flag from Hotelling's T² on the scores and the Q
//! (squared reconstruction) residual, with limits from the held-out
//! objects' own values in cross-validation.

use linfa::prelude::*;
use linfa_pls::PlsRegression;
use ndarray::{Array1, Array2, Axis};
use serde::{Deserialize, Serialize};

/// Which regression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    Pls,
    Pcr,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Pls => "PLSR",
            Method::Pcr => "PCR",
        }
    }
}

/// A fitted linear model as plain numbers (so the JSON model is
/// self-contained): standardise `xs = (x - x_mean) / x_scale`; predict
/// `y = xs · coef + intercept`; scores `t = t0 + xs · rot`; reconstruction
/// `xs ≈ t · load^T`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Linear {
    pub method: Method,
    pub components: usize,
    pub x_mean: Vec<f64>,
    pub x_scale: Vec<f64>,
    /// p × targets, row-major.
    pub coef: Vec<Vec<f64>>,
    pub intercept: Vec<f64>,
    /// p × components.
    pub rot: Vec<Vec<f64>>,
    pub t0: Vec<f64>,
    pub load: Vec<Vec<f64>>,
    /// Variance of each score over the training rows.
    pub score_var: Vec<f64>,
}

/// T² and Q of one row.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Distance {
    pub t2: f64,
    pub q: f64,
}

fn standardise(x: &Array2<f64>) -> (Array1<f64>, Array1<f64>) {
    let mean = x
        .mean_axis(Axis(0))
        .unwrap_or_else(|| Array1::zeros(x.ncols()));
    let mut sd = x.std_axis(Axis(0), 1.0);
    sd.mapv_inplace(|v| if v > 1e-12 && v.is_finite() { v } else { 1.0 });
    (mean, sd)
}

/// The `k` leading principal axes of the centred rows `x` (p × k, by
/// decreasing singular value): nalgebra's SVD, which smooth, nearly
/// collinear features (expected spectra) do not upset. Axes beyond the
/// rows' rank are zero, so their scores are zero and add nothing.
fn principal_axes(x: &Array2<f64>, k: usize) -> Result<Array2<f64>, String> {
    let (n, p) = x.dim();
    let m = nalgebra::DMatrix::from_fn(n, p, |i, j| x[[i, j]]);
    let svd = nalgebra::linalg::SVD::try_new(m, false, true, f64::EPSILON, 0)
        .ok_or("PCA: the SVD did not converge")?;
    let vt = svd.v_t.ok_or("PCA: the SVD gave no axes")?;
    let sv = &svd.singular_values;
    let mut order: Vec<usize> = (0..sv.len()).collect();
    order.sort_by(|&a, &b| sv[b].total_cmp(&sv[a]));
    let top = order.first().map_or(0.0, |&i| sv[i]);
    Ok(Array2::from_shape_fn((p, k), |(i, a)| match order.get(a) {
        Some(&r) if sv[r] > 1e-12 * top => vt[(r, i)],
        _ => 0.0,
    }))
}

/// An affine map `f(xs) = b + xs · A`, read off `f` at 0 and at each unit vector.
fn probe(p: usize, f: impl Fn(&Array2<f64>) -> Array2<f64>) -> (Vec<f64>, Vec<Vec<f64>>) {
    let mut x = Array2::zeros((p + 1, p));
    for i in 0..p {
        x[[i + 1, i]] = 1.0;
    }
    let y = f(&x);
    let b: Vec<f64> = y.row(0).to_vec();
    let a = (0..p)
        .map(|i| y.row(i + 1).iter().zip(&b).map(|(v, b0)| v - b0).collect())
        .collect();
    (b, a)
}

/// Fits `method` with `components` on rows `x` (n × p) and targets `y` (n × q).
pub fn fit(
    method: Method,
    components: usize,
    x: &Array2<f64>,
    y: &Array2<f64>,
) -> Result<Linear, String> {
    let (n, p) = x.dim();
    if components == 0 || components > p || components >= n {
        return Err(format!(
            "{} components need more than {components} rows (have {n}) and at least {components} features (have {p})",
            method.name()
        ));
    }
    let (mean, sd) = standardise(x);
    let xs = (x - &mean) / &sd;
    // A target that does not vary over the training rows has nothing to
    // learn (and PLS's power method fails on it): the principal
    // components' least squares then predicts its constant, and the
    // components still give T² and Q.
    let constant = y.columns().into_iter().all(|c| {
        let m = c.mean().unwrap_or(0.0);
        c.iter().all(|v| (v - m).abs() <= 1e-12 * m.abs().max(1.0))
    });
    let solver = if constant { Method::Pcr } else { method };
    let (coef_b, coef, rot_b, rot, load) = match solver {
        Method::Pls => {
            let ds = Dataset::new(xs.clone(), y.clone());
            let pls = PlsRegression::params(components)
                .fit(&ds)
                .map_err(|e| format!("PLS fit: {e}"))?;
            let (cb, c) = probe(p, |v| pls.predict(v));
            let q = y.ncols();
            let (rb, r) = probe(p, |v| {
                pls.transform(Dataset::new(v.clone(), Array2::zeros((v.nrows(), q))))
                    .records()
                    .clone()
            });
            let l = pls.loadings().0;
            let load = (0..p).map(|i| l.row(i).to_vec()).collect();
            (cb, c, rb, r, load)
        }
        Method::Pcr => {
            let axes = principal_axes(&xs, components)?;
            let (rb, r) = probe(p, |v| v.dot(&axes));
            let t = xs.dot(&axes);
            // Least squares on the (orthogonal) scores, with an intercept.
            let ym = y
                .mean_axis(Axis(0))
                .unwrap_or_else(|| Array1::zeros(y.ncols()));
            let tm = t
                .mean_axis(Axis(0))
                .unwrap_or_else(|| Array1::zeros(t.ncols()));
            let tc = &t - &tm;
            let yc = y - &ym;
            let mut beta = Array2::<f64>::zeros((components, y.ncols()));
            for a in 0..components {
                let ta = tc.column(a);
                let ss = ta.dot(&ta);
                if ss > 0.0 {
                    for j in 0..y.ncols() {
                        beta[[a, j]] = ta.dot(&yc.column(j)) / ss;
                    }
                }
            }
            // y = ym + (t - tm) β, t = rb + xs R.
            let rm = Array2::from_shape_fn((p, components), |(i, a)| r[i][a]);
            let c = rm.dot(&beta);
            let rba = Array1::from(rb.clone());
            let cb = (&ym + &(&rba - &tm).dot(&beta)).to_vec();
            let coef = (0..p).map(|i| c.row(i).to_vec()).collect();
            // PCA's rotation is orthonormal: its loadings are its rotation.
            let load = r.clone();
            (cb, coef, rb, r, load)
        }
    };
    let mut lin = Linear {
        method,
        components,
        x_mean: mean.to_vec(),
        x_scale: sd.to_vec(),
        coef,
        intercept: coef_b,
        rot,
        t0: rot_b,
        load,
        score_var: vec![1.0; components],
    };
    let scores: Vec<Vec<f64>> = x
        .rows()
        .into_iter()
        .map(|r| lin.scores(&r.to_vec()))
        .collect();
    for a in 0..components {
        let m = scores.iter().map(|s| s[a]).sum::<f64>() / n as f64;
        let v = scores.iter().map(|s| (s[a] - m).powi(2)).sum::<f64>() / (n - 1).max(1) as f64;
        lin.score_var[a] = if v > 0.0 { v } else { 1.0 };
    }
    Ok(lin)
}

impl Linear {
    fn xs(&self, x: &[f64]) -> Vec<f64> {
        x.iter()
            .zip(&self.x_mean)
            .zip(&self.x_scale)
            .map(|((v, m), s)| (v - m) / s)
            .collect()
    }

    pub fn predict(&self, x: &[f64]) -> Vec<f64> {
        let xs = self.xs(x);
        let mut y = self.intercept.clone();
        for (v, row) in xs.iter().zip(&self.coef) {
            for (o, c) in y.iter_mut().zip(row) {
                *o += v * c;
            }
        }
        y
    }

    pub fn scores(&self, x: &[f64]) -> Vec<f64> {
        let xs = self.xs(x);
        let mut t = self.t0.clone();
        for (v, row) in xs.iter().zip(&self.rot) {
            for (o, c) in t.iter_mut().zip(row) {
                *o += v * c;
            }
        }
        t
    }

    /// Hotelling's T² of the scores and the Q residual (mean squared
    /// standardised reconstruction error per feature).
    pub fn distance(&self, x: &[f64]) -> Distance {
        let t = self.scores(x);
        let t2 = t
            .iter()
            .zip(&self.score_var)
            .map(|(v, s)| v * v / s)
            .sum::<f64>();
        let xs = self.xs(x);
        let q = xs
            .iter()
            .zip(&self.load)
            .map(|(v, l)| {
                let r: f64 = l.iter().zip(&t).map(|(a, b)| a * b).sum();
                (v - r).powi(2)
            })
            .sum::<f64>()
            / xs.len().max(1) as f64;
        Distance { t2, q }
    }
}

/// Pearson's correlation (NaN for fewer than 2 points or no spread).
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n < 2 {
        return f64::NAN;
    }
    let ma = a[..n].iter().sum::<f64>() / n as f64;
    let mb = b[..n].iter().sum::<f64>() / n as f64;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (x, y) = (a[i] - ma, b[i] - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    sab / (saa * sbb).sqrt()
}

/// Kendall's τ-b.
pub fn kendall_tau(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (mut c, mut d, mut ta, mut tb) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for i in 0..n {
        for j in i + 1..n {
            let (x, y) = ((a[i] - a[j]).signum(), (b[i] - b[j]).signum());
            if a[i] == a[j] && b[i] == b[j] {
                continue;
            } else if a[i] == a[j] {
                ta += 1.0;
            } else if b[i] == b[j] {
                tb += 1.0;
            } else if x == y {
                c += 1.0;
            } else {
                d += 1.0;
            }
        }
    }
    (c - d) / ((c + d + ta) * (c + d + tb)).sqrt()
}

/// Mean |predicted − true| / true, in percent, of the properties (not logs).
pub fn mean_pct_error(log_pred: &[f64], log_true: &[f64]) -> f64 {
    let n = log_pred.len().min(log_true.len());
    if n == 0 {
        return f64::NAN;
    }
    (0..n)
        .map(|i| ((log_pred[i] - log_true[i]).exp() - 1.0).abs())
        .sum::<f64>()
        / n as f64
        * 100.0
}

/// Reads a number that JSON wrote as `null` (NaN, ±inf) as NaN.
pub fn nan_or<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// Metrics of one target (`null` in JSON when undefined).
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct Metrics {
    #[serde(deserialize_with = "nan_or")]
    pub r: f64,
    /// R of each object's mean prediction against its property: the R
    /// of thesis Fig. 5-10 ("averaged across video samples containing the
    /// same fabric"). NaN with fewer than three objects or none given.
    #[serde(default = "nan", deserialize_with = "nan_or")]
    pub r_objects: f64,
    #[serde(deserialize_with = "nan_or")]
    pub pct_error: f64,
    #[serde(deserialize_with = "nan_or")]
    pub kendall_tau: f64,
    /// Standard deviation of the log residuals.
    #[serde(deserialize_with = "nan_or")]
    pub resid_sd: f64,
}

fn nan() -> f64 {
    f64::NAN
}

/// The mean of `v` over each object's rows (`object[i]` is row i's), in
/// the order of the objects' first rows.
pub fn object_means(v: &[f64], object: &[String]) -> Vec<f64> {
    let mut order: Vec<&String> = Vec::new();
    let mut sums: Vec<(f64, usize)> = Vec::new();
    for (x, o) in v.iter().zip(object) {
        let k = match order.iter().position(|p| *p == o) {
            Some(k) => k,
            None => {
                order.push(o);
                sums.push((0.0, 0));
                order.len() - 1
            }
        };
        sums[k].0 += x;
        sums[k].1 += 1;
    }
    sums.iter().map(|&(s, n)| s / n as f64).collect()
}

/// The metrics of held-out predictions against the truth; with `object`
/// (each row's object) also the R of the objects' means.
pub fn metrics(pred: &[f64], truth: &[f64], object: Option<&[String]>) -> Metrics {
    let n = pred.len().min(truth.len());
    let ms = (0..n).map(|i| (pred[i] - truth[i]).powi(2)).sum::<f64>() / n.max(1) as f64;
    let r_objects = match object {
        Some(o) if o.len() == n => {
            let (p, t) = (object_means(&pred[..n], o), object_means(&truth[..n], o));
            if p.len() >= 3 {
                pearson(&p, &t)
            } else {
                f64::NAN
            }
        }
        _ => f64::NAN,
    };
    Metrics {
        r: pearson(pred, truth),
        r_objects,
        pct_error: mean_pct_error(pred, truth),
        kendall_tau: kendall_tau(pred, truth),
        resid_sd: ms.sqrt(),
    }
}

/// Held-out predictions: leave each object out of the training rows, fit,
/// predict that object's test rows. `train`/`test` are row indices;
/// `object[i]` the object of row i. Returns, per test row (in `test`
/// order), the prediction and its distance.
pub fn leave_one_object_out(
    method: Method,
    components: usize,
    x: &Array2<f64>,
    y: &Array2<f64>,
    object: &[String],
    train: &[usize],
    test: &[usize],
) -> Result<Vec<(Vec<f64>, Distance)>, String> {
    let mut out = vec![(Vec::new(), Distance { t2: 0.0, q: 0.0 }); test.len()];
    let mut objects: Vec<&String> = test.iter().map(|&i| &object[i]).collect();
    objects.sort();
    objects.dedup();
    for obj in objects {
        let rows: Vec<usize> = train
            .iter()
            .copied()
            .filter(|&i| &object[i] != obj)
            .collect();
        let xt = x.select(Axis(0), &rows);
        let yt = y.select(Axis(0), &rows);
        let m = fit(method, components, &xt, &yt)?;
        for (k, &i) in test.iter().enumerate() {
            if &object[i] == obj {
                let row = x.row(i).to_vec();
                out[k] = (m.predict(&row), m.distance(&row));
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn metrics_of_known_cases() {
        assert!((pearson(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.5]) - 0.9986).abs() < 1e-3);
        assert!((kendall_tau(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        assert!((mean_pct_error(&[0.1f64.ln()], &[0.2f64.ln()]) - 50.0).abs() < 1e-9);
        // Per-video scatter around each object's truth averages out.
        let o: Vec<String> = ["a", "a", "b", "b", "c", "c"].map(String::from).to_vec();
        let truth = [1.0, 1.0, 2.0, 2.0, 3.0, 3.0];
        let pred = [0.0, 2.0, 3.0, 1.0, 3.5, 2.5];
        assert_eq!(object_means(&pred, &o), vec![1.0, 2.0, 3.0]);
        let m = metrics(&pred, &truth, Some(&o));
        assert!((m.r_objects - 1.0).abs() < 1e-12 && m.r < 0.9, "{m:?}");
        assert!(metrics(&pred, &truth, None).r_objects.is_nan());
    }

    #[test]
    fn both_methods_recover_a_linear_law_and_flag_outliers() {
        // y0 = 2 x0 - x1, y1 = x2 + 0.5 x3 on 40 rows of 8 features; the
        // rest are correlated copies.
        let n = 40;
        let mut rng = vibroscope_math::rng::Xoshiro256::new(5);
        let mut x = Array2::zeros((n, 8));
        for i in 0..n {
            for j in 0..4 {
                x[[i, j]] = rng.next_f64();
            }
            for j in 4..8 {
                x[[i, j]] = x[[i, j - 4]] + 0.01 * rng.next_f64();
            }
        }
        let y = Array2::from_shape_fn((n, 2), |(i, k)| {
            if k == 0 {
                2.0 * x[[i, 0]] - x[[i, 1]]
            } else {
                x[[i, 2]] + 0.5 * x[[i, 3]]
            }
        });
        for method in [Method::Pls, Method::Pcr] {
            let m = fit(method, 4, &x, &y).unwrap();
            let p: Vec<f64> = (0..n).map(|i| m.predict(&x.row(i).to_vec())[0]).collect();
            let t: Vec<f64> = y.column(0).to_vec();
            assert!(pearson(&p, &t) > 0.99, "{method:?}");
            let inside = m.distance(&x.row(0).to_vec());
            let far: Vec<f64> = (0..8)
                .map(|j| if j % 2 == 0 { 5.0 } else { -4.0 })
                .collect();
            let outside = m.distance(&far);
            assert!(
                outside.t2 > 10.0 * inside.t2.max(1.0) || outside.q > 10.0 * inside.q.max(1e-3)
            );
        }
        assert!(fit(Method::Pls, 40, &x, &y)
            .unwrap_err()
            .contains("more than"));
    }
}
