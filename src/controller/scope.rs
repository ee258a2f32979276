//! The scope and the test signals, as the controller runs them: capture
//! configure / trigger / status / read, `start_test` with its bounds, and
//! the one hook the PWM period calls while either is active.
//!
//! Cost: `step` tests one byte (`hooks`) per period; everything else runs
//! only while a capture records or a test runs. The loops read the test's
//! offsets at their own rates (speed, position), never per PWM period.

use super::{Controller, HOOK_CAPTURE, HOOK_TEST};
use crate::capture::{CaptureLayout, CaptureStore};
use crate::foc::Dq;
use crate::io::SensorSample;
use crate::lifecycle::Readiness;
use crate::motion::speed_loop::friction_feedforward_n_m;
use crate::motion::ScurveMove;
use crate::capture::{CaptureConfig, CaptureStatus, CaptureTrigger, Signal};
use crate::test_signals::{ChirpTarget, TestSignal};
use crate::telemetry::Mode;
use crate::test_signals::{Chirp, TestPhase, TestRun, TEST_DURATION_MAX_S};
use crate::reason::Reason;

impl Controller {
    // ---- capture ----

    /// Gives the controller the store its captures write to (a `static`
    /// on the board; the simulator may leak one). Any capture in progress
    /// is dropped.
    pub fn attach_capture_store(&mut self, store: &'static CaptureStore) {
        self.capture.attach(store);
        self.refresh_hooks();
    }

    /// Checks and arms a capture; on refusal nothing changes and the reason
    /// is named. Re-arming drops a capture in progress or done.
    pub fn capture_configure(&mut self, config: &CaptureConfig) -> Result<(), Reason> {
        self.capture.configure(config, &self.params)?;
        self.refresh_hooks();
        Ok(())
    }

    /// Triggers the armed capture at its next sample (whatever trigger it
    /// was armed with).
    pub fn capture_trigger(&mut self) -> Result<(), Reason> {
        self.capture.trigger_now()
    }

    pub fn capture_status(&self) -> CaptureStatus {
        self.capture.status()
    }

    /// What a reader of the store needs, once the capture is done: thread
    /// mode may then read the store directly ([`CaptureStore::read`]); the
    /// interrupt writes nothing more until the next configure.
    pub fn capture_layout(&self) -> Result<CaptureLayout, Reason> {
        self.capture.layout()
    }

    /// Values of the capture's signal slot `signal` from record sample
    /// `start` (0 = oldest) into `out`; returns how many. Done captures only.
    pub fn capture_read(&self, signal: u8, start: u16, out: &mut [f32]) -> Result<usize, Reason> {
        self.capture.read(signal, start, out)
    }

    // ---- test signals ----

    /// True from an accepted `start_test` to the test's end or abort.
    pub fn test_running(&self) -> bool {
        self.test.active()
    }

    /// Pending (waiting for its loop's tick or a capture's pre-trigger
    /// samples), running, or idle.
    pub fn test_phase(&self) -> TestPhase {
        self.test.phase
    }

