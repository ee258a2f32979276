//! `drive identify stiffness`: the cylinder's axial compliance against its
//! rig file's design (`trainer::stiffness`), measured on the drive through
//! the protocol, and the shipped observer weights scaled by it.
//!
//! On the drive: the q-current step with its capture, as `drive step
//! current` runs it, a few times. On the design: the same probe on a
//! simulated drive built from the rig file, first at the design's payload
//! (its hold current against the cylinder's gives the cylinder's payload),
//! then at that payload (the mode goes with the mass as with the
//! stiffness). The ratio of the squared frequencies is the compliance
//! ratio; the compiled weights' output scaled by it is the block the drive
//! runs (`drive observer upload`'s path, verified by CRC).

use super::access::fetch_one_f32;
use super::client::{Client, Endpoint};
use super::observer;
use super::test::{capture_test, wait_running, Spec, Target};
use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace};
use crate::trainer::stiffness::{self as st, ComplianceId, Rings};
use anyhow::{anyhow, bail, Context, Result};
use servo_core::observer::block::{ForceSource, Weights, COMPILED};
use servo_core::protocol::{DriveCommand, Reply, Request};
use servo_core::Mode;
use std::path::Path;
use std::time::{Duration, Instant};

/// How the probe runs.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct ProbeOptions {
    /// The current step from the hold current, A (positive: the load is
    /// thrown up).
    pub step_a: f64,
    pub repeats: usize,
    /// Drive time the rod rests before each probe, s.
    pub rest_s: f64,
}

impl Default for ProbeOptions {
    fn default() -> Self {
        Self { step_a: st::STEP_A, repeats: st::REPEATS, rest_s: REST_S }
    }
}

fn status(c: &mut Client) -> Result<servo_core::protocol::Status> {
    match c.ask(Request::Status)? {
        Reply::Status(s) => Ok(s),
        r => bail!("Status answered {r:?}"),
    }
}

/// The probe on a connected, running drive: `o.repeats` steps, each read
/// (`trainer::stiffness::ring_of`); the captures are written to `out`.
pub fn probe(c: &mut Client, o: &ProbeOptions, out: Option<&Path>) -> Result<Rings> {
    let s = status(c)?;
    if s.mode != Mode::Running || s.faults != 0 {
        bail!(
            "the drive is {:?}{}: the probe needs it enabled and holding the load (`drive cmd enable`)",
            s.mode,
            if s.faults != 0 { " with faults latched" } else { "" }
        );
    }
    let (Some(lo), Some(hi)) = (fetch_one_f32(c, "limits.stroke_min_m"), fetch_one_f32(c, "limits.stroke_max_m")) else {
        bail!("the drive's stroke (limits.stroke_min_m, stroke_max_m) could not be read");
    };
    let room = st::DROP_ROOM_M * o.repeats as f64;
    let x = f64::from(s.position_m);
    if x - f64::from(lo) < room || f64::from(hi) - x < room {
        bail!(
            "the rod is at {x:.4} m: the probe moves it up to {room:.3} m, which the stroke {lo} … {hi} m does not leave on both sides; `drive move` it to within {:.3} … {:.3} m first",
            f64::from(lo) + room,
            f64::from(hi) - room
        );
    }
    let pwm = f64::from(c.info.as_ref().map_or(20_000.0, |i| i.pwm_frequency_hz));
    let spec = Spec::step(Target::Current, o.step_a, st::STEP_S);
    let mut rings = Vec::new();
    for k in 0..o.repeats {
        at_rest(c, o.rest_s)?;
        let cap = capture_test(c, &spec, pwm).with_context(|| format!("probe {}", k + 1))?;
        if let Some(dir) = out {
            cap.write_csv(&dir.join(format!("probe_{}.csv", k + 1)))?;
        }
        let speed = cap.values.get(3).context("the capture has no speed")?;
        let ring = st::ring_of(speed, &cap.values[1], cap.dt_s, cap.trigger_index).with_context(|| format!("probe {}", k + 1))?;
        rings.push(ring);
        settle(c)?;
    }
    st::combine(rings)
}

