//! Averaged two-level inverter on an ideal (stiff) DC bus.
//!
//! Enabled: each leg's output averaged over a PWM period is `d_x V_bus`; the
//! star point of the motor floats, so the phase-to-neutral voltage is
//! `u_x = V_bus (d_x − mean(d))`. Switching ripple, dead time and device
//! drops are not modelled (the averaged model is what the current loop sees
//! at its sampling instant, the PWM centre).
//!
//! Disabled (all six switches open): only the freewheel diodes can conduct.
//! A phase carrying current into the motor (i > 0) is fed through its
//! low-side diode, so its terminal sits at 0 V; one carrying current out
//! (i < 0) conducts through its high-side diode to `V_bus`. A phase with no
//! current floats (its terminal follows neutral + back-EMF) until that would
//! rise above `V_bus` or below 0, when a diode starts to conduct. Hence:
//! - currents flowing at switch-off are driven to zero by ≈ −V_bus in
//!   ≈ L·I/V_bus (tens of µs), returning their energy to the bus;
//! - at standstill or low speed nothing conducts: the motor coasts freely;
//! - when the line-to-line back-EMF exceeds `V_bus` (overspeed, e.g. the
//!   load back-driving the screw with PWM off) the diodes rectify and the
//!   motor brakes, pumping energy into the bus (which stays stiff here).
//!
//! The conduction pattern is decided at the start of each RK4 step and held
//! through it; after the step a phase whose current crossed zero against its
//! diode is clamped to zero (`enforce_blocking`). Diode drops are neglected.
//!
//! Open phase (fault injection: a broken motor lead or a blown leg): one
//! phase is disconnected from its leg whatever the switches do. It carries
//! no current, its terminal floats at neutral + back-EMF, and the neutral is
//! set by the two phases still connected (`pwm_phase_voltages_open`,
//! `diode_legs_open`, `force_open`).

use super::frames;

/// What one inverter leg connects its phase to while the switches are off.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Leg {
    /// Low-side diode conducting: terminal at 0 V, current into the motor.
    Low,
    /// High-side diode conducting: terminal at `V_bus`, current out of the motor.
    High,
    /// Neither: zero current, terminal floating.
    Open,
}

/// How the inverter drives the motor during one RK4 step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Drive {
    /// Switching, with these duties in [0, 1].
    Pwm([f64; 3]),
    /// Switches off; these legs conduct through their diodes.
    Diodes([Leg; 3]),
}

/// Below this a phase current counts as zero (it is exactly zero after
/// `enforce_blocking`, up to rounding of the frame transforms).
const ZERO_CURRENT_A: f64 = 1e-9;

/// Phase-to-neutral voltages of the switching inverter.
#[inline]
pub fn pwm_phase_voltages(duty: [f64; 3], bus_v: f64) -> [f64; 3] {
    let mean = (duty[0] + duty[1] + duty[2]) / 3.0;
    [bus_v * (duty[0] - mean), bus_v * (duty[1] - mean), bus_v * (duty[2] - mean)]
}

/// Phase-to-neutral voltages of the switching inverter with phase `open`
/// disconnected. The connected phases sit at `d V_bus − v_n` with the
/// neutral `v_n = mean over connected phases of (d V_bus − e)` (balanced R,
/// L; the open phase carries no current, so the two connected currents sum
/// to zero); the open phase's voltage is its back-EMF, so its current stays
/// zero (exactly for L_d = L_q; `force_open` removes the residue otherwise).
pub fn pwm_phase_voltages_open(duty: [f64; 3], bus_v: f64, e_abc: [f64; 3], open: usize) -> [f64; 3] {
    let mut sum = 0.0;
    for k in 0..3 {
        if k != open {
            sum += duty[k] * bus_v - e_abc[k];
        }
    }
    let neutral = 0.5 * sum;
    std::array::from_fn(|k| if k == open { e_abc[k] } else { duty[k] * bus_v - neutral })
}

