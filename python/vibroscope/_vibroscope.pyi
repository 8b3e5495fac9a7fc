"""The native module (crates/python): the recipes, called by vibroscope's functions."""

from typing import Any, Callable, List, Optional, Tuple

_Progress = Optional[Callable[[int, Optional[int]], Any]]

def version() -> str:
    """The library's version."""

def probe(video: str, fps: Optional[float] = None) -> str:
    """`vibroscope probe --json`'s document, as JSON text."""

def displacement(
    video: str,
    regions: List[Tuple[int, int, int, int]],
    fps: Optional[float] = None,
    progress: _Progress = None,
) -> Tuple[float, List[Tuple[bytes, bytes, bytes]]]:
    """The rate, and per region its times (s), x and y (px) as little-endian f64 bytes."""

def spectrum(
    video: str,
    json_path: str,
    fps: Optional[float] = None,
    roi: Optional[Tuple[int, int, int, int]] = None,
    peaks: int = 5,
    min_hz: Optional[float] = None,
    max_hz: Optional[float] = None,
    false_alarm: Optional[float] = None,
    scale: Optional[float] = None,
    quantity: str = "displacement",
    regions: List[Tuple[int, int, int, int]] = ...,
    uff: Optional[str] = None,
    waveform: Optional[str] = None,
    progress: _Progress = None,
) -> str:
    """Runs `vibroscope spectrum`, writes `json_path` and returns its text."""

def listen(
    video: str,
    output: str,
    fps: Optional[float] = None,
    roi: Optional[Tuple[int, int, int, int]] = None,
    float: bool = False,
    native_rate: bool = False,
    progress: _Progress = None,
) -> Tuple[str, int, bytes]:
    """Runs `vibroscope listen` to `output`: its report's JSON, the WAV's rate and samples (f64 bytes)."""

def simulate(
    scene: str,
    output: str,
    set: List[str] = ...,
    progress: _Progress = None,
) -> str:
    """Runs `vibroscope simulate` to `output`: what it wrote, as JSON."""
