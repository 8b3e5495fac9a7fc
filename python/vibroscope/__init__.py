"""vibroscope from Python: the recipes of the `vibroscope` command, in-process.

Each function runs the same recipe as the command of the same name (no
subprocess): the GIL is released while it runs, Ctrl-C stops it (the run
is cancelled, then ``KeyboardInterrupt`` is raised), and an error is a
Python exception carrying the library's message (``OSError`` for a file
that is missing or unreadable, ``ValueError`` for a wrong value).

Progress: ``progress=None`` shows a tqdm bar when tqdm is installed,
``progress=False`` shows nothing, and a callable is called about ten times
a second as ``progress(frames_done, frames_total_or_None)``.

>>> import vibroscope
>>> (m,) = vibroscope.displacement("beam.y4m", [(40, 16, 16, 16)], scale=0.5)
>>> m.unit, m.rate_hz, m.y[:3]
"""

from __future__ import annotations

import json as _json
import os as _os
import tempfile as _tempfile
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _vibroscope as _native

__all__ = [
    "ArgumentError",
    "Audio",
    "Displacement",
    "calibrate",
    "displacement",
    "Item",
    "items",
    "Items",
    "listen",
    "magnify",
    "magnify_frames",
    "modes",
    "probe",
    "simulate",
    "spectrum",
]

__version__: str = _native.version()

PathLike = Union[str, "os.PathLike[str]"]
Region = Tuple[int, int, int, int]
Progress = Union[None, bool, Callable[[int, Optional[int]], Any]]


class ArgumentError(ValueError, TypeError):
    """An argument of the wrong type or shape (a ``ValueError`` and a ``TypeError``)."""


@dataclass
class Displacement:
    """One region's motion: +x right, +y down, as measured (not detrended)."""

    region: Region
    """``(x, y, w, h)`` in pixels."""
    rate_hz: float
    t: np.ndarray = field(repr=False)
    """Each sample's capture time, s."""
    x: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    unit: str = "px"
    """``px``, or ``mm`` with a scale."""


@dataclass
class Audio:
    """What ``listen`` recovered: the WAV's samples and rate, and its report."""

    samples: np.ndarray = field(repr=False)
    rate_hz: int
    report: Dict[str, Any]
    path: Optional[str]
    """The WAV written (``None`` when no ``output`` was asked)."""


def _path(name: str, value: Any) -> str:
    if not isinstance(value, (str, bytes, _os.PathLike)):
        raise ArgumentError(f"{name}: expected a path, got {type(value).__name__} {value!r}")
    return _os.fsdecode(value)


def _number(name: str, value: Any, integer: bool = False) -> Any:
    if value is None:
        return None
    kinds = (int, np.integer) if integer else (int, float, np.integer, np.floating)
    if isinstance(value, bool) or not isinstance(value, kinds):
        raise ArgumentError(
            f"{name}: expected {'an integer' if integer else 'a number'}, "
            f"got {type(value).__name__} {value!r}"
        )
    return int(value) if integer else float(value)


def _region(name: str, value: Any) -> Region:
    try:
        r = tuple(value)
    except TypeError:
        r = ()
    if len(r) != 4 or any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0 for v in r):
        raise ArgumentError(f"{name}: expected (x, y, w, h), four integers >= 0, got {value!r}")
    return tuple(int(v) for v in r)  # type: ignore[return-value]


def _regions(name: str, value: Any) -> List[Region]:
    if value is None:
        return []
    try:
        first = next(iter(value), None)
    except TypeError:
        raise ArgumentError(f"{name}: expected a list of (x, y, w, h), got {value!r}") from None
    if isinstance(first, (int, np.integer)):
        return [_region(name, value)]
    return [_region(f"{name}[{i}]", r) for i, r in enumerate(value)]


class _Bar:
    """A tqdm bar fed by the native progress callback."""

    def __init__(self, desc: str) -> None:
        from tqdm.auto import tqdm  # type: ignore[import-not-found]

        self._bar = tqdm(desc=desc, unit="frame")

    def __call__(self, done: int, total: Optional[int]) -> None:
        if total is not None and self._bar.total != total:
            self._bar.total = total
        self._bar.n = done
        self._bar.refresh()

    def close(self) -> None:
        self._bar.close()


def _with_progress(progress: Progress, desc: str, call: Callable[[Any], Any]) -> Any:
    if progress is False:
        return call(None)
    if callable(progress):
        return call(progress)
    if progress not in (None, True):
        raise ArgumentError(f"progress: expected None, a bool or a callable, got {progress!r}")
    try:
        bar = _Bar(desc)
    except ImportError:
        if progress is True:
            raise
        return call(None)
    try:
        return call(bar)
    finally:
        bar.close()


