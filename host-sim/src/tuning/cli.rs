//! `host-sim tune identify | propose | bench`.

use super::identify::Capture;
use super::simcheck::Loop;
use super::*;
use crate::report::plots::{line_chart, Series};
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct TuneArgs {
    #[command(subcommand)]
    pub cmd: TuneCmd,
}

#[derive(Subcommand)]
pub enum TuneCmd {
    /// Identify inertia and friction (speed-step captures, both directions)
    /// and R, L (a d-current step captured every PWM period). Writes
    /// identified.json. Without --capture: runs the captures on the
    /// simulated rig first (and writes them).
    Identify {
        /// Speed-step (or any motion) capture CSVs as `host-sim drive step
        /// speed` writes them (t_s, current_q, speed[, motor_position]).
        #[arg(long)]
        capture: Vec<PathBuf>,
        /// A d-current step capture (t_s, current_d, voltage_d[, speed]),
        /// decimation 1, as `host-sim drive step current-d` writes it (a
        /// q-current step's current_q, voltage_q also work, less well: the
        /// rotor turns).
        #[arg(long)]
        current_capture: Option<PathBuf>,
        #[arg(long)]
        params: Option<PathBuf>,
        #[arg(long, default_value = "out/tune/identified.json")]
        out: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Propose gains for the asked bandwidths and phase margin; check them
    /// on the simulator; write proposal.toml, summary.json, predicted step
    /// responses (CSV + PNG).
    Propose {
        #[arg(long, default_value_t = 1000.0)]
        current_bw_hz: f64,
        #[arg(long)]
        speed_bw_hz: f64,
        #[arg(long, default_value_t = 60.0)]
        phase_margin_deg: f64,
        #[arg(long)]
        position_bw_hz: f64,
        /// Asked current-step overshoot, %.
        #[arg(long, default_value_t = 0.0)]
        current_overshoot_pct: f64,
        /// Asked speed-step overshoot, % (met by the speed PI's setpoint
        /// weight); default: a plain PI, whatever overshoot it gives.
        #[arg(long)]
        speed_overshoot_pct: Option<f64>,
        /// Asked position-step overshoot, %.
        #[arg(long, default_value_t = 0.0)]
        position_overshoot_pct: f64,
        /// identified.json of `tune identify`; default: the parameters' own
        /// inertia, friction and winding.
        #[arg(long)]
        identified: Option<PathBuf>,
        #[arg(long)]
        params: Option<PathBuf>,
        /// Override the torque filter corner (Hz) the design keeps.
        #[arg(long)]
        torque_filter_hz: Option<f64>,
        /// Design on the rigid model (without the rod's axial mode).
        #[arg(long)]
        rigid: bool,
        #[arg(long, default_value = "out/tune/proposal")]
        out: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// The benchmark: identification on the simulator, then proposals for
    /// several asked speed-loop bandwidths / margins, each checked on the
    /// full plant (steps and chirps). Writes summary.json.
    Bench {
        #[arg(long, default_value = "out/tune/bench")]
        out: PathBuf,
        #[arg(long)]
        params: Option<PathBuf>,
        /// A JSON list of cases ({name, asked, rigid}) instead of the
        /// built-in ones.
        #[arg(long)]
        cases: Option<PathBuf>,
        /// Diagnostic: propose and check even asks the limits refuse.
        #[arg(long)]
        unchecked: bool,
        /// The bench on every rig of a family (`host-sim rigs`): a row per
        /// rig, every loop result and the worst case in summary.json,
        /// family.md; fails when a rig does.
        #[arg(long, conflicts_with = "params")]
        family: Option<PathBuf>,
    },
}

pub fn run(a: TuneArgs) -> Result<()> {
    match a.cmd {
        TuneCmd::Identify { capture, current_capture, params, out, seed } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let dir = out.parent().map(Path::to_path_buf).unwrap_or_default();
            std::fs::create_dir_all(&dir)?;
            let (speed, cur) = if capture.is_empty() {
                let (s, c) = simulate_identification_captures(&rig, seed)?;
                for (k, cap) in s.iter().enumerate() {
                    cap.write_csv(&dir.join(format!("speed_step_{k}.csv")))?;
                }
                c.write_csv(&dir.join("current_step.csv"))?;
                (s, Some(c))
            } else {
                let s = capture.iter().map(|p| Capture::read_csv(p)).collect::<Result<Vec<_>>>()?;
                let c = current_capture.as_ref().map(|p| Capture::read_csv(p)).transpose()?;
                (s, c)
            };
            let (m, e) = identify(&speed, cur.as_ref(), &rig.control)?;
            let id = Identified::from_fits(&m, e.as_ref());
            let nominal = identify::nominal_mech(&Physics::from_rig(&rig), f64::from(rig.control.startup.expected_load_force_n).max(rig_load_n(&rig)));
            // The friction feedforward the identification asks for, as the
            // `drive param set` lines a bench applies before it logs for the
            // observer (docs/tuning.md, step 6).
            let mut with_friction = rig.control;
            crate::tuning::apply_friction(&mut with_friction, &id);
            let friction_lines: Vec<_> =
                crate::tuning::friction_param_set_lines(&with_friction).into_iter().map(|(n, v)| serde_json::json!([n, v])).collect();
            let doc = serde_json::json!({ "identified": id, "nominal_rig": nominal, "friction_param_set": friction_lines,
                "parameters": { "reflected_inertia_kg_m2": rig.control.reflected_inertia_kg_m2(),
                    "phase_resistance_ohm": rig.control.motor.phase_resistance_ohm, "inductance_q_h": rig.control.motor.inductance_q_h } });
            std::fs::write(&out, serde_json::to_string_pretty(&doc)?)?;
            println!("{}", serde_json::to_string_pretty(&serde_json::json!({
                "inertia_kg_m2": [m.inertia_kg_m2.value, m.inertia_kg_m2.std_err],
                "viscous_n_m_s_rad": [m.viscous_n_m_s_rad.value, m.viscous_n_m_s_rad.std_err],
                "coulomb_n_m": m.coulomb_n_m.as_ref().map(|c| [c.value, c.std_err]),
                "load_n_m": [m.load_n_m.value, m.load_n_m.std_err],
                "r2": m.fit.r2, "rms_residual_n_m": m.fit.rms_residual,
                "resistance_ohm": e.as_ref().map(|e| [e.resistance_ohm.value, e.resistance_ohm.std_err]),
                "inductance_h": e.as_ref().map(|e| [e.inductance_h.value, e.inductance_h.std_err]),
                "nominal_rig": nominal, "friction_param_set": friction_lines, "written": out }))?);
            Ok(())
        }
        TuneCmd::Propose {
            current_bw_hz,
            speed_bw_hz,
            phase_margin_deg,
            position_bw_hz,
            current_overshoot_pct,
            speed_overshoot_pct,
            position_overshoot_pct,
            identified,
            params,
            torque_filter_hz,
            rigid,
            out,
            seed,
        } => {
            let mut rig = RigConfig::load_or_nominal(params.as_ref())?;
            if let Some(f) = torque_filter_hz {
                rig.control.torque_filter_hz = f as f32;
            }
            let id: Option<Identified> = match identified {
                Some(p) => {
                    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))?)?;
                    Some(serde_json::from_value(v.get("identified").cloned().unwrap_or(v))?)
                }
                None => None,
            };
            let asked = Asked {
                current_bw_hz,
                current_overshoot_pct,
                speed_bw_hz,
                phase_margin_deg,
                speed_overshoot_pct,
                position_bw_hz,
                position_overshoot_pct,
            };
            let s = propose_and_check(&rig, id.as_ref(), asked, rigid, seed, &out)?;
            println!("{}", serde_json::to_string_pretty(&s["table"])?);
            println!("wrote {}/proposal.toml, summary.json, step_*.csv/png", out.display());
            Ok(())
        }
        TuneCmd::Bench { out, family: Some(dir), cases, unchecked, .. } => {
            super::feasible::set_enforced(!unchecked);
            let rigs = crate::rigs::load_family(&dir)?;
            let s = super::family::bench_family(&rigs, &dir, cases.as_deref(), &out)?;
            print!("{}", std::fs::read_to_string(out.join("family.md"))?);
            println!("worst: {}", serde_json::to_string_pretty(&s["worst"])?);
            println!("{} of {} rigs pass; wrote {}/{{summary.json, family.md}} and a folder per rig", s["rigs_passed"], s["rigs"], out.display());
            if s["rigs_passed"] != s["rigs"] {
                bail!("tune bench: rigs failed: {}", s["rigs_failed"]);
            }
            Ok(())
        }
        TuneCmd::Bench { out, params, cases, unchecked, family: None } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            super::feasible::set_enforced(!unchecked);
            let s = bench(&rig, &out, cases.as_deref())?;
            println!("{}", serde_json::to_string_pretty(&s["table"])?);
            println!("{}", serde_json::to_string_pretty(&s["refused"])?);
            let why = bench_misses(&s);
            if !why.is_empty() {
                bail!("tune bench: {} (summary: {})", why.join("; "), out.join("summary.json").display());
            }
            Ok(())
        }
    }
}

