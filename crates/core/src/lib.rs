//! The engine's core: frames and their pool, typed items, edges, the
//! pipeline configuration and its validation (against a registry of stage
//! kinds the caller assembles), typed stage parameters, and the threaded
//! runner. No stage kind and no device driver lives here: the kinds are in
//! `vibroscope-engine`, which registers them. It builds without cpal, v4l,
//! nokhwa or zenoh (`cargo tree -p vibroscope-core`).

pub mod config;
pub mod edge;
pub mod frame;
pub mod graph;
pub mod item;
pub mod latency;
pub mod memory;
pub mod notify;
pub mod observe;
pub mod runner;
pub mod spec;
pub mod spin;
pub mod stage;
pub mod wire;

pub use config::{ConfigError, Origin, Params, PipelineDecl};
pub use edge::Policy;
pub use frame::{
    Frame, FrameFormat, FrameMeta, FrameMut, FramePool, PixelsMut, PixelsRef, RowTiming,
};
pub use graph::{BuildCtx, Graph, KindSpec, Output, Plan};
pub use item::{
    AudioBlock, Item, PeakSet, PortType, PyramidData, PyramidFrame, Resonance, SampleBlock,
    Spectrum, Taper,
};
pub use latency::{LatencyHist, LatencySummary};
pub use observe::{
    FrameHistory, HistoryLimits, Latest, Next, Observer, Snapshot, StageLive, TapFrame, TapSlot,
    Tuned, Tuning,
};
pub use runner::{
    error_chain, run, thousands, RunError, RunOptions, RunReport, SourceProgress, StageReport,
};
pub use spec::{
    Def, InPort, Key, KindParams, OutPort, OutType, ParamSpec, ParamType, Range, StageId,
    NO_INPUTS, NO_OUTPUTS,
};
pub use stage::{Control, EmitError, Emitter, Node, Source, SourceCtx, Stage, StageError};
