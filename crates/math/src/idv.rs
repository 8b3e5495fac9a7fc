//! Interactive dynamic video (thesis ch. 6): an image-space modal basis,
//! its simulation and its rendering. No I/O: the recipe
//! (`vibroscope::idv`) measures the basis from a video and writes frames.
//!
//! - [`Oscillator`]: one modal coordinate, ρ'' + 2ξω ρ' + ω² ρ = f (unit
//!   modal mass), advanced by its exact state-transition matrix for any
//!   step h with the force held over the step (zero-order hold). Eq. 6.5
//!   is the first-order (forward Euler) form of the same system and needs
//!   a small h to stay stable; the exact form does not, so the response is
//!   the same at any output frame rate.
//! - [`dominant_axis_rotation`]: the phase that makes a complex shape's
//!   dominant axis real (6.4.2).
//! - [`Shape`]: a complex mode shape, x and y displacement per pixel
//!   (Eq. 6.4), and the modal force / manipulation of a point (Eq.
//!   6.6-6.9).
//! - [`Renderer`]: the displacement field D = Σ Re{φ'_i q_i} (Eq. 6.10)
//!   applied to the rest frame by a forward warp in which pixels that move
//!   more occlude those that move less (6.4.5), disocclusions filled by
//!   sampling the rest frame back along the local displacement.

pub use rustfft::num_complex::{Complex32, Complex64};

/// One modal coordinate: a damped oscillator of unit modal mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Oscillator {
    /// Undamped angular frequency ω, rad/s.
    pub omega: f64,
    /// Damping ratio ξ, in [0, 1).
    pub xi: f64,
    /// Modal displacement ρ.
    pub rho: f64,
    /// Modal velocity ρ'.
    pub vel: f64,
}

impl Oscillator {
    /// At rest. `freq_hz` is the damped (observed) frequency f_d: ω =
    /// 2π f_d / √(1 - ξ²), so the free motion rings at f_d.
    pub fn new(freq_hz: f64, xi: f64) -> Oscillator {
        let xi = xi.clamp(0.0, 0.999);
        Oscillator {
            omega: std::f64::consts::TAU * freq_hz / (1.0 - xi * xi).sqrt(),
            xi,
            rho: 0.0,
            vel: 0.0,
        }
    }

    /// The state-transition matrix e^{Ah} and the zero-order-hold input
    /// vector Γ = ∫₀ʰ e^{Aτ} dτ [0 1]ᵀ of A = [[0, 1], [-ω², -2ξω]].
    pub fn transition(&self, h: f64) -> ([[f64; 2]; 2], [f64; 2]) {
        let w = self.omega;
        let sigma = self.xi * w;
        let wd = w * (1.0 - self.xi * self.xi).sqrt();
        let e = (-sigma * h).exp();
        let (s, c) = (wd * h).sin_cos();
        let p11 = e * (c + sigma / wd * s);
        let p12 = e * s / wd;
        let p21 = -e * w * w / wd * s;
        let p22 = e * (c - sigma / wd * s);
        // dΦ₁₁/dτ = -ω² Φ₁₂ and dΦ₁₂/dτ = Φ₂₂ give the integrals exactly.
        ([[p11, p12], [p21, p22]], [(1.0 - p11) / (w * w), p12])
    }

    /// Advances by `h` seconds with the force `f` held constant.
    pub fn step(&mut self, h: f64, f: f64) {
        if h <= 0.0 {
            return;
        }
        let (p, g) = self.transition(h);
        let (r, v) = (self.rho, self.vel);
        self.rho = p[0][0] * r + p[0][1] * v + g[0] * f;
        self.vel = p[1][0] * r + p[1][1] * v + g[1] * f;
    }

    /// An impulse `j` (force × time): the velocity jumps by `j`.
    pub fn kick(&mut self, j: f64) {
        self.vel += j;
    }

    /// The complex modal coordinate q = ρ - i ρ'/ω (6.4.3).
    pub fn q(&self) -> Complex64 {
        Complex64::new(self.rho, -self.vel / self.omega)
    }

    /// Sets the state from a complex modal coordinate (direct manipulation).
    pub fn set_q(&mut self, q: Complex64) {
        self.rho = q.re;
        self.vel = -q.im * self.omega;
    }
}

