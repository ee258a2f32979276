//! Board support: everything that knows about pins, timers and analog scaling.
//!
//! The control core (`servo_core`) never sees a register. A board module owns
//! the PWM timer, the ADC and the PWM-synchronous interrupt; that interrupt
//! converts raw codes to a [`SensorSample`] in SI units, hands it to
//! [`control_period`] (board-independent, here) and writes the returned
//! [`PwmCommand`] to the timer.
//!
//! # Porting to another STM32G4 board
//!
//! Add `src/board/<name>.rs` with the same public surface as
//! [`b_g431b_esc1`]:
//!
//! - `NAME`, `PARAMS`, `clock_config()`, `apply_board_limits()` (a `const fn`);
//! - `Board::new(peripherals, pwm_frequency_hz) -> Result<Board, BoardError>`;
//! - an implementation of [`ServoBoard`] for `Board`;
//! - the ADC end-of-injected-sequence interrupt handler that calls
//!   [`control_period`], [`report_overrun`] and updates [`ISR_STATS`];
//!
//! then point `active` below at it. `main.rs` only uses `active::…` and the
//! items of this file, so nothing else changes.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use critical_section::{CriticalSection, Mutex};
use servo_core::{Controller, PwmCommand, SensorSample};

pub mod b_g431b_esc1;
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
        // A const panic takes one `&str`: the field's name (its rule is in
        // `ControlParams::validate`, and host-sim's `--params` prints both).
        Err(e) => panic!("{}", e.field),
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

/// The drive. The PWM interrupt steps it every period; the main task sends
/// commands and reads telemetry between periods, each time inside a short
/// critical section. `None` until the main task installs it (after the
/// current-offset calibration), during which the interrupt keeps the bridge off.
pub static CONTROLLER: Mutex<RefCell<Option<Controller>>> = Mutex::new(RefCell::new(None));

/// Puts the controller in place. Takes effect at the next PWM period.
pub fn install_controller(controller: Controller) {
    critical_section::with(|cs| {
        if let Ok(mut slot) = CONTROLLER.borrow(cs).try_borrow_mut() {
            *slot = Some(controller);
        }
    });
}

/// Runs `f` on the controller from thread mode. Interrupts are masked while
/// `f` runs, so keep it short (a command, a telemetry copy). `None` if no
/// controller is installed.
pub fn with_controller<R>(f: impl FnOnce(&mut Controller) -> R) -> Option<R> {
    critical_section::with(|cs| {
        let mut slot = CONTROLLER.borrow(cs).try_borrow_mut().ok()?;
        slot.as_mut().map(f)
    })
}

/// One control period, called by the board's PWM interrupt with a converted
/// sample. Never blocks, never panics; with no controller installed (or the
/// slot unexpectedly borrowed) the answer is [`PwmCommand::OFF`].
#[inline(always)]
pub fn control_period(cs: CriticalSection<'_>, sample: &SensorSample) -> PwmCommand {
    match CONTROLLER.borrow(cs).try_borrow_mut() {
        Ok(mut slot) => match slot.as_mut() {
            Some(c) => c.step(sample),
            None => PwmCommand::OFF,
        },
        Err(_) => {
            ISR_STATS.busy.fetch_add(1, Ordering::Relaxed);
            PwmCommand::OFF
        }
    }
}

/// Tells the controller that a PWM period was missed (it latches
/// `ISR_OVERRUN` and switches the bridge off).
#[inline(always)]
pub fn report_overrun(cs: CriticalSection<'_>) {
    if let Ok(mut slot) = CONTROLLER.borrow(cs).try_borrow_mut() {
        if let Some(c) = slot.as_mut() {
            c.report_isr_overrun();
        }
    }
}

/// Latches `BRIDGE_BREAK` from the PWM interrupt after the hardware
/// overcurrent break fired (the board latches its own flag too; the operator
/// clears both, see `main`).
#[inline(always)]
pub fn report_bridge_break(cs: CriticalSection<'_>) {
    if let Ok(mut slot) = CONTROLLER.borrow(cs).try_borrow_mut() {
        if let Some(c) = slot.as_mut() {
            c.report_bridge_break();
        }
    }
}

/// What a board does for the main task, besides running its interrupt.
pub trait ServoBoard {
    /// Starts averaging `samples` phase-current readings with the bridge off
    /// (the PWM interrupt does the summing).
    fn begin_offset_calibration(&mut self, samples: u32);
    /// Where the offset calibration stands.
    fn offset_calibration(&mut self) -> Calibration;
    /// Latest bus voltage, temperature and hardware protection state.
    fn status(&self) -> BoardStatus;
    /// Clears a latched hardware trip (e.g. the overcurrent break) if its
    /// cause is gone. Returns whether the board is clear now.
    fn clear_latched_faults(&mut self) -> bool;
    fn set_led(&mut self, on: bool);
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
    /// Controller slot found borrowed (cannot happen on one core; counted,
    /// bridge off for that period).
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
