"""pyOMA2 SSI-cov on a motion signal vibroscope extracted (README, "Spectra
and damping"). Usage: python pyoma2_ssi_cov.py motion.wav [BLOCK_ROWS]

The motion comes from the kept beam video through this graph (no high-pass,
so the 7.3 Hz mode survives), saved as extract.toml next to beam.y4m:

    [pipeline]
    name = "extract"
    [[stage]]
    id = "src"
    kind = "file"
    path = "beam.y4m"
    [[stage]]
    id = "phase"
    kind = "phase"
    input = "src"
    pyramid = "riesz"
    scales = 4
    block = 64
    [[stage]]
    id = "align"
    kind = "align"
    input = "phase"
    [[stage]]
    id = "out"
    kind = "wav"
    input = "align"
    path = "motion.wav"

    vibroscope run extract.toml
"""
import sys, time, numpy as np
from pyoma2.algorithms import SSI
from pyoma2.setup import SingleSetup

def read_f32_wav(path):
    b = open(path, "rb").read()
    i = 12
    rate = None
    while i < len(b):
        cid, size = b[i:i+4], int.from_bytes(b[i+4:i+8], "little")
        if cid == b"fmt ":
            rate = int.from_bytes(b[i+12:i+16], "little")
        if cid == b"data":
            return rate, np.frombuffer(b[i+8:i+8+size], dtype="<f4").astype(float)
        i += 8 + size + (size & 1)
    raise SystemExit("no data chunk")

rate, x = read_f32_wav(sys.argv[1])
br = int(sys.argv[2]) if len(sys.argv) > 2 else 60
t = time.time()
ss = SingleSetup(x[:, None], fs=rate)
alg = SSI(name="SSIcov", method="cov", br=br, ordmax=30, hc={"xi_max": 0.2, "mpc_lim": None, "mpd_lim": None, "CoV_max": None})
ss.add_algorithms(alg)
ss.run_by_name("SSIcov")
r = ss["SSIcov"].result
F, X = r.Fn_poles, r.Xi_poles
print("br", br, "seconds", round(time.time() - t, 1), "poles shape", F.shape)
for k, f0 in enumerate([7.3, 58.3, 128.0]):
    rows = []
    for o in range(F.shape[1]):
        col = F[:, o]
        ok = np.isfinite(col)
        if not ok.any():
            continue
        i = np.nanargmin(np.abs(col - f0))
        if abs(col[i] - f0) < 0.05 * f0:
            rows.append((o, col[i], X[i, o]))
    if rows:
        fs = np.array([r[1] for r in rows]); xs = np.array([r[2] for r in rows])
        # the orders where the pole is stable: the upper half of the orders found
        half = rows[len(rows)//2:]
        fh = np.median([r[1] for r in half]); xh = np.median([r[2] for r in half])
        print(f"mode {k+1}: median over orders {half[0][0]}-{half[-1][0]}: {fh:.4f} Hz xi {xh:.5f} (spread {np.std([r[2] for r in half]):.5f})")
