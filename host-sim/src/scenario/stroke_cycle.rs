//! The paper's experiment (§5.2) as a scenario: elongation 0 → 450 mm while the
//! tilt goes 90° → 60° → 90°, a dwell, then contraction 450 → 0 mm with
//! 90° → 120° → 90°, under rated load. The tilt follows the reference
//! position (the "single-cycle saddle"), so it is the same function of stroke
//! whatever the speed. Parameterised so the observer's datasets can sweep
//! tilt swings and payloads with the same code.

use crate::config::RigConfig;
use crate::plant::Plant;
use crate::sim::{ClosedLoop, TruthRecord};
use anyhow::{bail, Result};
use servo_core::{Command, CommandOutcome, Controller, Telemetry};
use std::f64::consts::PI;
use std::time::Instant;

/// Which leg of the cycle a record belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Direction {
    /// Standing still (settling or dwelling).
    Hold,
    Elongation,
    Contraction,
}

/// One elongation–contraction cycle.
#[derive(Clone, Debug)]
pub struct StrokeCycle {
    /// Where both legs turn round, metres (paper: 0.45).
    pub top_m: f64,
    /// Tilt departs from 90° by this much mid-stroke (paper: 30°): down to
    /// 60° on elongation, up to 120° on contraction.
    pub tilt_swing_deg: f64,
    /// Multiplies the plant's payload mass (1.0 = rated load).
    pub payload_scale: f64,
    /// Standing time before the first move and after each leg.
    pub settle_s: f64,
    pub dwell_s: f64,
    pub seed: u64,
    /// Switch the observer's terminal-error compensation on after enabling.
    pub compensation: bool,
}

impl StrokeCycle {
    /// The paper's run at rated load.
    pub fn paper(seed: u64) -> Self {
        Self { top_m: 0.45, tilt_swing_deg: 30.0, payload_scale: 1.0, settle_s: 0.5, dwell_s: 0.5, seed, compensation: false }
    }

    /// Tilt from horizontal, degrees, for a reference position on a leg.
    pub fn tilt_deg(&self, direction: Direction, reference_m: f64) -> f64 {
        let s = (reference_m / self.top_m).clamp(0.0, 1.0);
        match direction {
            Direction::Hold => 90.0,
            Direction::Elongation => 90.0 - self.tilt_swing_deg * (PI * s).sin(),
            Direction::Contraction => 90.0 + self.tilt_swing_deg * (PI * s).sin(),
        }
    }
}

/// Everything one run recorded at the position-loop rate.
#[derive(Clone, Debug)]
pub struct RunTrace {
    pub telemetry: Vec<Telemetry>,
    pub truth: Vec<TruthRecord>,
    pub direction: Vec<Direction>,
    pub simulated_s: f64,
    pub wall_s: f64,
    /// Why the run stopped early (a latched fault, a stuck leg), if it did.
    /// The trace up to that point is kept so it can be looked at.
    pub aborted: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Leg {
    Settle,
    Elongation,
    DwellTop,
    Contraction,
    DwellBottom,
}

/// Runs one cycle closed-loop through the control core.
pub fn run_stroke_cycle(rig: &RigConfig, cycle: &StrokeCycle) -> Result<RunTrace> {
    run_stroke_cycle_with(rig, cycle, None)
}

/// [`run_stroke_cycle`] with the observer running `weights` (as uploaded
/// to a drive) instead of the compiled model.
pub fn run_stroke_cycle_with(
    rig: &RigConfig,
    cycle: &StrokeCycle,
    weights: Option<&'static servo_core::observer::block::Weights>,
) -> Result<RunTrace> {
    let mut scaled = rig.clone();
    scaled.plant.rod.payload_mass_kg *= cycle.payload_scale;
    scaled.validate().map_err(|e| anyhow::anyhow!("payload ×{}: {e}", cycle.payload_scale))?;
    let mut plant = Plant::try_new(scaled.plant, cycle.seed).map_err(|e| anyhow::anyhow!("payload ×{}: {e}", cycle.payload_scale))?;
    plant.set_initial_state(0.0, 90f64.to_radians());
    let controller =
        Controller::try_new(crate::sim::commissioned_control(rig.control, &plant)).map_err(|e| anyhow::anyhow!("rig: {e}"))?;
    let bus = rig.plant.inverter.nominal_bus_voltage_v;
    let mut cl = ClosedLoop::new(controller, plant, bus);
    if let Err(e) = cl.controller.command(Command::Enable) {
        bail!("the drive refused to enable: {e:?}");
    }
    if let Some(weights) = weights {
        if let Err(e) = cl.controller.command(Command::SetObserverWeights { weights }) {
            bail!("the drive refused the observer weights: {e:?}");
        }
    }
    if let Err(e) = cl.controller.command(Command::SetCompensation { enabled: cycle.compensation }) {
        bail!("the drive refused to switch compensation: {e:?}");
    }

    let divider = u64::from(rig.control.rates.position_loop_divider);
    let started = Instant::now();
    let mut trace =
        RunTrace { telemetry: vec![], truth: vec![], direction: vec![], simulated_s: 0.0, wall_s: 0.0, aborted: None };
    let mut leg = Leg::Settle;
    let mut leg_start_s = 0.0;
    // A generous bound: a leg that never finishes is a failure, not a hang.
    let max_s = cycle.settle_s + 2.0 * cycle.dwell_s + 4.0 * (cycle.top_m / 0.05 + 5.0);
    loop {
        let tel = cl.step();
        if !cl.periods().is_multiple_of(divider) {
            continue;
        }
        let t = cl.time_s();
        let moving = cl.controller.move_in_progress();
        let direction = match leg {
            Leg::Elongation => Direction::Elongation,
            Leg::Contraction => Direction::Contraction,
            _ => Direction::Hold,
        };
        let tilt_deg = cycle.tilt_deg(direction, f64::from(tel.position_reference_m));
        cl.plant.set_tilt_rad(tilt_deg.to_radians());
        trace.telemetry.push(tel);
        trace.truth.push(cl.truth(direction, tilt_deg, 0.0));
        trace.direction.push(direction);
        if !tel.faults.is_empty() {
            trace.aborted = Some(format!("fault {:?} latched at t = {t:.3} s during {leg:?}", tel.faults));
            break;
        }
        let next = match leg {
            Leg::Settle if t - leg_start_s >= cycle.settle_s => Some((Leg::Elongation, Some(cycle.top_m))),
            Leg::Elongation if !moving => Some((Leg::DwellTop, None)),
            Leg::DwellTop if t - leg_start_s >= cycle.dwell_s => Some((Leg::Contraction, Some(0.0))),
            Leg::Contraction if !moving => Some((Leg::DwellBottom, None)),
            Leg::DwellBottom if t - leg_start_s >= cycle.dwell_s => break,
            _ => None,
        };
        if let Some((new_leg, target)) = next {
            if let Some(x) = target {
                match cl.controller.command(Command::MoveTo { position_m: x as f32 }) {
                    Ok(CommandOutcome::Accepted) => {}
                    Ok(other) => bail!("move to {x} m was bounded: {other:?}"),
                    Err(e) => bail!("move to {x} m refused: {e:?}"),
                }
            }
            leg = new_leg;
            leg_start_s = t;
        }
        if t > max_s {
            trace.aborted = Some(format!("the cycle did not finish within {max_s:.1} s (stuck in {leg:?})"));
            break;
        }
    }
    trace.simulated_s = cl.time_s();
    trace.wall_s = started.elapsed().as_secs_f64();
    Ok(trace)
}
