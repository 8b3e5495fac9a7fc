//! Running a pipeline: validation against the registry, the process's run
//! under way (progress, Ctrl-C, a caller's cancel), empty sources as
//! errors, and a run watched by an observer.

use super::*;
use crate::engine::config::PipelineDecl;
use crate::engine::{self, Control, RunReport};
use crate::error::{Error, Result};
use crate::stages;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
/// How a run shows itself.
#[derive(Clone, Copy, Debug, Default)]
pub struct RunSettings {
    /// Count the sources' frames for [`progress`].
    pub progress: bool,
}

/// How far the run under way is: frames out of the source, and how many
/// it will give when known.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    pub frames: u64,
    pub total: Option<u64>,
    /// Runs started in this process (a recipe may run several graphs).
    pub runs: u64,
}

static RUNS: AtomicU64 = AtomicU64::new(0);
static COUNTER: Mutex<Option<Arc<engine::SourceProgress>>> = Mutex::new(None);

/// The progress of the run under way (for a progress bar).
pub fn progress() -> Progress {
    let c = COUNTER.lock().ok().and_then(|g| g.clone());
    Progress {
        frames: c.as_ref().map_or(0, |c| c.frames()),
        total: c.as_ref().and_then(|c| c.total()),
        runs: RUNS.load(Ordering::Relaxed),
    }
}

static CURRENT: Mutex<Option<Arc<Control>>> = Mutex::new(None);

/// Stops the run under way, if any: sources stop, queues drain and sinks
/// finalise (the first Ctrl-C).
pub fn stop_current() -> bool {
    current().map(|c| c.stop()).is_some()
}

/// Stops the run under way at once; sinks still finalise (the second Ctrl-C).
pub fn abort_current() -> bool {
    current().map(|c| c.abort()).is_some()
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);
static STEPS: AtomicU64 = AtomicU64::new(0);

/// While alive, the recipe checks [`check_interrupt`] between its steps
/// (calibrate: recovery, fit, writing), so an interruption with no run
/// under way can wait for the step to end instead of exiting at once.
pub struct Steps(());

impl Steps {
    pub fn begin() -> Steps {
        STEPS.fetch_add(1, Ordering::SeqCst);
        Steps(())
    }
}

impl Drop for Steps {
    fn drop(&mut self) {
        STEPS.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A caller's own stop, apart from the process's Ctrl-C: the runs made
/// on the thread that entered [`Cancel::scope`] stop when [`Cancel::cancel`]
/// is called from anywhere (the studio cancels a request's analysis when
/// its client goes away). A stopped run's recipe returns
/// [`Error::Interrupted`], as on Ctrl-C; the sinks finalise what they had.
/// Runs that a recipe starts on threads of its own are not covered.
#[derive(Default)]
pub struct Cancel {
    cancelled: AtomicBool,
    run: Mutex<Option<Arc<Control>>>,
}

thread_local! {
    static CANCEL: std::cell::RefCell<Option<Arc<Cancel>>> = const { std::cell::RefCell::new(None) };
}

impl Cancel {
    pub fn new() -> Arc<Cancel> {
        Arc::new(Cancel::default())
    }

    /// Stops the run under way in the scope, and every later one.
    pub fn cancel(&self) {
        self.cancelled.store(true, Ordering::SeqCst);
        if let Some(c) = self.run.lock().unwrap_or_else(|p| p.into_inner()).as_ref() {
            c.stop();
        }
    }

    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::SeqCst)
    }

    /// Runs `f` with `this` as the calling thread's cancel scope.
    pub fn scope<T>(this: &Arc<Cancel>, f: impl FnOnce() -> T) -> T {
        struct Restore(Option<Arc<Cancel>>);
        impl Drop for Restore {
            fn drop(&mut self) {
                let old = self.0.take();
                CANCEL.with(|c| *c.borrow_mut() = old);
            }
        }
        let _restore = Restore(CANCEL.with(|c| c.borrow_mut().replace(Arc::clone(this))));
        f()
    }

    fn current() -> Option<Arc<Cancel>> {
        CANCEL.with(|c| c.borrow().clone())
    }

    /// Ties `control` to the scope (stopped at once when already cancelled).
    fn attach(&self, control: &Arc<Control>) {
        *self.run.lock().unwrap_or_else(|p| p.into_inner()) = Some(Arc::clone(control));
        if self.is_cancelled() {
            control.stop();
        }
    }

    fn detach(&self) {
        *self.run.lock().unwrap_or_else(|p| p.into_inner()) = None;
    }
}

/// An interruption that arrived while no run was under way: the next run
/// or [`check_interrupt`] returns [`Error::Interrupted`]. Returns whether a
/// recipe will see it ([`Steps`]); when not, the caller should exit now.
pub fn interrupt() -> bool {
    INTERRUPTED.store(true, Ordering::SeqCst);
    STEPS.load(Ordering::SeqCst) > 0
}