/// The rotation e^{-iθ} that puts the dominant axis of `values` (the
/// principal axis of the points in the complex plane, arg Σ v² / 2) on the
/// real axis (6.4.2). A shape with only binary phases becomes real.
pub fn dominant_axis_rotation<'a>(values: impl Iterator<Item = &'a Complex32>) -> Complex32 {
    let s: Complex64 = values
        .map(|c| {
            let c = Complex64::new(c.re as f64, c.im as f64);
            c * c
        })
        .sum();
    let r = Complex64::from_polar(1.0, -0.5 * s.arg());
    // Of the two opposite rotations, the one whose largest value points +.
    Complex32::new(r.re as f32, r.im as f32)
}

/// A complex mode shape: x and y displacement per pixel (row-major), in
/// pixels per unit of modal coordinate.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    pub x: Vec<Complex32>,
    pub y: Vec<Complex32>,
}

impl Shape {
    /// Rotates both axes by one phase so the dominant axis is real (6.4.2).
    pub fn align(&mut self) {
        let r = dominant_axis_rotation(self.x.iter().chain(self.y.iter()));
        // Sign: make the largest real value positive (the phase origin is free).
        let mut best = (0.0f32, 1.0f32);
        for c in self.x.iter().chain(self.y.iter()) {
            let v = (c * r).re;
            if v.abs() > best.0 {
                best = (v.abs(), v.signum());
            }
        }
        let r = r * best.1;
        self.x
            .iter_mut()
            .chain(self.y.iter_mut())
            .for_each(|c| *c *= r);
    }

    /// d·φ'(p): the shape at pixel `p` seen along direction `d`.
    pub fn along(&self, p: usize, d: [f64; 2]) -> Complex64 {
        let (x, y) = (self.x[p], self.y[p]);
        Complex64::new(x.re as f64, x.im as f64) * d[0]
            + Complex64::new(y.re as f64, y.im as f64) * d[1]
    }
}

/// The modal force of a force `d` (pixels, any length) at pixel `p`, times
/// `alpha`. Eq. 6.6 takes the magnitude |dᵀφ'(p)|; we take the real part
/// of the phase-aligned shape instead, which keeps its sign: for real
/// shapes it is the exact modal force dᵀφ(p), so a push beyond a node of
/// a mode drives that mode the other way, as a real object does.
pub fn modal_force(shape: &Shape, p: usize, d: [f64; 2], alpha: f64) -> f64 {
    shape.along(p, d).re * alpha
}

/// Direct manipulation (Eq. 6.7-6.9): the complex modal coordinate with
/// |q| = |dᵀφ'(p)| α and the phase that maximises the displacement
/// (`velocity = false`, Eq. 6.8) or the velocity (Eq. 6.9) of `p` along `d`.
/// With q = ρ - iρ'/ω ([`Oscillator::q`]) free motion turns q by e^{+iωt},
/// so the velocity of `p` along `d`, Re{iω dᵀφ' q}, is largest a quarter
/// turn *behind* the displacement's phase: -π/2 (the thesis writes +π/2
/// for its own sign of the imaginary part).
pub fn manipulate(shape: &Shape, p: usize, d: [f64; 2], alpha: f64, velocity: bool) -> Complex64 {
    let a = shape.along(p, d);
    let mut arg = -a.arg();
    if velocity {
        arg -= std::f64::consts::FRAC_PI_2;
    }
    Complex64::from_polar(a.norm() * alpha, arg)
}

/// Renders frames: D = Σ Re{φ'_i q_i} (Eq. 6.10), then the rest frame
/// warped by D. All buffers are made once; [`Renderer::render`] allocates
/// nothing.
pub struct Renderer {
    width: usize,
    height: usize,
    /// Displacement field, px.
    pub dx: Vec<f32>,
    pub dy: Vec<f32>,
    /// Per output pixel: |D| of the source pixel that landed there (-1: none).
    depth: Vec<f32>,
    /// Per output pixel: the displacement it samples the rest frame with.
    own_x: Vec<f32>,
    own_y: Vec<f32>,
}

impl Renderer {
    pub fn new(width: usize, height: usize) -> Renderer {
        let n = width * height;
        Renderer {
            width,
            height,
            dx: vec![0.0; n],
            dy: vec![0.0; n],
            depth: vec![0.0; n],
            own_x: vec![0.0; n],
            own_y: vec![0.0; n],
        }
    }

