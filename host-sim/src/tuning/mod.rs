//! Tuning from identification (issue 11, items 7 and 8): identify the
//! mechanics and the winding from captures, propose gains for asked
//! bandwidths and phase margin, check them on the full plant before they
//! go to a drive. `host-sim tune …`; docs/tuning.md.


pub mod design;
pub mod identify;
pub mod model;
pub mod simcheck;
pub mod cli;

use crate::config::RigConfig;
use crate::diagnose::residual::Physics;
use anyhow::{anyhow, Result};
use design::{DesignPlant, LoopDesign, RodMode};
use identify::{Capture, ElecId, MechId, MechOptions};
use model::{Gains, StepKind};
use servo_core::ControlParams;
use simcheck::{Loop, TestFigures, TestSpec};

/// Where the simulated tests run: the rod at mid-stroke under the rated
/// vertical load (as `drive serve --commissioned`).
pub const X0_M: f64 = 0.25;

/// What `tune identify` found (its JSON).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Identified {
    pub inertia_kg_m2: f64,
    pub viscous_n_m_s_rad: f64,
    pub coulomb_n_m: Option<f64>,
    pub load_n_m: f64,
    pub resistance_ohm: Option<f64>,
    pub inductance_h: Option<f64>,
    pub flux_linkage_wb: Option<f64>,
    /// The full fits (estimates, standard errors, residuals).
    pub mechanics: serde_json::Value,
    pub electrical: Option<serde_json::Value>,
}

impl Identified {
    pub fn from_fits(m: &MechId, e: Option<&ElecId>) -> Self {
        Identified {
            inertia_kg_m2: m.inertia_kg_m2.value,
            viscous_n_m_s_rad: m.viscous_n_m_s_rad.value,
            coulomb_n_m: m.coulomb_n_m.as_ref().map(|c| c.value),
            load_n_m: m.load_n_m.value,
            resistance_ohm: e.map(|e| e.resistance_ohm.value),
            inductance_h: e.map(|e| e.inductance_h.value),
            flux_linkage_wb: e.and_then(|e| e.flux_linkage_wb.as_ref().map(|f| f.value)),
            mechanics: serde_json::to_value(m).unwrap_or_default(),
            electrical: e.map(|e| serde_json::to_value(e).unwrap_or_default()),
        }
    }
}

/// Runs the identification experiments on the simulated rig with the
/// drive's present parameters: speed steps ±`amp` rad/s (two amplitudes)
/// and a q-current step, each captured as `host-sim drive step` captures
/// it. Returns the captures (speed steps, current step).
pub fn simulate_identification_captures(rig: &RigConfig, seed: u64) -> Result<(Vec<Capture>, Capture)> {
    let mut cl = simcheck::holding(rig, rig.control, X0_M, seed)?;
    let mut speed = Vec::new();
    for (i, a) in [20.0, -20.0, 50.0, -50.0].into_iter().enumerate() {
        let c = simcheck::run_test(&mut cl, &TestSpec::step(Loop::Speed, a, 0.25))?;
        let mut cap = c.capture;
        cap.source = format!("simulated speed step {a:+} rad/s #{i}");
        speed.push(cap);
    }
    let c = simcheck::run_test(&mut cl, &TestSpec::step(Loop::Current, 8.0, 0.02))?;
    let mut cur = c.capture;
    cur.source = "simulated q-current step 8 A".into();
    Ok((speed, cur))
}

/// Corner of the zero-phase low-pass on the current-step sequences.
pub const ELECTRICAL_FILTER_HZ: f64 = 2000.0;

pub fn identify(speed: &[Capture], current: Option<&Capture>, control: &ControlParams) -> Result<(MechId, Option<ElecId>)> {
    let kt = f64::from(control.torque_constant_n_m_a());
    let mech = identify::identify_mechanics(speed, kt, f64::from(control.metres_per_rad()), &MechOptions::default())?;
    let elec = match current {
        Some(c) => Some(identify::identify_electrical(c, f64::from(control.motor.pole_pairs), f64::from(control.pwm_period_s()), ELECTRICAL_FILTER_HZ)?),
        None => None,
    };
    Ok((mech, elec))
}

/// What is asked of the loops.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct Asked {
    pub current_bw_hz: f64,
    pub speed_bw_hz: f64,
    pub phase_margin_deg: f64,
    pub position_bw_hz: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Proposal {
    pub asked: Asked,
    pub plant: DesignPlant,
    pub current: LoopDesign,
    pub speed: LoopDesign,
    pub position: LoopDesign,
    /// The rod's axial mode at the test position (nominal rig), for the
    /// record: the design model is rigid unless `with_rod_mode`.
    pub rod_mode: RodMode,
    #[serde(skip)]
    pub params: ControlParams,
}

/// The nominal axial mode of the rig at `x` under its vertical load.
pub fn rod_mode(rig: &RigConfig, x: f64) -> RodMode {
    let ph = Physics::from_rig(rig);
    let load = ph.m_moving * ph.gravity;
    let c = ph.local_compliance(load, x);
    RodMode::new(1.0 / c, ph.axial_damping_n_s_m, ph.m_moving, ph.j_eq(), ph.j_rot)
}

