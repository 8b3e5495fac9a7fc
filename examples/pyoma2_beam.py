"""Operational modal analysis of a beam filmed by a camera: vibroscope
measures several regions' displacement, pyOMA2's SSI-cov identifies the
modes, and both are compared with vibroscope's own resonances (its
spectrum's peaks; its mode shapes: each region's motion at each peak, the
thesis's modal image sampled at the regions) and, on the built-in scene,
with the simulator's truth.

    pip install ./ pyOMA-2          # from the repository's root
    python examples/pyoma2_beam.py                  # the simulated beam
    python examples/pyoma2_beam.py clip.y4m --fps 600 --hz 7.3,58,128 \
        --regions 8,16,10,16 18,16,10,16 ...        # a recording of yours

Without a recording it renders a cantilever beam with three known modes
(the simulator's `modal` key: Euler-Bernoulli clamped-free shapes at
7.3, 58.3 and 128 Hz), 20 s at 300 frames/s, and prints how far each
estimate is from the truth. python/tests/test_pyoma2.py runs it.
"""

import argparse
import logging
import os
import sys
import tempfile

import numpy as np

import vibroscope

BEAM = """width = 96
height = 48
fps = 300.0
frames = 6000
object = [8, 8, 80, 32]
noise_std = 2.0
seed = {seed}
modal = {{ modes = [
    {{ freq_hz = 7.3, amplitude_px = 0.3, shape = 1, damping = 0.01 }},
    {{ freq_hz = 58.3, amplitude_px = 0.2, shape = 2, damping = 0.005 }},
    {{ freq_hz = 128.0, amplitude_px = 0.15, shape = 3, damping = 0.005 }},
] }}
"""
BEAM_HZ = [7.3, 58.3, 128.0]
# The beam is columns 8..88; eight regions of 10 columns, on rows 16..32
# (away from its static top and bottom outline).
BEAM_REGIONS = [(8 + 10 * k, 16, 10, 16) for k in range(8)]
BEAM_X0, BEAM_LEN = 8, 80


def cantilever_shape(n, s):
    """Clamped-free Euler-Bernoulli mode n at s = x / L (the simulator's)."""
    b = [1.8751040687, 4.6940911330, 7.8547574382, 10.995540735][n - 1]
    sigma = (np.cosh(b) + np.cos(b)) / (np.sinh(b) + np.sin(b))

    def raw(s):
        return np.cosh(b * s) - np.cos(b * s) - sigma * (np.sinh(b * s) - np.sin(b * s))

    return raw(s) / raw(1.0)


def beam_truth(regions):
    """Each mode's shape averaged over each region's columns."""
    shapes = []
    for n in (1, 2, 3):
        shapes.append(
            [
                np.mean(cantilever_shape(n, (np.arange(x - BEAM_X0, x - BEAM_X0 + w) + 0.5) / BEAM_LEN))
                for x, _, w, _ in regions
            ]
        )
    return np.array(shapes).T


def mac(a, b):
    """The modal assurance criterion of two shapes (NaN when either is unknown)."""
    a, b = np.asarray(a), np.asarray(b)
    return float(abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real))


def region_shapes(motion, freqs):
    """vibroscope's mode shapes: each region's y motion at each frequency
    (the complex amplitude of a Hann-windowed DFT at that frequency; NaN
    where the frequency is NaN)."""
    y = np.stack([m.y - m.y.mean() for m in motion], axis=1)
    n = len(y)
    t = np.arange(n) / motion[0].rate_hz
    w = np.hanning(n)
    return np.array([(w[:, None] * y * np.exp(-2j * np.pi * f * t)[:, None]).sum(0) for f in freqs]).T


