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
use pyo3::types::{PyBytes, PyDict};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use vibroscope::live::{Latest, Next, Observer, TapSlot};
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
        let value = match result {
            Ok(r) => r.map_err(py_err)?,
            Err(_) => {
                return Err(PyRuntimeError::new_err(
                    "vibroscope: the run panicked (a bug: please report it with the input)",
                ))
            }
        };
        // The last count, so that a bar ends where the run did.
        if let Some(cb) = progress {
            let p = vibroscope::pipeline::progress();
            cb.call1((p.frames, p.total))?;
        }
        Ok(value)
    })
}

fn bytes<'py>(py: Python<'py>, v: impl IntoIterator<Item = f64>) -> Bound<'py, PyBytes> {
    let raw: Vec<u8> = v.into_iter().flat_map(f64::to_le_bytes).collect();
    PyBytes::new(py, &raw)
}

fn json<T: serde::Serialize + ?Sized>(v: &T) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

fn to_roi(r: Option<[u32; 4]>) -> Option<Roi> {
    r.map(|[x, y, w, h]| Roi { x, y, w, h })
}

fn rois(regions: Vec<[u32; 4]>) -> Vec<Roi> {
    regions
        .into_iter()
        .map(|[x, y, w, h]| Roi { x, y, w, h })
        .collect()
}

/// A run that counts frames for the progress callback when there is one.
fn settings(progress: Option<&Bound<'_, PyAny>>) -> RunSettings {
    RunSettings {
        progress: progress.is_some(),
    }
}

/// The report a recipe wrote to `path`, as text.
fn read_report(path: &std::path::Path) -> PyResult<String> {
    std::fs::read_to_string(path)
        .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))
}

/// `--scale MM_PER_PX`.
fn scale_arg(scale: Option<f64>) -> PyResult<Option<vibroscope::units::ScaleArg>> {
    scale
        .map(|s| {
            vibroscope::units::ScaleArg::mm_per_px(&s.to_string()).map_err(|e| py_err(e.into()))
        })
        .transpose()
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
    let run_settings = settings(progress.as_ref());
    let motion = run(py, progress.as_ref(), move || {
        vibroscope::motion::displacement(&video, fps, regions, run_settings)
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
    waveform=None, include_spectrum=false, progress=None))]
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
    include_spectrum: bool,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    use vibroscope::spectrum::SpectrumOptions;
    let mut o = SpectrumOptions::new(&video, &json_path);
    o.fps = fps;
    o.region.roi = to_roi(roi);
    o.peaks = peaks;
    o.min_hz = min_hz;
    o.max_hz = max_hz;
    if let Some(p) = false_alarm {
        o.false_alarm = p;
    }
    o.scale = scale_arg(scale)?;
    o.quantity = quantity
        .parse()
        .map_err(|e: vibroscope::UsageError| py_err(e.into()))?;
    o.regions = rois(regions);
    o.uff = uff;
    o.waveform = waveform;
    o.include_spectrum = include_spectrum;
    o.run = settings(progress.as_ref());
    if o.waveform.is_none() && o.uff.is_none() && !o.regions.is_empty() {
        return Err(PyValueError::new_err(
            "regions apply to the waveform and uff exports: give waveform= or uff=",
        ));
    }
    run(py, progress.as_ref(), move || {
        vibroscope::spectrum::spectrum(&o).map(|_| ())
    })?;
    read_report(&json_path)
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
        run: settings(progress.as_ref()),
        ..ListenOptions::default()
    };
    o.region.roi = to_roi(roi);
    let report = run(py, progress.as_ref(), move || {
        vibroscope::listen::listen(&o)
    })?;
    let (rate, samples) =
        vibroscope::files::read_wav_mono(&output).map_err(|e| py_err(Error::File(e.into())))?;
    Ok((json(&report)?, rate, bytes(py, samples)))
}

