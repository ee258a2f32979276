//! Logs as a rig writes them, from the simulated drive: moves back and
//! forth over the stroke at one payload, every telemetry field recorded at
//! a fixed rate into the CSV `drive telemetry --csv` writes. For tests and
//! the route benchmark; a bench records the same file with the host tool.

use crate::config::RigConfig;
use crate::drive::{DriveOptions, SimDrive};
use crate::tool::view::TELEMETRY_NAMES;
use anyhow::{anyhow, bail, Context, Result};
use servo_core::protocol::{DriveCommand, DriveFrame, Reply, Request, RequestFrame, TelemetryField};
use std::path::Path;

/// What to log.
#[derive(Clone, Debug)]
pub struct LogPlan {
    /// Payload relative to the rig file's.
    pub payload_scale: f64,
    /// Where the rod stands when logging starts (m).
    pub start_m: f64,
    /// Positions moved to in turn (m), each followed by `dwell_s`.
    pub targets_m: Vec<f32>,
    /// Held at rest after the brake has let go, before the first move.
    pub settle_s: f64,
    pub dwell_s: f64,
    /// Telemetry rate (Hz).
    pub rate_hz: u16,
    /// Observer compensation on while logging.
    pub compensation: bool,
    pub seed: u64,
}

impl LogPlan {
    /// `cycles` strokes out and back over the whole travel used, 0 to
    /// 0.45 m, with shorter moves in between (the loads at several
    /// speeds). The network clamps the displacement to the range it saw,
    /// so the ends of the travel must be in the log. Logged as the drive
    /// runs in service: compensation on (the shift's rate is fed forward
    /// during moves, which shapes the speed and force at each move start),
    /// and the first move from a settled hold, as after any enable.
    pub fn strokes(payload_scale: f64, cycles: usize, seed: u64) -> Self {
        let mut targets_m = Vec::new();
        for k in 0..cycles {
            let mid = 0.15 + 0.05 * (k % 3) as f32;
            targets_m.extend([0.45, mid, 0.35, 0.0]);
        }
        Self { payload_scale, start_m: 0.0, targets_m, settle_s: 0.5, dwell_s: 0.3, rate_hz: 200, compensation: true, seed }
    }
}

fn ask(d: &mut SimDrive, request: Request) -> Result<Reply> {
    let what = format!("{request:?}");
    match d.handle(&RequestFrame { seq: 1, request }) {
        Some(DriveFrame::Reply { reply: Reply::Error(e), .. }) => bail!("{what}: refused: {}", crate::tool::client::describe(&e)),
        Some(DriveFrame::Reply { reply, .. }) => Ok(reply),
        other => Err(anyhow!("{what}: answered {other:?}")),
    }
}

/// Runs the plan on a simulated drive of `rig` and writes the telemetry
/// log to `path`; the seconds of drive time logged.
pub fn record(rig: &RigConfig, plan: &LogPlan, path: &Path) -> Result<f64> {
    let mut rig = rig.clone();
    rig.plant.rod.payload_mass_kg *= plan.payload_scale;
    let mut o = DriveOptions::new(rig);
    o.commissioned = true;
    o.initial_position_m = plan.start_m;
    o.seed = plan.seed;
    let mut d = SimDrive::new(o)?;
    if plan.compensation {
        ask(&mut d, Request::Command(DriveCommand::SetCompensation { enabled: true }))?;
    }
    ask(&mut d, Request::Command(DriveCommand::Enable))?;
    ask(&mut d, Request::Telemetry { fields: (1u32 << TelemetryField::COUNT) - 1, rate_hz: plan.rate_hz })?;
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut w = csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
    let mut header = vec!["time_s"];
    header.extend(TELEMETRY_NAMES);
    w.write_record(&header)?;
    let mut frames = Vec::new();
    let period = d.divider() as f64 / d.pwm_hz();
    let mut write = |frames: &mut Vec<servo_core::protocol::TelemetryFrame>| -> Result<()> {
        for t in frames.drain(..) {
            let mut row = vec![format!("{}", t.time_s)];
            for (i, v) in t.values.iter().enumerate() {
                row.push(if i == TelemetryField::Faults as usize { format!("{}", v.to_bits()) } else { format!("{v}") });
            }
            w.write_record(&row)?;
        }
        Ok(())
    };
    let t0 = d.cl.time_s();
    // Enabling (brake release) first.
    let mut k = 0;
    while d.cl.controller.mode() != servo_core::Mode::Running {
        d.step_to_boundary(&mut frames);
        k += 1;
        if k > 5000 {
            bail!("the simulated drive did not reach Running: {:?}", d.cl.controller.telemetry().faults);
        }
    }
    for _ in 0..((plan.settle_s / period).round() as usize) {
        d.step_to_boundary(&mut frames);
    }
    write(&mut frames)?;
    for &x in &plan.targets_m {
        ask(&mut d, Request::Command(DriveCommand::MoveTo { position_m: x }))?;
        let mut steps = 0;
        // The move, then the dwell.
        loop {
            d.step_to_boundary(&mut frames);
            steps += 1;
            let t = d.cl.controller.telemetry();
            if !t.faults.is_empty() {
                bail!("fault while logging: {:?}", t.faults);
            }
            if (t.position_reference_m - x).abs() < 1e-7 || f64::from(steps) * period > 10.0 {
                break;
            }
        }
        for _ in 0..((plan.dwell_s / period).round() as usize) {
            d.step_to_boundary(&mut frames);
        }
        write(&mut frames)?;
    }
    w.flush()?;
    Ok(d.cl.time_s() - t0)
}
