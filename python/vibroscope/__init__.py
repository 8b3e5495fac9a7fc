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
    "displacement",
    "listen",
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
    progress: Progress = None,
) -> Dict[str, Any]:
    """The motion spectrum's resonances: ``vibroscope spectrum`` in-process.

    Returns the report ``spectrum -o OUT.json`` writes (``peaks``: each
    with ``frequency_hz``, ``frequency_std_hz``, ``damping_ratio``,
    ``damping_ratio_std``, ``amplitude`` ...), and writes it to ``json``
    when given. ``uff``: also write the regions' motion as a Universal
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
    return _json.loads(text)


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
