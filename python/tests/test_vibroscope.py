"""The Python package against the command line (issue 53).

Every function must return what the `vibroscope` command returns for the
same input: bit for bit where the command writes a file (JSON, UFF, WAV),
to rounding where the command prints numbers in a chosen unit (the
waveform CSV). Bad input raises with the library's message; a cancelled
run leaves no thread behind. pyuff must read every UFF file vibroscope
writes, with its units, lengths and nodes.

Needs the command: VIBROSCOPE_BIN, or `vibroscope` on PATH; the test
scenes are rendered by its simulator. Run by `.ci/run` (python/test.sh).
"""

import json
import os
import shutil
import signal
import subprocess
import threading
import time
import wave

import numpy as np
import pytest

import vibroscope

BIN = os.environ.get("VIBROSCOPE_BIN") or shutil.which("vibroscope")
if not BIN:
    pytest.skip(
        "no vibroscope command: set VIBROSCOPE_BIN (python/test.sh does)",
        allow_module_level=True,
    )

BEAM = """width = 96
height = 48
fps = 300.0
frames = 1200
object = [8, 8, 80, 32]
noise_std = 2.0
seed = {seed}
modal = {{ modes = [
    {{ freq_hz = 7.3, amplitude_px = 0.3, shape = 1, damping = 0.02 }},
    {{ freq_hz = 58.3, amplitude_px = 0.15, shape = 2, drive = "tone" }},
    {{ freq_hz = 128.0, amplitude_px = 0.1, shape = 3, damping = 0.005 }},
] }}
"""

# Long enough (about a second of `spectrum`) to be stopped midway.
LONG = """width = 128
height = 128
fps = 2000.0
frames = 4000
noise_std = 2.0
seed = 5
signal = { type = "tone", freq_hz = 440.0 }
amplitude_px = 0.05
"""

REGIONS = [(8, 16, 16, 16), (40, 16, 16, 16), (72, 16, 16, 16)]


def cli(*args, cwd=None):
    r = subprocess.run([BIN, *map(str, args)], capture_output=True, text=True, cwd=cwd)
    assert r.returncode == 0, f"vibroscope {' '.join(map(str, args))}: {r.stderr}"
    return r


def render(tmp, name, scene):
    toml = tmp / f"{name}.toml"
    toml.write_text(scene)
    out = tmp / f"{name}.y4m"
    cli("simulate", toml, "-o", out)
    return out


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("scenes")
    return {
        "beam": render(tmp, "beam", BEAM.format(seed=3)),
        "long": render(tmp, "long", LONG),
    }


def region_args(regions):
    return [a for r in regions for a in ("--region", ",".join(map(str, r)))]


def test_simulate_is_the_commands(scenes, tmp_path):
    (tmp_path / "b.toml").write_text(BEAM.format(seed=4))
    cli("simulate", tmp_path / "b.toml", "-o", tmp_path / "cli.y4m")
    r = vibroscope.simulate(tmp_path / "b.toml", tmp_path / "py.y4m", progress=False)
    assert r["frames"] == 1200
    assert (tmp_path / "cli.y4m").read_bytes() == (tmp_path / "py.y4m").read_bytes()
    with pytest.raises(ValueError, match="b.toml"):
        (tmp_path / "b.toml").write_text("widht = 3\n")
        vibroscope.simulate(tmp_path / "b.toml", tmp_path / "bad.y4m")
    assert not (tmp_path / "bad.y4m").exists()


def test_probe_is_the_commands(scenes, tmp_path):
    cli("probe", scenes["beam"], "--json", tmp_path / "probe.json")
    assert vibroscope.probe(scenes["beam"]) == json.loads((tmp_path / "probe.json").read_text())
    assert vibroscope.probe(str(scenes["beam"]), fps=250)["fps"] == 250.0