    /// Starts a test signal: only while `Running` (bridge on, holding, no
    /// move or stream, brake open), within the limits; the reason names the
    /// bound on refusal. The test starts on the next tick of its loop (once
    /// a capture armed with `TestStart` has its pre-trigger samples) and
    /// triggers that capture there; at its end the drive
    /// holds (a position step at the new place; the others where the rod
    /// is). Faults still act during a test; a fault or `Disable` aborts it.
    pub fn start_test(&mut self, signal: TestSignal) -> Result<(), Reason> {
        if !self.faults.is_empty() {
            return Err(Reason::FaultsLatched);
        }
        if self.mode != Mode::Running {
            return Err(Reason::NotRunning);
        }
        if self.test.active() {
            return Err(Reason::TestRunning);
        }
        if self.move_in_progress() {
            return Err(Reason::MoveInProgress);
        }
        if self.brake_opening() {
            return Err(Reason::BrakeOpening);
        }
        // A test moves the rod on purpose, as homing does: it waits until
        // the loops have held it still once after the brake let go, so its
        // response is the loop's alone and the torque watch judges the
        // start-up undisturbed.
        if self.torque_watch.watching() {
            return Err(Reason::AxisNotYetSettled);
        }
        let duration_s = TestRun::duration_s(&signal);
        if !(duration_s > 0.0 && duration_s <= TEST_DURATION_MAX_S) {
            return Err(Reason::DurationOutOfRange);
        }
        let pwm_hz = self.params.rates.pwm_frequency_hz;
        // Whole periods, at least one.
        let periods = crate::math::round(duration_s * pwm_hz).max(1.0) as u32;
        let l = &self.params.limits;
        let homed = self.readiness.contains(Readiness::HOMED);
        let mut chirp = Chirp::new(0.0, 1.0, 1.0, 1, pwm_hz);
        match signal {
            TestSignal::CurrentStep { axis_q, amplitude_a, .. } => {
                if !amplitude_a.is_finite() {
                    return Err(Reason::AmplitudeNotFinite);
                }
                if amplitude_a.abs() > l.current_max_a {
                    return Err(Reason::CurrentStepBeyondLimit);
                }
                let base = self.current_reference.q;
                let (d, q) = if axis_q { (0.0, base + amplitude_a) } else { (amplitude_a, base) };
                if d * d + q * q > self.derived.current_limit_a * self.derived.current_limit_a {
                    return Err(Reason::CurrentStepPlusHoldBeyondLimit);
                }
            }
            TestSignal::SpeedStep { amplitude_rad_s, .. } => {
                if !amplitude_rad_s.is_finite() {
                    return Err(Reason::AmplitudeNotFinite);
                }
                if !homed {
                    return Err(Reason::NotHomedStrokeUnknown);
                }
                let w = self.speed_reference_rad_s + amplitude_rad_s;
                if w.abs() > l.speed_max_rad_s {
                    return Err(Reason::SpeedStepBeyondLimit);
                }
                // Where a stop at the end of the step would come to rest.
                let v = w * self.params.metres_per_rad();
                let rest = self.motor_position_m() + v * duration_s + v * v.abs() / (2.0 * self.params.faults.stop_deceleration_m_s2);
                if !(rest >= l.stroke_min_m && rest <= l.stroke_max_m) {
                    return Err(Reason::SpeedStepLeavesStroke);
                }
            }
            TestSignal::PositionStep { distance_m, .. } => {
                if !distance_m.is_finite() {
                    return Err(Reason::DistanceNotFinite);
                }
                if !homed {
                    return Err(Reason::NotHomedStrokeUnknown);
                }
                if distance_m.abs() >= self.params.faults.position_following_error_m {
                    return Err(Reason::PositionStepBeyondFollowingError);
                }
                let target = self.trajectory.end_m() + distance_m;
                if !(target >= l.stroke_min_m && target <= l.stroke_max_m) {
                    return Err(Reason::PositionStepBeyondStroke);
                }
            }
            TestSignal::Chirp { target, amplitude, start_hz, end_hz, .. } => {
                if !(amplitude.is_finite() && start_hz.is_finite() && end_hz.is_finite()) {
                    return Err(Reason::ChirpArgumentNotFinite);
                }
                if !(amplitude >= 0.0) {
                    return Err(Reason::ChirpAmplitudeNegative);
                }
                if !(start_hz > 0.0 && end_hz > 0.0) {
                    return Err(Reason::ChirpFrequencyNotPositive);
                }
                let divider = match target {
                    ChirpTarget::Current => 1,
                    ChirpTarget::Speed => self.params.rates.speed_loop_divider,
                    ChirpTarget::Position => self.params.rates.position_loop_divider,
                };
                let nyquist_hz = 0.5 * pwm_hz / divider as f32;
                if !(start_hz < nyquist_hz && end_hz < nyquist_hz) {
                    return Err(Reason::ChirpAboveNyquist);
                }
                match target {
                    ChirpTarget::Current => {
                        if amplitude + self.current_reference.q.abs() > self.derived.current_limit_a {
                            return Err(Reason::ChirpPlusHoldBeyondLimit);
                        }
                    }
                    ChirpTarget::Speed => {
                        if !homed {
                            return Err(Reason::NotHomedStrokeUnknown);
                        }
                        if amplitude > l.speed_max_rad_s {
                            return Err(Reason::ChirpBeyondSpeedLimit);
                        }
                    }
                    ChirpTarget::Position => {
                        if !homed {
                            return Err(Reason::NotHomedStrokeUnknown);
                        }
                        if amplitude >= self.params.faults.position_following_error_m {
                            return Err(Reason::ChirpBeyondFollowingError);
                        }
                        let x = self.trajectory.end_m();
                        if !(x - amplitude >= l.stroke_min_m && x + amplitude <= l.stroke_max_m) {
                            return Err(Reason::ChirpBeyondStroke);
                        }
                    }
                }
                chirp = Chirp::new(amplitude, start_hz, end_hz, periods, pwm_hz);
            }
        }
        self.test = TestRun { phase: TestPhase::Pending, signal, periods, chirp, ..TestRun::new() };
        self.refresh_hooks();
        Ok(())
    }

