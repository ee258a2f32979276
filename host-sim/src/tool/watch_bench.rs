//! `drive bench-watch`: how often `drive watch` refreshes, measured. A
//! simulated drive in real-time pacing; one client enables it and moves
//! the rod out and back (the view is meant to run beside a controlling
//! client); a second, read-only client runs the very `watch` loop drawing
//! into an off-screen ratatui `TestBackend` (the same widgets and layout
//! as on a terminal, without one). Figures: frames, refresh rate, the
//! spread of the frame intervals, what the last frame shows.

use super::client::{Client, Endpoint};
use super::test::wait_running;
use super::view;
use crate::config::RigConfig;
use crate::drive::{self, DriveOptions, Pace};
use anyhow::{Context, Result};
use servo_core::protocol::{DriveCommand, Request};
use std::path::Path;
use std::time::Duration;

/// The bar for the live view, Hz.
pub const REFRESH_MIN_HZ: f64 = 10.0;
/// Size of the off-screen terminal (a common 100 × 30 window).
const COLUMNS: u16 = 100;
const LINES: u16 = 30;

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

pub fn run(rig: &RigConfig, out: &Path, rate_hz: f64, seconds: f64) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out)?;
    let mut o = DriveOptions::new(rig.clone());
    o.pace = Pace::Realtime;
    o.commissioned = true;
    let x0 = o.initial_position_m;
    let (addr, stop, h) = drive::spawn_local(o)?;
    let endpoint = Endpoint::Tcp(addr.to_string());
    let result = (|| -> Result<serde_json::Value> {
        let mut control = Client::connect(&endpoint)?;
        control.timeout = Duration::from_secs(10);
        control.ask(Request::Command(DriveCommand::Enable))?;
        wait_running(&mut control)?;
        // Out 20 mm and back while the view runs, then hold control.
        let mover = std::thread::spawn(move || -> Result<()> {
            for target in [x0 + 0.02, x0] {
                control.ask(Request::Command(DriveCommand::MoveTo { position_m: target as f32 }))?;
                std::thread::sleep(Duration::from_secs_f64(0.5 * seconds));
            }
            Ok(())
        });
        let mut watcher = Client::connect(&endpoint)?;
        let mut terminal = ratatui::Terminal::new(ratatui::backend::TestBackend::new(COLUMNS, LINES)).context("the off-screen terminal")?;
        let run = view::watch_on(&mut terminal, &mut watcher, rate_hz, seconds, false)?;
        mover.join().map_err(|_| anyhow::anyhow!("the controlling client panicked"))??;
        let screen: String = terminal.backend().buffer().content().iter().map(|c| c.symbol()).collect();
        let mut intervals = run.intervals_s.clone();
        intervals.sort_by(f64::total_cmp);
        // Frame to frame: the first status round trip is no refresh interval.
        let span_s: f64 = intervals.iter().sum();
        let refresh_hz = if span_s > 0.0 { intervals.len() as f64 / span_s } else { 0.0 };
        let summary = serde_json::json!({
            "asked_rate_hz": rate_hz,
            "seconds": run.seconds,
            "frames": run.frames,
            "refresh_hz": refresh_hz,
            "interval_ms": {
                "median": percentile(&intervals, 0.5) * 1e3,
                "p95": percentile(&intervals, 0.95) * 1e3,
                "max": intervals.last().copied().unwrap_or(f64::NAN) * 1e3,
            },
            "bar_hz": REFRESH_MIN_HZ,
            "refresh_ok": refresh_hz >= REFRESH_MIN_HZ,
            "last_frame_shows_running": screen.contains("Running"),
            "terminal": format!("{COLUMNS}x{LINES} (ratatui TestBackend)"),
            "beside": "a controlling client moving the rod 20 mm out and back",
        });
        std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
        Ok(summary)
    })();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().map_err(|_| anyhow::anyhow!("drive thread panicked"))??;
    result
}