def test_spectrum_and_uff_are_the_commands_bit_for_bit(scenes, tmp_path):
    a, b = tmp_path / "cli", tmp_path / "py"
    a.mkdir()
    b.mkdir()
    flags = ["--scale", "0.5", "--quantity", "velocity", "--include-spectrum", *region_args(REGIONS)]
    cli("spectrum", scenes["beam"], "-o", "s.json", "--uff", "s.uff", *flags, cwd=a)
    # The same relative paths, from the same kind of directory.
    cwd = os.getcwd()
    os.chdir(b)
    try:
        report = vibroscope.spectrum(
            scenes["beam"],
            json="s.json",
            uff="s.uff",
            scale=0.5,
            quantity="velocity",
            regions=REGIONS,
            progress=False,
        )
    finally:
        os.chdir(cwd)
    assert (a / "s.json").read_bytes() == (b / "s.json").read_bytes()
    assert (a / "s.uff").read_bytes() == (b / "s.uff").read_bytes()
    freqs_hz, power = report.pop("frequencies_hz"), report.pop("power_db")
    assert report == json.loads((a / "s.json").read_text())
    assert len(freqs_hz) == len(power) == len(report["spectrum"]["power_db"])
    # The spectrum's strongest bin is one of the peaks.
    top = freqs_hz[np.argmax(power)]
    assert any(abs(p["frequency_hz"] - top) <= report["resolution_hz"] for p in report["peaks"]), top
    freqs = sorted(p["frequency_hz"] for p in report["peaks"])
    # The tone-driven mode, within the spectrum's resolution.
    assert any(abs(f - 58.3) < 2 * report["resolution_hz"] for f in freqs), freqs


def test_listen_is_the_commands(scenes, tmp_path):
    cli("listen", scenes["long"], "-o", tmp_path / "cli.wav")
    audio = vibroscope.listen(scenes["long"], tmp_path / "py.wav", progress=False)
    assert (tmp_path / "cli.wav").read_bytes() == (tmp_path / "py.wav").read_bytes()
    with wave.open(str(tmp_path / "cli.wav")) as w:
        assert w.getframerate() == audio.rate_hz
        pcm = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2")
    np.testing.assert_array_equal(audio.samples, pcm / 32768.0)
    # Without an output, nothing is kept and the samples are the same.
    again = vibroscope.listen(scenes["long"], progress=False)
    assert again.path is None and again.report["output"] is None
    np.testing.assert_array_equal(again.samples, audio.samples)


def test_displacement_is_the_waveform_export(scenes, tmp_path):
    cli(
        "spectrum", scenes["beam"], "-o", tmp_path / "s.json",
        "--waveform", tmp_path / "w.csv", "--scale", "0.5", *region_args(REGIONS),
    )
    motion = vibroscope.displacement(scenes["beam"], REGIONS, scale=0.5, progress=False)
    assert [m.region for m in motion] == REGIONS
    per_unit = {"mm": 1.0, "µm": 1000.0}
    for k, m in enumerate(motion, start=1):
        assert m.unit == "mm" and len(m.t) == len(m.x) == len(m.y) == 1200
        with open(tmp_path / f"w.roi{k}.csv", encoding="utf-8") as f:
            header = f.readline().strip().split(",")
        unit = header[1][len("x_"):]
        table = np.loadtxt(tmp_path / f"w.roi{k}.csv", delimiter=",", skiprows=1)
        np.testing.assert_allclose(m.t, table[:, 0], atol=1e-9)
        for got, col in ((m.x, 1), (m.y, 2)):
            want = table[:, col] / per_unit[unit]
            scale = np.abs(want).max()
            np.testing.assert_allclose(got - got.mean(), want, rtol=0, atol=1e-6 * scale)
    # The beam moves along y, most at its free end (region 3).
    amp = [np.std(m.y) for m in motion]
    assert amp[0] < amp[2] and np.std(motion[2].x) < amp[2] / 3


