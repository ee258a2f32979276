//! Scenarios: what the closed loop is asked to do, and what it recorded.

pub mod dataset;
pub mod family;
pub mod identification;
pub mod no_load_cell;
pub mod stroke_cycle;

pub use stroke_cycle::{run_stroke_cycle, Direction, RunTrace, StrokeCycle};