def _f64(b: bytes) -> np.ndarray:
    return np.frombuffer(b, dtype="<f8")


def probe(video: PathLike, fps: Optional[float] = None) -> Dict[str, Any]:
    """Describe a recording: format, size, bits, frames, rates, timestamps.

    The same fields as ``vibroscope probe --json`` writes.
    """
    return _json.loads(_native.probe(_path("video", video), _number("fps", fps)))


def displacement(
    video: PathLike,
    regions: Union[Region, Sequence[Region]],
    fps: Optional[float] = None,
    scale: Optional[float] = None,
    progress: Progress = None,
) -> List[Displacement]:
    """Each region's sub-pixel displacement over the recording, in one pass.

    ``regions``: one ``(x, y, w, h)`` or a list of them, in pixels. ``fps``:
    the capture rate when the file states the wrong one. ``scale``: mm per
    pixel (the values are then in mm). The method is ``spectrum
    --waveform``'s (the ``displacement`` stage: 2-D least squares on a
    7-tap gradient against the first frames).
    """
    rois = _regions("regions", regions)
    if not rois:
        raise ArgumentError("regions: give at least one (x, y, w, h)")
    k = _number("scale", scale)
    if k is not None and not (k > 0 and np.isfinite(k)):
        raise ArgumentError(f"scale: expected mm per pixel > 0, got {scale!r}")
    path = _path("video", video)
    rate, series = _with_progress(
        progress,
        "displacement",
        lambda cb: _native.displacement(path, rois, _number("fps", fps), cb),
    )
    c = 1.0 if k is None else k
    return [
        Displacement(
            region=r,
            rate_hz=rate,
            t=_f64(t),
            x=_f64(x) * c,
            y=_f64(y) * c,
            unit="px" if k is None else "mm",
        )
        for r, (t, x, y) in zip(rois, series)
    ]


def spectrum(
    video: PathLike,
    *,
    fps: Optional[float] = None,
    roi: Optional[Region] = None,
    peaks: int = 5,
    min_hz: Optional[float] = None,
    max_hz: Optional[float] = None,
    false_alarm: Optional[float] = None,
    scale: Optional[float] = None,
    quantity: str = "displacement",
    regions: Optional[Sequence[Region]] = None,
    uff: Optional[PathLike] = None,
    waveform: Optional[PathLike] = None,
    json: Optional[PathLike] = None,
    include_spectrum: bool = True,
    progress: Progress = None,
) -> Dict[str, Any]:
    """The motion spectrum's resonances: ``vibroscope spectrum`` in-process.

    Returns the report ``spectrum -o OUT.json`` writes (``peaks``: each
    with ``frequency_hz``, ``frequency_std_hz``, ``damping_ratio``,
    ``damping_ratio_std``, ``amplitude`` ...), and writes it to ``json``
    when given. With ``include_spectrum`` (``--include-spectrum``) the
    report also holds the spectrum, and two numpy arrays are added to
    the dict (not to the file): ``frequencies_hz`` and ``power_db``. ``uff``: also write the regions' motion as a Universal
    File (``--uff``: UFF 58 time responses and amplitude spectra of
    ``quantity``, a UFF 15 node per region); ``waveform``: the CSV
    exports (``--waveform``); ``regions``: theirs (``--region``).
    """
    args = dict(
        fps=_number("fps", fps),
        roi=None if roi is None else _region("roi", roi),
        peaks=_number("peaks", peaks, integer=True),
        min_hz=_number("min_hz", min_hz),
        max_hz=_number("max_hz", max_hz),
        false_alarm=_number("false_alarm", false_alarm),
        scale=_number("scale", scale),
        regions=_regions("regions", regions),
        uff=None if uff is None else _path("uff", uff),
        waveform=None if waveform is None else _path("waveform", waveform),
        include_spectrum=bool(include_spectrum),
    )
    if not isinstance(quantity, str):
        raise ArgumentError(f"quantity: expected a string, got {quantity!r}")
    path = _path("video", video)
    with _tempfile.TemporaryDirectory(prefix="vibroscope-") as tmp:
        out = _path("json", json) if json is not None else _os.path.join(tmp, "spectrum.json")
        text = _with_progress(
            progress,
            "spectrum",
            lambda cb: _native.spectrum(path, out, quantity=quantity, progress=cb, **args),
        )
    report = _json.loads(text)
    sp = report.get("spectrum")
    if sp:
        report["power_db"] = np.asarray(sp["power_db"], dtype=float)
        report["frequencies_hz"] = sp["f0_hz"] + sp["resolution_hz"] * np.arange(len(sp["power_db"]))
    return report


