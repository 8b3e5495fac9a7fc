"""A numpy reference of the phase-based methods (issue 52): the visual
microphone's A²-weighted local phase sums (thesis Eq. 3.2-3.4) and
phase-based motion magnification (Wadhwa et al. 2013 and 2014), with the
complex steerable pyramid or the Riesz pyramid, written as a researcher
would write them in numpy: whole arrays, no compiled code of its own.
Also `listen`'s default, the tile method (`--pyramid tiles`): per 16x16
tile, the gradient least-squares motion along x and y against the first
frame, then the first principal component of all tiles' motions.

It is a yardstick for speed (`cargo bench --bench roofline` times it on
the same file as `vibroscope listen` and `vibroscope magnify`), so it
follows the same steps with the same sizes: 4 scales, 2 orientations for
listening, 8 for the steerable magnifier, the 5-tap binomial Riesz
pyramid, a Butterworth band-pass (order 2 per edge) and an
amplitude-weighted Gaussian blur of the filtered phase (sigma 2 band
pixels). The steerable pyramid's bands are kept at full resolution (the
common numpy port), the Riesz pyramid's levels are decimated.

    python3 scripts/numpy_reference.py listen VIDEO.y4m OUT.wav --pyramid riesz [--frames N] [--compare OURS.wav]
    python3 scripts/numpy_reference.py listen VIDEO.y4m OUT.wav --pyramid tiles [--frames N] [--compare OURS.wav]
    python3 scripts/numpy_reference.py magnify VIDEO.y4m OUT.y4m --pyramid csp --band 35,45 --factor 10 [--frames N] [--compare OURS.y4m]

Prints one JSON line: frames, pixels per frame, seconds (reading the file
included, starting Python and importing numpy not), and with --compare
the correlation of its output with the other one (listen: the two sound
tracks after a 20 Hz high-pass; magnify: the motion each output adds to
the input, per frame, and the ratio of their sizes).
"""

import argparse
import json
import math
import sys
import time

import numpy as np
from scipy import ndimage, signal
from scipy.io import wavfile


def read_y4m(path, limit=None):
    """Frames of an 8-bit Y4M (luma only) as float32, and the frame rate."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"\n")
    tags = data[:end].split()
    if not tags or tags[0] != b"YUV4MPEG2":
        sys.exit(f"{path}: not a YUV4MPEG2 file")
    w = h = 0
    fps = 0.0
    chroma = b"420jpeg"
    for t in tags[1:]:
        if t[:1] == b"W":
            w = int(t[1:])
        elif t[:1] == b"H":
            h = int(t[1:])
        elif t[:1] == b"F":
            a, b = t[1:].split(b":")
            fps = int(a) / int(b)
        elif t[:1] == b"C":
            chroma = t[1:]
    plane = w * h
    size = plane if chroma.startswith(b"mono") else plane * 3 // 2
    frames = []
    pos = end + 1
    while pos < len(data) and (limit is None or len(frames) < limit):
        nl = data.index(b"\n", pos)
        start = nl + 1
        frames.append(np.frombuffer(data, np.uint8, plane, start).reshape(h, w))
        pos = start + size
    return np.asarray(frames, np.float32), fps


def write_y4m(path, frames, fps):
    n, h, w = frames.shape
    with open(path, "wb") as f:
        f.write(b"YUV4MPEG2 W%d H%d F%d:1000 Ip A1:1 Cmono\n" % (w, h, round(fps * 1000)))
        out = np.clip(np.rint(frames), 0, 255).astype(np.uint8)
        for fr in out:
            f.write(b"FRAME\n")
            f.write(fr.tobytes())


# ---- Riesz pyramid ---------------------------------------------------------

BINOMIAL = np.array([1, 4, 6, 4, 1], np.float32) / 16


def blur(x):
    x = ndimage.convolve1d(x, BINOMIAL, axis=-1, mode="mirror")
    return ndimage.convolve1d(x, BINOMIAL, axis=-2, mode="mirror")


def riesz_levels(frame, scales):
    """Per level the triple (band, R1, R2)."""
    out = []
    g = frame
    for _ in range(scales):
        s = blur(g)
        t = blur(s)
        band = s - t
        r1 = np.zeros_like(band)
        r1[:, 1:-1] = 0.5 * (band[:, :-2] - band[:, 2:])
        r2 = np.zeros_like(band)
        r2[1:-1] = 0.5 * (band[:-2] - band[2:])
        out.append((band, r1, r2))
        g = t[::2, ::2]
    return out


def expand(x, shape):
    up = np.zeros(shape, np.float32)
    up[::2, ::2] = x
    return 4 * blur(up)


# ---- complex steerable pyramid (full-resolution bands) ----------------------


def csp_filters(h, w, scales, orientations):
    """Frequency masks: one per (scale, orientation), plus the low-pass residual's."""
    fy = np.fft.fftfreq(h)[:, None] * 2
    fx = np.fft.fftfreq(w)[None, :] * 2
    r = np.sqrt(fx**2 + fy**2)
    th = np.arctan2(fy, fx)
    logr = np.log2(np.maximum(r, 1e-12))
    masks = []
    k = orientations
    c = 2 ** (k - 1) * math.factorial(k - 1) / np.sqrt(k * math.factorial(2 * (k - 1)))
    for s in range(scales):
        # Raised-cosine radial window one octave wide, centred at 2^-(s+1) of Nyquist.
        d = np.clip(logr + s + 0.5, -1, 1)
        radial = np.where(np.abs(logr + s + 0.5) < 1, np.cos(np.pi / 2 * d) ** 2, 0.0)
        for o in range(orientations):
            ang = np.angle(np.exp(1j * (th - np.pi * o / orientations)))
            angular = 2 * c * np.abs(np.cos(ang)) ** (k - 1) * (np.abs(ang) < np.pi / 2)
            masks.append((radial * angular).astype(np.float32))
    low = np.where(logr < -scales - 0.5, 1.0, 0.0).astype(np.float32)
    return masks, low


