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
    /// and R, L (a q-current step captured every PWM period). Writes
    /// identified.json. Without --capture: runs the captures on the
    /// simulated rig first (and writes them).
    Identify {
        /// Speed-step (or any motion) capture CSVs as `host-sim drive step
        /// speed` writes them (t_s, current_q, speed[, motor_position]).
        #[arg(long)]
        capture: Vec<PathBuf>,
        /// A q-current step capture (t_s, current_q, voltage_q[, speed]),
        /// decimation 1, as `host-sim drive step current` writes it.
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
        /// identified.json of `tune identify`; default: the parameters' own
        /// inertia, friction and winding.
        #[arg(long)]
        identified: Option<PathBuf>,
        #[arg(long)]
        params: Option<PathBuf>,
        /// Override the torque filter corner (Hz) the design keeps.
        #[arg(long)]
        torque_filter_hz: Option<f64>,
        /// Design the speed loop on the two-mass model (rod mode) instead of
        /// the rigid one.
        #[arg(long)]
        rod_mode: bool,
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
            let doc = serde_json::json!({ "identified": id, "nominal_rig": nominal,
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
                "nominal_rig": nominal, "written": out }))?);
            Ok(())
        }
        TuneCmd::Propose { current_bw_hz, speed_bw_hz, phase_margin_deg, position_bw_hz, identified, params, torque_filter_hz, rod_mode, out, seed } => {
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
            let asked = Asked { current_bw_hz, speed_bw_hz, phase_margin_deg, position_bw_hz };
            let s = propose_and_check(&rig, id.as_ref(), asked, rod_mode, seed, &out)?;
            println!("{}", serde_json::to_string_pretty(&s["table"])?);
            println!("wrote {}/proposal.toml, summary.json, step_*.csv/png", out.display());
            Ok(())
        }
        TuneCmd::Bench { out, params } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let s = bench(&rig, &out)?;
            println!("{}", serde_json::to_string_pretty(&s["table"])?);
            Ok(())
        }
    }
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
pub fn propose_and_check(rig: &RigConfig, id: Option<&Identified>, asked: Asked, rod: bool, seed: u64, out: &Path) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let prop = propose(rig, id, asked, rod)?;
    std::fs::write(out.join("proposal.toml"), control_fragment(&prop.params))?;
    let results = check(rig, prop.params, &asked, seed)?;
    let mut table = serde_json::Map::new();
    let mut rows = Vec::new();
    for (lp, design) in [(Loop::Current, &prop.current), (Loop::Speed, &prop.speed), (Loop::Position, &prop.position)] {
        let step = results.iter().find(|r| r.target == lp && r.spec.chirp.is_none()).expect("a step");
        let chirp = results.iter().find(|r| r.target == lp && r.spec.chirp.is_some()).expect("a chirp");
        let sf = step.figures.step.clone().unwrap_or_default();
        let ff = chirp.figures.frf.clone().unwrap_or_default();
        let bw = chirp.figures.bandwidth_3db_interp_hz;
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
        let row = serde_json::json!({
            "loop": name,
            "asked_bandwidth_hz": design.asked_bandwidth_hz,
            "asked_phase_margin_deg": design.asked_phase_margin_deg,
            "model_bandwidth_hz": design.model_bandwidth_hz,
            "achieved_bandwidth_hz": bw,
            "achieved_bandwidth_first_bin_hz": ff.bandwidth_3db_hz,
            "bandwidth_error_pct": within(design.asked_bandwidth_hz, bw),
            "model_phase_margin_deg": design.margins.phase_margin_deg,
            "achieved_phase_margin_deg": ff.phase_margin_deg,
            "asked_overshoot_pct": design.model_overshoot_pct,
            "achieved_overshoot_pct": sf.overshoot_pct,
            "overshoot_error_pct": if design.model_overshoot_pct > 0.5 { Some(100.0 * (sf.overshoot_pct - design.model_overshoot_pct) / design.model_overshoot_pct) } else { None },
            "rise_time_s": sf.rise_time_s,
            "settling_time_s": sf.settling_time_s,
        });
        rows.push(row.clone());
        table.insert(name, row);
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

/// Identification on the simulator, then two speed-loop cases.
pub fn bench(rig: &RigConfig, out: &Path) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let (speed, cur) = simulate_identification_captures(rig, 1)?;
    let (m, e) = identify(&speed, Some(&cur), &rig.control)?;
    let id = Identified::from_fits(&m, e.as_ref());
    let nominal = identify::nominal_mech(&Physics::from_rig(rig), rig_load_n(rig));
    let cases = [
        ("30hz_60deg", Asked { current_bw_hz: 1000.0, speed_bw_hz: 30.0, phase_margin_deg: 60.0, position_bw_hz: 5.0 }, false),
        ("60hz_50deg", Asked { current_bw_hz: 1000.0, speed_bw_hz: 60.0, phase_margin_deg: 50.0, position_bw_hz: 10.0 }, false),
        // Below the rod's ≈32 Hz anti-resonance and the ≈380 Hz torsional
        // mode, where the rigid design model holds.
        ("10hz_60deg", Asked { current_bw_hz: 300.0, speed_bw_hz: 10.0, phase_margin_deg: 60.0, position_bw_hz: 2.0 }, false),
        ("15hz_55deg", Asked { current_bw_hz: 400.0, speed_bw_hz: 15.0, phase_margin_deg: 55.0, position_bw_hz: 3.0 }, false),
    ];
    let mut table = Vec::new();
    let mut all = Vec::new();
    for (name, asked, rod) in cases {
        let s = propose_and_check(rig, Some(&id), asked, rod, 1, &out.join(name))?;
        for r in s["table"].as_array().into_iter().flatten() {
            let mut r = r.clone();
            r["case"] = serde_json::json!(name);
            table.push(r);
        }
        all.push(serde_json::json!({ "case": name, "asked": asked, "rod_mode_design": rod, "table": s["table"] }));
    }
    if table.is_empty() {
        bail!("no case ran");
    }
    let summary = serde_json::json!({
        "identified": id,
        "nominal_rig": nominal,
        "cases": all,
        "table": table,
    });
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    Ok(summary)
}
