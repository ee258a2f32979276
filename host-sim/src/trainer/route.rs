//! The whole retraining route as a user walks it, timed: the rig's
//! friction identified and written into the drive's friction feedforward
//! (docs/tuning.md), the screw's lead fitted from short logs at three
//! payloads and written into the drive's lead, logs at three payloads →
//! `dataset-from-logs` → `train
//! --hidden 8` → upload to a simulated drive over TCP → verify (the drive
//! runs the file's words, a restarted drive runs them from its store, and a
//! stroke with compensation lands the rod closer than without). Writes
//! `summary.json` with each stage's wall-clock time against the 2-minute bar.

use super::from_logs::{self, LogOptions};
use super::log_moves::{record, LogPlan};
use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace, SimDrive};
use crate::tool::client::{Client, Endpoint};
use crate::tool::observer as obs;
use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;
use servo_core::protocol::{observer::words_crc, DriveCommand, DriveFrame, ObserverSource, Reply, Request, RequestFrame};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Instant;

/// `host-sim observer-route`.
#[derive(clap::Args, Debug)]
pub struct RouteArgs {
    #[arg(long, default_value = "../out/observer-route")]
    pub out: PathBuf,
    /// Rig file; default: the shipped rig.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Stroke cycles logged per payload.
    #[arg(long, default_value_t = 6)]
    pub cycles: usize,
    /// Log with the friction feedforward as the rig file has it, instead of
    /// identifying the friction first.
    #[arg(long)]
    pub keep_friction: bool,
    /// Log with the lead as the rig file has it, instead of fitting the
    /// screw's lead from the logs first.
    #[arg(long)]
    pub keep_lead: bool,
}

/// The bar: the whole route within 2 minutes on this machine.
pub const BAR_S: f64 = 120.0;

#[derive(Parser)]
struct TrainCli {
    #[command(flatten)]
    a: super::TrainArgs,
}

/// Largest |terminal − reference| (m) over a stroke out and back, with the
/// observer on or off, on a drive started from `store`.
fn stroke_error_m(rig: &RigConfig, store: &Path, compensation: bool) -> Result<f64> {
    let mut o = DriveOptions::new(rig.clone());
    o.commissioned = true;
    o.initial_position_m = 0.05;
    o.store = Some(store.to_path_buf());
    let mut d = SimDrive::new(o)?;
    let ask = |d: &mut SimDrive, request: Request| -> Result<()> {
        match d.handle(&RequestFrame { seq: 1, request }) {
            Some(DriveFrame::Reply { reply: Reply::Command(_), .. }) => Ok(()),
            other => Err(anyhow!("verify: {other:?}")),
        }
    };
    ask(&mut d, Request::Command(DriveCommand::SetCompensation { enabled: compensation }))?;
    ask(&mut d, Request::Command(DriveCommand::Enable))?;
    let mut sink = Vec::new();
    for _ in 0..600 {
        d.step_to_boundary(&mut sink);
    }
    let mut worst = 0.0f64;
    for x in [0.45f32, 0.05] {
        ask(&mut d, Request::Command(DriveCommand::MoveTo { position_m: x }))?;
        for _ in 0..3500 {
            d.step_to_boundary(&mut sink);
            let t = d.cl.controller.telemetry();
            if !t.faults.is_empty() {
                bail!("verify: fault {:?}", t.faults);
            }
            let scale = t.terminal_position_m.ok_or_else(|| anyhow!("verify: the rig has no linear scale"))?;
            worst = worst.max(f64::from(scale - t.position_reference_m).abs());
        }
    }
    Ok(worst)
}

/// What the route does on one rig.
#[derive(Clone, Debug)]
pub struct RoutePlan {
    /// Stroke cycles logged per payload.
    pub cycles: usize,
    /// Payloads logged, relative to the rig file's.
    pub payloads: Vec<f64>,
    /// Seeds: identification `seed`, logs `seed + 1 …`.
    pub seed: u64,
    /// Identify the friction and write it into the feedforward before logging.
    pub identify_friction: bool,
    /// Fit the screw's lead from short logs and write it into the drive's
    /// lead before the training logs.
    pub identify_lead: bool,
    /// Stroke cycles per payload of the lead's logs.
    pub lead_cycles: usize,
}