# ---- listen ---------------------------------------------------------------


def align_sum(x):
    """Bands' signals aligned in sign to the strongest and summed."""
    x = x - x.mean(axis=0)
    ref = x[:, np.argmax(x.var(axis=0))]
    sign = np.sign(x.T @ ref)
    return x @ sign


def listen_riesz(frames, scales=4, orientations=2):
    dirs = [(np.cos(np.pi * k / orientations), np.sin(np.pi * k / orientations)) for k in range(orientations)]
    ref = riesz_levels(frames[0], scales)
    weights = [bd**2 + a**2 + b**2 for bd, a, b in ref]
    out = np.zeros((len(frames), scales * orientations))
    for n, fr in enumerate(frames):
        for s, (cur, prev, wt) in enumerate(zip(riesz_levels(fr, scales), ref, weights)):
            a, b, c = cur
            d, e, f = prev
            re = a * d + b * e + c * f
            vi = b * d - a * e
            vj = c * d - a * f
            vk = c * e - b * f
            vn = np.sqrt(vi**2 + vj**2 + vk**2)
            dphi = np.arctan2(vn, re)
            ij = np.sqrt(vi**2 + vj**2)
            scale = np.divide(dphi, ij, out=np.zeros_like(ij), where=ij > 0)
            for o, (ck, sk) in enumerate(dirs):
                out[n, s * orientations + o] = np.sum(wt * scale * (vi * ck + vj * sk)) / wt.sum()
    return align_sum(out)


def listen_csp(frames, scales=4, orientations=2):
    h, w = frames.shape[1:]
    masks, _ = csp_filters(h, w, scales, orientations)
    spec0 = np.fft.fft2(frames[0])
    refs = [np.fft.ifft2(spec0 * m) for m in masks]
    weights = [np.abs(r) ** 2 for r in refs]
    out = np.zeros((len(frames), len(masks)))
    for n, fr in enumerate(frames):
        spec = np.fft.fft2(fr)
        for i, (m, r, wt) in enumerate(zip(masks, refs, weights)):
            band = np.fft.ifft2(spec * m)
            out[n, i] = np.sum(wt * np.angle(band * np.conj(r))) / wt.sum()
    return align_sum(out)


