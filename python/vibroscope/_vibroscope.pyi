"""The native module (crates/python): the recipes, called by vibroscope's functions."""

from typing import Any, Callable, Dict, List, Optional, Tuple

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
    include_spectrum: bool = False,
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

def modes(
    video: str,
    at_hz: List[float],
    png: str,
    npy: Optional[str] = None,
    fps: Optional[float] = None,
    roi: Optional[Tuple[int, int, int, int]] = None,
    motion: str = "sum",
    scale: Optional[float] = None,
    sigma: Optional[float] = None,
    progress: _Progress = None,
) -> str:
    """Runs `vibroscope modes`: the reports' JSON (a list, one per frequency)."""

def magnify(
    video: str,
    output: str,
    lo_hz: float,
    hi_hz: float,
    factor: float,
    fps: Optional[float] = None,
    roi: Optional[Tuple[int, int, int, int]] = None,
    pyramid: str = "csp",
    side_by_side: bool = False,
    progress: _Progress = None,
) -> str:
    """Runs `vibroscope magnify` to `output`: its report's JSON."""

def calibrate(
    video: str,
    json_path: str,
    reference: Optional[str] = None,
    reference_tone_hz: Optional[float] = None,
    output: Optional[str] = None,
    fps: Optional[float] = None,
    roi: Optional[Tuple[int, int, int, int]] = None,
    effects: Optional[List[str]] = None,
    progress: _Progress = None,
) -> str:
    """Runs `vibroscope calibrate`, writes `json_path` and returns its text."""

class Items:
    """A running pipeline's items of one stage, as dicts (arrays as bytes)."""

    def __iter__(self) -> "Items": ...
    def __next__(self) -> Dict[str, Any]: ...
    def close(self) -> None:
        """Stops the run and waits for its threads."""
    @property
    def stats(self) -> Optional[str]:
        """The run's per-stage table, once it has ended."""

def items(
    pipeline: str,
    stage: str,
    replay: Optional[str] = None,
    set: List[str] = ...,
    fps: Optional[float] = None,
    queue: int = 64,
) -> Items:
    """Starts the pipeline with a tap handing `stage`'s items over in order."""