/// `Err(Error::Interrupted)` once [`interrupt`] was called: recipes call it
/// between their steps, before writing their outputs.
pub fn check_interrupt() -> Result<()> {
    if INTERRUPTED.load(Ordering::SeqCst) || Cancel::current().is_some_and(|c| c.is_cancelled()) {
        return Err(interrupted());
    }
    Ok(())
}

/// The error of an interruption with no run report of its own (exit 130,
/// 143 or 129 by the signal).
pub fn interrupted() -> Error {
    Error::Interrupted {
        report: Box::new(engine::RunReport {
            stages: Vec::new(),
            errors: Vec::new(),
            interrupted: true,
            elapsed: std::time::Duration::ZERO,
        }),
    }
}

fn current() -> Option<Arc<Control>> {
    CURRENT.lock().ok().and_then(|g| g.clone())
}

/// `decl` as a graph, once no sink would overwrite a file the pipeline
/// reads (nor its own file), checked before validation, which may open the
/// sinks' files.
fn checked(decl: &PipelineDecl) -> Result<engine::Graph> {
    let inputs = input_files(decl);
    let outs = outputs(decl);
    crate::error::check_outputs(
        &inputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
        &outs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    // Errors name the stages the user's pipeline has: validate it first.
    Ok(engine::graph::validate(decl, stages::registry())?)
}

/// Validates and runs `decl`. A stage error or an interruption is an
/// [`Error`] holding the run's report; with `allow_interrupt`, an
/// interrupted run is returned (its `interrupted` set).
pub fn run_with(decl: &PipelineDecl, s: RunSettings, allow_interrupt: bool) -> Result<RunReport> {
    run_inner(decl, s, allow_interrupt, None)
}

fn run_inner(
    decl: &PipelineDecl,
    s: RunSettings,
    allow_interrupt: bool,
    observer: Option<Arc<engine::Observer>>,
) -> Result<RunReport> {
    let graph = checked(decl)?;
    check_interrupt()?;
    let counter = s
        .progress
        .then(|| Arc::new(engine::SourceProgress::default()));
    if let Some(c) = &counter {
        if let Ok(mut g) = COUNTER.lock() {
            *g = Some(Arc::clone(c));
        }
        RUNS.fetch_add(1, Ordering::Relaxed);
    }
    let control = Control::new();
    if let Ok(mut g) = CURRENT.lock() {
        *g = Some(Arc::clone(&control));
    }
    if INTERRUPTED.load(Ordering::SeqCst) {
        // Interrupted between the check above and now: stop at once.
        control.stop();
    }
    let cancel = Cancel::current();
    if let Some(c) = &cancel {
        c.attach(&control);
    }
    let report = engine::run(
        graph,
        Arc::clone(&control),
        &engine::RunOptions { counter, observer },
    )
    .map_err(|source| Error::Start {
        file: decl.file.clone(),
        source: Box::new(source),
    });
    if let Some(c) = &cancel {
        c.detach();
    }
    if let Ok(mut g) = CURRENT.lock() {
        *g = None;
    }
    let report = report?;
    if !report.interrupted {
        empty_sources(decl, &report)?;
    }
    if !report.errors.is_empty() {
        return Err(Error::Stages {
            report: Box::new(report),
        });
    }
    if report.interrupted && !allow_interrupt {
        return Err(Error::Interrupted {
            report: Box::new(report),
        });
    }
    Ok(report)
}

/// A source that delivered no frame at all (a video with a header and no
/// frames) is an input error: nothing was processed and the sinks wrote
/// nothing, which must not look like success.
fn empty_sources(decl: &PipelineDecl, report: &RunReport) -> Result<()> {
    for s in decl.stages.iter().filter(|s| s.inputs.is_empty()) {
        let Some(r) = report.stages.iter().find(|r| r.id == s.id) else {
            continue;
        };
        if r.items_out > 0 {
            continue;
        }
        let path = s
            .params()
            .iter()
            .find(|p| p.key == "path")
            .and_then(|p| p.value.as_str())
            .map_or_else(|| format!("stage `{}`", s.id), str::to_string);
        return Err(Error::input(
            path,
            "holds no frames: nothing was processed and no output was written",
        ));
    }
    Ok(())
}

/// Runs `decl` watched by `observer` (its stages' counters and the latest
/// item of each `tap` stage, read from other threads while it runs); the
/// run stops early through [`engine::Observer::stop`]. It is the process's
/// run under way, as [`run_with`]'s: Ctrl-C stops it, its sinks finalise,
/// and the report says `interrupted` (which [`engine::Observer::stop`]
/// sets too: the caller knows which it asked for).
pub fn run_observed(decl: &PipelineDecl, observer: &Arc<engine::Observer>) -> Result<RunReport> {
    run_inner(
        decl,
        RunSettings::default(),
        true,
        Some(Arc::clone(observer)),
    )
}

/// [`run_with`], an interruption being an error.
pub fn run(decl: &PipelineDecl, s: RunSettings) -> Result<RunReport> {
    run_with(decl, s, false)
}