    /// Ends a test now (a fault, `Disable`, a host's stop): the step or
    /// sweep comes off its reference; the loops resume, holding where the
    /// rod is if `hold`.
    pub(super) fn finish_test(&mut self, hold: bool) {
        if !self.test.active() {
            return;
        }
        if self.test.running() {
            match self.test.signal {
                TestSignal::CurrentStep { .. } => self.current_reference = Dq { d: 0.0, q: self.test.base },
                TestSignal::SpeedStep { .. } => {
                    self.speed_reference_rad_s = self.test.base;
                    self.acceleration_reference_rad_s2 = 0.0;
                }
                TestSignal::PositionStep { .. } => {}
                TestSignal::Chirp { .. } => {
                    self.current_reference.q -= self.test.current_offset_a;
                    self.speed_reference_rad_s -= self.test.speed_offset_rad_s;
                }
            }
            if hold && !matches!(self.test.signal, TestSignal::PositionStep { .. }) {
                self.hold_here();
            }
        }
        self.test = TestRun::new();
        self.refresh_hooks();
    }

    /// Stops a running test as at its end (holding where the rod is).
    pub fn stop_test(&mut self) {
        let hold = self.mode == Mode::Running;
        self.finish_test(hold);
    }

    pub(super) fn refresh_hooks(&mut self) {
        let mut h = 0;
        if self.capture.recording() {
            h |= HOOK_CAPTURE;
        }
        if self.test.active() {
            h |= HOOK_TEST;
        }
        self.hooks = h;
    }

    /// The end of a PWM period with a capture recording or a test active:
    /// the sample of this period, then the test's reference for the next.
    /// `speed_tick`: this period ran the speed loop (the capture encodes
    /// its staged frames there).
    #[inline(always)]
    pub(super) fn hooks_period(&mut self, s: &SensorSample, speed_tick: bool) {
        if self.hooks & HOOK_CAPTURE != 0 && self.capture.tick() {
            self.capture_frame(s, speed_tick);
        }
        if self.hooks & HOOK_TEST != 0 {
            self.test_period();
        }
    }

    /// One frame of the capture: each slot's value, staged as it is (the
    /// encoding runs in a batch, see `Capture::flush`). All four slots,
    /// written out: no loop and no jump on the configured count (a slot
    /// beyond it reads a value nobody keeps, at the cost of one load).
    #[inline(always)]
    fn capture_frame(&mut self, s: &SensorSample, speed_tick: bool) {
        let values = [
            self.signal_value(self.capture.signal::<0>(), s),
            self.signal_value(self.capture.signal::<1>(), s),
            self.signal_value(self.capture.signal::<2>(), s),
            self.signal_value(self.capture.signal::<3>(), s),
        ];
        let full = self.capture.stage(values);
        if self.capture.advance() {
            self.capture_event();
        }
        if full || speed_tick {
            self.capture.flush();
        }
    }

    /// The capture's frame count-down ran out (see `Capture::frames_event`).
    #[cold]
    #[inline(never)]
    fn capture_event(&mut self) {
        if !self.capture.frames_event() {
            self.refresh_hooks();
        }
    }

    /// One signal's value now: a load for most, a multiply or two for the
    /// speed and the position. Inlined in each slot: a jump on the signal
    /// and the load cost what an indirect load through a table would.
    #[inline(always)]
    fn signal_value(&self, sig: Signal, s: &SensorSample) -> f32 {
        match sig {
            Signal::CurrentD => self.current_dq.d,
            Signal::CurrentQ => self.current_dq.q,
            Signal::CurrentQReference => self.current_reference.q,
            Signal::CurrentDReference => self.current_reference.d,
            Signal::VoltageD => self.voltage_dq.d,
            Signal::VoltageQ => self.voltage_dq.q,
            Signal::Speed => self.speed_rad_s(),
            Signal::SpeedReference => self.speed_reference_rad_s,
            Signal::MotorPosition => self.motor_position_m_inline(),
            Signal::PositionCommand => self.position_command_m,
            Signal::PositionReference => self.position_reference_m,
            Signal::BusVoltage => s.bus_voltage_v,
            Signal::PhaseCurrentA => s.phase_current_a[0],
            Signal::PhaseCurrentB => s.phase_current_a[1],
            Signal::PhaseCurrentC => s.phase_current_a[2],
            Signal::ElectricalAngle => self.electrical_angle_rad_inline(),
        }
    }

