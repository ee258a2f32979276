//! Tuning from identification: identify the
//! mechanics and the winding from captures, propose gains for asked
//! bandwidths and phase margin, check them on the full plant before they
//! go to a drive. `host-sim tune …`; docs/tuning.md.


pub mod cli;
pub mod design;
pub mod family;
pub mod feasible;
pub mod filter;
pub mod identify;
pub mod measure;
pub mod model;
pub mod simcheck;

use crate::config::RigConfig;
use crate::diagnose::residual::Physics;
use anyhow::{anyhow, Context, Result};
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

impl Identified {
    /// The mechanics in the unit's own torque: the fits turn current into
    /// torque with the drive's torque constant (`1.5 p ψ` of its belief),
    /// so with an identified ψ every torque-scaled quantity is rescaled by
    /// `ψ/ψ_belief`, and the flux is the identified one. Without an
    /// identified ψ, unchanged.
    pub fn in_unit_torque(&self, flux_belief_wb: f64) -> Identified {
        let Some(psi) = self.flux_linkage_wb.filter(|f| f.is_finite() && *f > 0.0 && flux_belief_wb > 0.0) else {
            return self.clone();
        };
        let s = psi / flux_belief_wb;
        Identified {
            inertia_kg_m2: self.inertia_kg_m2 * s,
            viscous_n_m_s_rad: self.viscous_n_m_s_rad * s,
            coulomb_n_m: self.coulomb_n_m.map(|c| c * s),
            load_n_m: self.load_n_m * s,
            ..self.clone()
        }
    }
}

/// Runs the identification experiments on the simulated rig with the
/// drive's present parameters: speed steps ±`amp` rad/s (two amplitudes)
/// and a q-current step, each captured as `host-sim drive step` captures
/// it. Returns the captures (speed steps, current step).
pub fn simulate_identification_captures(rig: &RigConfig, seed: u64) -> Result<(Vec<Capture>, Capture)> {
    let mut cl = simcheck::holding(rig, rig.control, X0_M, seed)?;
    // The winding from a d-axis current step: no torque, so the rotor
    // stands and no back-EMF enters the voltage. A q step accelerates the
    // rotor, and R then trades against ψ unless a hold current at
    // standstill gives it (none on a lightly loaded unit: R came out 24 %
    // high holding 6 kg).
    let c = simcheck::run_test(&mut cl, &TestSpec::current_step_d(8.0, 0.02)).context("identification, d-current step 8 A")?;
    let mut cur = c.capture;
    cur.source = "simulated d-current step 8 A".into();
    let mut speed = Vec::new();
    for (i, a) in [20.0, -20.0, 50.0, -50.0].into_iter().enumerate() {
        // The q voltage instead of the position (the speed is captured):
        // it carries the back-EMF, hence the magnets' flux.
        let spec = TestSpec { signals: vec!["speed_reference", "speed", "current_q", "voltage_q"], ..TestSpec::step(Loop::Speed, a, 0.25) };
        let c = simcheck::run_test(&mut cl, &spec).with_context(|| format!("identification, speed step {a:+} rad/s"))?;
        let mut cap = c.capture;
        cap.source = format!("simulated speed step {a:+} rad/s #{i}");
        speed.push(cap);
    }
    Ok((speed, cur))
}

/// How much the check widens the following-error bound for its own tests
/// (on a drive: `param set faults.position_following_error_m` to this
/// multiple for the tests, back after).
pub const TEST_FOLLOWING_ERROR_FACTOR: f32 = 2.0;

/// Corner of the zero-phase low-pass on the current-step sequences.
pub const ELECTRICAL_FILTER_HZ: f64 = 2000.0;

pub fn identify(speed: &[Capture], current: Option<&Capture>, control: &ControlParams) -> Result<(MechId, Option<ElecId>)> {
    let kt = f64::from(control.torque_constant_n_m_a());
    let mech = identify::identify_mechanics(speed, kt, f64::from(control.metres_per_rad()), &MechOptions::default())?;
    let mut elec = match current {
        Some(c) => Some(identify::identify_electrical(c, f64::from(control.motor.pole_pairs), f64::from(control.pwm_period_s()), ELECTRICAL_FILTER_HZ)?),
        None => None,
    };
    // With R and L from the d step, the speed steps' q voltage gives ψ.
    if let Some(e) = elec.as_mut().filter(|e| e.axis == "d") {
        e.flux_linkage_wb = identify::identify_flux(speed, f64::from(control.motor.pole_pairs), e.resistance_ohm.value, e.inductance_h.value)?;
    }
    Ok((mech, elec))
}

