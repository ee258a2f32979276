//! Seeing the drive: `status` in words, `watch` (a live terminal view,
//! ratatui), `telemetry --csv` (records to a file).

use super::client::Client;
use anyhow::{bail, Context, Result};
use servo_core::protocol::{BootRecord, Reply, Request, Status, TelemetryField};
use servo_core::{FaultSet, Mode};
use std::path::Path;
use std::time::{Duration, Instant};

pub fn status(c: &mut Client) -> Result<Status> {
    match c.ask(Request::Status)? {
        Reply::Status(s) => Ok(s),
        r => bail!("Status answered with {r:?}"),
    }
}

pub fn fault_names(bits: u32) -> Vec<&'static str> {
    FaultSet::from_bits_retain(bits).names().collect()
}

pub fn readiness_names(bits: u8) -> Vec<&'static str> {
    [(1u8, "calibrated"), (2, "commutated"), (4, "homed")].iter().filter(|(b, _)| bits & b != 0).map(|(_, n)| *n).collect()
}

pub fn boot_record_text(b: &BootRecord) -> String {
    match b {
        BootRecord::Unknown => "not reported by this drive".into(),
        BootRecord::NoRecord => "no saved record: image defaults".into(),
        BootRecord::Loaded => "saved record loaded".into(),
        BootRecord::Rejected { why, leaf } if *leaf != u16::MAX => {
            format!("saved record REJECTED at power-up ({why:?}, `{}`): image defaults run; `param save` writes the present set", super::client::param_path(*leaf))
        }
        BootRecord::Rejected { why, .. } => format!("saved record REJECTED at power-up ({why:?}): image defaults run; `param save` writes the present set"),
    }
}

/// The next command for a drive in this state.
pub fn next_step(s: &Status) -> &'static str {
    let homed = s.readiness & 4 != 0;
    let commutated = s.readiness & 2 != 0;
    if s.faults != 0 {
        return "`cmd clear-faults`, then `cmd enable`";
    }
    match s.mode {
        Mode::Fault => "`cmd clear-faults`",
        Mode::Disabled if !commutated || !homed => "`cmd startup` (calibration, commutation, homing)",
        Mode::Disabled => "`cmd enable`",
        Mode::Running => "`move POSITION_M`, `jog DISTANCE_M` or `stream FILE.csv`",
        _ => "wait (`status`), or `cmd stop`",
    }
}

/// `status` as lines of `name  value`.
pub fn status_lines(s: &Status, metres_per_rad: Option<f32>) -> Vec<(String, String)> {
    let faults = fault_names(s.faults);
    let rod = metres_per_rad.map(|r| format!(" ({:.1} mm/s at the rod)", s.speed_rad_s * r * 1e3)).unwrap_or_default();
    vec![
        ("mode".into(), format!("{:?}", s.mode)),
        ("faults".into(), if faults.is_empty() { "none".into() } else { faults.join(", ") }),
        ("readiness".into(), {
            let r = readiness_names(s.readiness);
            if r.is_empty() { "nothing known (power-up)".into() } else { r.join(", ") }
        }),
        ("position".into(), format!("{:.6} m", s.position_m)),
        ("speed".into(), format!("{:.2} rad/s{rod}", s.speed_rad_s)),
        ("current".into(), format!("d {:.2} A, q {:.2} A", s.current_d_a, s.current_q_a)),
        ("bus".into(), format!("{:.1} V", s.bus_voltage_v)),
        ("winding".into(), if s.winding_thermal_level.is_finite() { format!("{:.2} of its continuous rating (I²t model)", s.winding_thermal_level) } else { "not reported".into() }),
        ("power stage".into(), s.power_stage_temperature_c.map_or("not measured".into(), |t| format!("{t:.1} °C"))),
        ("record".into(), boot_record_text(&s.boot_record)),
        ("test".into(), if s.test_running { "running".into() } else { "none".into() }),
        ("drive time".into(), format!("{:.3} s", s.time_s)),
        ("next".into(), next_step(s).into()),
    ]
}

pub fn status_json(s: &Status) -> serde_json::Value {
    serde_json::json!({
        "mode": format!("{:?}", s.mode),
        "faults": fault_names(s.faults),
        "readiness": readiness_names(s.readiness),
        "position_m": s.position_m,
        "speed_rad_s": s.speed_rad_s,
        "current_d_a": s.current_d_a,
        "current_q_a": s.current_q_a,
        "bus_voltage_v": s.bus_voltage_v,
        "winding_thermal_level": if s.winding_thermal_level.is_finite() { Some(s.winding_thermal_level) } else { None },
        "power_stage_temperature_c": s.power_stage_temperature_c,
        "boot_record": boot_record_text(&s.boot_record),
        "test_running": s.test_running,
        "time_s": s.time_s,
        "next": next_step(s),
    })
}

/// Every telemetry field, by name, in bit order.
pub const TELEMETRY_NAMES: [&str; TelemetryField::COUNT as usize] = [
    "position_reference_m",
    "position_command_m",
    "position_shift_m",
    "motor_position_m",
    "speed_reference_rad_s",
    "speed_rad_s",
    "current_d_a",
    "current_q_a",
    "current_q_reference_a",
    "voltage_d_v",
    "voltage_q_v",
    "bus_voltage_v",
    "terminal_position_m",
    "load_force_estimate_n",
    "mode",
    "faults",
    "readiness",
];