def test_pyuff_reads_the_uff_with_units_lengths_and_nodes(scenes, tmp_path):
    pyuff = pytest.importorskip("pyuff", reason="pyuff is not installed (pip install pyuff)")
    out = tmp_path / "beam.uff"
    vibroscope.spectrum(
        scenes["beam"], uff=out, regions=REGIONS, scale=0.5, quantity="velocity", progress=False
    )
    sets = pyuff.UFF(str(out)).read_sets()
    kinds = [s["type"] for s in sets]
    assert kinds == [164, 15] + [58] * (4 * len(REGIONS)), kinds
    units, nodes, records = sets[0], sets[1], sets[2:]
    assert units["units_code"] == 5 and units["length"] == 1000.0
    assert list(nodes["node_nums"]) == [1, 2, 3]
    centres = [((x + w / 2) * 0.5, (y + h / 2) * 0.5) for x, y, w, h in REGIONS]
    np.testing.assert_allclose(list(zip(nodes["x"], nodes["y"])), centres)
    np.testing.assert_allclose(nodes["z"], 0.0)
    motion = vibroscope.displacement(scenes["beam"], REGIONS, scale=0.5, progress=False)
    for i, r in enumerate(records):
        node, axis, kind = 1 + i // 4, 1 + (i // 2) % 2, i % 2
        assert (r["rsp_node"], r["rsp_dir"]) == (node, axis)
        assert r["ordinate_spec_data_type"] == 11 and r["ordinate_len_unit_exp"] == 1
        assert r["ordinate_axis_units_lab"] == "mm/s"
        if kind == 0:
            assert r["func_type"] == 1 and r["abscissa_axis_units_lab"] == "s"
            assert r["abscissa_spec_data_type"] == 17
            assert len(r["data"]) == 1200
            assert abs(r["abscissa_inc"] - 1 / 300) < 1e-8
            # The velocity of the displacement: d/dt in the frequency
            # domain (the line through it taken out and its slope put
            # back, the rest mirrored), as the documentation says.
            d = (motion[node - 1].x, motion[node - 1].y)[axis - 1]
            i = np.arange(len(d))
            slope, icpt = np.polyfit(i, d, 1)
            rest = d - (slope * i + icpt)
            ext = np.concatenate([rest, rest[::-1]])
            spec = np.fft.rfft(ext) * 2j * np.pi * np.fft.rfftfreq(len(ext), 1 / 300)
            spec[-1] = 0
            v = np.fft.irfft(spec, len(ext))[: len(d)] + slope * 300
            np.testing.assert_allclose(r["data"], v, rtol=0, atol=1e-9 * np.abs(v).max() + 1e-12)
            # The beam moves along y, and its free end most: that region's
            # velocity is the tone-driven mode's, 2π · 58.3 Hz · 0.15 px ·
            # 0.5 mm/px at the free end (28 mm/s) times the mode shape.
            if axis == 2 and node == 3:
                assert 5 < np.abs(r["data"]).max() < 60
        else:
            assert r["func_type"] == 12 and r["abscissa_axis_units_lab"] == "Hz"
            assert r["abscissa_spec_data_type"] == 18
            assert len(r["data"]) == 601 and abs(r["abscissa_inc"] - 0.25) < 1e-9
    # Without a scale: pixels, and no unit system record.
    vibroscope.spectrum(scenes["beam"], uff=tmp_path / "px.uff", regions=REGIONS[:1], progress=False)
    sets = pyuff.UFF(str(tmp_path / "px.uff")).read_sets()
    assert [s["type"] for s in sets] == [15, 58, 58, 58, 58]
    assert sets[1]["ordinate_axis_units_lab"] == "px" and sets[1]["ordinate_spec_data_type"] == 8


