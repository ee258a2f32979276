//! `host-sim drive …`: each command line run, on a simulated drive the
//! tool starts itself or over a connection.

use super::access::{command, fetch_one_f32, info_json, param_get, param_list, param_set, reply_text};
use super::cli::{DriveArgs, DriveCmd, IdentifyCmd, ObserverCmd, ParamCmd};
use super::client::Client;
use super::{bench, bench_asap, bench_family, moves, test, config_file, observer, params, stiffness, stream_cmd, stream_loss, view, watch_bench};
use super::scope::{capture, signal_by_name};
use crate::config::RigConfig;
use crate::drive::{self, DriveOptions};
use anyhow::{bail, Context, Result};
use servo_core::protocol::{CaptureTrigger, DriveCommand, Reply, Request};
use std::time::Duration;

pub fn run_cli(a: DriveArgs) -> Result<()> {
    match a.cmd {
        DriveCmd::Serve { listen, params, pace, store, commissioned, initial_position_m, stream_period_s } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            check_serve(&rig, initial_position_m, stream_period_s)?;
            let mut o = DriveOptions::new(rig);
            o.pace = pace;
            o.store = store;
            o.commissioned = commissioned;
            o.initial_position_m = initial_position_m;
            if let Some(s) = stream_period_s {
                o.stream_period_s = s;
            }
            let l = std::net::TcpListener::bind(&listen).with_context(|| format!("binding {listen}"))?;
            eprintln!("drive: serving on {} ({pace:?} pacing)", l.local_addr()?);
            drive::serve(l, o, Default::default())
        }
        DriveCmd::Log { input, out } => {
            let log = crate::diagnose::log::read_any(&input)?;
            for i in &log.issues {
                eprintln!("{i}");
            }
            log.write_csv(&out)?;
            println!("{} rows → {}", log.len(), out.display());
            Ok(())
        }
        DriveCmd::BenchStreamLoss { out, params } => {
            let s = stream_loss::run(&RigConfig::load_or_nominal(params.as_ref())?, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
            Ok(())
        }
        DriveCmd::BenchStream { out, family: Some(dir), tune_filter, .. } => {
            let rigs = crate::rigs::load_family(&dir)?;
            let s = bench_family::run_family(&rigs, &dir, tune_filter, &out)?;
            print!("{}", std::fs::read_to_string(out.join("family.md"))?);
            println!("worst: {}", serde_json::to_string_pretty(&s["worst"])?);
            println!("{} of {} rigs pass; wrote {}/{{summary.json, family.md}} and a folder per rig", s["rigs_passed"], s["rigs"], out.display());
            if s["rigs_passed"] != s["rigs"] {
                bail!("drive bench-stream: rigs failed: {}", s["rigs_failed"]);
            }
            Ok(())
        }
        DriveCmd::BenchStream { out, params, family: None, .. } => {
            let s = bench::run(&RigConfig::load_or_nominal(params.as_ref())?, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
            let why = bench_family::misses(&s);
            if !why.is_empty() {
                bail!("drive bench-stream: the stream missed its requirement: {} (summary: {})", why.join("; "), out.join("summary.json").display());
            }
            Ok(())
        }
        DriveCmd::BenchAsap { out, params, seconds, rate_hz } => {
            let s = bench_asap::run(&RigConfig::load_or_nominal(params.as_ref())?, &out, seconds, rate_hz)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
            Ok(())
        }
        DriveCmd::BenchWatch { out, params, rate_hz, seconds } => {
            let s = watch_bench::run(&RigConfig::load_or_nominal(params.as_ref())?, &out, rate_hz, seconds)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
            if s["refresh_ok"] != serde_json::Value::Bool(true) {
                bail!("`watch` refreshed at {} Hz, below {} Hz: {}", s["refresh_hz"], watch_bench::REFRESH_MIN_HZ, out.join("summary.json").display());
            }
            Ok(())
        }
        cmd => {
            let mut c = a.conn.connect()?;
            run_on(&mut c, cmd)
        }
    }
}

fn run_on(c: &mut Client, cmd: DriveCmd) -> Result<()> {
    match cmd {
        DriveCmd::Info => println!("{}", serde_json::to_string_pretty(&info_json(c)?)?),
        DriveCmd::Status { json } => {
            let s = view::status(c)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&view::status_json(&s))?);
            } else {
                let per_rad = fetch_one_f32(c, "drive_train.screw_lead_m").map(|l| l / std::f32::consts::TAU);
                for (k, v) in view::status_lines(&s, per_rad) {
                    println!("{k:<12} {v}");
                }
            }
            if s.faults != 0 {
                bail!("faults latched: {}; next: {}", view::fault_names(s.faults).join(", "), view::next_step(&s));
            }
        }
        DriveCmd::Watch { rate_hz, seconds } => {
            let n = view::watch(c, rate_hz, seconds)?;
            eprintln!("{n} refreshes");
        }
        DriveCmd::Telemetry { csv, rate_hz, seconds } => {
            let n = view::telemetry_csv(c, &csv, rate_hz, seconds)?;
            println!("{n} records → {}", csv.display());
            if n == 0 {
                bail!("no telemetry arrived in {seconds} s");
            }
        }
        DriveCmd::Observer(o) => {
            let s = match o {
                ObserverCmd::Status => observer::status(c)?,
                ObserverCmd::Upload { model } => {
                    let (w, source) = observer::read_model_file(&model)?;
                    observer::upload(c, &w, source).with_context(|| format!("uploading {} (trained on the {})", model.display(), source.name()))?
                }
                ObserverCmd::Compiled => observer::use_compiled(c)?,
            };
            println!("{}", observer::describe_status(&s));
        }
        DriveCmd::Identify(IdentifyCmd::Stiffness { params, out, upload, step_a, repeats }) => {
            let design = RigConfig::load_or_nominal(params.as_ref())?;
            let o = stiffness::ProbeOptions { step_a, repeats, ..Default::default() };
            let s = stiffness::run(c, &design, &o, upload, &out)?;
            println!("{}", stiffness::describe(&s));
            println!("wrote {}", out.join("stiffness.json").display());
        }
        DriveCmd::Param(p) => match p {
            ParamCmd::List => {
                for line in config_file::list_lines(&param_list(c)?) {
                    println!("{line}");
                }
            }
            ParamCmd::Get { path } => {
                let full = params::full_path(&path);
                println!("{}", params::value_text_at(&full, &param_get(c, &path)?));
            }
            ParamCmd::Set { path, value } => {
                let full = params::full_path(&path);
                println!("{full} = {}", params::value_text_at(&full, &param_set(c, &path, &value)?));
            }
            ParamCmd::Save => {
                c.ask(Request::Save)?;
                println!("saved");
            }
            ParamCmd::Load => match c.ask(Request::Load)? {
                Reply::Loaded { note, .. } => println!("loaded: {note}"),
                r => bail!("Load answered with {r:?}"),
            },
            ParamCmd::Defaults => {
                c.ask(Request::Defaults)?;
                println!("image defaults applied (`param save` writes them to flash)");
            }
            ParamCmd::Export { file } => {
                let n = config_file::export(c, &file)?;
                println!("{n} parameters → {}", file.display());
            }
            ParamCmd::Import { file } => {
                let changed = config_file::import(c, &file)?;
                println!("{} parameters changed from {} ({})", changed.len(), file.display(), changed.join(", "));
            }
        },
        DriveCmd::Cmd { name, arg } => println!("{}", reply_text(&command(c, &name, arg.as_deref())?)),
        DriveCmd::Move { position_m } => {
            moves::within_stroke(c, &format!("move {position_m}"), position_m)?;
            println!("{}", reply_text(&c.ask(Request::Command(DriveCommand::MoveTo { position_m: position_m as f32 }))?))
        }
        DriveCmd::Jog { distance_m } => {
            moves::check_jog(c, distance_m)?;
            println!("{}", reply_text(&c.ask(Request::Command(DriveCommand::Jog { distance_m: distance_m as f32 }))?))
        }
        DriveCmd::SetHome { position_m } => {
            println!("{}", reply_text(&c.ask(Request::Command(DriveCommand::SetHome { position_m: position_m as f32 }))?))
        }
        DriveCmd::Stream { file, asap, out } => stream_cmd::run(c, &file, asap, &out)?,
        DriveCmd::Step { target, amplitude, duration, out, params } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let spec = test::Spec::step(target, amplitude, duration);
            let s = test::run(c, &rig, &spec, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
        }
        DriveCmd::Chirp { target, amplitude, from, to, duration, out, params } => {
            let rig = RigConfig::load_or_nominal(params.as_ref())?;
            let spec = test::Spec::chirp(target, amplitude, from, to, duration);
            let s = test::run(c, &rig, &spec, &out)?;
            println!("{}", serde_json::to_string_pretty(&s)?);
        }
        DriveCmd::Capture { signals, samples, decimation, trigger, pre_trigger, out, wait_s } => {
            let sigs = signals.iter().map(|s| signal_by_name(s)).collect::<Result<Vec<_>>>()?;
            let trig = match trigger.as_str() {
                "command" => CaptureTrigger::Command,
                "fault" => CaptureTrigger::Fault,
                "test" => CaptureTrigger::TestStart,
                t => bail!("--trigger: `{t}`; one of command, fault, test"),
            };
            let cap = capture(c, &sigs, samples, decimation, pre_trigger, trig, Duration::from_secs_f64(wait_s))?;
            cap.write_csv(&out)?;
            println!("{} signals × {} samples at {:.1} Hz → {}", cap.names.len(), cap.len(), 1.0 / cap.dt_s, out.display());
        }
        DriveCmd::Serve { .. } | DriveCmd::Log { .. } | DriveCmd::BenchAsap { .. } | DriveCmd::BenchStream { .. } | DriveCmd::BenchStreamLoss { .. } | DriveCmd::BenchWatch { .. } => {
            bail!("not a command for a connected drive")
        }
    }
    Ok(())
}

/// `serve`'s options against the rig: the rod starts within the stroke, and
/// a stream period is one the drive interpolates.
fn check_serve(rig: &RigConfig, initial_position_m: f64, stream_period_s: Option<f64>) -> Result<()> {
    let l = &rig.control.limits;
    let (lo, hi) = (f64::from(l.stroke_min_m), f64::from(l.stroke_max_m));
    if !(lo..=hi).contains(&initial_position_m) {
        bail!(
            "--initial-position-m {initial_position_m}: outside the rig's stroke {lo} … {hi} m (control.limits.stroke_min_m, stroke_max_m){}",
            super::moves::millimetre_hint(initial_position_m, lo, hi)
        );
    }
    if let Some(t) = stream_period_s {
        let (fastest, slowest) = (f64::from(rig.control.position_period_s()), f64::from(rig.control.stream.period_max_s));
        let tol = super::stream::PERIOD_TOLERANCE;
        if t < fastest * (1.0 - tol) || t > slowest * (1.0 + tol) {
            bail!("--stream-period-s {t}: the drive interpolates streams at {fastest} … {slowest} s per point (the position-loop period … control.stream.period_max_s)");
        }
    }
    Ok(())
}