/// `vibroscope modes`: the modal image at each of `at_hz` (PNG, and the
/// complex image as `.npy` when `npy` is given; several frequencies name
/// their files after the frequency, as the command does). Returns the
/// reports' JSON (a list).
#[pyfunction]
#[pyo3(signature = (video, at_hz, png, npy=None, fps=None, roi=None, motion="sum", scale=None,
    sigma=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn modes(
    py: Python<'_>,
    video: PathBuf,
    at_hz: Vec<f64>,
    png: PathBuf,
    npy: Option<PathBuf>,
    fps: Option<f64>,
    roi: Option<[u32; 4]>,
    motion: &str,
    scale: Option<f64>,
    sigma: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    use vibroscope::modes::{ModesOptions, Motion};
    let Some((&first, rest)) = at_hz.split_first() else {
        return Err(PyValueError::new_err("at_hz: give at least one frequency"));
    };
    let motion = match motion {
        "x" => Motion::X,
        "y" => Motion::Y,
        "sum" => Motion::Sum,
        m => {
            return Err(PyValueError::new_err(format!(
                "motion: expected x, y or sum, got `{m}`"
            )))
        }
    };
    let mut o = ModesOptions {
        video,
        at_hz: first,
        also_at_hz: rest.to_vec(),
        output: png,
        npy,
        fps,
        motion,
        sigma,
        scale: scale_arg(scale)?,
        run: settings(progress.as_ref()),
        ..ModesOptions::default()
    };
    o.region.roi = to_roi(roi);
    let (r, _) = run(py, progress.as_ref(), move || {
        vibroscope::modes::modes_all(&o)
    })?;
    json(&r)
}

/// `vibroscope magnify`: writes the magnified video to `output` and
/// returns its report's JSON.
#[pyfunction]
#[pyo3(signature = (video, output, lo_hz, hi_hz, factor, fps=None, roi=None, pyramid="csp",
    side_by_side=false, progress=None))]
#[allow(clippy::too_many_arguments)]
fn magnify(
    py: Python<'_>,
    video: PathBuf,
    output: PathBuf,
    lo_hz: f64,
    hi_hz: f64,
    factor: f64,
    fps: Option<f64>,
    roi: Option<[u32; 4]>,
    pyramid: &str,
    side_by_side: bool,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    use vibroscope::magnify::MagnifyOptions;
    use vibroscope::pipeline::Pyramid;
    let pyramid = match pyramid {
        "csp" => Pyramid::Csp,
        "riesz" => Pyramid::Riesz,
        p => {
            return Err(PyValueError::new_err(format!(
                "pyramid: expected csp or riesz, got `{p}`"
            )))
        }
    };
    let o = MagnifyOptions {
        video,
        output,
        lo_hz,
        hi_hz,
        factor,
        fps,
        roi: to_roi(roi),
        pyramid,
        side_by_side,
        run: settings(progress.as_ref()),
        ..MagnifyOptions::default()
    };
    let r = run(py, progress.as_ref(), move || {
        vibroscope::magnify::magnify(&o)
    })?;
    json(&r)
}

/// `vibroscope calibrate`: writes REPORT.json to `json_path` (and the
/// corrected WAV to `output`) and returns the JSON's text.
#[pyfunction]
#[pyo3(signature = (video, json_path, reference=None, reference_tone_hz=None, output=None,
    fps=None, roi=None, effects=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn calibrate(
    py: Python<'_>,
    video: PathBuf,
    json_path: PathBuf,
    reference: Option<PathBuf>,
    reference_tone_hz: Option<f64>,
    output: Option<PathBuf>,
    fps: Option<f64>,
    roi: Option<[u32; 4]>,
    effects: Option<Vec<String>>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    use vibroscope::calibrate::CalibrateOptions;
    let effects = match effects {
        Some(list) => Some(vibroscope::calibrate::parse_effects(&list.join(",")).map_err(py_err)?),
        None => None,
    };
    let mut o = CalibrateOptions {
        video,
        reference: reference.unwrap_or_default(),
        reference_tone_hz,
        json: json_path.clone(),
        output,
        fps,
        effects,
        run: settings(progress.as_ref()),
        ..CalibrateOptions::default()
    };
    o.region.roi = to_roi(roi);
    run(py, progress.as_ref(), move || {
        vibroscope::calibrate::calibrate(&o).map(drop)
    })?;
    read_report(&json_path)
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
        run: settings(progress.as_ref()),
    };
    let r = run(py, progress.as_ref(), move || {
        vibroscope::simulate::simulate(&o)
    })?;
    json(&r)
}

