//! The workspace's integration tests, one module per subject, in one test
//! binary (issue 49): one link instead of 25, and libtest keeps both
//! cores busy across subjects where 25 binaries, run one after another,
//! each waited for its own slowest test.
//!
//!     cargo test --release --test suite SUBJECT::   # one subject, e.g. calibrate::
//!
//! Three stay binaries of their own: `alloc` (a counting global
//! allocator would count every other test's allocations), `layers` (CI
//! prints it) and `vm_check` (run by `tests/vm/run.sh` on the VM's output).
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "../common/mod.rs"]
mod common;

mod backpressure;
mod bound;
mod calibrate;
mod config_errors;
mod explain;
mod faults;
mod filters;
mod hostile;
mod idv;
mod learn;
mod live;
mod magnify;
mod microphone;
mod modes;
mod network;
mod pitch;
mod plots;
mod protocol;
mod replay;
mod resonances;
mod rolling_shutter;
mod score;
mod simulate;
mod speaker;
mod spectrum;
mod units;
mod vibrometry;
