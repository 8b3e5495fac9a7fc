//! The streaming engine: frames and their pool, typed items, edges, the
//! pipeline configuration and its validation, and the runner.

pub mod config;
pub mod edge;
pub mod frame;
pub mod graph;
pub mod item;
pub mod latency;
pub mod memory;
#[cfg(feature = "net")]
pub mod net;
pub mod notify;
pub mod observe;
pub mod runner;
pub mod spec;
pub mod stage;
#[cfg(test)]
pub(crate) mod test_support;
pub mod wire;

pub mod pipelines;
pub mod stages;

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
    FrameHistory, HistoryLimits, Latest, Observer, Snapshot, StageLive, TapFrame, TapSlot,
};
pub use runner::{
    error_chain, run, thousands, RunError, RunOptions, RunReport, SourceProgress, StageReport,
};
pub use spec::{
    Def, InPort, Key, KindParams, OutPort, OutType, ParamSpec, ParamType, Range, StageId,
    NO_INPUTS, NO_OUTPUTS,
};
pub use stage::{Control, EmitError, Emitter, Node, Source, SourceCtx, Stage, StageError};
