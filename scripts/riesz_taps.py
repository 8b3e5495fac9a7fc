"""The taps of the Riesz magnifier's 7x7 pair (crates/math/src/magnify/riesz_fir.rs).

`R1` is the band convolved with `h(m, n)`, odd along x, even along y;
`R2` with its transpose. Its response is
`2 sum c[m][n] sin(m wx) (2 cos(n wy), or 1 for n = 0)` for m = 1..K,
n = 0..K. The taps `c` are the weighted least-squares fit of that
response to the Riesz transform's `wx / |w|` on a 128x128 grid of
frequencies, weighted by what a Laplacian level holds: the mean power
spectrum of levels 0 to 2 of noise textures with `1/f^beta` amplitude
spectra (beta 0.8, 1.0, 1.2; seeds 1 to 5), built as the magnifier
builds them (5-tap binomial, mirrored borders).

It then checks the fit on textures it was not fitted on (seeds 101 and
102): the error of the pair against the exact pair by FFT, in dB of the
pair's energy per level, for K = 1 (the 3-tap pair of Wadhwa et al.) to
5; and the amplitude-weighted phase change that a 0.05 px shift gives
with the filter, over the one with the exact pair.

    python3 scripts/riesz_taps.py [--k 3]

Needs numpy and scipy (Debian's python3-scipy). Prints the taps as a
Rust array, then the checks.
"""

import argparse

import numpy as np
from scipy.ndimage import convolve1d

BINOMIAL = np.array([1, 4, 6, 4, 1]) / 16.0
GRID = 128


def blur(x):
    x = convolve1d(x, BINOMIAL, axis=0, mode="mirror")
    return convolve1d(x, BINOMIAL, axis=1, mode="mirror")


def laplacian(img, levels=4):
    out, g = [], img
    for _ in range(levels):
        low = blur(g)[::2, ::2]
        up = np.zeros(g.shape)
        up[::2, ::2] = low
        out.append(g - 4 * blur(up))
        g = low
    return out


def texture(n, seed, beta):
    r = np.random.default_rng(seed)
    f = np.fft.fftfreq(n)
    fx, fy = np.meshgrid(f, f)
    rad = np.hypot(fx, fy)
    rad[0, 0] = 1
    spec = (r.standard_normal((n, n)) + 1j * r.standard_normal((n, n))) / rad**beta
    spec[0, 0] = 0
    return np.real(np.fft.ifft2(spec))


def exact_pair(b):
    h, w = b.shape
    wx, wy = np.meshgrid(2 * np.pi * np.fft.fftfreq(w), 2 * np.pi * np.fft.fftfreq(h))
    r = np.hypot(wx, wy)
    r[0, 0] = 1
    f = np.fft.fft2(b)
    return np.real(np.fft.ifft2(-1j * wx / r * f)), np.real(np.fft.ifft2(-1j * wy / r * f))


def filter_pair(b, c, k):
    p = np.pad(b, k, mode="reflect")
    h, w = b.shape
    r1, r2 = np.zeros_like(b), np.zeros_like(b)
    for (m, n), v in c.items():
        for sy in [0] if n == 0 else [n, -n]:
            r1 += v * (p[k + sy : k + sy + h, k - m : k - m + w] - p[k + sy : k + sy + h, k + m : k + m + w])
            r2 += v * (p[k - m : k - m + h, k + sy : k + sy + w] - p[k + m : k + m + h, k + sy : k + sy + w])
    return r1, r2


def level_spectrum():
    win = np.outer(np.hanning(GRID), np.hanning(GRID))
    power = np.zeros((GRID, GRID))
    for seed in range(1, 6):
        for beta in (0.8, 1.0, 1.2):
            for b in laplacian(texture(512, seed, beta))[:3]:
                h, w = b.shape
                for y in range(0, h - GRID + 1, GRID):
                    for x in range(0, w - GRID + 1, GRID):
                        t = b[y : y + GRID, x : x + GRID]
                        power += np.abs(np.fft.fft2(t * win)) ** 2 / np.sum(t**2)
    return power