/// Drive time the rod must have rested before a probe, s: the start-up
/// torque watch runs from `Enable` until the position loop first settles,
/// and reads a probe during it as a torque that does not make the motion.
const REST_S: f64 = 0.25;

/// Waits until the drive has held the rod at rest for [`REST_S`] of its
/// own time.
fn at_rest(c: &mut Client, rest_s: f64) -> Result<()> {
    let t0 = Instant::now();
    let mut since: Option<f32> = None;
    loop {
        let s = status(c)?;
        if s.faults != 0 || s.mode != Mode::Running {
            bail!("the drive left Running ({:?}, faults {:#x}) before the probe", s.mode, s.faults);
        }
        if s.test_running || s.speed_rad_s.abs() >= 0.5 {
            since = None;
        } else if f64::from(s.time_s - *since.get_or_insert(s.time_s)) >= rest_s {
            return Ok(());
        }
        if t0.elapsed() > Duration::from_secs(20) {
            bail!("the rod did not rest for {rest_s} s within 20 s (speed {:.2} rad/s): the probe needs it held still", s.speed_rad_s);
        }
        c.poll(Duration::from_millis(10))?;
        c.telemetry.clear();
    }
}

/// Waits until the test has ended and the drive holds again.
fn settle(c: &mut Client) -> Result<()> {
    let t0 = Instant::now();
    loop {
        let s = status(c)?;
        if s.faults != 0 {
            bail!("faults latched after the probe: {:?}", servo_core::FaultSet::from_bits_retain(s.faults).names().collect::<Vec<_>>());
        }
        if !s.test_running && s.speed_rad_s.abs() < 0.5 {
            return Ok(());
        }
        if t0.elapsed() > Duration::from_secs(10) {
            bail!("the drive did not come to rest after the probe (speed {:.2} rad/s)", s.speed_rad_s);
        }
        c.poll(Duration::from_millis(20))?;
        c.telemetry.clear();
    }
}

/// The probe on a simulated drive of `rig` at `position_m` (fast pacing,
/// commissioned, enabled).
pub fn probe_simulated(rig: &RigConfig, position_m: f64, seed: u64, o: &ProbeOptions) -> Result<Rings> {
    let mut opts = DriveOptions::new(rig.clone());
    opts.pace = Pace::Fast;
    opts.commissioned = true;
    opts.initial_position_m = position_m;
    opts.seed = seed;
    let (addr, stop, h) = drive::spawn_local(opts)?;
    let r = (|| {
        let mut c = Client::connect(&Endpoint::Tcp(addr.to_string()))?;
        c.ask(Request::Command(DriveCommand::Enable))?;
        wait_running(&mut c)?;
        probe(&mut c, o, None)
    })();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().map_err(|_| anyhow!("the simulated drive's thread panicked"))??;
    r
}

/// The design's side: its hold current at its own payload, then its rings
/// at the payload the cylinder's hold current says.
pub fn against_design(cylinder: &Rings, design: &RigConfig, position_m: f64, seed: u64, o: &ProbeOptions) -> Result<ComplianceId> {
    let own = probe_simulated(design, position_m, seed, o).context("the design at its own payload")?;
    let scale = st::payload_scale(design, cylinder.hold_a, own.hold_a)?;
    let mut matched = design.clone();
    matched.plant.rod.payload_mass_kg *= scale;
    let at = probe_simulated(&matched, position_m, seed.wrapping_add(1), o).context("the design at the cylinder's payload")?;
    st::compliance(cylinder, own.hold_a, scale, &at)
}

/// The whole identification on a simulated drive of `rig` (the bench and
/// the tests: the same code as on a board).
pub fn identify_simulated(rig: &RigConfig, design: &RigConfig, seed: u64) -> Result<ComplianceId> {
    identify_simulated_with(rig, design, seed, &ProbeOptions::default())
}

