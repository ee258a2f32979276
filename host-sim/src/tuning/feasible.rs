//! What the proposal can promise: each loop's design for the asked
//! bandwidth and overshoot, or a refusal that names the limit (the rod's
//! axial mode, the screw's torsional mode, the regulator's structure) and
//! the highest ask this rig carries (docs/tuning.md, "Design rules").

use super::design::{self, DesignPlant, Margins};
use super::measure::overshoot_tolerance_pct;
use super::model::{self, Gains, StepKind};
use super::Asked;
use anyhow::{bail, Result};
use std::sync::atomic::{AtomicBool, Ordering};

/// Least gain margin and largest sensitivity peak a proposal may have on
/// the design model (with the rod's mode): 6 dB each, the usual robustness
/// floor (a modulus margin of 0.5).
pub const GAIN_MARGIN_MIN_DB: f64 = 6.0;
pub const SENSITIVITY_PEAK_MAX_DB: f64 = 6.0;

/// Highest current-loop bandwidth as a share of the drive train's mode
/// that the q current loop sees through the back-EMF (docs/tuning.md,
/// "Limits"): near the mode the closed loop's gain dips 2–4 dB below its
/// model and the −3 dB falls there.
pub const CURRENT_BW_PER_MODE: f64 = 0.7;

/// That mode (coupling + screw twist) on the nominal rig at the bench's
/// 250 mm, Hz: the dip of the q current loop's measured gain against its
/// model (440–500 Hz, `tune bench --unchecked`, the 1 kHz ask). Measured on
/// the simulator, not identified per rig or position (≈370 Hz at full
/// extension).
pub const DRIVE_TRAIN_MODE_HZ: f64 = 450.0;

static ENFORCED: AtomicBool = AtomicBool::new(true);

/// Diagnostic switch (`tune bench --unchecked`): off, the limits below do not
/// refuse (a design that exists is still proposed).
pub fn set_enforced(on: bool) {
    ENFORCED.store(on, Ordering::Relaxed);
}

fn enforced() -> bool {
    ENFORCED.load(Ordering::Relaxed)
}

fn overshoot(p: &DesignPlant, g: &Gains, kind: StepKind, dur: f64) -> f64 {
    model::design_overshoot_pct(p, g, kind, dur)
}

/// The current PI (pole-zero cancellation), if the ask is below the
/// torsional mode's limit and its overshoot is what that design gives.
pub fn current(p: &DesignPlant, a: &Asked) -> Result<(f64, f64, Margins, f64)> {
    let max = CURRENT_BW_PER_MODE * DRIVE_TRAIN_MODE_HZ;
    if enforced() && a.current_bw_hz > max {
        bail!(
            "current-loop bandwidth {} Hz refused: the drive train's torsional mode at ≈{DRIVE_TRAIN_MODE_HZ:.0} Hz (250 mm), seen through the back-EMF, dips the q loop's gain 2–4 dB there (a 1 kHz design measures 446 Hz); at most {max:.0} Hz (no notch on the current reference in this core)",
            a.current_bw_hz
        );
    }
    let (kp, ki, m, bw) = design::design_current(p, a.current_bw_hz)?;
    let os = overshoot(
        p,
        &Gains {
            current: (kp, ki),
            speed: (0.0, 0.0),
            position_kp: 0.0,
        },
        StepKind::Current,
        0.01,
    );
    if enforced()
        && (os - a.current_overshoot_pct).abs() > overshoot_tolerance_pct(a.current_overshoot_pct)
    {
        bail!(
            "current-loop overshoot {} % refused: the pole-zero current PI gives {os:.1} % at {} Hz, and this tool offers no other",
            a.current_overshoot_pct,
            a.current_bw_hz
        );
    }
    Ok((kp, ki, m, bw))
}

#[derive(Clone, Debug)]
pub struct SpeedDesign {
    pub kp: f64,
    pub ki: f64,
    pub weight: f64,
    pub margins: Margins,
    pub model_bw_hz: f64,
    pub model_overshoot_pct: f64,
}