def design(k, power):
    w = 2 * np.pi * np.fft.fftfreq(GRID)
    wx, wy = np.meshgrid(w, w)
    r = np.hypot(wx, wy)
    r[0, 0] = 1
    cols, idx = [], []
    for m in range(1, k + 1):
        for n in range(0, k + 1):
            cols.append((2 * np.sin(m * wx) * (1.0 if n == 0 else 2 * np.cos(n * wy))).ravel())
            idx.append((m, n))
    a = np.array(cols).T
    s = np.sqrt(power.ravel())
    c, *_ = np.linalg.lstsq(a * s[:, None], (wx / r).ravel() * s, rcond=None)
    return dict(zip(idx, c))


def shifted(img, dx, dy):
    h, w = img.shape
    fx, fy = np.meshgrid(np.fft.fftfreq(w), np.fft.fftfreq(h))
    return np.real(np.fft.ifft2(np.fft.fft2(img) * np.exp(-2j * np.pi * (fx * dx + fy * dy))))


def phase_change(b0, q0, b1, q1):
    """Amplitude-weighted quaternionic phase change along x and y."""
    (a1, a2), (c1, c2) = q0, q1
    re = b1 * b0 + c1 * a1 + c2 * a2
    vx, vy = -b1 * a1 + b0 * c1, -b1 * a2 + b0 * c2
    vn = np.hypot(vx, vy)
    d = np.arctan2(vn, re) / np.maximum(vn, 1e-30)
    wt = b0**2 + a1**2 + a2**2
    return np.sum(wt * d * vx) / np.sum(wt), np.sum(wt * d * vy) / np.sum(wt)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--k", type=int, default=3, help="half-width of the filter (3: 7x7)")
    k = ap.parse_args().k
    power = level_spectrum()
    c = design(k, power)
    print(f"const TAPS: [[f32; {k + 1}]; {k}] = [")
    for m in range(1, k + 1):
        print("    [" + ", ".join(f"{c[(m, n)]:.9f}" for n in range(k + 1)) + "],")
    print("];")
    print("error against the exact pair, dB of its energy, levels 0-3, seeds 101 and 102:")
    for kk in range(1, 6):
        ck = {(1, 0): 0.5} if kk == 1 else design(kk, power)
        errs = []
        for seed in (101, 102):
            for lv, b in enumerate(laplacian(texture(512, seed, 1.0))):
                e1, e2 = exact_pair(b)
                f1, f2 = filter_pair(b, ck, kk)
                s = slice(16 >> lv, -(16 >> lv))
                num = np.sum((f1 - e1)[s, s] ** 2 + (f2 - e2)[s, s] ** 2)
                errs.append(10 * np.log10(num / np.sum(e1[s, s] ** 2 + e2[s, s] ** 2)))
        name = "3-tap" if kk == 1 else f"{2 * kk + 1}x{2 * kk + 1}"
        print(f"  {name:6} " + " ".join(f"{e:6.1f}" for e in errs))
    print("phase change of a 0.05 px shift, filter over exact, levels 0-2 (x, y, diagonal):")
    img = texture(512, 201, 1.0)
    for kk in (1, k):
        ck = {(1, 0): 0.5} if kk == 1 else design(kk, power)
        ratios = []
        for dx, dy in ((0.05, 0.0), (0.0, 0.05), (0.04, 0.03)):
            b0s, b1s = laplacian(img), laplacian(shifted(img, dx, dy))
            for lv in range(3):
                s = slice(24 >> lv, -(24 >> lv))
                got = []
                for pair in (exact_pair, lambda b: filter_pair(b, ck, kk)):
                    q0, q1 = pair(b0s[lv]), pair(b1s[lv])
                    crop = lambda q: (q[0][s, s], q[1][s, s])
                    px, py = phase_change(b0s[lv][s, s], crop(q0), b1s[lv][s, s], crop(q1))
                    got.append((px * dx + py * dy) / np.hypot(dx, dy))
                ratios.append(got[1] / got[0])
        name = "3-tap" if kk == 1 else f"{2 * kk + 1}x{2 * kk + 1}"
        print(f"  {name:6} " + " ".join(f"{r:.3f}" for r in ratios))


if __name__ == "__main__":
    main()
