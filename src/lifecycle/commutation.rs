//! Commutation with the load on the rod and the brake closed.
//!
//! 1. Brake closed, a test current vector of angle `φ` swept through one
//!    electrical turn forwards and back. The brake disc's compliance lets the
//!    rotor twist by `A sin(φ − θ_e) + C`: the first harmonic gives the rotor's
//!    electrical angle `θ_e`, whatever constant torque the load puts on the
//!    brake (it goes into `C`). No twist at all: no encoder signal. Too much:
//!    the disc slipped.
//! 2. A stationary current vector, pointed so its torque balances the expected
//!    load, takes over from the brake. It does not use the encoder, so a
//!    reversed encoder or a wrong pole count cannot make it run away.
//! 3. The vector turns by a known electrical angle `Δφ` and back while it
//!    dithers (a small sinusoidal swing of its angle) so the rotor keeps
//!    sliding: the friction band, which would let a still rotor stop
//!    anywhere within it, averages out, and the rotor's mean position over
//!    whole dither periods sits where the vector's torque balances the
//!    load alone. Out minus the mean of before and after is the rotation,
//!    measured both ways, so friction, load and any drift cancel. The
//!    encoder must show `Δφ / p` the right way round; the threshold for a
//!    wrong pole count sits midway between 1 and the nearest wrong count's
//!    ratio `p/(p ± 1)`; nothing at all: the rotor is blocked.
//! 4. Handover: the present vector, seen in the rotor frame, is the current
//!    reference field-oriented control starts from (bumpless); its q part is
//!    the measured load.
//!
//! A stored offset (`startup.commutation_known`) goes through the same
//! steps: the sweep must find it within an eighth of a turn, whatever the
//! load, before the brake lets go.
//!
//! A failure after the brake let go holds the vector while the brake closes,
//! then reports: the load never hangs on nothing.

use crate::math::{atan2, sincos, sqrt, wrap_pi};
use crate::params::ControlParams;
use crate::protection::FaultSet;
use core::f32::consts::PI;

/// Sampled once per position period.
#[derive(Clone, Copy, Debug, Default)]
pub struct CommutationInput {
    /// Tracked multi-turn position, counts (direction applied).
    pub position_counts: f32,
    /// Tracked position within a turn, as the rotor angle uses it.
    pub counts_in_turn: f32,
    pub speed_counts_s: f32,
    /// q current that would hold the expected load (signed: positive pushes
    /// the way the encoder counts up).
    pub load_hint_q_a: f32,
}

/// What the controller applies until the next position period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommutationOutput {
    /// Stationary current vector: magnitude, amperes…
    pub current_a: f32,
    /// …at this electrical angle in the controller's frame.
    pub angle_rad: f32,
    pub brake_release: bool,
    pub done: Option<Result<CommutationResult, FaultSet>>,
}

/// A commutation that passed every check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommutationResult {
    /// Electrical angle at count zero, for `encoder.electrical_offset_rad`.
    pub electrical_offset_rad: f32,
    /// The hold vector in the rotor frame at handover (bumpless start).
    pub current_d_a: f32,
    pub current_q_a: f32,
    /// Twist amplitude of the sweep, counts.
    pub twist_amplitude_counts: f32,
    /// Measured / expected check rotation (1 = right direction and poles).
    pub rotation_ratio: f32,
}

/// What the step found so far, for logs and the power-up report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CommutationReport {
    /// The fitted offset (valid once the sweep ended).
    pub electrical_offset_rad: f32,
    pub twist_amplitude_counts: f32,
    /// Mean twist of the sweep, counts from the start.
    pub twist_mean_counts: f32,
    /// Check rotation: measured / expected (valid once it ran).
    pub rotation_ratio: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    RampIn,
    SettleBeforeSweep,
    Sweep,
    BuildHold,
    Release,
    /// The dithered rotation check (`ProbeStage`).
    Probe(ProbeStage),
    SettleBack,
    /// Holding the vector while the brake closes, then `done` with the fault.
    Failing(FaultSet),
}

