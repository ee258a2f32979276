//! Open-phase detection: a broken motor lead or a dead inverter leg.
//!
//! An open phase carries no current whatever its voltage, while the other
//! two carry ± the same current, so the three still sum to zero and the
//! current-sum check cannot see it. What gives it away is a phase that the
//! current reference needs and that stays empty: over a window, a phase
//! that, in the samples where it was asked for at least
//! `open_phase_current_a`, carried on average less than `open_phase_ratio`
//! of that threshold, i.e. sensor noise only.
//!
//! The bound on what the phase carries is absolute, not a fraction of the
//! demand: an open lead carries nothing whatever the load, so the check
//! holds from a light payload (a demand just above the threshold) to the
//! rated one, and a phase that carries a real but lagging share of a large
//! demand (a slipping frame, a saturated loop) is not called open.
//!
//! Why not a current-following check on |i_dq,ref − i_dq|: an encoder that
//! stops counting also makes the dq currents miss their references (the
//! back-EMF rotates in the frozen frame), so that check fires on encoder
//! faults first and names the wrong cause. Per phase, a wrong angle still
//! puts current in all three phases; only an open circuit empties one.
//!
//! At standstill the reference may ask next to nothing of one phase (its
//! axis perpendicular to the current vector); a window without enough
//! demand on any empty phase gives no verdict, and the last one stands.
//!
//! A nearly empty rod cruising asks for its friction only (about 1 A), so
//! no phase reaches the floor and no window judges while moving. There the
//! speed period adds a d-axis probe ([`probe_current_d_a`]): on surface
//! magnets (L_d = L_q) d current makes no torque, so the load does not feel
//! it, but it lengthens the current vector so that every phase is asked for
//! the floor in every window at the catalogue's cruise (see below).
//!
//! The probe switches on and off as the q reference crosses its length, and
//! turns the reference vector as it does: after a break the torque dips
//! swing q across it, which can park a phase's zero crossing mid-window. A
//! window judged on the phase's mean demand then misses the floor although
//! the phase is asked well on either side, so a window judges each phase
//! only over the samples in which it was asked ([`JUDGED_SHARE`]).
//!
//! "Asked" is what a healthy loop surely carries, not the raw reference:
//! the reference also passes through a first-order model of the current
//! loop, slower than the loop ([`follow_gain`]), and a phase is asked only
//! what the reference and the model both ask. A current loop
//! tuned slow (a 300 Hz ask on the tuning bench has a 0.53 ms time
//! constant, three speed periods) lags a speed step's reversal by more than
//! the floor for the few samples a window judges; judged on the raw
//! reference, a working phase read as empty there. The model settles in a
//! few of its time constants, so an open lead, which carries nothing
//! whatever the loop does, is still found within a window or two.

use crate::foc::transforms::{inverse_clarke, inverse_park, SinCos};
use crate::foc::Dq;
use crate::params::FaultParams;

/// The current vector the probe fills up to, in multiples of the demand
/// floor. A window spanning an angle x of the electrical period, centred on
/// a phase's zero crossing (the worst place), asks that phase a mean |cos|
/// of (1 − cos(x/2))/(x/2); at 0.2 m/s a 2 ms window spans x ≈ 2.0 rad and
/// the mean is 0.46, so 3 floors ask 1.38 floors of every phase in every
/// window, and a phase is asked the floor wherever |cos| ≥ 1/3, 78 % of the
/// period: a lost lead is judged in the first whole window after it breaks.
/// Every window judges every phase down to about 0.14 m/s (x = 1.4 rad, mean
/// 1/3); slower, a phase is judged in the windows near its peak, once an
/// electrical period.
pub const PROBE_VECTOR_PER_FLOOR: f32 = 3.0;

/// The d-axis probe current that makes the current vector
/// [`PROBE_VECTOR_PER_FLOOR`] floors long, given the q reference: 0 when q
/// alone is already that long, or when the vector would not fit inside
/// `current_limit_a` (a thermal foldback keeps its whole budget for torque).
/// Negative, the flux-weakening sign: it lowers the voltage the back-EMF
/// needs instead of raising it, so it never pushes the loop into the
/// voltage limit.
pub fn probe_current_d_a(f: &FaultParams, current_q_a: f32, current_limit_a: f32) -> f32 {
    let target_a = PROBE_VECTOR_PER_FLOOR * f.open_phase_current_a;
    // Written so that a NaN anywhere gives no probe.
    if !(target_a < current_limit_a) {
        return 0.0;
    }
    let d2 = target_a * target_a - current_q_a * current_q_a;
    if !(d2 > 0.0) {
        return 0.0;
    }
    -crate::math::sqrt(d2)
}

/// The least share of a window's samples in which a phase must be asked
/// for the floor before its window judges it. A quarter of the 2 ms window
/// (3 of 11 speed periods) averages the sensor noise (0.03 A σ, far under
/// the empty bound) and leaves a healthy loop's lag no room: asked 1 A, a
/// working phase carries most of it within a speed period.
pub const JUDGED_SHARE: f32 = 0.25;