/// What a bench's summary misses: each accepted loop result outside its
/// ask, each check that failed, or no accepted case at all (a refusal with
/// its reason is an answer, not a miss).
pub fn bench_misses(s: &serde_json::Value) -> Vec<String> {
    let mut why: Vec<String> = s["table"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|r| r["pass"].as_bool() != Some(true))
        .map(|r| format!("{} {} loop outside its ask (bandwidth error {} %, overshoot {} % asked {} %)", r["case"], r["loop"], r["bandwidth_error_pct"], r["achieved_overshoot_pct"], r["asked_overshoot_pct"]))
        .collect();
    why.extend(s["check_failed"].as_array().into_iter().flatten().map(|f| format!("{} check failed: {}", f["case"], f["check_failed"])));
    if s["table"].as_array().is_none_or(Vec::is_empty) && why.is_empty() {
        why.push("no case was accepted".into());
    }
    why
}

fn rig_load_n(rig: &RigConfig) -> f64 {
    let ph = Physics::from_rig(rig);
    ph.m_moving * ph.gravity * ph.tilt_deg.to_radians().sin()
}

fn within(asked: f64, got: Option<f64>) -> Option<f64> {
    got.map(|g| 100.0 * (g - asked) / asked)
}

/// Proposes, checks on the simulator, writes everything to `out`; returns
/// the summary.
pub fn propose_and_check(rig: &RigConfig, id: Option<&Identified>, asked: Asked, rigid: bool, seed: u64, out: &Path) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let prop = propose(rig, id, asked, rigid)?;
    std::fs::write(out.join("proposal.toml"), control_fragment(&prop.params))?;
    let results = check(rig, prop.params, &asked, seed)?;
    let mut table = serde_json::Map::new();
    let mut rows = Vec::new();
    for (lp, design) in [(Loop::Current, &prop.current), (Loop::Speed, &prop.speed), (Loop::Position, &prop.position)] {
        let step = results.iter().find(|r| r.target == lp && r.spec.chirp.is_none()).expect("a step");
        let chirp = results.iter().find(|r| r.target == lp && r.spec.chirp.is_some()).expect("a chirp");
        let sf = step.figures.step.clone().unwrap_or_default();
        let bw = chirp.figures.bandwidth_3db_hz;
        let name = format!("{lp:?}").to_lowercase();
        // The predicted step (design model) next to the simulated one.
        let cap = &step.captured.capture;
        let t0 = step.captured.trigger_index as f64 * cap.dt_s;
        let y = &cap.columns[1];
        let y0 = y[..step.captured.trigger_index.max(1)].iter().sum::<f64>() / step.captured.trigger_index.max(1) as f64;
        let plant = &prop.plant;
        let g = Gains { current: (prop.current.kp, prop.current.ki), speed: (prop.speed.kp, prop.speed.ki), position_kp: prop.position.kp };
        let (kind, scale) = match lp {
            Loop::Current => (StepKind::Current, 1.0),
            Loop::Speed => (StepKind::Speed, 1.0),
            Loop::Position => (StepKind::Position, 1.0 / f64::from(prop.params.metres_per_rad())),
        };
        let dur = cap.len() as f64 * cap.dt_s - t0;
        let model_y = model::step_response(plant, &g, kind, step.spec.amplitude * scale, dur);
        let mut w = csv::Writer::from_path(out.join(format!("step_{name}.csv")))?;
        w.write_record(["t_s", "reference", "simulated", "predicted_model"])?;
        let mut sim_pts = Vec::new();
        let mut mod_pts = Vec::new();
        let mut ref_pts = Vec::new();
        for k in 0..cap.len() {
            let t = k as f64 * cap.dt_s - t0;
            let m = if t >= 0.0 {
                let n = ((t / plant.t_pwm()).round() as usize).min(model_y.len().saturating_sub(1));
                y0 + model_y[n] / scale
            } else {
                y0
            };
            w.write_record([t, cap.columns[0][k], y[k], m].map(|v| v.to_string()))?;
            sim_pts.push((t, y[k]));
            mod_pts.push((t, m));
            ref_pts.push((t, cap.columns[0][k]));
        }
        w.flush()?;
        line_chart(
            &out.join(format!("step_{name}.png")),
            &format!("{name} step: full-plant simulation vs design model"),
            "time from step [s]",
            &cap.names[1],
            &[Series { name: "reference", points: ref_pts }, Series { name: "simulated (full plant)", points: sim_pts }, Series { name: "design model", points: mod_pts }],
        )?;
        let asked_os = design.asked_overshoot_pct.unwrap_or(design.model_overshoot_pct);
        let bw_pass = measure::bandwidth_ok(design.asked_bandwidth_hz, bw);
        let os_pass = measure::overshoot_ok(asked_os, sf.overshoot_pct);
        let row = serde_json::json!({
            "loop": name,
            "asked_bandwidth_hz": design.asked_bandwidth_hz,
            "asked_phase_margin_deg": design.asked_phase_margin_deg,
            "model_bandwidth_hz": design.model_bandwidth_hz,
            "achieved_bandwidth_hz": bw,
            "bandwidth_error_pct": within(design.asked_bandwidth_hz, bw),
            "low_frequency_gain_db": chirp.figures.low_frequency_gain_db,
            "model_phase_margin_deg": design.margins.phase_margin_deg,
            "model_gain_margin_db": design.margins.gain_margin_db,
            "achieved_phase_margin_deg": chirp.figures.margins.as_ref().and_then(|m| m.phase_margin_deg),
            "achieved_gain_margin_db": chirp.figures.margins.as_ref().and_then(|m| m.gain_margin_db),
            "asked_overshoot_pct": asked_os,
            "overshoot_asked_explicitly": design.asked_overshoot_pct.is_some(),
            "model_overshoot_pct": design.model_overshoot_pct,
            "achieved_overshoot_pct": sf.overshoot_pct,
            "overshoot_tolerance_pct": measure::overshoot_tolerance_pct(asked_os),
            "overshoot_noise_floor_pct": measure::overshoot_noise_floor_pct(y, cap.dt_s, t0, step.spec.duration_s, step.spec.amplitude),
            "bandwidth_pass": bw_pass,
            "overshoot_pass": os_pass,
            "pass": bw_pass && os_pass,
            "rise_time_s": sf.rise_time_s,
            "settling_time_s": sf.settling_time_s,
            "step_amplitude": step.spec.amplitude,
            "chirp_amplitude": chirp.spec.amplitude,
            "chirp_hz": chirp.spec.chirp,
            // Measured against the design model's closed loop, every 8th
            // grid point: (Hz, measured dB, model dB, measured °, model °).
            "frf_vs_model": chirp.figures.frf.iter().flatten().step_by(8).map(|&(f, g, ph)| {
                let w = std::f64::consts::TAU * f;
                let (cu, sp) = ((prop.current.kp, prop.current.ki), (prop.speed.kp, prop.speed.ki));
                let m = match lp {
                    Loop::Current => prop.plant.current_cl(cu.0, cu.1, w),
                    Loop::Speed => prop.plant.speed_cl(cu, sp, w),
                    Loop::Position => prop.plant.position_cl(cu, sp, prop.position.kp, w),
                };
                [f, g, 20.0 * m.norm().log10(), ph, m.arg().to_degrees()]
            }).collect::<Vec<_>>(),
        });
        rows.push(row.clone());
        table.insert(name.clone(), row);
        step.captured.capture.write_csv(&out.join(format!("capture_step_{name}.csv")))?;
        // The chirp's FRF too.
        let cc = &chirp.captured.capture;
        chirp.captured.capture.write_csv(&out.join(format!("chirp_{}.csv", format!("{lp:?}").to_lowercase())))?;
        let _ = cc;
    }
    let summary = serde_json::json!({
        "asked": asked,
        "design": &prop,
        "proposal_toml": control_fragment(&prop.params),
        "param_set": param_set_lines(&prop.params),
        "checks": results,
        "table": rows,
    });
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    let _ = table;
    Ok(summary)
}