    /// The frame's width and height.
    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }

    /// Eq. 6.10: D = Σ_i Re{φ'_i q_i}, into [`Renderer::dx`], [`Renderer::dy`].
    pub fn displacement(&mut self, shapes: &[Shape], q: &[Complex64]) {
        displacement_part(shapes, q, 0, &mut self.dx, &mut self.dy);
    }

    /// Warps `rest` (one plane, row-major, values 0..=255) by the current
    /// displacement field into `out`: [`Renderer::resolve`] then
    /// [`Renderer::sample`].
    pub fn warp(&mut self, rest: &[u8], out: &mut [u8]) {
        self.resolve();
        self.sample(rest, out);
    }

    /// Where each output pixel takes its value from, for the current
    /// displacement field. Each source pixel lands on the output pixel
    /// nearest to where it moves; where several land, the one that moves
    /// most wins (the depth rule of 6.4.5). Each output pixel then
    /// samples the rest frame at itself minus the winner's displacement
    /// (sub-pixel motion stays smooth); a pixel nothing lands on (a
    /// disocclusion) samples it with its own displacement.
    pub fn resolve(&mut self) {
        let (w, h) = (self.width, self.height);
        self.depth.fill(-1.0);
        self.own_x.copy_from_slice(&self.dx);
        self.own_y.copy_from_slice(&self.dy);
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let (ddx, ddy) = (self.dx[i], self.dy[i]);
                let tx = (x as f32 + ddx).round();
                let ty = (y as f32 + ddy).round();
                if tx < 0.0 || ty < 0.0 || tx >= w as f32 || ty >= h as f32 {
                    continue;
                }
                let t = ty as usize * w + tx as usize;
                let mag = ddx * ddx + ddy * ddy;
                if mag > self.depth[t] {
                    self.depth[t] = mag;
                    self.own_x[t] = ddx;
                    self.own_y[t] = ddy;
                }
            }
        }
    }

    /// Samples one plane of the rest frame (`rest`, row-major 0..=255)
    /// bilinearly where [`Renderer::resolve`] said, into `out`: called once
    /// per plane (luma, then each chroma plane of a colour frame), the
    /// planes move together.
    pub fn sample(&self, rest: &[u8], out: &mut [u8]) {
        assert!(out.len() == self.width * self.height, "frame size");
        self.sample_rows(rest, 0, out);
    }

    /// [`Renderer::sample`] of the whole rows from `y0` on into `out`
    /// (as many rows as it holds): a frame's rows can be shared between
    /// threads.
    pub fn sample_rows(&self, rest: &[u8], y0: usize, out: &mut [u8]) {
        let (w, h) = (self.width, self.height);
        assert!(rest.len() == w * h, "frame size");
        assert!(
            out.len().is_multiple_of(w) && y0 + out.len() / w <= h,
            "rows"
        );
        for (r, row) in out.chunks_exact_mut(w).enumerate() {
            let y = y0 + r;
            for (x, o) in row.iter_mut().enumerate() {
                let i = y * w + x;
                let sx = x as f32 - self.own_x[i];
                let sy = y as f32 - self.own_y[i];
                *o = bilinear_u8(rest, w, h, sx, sy);
            }
        }
    }
}

/// Eq. 6.10 for the pixels `start..start + dx.len()`: D = Σ_i Re{φ'_i q_i}
/// into `dx`, `dy` (a frame's pixels can be shared between threads).
pub fn displacement_part(
    shapes: &[Shape],
    q: &[Complex64],
    start: usize,
    dx: &mut [f32],
    dy: &mut [f32],
) {
    dx.fill(0.0);
    dy.fill(0.0);
    let end = start + dx.len();
    for (s, q) in shapes.iter().zip(q) {
        let (qr, qi) = (q.re as f32, q.im as f32);
        for (d, c) in dx.iter_mut().zip(&s.x[start..end]) {
            *d += c.re * qr - c.im * qi;
        }
        for (d, c) in dy.iter_mut().zip(&s.y[start..end]) {
            *d += c.re * qr - c.im * qi;
        }
    }
}