fn robust(m: &Margins) -> bool {
    m.gain_margin_db.is_none_or(|g| g >= GAIN_MARGIN_MIN_DB)
        && m.sensitivity_peak_db <= SENSITIVITY_PEAK_MAX_DB
}

/// The speed PI for `bw_hz` at `pm_deg` with setpoint weight `b`.
fn speed_at(
    p: &DesignPlant,
    cur: (f64, f64),
    bw_hz: f64,
    pm_deg: f64,
    b: f64,
) -> Result<SpeedDesign> {
    let mut q = p.clone();
    q.speed_setpoint_weight = b;
    let (kp, ki, margins, model_bw_hz) = design::design_speed(&q, cur, bw_hz, pm_deg)?;
    let g = Gains {
        current: cur,
        speed: (kp, ki),
        position_kp: 0.0,
    };
    let model_overshoot_pct =
        overshoot(&q, &g, StepKind::Speed, model::speed_step_duration_s(bw_hz));
    Ok(SpeedDesign {
        kp,
        ki,
        weight: b,
        margins,
        model_bw_hz,
        model_overshoot_pct,
    })
}

/// Highest speed bandwidth (plain PI at `pm_deg`) that stays robust on the
/// design model, searched down from `from_hz`.
pub fn speed_bw_max_hz(p: &DesignPlant, cur: (f64, f64), from_hz: f64, pm_deg: f64) -> Option<f64> {
    let mut f = from_hz;
    while f > 0.5 {
        if speed_at(p, cur, f, pm_deg, 1.0).is_ok_and(|d| robust(&d.margins)) {
            return Some(f);
        }
        f *= 0.97;
    }
    None
}