/// f32 samples as little-endian bytes.
fn f32_bytes<'py>(py: Python<'py>, v: &[f32]) -> Bound<'py, PyBytes> {
    let raw: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    PyBytes::new(py, &raw)
}

/// One item as a dict (arrays as bytes; the Python layer makes numpy
/// arrays of them).
fn item_dict<'py>(py: Python<'py>, item: Latest) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    match item {
        Latest::Frame(f) => {
            d.set_item("kind", "frame")?;
            d.set_item("t", f.t_ns as f64 * 1e-9)?;
            d.set_item("seq", f.seq)?;
            d.set_item("width", f.width)?;
            d.set_item("height", f.height)?;
            d.set_item("pixels", PyBytes::new(py, &f.gray))?;
        }
        Latest::Samples(b) => {
            d.set_item("kind", "samples")?;
            d.set_item("t0", b.t0_ns as f64 * 1e-9)?;
            d.set_item("rate_hz", b.rate_hz)?;
            d.set_item("channels", b.channels)?;
            d.set_item("data", f32_bytes(py, &b.data))?;
            if let Some(t) = &b.times_ns {
                let times: Vec<f64> = t.iter().map(|&v| v as f64 * 1e-9).collect();
                d.set_item("times", bytes(py, times))?;
            }
        }
        Latest::Audio(a) => {
            d.set_item("kind", "audio")?;
            d.set_item("t0", a.t0_ns as f64 * 1e-9)?;
            d.set_item("rate_hz", a.rate_hz)?;
            d.set_item("data", f32_bytes(py, &a.samples))?;
        }
        Latest::Spectrum(s) => {
            d.set_item("kind", "spectrum")?;
            d.set_item("t", s.t_ns as f64 * 1e-9)?;
            d.set_item("f0_hz", s.f0_hz)?;
            d.set_item("resolution_hz", s.resolution_hz)?;
            d.set_item("rate_hz", s.rate_hz)?;
            d.set_item("window", s.window)?;
            d.set_item("segments", s.segments)?;
            d.set_item("power", f32_bytes(py, &s.power))?;
        }
    }
    Ok(d)
}

/// The items of one stage of a running pipeline, in order (see
/// [`items`]). Closing it (or dropping it) stops the run and waits for
/// its threads.
#[pyclass(module = "vibroscope._vibroscope")]
struct Items {
    observer: Arc<Observer>,
    slot: Arc<TapSlot>,
    /// The run: its per-stage table, or its error.
    thread: Option<std::thread::JoinHandle<vibroscope::Result<String>>>,
    /// The run's table once it ended (`--stats`'s).
    report: Option<String>,
}

impl Items {
    /// Stops the run (when `stop`), waits for it, and gives its error.
    fn end(&mut self, py: Python<'_>, stop: bool) -> PyResult<()> {
        if stop {
            self.slot.abandon();
            self.observer.stop();
        }
        if let Some(t) = self.thread.take() {
            match py.detach(|| t.join()) {
                Ok(Ok(table)) => self.report = Some(table),
                Ok(Err(e)) if !stop => return Err(py_err(e)),
                Ok(Err(_)) => {}
                Err(_) => {
                    return Err(PyRuntimeError::new_err(
                        "vibroscope: the pipeline's thread panicked (a bug: please report it)",
                    ))
                }
            }
        }
        Ok(())
    }
}