/// [`identify_simulated`] with the probe's options.
pub fn identify_simulated_with(rig: &RigConfig, design: &RigConfig, seed: u64, o: &ProbeOptions) -> Result<ComplianceId> {
    let x0 = crate::tuning::X0_M;
    let cylinder = probe_simulated(rig, x0, seed, o).context("the cylinder")?;
    against_design(&cylinder, design, x0, seed.wrapping_add(2), o)
}

/// The compiled weights scaled by the identified ratio.
pub fn scaled_block(id: &ComplianceId) -> Weights {
    st::scaled_weights(&COMPILED, id.compliance_ratio)
}

/// `drive identify stiffness`: probe, compare with the design, write
/// `out/stiffness.json` (and the captures); with `upload`, switch the
/// bridge off and upload the scaled weights (the compiled ones when the
/// ratio is within the test's resolution), verified by CRC.
pub fn run(c: &mut Client, design: &RigConfig, o: &ProbeOptions, upload: bool, out: &Path) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let x0 = f64::from(status(c)?.position_m);
    let cylinder = probe(c, o, Some(out)).context("the probe on the drive")?;
    let id = against_design(&cylinder, design, x0, 1, o)?;
    let w = scaled_block(&id);
    let (words, n) = servo_core::observer::block::to_block_words(&w, servo_core::observer::block::inputs_of(&w));
    let words = &words[..n];
    let mut summary = serde_json::json!({
        "probe": o,
        "position_m": x0,
        "cylinder": cylinder,
        "identified": id,
        "weights": {
            "what": "the compiled (shipped) weights, output scale and offset times the compliance ratio",
            "force_source": ForceSource::LoadCell.name(),
            "words_crc": format!("{:08x}", servo_core::protocol::observer::words_crc(&w)),
            "words": words.to_vec(),
        },
    });
    if upload {
        disable(c)?;
        let s = if id.compliance_ratio == 1.0 {
            observer::use_compiled(c)?
        } else {
            observer::upload(c, &w, ForceSource::LoadCell).context("uploading the scaled weights")?
        };
        summary["uploaded"] = serde_json::json!(observer::describe_status(&s));
    }
    std::fs::write(out.join("stiffness.json"), serde_json::to_string_pretty(&summary)?)?;
    Ok(summary)
}

/// Bridge off (the drive stores weights only then): `Disable`, then wait
/// for the mode to say so.
fn disable(c: &mut Client) -> Result<()> {
    c.ask(Request::Command(DriveCommand::Disable))?;
    let t0 = Instant::now();
    while status(c)?.mode != Mode::Disabled {
        if t0.elapsed() > Duration::from_secs(10) {
            bail!("the drive did not switch its bridge off within 10 s after `cmd disable`");
        }
        c.poll(Duration::from_millis(20))?;
        c.telemetry.clear();
    }
    Ok(())
}

/// One line per figure, for the terminal.
pub fn describe(s: &serde_json::Value) -> String {
    let i = &s["identified"];
    let mut t = format!(
        "axial mode {:.2} ± {:.2} Hz; the design's at this payload {:.2} ± {:.2} Hz (payload ×{:.3} from the hold current {:.2} A)\ncompliance ratio {:.3} ± {:.3} (noise ± {:.3}); applied {:.3}",
        i["mode_hz"].as_f64().unwrap_or(f64::NAN),
        i["mode_std_hz"].as_f64().unwrap_or(f64::NAN),
        i["design_mode_hz"].as_f64().unwrap_or(f64::NAN),
        i["design_mode_std_hz"].as_f64().unwrap_or(f64::NAN),
        i["payload_scale"].as_f64().unwrap_or(f64::NAN),
        i["hold_a"].as_f64().unwrap_or(f64::NAN),
        i["measured_ratio"].as_f64().unwrap_or(f64::NAN),
        i["ratio_uncertainty"].as_f64().unwrap_or(f64::NAN),
        i["ratio_std"].as_f64().unwrap_or(f64::NAN),
        i["compliance_ratio"].as_f64().unwrap_or(f64::NAN),
    );
    if let Some(u) = s["uploaded"].as_str() {
        t.push_str(&format!("\n{u}"));
    }
    t
}
