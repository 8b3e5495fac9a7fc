//! `vibroscope._vibroscope`: the recipes, called in-process from Python.
//!
//! Each function runs its recipe on a thread of its own, without the GIL,
//! while the calling thread waits: every 100 ms it takes the GIL back to
//! call the progress callback (frames done, frames in all or `None`) and
//! to let Python handle its signals. A Ctrl-C (any exception raised by a
//! signal handler, or by the callback) cancels the run (sinks finalise
//! what they had, as on the command line's Ctrl-C), waits for it to end
//! and raises that exception: no thread of the run outlives the call.
//!
//! Errors carry the library's message: a missing or unreadable file is an
//! `OSError`, a wrong value (a region outside the frame, an unknown
//! quantity) a `ValueError`, anything else that failed while running a
//! `RuntimeError`.
//!
//! Reports come back as the JSON text the command line writes (the Python
//! layer parses it) and sample arrays as little-endian f64 bytes (the
//! Python layer wraps them in numpy arrays without a copy): the module
//! needs no numpy headers, so one abi3 wheel serves every Python 3.

use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use vibroscope::pipeline::{Cancel, Roi, RunSettings};
use vibroscope::{Error, ErrorKind};

/// The error and its causes, as the command line prints them.
fn message(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let s = c.to_string();
        if !text.contains(&s) {
            text.push_str(": ");
            text.push_str(&s);
        }
        cause = c.source();
    }
    text
}

fn py_err(e: Error) -> PyErr {
    let text = message(&e);
    match (&e, e.kind()) {
        (Error::Interrupted { .. }, _) | (_, ErrorKind::Interrupted) => {
            PyKeyboardInterrupt::new_err(text)
        }
        (Error::Input { .. } | Error::File(_), _) => PyOSError::new_err(text),
        (_, ErrorKind::Usage) => PyValueError::new_err(text),
        _ => PyRuntimeError::new_err(text),
    }
}

/// Runs `f` off the GIL on a thread of its own (see the module docs).
fn run<T: Send>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    f: impl FnOnce() -> vibroscope::Result<T> + Send,
) -> PyResult<T> {
    let cancel = Cancel::new();
    let worker_cancel = Arc::clone(&cancel);
    std::thread::scope(|s| {
        let worker = s.spawn(move || Cancel::scope(&worker_cancel, f));
        let mut stopped: Option<PyErr> = None;
        loop {
            let finished = py.detach(|| {
                for _ in 0..10 {
                    if worker.is_finished() {
                        return true;
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
                worker.is_finished()
            });
            if finished {
                break;
            }
            if stopped.is_some() {
                continue;
            }
            let mut check = py.check_signals();
            if check.is_ok() {
                if let Some(cb) = progress {
                    let p = vibroscope::pipeline::progress();
                    check = cb.call1((p.frames, p.total)).map(drop);
                }
            }
            if let Err(e) = check {
                cancel.cancel();
                stopped = Some(e);
            }
        }
        let result = worker.join();
        if let Some(e) = stopped {
            return Err(e);
        }
        match result {
            Ok(r) => r.map_err(py_err),
            Err(_) => Err(PyRuntimeError::new_err(
                "vibroscope: the run panicked (a bug: please report it with the input)",
            )),
        }
    })
}

fn bytes<'py>(py: Python<'py>, v: impl IntoIterator<Item = f64>) -> Bound<'py, PyBytes> {
    let raw: Vec<u8> = v.into_iter().flat_map(f64::to_le_bytes).collect();
    PyBytes::new(py, &raw)
}

fn json<T: serde::Serialize + ?Sized>(v: &T) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

fn rois(regions: Vec<[u32; 4]>) -> Vec<Roi> {
    regions
        .into_iter()
        .map(|[x, y, w, h]| Roi { x, y, w, h })
        .collect()
}

/// What `vibroscope probe --json` writes, as JSON text.
#[pyfunction]
#[pyo3(signature = (video, fps=None))]
fn probe(py: Python<'_>, video: PathBuf, fps: Option<f64>) -> PyResult<String> {
    let r = run(py, None, move || vibroscope::probe::probe(&video, fps))?;
    json(&r)
}

/// One region's times, x and y (f64 bytes).
type Series<'py> = (
    Bound<'py, PyBytes>,
    Bound<'py, PyBytes>,
    Bound<'py, PyBytes>,
);

/// Each region's displacement in px: (rate_hz, [(t, x, y) bytes per region]).
#[pyfunction]
#[pyo3(signature = (video, regions, fps=None, progress=None))]
fn displacement<'py>(
    py: Python<'py>,
    video: PathBuf,
    regions: Vec<[u32; 4]>,
    fps: Option<f64>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(f64, Vec<Series<'py>>)> {
    let settings = RunSettings {
        progress: progress.is_some(),
    };
    let motion = run(py, progress.as_ref(), move || {
        vibroscope::motion::displacement(&video, fps, regions, settings)
    })?;
    let rate = motion.first().map_or(f64::NAN, |m| m.rate_hz);
    let out = motion
        .iter()
        .map(|m| {
            (
                bytes(py, m.t_s.iter().copied()),
                bytes(py, m.x.iter().map(|&v| f64::from(v))),
                bytes(py, m.y.iter().map(|&v| f64::from(v))),
            )
        })
        .collect();
    Ok((rate, out))
}

