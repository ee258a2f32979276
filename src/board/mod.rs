//! Board support: everything that knows about pins, timers and analog scaling.
//!
//! The control core (`servo_core`) never sees a register. A board module owns
//! the PWM timer, the ADC and the PWM-synchronous interrupt; that interrupt
//! converts raw codes to a [`servo_core::SensorSample`] in SI units, steps the
//! controller it owns and writes the returned [`servo_core::PwmCommand`] to
//! the timer. Thread mode reaches the interrupt only through [`link`]:
//! lock-free requests, replies and snapshots, never a critical section.
//!
//! # Porting to another STM32G4 board
//!
//! Add `src/board/<name>/` with the same public surface as
//! [`b_g431b_esc1`]:
//!
//! - `NAME`, `PARAMS`, `RATING` (the power stage's), `clock_config()`,
//!   `apply_board_limits()` (a `const fn`, `RATING.lower`),
//!   `BRAKE` (the brake pin) and `brake::force_closed()`;
//! - `Board::new(peripherals, pwm_frequency_hz) -> Result<Board, BoardError>`;
//! - an implementation of [`ServoBoard`] for `Board`;
//! - the ADC end-of-injected-sequence interrupt handler that serves
//!   [`link::IsrLink`] (requests at the start of the period, snapshots),
//!   steps the controller and updates [`ISR_STATS`], and never calls into
//!   `critical_section` or `defmt`;
//!
//! then point `active` below at it. `main.rs` only uses `active::…` and the
//! items of this module, so nothing else changes.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

pub mod b_g431b_esc1;
pub mod drive;
pub mod link;
pub mod watchdog;

/// The board this image is built for.
pub use b_g431b_esc1 as active;

/// `active::PARAMS` lowered to the board's ratings, and what was lowered.
pub const BOARD_PARAMS: (servo_core::ControlParams, active::BoardLimitsApplied) =
    active::apply_board_limits(active::PARAMS);

/// The firmware's parameter set, validated at compile time: an invalid set
/// (a tuning mistake, or a limit the board lowered below another) fails the
/// build with the field's name and the reason.
pub const VALID_PARAMS: servo_core::params::ValidatedParams =
    match servo_core::params::ValidatedParams::new(BOARD_PARAMS.0) {
        Ok(v) => v,
        // Evaluated by the compiler, never in the image: this panic is a
        // build error, not a run-time path (the panic-never link check
        // proves the image has none). A const panic takes one `&str`: the
        // field's name (its rule is in `ControlParams::validate`, and
        // host-sim's `--params` prints both).
        Err(e) => panic!("{}", e.field()),
    };

/// Brings the board up for [`VALID_PARAMS`], logging what the board's
/// ratings lowered (never silent). The firmware and the on-board tests both
/// start here, so they run the same configuration.
pub fn bring_up(p: embassy_stm32::Peripherals) -> Result<active::Board, active::BoardError> {
    let lowered = BOARD_PARAMS.1;
    if lowered != active::BoardLimitsApplied::default() {
        defmt::warn!("parameters lowered to the board's ratings: {}", lowered);
    }
    active::Board::new(p, VALID_PARAMS.get().rates.pwm_frequency_hz)
}

/// What a board does for thread mode, besides running its interrupt. Every
/// method returns at once or after at most a few PWM periods; none masks
/// an interrupt.
pub trait ServoBoard {
    /// Sends a request to the interrupt and waits (spinning, ≤ a few PWM
    /// periods) for its reply.
    fn call(&mut self, request: link::Request) -> Result<link::Reply, link::LinkError>;
    /// The newest snapshot the interrupt published.
    fn snapshot(&mut self) -> link::Snapshot;
    /// Starts averaging `samples` phase-current readings with the bridge off
    /// (the PWM interrupt does the summing).
    fn begin_offset_calibration(&mut self, samples: u32) -> Result<(), link::LinkError>;
    /// Where the offset calibration stands. When the sums are complete and
    /// plausible, tells the interrupt to convert with them and returns `Done`.
    fn offset_calibration(&mut self) -> Calibration;
    /// Latest bus voltage, temperature and hardware protection state.
    fn status(&mut self) -> BoardStatus;
    /// Clears a latched hardware trip (e.g. the overcurrent break) if its
    /// cause is gone. Returns whether the board is clear now.
    fn clear_latched_faults(&mut self) -> bool;
    /// The controller's parameters as it runs them (through the link).
    fn read_params(&mut self) -> Result<servo_core::ControlParams, link::LinkError>;
    /// Applies a whole validated set between two periods (through the
    /// link); the controller's answer.
    fn apply_params(
        &mut self,
        params: &servo_core::params::ValidatedParams,
    ) -> Result<Result<(), servo_core::controller::ApplyError>, link::LinkError>;
    /// A capture or test-signal request served by the interrupt between two
    /// steps (through the link); what it answered.
    fn bulk(&mut self, payload: link::BulkIn) -> Result<link::BulkOut, link::LinkError>;
    fn set_led(&mut self, on: bool);
    /// The power stage's rating: a parameter set sent or loaded while
    /// running that asks more is refused, naming the leaf.
    fn rating(&self) -> servo_core::params::PowerStageRating;
    /// The user button, debounced by the caller.
    fn button_pressed(&self) -> bool;
}