def test_bad_input_raises_the_librarys_message(scenes, tmp_path):
    with pytest.raises(OSError, match="missing.y4m"):
        vibroscope.probe(tmp_path / "missing.y4m")
    with pytest.raises(OSError, match="missing.y4m"):
        vibroscope.displacement(tmp_path / "missing.y4m", [(0, 0, 8, 8)])
    with pytest.raises(ValueError, match=r"region 2 \(90,40,20,20\) does not fit in the 96x48 frame"):
        vibroscope.displacement(scenes["beam"], [(0, 0, 8, 8), (90, 40, 20, 20)])
    with pytest.raises(ValueError, match="does not fit"):
        vibroscope.spectrum(scenes["beam"], uff=tmp_path / "x.uff", regions=[(90, 40, 20, 20)])
    assert not (tmp_path / "x.uff").exists()
    with pytest.raises(ValueError, match="fps: expected a number, got str"):
        vibroscope.spectrum(scenes["beam"], fps="300")
    with pytest.raises(ValueError, match="regions"):
        vibroscope.displacement(scenes["beam"], "0,0,8,8")
    with pytest.raises(ValueError, match="quantity"):
        vibroscope.spectrum(scenes["beam"], quantity="jerk")
    with pytest.raises(ValueError, match="video: expected a path"):
        vibroscope.listen(42)
    with pytest.raises(OSError, match="missing.y4m"):
        vibroscope.items("motion", "motion", replay=tmp_path / "missing.y4m")
    # Bad keys are refused and named: a pipeline's, and a keyword's.
    with pytest.raises(ValueError, match="field `nosuch`"):
        vibroscope.items("motion", "motion", replay=scenes["beam"], set=["motion.nosuch=1"])
    with pytest.raises(TypeError, match="nosuch"):
        vibroscope.spectrum(scenes["beam"], nosuch=1)


def threads():
    return len(os.listdir("/proc/self/task"))


def settle(before, timeout=2.0):
    end = time.time() + timeout
    while threads() > before and time.time() < end:
        time.sleep(0.01)
    return threads()


def test_a_stopped_run_leaves_no_thread(scenes, tmp_path):
    before = threads()
    calls = []

    def stop(done, total):
        calls.append((done, total))
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        vibroscope.spectrum(scenes["long"], json=tmp_path / "s.json", progress=stop)
    assert len(calls) == 1
    assert settle(before) == before
    # Ctrl-C itself: SIGINT while the run is under way.
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.time()
    with pytest.raises(KeyboardInterrupt):
        vibroscope.spectrum(scenes["long"], json=tmp_path / "s2.json", progress=False)
    assert time.time() - t0 < 5
    timer.join()
    assert settle(before) == before
    # The library is usable again afterwards.
    assert vibroscope.listen(scenes["long"], progress=False).rate_hz == 48000


def test_the_gil_is_released_and_progress_reported(scenes, tmp_path):
    seen = []
    done = threading.Event()

    def work():
        try:
            vibroscope.spectrum(
                scenes["long"], json=tmp_path / "s.json", progress=lambda d, t: seen.append((d, t))
            )
        finally:
            done.set()

    th = threading.Thread(target=work)
    th.start()
    spins = 0
    while not done.is_set():
        spins += 1
    th.join()
    # Python ran on this thread all along the call.
    assert spins > 10_000, spins
    assert seen and all(t == 4000 for _, t in seen), seen[:3]
    assert all(a <= b for (a, _), (b, _) in zip(seen, seen[1:]))


def test_modes_is_the_commands(scenes, tmp_path):
    cli("modes", scenes["beam"], "--at", "58.3", "-o", tmp_path / "cli.png", "--npy", tmp_path / "cli.npy")
    (r,) = vibroscope.modes(scenes["beam"], 58.3, tmp_path / "py.png", npy=tmp_path / "py.npy", progress=False)
    assert (tmp_path / "cli.npy").read_bytes() == (tmp_path / "py.npy").read_bytes()
    assert (tmp_path / "cli.png").read_bytes() == (tmp_path / "py.png").read_bytes()
    image = np.load(tmp_path / "cli.npy")
    assert r["image"].dtype == np.complex64 and r["image"].shape == (48, 96)
    np.testing.assert_array_equal(r["image"], image)
    assert r["freq_hz"] == 58.3 and r["peak"]["amplitude"] > 0
    # Two frequencies in one pass, no files kept.
    two = vibroscope.modes(scenes["beam"], [7.3, 58.3], progress=False)
    assert [m["freq_hz"] for m in two] == [7.3, 58.3] and two[0]["npy"] is None
    np.testing.assert_array_equal(two[1]["image"], image)