def listen_tiles(frames, tile=16):
    """Gradient least squares per tile (both axes) against the first
    frame, then the tiles' motions on their first principal component."""
    ref = frames[0]
    h, w = ref.shape
    gy, gx = np.gradient(ref)
    # The border has no central difference; tiles cover the interior.
    gx, gy = gx[1:-1, 1:-1], gy[1:-1, 1:-1]
    ny, nx = (h - 2) // tile, (w - 2) // tile
    crop = (slice(0, ny * tile), slice(0, nx * tile))
    gx, gy = gx[crop], gy[crop]

    def tiles(a):
        return a.reshape(a.shape[:-2] + (ny, tile, nx, tile)).sum(axis=(-3, -1))

    sxx, sxy, syy = tiles(gx * gx), tiles(gx * gy), tiles(gy * gy)
    det = sxx * syy - sxy**2
    ok = det > 1e-9 * max(det.max(), 1e-30)
    d = ref[1:-1, 1:-1][crop] - frames[:, 1:-1, 1:-1][(slice(None),) + crop]
    px, py = tiles(gx * d), tiles(gy * d)
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    dx = (syy * px - sxy * py) * inv
    dy = (sxx * py - sxy * px) * inv
    x = np.concatenate([dx.reshape(len(frames), -1), dy.reshape(len(frames), -1)], axis=1)
    x = x - x.mean(axis=0)
    _, _, vt = np.linalg.svd(x, full_matrices=False)
    return x @ vt[0]


# ---- magnify --------------------------------------------------------------


def bandpass(fps, lo, hi):
    return signal.butter(2, [lo, hi], btype="bandpass", fs=fps, output="sos")


def weighted_blur(phase, amp, sigma=2.0):
    """G*(A·φ) / G*A over each frame (axes 1 and 2)."""
    num = ndimage.gaussian_filter(amp * phase, (0, sigma, sigma))
    den = ndimage.gaussian_filter(amp, (0, sigma, sigma))
    return num / np.maximum(den, 1e-12)


def magnify_riesz(frames, fps, lo, hi, factor, scales=4):
    sos = bandpass(fps, lo, hi)
    n = len(frames)
    # A Laplacian pyramid (exact synthesis) with the 3-tap Riesz pair on
    # each band, as the magnifier builds it.
    pyramids, lows = [], []
    for fr in frames:
        g, levels = fr, []
        for _ in range(scales):
            r = blur(g)[::2, ::2]
            band = g - expand(r, g.shape)
            r1 = np.zeros_like(band)
            r1[:, 1:-1] = 0.5 * (band[:, :-2] - band[:, 2:])
            r2 = np.zeros_like(band)
            r2[1:-1] = 0.5 * (band[:-2] - band[2:])
            levels.append((band, r1, r2))
            g = r
        pyramids.append(levels)
        lows.append(g)
    out_levels = []
    for s in range(scales):
        band = np.stack([p[s][0] for p in pyramids])
        r1 = np.stack([p[s][1] for p in pyramids])
        r2 = np.stack([p[s][2] for p in pyramids])
        rr = np.sqrt(r1**2 + r2**2)
        amp = np.sqrt(band**2 + rr**2)
        cos_t = np.divide(r1, rr, out=np.ones_like(rr), where=rr > 0)
        sin_t = np.divide(r2, rr, out=np.zeros_like(rr), where=rr > 0)
        # The quaternionic phase change from each frame to the next
        # (q_t · conj(q_t-1)), as φ·cosθ and φ·sinθ, summed over time.
        a, b, c = band[1:], r1[1:], r2[1:]
        d, e, f = band[:-1], r1[:-1], r2[:-1]
        re = a * d + b * e + c * f
        vi = b * d - a * e
        vj = c * d - a * f
        vk = c * e - b * f
        ij = np.sqrt(vi**2 + vj**2)
        dphi = np.arctan2(np.sqrt(ij**2 + vk**2), re)
        k = np.divide(dphi, ij, out=np.zeros_like(ij), where=ij > 0)
        zero = np.zeros((1,) + band.shape[1:], np.float32)
        pc = np.concatenate([zero, np.cumsum(k * vi, axis=0)])
        ps = np.concatenate([zero, np.cumsum(k * vj, axis=0)])
        fc = signal.sosfilt(sos, pc, axis=0)
        fs = signal.sosfilt(sos, ps, axis=0)
        fc = weighted_blur(fc, amp)
        fs = weighted_blur(fs, amp)
        shift = np.clip((factor - 1) * (fc * cos_t + fs * sin_t), -np.pi / 2, np.pi / 2)
        out_levels.append(band * np.cos(shift) - rr * np.sin(shift))
    out = np.empty_like(frames)
    for t in range(n):
        g = lows[t]
        for s in reversed(range(scales)):
            shape = out_levels[s][t].shape
            g = expand(g, shape) + out_levels[s][t]
        out[t] = g
    return out