impl RoutePlan {
    pub fn new(cycles: usize) -> Self {
        Self { cycles, payloads: vec![0.02, 0.5, 1.0], seed: 20, identify_friction: true, identify_lead: true, lead_cycles: 2 }
    }
}

/// A route's result: the weights the drive runs after the upload, and the
/// rig with the drive's parameters as the route left them.
pub struct RouteOutcome {
    pub summary: serde_json::Value,
    pub weights: &'static servo_core::observer::block::Weights,
    pub rig: RigConfig,
    pub logged_s: f64,
    /// Motion in the training logs, and at most this in the lead's (s).
    pub moving_s: f64,
    pub total_s: f64,
}

/// Runs the route on `rig` into `out` (logs/, dataset/, observer/, flash.bin).
pub fn run_route(rig: &RigConfig, plan: &RoutePlan, out: &Path) -> Result<RouteOutcome> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let t_all = Instant::now();
    // 0. The friction, as `tune identify` finds it, into the feedforward:
    // a lag the speed loop leaves at each move start is not the observer's.
    let t = Instant::now();
    let (rig, friction) = if plan.identify_friction {
        let (tuned, ident) = crate::tuning::identify_friction_sim(rig, plan.seed)?;
        let lines: Vec<_> = crate::tuning::friction_param_set_lines(&tuned.control)
            .into_iter()
            .map(|(name, v)| serde_json::json!({ "name": name, "before": crate::tuning::friction_param_set_lines(&rig.control).iter().find(|(n, _)| *n == name).map(|(_, b)| *b), "after": v }))
            .collect();
        let note = serde_json::json!({ "identified_coulomb_n_m": ident.coulomb_n_m, "identified_viscous_n_m_s_rad": ident.viscous_n_m_s_rad, "param_set": lines });
        (tuned, note)
    } else {
        (rig.clone(), serde_json::Value::Null)
    };
    let identify_s = t.elapsed().as_secs_f64();
    // 1a. The lead, from its own short logs: every later log, the dataset
    // and the weights are then in the rod's metres.
    let t = Instant::now();
    let mut logged_s = 0.0;
    let (rig, lead) = if plan.identify_lead {
        let mut lead_logs = Vec::new();
        for (k, &p) in plan.payloads.iter().enumerate() {
            let path = out.join("logs_lead").join(format!("payload_{k}.csv"));
            logged_s += record(&rig, &LogPlan::strokes(p, plan.lead_cycles, plan.seed + 101 + k as u64), &path)?;
            lead_logs.push(path);
        }
        let before = rig.control.drive_train.screw_lead_m;
        let fit = super::lead::fit(&lead_logs, f64::from(before)).context("fitting the screw's lead from logs_lead/")?;
        let mut tuned = rig;
        tuned.control.drive_train.screw_lead_m = fit.lead_m as f32;
        tuned.control.validate().map_err(|e| anyhow!("the fitted lead does not validate: {e:?}"))?;
        let note = serde_json::json!({ "fit": fit, "param_set": [{ "name": "drive_train.screw_lead_m", "before": before, "after": tuned.control.drive_train.screw_lead_m }] });
        (tuned, note)
    } else {
        (rig, serde_json::Value::Null)
    };
    let lead_logged_s = logged_s;
    let lead_s = t.elapsed().as_secs_f64();
    // 1. Logs, as a user records them at each payload.
    let t = Instant::now();
    let mut logs = Vec::new();
    for (k, &p) in plan.payloads.iter().enumerate() {
        let path = out.join("logs").join(format!("payload_{k}.csv"));
        logged_s += record(&rig, &LogPlan::strokes(p, plan.cycles, plan.seed + 1 + k as u64), &path)?;
        logs.push(path);
    }
    let log_s = t.elapsed().as_secs_f64();
    // 2. Dataset.
    let t = Instant::now();
    let mut o = LogOptions::new(f64::from(rig.control.drive_train.screw_lead_m));
    o.force_source = Some(servo_core::protocol::observer::force_source(&rig.control));
    let (ds, ls) = from_logs::convert(&logs, &o)?;
    let data = out.join("dataset").join("dataset.csv");
    std::fs::create_dir_all(out.join("dataset"))?;
    ds.write_csv(&data)?;
    let dataset_s = t.elapsed().as_secs_f64();
    // 3. Train, as documented (8 hidden units, the firmware's).
    let t = Instant::now();
    let model_dir = out.join("observer");
    let argv = ["train", "--data", &data.display().to_string(), "--out", &model_dir.display().to_string(), "--hidden", "8", "--no-baselines", "--no-progress"];
    let cli = TrainCli::try_parse_from(argv).map_err(|e| anyhow!("train arguments: {e}"))?;
    let report = super::run_cli(&cli.a)?;
    let train_s = t.elapsed().as_secs_f64();
    // 4. Upload to a simulated drive over TCP, verified by CRC.
    let t = Instant::now();
    let store = out.join("flash.bin");
    let _ = std::fs::remove_file(&store);
    let mut opts = DriveOptions::new(rig.clone());
    opts.pace = Pace::Fast;
    opts.commissioned = true;
    opts.store = Some(store.clone());
    let (addr, stop, thread) = drive::spawn_local(opts)?;
    let (weights, source) = obs::read_model_file(&model_dir.join("model.json"))?;
    let uploaded = (|| -> Result<_> {
        let mut c = Client::connect(&Endpoint::Tcp(addr.to_string()))?;
        obs::upload(&mut c, &weights, source)
    })();
    stop.store(true, Ordering::Relaxed);
    thread.join().map_err(|_| anyhow!("the simulated drive's thread panicked"))??;
    let status = uploaded?;
    let upload_s = t.elapsed().as_secs_f64();
    // 5. Verify: restarted from its store the drive runs the same words; a
    // stroke at full payload with the observer on and off.
    let t = Instant::now();
    let restarted = SimDrive::new({
        let mut o = DriveOptions::new(rig.clone());
        o.store = Some(store.clone());
        o
    })?;
    let running = restarted.cl.controller.observer_weights();
    if words_crc(running) != words_crc(&weights) || status.source != ObserverSource::Uploaded {
        bail!("verify: the restarted drive runs other weights ({})", restarted.boot_note);
    }
    let off = stroke_error_m(&rig, &store, false)?;
    let on = stroke_error_m(&rig, &store, true)?;
    let verify_s = t.elapsed().as_secs_f64();
    let total_s = t_all.elapsed().as_secs_f64();
    let summary = serde_json::json!({
        "command": "host-sim observer-route",
        "stages_s": { "identify_friction": identify_s, "lead": lead_s, "log": log_s, "dataset": dataset_s, "train": train_s, "upload": upload_s, "verify": verify_s },
        "total_s": total_s,
        "bar_s": BAR_S,
        "within_bar": total_s <= BAR_S,
        "friction_feedforward": friction,
        "lead": lead,
        "lead_logged_drive_time_s": lead_logged_s,
        "logged_drive_time_s": logged_s,
        "payload_scales": plan.payloads,
        "dataset": { "runs_elongation": ls.runs_elongation, "runs_contraction": ls.runs_contraction, "samples": ls.samples,
                     "moving_s": ls.moving_s, "load_force_n": [ls.load_force_min_n, ls.load_force_max_n] },
        "train": { "hidden": report.hidden, "test_rmse_um": report.test.rmse_um, "test_uncompensated_rmse_um": report.test_uncompensated.rmse_um },
        "upload": { "words_crc": format!("{:08x}", status.words_crc) },
        "verify_stroke_full_payload": {
            "max_terminal_error_um_observer_off": off * 1e6,
            "max_terminal_error_um_observer_on": on * 1e6,
            "reduction_pct": 100.0 * (1.0 - on / off),
        },
    });
    Ok(RouteOutcome { summary, weights: running, rig, logged_s, moving_s: ls.moving_s + lead_logged_s, total_s })
}

/// Runs the route; writes `out/summary.json`.
pub fn run(a: &RouteArgs) -> Result<serde_json::Value> {
    let rig = RigConfig::load_or_nominal(a.params.as_ref())?;
    let mut plan = RoutePlan::new(a.cycles);
    plan.identify_friction = !a.keep_friction;
    plan.identify_lead = !a.keep_lead;
    let r = run_route(&rig, &plan, &a.out)?;
    std::fs::write(a.out.join("summary.json"), serde_json::to_string_pretty(&r.summary)?)?;
    println!("{}", serde_json::to_string_pretty(&r.summary)?);
    Ok(r.summary)
}
