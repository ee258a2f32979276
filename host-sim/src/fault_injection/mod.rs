//! Fault injection: each fault the drive must survive, injected where the
//! real fault would act (the sample the core sees, the plant, the board, the
//! command interface), run closed-loop through the firmware's control core,
//! and measured: how many PWM periods until the fault latched, what the
//! drive did (bridge off, or a controlled stop), how large the true phase
//! current got, whether the stroke held, and whether anything became NaN.
//!
//! - [`injection`]: what can be injected and when;
//! - [`scenario`]: a [`Scenario`]: its [`Setup`], injections and [`Expect`];
//! - [`runner`]: [`run`] a [`Scenario`] into an [`Outcome`];
//! - [`outcome`]: what a run recorded and the figures read from it;
//! - [`catalog`]: the scenarios of the reliability table (`docs/reliability.md`),
//!   shared by the tests (`tests/fault_*.rs`) and `host-sim faults`;
//! - [`report`]: `summary.json` and the measured table;
//! - [`family`]: the catalogue over a rig family (`host-sim faults --family DIR`).

pub mod catalog;
pub mod family;
pub mod injection;
pub mod outcome;
pub mod report;
pub mod runner;
pub mod scenario;

pub use injection::{CommandAt, Injection, SensorCorruptor, Timed, Window};
pub use outcome::{names, CommandRecord, Outcome, PeriodRecord};
pub use runner::run;
pub use scenario::{Expect, Scenario, Setup};