/// Diode conduction with phase `open` disconnected: only the other two
/// phases can conduct, in series (their currents are equal and opposite).
/// They keep conducting while current flows, and start when their
/// line-to-line EMF beats the bus.
pub fn diode_legs_open(i_abc: [f64; 3], e_abc: [f64; 3], bus_v: f64, open: usize) -> [Leg; 3] {
    let (j, m) = match open {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let mut legs = [Leg::Open; 3];
    let i = 0.5 * (i_abc[j] - i_abc[m]);
    let idle = i.abs() <= ZERO_CURRENT_A;
    // Current out of j (or, with none flowing, j's EMF above m's by more
    // than the bus) conducts through j's high-side diode.
    let (lj, lm) = if i > ZERO_CURRENT_A || (idle && e_abc[m] - e_abc[j] > bus_v) {
        (Leg::Low, Leg::High)
    } else if i < -ZERO_CURRENT_A || (idle && e_abc[j] - e_abc[m] > bus_v) {
        (Leg::High, Leg::Low)
    } else {
        return legs;
    };
    legs[j] = lj;
    legs[m] = lm;
    legs
}

/// Sets the open phase's current to zero, sharing it equally between the
/// other two (the projection that keeps the sum zero), as `enforce_blocking`
/// does for a blocked diode.
pub fn force_open(i_abc: [f64; 3], open: usize) -> [f64; 3] {
    let share = 0.5 * i_abc[open];
    std::array::from_fn(|k| if k == open { 0.0 } else { i_abc[k] + share })
}

/// Decides which diodes conduct, from the phase currents and back-EMFs at
/// the start of a step.
pub fn diode_legs(i_abc: [f64; 3], e_abc: [f64; 3], bus_v: f64) -> [Leg; 3] {
    let mut legs = [Leg::Open; 3];
    for k in 0..3 {
        if i_abc[k] > ZERO_CURRENT_A {
            legs[k] = Leg::Low;
        } else if i_abc[k] < -ZERO_CURRENT_A {
            legs[k] = Leg::High;
        }
    }
    let conducting = legs.iter().filter(|l| **l != Leg::Open).count();
    if conducting < 2 {
        // Nothing flows (a lone nonzero phase is rounding residue that
        // `enforce_blocking` removes). Conduction starts only if the
        // largest line-to-line EMF beats the bus.
        legs = [Leg::Open; 3];
        let (hi, lo) = extremes(e_abc);
        if e_abc[hi] - e_abc[lo] > bus_v {
            legs[hi] = Leg::High;
            legs[lo] = Leg::Low;
        } else {
            return legs;
        }
    }
    // With two legs conducting, the open phase's terminal is neutral + EMF;
    // past either rail its diode turns on.
    if let Some(open) = legs.iter().position(|l| *l == Leg::Open) {
        let neutral = neutral_voltage(legs, e_abc, bus_v);
        let terminal = neutral + e_abc[open];
        if terminal > bus_v {
            legs[open] = Leg::High;
        } else if terminal < 0.0 {
            legs[open] = Leg::Low;
        }
    }
    legs
}

/// Phase-to-neutral voltages with the switches off. Conducting phases sit at
/// their rail minus the neutral; an open phase's voltage equals its EMF, so
/// its current stays zero. The result sums to zero for a balanced EMF.
pub fn diode_phase_voltages(legs: [Leg; 3], e_abc: [f64; 3], bus_v: f64) -> [f64; 3] {
    if legs.iter().all(|l| *l == Leg::Open) {
        return e_abc;
    }
    let neutral = neutral_voltage(legs, e_abc, bus_v);
    let mut u = e_abc;
    for k in 0..3 {
        if let Some(v) = rail(legs[k], bus_v) {
            u[k] = v - neutral;
        }
    }
    u
}

/// After a step with the switches off: a diode cannot carry reverse current,
/// so a phase whose current went against its leg (or an open phase that
/// drifted) is set to zero, its current shared equally by the other two
/// (the projection that keeps the sum zero). Two or more blocked → all zero.
/// Returns the corrected currents.
pub fn enforce_blocking(legs: [Leg; 3], i_abc: [f64; 3]) -> [f64; 3] {
    let blocked: [bool; 3] = std::array::from_fn(|k| match legs[k] {
        Leg::Low => i_abc[k] < 0.0,
        Leg::High => i_abc[k] > 0.0,
        Leg::Open => true,
    });
    match blocked.iter().filter(|b| **b).count() {
        0 => i_abc,
        1 => {
            let k = blocked.iter().position(|b| *b).unwrap_or(0);
            let share = 0.5 * i_abc[k];
            let mut out = i_abc;
            for (j, v) in out.iter_mut().enumerate() {
                *v = if j == k { 0.0 } else { *v + share };
            }
            out
        }
        _ => [0.0; 3],
    }
}

/// Neutral-point voltage: with balanced R and L and the open phases carrying
/// no current, summing the conducting phases' equations gives
/// `v_n = mean over conducting phases of (v_x − e_x)`.
fn neutral_voltage(legs: [Leg; 3], e_abc: [f64; 3], bus_v: f64) -> f64 {
    let mut sum = 0.0;
    let mut n = 0.0;
    for k in 0..3 {
        if let Some(v) = rail(legs[k], bus_v) {
            sum += v - e_abc[k];
            n += 1.0;
        }
    }
    if n > 0.0 { sum / n } else { 0.0 }
}

fn rail(leg: Leg, bus_v: f64) -> Option<f64> {
    match leg {
        Leg::Low => Some(0.0),
        Leg::High => Some(bus_v),
        Leg::Open => None,
    }
}

fn extremes(e: [f64; 3]) -> (usize, usize) {
    let mut hi = 0;
    let mut lo = 0;
    for k in 1..3 {
        if e[k] > e[hi] {
            hi = k;
        }
        if e[k] < e[lo] {
            lo = k;
        }
    }
    (hi, lo)
}

/// d-q voltages for a drive mode at electrical angle θ_e (given as sin, cos)
/// and PM back-EMF `e_abc`.
#[inline]
pub fn dq_voltages(drive: &Drive, bus_v: f64, e_abc: [f64; 3], sin_e: f64, cos_e: f64) -> (f64, f64) {
    frames::abc_to_dq(phase_voltages(drive, bus_v, e_abc), sin_e, cos_e)
}

/// Phase-to-neutral voltages for a drive mode (for the state record).
pub fn phase_voltages(drive: &Drive, bus_v: f64, e_abc: [f64; 3]) -> [f64; 3] {
    phase_voltages_open(drive, bus_v, e_abc, None)
}

/// `phase_voltages` with an optional disconnected phase. With the switches
/// off the open phase is already `Leg::Open` in the diode pattern.
pub fn phase_voltages_open(drive: &Drive, bus_v: f64, e_abc: [f64; 3], open: Option<usize>) -> [f64; 3] {
    match (drive, open) {
        (Drive::Pwm(duty), None) => pwm_phase_voltages(*duty, bus_v),
        (Drive::Pwm(duty), Some(k)) => pwm_phase_voltages_open(*duty, bus_v, e_abc, k),
        (Drive::Diodes(legs), _) => diode_phase_voltages(*legs, e_abc, bus_v),
    }
}

/// Duties that make the averaged inverter apply d-q voltages `(u_d, u_q)`
/// at electrical angle `θ_e` (sinusoidal modulation centred on 50 %). Not
/// clamped: the caller sees a value outside [0, 1] if it asks too much.
pub fn duties_for_dq(u_d: f64, u_q: f64, theta_e: f64, bus_v: f64) -> [f64; 3] {
    let (sin_e, cos_e) = theta_e.sin_cos();
    frames::dq_to_abc(u_d, u_q, sin_e, cos_e).map(|u| 0.5 + u / bus_v)
}