impl Drop for Items {
    fn drop(&mut self) {
        self.slot.abandon();
        self.observer.stop();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[pymethods]
impl Items {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        loop {
            if self.thread.is_none() {
                return Ok(None);
            }
            let slot = Arc::clone(&self.slot);
            match py.detach(move || slot.next(Duration::from_millis(100))) {
                Next::Item(item) => return item_dict(py, item).map(Some),
                Next::End => {
                    self.end(py, false)?;
                    return Ok(None);
                }
                Next::Wait => {
                    if let Err(e) = py.check_signals() {
                        self.end(py, true)?;
                        return Err(e);
                    }
                    // A run that failed before its tap started never closes it.
                    if self.thread.as_ref().is_some_and(|t| t.is_finished()) {
                        let slot = Arc::clone(&self.slot);
                        if let Next::Item(item) = slot.next(Duration::ZERO) {
                            return item_dict(py, item).map(Some);
                        }
                        self.end(py, false)?;
                        return Ok(None);
                    }
                }
            }
        }
    }

    /// Stops the run (its sinks finalise what they had) and waits for it.
    fn close(&mut self, py: Python<'_>) -> PyResult<()> {
        self.end(py, true)
    }

    /// The run's per-stage table, once it has ended.
    #[getter]
    fn stats(&self) -> Option<String> {
        self.report.clone()
    }
}

/// Starts `pipeline` (a shipped name or a TOML file; `set`: `STAGE.KEY=VALUE`
/// overrides; `replay`: its source replaced by a recording) with a `tap`
/// on `stage` that hands every item of it over in order, at most `queue`
/// unread (a replay then waits for the reader; a live source drops by
/// its edges' policy). The run starts at once, on threads of its own.
#[pyfunction]
#[pyo3(signature = (pipeline, stage, replay=None, set=Vec::new(), fps=None, queue=64))]
fn items(
    pipeline: String,
    stage: String,
    replay: Option<PathBuf>,
    set: Vec<String>,
    fps: Option<f64>,
    queue: u64,
) -> PyResult<Items> {
    use vibroscope::live::{Origin, TapParams};
    use vibroscope::pipeline as pl;
    // A recording that cannot be read is told now, as an OSError, not
    // when the iteration starts.
    if let Some(r) = &replay {
        vibroscope::probe::probe(r, fps).map_err(py_err)?;
    }
    let mut decl = pl::prepare(&pl::PipelineOptions {
        pipeline,
        set,
        replay,
        fps,
    })
    .map_err(py_err)?;
    let origin = Origin::Builtin("the Python package's items()".into());
    let mut st = pl::new_stage::<TapParams>("python_items", &[&stage], origin.clone());
    st.capacity = Some((64, origin.clone()));
    pl::put(
        &mut st,
        TapParams::name,
        "python".to_string(),
        origin.clone(),
    )
    .map_err(py_err)?;
    pl::put(&mut st, TapParams::every_ms, 0.0, origin.clone()).map_err(py_err)?;
    pl::put(&mut st, TapParams::queue, queue.max(1), origin).map_err(py_err)?;
    decl.stages.push(st);
    pl::validate(&decl).map_err(|e| py_err(e.into()))?;
    let observer = Observer::new();
    let slot = observer.slot("python");
    let watcher = Arc::clone(&observer);
    let thread = std::thread::Builder::new()
        .name("vibroscope-items".into())
        .spawn(move || pl::run_observed(&decl, &watcher).map(|r| r.table()))
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start the pipeline's thread: {e}")))?;
    Ok(Items {
        observer,
        slot,
        thread: Some(thread),
        report: None,
    })
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
    m.add_function(wrap_pyfunction!(modes, m)?)?;
    m.add_function(wrap_pyfunction!(magnify, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(items, m)?)?;
    m.add_class::<Items>()?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