/// Records every telemetry field at `rate_hz` for `seconds` into `path`
/// as CSV: `time_s` and one column per field
/// (`faults` as its bits, an integer). Returns the records written.
pub fn telemetry_csv(c: &mut Client, path: &Path, rate_hz: u16, seconds: f64) -> Result<usize> {
    let fields = (1u32 << TelemetryField::COUNT) - 1;
    c.ask(Request::Telemetry { fields, rate_hz })?;
    if let Some(d) = path.parent() {
        std::fs::create_dir_all(d).ok();
    }
    let mut w = csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
    let mut header = vec!["time_s"];
    header.extend(TELEMETRY_NAMES);
    w.write_record(&header)?;
    let t0 = Instant::now();
    let mut n = 0;
    while t0.elapsed().as_secs_f64() < seconds {
        c.poll(Duration::from_millis(20))?;
        for t in c.telemetry.drain(..) {
            let mut row = vec![format!("{}", t.time_s)];
            for (i, v) in t.values.iter().enumerate() {
                row.push(if i == TelemetryField::Faults as usize { format!("{}", v.to_bits()) } else { format!("{v}") });
            }
            w.write_record(&row)?;
            n += 1;
        }
    }
    c.ask(Request::Telemetry { fields: 0, rate_hz: 0 })?;
    w.flush()?;
    Ok(n)
}

/// The live view: status and the main readouts, `rate_hz` times a second,
/// until `q` or Esc (or `seconds`, if > 0). Read-only: works beside a
/// controlling client.
pub fn watch(c: &mut Client, rate_hz: f64, seconds: f64) -> Result<usize> {
    if !std::io::IsTerminal::is_terminal(&std::io::stdout()) {
        bail!("`watch` needs a terminal; for a record, use `telemetry --csv FILE`, for one look `status`");
    }
    let mut terminal = ratatui::try_init().context("opening the terminal for `watch`")?;
    let result = watch_on(&mut terminal, c, rate_hz, seconds, true);
    ratatui::restore();
    result.map(|r| r.frames)
}

/// What a `watch` run drew.
#[derive(Clone, Debug, Default)]
pub struct WatchRun {
    pub frames: usize,
    /// Wall-clock seconds from the first status request to the last frame.
    pub seconds: f64,
    /// Seconds from one frame drawn to the next.
    pub intervals_s: Vec<f64>,
}

/// [`watch`] on any ratatui backend (the bench and the tests draw into a
/// `TestBackend`); `keys`: q or Esc end it (a terminal's), else it sleeps
/// out each period.
pub fn watch_on<B: ratatui::backend::Backend>(
    terminal: &mut ratatui::Terminal<B>,
    c: &mut Client,
    rate_hz: f64,
    seconds: f64,
    keys: bool,
) -> Result<WatchRun> {
    use ratatui::crossterm::event::{self, Event, KeyCode};
    use ratatui::layout::{Constraint, Layout};
    use ratatui::style::{Color, Style};
    use ratatui::widgets::{Block, Borders, Row, Sparkline, Table};
    let period = Duration::from_secs_f64(1.0 / rate_hz.max(1.0));
    let t0 = Instant::now();
    let mut run = WatchRun::default();
    let mut last_frame: Option<Instant> = None;
    let mut history: Vec<u64> = Vec::new();
    loop {
        let tick = Instant::now();
        let s = status(c)?;
        history.push((s.current_q_a.abs() * 100.0) as u64);
        if history.len() > 200 {
            history.remove(0);
        }
        let lines = status_lines(&s, None);
        let elapsed = t0.elapsed().as_secs_f64();
        let rate = if elapsed > 0.0 { run.frames as f64 / elapsed } else { 0.0 };
        terminal
            .draw(|f| {
                let [top, bottom] = Layout::vertical([Constraint::Min(15), Constraint::Length(6)]).areas(f.area());
                let rows = lines.iter().map(|(k, v)| {
                    let style = if k == "faults" && s.faults != 0 { Style::default().fg(Color::Red) } else { Style::default() };
                    Row::new(vec![k.clone(), v.clone()]).style(style)
                });
                let table = Table::new(rows, [Constraint::Length(12), Constraint::Min(20)])
                    .block(Block::default().borders(Borders::ALL).title(format!(" drive · {rate:.0} Hz · q: quit ")));
                f.render_widget(table, top);
                let spark = Sparkline::default().block(Block::default().borders(Borders::ALL).title(" |i_q| (cA) ")).data(&history);
                f.render_widget(spark, bottom);
            })
            .map_err(|e| anyhow::anyhow!("drawing the view: {e}"))?;
        let now = Instant::now();
        if let Some(l) = last_frame {
            run.intervals_s.push((now - l).as_secs_f64());
        }
        last_frame = Some(now);
        run.frames += 1;
        run.seconds = t0.elapsed().as_secs_f64();
        if seconds > 0.0 && run.seconds >= seconds {
            return Ok(run);
        }
        let left = period.saturating_sub(tick.elapsed());
        if keys {
            if event::poll(left)? {
                if let Event::Key(k) = event::read()? {
                    if matches!(k.code, KeyCode::Char('q') | KeyCode::Esc) {
                        return Ok(run);
                    }
                }
            }
        } else {
            std::thread::sleep(left);
        }
    }
}