/// The stages of the rotation check, in order.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ProbeStage {
    /// A first move out without dither, and its settle: its sign alone
    /// tells a mirrored phase sequence (whose hold is an unstable balance
    /// that a dither would tip over) before anything swings.
    PreOut,
    PreSettle,
    /// The dither grows to its amplitude over one dither period.
    DitherIn,
    /// Settling, then the mean position over whole dither periods: out,
    /// back at the hold angle, out again.
    Out,
    MoveBack,
    Back,
    MoveOut,
    Out2,
    /// Home to the hold angle, and the dither dies away over one period.
    MoveHome,
    DitherOut,
}

/// Dither periods per check move (`check_time_s`): 2 gives 150 ms
/// (6.7 Hz) with the default 0.3 s, far below the rotor-on-vector
/// resonance (≈ 30–45 Hz over the rig family), so the rotor follows the
/// swing quasi-statically instead of ringing up.
const DITHER_PERIODS_PER_CHECK: f32 = 2.0;
/// Dither periods waited after a move before averaging, and averaged.
const DITHER_SETTLE_PERIODS: u32 = 1;
const DITHER_MEAN_PERIODS: u32 = 2;
/// Dither amplitude as a fraction of the check angle: half of it
/// (0.1 rad, 20 µm of rod) swings the vector's torque by ±0.27 N·m at the
/// rated load, across the screw's and the seal's friction band.
const DITHER_OF_CHECK_ANGLE: f32 = 0.5;

#[derive(Clone, Copy, Debug)]
pub struct Commutation {
    phase: Phase,
    /// Time in the present phase, and in the whole step.
    phase_s: f32,
    total_s: f32,
    still_s: f32,
    /// Where the rotor was when it last moved: a rotor within a count of
    /// it is still, whatever the speed estimate says.
    still_at_counts: f32,
    x0_counts: f32,
    turn0_counts: f32,
    sum_cos: f32,
    sum_sin: f32,
    sum_x: f32,
    n: u32,
    offset_rad: f32,
    amplitude_counts: f32,
    /// Vector at the start and the end of `BuildHold`.
    from: (f32, f32),
    hold_a: f32,
    hold_angle_rad: f32,
    ratio: f32,
    /// Dither: samples per period, the present sample within its period,
    /// samples since the present stage started, and the present stage's position sum
    /// (counts from `x0`).
    dither_samples: u32,
    dither_k: u32,
    stage_k: u32,
    mean_sum: f32,
    /// Mean positions out, back and out again; the position before the
    /// first move.
    means: [f32; 3],
    x_pre_counts: f32,
    /// Position when the hold vector was pointed, and its angle ahead of
    /// the rotor (`atan2(q, d)`): what a mirrored hold needs.
    x_build_counts: f32,
    hold_lead_rad: f32,
    output: CommutationOutput,
}

impl Commutation {
    pub fn new() -> Self {
        Self {
            phase: Phase::RampIn,
            phase_s: 0.0,
            total_s: 0.0,
            still_s: 0.0,
            still_at_counts: 0.0,
            x0_counts: 0.0,
            turn0_counts: 0.0,
            sum_cos: 0.0,
            sum_sin: 0.0,
            sum_x: 0.0,
            n: 0,
            offset_rad: 0.0,
            amplitude_counts: 0.0,
            from: (0.0, 0.0),
            hold_a: 0.0,
            hold_angle_rad: 0.0,
            ratio: 0.0,
            dither_samples: 1,
            dither_k: 0,
            stage_k: 0,
            mean_sum: 0.0,
            means: [0.0; 3],
            x_pre_counts: 0.0,
            x_build_counts: 0.0,
            hold_lead_rad: 0.0,
            output: CommutationOutput { current_a: 0.0, angle_rad: 0.0, brake_release: false, done: None },
        }
    }

    pub fn report(&self) -> CommutationReport {
        let n = crate::math::max(self.n as f32, 1.0);
        CommutationReport {
            electrical_offset_rad: self.offset_rad,
            twist_amplitude_counts: self.amplitude_counts,
            twist_mean_counts: self.sum_x / n,
            rotation_ratio: self.ratio,
        }
    }

    /// The vector to apply now (between position periods).
    pub fn output(&self) -> CommutationOutput {
        self.output
    }