    /// The test's part of a period (out of line: the capture's frame needs
    /// few registers, the test's clock many).
    #[inline(never)]
    fn test_period(&mut self) {
        self.test_tick();
        self.refresh_hooks();
    }

    /// The test's clock, at the end of a period: starts a pending test when
    /// the next period is a tick of its loop, sets the next period's
    /// reference, ends the test after its periods.
    fn test_tick(&mut self) {
        if self.mode != Mode::Running {
            self.finish_test(false);
            return;
        }
        match self.test.phase {
            TestPhase::Idle => {}
            TestPhase::Pending => {
                let next_speed_tick = self.speed_countdown == 1;
                let ready = match self.test.target() {
                    ChirpTarget::Current => true,
                    ChirpTarget::Speed => next_speed_tick,
                    ChirpTarget::Position => next_speed_tick && self.position_countdown == 1,
                };
                // A capture waiting for this test gets its pre-trigger
                // samples first.
                let capture_ready = !self.capture.awaits(CaptureTrigger::TestStart) || self.capture.pre_trigger_filled();
                if ready && capture_ready {
                    self.begin_test();
                }
            }
            TestPhase::Running => {
                self.test.elapsed = self.test.elapsed.saturating_add(1);
                if self.test.elapsed >= self.test.periods {
                    self.finish_test(true);
                } else if let TestSignal::Chirp { target, .. } = self.test.signal {
                    let c = self.test.chirp.value(self.test.elapsed);
                    self.apply_chirp(target, c);
                }
            }
        }
    }

    /// The first test period is the next one: its reference, and the
    /// capture's trigger.
    fn begin_test(&mut self) {
        self.test.phase = TestPhase::Running;
        self.test.elapsed = 0;
        match self.test.signal {
            TestSignal::CurrentStep { axis_q, amplitude_a, .. } => {
                self.test.base = self.current_reference.q;
                if axis_q {
                    self.current_reference.q += amplitude_a;
                } else {
                    self.current_reference.d = amplitude_a;
                }
            }
            TestSignal::SpeedStep { amplitude_rad_s, .. } => {
                self.test.base = self.speed_reference_rad_s;
                self.speed_reference_rad_s += amplitude_rad_s;
                self.acceleration_reference_rad_s2 = 0.0;
            }
            TestSignal::PositionStep { distance_m, .. } => {
                self.trajectory = ScurveMove::hold(self.trajectory.end_m() + distance_m);
                self.restart_move();
            }
            TestSignal::Chirp { target, .. } => self.apply_chirp(target, 0.0),
        }
        self.capture.event(CaptureTrigger::TestStart);
    }

    /// The sweep's value `c` on its reference from the next period on (the
    /// loops add the offsets again when they recompute the reference).
    fn apply_chirp(&mut self, target: ChirpTarget, c: f32) {
        match target {
            ChirpTarget::Current => {
                self.current_reference.q += c - self.test.current_offset_a;
                self.test.current_offset_a = c;
            }
            ChirpTarget::Speed => {
                self.speed_reference_rad_s += c - self.test.speed_offset_rad_s;
                self.test.speed_offset_rad_s = c;
            }
            ChirpTarget::Position => self.test.position_offset_m = c,
        }
    }

    /// The position period while a step suspends the position loop: the
    /// command follows the rod (nothing to follow, and no jump at the end),
    /// the friction feedforward follows the speed reference.
    pub(super) fn test_track_position(&mut self) {
        let x = self.motor_position_m();
        self.position_reference_m = x;
        self.position_command_m = x;
        let v = self.speed_reference_rad_s * self.params.metres_per_rad();
        self.friction_ff_n_m = friction_feedforward_n_m(&self.params, v, self.load.slow_force_n());
    }
}