/// Proposes the gains. `ident` (else the parameters' own beliefs) gives
/// the inertia, friction and winding; `with_rod_mode` designs the speed
/// loop on the two-mass model instead of the rigid one.
pub fn propose(rig: &RigConfig, ident: Option<&Identified>, asked: Asked, with_rod_mode: bool) -> Result<Proposal> {
    let base = rig.control;
    let j = ident.map_or(f64::from(base.reflected_inertia_kg_m2()), |i| i.inertia_kg_m2);
    let b = ident.map_or(f64::from(base.drive_train.viscous_friction_n_m_s_rad), |i| i.viscous_n_m_s_rad.max(0.0));
    let mut plant = DesignPlant::from_params(&base, j, b);
    if let Some(r) = ident.and_then(|i| i.resistance_ohm) {
        plant.r_ohm = r;
    }
    if let Some(l) = ident.and_then(|i| i.inductance_h) {
        plant.l_h = l;
    }
    let mode = rod_mode(rig, X0_M);
    if with_rod_mode {
        plant.rod_mode = Some(mode);
    }
    let (ckp, cki, cm, cbw) = design::design_current(&plant, asked.current_bw_hz)?;
    let cur = (ckp, cki);
    let (skp, ski, sm, sbw) = design::design_speed(&plant, cur, asked.speed_bw_hz, asked.phase_margin_deg)?;
    let spd = (skp, ski);
    let (pkp, pm, pbw) = design::design_position(&plant, cur, spd, asked.position_bw_hz)?;
    let gains = Gains { current: cur, speed: spd, position_kp: pkp };
    let os = |kind, dur| model::overshoot_pct(&model::step_response(&plant, &gains, kind, 1.0, dur), 1.0);
    let mut p = base;
    p.current_pi.kp = ckp as f32;
    p.current_pi.ki = cki as f32;
    p.speed_pi.kp = skp as f32;
    p.speed_pi.ki = ski as f32;
    p.position_kp_per_s = pkp as f32;
    if let Some(i) = ident {
        // The feedforwards believe the identified mechanics: the rotating
        // share is what is left after the moving mass's reflection; the
        // load-independent Coulomb share after the screw's efficiency law
        // under the identified load.
        let k = f64::from(base.metres_per_rad());
        let reflected = f64::from(base.drive_train.moving_mass_kg) * k * k;
        p.drive_train.rotating_inertia_kg_m2 = (i.inertia_kg_m2 - reflected).max(0.0) as f32;
        p.drive_train.viscous_friction_n_m_s_rad = i.viscous_n_m_s_rad.max(0.0) as f32;
        if let Some(tc) = i.coulomb_n_m {
            let eta = f64::from(base.drive_train.screw_efficiency);
            let screw = k * (1.0 - eta) / eta * (i.load_n_m / k).abs();
            p.drive_train.coulomb_friction_n_m = (tc - screw).max(0.0) as f32;
        }
        if let Some(r) = i.resistance_ohm {
            p.motor.phase_resistance_ohm = r as f32;
        }
        if let Some(l) = i.inductance_h {
            p.motor.inductance_q_h = l as f32;
            p.motor.inductance_d_h = l as f32;
        }
    }
    p.validate().map_err(|e| anyhow!("the proposal does not validate: {e:?}"))?;
    let current = LoopDesign {
        kp: ckp,
        ki: cki,
        asked_bandwidth_hz: asked.current_bw_hz,
        asked_phase_margin_deg: None,
        model_bandwidth_hz: cbw,
        margins: cm,
        model_overshoot_pct: os(StepKind::Current, 0.01),
        rule: "pole-zero cancellation kp = L ω_c, ki = R ω_c on the sampled loop (one period of computation + the PWM update); ω_c solved for the asked −3 dB frequency".into(),
    };
    let speed = LoopDesign {
        kp: skp,
        ki: ski,
        asked_bandwidth_hz: asked.speed_bw_hz,
        asked_phase_margin_deg: Some(asked.phase_margin_deg),
        model_bandwidth_hz: sbw,
        margins: sm,
        model_overshoot_pct: os(StepKind::Speed, 0.3),
        rule: format!(
            "loop shaping at crossover on K_t/(J s + B) (J = {j:.4e} kg·m²{}) × closed current loop × torque filter ({} Hz) × speed hold × encoder PLL: PI zero for the asked phase margin, kp for |L| = 1, crossover solved for the asked −3 dB frequency",
            if with_rod_mode { ", with the rod's axial mode" } else { ", rigid" },
            plant.torque_filter_hz
        ),
    };
    let position = LoopDesign {
        kp: pkp,
        ki: 0.0,
        asked_bandwidth_hz: asked.position_bw_hz,
        asked_phase_margin_deg: None,
        model_bandwidth_hz: pbw,
        margins: pm,
        model_overshoot_pct: os(StepKind::Position, 1.0),
        rule: "P on K_p T_ω(s)/s through the 1 kHz hold; K_p solved for the asked −3 dB frequency".into(),
    };
    Ok(Proposal { asked, plant, current, speed, position, rod_mode: mode, params: p })
}