/// Progress of the current-offset calibration.
#[derive(Clone, Copy, Debug, PartialEq, defmt::Format)]
pub enum Calibration {
    Pending,
    /// Zero-current ADC codes per phase; the interrupt now converts with them.
    Done { offset_codes: [f32; 3] },
    /// An offset is outside the expected band: the analog front end is not
    /// what the board module assumes. The bridge stays off.
    Failed { offset_codes: [f32; 3] },
}

/// Slow-changing board state for the heartbeat.
#[derive(Clone, Copy, Debug, PartialEq, defmt::Format)]
pub struct BoardStatus {
    pub bus_voltage_v: f32,
    /// Power-stage temperature (linearised NTC; a coarse figure).
    pub temperature_c: f32,
    /// Hardware overcurrent protection armed.
    pub hw_overcurrent_armed: bool,
    /// The hardware overcurrent break fired and is latched.
    pub hw_overcurrent_tripped: bool,
}

/// Counters kept by the PWM interrupt, readable without locking.
#[derive(Debug)]
pub struct IsrStats {
    /// Interrupts served.
    pub periods: AtomicU32,
    /// Periods missed: a new ADC sequence finished before the previous step
    /// did, or two interrupts lay more than 1.5 PWM periods apart.
    pub overruns: AtomicU32,
    /// Longest interrupt, entry to exit, in CPU cycles (DWT CYCCNT).
    pub worst_cycles: AtomicU32,
    /// Latest start of the interrupt after the PWM valley (the sampling
    /// instant), in PWM-timer ticks.
    pub worst_latency_ticks: AtomicU32,
    /// The interrupt started after the PWM peak: far too late, or the ADC
    /// trigger is on the wrong counter turn-around.
    pub late: AtomicU32,
    /// The interrupt found its own state missing (cannot happen once
    /// `Board::new` returned; counted, bridge off for that period).
    pub busy: AtomicU32,
    /// The core asked for a non-finite duty; that period ran with the bridge off.
    pub bad_duty: AtomicU32,
}

impl IsrStats {
    pub const fn new() -> Self {
        Self {
            periods: AtomicU32::new(0),
            overruns: AtomicU32::new(0),
            worst_cycles: AtomicU32::new(0),
            worst_latency_ticks: AtomicU32::new(0),
            late: AtomicU32::new(0),
            busy: AtomicU32::new(0),
            bad_duty: AtomicU32::new(0),
        }
    }

    pub fn snapshot(&self) -> IsrSnapshot {
        IsrSnapshot {
            periods: self.periods.load(Ordering::Relaxed),
            overruns: self.overruns.load(Ordering::Relaxed),
            worst_cycles: self.worst_cycles.load(Ordering::Relaxed),
            worst_latency_ticks: self.worst_latency_ticks.load(Ordering::Relaxed),
            late: self.late.load(Ordering::Relaxed),
            busy: self.busy.load(Ordering::Relaxed),
            bad_duty: self.bad_duty.load(Ordering::Relaxed),
        }
    }
}

impl Default for IsrStats {
    fn default() -> Self {
        Self::new()
    }
}

/// A copy of [`IsrStats`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct IsrSnapshot {
    pub periods: u32,
    pub overruns: u32,
    pub worst_cycles: u32,
    pub worst_latency_ticks: u32,
    pub late: u32,
    pub busy: u32,
    pub bad_duty: u32,
}

pub static ISR_STATS: IsrStats = IsrStats::new();

/// Set by thread mode around a flash erase or write (bridge off): the
/// interrupt, fetched from flash, stalls and misses periods meanwhile; it
/// does not report those as an overrun (read only when it saw one).
pub static FLASH_STALL: AtomicBool = AtomicBool::new(false);