def analyse(video, regions, hz, fps=None, br=120, order=20):
    """pyOMA2's SSI-cov and vibroscope's own modes of `regions` of `video`
    near the frequencies `hz`."""
    from pyoma2.algorithms import SSI
    from pyoma2.setup import SingleSetup

    logging.getLogger("pyoma2").setLevel(logging.WARNING)
    motion = vibroscope.displacement(video, regions, fps=fps, progress=False)
    rate = motion[0].rate_hz
    data = np.stack([m.y - m.y.mean() for m in motion], axis=1)
    setup = SingleSetup(data, fs=rate)
    ssi = SSI(name="SSIcov", method="cov", br=br, ordmax=2 * order)
    setup.add_algorithms(ssi)
    setup.run_all()
    setup.mpe("SSIcov", sel_freq=list(hz), order_in=order)
    res = setup["SSIcov"].result
    # vibroscope's resonances: the spectrum's peak nearest each frequency,
    # within 3% of it (none: vibroscope reported no resonance there).
    report = vibroscope.spectrum(video, fps=fps, peaks=10, progress=False)
    ours = []
    for f in hz:
        near = [p for p in report["peaks"] if abs(p["frequency_hz"] / f - 1) < 0.03]
        ours.append(min(near, key=lambda p: abs(p["frequency_hz"] - f)) if near else None)
    our_hz = [p["frequency_hz"] if p else float("nan") for p in ours]
    return {
        "rate_hz": rate,
        "pyoma2_hz": np.asarray(res.Fn, dtype=float),
        "pyoma2_damping": np.asarray(res.Xi, dtype=float),
        "pyoma2_shapes": np.asarray(res.Phi),
        "vibroscope_hz": np.asarray(our_hz),
        "vibroscope_damping": np.asarray([p["damping_ratio"] if p else float("nan") for p in ours]),
        "vibroscope_shapes": region_shapes(motion, our_hz),
    }


def main(argv=None, seed=11):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("video", nargs="?", help="a recording (default: render the simulated beam)")
    ap.add_argument("--fps", type=float, help="capture rate, when the file states the wrong one")
    ap.add_argument("--regions", nargs="+", help="regions X,Y,W,H (at least four)")
    ap.add_argument("--hz", help="the modes' approximate frequencies, F1,F2,...")
    ap.add_argument("--seed", type=int, default=seed, help="the simulated beam's noise seed")
    a = ap.parse_args(argv)
    truth = None
    with tempfile.TemporaryDirectory(prefix="pyoma2-beam-") as tmp:
        if a.video is None:
            scene = os.path.join(tmp, "beam.toml")
            with open(scene, "w", encoding="utf-8") as f:
                f.write(BEAM.format(seed=a.seed))
            video = os.path.join(tmp, "beam.y4m")
            vibroscope.simulate(scene, video, progress=False)
            regions, hz = BEAM_REGIONS, BEAM_HZ
            truth = beam_truth(regions)
        else:
            if not (a.regions and a.hz):
                ap.error("with a recording, give --regions (at least four) and --hz")
            video = a.video
            regions = [tuple(int(v) for v in r.split(",")) for r in a.regions]
            hz = [float(v) for v in a.hz.split(",")]
        r = analyse(video, regions, hz, fps=a.fps)
    print(f"{len(regions)} regions at {r['rate_hz']:.1f} samples/s")
    print(" mode  truth Hz  pyOMA2 Hz (damping)  vibroscope Hz (damping)  MAC pyOMA2-vibroscope"
          + ("  MAC pyOMA2-truth  MAC vibroscope-truth" if truth is not None else ""))
    r["mac_pyoma2_truth"], r["mac_vibroscope_truth"], r["mac_between"] = [], [], []
    for k, f in enumerate(hz):
        between = mac(r["pyoma2_shapes"][:, k], r["vibroscope_shapes"][:, k])
        r["mac_between"].append(between)
        line = (f" {k + 1:4d}  {f if truth is not None else float('nan'):8.2f}  "
                f"{r['pyoma2_hz'][k]:9.3f} ({r['pyoma2_damping'][k]:.4f})  "
                f"{r['vibroscope_hz'][k]:13.3f} ({r['vibroscope_damping'][k]:.4f})  {between:21.4f}")
        if truth is not None:
            a1 = mac(r["pyoma2_shapes"][:, k], truth[:, k])
            a2 = mac(r["vibroscope_shapes"][:, k], truth[:, k])
            r["mac_pyoma2_truth"].append(a1)
            r["mac_vibroscope_truth"].append(a2)
            line += f"  {a1:16.4f}  {a2:20.4f}"
        print(line)
    return r


if __name__ == "__main__":
    main()
    sys.exit(0)