    fn enter(&mut self, phase: Phase) {
        self.phase = phase;
        self.phase_s = 0.0;
        self.still_s = 0.0;
        self.stage_k = 0;
    }

    /// Fails the step; once the brake was open, through `Failing`.
    // Out of line: ≈ 10 call sites in the commutation step.
    #[inline(never)]
    fn fail(&mut self, fault: FaultSet) {
        if self.output.brake_release {
            self.output.brake_release = false;
            self.enter(Phase::Failing(fault));
        } else {
            self.output = CommutationOutput { current_a: 0.0, angle_rad: 0.0, brake_release: false, done: Some(Err(fault)) };
        }
    }

    /// True once the rotor has been slower than the settle speed for
    /// `settle_s`; fails the step after `settle_timeout_s`.
    ///
    /// A rotor resting on a count edge toggles between two counts as the
    /// current ripple and the brake's twist shake it by micro-radians; one
    /// count in one position period reads as a speed above the settle
    /// speed (0.63 rad/s at 10000 counts and 1 kHz). Such a rotor is still:
    /// within a count of where it last moved, the estimate is the encoder's
    /// resolution, not motion.
    fn settled(&mut self, p: &ControlParams, s: &CommutationInput, dt_s: f32, counts_per_rad: f32) -> bool {
        let c = &p.commutation;
        let slow = s.speed_counts_s.abs() < c.settle_speed_rad_s * counts_per_rad;
        if slow || (s.position_counts - self.still_at_counts).abs() <= 1.0 {
            self.still_s += dt_s;
        } else {
            self.still_s = 0.0;
            self.still_at_counts = s.position_counts;
        }
        if self.still_s >= c.settle_s {
            return true;
        }
        if self.phase_s > c.settle_timeout_s {
            self.fail(FaultSet::LIFECYCLE_TIMEOUT);
        }
        false
    }