def test_magnify_is_the_commands(scenes, tmp_path):
    cli("magnify", scenes["beam"], "--band", "50,65", "--factor", "10", "-o", tmp_path / "cli.y4m")
    r = vibroscope.magnify(scenes["beam"], tmp_path / "py.y4m", 50, 65, 10, progress=False)
    assert (tmp_path / "cli.y4m").read_bytes() == (tmp_path / "py.y4m").read_bytes()
    assert r["frames"] == 1200 and (r["width"], r["height"]) == (96, 48)
    # The frames as an iterator: the luma of each frame of that file.
    data = (tmp_path / "cli.y4m").read_bytes()
    stream = data[: data.index(b"\n")].split()
    chroma = {b"Cmono": 0, b"C444": 2}.get(next((t for t in stream if t.startswith(b"C")), b"C420"), 0.5)
    pos, n = data.index(b"\n") + 1, 0
    for f in vibroscope.magnify_frames(scenes["beam"], 50, 65, 10, progress=False):
        assert data[pos : pos + 5] == b"FRAME"
        pos = data.index(b"\n", pos) + 1
        want = np.frombuffer(data[pos : pos + 96 * 48], dtype=np.uint8).reshape(48, 96)
        np.testing.assert_array_equal(f, want)
        pos += int(96 * 48 * (1 + chroma))
        n += 1
    assert n == 1200 and pos == len(data)


def test_calibrate_is_the_commands(scenes, tmp_path):
    cli("calibrate", scenes["long"], "--reference-tone", "440", "--json", tmp_path / "cli.json")
    r = vibroscope.calibrate(scenes["long"], reference_tone_hz=440, json=tmp_path / "py.json", progress=False)
    assert json.loads((tmp_path / "cli.json").read_text()) == r
    assert (tmp_path / "cli.json").read_bytes() == (tmp_path / "py.json").read_bytes()
    with pytest.raises(ValueError, match="one of the two"):
        vibroscope.calibrate(scenes["long"])
    with pytest.raises(ValueError, match="nonsense"):
        vibroscope.calibrate(scenes["long"], reference_tone_hz=440, effects=["nonsense"])


def test_a_pipelines_items_are_the_commands(scenes, tmp_path):
    # The shipped `motion` pipeline replayed: its WAV (32-bit float) holds
    # the samples the iterator hands over, bit for bit.
    cli("run", "motion", "--replay", scenes["long"], "--set", f"out.path={json.dumps(str(tmp_path / 'm.wav'))}")
    with vibroscope.items("motion", "motion", replay=scenes["long"]) as run:
        blocks = list(run)
        assert run.stats is not None
    assert blocks and all(b.kind == "audio" for b in blocks)
    got = np.concatenate([b.data for b in blocks])
    with open(tmp_path / "m.wav", "rb") as f:
        raw = f.read()
    data = raw[raw.index(b"data") + 8 :]
    want = np.frombuffer(data, dtype="<f4")
    assert len(got) == 4000
    np.testing.assert_array_equal(got, want[: len(got)])
    assert blocks[0].info["rate_hz"] == 2000.0 and blocks[0].t == 0.0
    # Frames, from the source.
    with vibroscope.items("motion", "src", replay=scenes["beam"]) as run:
        first = next(run)
    assert first.kind == "frame" and first.data.shape == (48, 96)
    # A bad stage is named.
    with pytest.raises(ValueError, match="nosuch"):
        vibroscope.items("motion", "nosuch", replay=scenes["beam"])


def test_a_pipeline_stopped_early_leaves_no_thread(scenes):
    before = threads()
    run = vibroscope.items("motion", "src", replay=scenes["long"], queue=4)
    for k, item in enumerate(run):
        if k == 10:
            break
    assert threads() > before
    run.close()
    assert settle(before) == before
    # Dropped without close: the same.
    run = vibroscope.items("motion", "src", replay=scenes["long"], queue=4)
    next(run)
    del run
    assert settle(before) == before