/// What is asked of the loops: a bandwidth and an overshoot each (the
/// speed loop also a phase margin; its overshoot, when given, is met by the
/// setpoint weight `control.speed_setpoint_weight`).
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct Asked {
    pub current_bw_hz: f64,
    #[serde(default)]
    pub current_overshoot_pct: f64,
    pub speed_bw_hz: f64,
    pub phase_margin_deg: f64,
    /// None: a plain PI (weight 1), whatever overshoot that gives.
    #[serde(default)]
    pub speed_overshoot_pct: Option<f64>,
    pub position_bw_hz: f64,
    #[serde(default)]
    pub position_overshoot_pct: f64,
}

impl Asked {
    pub fn new(current_bw_hz: f64, speed_bw_hz: f64, phase_margin_deg: f64, position_bw_hz: f64) -> Self {
        Asked {
            current_bw_hz,
            current_overshoot_pct: 0.0,
            speed_bw_hz,
            phase_margin_deg,
            speed_overshoot_pct: None,
            position_bw_hz,
            position_overshoot_pct: 0.0,
        }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Proposal {
    pub asked: Asked,
    pub plant: DesignPlant,
    pub current: LoopDesign,
    pub speed: LoopDesign,
    pub position: LoopDesign,
    /// The speed PI's setpoint weight.
    pub speed_setpoint_weight: f64,
    /// The rod's axial mode at the test position (nominal rig); in the
    /// design model unless `rigid`.
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

/// Proposes the gains, or refuses the ask with the reason
/// (`feasible`). `ident` (else the parameters' own beliefs) gives the
/// inertia, friction and winding; the design model carries the rod's axial
/// mode unless `rigid`.
pub fn propose(rig: &RigConfig, ident: Option<&Identified>, asked: Asked, rigid: bool) -> Result<Proposal> {
    let mut base = rig.control;
    // The unit's own flux, when identified: the drive's torque constant and
    // back-EMF feedforward follow it (a unit with 9.5 % less flux than the
    // drive believed read 2.99 % for a 5 % speed overshoot ask, 5.17 % with
    // the believed flux in the plant), and the mechanics are rescaled to it.
    let unit = ident.map(|i| i.in_unit_torque(f64::from(base.motor.flux_linkage_wb)));
    let ident = unit.as_ref();
    if let Some(f) = ident.and_then(|i| i.flux_linkage_wb) {
        base.motor.flux_linkage_wb = f as f32;
    }
    let j = ident.map_or(f64::from(base.reflected_inertia_kg_m2()), |i| i.inertia_kg_m2);
    let b = ident.map_or(f64::from(base.drive_train.viscous_friction_n_m_s_rad), |i| i.viscous_n_m_s_rad.max(0.0));
    let mut plant = DesignPlant::from_params(&base, j, b);
    plant.speed_setpoint_weight = 1.0;
    if let Some(r) = ident.and_then(|i| i.resistance_ohm) {
        plant.r_ohm = r;
    }
    if let Some(l) = ident.and_then(|i| i.inductance_h) {
        plant.l_h = l;
    }
    // The screw's efficiency law under the static load: what a one-way
    // step adds to the inertia, `μ m r²` (the load's sign identified, else
    // the rig's gravity).
    let k = f64::from(base.metres_per_rad());
    let (mass, mu) = lifting_law(&base, ident);
    plant.load_inertia_kg_m2 = mass * k * k;
    plant.screw_mu = mu;
    plant.load_sign = ident.map_or_else(
        || {
            let ph = Physics::from_rig(rig);
            ph.m_moving * ph.gravity * ph.tilt_deg.to_radians().sin()
        },
        |i| i.load_n_m,
    );
    plant.step_friction = ident.and_then(|i| step_friction(&base, i, &Physics::from_rig(rig)));
    let mode = rod_mode(rig, X0_M);
    if !rigid {
        plant.rod_mode = Some(mode);
    }
    let with_rod_mode = !rigid;
    let (ckp, cki, cm, cbw) = feasible::current(&plant, &asked)?;
    let cur = (ckp, cki);
    let sp = feasible::speed(&plant, cur, &asked)?;
    plant.speed_setpoint_weight = sp.weight;
    let (skp, ski, sm, sbw) = (sp.kp, sp.ki, sp.margins.clone(), sp.model_bw_hz);
    let spd = (skp, ski);
    let (pkp, pm, pbw) = feasible::position(&plant, cur, spd, &asked)?;
    let gains = Gains { current: cur, speed: spd, position_kp: pkp };
    let os = |kind, dur| model::design_overshoot_pct(&plant, &gains, kind, dur);
    let mut p = base;
    p.current_pi.kp = ckp as f32;
    p.current_pi.ki = cki as f32;
    p.speed_pi.kp = skp as f32;
    p.speed_pi.ki = ski as f32;
    p.speed_setpoint_weight = sp.weight as f32;
    p.position_kp_per_s = pkp as f32;
    if let Some(i) = ident {
        // The feedforwards believe the identified mechanics: the rotating
        // share is what is left after the moving mass's reflection; the
        // load-independent Coulomb share after the screw's efficiency law
        // under the identified load.
        let k = f64::from(base.metres_per_rad());
        let reflected = f64::from(base.drive_train.moving_mass_kg) * k * k;
        p.drive_train.rotating_inertia_kg_m2 = (i.inertia_kg_m2 - reflected).max(0.0) as f32;
        apply_friction(&mut p, i);
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
        asked_overshoot_pct: Some(asked.current_overshoot_pct),
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
        asked_overshoot_pct: asked.speed_overshoot_pct,
        model_overshoot_pct: os(StepKind::Speed, model::speed_step_duration_s(asked.speed_bw_hz)),
        rule: format!(
            "loop shaping at crossover on K_t/(J s + B) (J = {j:.4e} kg·m²{}) × closed current loop × torque filter ({} Hz) × speed hold × encoder PLL: PI zero for the asked phase margin, kp for |L| = 1, crossover solved for the asked −3 dB frequency of the reference response; setpoint weight b = {:.3} for the asked overshoot",
            if with_rod_mode { ", with the rod's axial mode" } else { ", rigid" },
            plant.torque_filter_hz,
            sp.weight
        ),
    };
    let position = LoopDesign {
        kp: pkp,
        ki: 0.0,
        asked_bandwidth_hz: asked.position_bw_hz,
        asked_phase_margin_deg: None,
        model_bandwidth_hz: pbw,
        margins: pm,
        asked_overshoot_pct: Some(asked.position_overshoot_pct),
        model_overshoot_pct: os(StepKind::Position, model::position_step_duration_s(asked.position_bw_hz)),
        rule: "P on K_p T_ω(s)/s through the 1 kHz hold; K_p solved for the asked −3 dB frequency".into(),
    };
    Ok(Proposal { asked, plant, current, speed, position, speed_setpoint_weight: sp.weight, rod_mode: mode, params: p })
}

const STANDARD_GRAVITY_M_S2: f64 = 9.80665;

/// The moving mass and the screw's `μ = (1 − η)/η` a one-way step meets.
/// From the identification when it separated Coulomb friction: the mass
/// from the gravity load (the tests hang it vertically), and `μ` from the
/// Coulomb friction's load-proportional share, `(T_c − T_c0)/|T_load|`, with
/// `T_c0` the drive's load-independent drag (`coulomb_friction_n_m`). The
/// product `μ m r² = (T_c − T_c0) r/g` is then the unit's own: the drive's
/// nominal mass and η put the speed steps' overshoot 1.2–1.8 points off the
/// model on light units and on units whose screw runs less efficiently.
/// An error in `T_c0` enters as `ΔT_c0 r/g` (0.016 N·m, 30 % of the shipped
/// drag, is 0.7 % of the shipped inertia), whatever the payload. Else the
/// drive's own beliefs.
pub fn lifting_law(base: &ControlParams, ident: Option<&Identified>) -> (f64, f64) {
    let eta = f64::from(base.drive_train.screw_efficiency);
    let nominal = (f64::from(base.drive_train.moving_mass_kg), (1.0 - eta) / eta);
    let Some((i, tc)) = ident.and_then(|i| i.coulomb_n_m.map(|tc| (i, tc))) else {
        return nominal;
    };
    let k = f64::from(base.metres_per_rad());
    let load = i.load_n_m.abs();
    if !(load > 0.0 && tc.is_finite()) {
        return nominal;
    }
    let mass = load / (k * STANDARD_GRAVITY_M_S2);
    let mu = ((tc - f64::from(base.drive_train.coulomb_friction_n_m)) / load).clamp(0.0, 1.0);
    (mass, mu)
}

/// The friction a speed step meets and the drive's feedforward of it once
/// the proposal's friction lines are in (`apply_friction`): the Coulomb
/// torque under the static load as identified (the viscous one is the
/// design plant's), fed forward at the size the core computes for the
/// identified load, the viscous one on the reference. The seal's share
/// (it drags the load, beyond the rod's spring), its breakaway above
/// Coulomb and its Stribeck speed come from the rig file, as the rod's mode
/// does (no capture here separates them; the breakaway fades within
/// ≈ 4 rad/s). None without a separated Coulomb friction (one-way captures).
pub fn step_friction(base: &ControlParams, i: &Identified, rig: &Physics) -> Option<design::StepFriction> {
    let tc = i.coulomb_n_m.filter(|t| t.is_finite())?;
    let mut p = *base;
    apply_friction(&mut p, i);
    let load_n = (i.load_n_m / f64::from(p.metres_per_rad())) as f32;
    let ff = p.drive_train.friction_feedforward_gain * servo_core::motion::speed_loop::coulomb_friction_n_m(&p, load_n);
    Some(design::StepFriction {
        coulomb_n_m: tc.max(0.0),
        load_side_n_m: (rig.k * rig.rod_coulomb_n).max(0.0),
        breakaway_excess_n_m: (rig.k * (rig.rod_static_n - rig.rod_coulomb_n)).max(0.0),
        stribeck_rad_s: rig.stribeck_m_s / rig.k,
        feedforward_coulomb_n_m: f64::from(ff),
        feedforward_ramp_rad_s: f64::from(p.drive_train.friction_feedforward_speed_rad_s),
        feedforward_viscous_n_m_s_rad: f64::from(p.drive_train.viscous_friction_n_m_s_rad),
        rest_n_m: 0.0,
    })
}

/// Writes the identified friction into the drive's friction feedforward
/// (`drive_train.viscous_friction_n_m_s_rad`, `coulomb_friction_n_m`): the
/// viscous part as identified, the Coulomb part less the screw's
/// efficiency-law share under the identified load, which the feedforward
/// adds itself at every load. A rig with more friction than its file says
/// then meets it in the speed loop's feedforward, not as a lag the speed
/// integrator winds out at each move start.
pub fn apply_friction(p: &mut ControlParams, i: &Identified) {
    let k = f64::from(p.metres_per_rad());
    p.drive_train.viscous_friction_n_m_s_rad = i.viscous_n_m_s_rad.max(0.0) as f32;
    if let Some(tc) = i.coulomb_n_m {
        let eta = f64::from(p.drive_train.screw_efficiency);
        let screw = k * (1.0 - eta) / eta * (i.load_n_m / k).abs();
        p.drive_train.coulomb_friction_n_m = (tc - screw).max(0.0) as f32;
    }
}

/// The `drive param set` lines of the friction feedforward alone.
pub fn friction_param_set_lines(p: &ControlParams) -> Vec<(String, f32)> {
    vec![
        ("drive_train.viscous_friction_n_m_s_rad".into(), p.drive_train.viscous_friction_n_m_s_rad),
        ("drive_train.coulomb_friction_n_m".into(), p.drive_train.coulomb_friction_n_m),
    ]
}

/// Identifies the simulated rig's friction as `tune identify` does with
/// no captures given (the same speed and current steps, on the drive's
/// present parameters) and returns the rig with it written into the
/// friction feedforward, and what was identified.
pub fn identify_friction_sim(rig: &RigConfig, seed: u64) -> Result<(RigConfig, Identified)> {
    let (speed, cur) = simulate_identification_captures(rig, seed)?;
    let (m, e) = identify(&speed, Some(&cur), &rig.control)?;
    let ident = Identified::from_fits(&m, e.as_ref());
    let mut out = rig.clone();
    apply_friction(&mut out.control, &ident);
    out.control.validate().map_err(|e| anyhow!("the identified friction does not validate: {e:?}"))?;
    Ok((out, ident))
}

/// The `[control]` fragment of a proposal: the gains and what the
/// feedforwards believe.
pub fn control_fragment(p: &ControlParams) -> String {
    let d = &p.drive_train;
    format!(
        "# Proposed by `host-sim tune propose`; paste into the rig's [control] or apply with `drive param set`.\n\
         [control]\ntorque_filter_hz = {}\nposition_kp_per_s = {}\nspeed_setpoint_weight = {}\n\n\
         [control.current_pi]\nkp = {}\nki = {}\n\n\
         [control.speed_pi]\nkp = {}\nki = {}\n\n\
         [control.motor]\nphase_resistance_ohm = {}\ninductance_d_h = {}\ninductance_q_h = {}\nflux_linkage_wb = {}\n\n\
         [control.drive_train]\nrotating_inertia_kg_m2 = {}\nviscous_friction_n_m_s_rad = {}\ncoulomb_friction_n_m = {}\n",
        p.torque_filter_hz,
        p.position_kp_per_s,
        p.speed_setpoint_weight,
        p.current_pi.kp,
        p.current_pi.ki,
        p.speed_pi.kp,
        p.speed_pi.ki,
        p.motor.phase_resistance_ohm,
        p.motor.inductance_d_h,
        p.motor.inductance_q_h,
        p.motor.flux_linkage_wb,
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
        // Not live: set it with the bridge off.
        ("speed_setpoint_weight".into(), p.speed_setpoint_weight),
        ("position_kp_per_s".into(), p.position_kp_per_s),
        ("drive_train.rotating_inertia_kg_m2".into(), p.drive_train.rotating_inertia_kg_m2),
        ("drive_train.viscous_friction_n_m_s_rad".into(), p.drive_train.viscous_friction_n_m_s_rad),
        ("drive_train.coulomb_friction_n_m".into(), p.drive_train.coulomb_friction_n_m),
        // Not live (the motor's parameters): set it with the bridge off.
        ("motor.flux_linkage_wb".into(), p.motor.flux_linkage_wb),
    ]
}

/// The check's tests: a step and a chirp per loop, sized for the gains
/// (the current step on the d axis: on q it accelerates the rotor, and the
/// back-EMF feedforward's 1.5-period lag turns the acceleration into a
/// current error of `1.5 T p ψ α / R`, ≈ 2 % of the step; that is the loop's
/// disturbance response, not its reference response)
/// (`hold_a`: the q current holding the load). The chirps start a decade
/// below the asked bandwidth and end 4–5 times above it; the steps and the
/// speed chirp are as large as a 6 A swing of the speed PI allows (up to
/// 100 rad/s), so that Coulomb friction (≈ 1.7 A) stays a small part of the
/// response.
pub fn check_specs(asked: &Asked, p: &ControlParams, hold_a: f64) -> Vec<(Loop, TestSpec)> {
    let pwm = f64::from(p.rates.pwm_frequency_hz);
    let samples = |signals: f64| (servo_core::capture::CAPTURE_STORE_CELLS as f64 / signals).floor();
    let dec = |to: f64, dur: f64, signals: f64| -> u16 {
        // Finest sampling the store allows for the duration, at least
        // 2.5 × the end frequency.
        let fit = (1.1 * dur * pwm / samples(signals)).ceil() as u16;
        let need = (pwm / (2.5 * to)).floor() as u16;
        fit.max(1).min(need.max(1))
    };
    // The whole sweep and its settling must fit the store at that sampling
    // (the FRF needs the record to end at rest): shortened if not.
    let fit_dur = |to: f64, dur: f64, signals: f64| -> f64 {
        let d = f64::from(dec(to, dur, signals));
        dur.min(0.95 * samples(signals) * d / (1.1 * pwm))
    };
    let (cb, sb, pb) = (asked.current_bw_hz, asked.speed_bw_hz, asked.position_bw_hz);
    let (cur_from, cur_to) = (cb / 10.0, (4.0 * cb).min(0.2 * pwm));
    let (spd_from, spd_to) = (sb / 2.0, (5.0 * sb).min(0.1 * pwm / f64::from(p.rates.speed_loop_divider)));
    let (pos_from, pos_to) = (pb / 4.0, (5.0 * pb).min(0.1 * pwm / f64::from(p.rates.position_loop_divider)));
    let cur_dur = fit_dur(cur_to, (4.0 / cur_from).clamp(0.1, 0.4), 3.0);
    let spd_dur = fit_dur(spd_to, (4.0 / spd_from).clamp(2.0, 8.0), 3.0);
    let pos_dur = fit_dur(pos_to, (4.0 / pos_from).clamp(2.0, 12.0), 3.0);
    let current_room = (f64::from(p.current_limit_a()) - hold_a.abs()).max(2.0);
    // The d-axis step needs no room for motion; the q chirp rides on the hold.
    let cur_amp = (0.4 * current_room).min(8.0);
    let spd_amp = model::speed_step_amplitude_rad_s(f64::from(p.speed_pi.kp), f64::from(p.limits.speed_max_rad_s));
    // The position loop runs under a speed chirp: its lowest frequency may
    // move the rod by at most half the following-error bound.
    let chirp_travel_rad = 0.5 * f64::from(p.faults.position_following_error_m) / f64::from(p.metres_per_rad());
    let spd_chirp_amp = spd_amp.min(chirp_travel_rad * std::f64::consts::TAU * spd_from);
    // Half the following-error bound: the friction's creep at rest (tens of
    // µm) stays a small share of it.
    let pos_amp = 0.5 * f64::from(p.faults.position_following_error_m);
    // The speed step runs from the settled hold, before any test that moves
    // the rotor (the d-current step does not): friction at rest holds what
    // the last motion left, and after the q-current chirp it carried up to
    // 30 % of the Coulomb torque of a light unit's load, which the hold
    // current then lacks when the step starts (−0.4 to −0.9 point on a 5 %
    // ask, `model::step_response`'s `rest_n_m`). The design model starts
    // from the settled hold.
    vec![
        (Loop::Current, TestSpec::current_step_d(cur_amp, 0.02)),
        (Loop::Speed, TestSpec::step(Loop::Speed, spd_amp, model::speed_step_duration_s(sb))),
        (Loop::Current, TestSpec::chirp(Loop::Current, 0.5 * (0.25 * current_room).min(8.0), cur_from, cur_to, cur_dur, dec(cur_to, cur_dur, 3.0))),
        (Loop::Speed, TestSpec::chirp(Loop::Speed, spd_chirp_amp, spd_from, spd_to, spd_dur, dec(spd_to, spd_dur, 3.0))),
        (Loop::Position, TestSpec::step(Loop::Position, pos_amp, model::position_step_duration_s(pb))),
        (Loop::Position, TestSpec::chirp(Loop::Position, 0.4 * f64::from(p.faults.position_following_error_m), pos_from, pos_to, pos_dur, dec(pos_to, pos_dur, 3.0))),
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
    // The tests' amplitudes follow the following-error bound (half of it
    // for the position step, 0.4 for its chirp); the check doubles it for
    // its own tests, so that Coulomb friction (≈ 1.4 mm of travel before a
    // 5 Hz speed loop's integral holds it) stays a small share of the
    // position tests: at the shipped bound the 1 Hz position loop read
    // 22–30 % low on the friction-heavy rigs of the family, at twice the
    // bound within 17 %. The proposal keeps the rig's bound.
    let mut params = params;
    params.faults.position_following_error_m *= TEST_FOLLOWING_ERROR_FACTOR;
    let mut cl = simcheck::holding(rig, params, X0_M, seed)?;
    let hold_a = f64::from(cl.controller.telemetry().current_q_a);
    let mut out = Vec::new();
    for (target, spec) in check_specs(asked, &params, hold_a) {
        let c = simcheck::run_test(&mut cl, &spec).map_err(|e| anyhow!("{target:?} {:?}: {e:#}", spec.chirp))?;
        out.push(CheckResult { target, figures: simcheck::figures(&spec, &c, &params), spec, captured: c });
    }
    Ok(out)
}