def magnify_csp(frames, fps, lo, hi, factor, scales=4, orientations=8):
    sos = bandpass(fps, lo, hi)
    h, w = frames.shape[1:]
    masks, low = csp_filters(h, w, scales, orientations)
    # What the bands pass, both halves of the plane (a band's real part
    # is its filter and its mirror image): the residual keeps the rest, so
    # a factor of 1 gives the input back.
    mirror = lambda m: np.roll(np.flip(m, (0, 1)), 1, (0, 1))
    covered = sum(m**2 + mirror(m) ** 2 for m in masks)
    norm = max(1.0, float(covered.max()))
    masks = [m / np.sqrt(norm) for m in masks]
    covered = covered / norm
    spec = np.fft.fft2(frames)
    out = np.fft.ifft2(spec * (1 - covered)).real.astype(np.float32)
    for m in masks:
        band = np.fft.ifft2(spec * m)
        amp = np.abs(band)
        d = np.angle(band[1:] * np.conj(band[:-1]))
        phase = np.concatenate([np.zeros((1, h, w)), np.cumsum(d, axis=0)])
        f = signal.sosfilt(sos, phase, axis=0)
        f = weighted_blur(f, amp)
        shift = np.clip((factor - 1) * f, -np.pi / 2, np.pi / 2)
        # Synthesis: the shifted band through its filter again.
        out += 2 * np.fft.ifft2(np.fft.fft2(band * np.exp(1j * shift)) * m).real
    return out


# ---- command line -----------------------------------------------------------


def motion(out, frames):
    """The motion an output adds to its input, per frame, along x and y:
    the difference projected on the mean frame's gradients (pixels, to
    first order); the first tenth of the frames (the band-pass starting)
    left out."""
    mean = frames.mean(axis=0)
    skip = len(frames) // 10
    d = (out - frames)[skip:]
    rows = []
    for g in np.gradient(mean):
        rows.append((d * g).sum(axis=(1, 2)) / max(float((g * g).sum()), 1e-12))
    return np.concatenate(rows)


def correlation(a, b):
    a = a.ravel() - a.mean()
    b = b.ravel() - b.mean()
    den = np.sqrt((a * a).sum() * (b * b).sum())
    return float(abs(a @ b) / den) if den > 0 else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("task", choices=["listen", "magnify"])
    ap.add_argument("video")
    ap.add_argument("out")
    ap.add_argument("--pyramid", choices=["riesz", "csp", "tiles"], default="riesz")
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument("--band", default="35,45")
    ap.add_argument("--factor", type=float, default=10.0)
    ap.add_argument("--compare", default=None)
    a = ap.parse_args()
    t0 = time.perf_counter()
    frames, fps = read_y4m(a.video, a.frames)
    if len(frames) < 2:
        sys.exit(f"{a.video}: fewer than 2 frames")
    result = {"frames": len(frames), "pixels": int(frames.shape[1] * frames.shape[2])}
    if a.task == "listen":
        x = {"riesz": listen_riesz, "csp": listen_csp, "tiles": listen_tiles}[a.pyramid](frames)
        x = x / max(np.abs(x).max(), 1e-12)
        wavfile.write(a.out, int(round(fps)), x.astype(np.float32))
        result["seconds"] = time.perf_counter() - t0
        if a.compare:
            _, ours = wavfile.read(a.compare)
            ours = np.asarray(ours, np.float64)
            hp = signal.butter(2, 20, btype="highpass", fs=fps, output="sos")
            m = min(len(ours), len(x))
            result["correlation"] = correlation(
                signal.sosfiltfilt(hp, ours[:m]), signal.sosfiltfilt(hp, x[:m])
            )
    else:
        if a.pyramid == "tiles":
            sys.exit("the tile method only listens")
        lo, hi = (float(v) for v in a.band.split(","))
        fn = magnify_riesz if a.pyramid == "riesz" else magnify_csp
        out = fn(frames, fps, lo, hi, a.factor)
        write_y4m(a.out, out, fps)
        result["seconds"] = time.perf_counter() - t0
        if a.compare:
            ours, _ = read_y4m(a.compare, len(frames))
            m = min(len(ours), len(out))
            mo, mn = motion(ours[:m], frames[:m]), motion(out[:m], frames[:m])
            result["correlation"] = correlation(mo, mn)
            result["motion_ratio"] = float(mn.std() / max(mo.std(), 1e-12))
    print(json.dumps(result))


if __name__ == "__main__":
    main()