    /// One position period. `dt_s` is the position period.
    pub fn update(&mut self, p: &ControlParams, s: &CommutationInput, dt_s: f32) -> CommutationOutput {
        if self.output.done.is_some() {
            return self.output;
        }
        let c = &p.commutation;
        let cpr = p.encoder.counts_per_rev as f32;
        let counts_per_rad = cpr / (2.0 * PI);
        let pole_pairs = p.motor.pole_pairs as f32;
        let electrical_rad_per_count = pole_pairs / counts_per_rad;
        self.phase_s += dt_s;
        self.total_s += dt_s;
        if self.total_s > c.timeout_s && !matches!(self.phase, Phase::Failing(_)) {
            self.fail(FaultSet::LIFECYCLE_TIMEOUT);
        }
        // While the brake is meant to hold, the shaft may only twist.
        let brake_holding = matches!(self.phase, Phase::RampIn | Phase::SettleBeforeSweep | Phase::Sweep | Phase::BuildHold);
        let twist_counts = c.max_twist_rad * counts_per_rad;
        // The first sample is the shaft at rest on the brake, load included.
        if self.total_s <= dt_s {
            self.x0_counts = s.position_counts;
        } else if brake_holding && (s.position_counts - self.x0_counts).abs() > twist_counts {
            self.fail(FaultSet::BRAKE_SLIP);
        }
        if self.output.done.is_some() {
            return self.output;
        }
        if matches!(self.phase, Phase::Release | Phase::Probe(_)) && self.output.brake_release {
            self.watch_runaway(p, s, electrical_rad_per_count);
            if !matches!(self.phase, Phase::Release | Phase::Probe(_)) {
                return self.output;
            }
        }
        match self.phase {
            Phase::RampIn => {
                let k = crate::math::min(self.phase_s / c.ramp_s, 1.0);
                self.output.current_a = k * c.test_current_a;
                self.output.angle_rad = 0.0;
                if k >= 1.0 {
                    self.enter(Phase::SettleBeforeSweep);
                }
            }
            Phase::SettleBeforeSweep => {
                if self.settled(p, s, dt_s, counts_per_rad) {
                    self.turn0_counts = s.counts_in_turn + (self.x0_counts - s.position_counts);
                    self.enter(Phase::Sweep);
                }
            }
            Phase::Sweep => {
                let t = self.phase_s / c.sweep_s;
                if t < 2.0 {
                    // One turn forwards, one back: the rotor's lag behind the
                    // vector cancels between the two.
                    let phi = if t < 1.0 { 2.0 * PI * t } else { 2.0 * PI * (2.0 - t) };
                    let x = s.position_counts - self.x0_counts;
                    let (sin_phi, cos_phi) = sincos(self.output.angle_rad);
                    self.sum_cos += x * cos_phi;
                    self.sum_sin += x * sin_phi;
                    self.sum_x += x;
                    self.n = self.n.saturating_add(1);
                    self.output.angle_rad = phi;
                } else {
                    self.finish_sweep(p, s, c.hold_current_d_a, electrical_rad_per_count);
                }
            }
            Phase::BuildHold => {
                let k = crate::math::min(self.phase_s / c.ramp_s, 1.0);
                let (ts, tc) = sincos(self.hold_angle_rad);
                let (a0, b0) = self.from;
                let a = a0 + k * (self.hold_a * tc - a0);
                let b = b0 + k * (self.hold_a * ts - b0);
                self.output.current_a = sqrt(a * a + b * b);
                self.output.angle_rad = atan2(b, a);
                if k >= 1.0 {
                    self.output.brake_release = true;
                    self.enter(Phase::Release);
                }
            }
            Phase::Release => {
                if self.phase_s >= p.brake.release_time_s && self.settled(p, s, dt_s, counts_per_rad) {
                    let period_s = c.check_time_s / DITHER_PERIODS_PER_CHECK;
                    self.dither_samples = crate::math::max(period_s / dt_s + 0.5, 4.0) as u32;
                    self.dither_k = 0;
                    self.x_pre_counts = s.position_counts;
                    self.enter(Phase::Probe(ProbeStage::PreOut));
                }
            }
            Phase::Probe(stage) => self.probe(p, s, stage, dt_s, electrical_rad_per_count),
            Phase::SettleBack => {
                if self.settled(p, s, dt_s, counts_per_rad) {
                    let theta = self.offset_rad + s.counts_in_turn * electrical_rad_per_count;
                    let (sd, cd) = sincos(self.hold_angle_rad - theta);
                    self.output.done = Some(Ok(CommutationResult {
                        electrical_offset_rad: self.offset_rad,
                        current_d_a: self.hold_a * cd,
                        current_q_a: self.hold_a * sd,
                        twist_amplitude_counts: self.amplitude_counts,
                        rotation_ratio: self.ratio,
                    }));
                }
            }
            Phase::Failing(fault) => {
                // The vector keeps holding until the brake has closed.
                if self.phase_s >= 2.0 * p.brake.engage_time_s {
                    self.output = CommutationOutput { current_a: 0.0, angle_rad: 0.0, brake_release: false, done: Some(Err(fault)) };
                }
            }
        }
        self.output
    }

