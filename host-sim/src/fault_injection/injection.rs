//! What can be injected, and when.
//!
//! Three levels, each acting where the real fault would:
//! - **sensor**: the sample is corrupted between the plant and the core (the
//!   plant's truth is untouched): noise bursts, a stuck or offset current
//!   sensor, a NaN reading, encoder glitches and dropouts;
//! - **plant**: the power stage or the load itself changes: an open phase,
//!   bus sag and surge, load spikes;
//! - **firmware/board**: the core is told of an ISR overrun, or does not run
//!   at all (a hung ISR: the timer keeps the last duties until the
//!   independent watchdog resets the chip).
//!
//! Command-level faults (reference jumps, NaN or out-of-stroke setpoints) are
//! [`CommandAt`] events of the scenario.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use servo_core::{Command, SensorSample};

/// One fault, active over a [`Window`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Injection {
    // --- sensor level ---
    /// Gaussian noise of this σ added to every phase-current reading.
    CurrentNoise { sigma_a: f32 },
    /// One phase-current reading replaced by a constant (a stuck ADC channel
    /// or a shorted shunt amplifier).
    CurrentStuck { phase: usize, value_a: f32 },
    /// A constant added to one phase-current reading (offset drift).
    CurrentOffset { phase: usize, offset_a: f32 },
    /// One phase-current reading is NaN.
    CurrentNan { phase: usize },
    /// The bus-voltage reading is NaN.
    BusReadingNan,
    /// The encoder counter reads this many counts off while active (EMI
    /// pulses the counter took as edges). A one-period window is a glitch
    /// that recovers; a long one a lasting miscount.
    EncoderOffset { counts: i32 },
    /// The encoder counter stops at the value it had when the window
    /// opened (a broken cable, a dead sensor).
    EncoderFrozen,
    /// The power stage's heat-sink reading at this temperature (a blocked
    /// fan, a hot cabinet).
    PowerStageTemperature { celsius: f32 },
    // --- plant level ---
    /// A motor phase disconnected from its inverter leg.
    OpenPhase { phase: usize },
    /// The DC bus (what the inverter applies and the ADC reads) at this
    /// voltage: sag or surge.
    BusVoltage { volts: f64 },
    /// An extra axial load on the rod, newtons, positive opposing extension
    /// (pushing the rod in).
    ExternalForce { newtons: f64 },
    /// A rigid obstacle in the rod's way (a collision, a jammed guide): a
    /// spring that pushes back once the rod extends past `position_m`,
    /// updated every PWM period.
    Obstacle { position_m: f64, stiffness_n_m: f64 },
    // --- firmware / board level ---
    /// The board reports a missed PWM period (once, at the window start).
    IsrOverrun,
    /// The core stops running (a hung ISR or a dead ADC trigger): the timer
    /// keeps applying the last duties until the independent watchdog
    /// resets the chip `Setup::watchdog_timeout_s` later; after the reset a
    /// fresh controller starts with `WATCHDOG_RESET` latched.
    CoreHang,
}

impl Injection {
    /// Acts on the sample the core sees (not on the plant).
    pub fn is_sensor_level(&self) -> bool {
        matches!(
            self,
            Self::CurrentNoise { .. }
                | Self::CurrentStuck { .. }
                | Self::CurrentOffset { .. }
                | Self::CurrentNan { .. }
                | Self::BusReadingNan
                | Self::EncoderOffset { .. }
                | Self::EncoderFrozen
                | Self::PowerStageTemperature { .. }
        )
    }
}

/// `[start_s, end_s)`, in simulated time from the start of the run.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Window {
    pub start_s: f64,
    pub end_s: f64,
}

impl Window {
    pub const fn new(start_s: f64, end_s: f64) -> Self {
        Self { start_s, end_s }
    }

    /// From `start_s` to the end of the run.
    pub const fn from(start_s: f64) -> Self {
        Self { start_s, end_s: f64::INFINITY }
    }

    /// Exactly one PWM period from `start_s`.
    pub fn one_period(start_s: f64, pwm_period_s: f64) -> Self {
        Self { start_s, end_s: start_s + pwm_period_s }
    }

    /// Active for the period starting at `t_s` (half a period of tolerance
    /// against rounding of the period grid).
    pub fn contains(&self, t_s: f64, pwm_period_s: f64) -> bool {
        let eps = 0.5 * pwm_period_s;
        t_s + eps >= self.start_s && t_s + eps < self.end_s
    }
}

/// An injection and when it is active.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Timed {
    pub window: Window,
    pub injection: Injection,
}

/// A command given to the drive at a given time (thread context, between
/// two periods).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandAt {
    pub at_s: f64,
    pub command: Command,
}

/// The state sensor-level injections need between periods (the noise
/// generator, the count a frozen encoder stopped at).
#[derive(Clone, Debug)]
pub struct SensorCorruptor {
    rng: ChaCha8Rng,
    /// Per injection (same index as the scenario's list): the count at
    /// which a frozen encoder stopped.
    frozen_count: Vec<Option<u16>>,
}

impl SensorCorruptor {
    pub fn new(injections: &[Timed], seed: u64) -> Self {
        Self { rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_fa17), frozen_count: vec![None; injections.len()] }
    }

    /// Applies every sensor-level injection active at `t_s` to `s`.
    pub fn apply(&mut self, injections: &[Timed], t_s: f64, pwm_period_s: f64, s: &mut SensorSample) {
        for (k, timed) in injections.iter().enumerate() {
            if !timed.window.contains(t_s, pwm_period_s) {
                if let Some(slot) = self.frozen_count.get_mut(k) {
                    *slot = None;
                }
                continue;
            }
            match timed.injection {
                Injection::CurrentNoise { sigma_a } => {
                    for i in s.phase_current_a.iter_mut() {
                        let z: f32 = self.rng.sample(StandardNormal);
                        *i += sigma_a * z;
                    }
                }
                Injection::CurrentStuck { phase, value_a } => {
                    if let Some(i) = s.phase_current_a.get_mut(phase) {
                        *i = value_a;
                    }
                }
                Injection::CurrentOffset { phase, offset_a } => {
                    if let Some(i) = s.phase_current_a.get_mut(phase) {
                        *i += offset_a;
                    }
                }
                Injection::CurrentNan { phase } => {
                    if let Some(i) = s.phase_current_a.get_mut(phase) {
                        *i = f32::NAN;
                    }
                }
                Injection::BusReadingNan => s.bus_voltage_v = f32::NAN,
                Injection::EncoderOffset { counts } => {
                    s.encoder_count = (i64::from(s.encoder_count) + i64::from(counts)).rem_euclid(1 << 16) as u16;
                }
                Injection::EncoderFrozen => {
                    if let Some(slot) = self.frozen_count.get_mut(k) {
                        let held = *slot.get_or_insert(s.encoder_count);
                        s.encoder_count = held;
                    }
                }
                Injection::PowerStageTemperature { celsius } => s.power_stage_temperature_c = Some(celsius),
                Injection::OpenPhase { .. }
                | Injection::BusVoltage { .. }
                | Injection::ExternalForce { .. }
                | Injection::Obstacle { .. }
                | Injection::IsrOverrun
                | Injection::CoreHang => {}
            }
        }
    }
}
