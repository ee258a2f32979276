//! Test signals generated in the core, timed in PWM periods: current, speed
//! and position steps and a logarithmic chirp added to a loop's reference.
//!
//! This module holds the signal and its clock; `controller::scope` checks
//! the bounds, starts it, feeds it to the loops and ends it.

mod signal;

pub use signal::{ChirpTarget, TestSignal};

/// Longest test, seconds.
pub const TEST_DURATION_MAX_S: f32 = 60.0;

/// Where a test run is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TestPhase {
    Idle,
    /// Accepted; starts in the first period that suits it (its loop's tick).
    Pending,
    Running,
}

/// A logarithmic sweep `A sin 2π φ(t)`, `φ(t) = f₀T/ln k · (k^{t/T} − 1)`,
/// `k = f₁/f₀`, with `t` counted in periods: instantaneous frequency
/// `f₀ k^{t/T}`. Evaluated in closed form (no phase accumulated over the
/// sweep, so no drift), φ in cycles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chirp {
    amplitude: f32,
    /// Start frequency in cycles per PWM period.
    f0_cycles: f32,
    /// `ln k`, and `1 / N` (N periods in the sweep).
    ln_k: f32,
    inv_periods: f32,
    /// `f₀ N / ln k`: cycles per unit of `k^{t/T} − 1`.
    cycles_scale: f32,
    k: f32,
}

impl Chirp {
    /// `start_hz`, `end_hz` > 0; `periods` ≥ 1 PWM periods of `pwm_hz`.
    pub fn new(amplitude: f32, start_hz: f32, end_hz: f32, periods: u32, pwm_hz: f32) -> Self {
        let f0_cycles = start_hz / pwm_hz;
        let k = end_hz / start_hz;
        let ln_k = crate::math::ln(k);
        let n = periods.max(1) as f32;
        let cycles_scale = if ln_k.abs() > 1e-4 { f0_cycles * n / ln_k } else { 0.0 };
        Self { amplitude, f0_cycles, ln_k, inv_periods: 1.0 / n, cycles_scale, k }
    }

    /// Phase in cycles after `n` periods.
    pub fn cycles(&self, n: u32) -> f32 {
        if self.cycles_scale == 0.0 {
            return self.f0_cycles * n as f32;
        }
        self.cycles_scale * (self.k_pow(n) - 1.0)
    }

    /// The value after `n` periods.
    pub fn value(&self, n: u32) -> f32 {
        let c = self.cycles(n);
        let frac = c - crate::math::round(c);
        let (s, _) = crate::math::sincos(frac * core::f32::consts::TAU);
        self.amplitude * s
    }

    /// Instantaneous frequency after `n` periods, in cycles per period.
    pub fn frequency_cycles(&self, n: u32) -> f32 {
        self.f0_cycles * self.k_pow(n)
    }

    /// `k^{n/N}`, through `exp_neg` with a non-positive exponent.
    fn k_pow(&self, n: u32) -> f32 {
        let x = n as f32 * self.inv_periods;
        if self.ln_k > 0.0 { self.k * crate::math::exp_neg((x - 1.0) * self.ln_k) } else { crate::math::exp_neg(x * self.ln_k) }
    }
}

/// A test in progress (or none).
#[derive(Clone, Copy, Debug)]
pub struct TestRun {
    pub phase: TestPhase,
    pub signal: TestSignal,
    /// Duration in PWM periods, and periods done since the start.
    pub periods: u32,
    pub elapsed: u32,
    /// The reference the step or sweep is added to, taken at the start.
    pub base: f32,
    pub chirp: Chirp,
    /// Read by the loops every tick (0 without a test): the chirp on the
    /// speed reference (position period adds it) and the position command.
    pub speed_offset_rad_s: f32,
    pub position_offset_m: f32,
    /// The chirp on the q-current reference (the speed period adds it).
    pub current_offset_a: f32,
}

impl Default for TestRun {
    fn default() -> Self {
        Self::new()
    }
}

impl TestRun {
    pub const fn new() -> Self {
        Self {
            phase: TestPhase::Idle,
            signal: TestSignal::CurrentStep { axis_q: true, amplitude_a: 0.0, duration_s: 0.0 },
            periods: 0,
            elapsed: 0,
            base: 0.0,
            chirp: Chirp { amplitude: 0.0, f0_cycles: 0.0, ln_k: 0.0, inv_periods: 1.0, cycles_scale: 0.0, k: 1.0 },
            speed_offset_rad_s: 0.0,
            position_offset_m: 0.0,
            current_offset_a: 0.0,
        }
    }

    /// Accepted or running.
    #[inline(always)]
    pub fn active(&self) -> bool {
        self.phase != TestPhase::Idle
    }

    pub fn running(&self) -> bool {
        self.phase == TestPhase::Running
    }

    /// The speed loop is suspended (current step).
    #[inline(always)]
    pub fn suspends_speed(&self) -> bool {
        self.phase == TestPhase::Running && matches!(self.signal, TestSignal::CurrentStep { .. })
    }

    /// The position loop is suspended (current or speed step).
    #[inline(always)]
    pub fn suspends_position(&self) -> bool {
        self.phase == TestPhase::Running && matches!(self.signal, TestSignal::CurrentStep { .. } | TestSignal::SpeedStep { .. })
    }

    /// A current chirp is running: its kHz `L di/dt` makes voltage without
    /// motion (a current step does not, past its edge, and keeps the
    /// back-EMF watch: it is the only encoder guard left while both outer
    /// loops are suspended).
    #[inline(always)]
    pub fn sweeps_current(&self) -> bool {
        self.phase == TestPhase::Running && matches!(self.signal, TestSignal::Chirp { target: ChirpTarget::Current, .. })
    }

    /// Which loop's tick the test starts on.
    pub fn target(&self) -> ChirpTarget {
        match self.signal {
            TestSignal::CurrentStep { .. } => ChirpTarget::Current,
            TestSignal::SpeedStep { .. } => ChirpTarget::Speed,
            TestSignal::PositionStep { .. } => ChirpTarget::Position,
            TestSignal::Chirp { target, .. } => target,
        }
    }

    pub fn duration_s(signal: &TestSignal) -> f32 {
        match *signal {
            TestSignal::CurrentStep { duration_s, .. }
            | TestSignal::SpeedStep { duration_s, .. }
            | TestSignal::PositionStep { duration_s, .. }
            | TestSignal::Chirp { duration_s, .. } => duration_s,
        }
    }
}
