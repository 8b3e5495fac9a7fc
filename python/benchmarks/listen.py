"""The Python call's cost over the recipe's (issue 53): `vibroscope.listen`
against the `vibroscope listen` command on the same 256x256, 2200-frame
recording, alternated, in one run. Prints each one's median wall time,
its throughput in Mpix/s and the ratio (the bar: at most 1.05).

    python python/benchmarks/listen.py [--runs N]     # VIBROSCOPE_BIN: the command

The command's time includes starting a process (a few ms); the Python
call's includes reading the WAV back into a numpy array.
"""

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import vibroscope

SCENE = """width = 256
height = 256
fps = 2200.0
frames = 2200
noise_std = 2.0
seed = 1
signal = { type = "chirp", f0_hz = 100.0, f1_hz = 1000.0, duration_s = 1.0 }
amplitude_px = 0.05
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    cmd = os.environ.get("VIBROSCOPE_BIN") or shutil.which("vibroscope")
    if not cmd:
        sys.exit("python/benchmarks/listen.py: no vibroscope command (set VIBROSCOPE_BIN)")
    with tempfile.TemporaryDirectory(prefix="vibroscope-bench-") as tmp:
        scene, video = os.path.join(tmp, "s.toml"), os.path.join(tmp, "s.y4m")
        with open(scene, "w", encoding="utf-8") as f:
            f.write(SCENE)
        vibroscope.simulate(scene, video, progress=False)
        out = os.path.join(tmp, "o.wav")
        py, cli = [], []
        for _ in range(a.runs):
            t = time.perf_counter()
            subprocess.run([cmd, "listen", video, "-o", out], check=True, capture_output=True)
            cli.append(time.perf_counter() - t)
            os.remove(out)
            t = time.perf_counter()
            vibroscope.listen(video, out, progress=False)
            py.append(time.perf_counter() - t)
            os.remove(out)
    mpix = 256 * 256 * 2200 / 1e6
    c, p = statistics.median(cli), statistics.median(py)
    print(f"listen, 256x256, 2200 frames, median of {a.runs}:")
    print(f"  command        {c:.3f} s  {mpix / c:7.1f} Mpix/s")
    print(f"  Python call    {p:.3f} s  {mpix / p:7.1f} Mpix/s")
    print(f"  ratio Python/command: {p / c:.3f} (bar: at most 1.05)")


if __name__ == "__main__":
    main()