/// `vibroscope spectrum`: writes `json` (and `uff`, `waveform`) and
/// returns the JSON's text.
#[pyfunction]
#[pyo3(signature = (video, json_path, fps=None, roi=None, peaks=5, min_hz=None, max_hz=None,
    false_alarm=None, scale=None, quantity="displacement", regions=Vec::new(), uff=None,
    waveform=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn spectrum(
    py: Python<'_>,
    video: PathBuf,
    json_path: PathBuf,
    fps: Option<f64>,
    roi: Option<[u32; 4]>,
    peaks: usize,
    min_hz: Option<f64>,
    max_hz: Option<f64>,
    false_alarm: Option<f64>,
    scale: Option<f64>,
    quantity: &str,
    regions: Vec<[u32; 4]>,
    uff: Option<PathBuf>,
    waveform: Option<PathBuf>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    use vibroscope::spectrum::SpectrumOptions;
    let mut o = SpectrumOptions::new(&video, &json_path);
    o.fps = fps;
    o.region.roi = roi.map(|[x, y, w, h]| Roi { x, y, w, h });
    o.peaks = peaks;
    o.min_hz = min_hz;
    o.max_hz = max_hz;
    if let Some(p) = false_alarm {
        o.false_alarm = p;
    }
    o.scale = match scale {
        Some(s) => Some(
            vibroscope::units::ScaleArg::mm_per_px(&s.to_string()).map_err(|e| py_err(e.into()))?,
        ),
        None => None,
    };
    o.quantity = quantity
        .parse()
        .map_err(|e: vibroscope::UsageError| py_err(e.into()))?;
    o.regions = rois(regions);
    o.uff = uff;
    o.waveform = waveform;
    o.run = RunSettings {
        progress: progress.is_some(),
    };
    if o.waveform.is_none() && o.uff.is_none() && !o.regions.is_empty() {
        return Err(PyValueError::new_err(
            "regions apply to the waveform and uff exports: give waveform= or uff=",
        ));
    }
    run(py, progress.as_ref(), move || {
        vibroscope::spectrum::spectrum(&o).map(|_| ())
    })?;
    std::fs::read_to_string(&json_path)
        .map_err(|e| PyOSError::new_err(format!("{}: {e}", json_path.display())))
}

/// `vibroscope listen`: writes `output` (a WAV) and returns the report's
/// JSON, the WAV's rate and its samples (mono, as read back: PCM scaled
/// to [-1, 1), or the float samples as written).
#[pyfunction]
#[pyo3(signature = (video, output, fps=None, roi=None, float=false, native_rate=false, progress=None))]
#[allow(clippy::too_many_arguments)]
fn listen<'py>(
    py: Python<'py>,
    video: PathBuf,
    output: PathBuf,
    fps: Option<f64>,
    roi: Option<[u32; 4]>,
    float: bool,
    native_rate: bool,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(String, u32, Bound<'py, PyBytes>)> {
    use vibroscope::listen::{ListenOptions, OutputRate};
    let mut o = ListenOptions {
        video,
        output: output.clone(),
        fps,
        float,
        rate: if native_rate {
            OutputRate::Native
        } else {
            OutputRate::Standard
        },
        run: RunSettings {
            progress: progress.is_some(),
        },
        ..ListenOptions::default()
    };
    o.region.roi = roi.map(|[x, y, w, h]| Roi { x, y, w, h });
    let report = run(py, progress.as_ref(), move || {
        vibroscope::listen::listen(&o)
    })?;
    let (rate, samples) =
        vibroscope::files::read_wav_mono(&output).map_err(|e| py_err(Error::File(e.into())))?;
    Ok((json(&report)?, rate, bytes(py, samples)))
}

/// `vibroscope simulate`: renders the scene file to `output` (Y4M) and
/// returns what it wrote, as JSON.
#[pyfunction]
#[pyo3(signature = (scene, output, set=Vec::new(), progress=None))]
fn simulate(
    py: Python<'_>,
    scene: PathBuf,
    output: PathBuf,
    set: Vec<String>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    let o = vibroscope::simulate::SimulateOptions {
        scene,
        output,
        set,
        run: RunSettings {
            progress: progress.is_some(),
        },
    };
    let r = run(py, progress.as_ref(), move || {
        vibroscope::simulate::simulate(&o)
    })?;
    json(&r)
}

/// The library's version.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[pymodule]
fn _vibroscope(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(probe, m)?)?;
    m.add_function(wrap_pyfunction!(displacement, m)?)?;
    m.add_function(wrap_pyfunction!(spectrum, m)?)?;
    m.add_function(wrap_pyfunction!(listen, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
