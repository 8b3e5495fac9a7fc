//! Deterministic parallel reductions over image rows, shared by the
//! per-frame analysis stages.
//!
//! Rows are cut into fixed chunks of [`CHUNK_ROWS`]; each chunk's sum lands
//! in its own slot and the slots are added in order, so the result is
//! bit-identical whether one thread or many did the work.

use super::roi::RoiParam;
use crate::{ConfigError, Def, ParamSpec, ParamType, Params, StageError};
use rayon::prelude::*;

/// Rows per reduction chunk: fixed, so the summation order never depends on threads.
pub const CHUNK_ROWS: usize = 8;

/// `roi`, shared by the per-frame stages.
pub const ROI: ParamSpec = ParamSpec::new("roi", ParamType::Ints, Def::Optional)
    .ints(0, u32::MAX as i64)
    .unit("px")
    .doc("region of interest [x, y, w, h]; the whole frame when absent");
/// `threads`, shared by the per-frame stages.
pub const THREADS: ParamSpec = ParamSpec::new("threads", ParamType::Int, Def::Int(1))
    .ints(1, 256)
    .doc("worker threads for the reduction (1 = none); the result is bit-identical for any");
/// `block`, shared by the per-frame stages.
pub const BLOCK: ParamSpec = ParamSpec::new("block", ParamType::Int, Def::Int(256))
    .ints(1, 1 << 20)
    .unit("samples")
    .doc("samples per emitted block");

/// Checks a region of interest (the ranges of `threads` and `block` are declared).
pub fn check_roi(p: &Params<'_>, roi: Option<&RoiParam>) -> Result<(), ConfigError> {
    if let Some(r) = roi {
        r.check().map_err(|m| p.error("roi", m))?;
    }
    Ok(())
}

/// A rayon pool of `threads` workers, or none for `threads <= 1` (work
/// then runs on the stage's own thread).
pub fn thread_pool(threads: usize) -> Result<Option<rayon::ThreadPool>, StageError> {
    if threads <= 1 {
        return Ok(None);
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map(Some)
        .map_err(|e| StageError::thread(format!("{threads} threads"), e))
}

/// Row-chunked summation on an optional rayon pool.
pub struct RowReducer {
    pool: Option<rayon::ThreadPool>,
    partial: Vec<f64>,
}

impl RowReducer {
    /// Starts `threads - 1` workers when `threads > 1`.
    pub fn new(threads: usize) -> Result<Self, StageError> {
        Ok(Self {
            pool: thread_pool(threads)?,
            partial: Vec::new(),
        })
    }

    /// Sum over `rows` rows of `row_chunk(first_row, end_row)`, chunked and
    /// added in a fixed order. Allocates only when `rows` grows.
    pub fn sum(&mut self, rows: usize, row_chunk: impl Fn(usize, usize) -> f64 + Sync) -> f64 {
        let chunks = rows.div_ceil(CHUNK_ROWS);
        if self.partial.len() != chunks {
            self.partial.resize(chunks, 0.0);
        }
        let work = |(c, slot): (usize, &mut f64)| {
            let y0 = c * CHUNK_ROWS;
            *slot = row_chunk(y0, (y0 + CHUNK_ROWS).min(rows));
        };
        match &self.pool {
            Some(pool) => pool.install(|| self.partial.par_iter_mut().enumerate().for_each(work)),
            None => self.partial.iter_mut().enumerate().for_each(work),
        }
        self.partial.iter().sum()
    }
}