/// The share of the current loop's design bandwidth (kp / L_q, the
/// pole-zero-cancelled PI's crossover) at which the model of a healthy
/// phase follows the reference. Slower than the loop, so a working phase
/// always leads the model: the model never asks for current that the loop
/// has not had time to build, which is what would read as an empty phase.
pub const MODEL_BANDWIDTH_SHARE: f32 = 0.5;

/// The per-speed-period gain of the first-order model of a healthy phase:
/// `1 − exp(−share · kp / L_q · T)`. 1 (no lag) if the gains give no finite
/// positive bandwidth, as the unmodelled detector did.
pub fn follow_gain(current_kp_v_per_a: f32, inductance_q_h: f32, speed_period_s: f32) -> f32 {
    let x = MODEL_BANDWIDTH_SHARE * current_kp_v_per_a / inductance_q_h * speed_period_s;
    if !(x > 0.0) || !x.is_finite() {
        return 1.0;
    }
    1.0 - crate::math::exp_neg(-x)
}

#[derive(Clone, Copy, Debug, Default)]
pub struct OpenPhaseMonitor {
    /// |measured| summed over the samples in which the phase was asked for
    /// at least the floor, and how many those were.
    measured_abs_sum_a: [f32; 3],
    asked_samples: [u32; 3],
    samples: u32,
    /// What a healthy loop would carry now: the dq reference through the
    /// model of the current loop (in the rotor frame, as the loop follows
    /// it, so the model adds no lag at the electrical frequency). Kept
    /// across windows.
    expected_dq_a: Dq,
}

impl OpenPhaseMonitor {
    pub const fn new() -> Self {
        Self { measured_abs_sum_a: [0.0; 3], asked_samples: [0; 3], samples: 0, expected_dq_a: Dq { d: 0.0, q: 0.0 } }
    }

    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Moves the model of a healthy loop one speed period towards the dq
    /// reference held over that period (gain from [`follow_gain`]) and
    /// returns, per phase, what both the reference and the model ask at the
    /// rotor angle `sc`: the smaller of the two where they agree in sign,
    /// 0 where they do not. A working loop is ahead of the slower model on a
    /// rise and at the reference after a fall, so it carries at least this
    /// much; through a reversal the two disagree and nothing is asked.
    pub fn expected_phase_current_a(&mut self, follow_gain: f32, reference_dq_a: Dq, sc: SinCos) -> [f32; 3] {
        let e = &mut self.expected_dq_a;
        e.d += follow_gain * (reference_dq_a.d - e.d);
        e.q += follow_gain * (reference_dq_a.q - e.q);
        let model = inverse_clarke(inverse_park(*e, sc));
        let reference = inverse_clarke(inverse_park(reference_dq_a, sc));
        let mut asked = [0.0; 3];
        for ((a, m), r) in asked.iter_mut().zip(model.iter()).zip(reference.iter()) {
            // NaN compares false: nothing asked.
            if m * r > 0.0 {
                *a = if m.abs() < r.abs() { *m } else { *r };
            }
        }
        asked
    }

    /// Adds one sample of the reference and measured phase currents. At the
    /// end of a window of `window_samples` returns `Some(open)`: whether a
    /// phase asked for at least `open_phase_current_a` in at least
    /// [`JUDGED_SHARE`] of the window carried, over those samples, less
    /// than `open_phase_ratio` of that floor on average; `Some(false)` if
    /// every phase so asked carried more; `None` mid-window or when no phase
    /// was asked often enough to judge.
    ///
    /// Judging a phase only where it is asked, not on its mean over the
    /// whole window, keeps the verdict from hanging on where the phase's
    /// zero crossing falls in the window: a window centred on it asks the
    /// phase little on average although it is asked well on either side.
    pub fn update(
        &mut self,
        f: &FaultParams,
        window_samples: u32,
        reference_a: [f32; 3],
        measured_a: [f32; 3],
    ) -> Option<bool> {
        for ((r, m), (ms, n)) in reference_a
            .iter()
            .zip(measured_a.iter())
            .zip(self.measured_abs_sum_a.iter_mut().zip(self.asked_samples.iter_mut()))
        {
            // A NaN reference compares false and is not counted as asked.
            if r.abs() >= f.open_phase_current_a {
                *ms += m.abs();
                *n = n.saturating_add(1);
            }
        }
        self.samples = self.samples.saturating_add(1);
        if self.samples < window_samples {
            return None;
        }
        let judged_min = crate::math::max(JUDGED_SHARE * window_samples as f32, 1.0);
        let mut verdict = None;
        for (ms, n) in self.measured_abs_sum_a.iter().zip(self.asked_samples.iter()) {
            let asked = *n as f32;
            if asked >= judged_min {
                let empty_max = f.open_phase_ratio * f.open_phase_current_a * asked;
                // NaN sums (non-finite samples are refused before this, but
                // never trust it) compare false and give no verdict.
                if *ms < empty_max {
                    verdict = Some(true);
                } else if *ms >= empty_max && verdict.is_none() {
                    verdict = Some(false);
                }
            }
        }
        let expected = self.expected_dq_a;
        self.reset();
        self.expected_dq_a = expected;
        verdict
    }
}