/// One benchmark case: a name, the ask, and the rigid-model switch.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct BenchCase {
    pub name: String,
    pub asked: Asked,
    #[serde(default)]
    pub rigid: bool,
}

/// The benchmark's cases: asks spread over what the rig carries (low ones
/// included: they missed before), with and without an overshoot ask, and
/// asks beyond the modes, which must be refused with the reason.
pub fn bench_cases() -> Vec<BenchCase> {
    let c = |name: &str, cb: f64, sb: f64, pm: f64, os: Option<f64>, pb: f64| BenchCase {
        name: name.into(),
        asked: Asked { speed_overshoot_pct: os, ..Asked::new(cb, sb, pm, pb) },
        rigid: false,
    };
    vec![
        c("c200_s5_os10_p1", 200.0, 5.0, 60.0, Some(10.0), 1.0),
        c("c300_s10_os10_p2", 300.0, 10.0, 60.0, Some(10.0), 2.0),
        c("c300_s10_plain_p2", 300.0, 10.0, 60.0, None, 2.0),
        c("c300_s12_os5_p2", 300.0, 12.0, 60.0, Some(5.0), 2.0),
        c("c250_s15_os15_p3", 250.0, 15.0, 55.0, Some(15.0), 3.0),
        c("c300_s20_os20_p4", 300.0, 20.0, 55.0, Some(20.0), 4.0),
        // Beyond the modes: refused.
        c("c1000_s30_p5", 1000.0, 30.0, 60.0, None, 5.0),
        c("c300_s30_os20_p5", 300.0, 30.0, 60.0, Some(20.0), 5.0),
        c("c300_s60_p10", 300.0, 60.0, 50.0, None, 10.0),
    ]
}