def listen(
    video: PathLike,
    output: Optional[PathLike] = None,
    *,
    fps: Optional[float] = None,
    roi: Optional[Region] = None,
    float: bool = False,
    native_rate: bool = False,
    progress: Progress = None,
) -> Audio:
    """The visual microphone: ``vibroscope listen`` in-process.

    Recovers the sound from the motion in ``roi`` (default: the whole
    frame) and returns its samples (mono, float64: 16-bit PCM scaled to
    [-1, 1), or with ``float=True`` the signal in its own units) and rate.
    ``output``: also keep the WAV there. ``native_rate``: the frame rate
    instead of a standard audio rate (``--rate native``).
    """
    path = _path("video", video)
    f = _number("fps", fps)
    r = None if roi is None else _region("roi", roi)
    with _tempfile.TemporaryDirectory(prefix="vibroscope-") as tmp:
        out = _path("output", output) if output is not None else _os.path.join(tmp, "listen.wav")
        report, rate, samples = _with_progress(
            progress,
            "listen",
            lambda cb: _native.listen(path, out, f, r, bool(float), bool(native_rate), cb),
        )
        samples = _f64(samples).copy()
    report = _json.loads(report)
    if output is None:
        report["output"] = None
    return Audio(
        samples=samples,
        rate_hz=rate,
        report=report,
        path=None if output is None else out,
    )


def simulate(
    scene: PathLike,
    output: PathLike,
    set: Optional[Sequence[str]] = None,
    progress: Progress = None,
) -> Dict[str, Any]:
    """Render a scene file (TOML) through the forward model to a Y4M file.

    ``vibroscope simulate SCENE -o OUTPUT --set KEY=VALUE ...`` in-process:
    the scene's keys are the ``synthetic`` source's (``vibroscope kinds
    synthetic``), among them ``modal`` for a cantilever beam with known
    modes. Returns ``{"output": ..., "frames": ...}``.
    """
    sets = list(set or [])
    if not all(isinstance(v, str) for v in sets):
        raise ArgumentError(f"set: expected KEY=VALUE strings, got {set!r}")
    src, out = _path("scene", scene), _path("output", output)
    text = _with_progress(progress, "simulate", lambda cb: _native.simulate(src, out, sets, cb))
    return _json.loads(text)


def modes(
    video: PathLike,
    at_hz: Union[float, Sequence[float]],
    png: Optional[PathLike] = None,
    *,
    npy: Optional[PathLike] = None,
    fps: Optional[float] = None,
    roi: Optional[Region] = None,
    motion: str = "sum",
    scale: Optional[float] = None,
    sigma: Optional[float] = None,
    progress: Progress = None,
) -> List[Dict[str, Any]]:
    """Modal images (thesis 3.5): ``vibroscope modes`` in-process.

    One report per frequency of ``at_hz`` (all imaged in one pass), each
    with ``image``: the complex modal image (numpy complex64, rows x
    columns; px, or mm/µm with ``scale``: the report's ``unit``), beside
    the command's fields (``peak``, ``shape`` checks ...). ``png`` and
    ``npy`` also keep the files (with several frequencies, named after
    each, as the command does).
    """
    freqs = [at_hz] if isinstance(at_hz, (int, float, np.integer, np.floating)) else list(at_hz)
    freqs = [_number(f"at_hz[{i}]", f) for i, f in enumerate(freqs)]
    if not isinstance(motion, str):
        raise ArgumentError(f"motion: expected x, y or sum, got {motion!r}")
    args = dict(
        fps=_number("fps", fps),
        roi=None if roi is None else _region("roi", roi),
        motion=motion,
        scale=_number("scale", scale),
        sigma=_number("sigma", sigma),
    )
    path = _path("video", video)
    with _tempfile.TemporaryDirectory(prefix="vibroscope-") as tmp:
        out_png = _path("png", png) if png is not None else _os.path.join(tmp, "mode.png")
        out_npy = _path("npy", npy) if npy is not None else _os.path.join(tmp, "mode.npy")
        text = _with_progress(
            progress,
            "modes",
            lambda cb: _native.modes(path, freqs, out_png, out_npy, progress=cb, **args),
        )
        reports = _json.loads(text)
        for r in reports:
            r["image"] = np.load(r["npy"])
            if png is None:
                r["png"] = None
            if npy is None:
                r["npy"] = None
    return reports