/// The `[control]` fragment of a proposal: the gains and what the
/// feedforwards believe.
pub fn control_fragment(p: &ControlParams) -> String {
    let d = &p.drive_train;
    format!(
        "# Proposed by `host-sim tune propose`; paste into the rig's [control] or apply with `drive param set`.\n\
         [control]\ntorque_filter_hz = {}\nposition_kp_per_s = {}\n\n\
         [control.current_pi]\nkp = {}\nki = {}\n\n\
         [control.speed_pi]\nkp = {}\nki = {}\n\n\
         [control.motor]\nphase_resistance_ohm = {}\ninductance_d_h = {}\ninductance_q_h = {}\n\n\
         [control.drive_train]\nrotating_inertia_kg_m2 = {}\nviscous_friction_n_m_s_rad = {}\ncoulomb_friction_n_m = {}\n",
        p.torque_filter_hz,
        p.position_kp_per_s,
        p.current_pi.kp,
        p.current_pi.ki,
        p.speed_pi.kp,
        p.speed_pi.ki,
        p.motor.phase_resistance_ohm,
        p.motor.inductance_d_h,
        p.motor.inductance_q_h,
        d.rotating_inertia_kg_m2,
        d.viscous_friction_n_m_s_rad,
        d.coulomb_friction_n_m
    )
}

/// The `drive param set` lines that apply a proposal.
pub fn param_set_lines(p: &ControlParams) -> Vec<(String, f32)> {
    vec![
        ("current_pi.kp".into(), p.current_pi.kp),
        ("current_pi.ki".into(), p.current_pi.ki),
        ("speed_pi.kp".into(), p.speed_pi.kp),
        ("speed_pi.ki".into(), p.speed_pi.ki),
        ("torque_filter_hz".into(), p.torque_filter_hz),
        ("position_kp_per_s".into(), p.position_kp_per_s),
        ("drive_train.rotating_inertia_kg_m2".into(), p.drive_train.rotating_inertia_kg_m2),
        ("drive_train.viscous_friction_n_m_s_rad".into(), p.drive_train.viscous_friction_n_m_s_rad),
        ("drive_train.coulomb_friction_n_m".into(), p.drive_train.coulomb_friction_n_m),
    ]
}

/// The check's tests: a step and a chirp per loop.
pub fn check_specs(asked: &Asked) -> Vec<(Loop, TestSpec)> {
    let cur_to = (4.0 * asked.current_bw_hz).min(4000.0);
    let spd_to = (5.0 * asked.speed_bw_hz).min(1000.0);
    let pos_to = (5.0 * asked.position_bw_hz).min(100.0);
    let dec = |to: f64, dur: f64, signals: f64| -> u16 {
        // Finest sampling the store allows for the duration, at least
        // 2.5 × the end frequency.
        let fit = (1.1 * dur * 20_000.0 / (4096.0 / signals)).ceil() as u16;
        let need = (20_000.0 / (2.5 * to)).floor() as u16;
        fit.max(1).min(need.max(1))
    };
    let cur_dur = 0.2;
    let spd_dur = 2.0;
    let pos_dur = 3.6;
    vec![
        (Loop::Current, TestSpec::step(Loop::Current, 4.0, 0.02)),
        (Loop::Current, TestSpec::chirp(Loop::Current, 2.0, 50.0, cur_to, cur_dur, dec(cur_to, cur_dur, 2.0))),
        (Loop::Speed, TestSpec::step(Loop::Speed, 10.0, 0.25)),
        (Loop::Speed, TestSpec::chirp(Loop::Speed, 30.0, 5.0, spd_to, spd_dur, dec(spd_to, spd_dur, 2.0))),
        (Loop::Position, TestSpec::step(Loop::Position, 0.001, 0.5)),
        (Loop::Position, TestSpec::chirp(Loop::Position, 0.0005, 0.5, pos_to, pos_dur, dec(pos_to, pos_dur, 2.0))),
    ]
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct CheckResult {
    pub target: Loop,
    pub spec: TestSpec,
    pub figures: TestFigures,
    #[serde(skip)]
    pub captured: simcheck::Captured,
}

/// Runs the check's tests on the simulated rig with `params`.
pub fn check(rig: &RigConfig, params: ControlParams, asked: &Asked, seed: u64) -> Result<Vec<CheckResult>> {
    let mut cl = simcheck::holding(rig, params, X0_M, seed)?;
    let mut out = Vec::new();
    for (target, spec) in check_specs(asked) {
        let c = simcheck::run_test(&mut cl, &spec).map_err(|e| anyhow!("{target:?} {:?}: {e:#}", spec.chirp))?;
        out.push(CheckResult { target, figures: simcheck::figures(&spec, &c), spec, captured: c });
    }
    Ok(out)
}