/// Bilinear sample of an 8-bit plane, edges clamped.
fn bilinear_u8(p: &[u8], w: usize, h: usize, x: f32, y: f32) -> u8 {
    let x = x.clamp(0.0, (w - 1) as f32);
    let y = y.clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let a = p[y0 * w + x0] as f32 * (1.0 - fx) + p[y0 * w + x1] as f32 * fx;
    let b = p[y1 * w + x0] as f32 * (1.0 - fx) + p[y1 * w + x1] as f32 * fx;
    (a * (1.0 - fy) + b * fy).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// Closed-form free decay from (ρ0, v0).
    fn free(o: &Oscillator, r0: f64, v0: f64, t: f64) -> f64 {
        let s = o.xi * o.omega;
        let wd = o.omega * (1.0 - o.xi * o.xi).sqrt();
        (-s * t).exp() * (r0 * (wd * t).cos() + (v0 + s * r0) / wd * (wd * t).sin())
    }

    #[test]
    fn free_decay_matches_the_closed_form_at_any_step() {
        for &h in &[1e-4, 1.0 / 30.0, 0.37] {
            let mut o = Oscillator::new(7.0, 0.03);
            o.rho = 0.5;
            o.vel = -2.0;
            let mut t = 0.0;
            for _ in 0..(3.0 / h) as usize {
                o.step(h, 0.0);
                t += h;
                let want = free(&o, 0.5, -2.0, t);
                assert!(
                    (o.rho - want).abs() < 1e-9,
                    "h {h} t {t}: {} vs {want}",
                    o.rho
                );
            }
        }
    }

    #[test]
    fn held_force_settles_and_matches_the_step_response() {
        // Step response from rest: ρ = f/ω² (1 - free(1, 0)).
        let mut o = Oscillator::new(3.0, 0.1);
        let f = 2.5;
        let mut t = 0.0;
        for k in 0..500 {
            let h = if k % 2 == 0 { 0.01 } else { 0.023 };
            o.step(h, f);
            t += h;
            let want = f / (o.omega * o.omega) * (1.0 - free(&o, 1.0, 0.0, t));
            assert!((o.rho - want).abs() < 1e-9, "t {t}");
        }
    }

    #[test]
    fn frequency_is_the_damped_one() {
        let o = Oscillator::new(10.0, 0.2);
        let wd = o.omega * (1.0 - 0.04f64).sqrt();
        assert!((wd - std::f64::consts::TAU * 10.0).abs() < 1e-9);
    }

    #[test]
    fn binary_phase_shapes_become_real_and_forces_keep_sign() {
        let rot = Complex32::from_polar(1.0, 1.1);
        let mut s = Shape {
            x: vec![Complex32::new(0.0, 0.0); 3],
            y: [1.0f32, -0.5, 0.25].iter().map(|&v| rot * v).collect(),
        };
        s.align();
        for (c, want) in s.y.iter().zip([1.0f32, -0.5, 0.25]) {
            assert!((c.re - want).abs() < 1e-5 && c.im.abs() < 1e-5, "{c}");
        }
        assert!((modal_force(&s, 1, [0.0, 2.0], 1.0) + 1.0).abs() < 1e-5);
        let q = manipulate(&s, 1, [0.0, 1.0], 2.0, false);
        // Displacement of p along d: Re{φ q} = |φ| |q| = 0.5.
        let d = (Complex64::new(s.y[1].re as f64, s.y[1].im as f64) * q).re;
        assert!((d - 0.5).abs() < 1e-5, "{d}");
    }

    #[test]
    fn warp_moves_content_and_nearer_motion_occludes() {
        let (w, h) = (8, 1);
        let rest: Vec<u8> = (0..8).map(|i| (i * 30) as u8).collect();
        let mut r = Renderer::new(w, h);
        // Pixel 2 moves +2 onto pixel 4, which moves +0.4 (rounds to itself).
        r.dx[2] = 2.0;
        r.dx[4] = 0.4;
        let mut out = vec![0u8; 8];
        r.warp(&rest, &mut out);
        assert_eq!(out[4], rest[2], "the larger motion wins");
        // Pixel 2 is a hole: it samples the rest frame at 2 - 2.0 = 0.
        assert_eq!(out[2], rest[0]);
        assert_eq!(out[7], rest[7]);
    }

    #[test]
    fn a_thrown_point_starts_at_rest_and_moves_along_the_drag() {
        let s = Shape {
            x: vec![Complex32::new(0.0, 0.0); 2],
            y: vec![Complex32::from_polar(0.8, 0.7), Complex32::new(0.1, 0.0)],
        };
        let d = [0.0, 1.0];
        let mut o = Oscillator::new(5.0, 0.01);
        o.set_q(manipulate(&s, 0, d, 1.0, true));
        let along = |o: &Oscillator| (s.along(0, d) * o.q()).re;
        let x0 = along(&o);
        o.step(1e-3, 0.0);
        assert!(x0.abs() < 1e-9, "not at rest: {x0}");
        assert!(along(&o) > 1e-4, "moves against the drag: {}", along(&o));
        // Held (Eq. 6.8): the point sits at its largest displacement along d.
        let mut o = Oscillator::new(5.0, 0.01);
        o.set_q(manipulate(&s, 0, d, 1.0, false));
        let x0 = along(&o);
        o.step(1e-3, 0.0);
        assert!(x0 > 0.0 && along(&o) < x0);
    }
}