    /// One position period of the rotation check: the vector's centre
    /// (the hold angle, or that plus the check angle), the dither on top,
    /// the stage's mean position, and the verdicts.
    fn probe(&mut self, p: &ControlParams, s: &CommutationInput, stage: ProbeStage, dt_s: f32, electrical_rad_per_count: f32) {
        let c = &p.commutation;
        let n = self.dither_samples;
        let dithering = !matches!(stage, ProbeStage::PreOut | ProbeStage::PreSettle);
        let (sin_d, _) = sincos(2.0 * PI * self.dither_k as f32 / n as f32);
        if dithering {
            // The swing's sample within its period, wrapped without a division.
            let next = self.dither_k.saturating_add(1);
            self.dither_k = if next >= n { 0 } else { next };
        }
        let k = self.stage_k;
        self.stage_k = self.stage_k.saturating_add(1);
        let ease = |x: f32| 0.5 * (1.0 - sincos(PI * crate::math::min(x, 1.0)).1);
        let move_k = self.phase_s / c.check_time_s;
        let ramp_k = crate::math::min(k as f32 / n as f32, 1.0);
        let (centre, amplitude) = match stage {
            ProbeStage::PreOut => (ease(move_k), 0.0),
            ProbeStage::PreSettle => (1.0, 0.0),
            ProbeStage::DitherIn => (1.0, ramp_k),
            ProbeStage::Out | ProbeStage::Out2 => (1.0, 1.0),
            ProbeStage::MoveBack | ProbeStage::MoveHome => (1.0 - ease(move_k), 1.0),
            ProbeStage::Back => (0.0, 1.0),
            ProbeStage::MoveOut => (ease(move_k), 1.0),
            ProbeStage::DitherOut => (0.0, 1.0 - ramp_k),
        };
        self.output.angle_rad =
            self.hold_angle_rad + (centre + amplitude * DITHER_OF_CHECK_ANGLE * sin_d) * c.check_angle_rad;
        let slot = match stage {
            ProbeStage::PreOut if move_k >= 1.0 => return self.enter(Phase::Probe(ProbeStage::PreSettle)),
            ProbeStage::PreSettle => {
                let counts_per_rad = p.encoder.counts_per_rev as f32 / (2.0 * PI);
                if self.settled(p, s, dt_s, counts_per_rad) {
                    let ratio = (s.position_counts - self.x_pre_counts) * electrical_rad_per_count / c.check_angle_rad;
                    if ratio < -c.blocked_ratio {
                        self.ratio = ratio;
                        self.fail(FaultSet::WRONG_DIRECTION);
                    } else {
                        self.enter(Phase::Probe(ProbeStage::DitherIn));
                    }
                }
                return;
            }
            ProbeStage::DitherIn if ramp_k >= 1.0 => return self.enter(Phase::Probe(ProbeStage::Out)),
            ProbeStage::MoveBack if move_k >= 1.0 => return self.enter(Phase::Probe(ProbeStage::Back)),
            ProbeStage::MoveOut if move_k >= 1.0 => return self.enter(Phase::Probe(ProbeStage::Out2)),
            ProbeStage::MoveHome if move_k >= 1.0 => return self.enter(Phase::Probe(ProbeStage::DitherOut)),
            ProbeStage::DitherOut if ramp_k >= 1.0 => return self.enter(Phase::SettleBack),
            ProbeStage::Out => 0,
            ProbeStage::Back => 1,
            ProbeStage::Out2 => 2,
            _ => return,
        };
        // After settling, the mean over whole dither periods (any n
        // consecutive samples of the swing sum to zero).
        let wait = DITHER_SETTLE_PERIODS.saturating_mul(n);
        if k < wait {
            self.mean_sum = 0.0;
            return;
        }
        self.mean_sum += s.position_counts - self.x0_counts;
        let taken = k.saturating_sub(wait).saturating_add(1);
        if taken >= DITHER_MEAN_PERIODS.saturating_mul(n) {
            if let Some(m) = self.means.get_mut(slot) {
                *m = self.mean_sum / taken as f32;
            }
            self.mean_sum = 0.0;
            match stage {
                ProbeStage::Out => self.enter(Phase::Probe(ProbeStage::MoveBack)),
                ProbeStage::Back => self.enter(Phase::Probe(ProbeStage::MoveOut)),
                _ => self.judge_rotation(p, electrical_rad_per_count),
            }
        }
    }

    /// With the brake open the rotor may only follow the vector: at most
    /// the hold's lead, and the check move plus the dither swing twice over
    /// for the lag. Beyond
    /// that the vector does not hold the load: its balance is unstable,
    /// which is what a mirrored phase sequence gives (`wrong_direction`).
    /// The vector is turned at once to the balance a mirrored motor has at
    /// the present position, `hold + π − 2·lead − Δθ` (the hold's lead
    /// mirrored, the rotor's travel since it was pointed undone), which
    /// holds the load while the brake closes.
    fn watch_runaway(&mut self, p: &ControlParams, s: &CommutationInput, electrical_rad_per_count: f32) {
        // The hold's lead is the expected load's: a load that differs moves
        // the balance by up to that much.
        let lead = self.hold_lead_rad.abs();
        let span_rad = match self.phase {
            Phase::Release => lead + p.commutation.check_angle_rad,
            _ => lead + 2.0 * (1.0 + DITHER_OF_CHECK_ANGLE) * p.commutation.check_angle_rad,
        };
        let moved_rad = (s.position_counts - self.x_pre_or_release(s)) * electrical_rad_per_count;
        if moved_rad.abs() <= span_rad {
            return;
        }
        let travelled = (s.position_counts - self.x_build_counts) * electrical_rad_per_count;
        self.ratio = moved_rad / p.commutation.check_angle_rad;
        self.output.angle_rad = wrap_pi(self.hold_angle_rad + PI - 2.0 * self.hold_lead_rad - travelled);
        self.fail(FaultSet::WRONG_DIRECTION);
    }