/// Identification on the simulator, then each case proposed (or refused)
/// and checked on the full plant. `cases`: a JSON list of [`BenchCase`]
/// instead of [`bench_cases`].
pub fn bench(rig: &RigConfig, out: &Path, cases: Option<&Path>) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let (speed, cur) = simulate_identification_captures(rig, 1)?;
    let (m, e) = identify(&speed, Some(&cur), &rig.control)?;
    let id = Identified::from_fits(&m, e.as_ref());
    let nominal = identify::nominal_mech(&Physics::from_rig(rig), rig_load_n(rig));
    let cases: Vec<BenchCase> = match cases {
        Some(p) => serde_json::from_str(&std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?)?,
        None => bench_cases(),
    };
    let mut table = Vec::new();
    let mut refused = Vec::new();
    let mut all = Vec::new();
    let mut failed = Vec::new();
    for case in cases {
        // A refusal is the proposal's; a test that faulted on an accepted
        // proposal is a failure of the check, never counted as a refusal.
        if let Err(e) = propose(rig, Some(&id), case.asked, case.rigid) {
            let why = format!("{e:#}");
            refused.push(serde_json::json!({ "case": case.name, "asked": case.asked, "refused": why }));
            all.push(serde_json::json!({ "case": case.name, "asked": case.asked, "rigid": case.rigid, "accepted": false, "refused": why }));
            continue;
        }
        match propose_and_check(rig, Some(&id), case.asked, case.rigid, 1, &out.join(&case.name)) {
            Ok(s) => {
                for r in s["table"].as_array().into_iter().flatten() {
                    let mut r = r.clone();
                    r["case"] = serde_json::json!(case.name);
                    table.push(r);
                }
                all.push(serde_json::json!({ "case": case.name, "asked": case.asked, "rigid": case.rigid, "accepted": true, "table": s["table"] }));
            }
            Err(e) => {
                let why = format!("{e:#}");
                failed.push(serde_json::json!({ "case": case.name, "asked": case.asked, "check_failed": why }));
                all.push(serde_json::json!({ "case": case.name, "asked": case.asked, "rigid": case.rigid, "accepted": true, "check_failed": why }));
            }
        }
    }
    if all.is_empty() {
        bail!("no case ran");
    }
    let pass = failed.is_empty() && !table.is_empty() && table.iter().all(|r| r["pass"].as_bool() == Some(true));
    let summary = serde_json::json!({
        "figure": "the proposed gains, on the simulator: step overshoot and bandwidth within 20 % of what was asked for (bandwidth ±20 % of the ask; overshoot ±20 % of the ask for asks ≥ 5 %, ±1 percentage point below)",
        "all_accepted_pass": pass,
        "identified": id,
        "nominal_rig": nominal,
        "cases": all,
        "table": table,
        "refused": refused,
        "check_failed": failed,
    });
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    Ok(summary)
}
