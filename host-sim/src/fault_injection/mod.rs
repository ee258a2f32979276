//! Fault injection: each fault the drive must survive, injected where the
//! real fault would act (the sample the core sees, the plant, the board, the
//! command interface), run closed-loop through the firmware's control core,
//! and measured: how many PWM periods until the fault latched, what the
//! drive did (bridge off, or a controlled stop), how large the true phase
//! current got, whether the stroke held, and whether anything became NaN.
//!
//! - [`injection`]: what can be injected and when;
//! - [`runner`]: [`run`] a [`Scenario`] into an [`Outcome`];
//! - [`catalog`]: the scenarios of the reliability table (`docs/reliability.md`),
//!   shared by the tests (`tests/fault_*.rs`) and `host-sim faults`;
//! - [`report`]: `summary.json` and the measured table;
//! - [`family`]: the catalogue over a rig family (`host-sim faults --family DIR`).

pub mod catalog;
pub mod family;
pub mod injection;
pub mod report;
pub mod runner;

pub use injection::{CommandAt, Injection, SensorCorruptor, Timed, Window};
pub use runner::{names, run, CommandRecord, Expect, Outcome, PeriodRecord, Scenario, Setup};