    /// Where the rotor was when the brake had let go (the release phase's
    /// start position until then).
    fn x_pre_or_release(&mut self, s: &CommutationInput) -> f32 {
        if self.phase == Phase::Release && self.stage_k == 0 {
            self.x_pre_counts = s.position_counts;
            self.stage_k = 1;
        }
        self.x_pre_counts
    }

    /// The rotation out, against back (both ways: the mean of the two
    /// outs against the back between them, so the load, the friction and a
    /// steady drift cancel), as a fraction of the one the drive's pole
    /// count predicts; the thresholds sit midway between 1 and the ratios
    /// of the neighbouring pole counts.
    fn judge_rotation(&mut self, p: &ControlParams, electrical_rad_per_count: f32) {
        let c = &p.commutation;
        let [out, back, out2] = self.means;
        let moved = 0.5 * (out + out2) - back;
        self.ratio = moved * electrical_rad_per_count / c.check_angle_rad;
        let pp = p.motor.pole_pairs as f32;
        let high = if pp > 1.0 { 0.5 * (1.0 + pp / (pp - 1.0)) } else { f32::INFINITY };
        let low = 0.5 * (1.0 + pp / (pp + 1.0));
        if self.ratio.abs() < c.blocked_ratio {
            self.fail(FaultSet::ROTOR_BLOCKED);
        } else if self.ratio < 0.0 {
            self.fail(FaultSet::WRONG_DIRECTION);
        } else if !(self.ratio >= low && self.ratio <= high) {
            self.fail(FaultSet::WRONG_POLE_PAIRS);
        } else {
            self.enter(Phase::Probe(ProbeStage::MoveHome));
        }
    }

    /// Fits the sweep's first harmonic and points the hold vector.
    fn finish_sweep(&mut self, p: &ControlParams, s: &CommutationInput, hold_d_a: f32, electrical_rad_per_count: f32) {
        let n = crate::math::max(self.n as f32, 1.0);
        let a = 2.0 * self.sum_cos / n;
        let b = 2.0 * self.sum_sin / n;
        let mean = self.sum_x / n;
        self.amplitude_counts = sqrt(a * a + b * b);
        if !(self.amplitude_counts >= p.commutation.min_amplitude_counts) {
            self.fail(FaultSet::ENCODER_NO_SIGNAL);
            return;
        }
        // x = A sin(φ − θ) + C: the fit's θ is the electrical angle at the
        // sweep's mean position.
        let theta_mean = atan2(-a, b);
        self.offset_rad = wrap_pi(theta_mean - (self.turn0_counts + mean) * electrical_rad_per_count);
        // A stored offset (an absolute encoder) is checked against the fit,
        // still on the closed brake: an error near a quarter turn makes no
        // torque, which a light load never shows once the brake lets go.
        // Within an eighth of a turn it is kept bit for bit.
        if p.startup.commutation_known {
            let stored = p.encoder.electrical_offset_rad;
            if wrap_pi(self.offset_rad - stored).abs() > 0.25 * PI {
                self.fail(FaultSet::WRONG_DIRECTION);
                return;
            }
            self.offset_rad = stored;
        }
        let theta_now = self.offset_rad + s.counts_in_turn * electrical_rad_per_count;
        let q = s.load_hint_q_a;
        self.hold_a = sqrt(hold_d_a * hold_d_a + q * q);
        self.hold_lead_rad = atan2(q, hold_d_a);
        self.hold_angle_rad = theta_now + self.hold_lead_rad;
        self.x_build_counts = s.position_counts;
        let (si, co) = sincos(self.output.angle_rad);
        self.from = (self.output.current_a * co, self.output.current_a * si);
        self.enter(Phase::BuildHold);
    }
}

impl Default for Commutation {
    fn default() -> Self {
        Self::new()
    }
}