def magnify(
    video: PathLike,
    output: PathLike,
    lo_hz: float,
    hi_hz: float,
    factor: float,
    *,
    fps: Optional[float] = None,
    roi: Optional[Region] = None,
    pyramid: str = "csp",
    side_by_side: bool = False,
    progress: Progress = None,
) -> Dict[str, Any]:
    """Motion magnification: ``vibroscope magnify`` in-process.

    Magnifies the motion between ``lo_hz`` and ``hi_hz`` by ``factor``
    (phase-based, ``pyramid`` ``"csp"`` or ``"riesz"``) into ``output``
    (``.y4m``, or ``.mp4`` and what else ffmpeg writes). Returns the
    report (frames, size, rate, notes).
    """
    args = dict(
        lo_hz=_number("lo_hz", lo_hz),
        hi_hz=_number("hi_hz", hi_hz),
        factor=_number("factor", factor),
        fps=_number("fps", fps),
        roi=None if roi is None else _region("roi", roi),
        side_by_side=bool(side_by_side),
    )
    if not isinstance(pyramid, str):
        raise ArgumentError(f"pyramid: expected csp or riesz, got {pyramid!r}")
    path, out = _path("video", video), _path("output", output)
    text = _with_progress(
        progress,
        "magnify",
        lambda cb: _native.magnify(path, out, pyramid=pyramid, progress=cb, **args),
    )
    return _json.loads(text)