/// The speed PI for the ask: crossover and PI zero for the bandwidth and
/// phase margin, the setpoint weight for the overshoot; refused when the
/// loop would not be robust on the model with the rod's mode.
pub fn speed(p: &DesignPlant, cur: (f64, f64), a: &Asked) -> Result<SpeedDesign> {
    let refuse = |why: String| -> anyhow::Error {
        let mode = p.rod_mode.map_or(String::new(), |m| {
            format!(
                " (the rod's axial mode: anti-resonance {:.1} Hz, resonance {:.1} Hz)",
                m.antiresonance_hz, m.resonance_hz
            )
        });
        let max = speed_bw_max_hz(p, cur, a.speed_bw_hz, a.phase_margin_deg)
            .map_or("none found".into(), |f| {
                format!("{f:.1} Hz at {}° of phase margin", a.phase_margin_deg)
            });
        anyhow::anyhow!(
            "speed-loop bandwidth {} Hz refused: {why}{mode}; the highest this rig carries: {max}",
            a.speed_bw_hz
        )
    };
    let plain = speed_at(p, cur, a.speed_bw_hz, a.phase_margin_deg, 1.0)
        .map_err(|e| refuse(format!("{e:#}")))?;
    if enforced() && !robust(&plain.margins) {
        return Err(refuse(format!(
            "gain margin {:.1} dB, sensitivity peak {:.1} dB on the design model (need ≥ {GAIN_MARGIN_MIN_DB} dB and ≤ {SENSITIVITY_PEAK_MAX_DB} dB)",
            plain.margins.gain_margin_db.unwrap_or(f64::INFINITY),
            plain.margins.sensitivity_peak_db
        )));
    }
    let Some(target) = a.speed_overshoot_pct else {
        return Ok(plain);
    };
    // Overshoot rises with b. The asked margin first, then the others of
    // 45…80° nearest to it first: the robust pair (margin, b) closest to
    // the asked margin. (Taking the least sensitivity peak instead drifted
    // to 80°, where the PI zero sits so far below crossover that its
    // integral no longer holds Coulomb friction: a 12 Hz loop with
    // ki 0.4 A/rad put the position loop behind it at −55 %.)
    let mut best: Option<SpeedDesign> = None;
    let mut range = (f64::INFINITY, 0.0f64);
    let mut others: Vec<f64> = (0..8).map(|k| 45.0 + 5.0 * k as f64).collect();
    others.sort_by(|x, y| (x - a.phase_margin_deg).abs().total_cmp(&(y - a.phase_margin_deg).abs()));
    let pms = std::iter::once(a.phase_margin_deg).chain(others);
    for pm in pms {
        let at = |b: f64| {
            speed_at(p, cur, a.speed_bw_hz, pm, b)
                .ok()
                .filter(|d| !enforced() || robust(&d.margins))
        };
        let grid: Vec<(f64, SpeedDesign)> = (0..=10)
            .filter_map(|k| at(0.2 * k as f64).map(|d| (0.2 * k as f64, d)))
            .collect();
        for g in &grid {
            range = (
                range.0.min(g.1.model_overshoot_pct),
                range.1.max(g.1.model_overshoot_pct),
            );
        }
        for w in grid.windows(2) {
            let (lo, hi) = (&w[0].1, &w[1].1);
            if (lo.model_overshoot_pct - target) * (hi.model_overshoot_pct - target) > 0.0 {
                continue;
            }
            let rising = hi.model_overshoot_pct >= lo.model_overshoot_pct;
            let (mut bl, mut bh) = (w[0].0, w[1].0);
            // The closest design to the ask seen while bisecting.
            let mut d = if (lo.model_overshoot_pct - target).abs() < (hi.model_overshoot_pct - target).abs() {
                lo.clone()
            } else {
                hi.clone()
            };
            for _ in 0..12 {
                let mid = 0.5 * (bl + bh);
                let Some(m) = at(mid) else { break };
                if (m.model_overshoot_pct < target) == rising {
                    bl = mid;
                } else {
                    bh = mid;
                }
                if (m.model_overshoot_pct - target).abs() < (d.model_overshoot_pct - target).abs() {
                    d = m;
                }
            }
            let close = (d.model_overshoot_pct - target).abs() <= 0.1 * overshoot_tolerance_pct(target);
            if close && best.as_ref().is_none_or(|b| d.margins.sensitivity_peak_db < b.margins.sensitivity_peak_db) {
                best = Some(d);
            }
            if close {
                break;
            }
        }
        if best.is_some() {
            break;
        }
    }
    best.ok_or_else(|| {
        anyhow::anyhow!(
            "speed-loop overshoot {target} % refused at {} Hz: robust designs (phase margin 45…80°, setpoint weight 0…2) give {:.1}…{:.1} %",
            a.speed_bw_hz,
            range.0,
            range.1
        )
    })
}

/// The position P for the ask; its overshoot is set by its bandwidth against
/// the speed loop's, so an overshoot ask must be what that gives.
pub fn position(
    p: &DesignPlant,
    cur: (f64, f64),
    spd: (f64, f64),
    a: &Asked,
) -> Result<(f64, Margins, f64)> {
    if enforced() && a.position_bw_hz > 0.35 * a.speed_bw_hz {
        bail!(
            "position-loop bandwidth {} Hz refused: a P position loop needs its speed loop ≥ 3× faster (speed {} Hz)",
            a.position_bw_hz,
            a.speed_bw_hz
        );
    }
    let (k, m, bw) = design::design_position(p, cur, spd, a.position_bw_hz)?;
    let g = Gains {
        current: cur,
        speed: spd,
        position_kp: k,
    };
    let os = overshoot(
        p,
        &g,
        StepKind::Position,
        model::position_step_duration_s(a.position_bw_hz),
    );
    if enforced()
        && (os - a.position_overshoot_pct).abs() > overshoot_tolerance_pct(a.position_overshoot_pct)
    {
        bail!(
            "position-loop overshoot {} % refused: the P loop at {} Hz gives {os:.1} % (set by its bandwidth against the speed loop's)",
            a.position_overshoot_pct,
            a.position_bw_hz
        );
    }
    Ok((k, m, bw))
}