def _y4m_frames(path: str):
    """The luma plane of each frame of a Y4M file, as uint8 or uint16 arrays."""
    with open(path, "rb") as f:
        header = f.readline().split()
        if not header or header[0] != b"YUV4MPEG2":
            raise ValueError(f"{path}: not a Y4M file")
        fields = {h[:1].decode(): h[1:].decode() for h in header[1:]}
        w, h = int(fields["W"]), int(fields["H"])
        c = fields.get("C", "420")
        depth = 2 if c == "mono16" or c.endswith(("p10", "p12", "p14", "p16")) else 1
        if c.startswith("mono"):
            chroma = 0
        elif c.startswith("444"):
            chroma = 2 * w * h
        elif c.startswith("422"):
            chroma = 2 * ((w + 1) // 2) * h
        else:
            chroma = 2 * ((w + 1) // 2) * ((h + 1) // 2)
        while True:
            line = f.readline()
            if not line:
                return
            if not line.startswith(b"FRAME"):
                raise ValueError(f"{path}: expected a FRAME header, got {line[:20]!r}")
            raw = f.read((w * h + chroma) * depth)
            if len(raw) < (w * h + chroma) * depth:
                raise ValueError(f"{path}: the last frame is cut short")
            dtype = "<u2" if depth == 2 else "u1"
            yield np.frombuffer(raw[: w * h * depth], dtype=dtype).reshape(h, w)


def magnify_frames(
    video: PathLike,
    lo_hz: float,
    hi_hz: float,
    factor: float,
    **kwargs: Any,
):
    """The magnified frames, one numpy array (luma, rows x columns) at a
    time: ``magnify`` into a temporary Y4M file, read back as it is
    iterated and removed when the iteration ends. Takes ``magnify``'s
    keyword arguments.
    """
    with _tempfile.TemporaryDirectory(prefix="vibroscope-") as tmp:
        out = _os.path.join(tmp, "magnified.y4m")
        magnify(video, out, lo_hz, hi_hz, factor, **kwargs)
        yield from _y4m_frames(out)


def calibrate(
    video: PathLike,
    reference: Optional[PathLike] = None,
    *,
    reference_tone_hz: Optional[float] = None,
    json: Optional[PathLike] = None,
    output: Optional[PathLike] = None,
    fps: Optional[float] = None,
    roi: Optional[Region] = None,
    effects: Optional[Sequence[str]] = None,
    progress: Progress = None,
) -> Dict[str, Any]:
    """The calibration loop: ``vibroscope calibrate`` in-process.

    Fits the recording's recovered sound to the ``reference`` that was
    played (a WAV), or to a pure tone of ``reference_tone_hz`` (a tuning
    fork), over the catalog of effects (``effects``: some of them by
    name) and the residual explainer; returns the REPORT.json it writes
    (to ``json`` when given; ``output``: also the corrected WAV).
    """
    if (reference is None) == (reference_tone_hz is None):
        raise ArgumentError("give reference (a WAV) or reference_tone_hz, one of the two")
    if effects is not None and (isinstance(effects, str) or not all(isinstance(e, str) for e in effects)):
        raise ArgumentError(f"effects: expected a list of effect names, got {effects!r}")
    args = dict(
        reference=None if reference is None else _path("reference", reference),
        reference_tone_hz=_number("reference_tone_hz", reference_tone_hz),
        output=None if output is None else _path("output", output),
        fps=_number("fps", fps),
        roi=None if roi is None else _region("roi", roi),
        effects=None if effects is None else list(effects),
    )
    path = _path("video", video)
    with _tempfile.TemporaryDirectory(prefix="vibroscope-") as tmp:
        out = _path("json", json) if json is not None else _os.path.join(tmp, "REPORT.json")
        text = _with_progress(
            progress, "calibrate", lambda cb: _native.calibrate(path, out, progress=cb, **args)
        )
    return _json.loads(text)


@dataclass
class Item:
    """One item of a pipeline's stage, as the stage emitted it."""

    kind: str
    """``frame``, ``samples``, ``audio`` or ``spectrum``."""
    t: float
    """Capture time (s): of the frame, of the first sample, of the spectrum's window centre."""
    data: np.ndarray = field(repr=False)
    """frame: uint8 (rows, columns); samples: float32 (n, channels);
    audio: float32 (n,); spectrum: float32 power per bin."""
    info: Dict[str, Any] = field(default_factory=dict)
    """The rest: rate_hz, seq, f0_hz, resolution_hz, window, segments, times."""


def _item(d: Dict[str, Any]) -> Item:
    kind = d.pop("kind")
    if kind == "frame":
        data = np.frombuffer(d.pop("pixels"), dtype=np.uint8).reshape(d["height"], d["width"])
        return Item(kind, d.pop("t"), data, d)
    if kind == "samples":
        data = np.frombuffer(d.pop("data"), dtype="<f4").reshape(-1, d["channels"])
        if "times" in d:
            d["times"] = _f64(d["times"])
        return Item(kind, d.pop("t0"), data, d)
    if kind == "audio":
        return Item(kind, d.pop("t0"), np.frombuffer(d.pop("data"), dtype="<f4"), d)
    return Item(kind, d.pop("t"), np.frombuffer(d.pop("power"), dtype="<f4"), d)


class Items:
    """The items of one stage of a running pipeline, in order.

    Iterate it (``for item in vibroscope.items(...)``); ``close()``, the
    end of a ``with`` block or dropping it stops the run (its sinks
    finalise what they had) and waits for its threads. Ctrl-C while it
    waits stops the run and raises ``KeyboardInterrupt``.
    """

    def __init__(self, native: Any) -> None:
        self._native = native

    def __iter__(self) -> "Items":
        return self

    def __next__(self) -> Item:
        return _item(next(self._native))

    def close(self) -> None:
        self._native.close()

    def __enter__(self) -> "Items":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    @property
    def stats(self) -> Optional[str]:
        """The run's per-stage table (``--stats``), once it has ended."""
        return self._native.stats


def items(
    pipeline: str,
    stage: str,
    *,
    replay: Optional[PathLike] = None,
    set: Optional[Sequence[str]] = None,
    fps: Optional[float] = None,
    queue: int = 64,
) -> Items:
    """Run a pipeline and iterate over one stage's items, live or replayed.

    ``pipeline``: a shipped pipeline's name (``vibroscope pipelines``) or a
    TOML file; ``stage``: the id of the stage whose output you want;
    ``replay``: a recording in place of the pipeline's source; ``set``:
    ``STAGE.KEY=VALUE`` overrides, as ``vibroscope run --set``. Every item
    comes in order: a replay waits for you (never drops, bit-identical to
    ``vibroscope run``); a live source drops by its edges' policy when
    more than ``queue`` items wait unread.
    """
    sets = list(set or [])
    if not all(isinstance(v, str) for v in sets):
        raise ArgumentError(f"set: expected STAGE.KEY=VALUE strings, got {set!r}")
    for name, v in (("pipeline", pipeline), ("stage", stage)):
        if not isinstance(v, str):
            raise ArgumentError(f"{name}: expected a string, got {v!r}")
    return Items(
        _native.items(
            pipeline,
            stage,
            None if replay is None else _path("replay", replay),
            sets,
            _number("fps", fps),
            _number("queue", queue, integer=True),
        )
    )
