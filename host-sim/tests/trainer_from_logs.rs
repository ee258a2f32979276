//! From the drive's logs to the trainer's dataset: telemetry recorded on the
//! simulated drive is cut into runs by direction, its target is the linear
//! scale minus the motor side, and logs that lack what the model needs are
//! refused naming it.

use host_sim::config::RigConfig;
use host_sim::trainer::dataset::{Dataset, DatasetLimits, Direction};
use host_sim::trainer::from_logs::{convert, LogOptions};
use host_sim::trainer::log_moves::{record, LogPlan};
use std::path::{Path, PathBuf};

fn options() -> LogOptions {
    let mut o = LogOptions::new(f64::from(RigConfig::nominal().unwrap().control.drive_train.screw_lead_m));
    // The nominal rig logs with its load cell feeding the observer.
    o.force_source = Some(servo_core::observer::block::ForceSource::LoadCell);
    o
}

/// Logs at a light, a half and the full payload, as a user would record
/// them by changing the payload between recordings.
fn logs(dir: &Path, payloads: &[f64], cycles: usize) -> Vec<PathBuf> {
    let rig = RigConfig::nominal().unwrap();
    payloads
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            let path = dir.join(format!("payload_{k}.csv"));
            record(&rig, &LogPlan::strokes(p, cycles, 7 + k as u64), &path).unwrap();
            path
        })
        .collect()
}

#[test]
fn telemetry_logs_become_runs_by_direction_with_the_scale_as_target() {
    let dir = tempfile::tempdir().unwrap();
    let files = logs(dir.path(), &[0.02, 0.5, 1.0], 2);
    let (ds, s) = convert(&files, &options()).unwrap();
    assert_eq!(ds.force_source, servo_core::observer::block::ForceSource::LoadCell);
    // The telemetry's force column is whichever input the drive had
    // selected: without being told which, the conversion refuses.
    let untold = LogOptions { force_source: None, ..options() };
    let e = format!("{:#}", convert(&files, &untold).unwrap_err());
    assert!(e.contains("--force-source"), "{e}");
    // 2 cycles × (out, back, out, back) per payload: 4 moves a direction.
    assert_eq!((s.runs_elongation, s.runs_contraction), (12, 12), "{s:?}");
    // Logged with compensation on, as in service: the setpoint shift
    // ramping in after the enable moves the rod before the first move.
    // By its travel that is not a move: its rows open the first run.
    assert!(s.short_runs_left_out.is_empty(), "{:?}", s.short_runs_left_out);
    let (_, loose) = convert(&files, &LogOptions { min_run_travel_m: 0.0, ..options() }).unwrap();
    assert!(loose.runs_elongation > s.runs_elongation, "without the travel criterion the ramp-in counts as a move: {loose:?}");
    assert!(s.rows_before_first_move > 0, "the standstill before the first move is counted");
    let lead = f64::from(RigConfig::nominal().unwrap().control.drive_train.screw_lead_m);
    let mut runs_opening_files: Vec<&str> = Vec::new();
    for r in &ds.runs {
        if !ds.runs.iter().any(|q| q.source == r.source && q.first_line < r.first_line) {
            runs_opening_files.push(r.id.as_str());
        }
    }
    for r in &ds.runs {
        // Direction from the motion: the run's net travel has its sign.
        let travel = r.motor_side_position_m.last().unwrap() - r.motor_side_position_m[0];
        match r.direction {
            Direction::Elongation => assert!(travel > 0.05, "{} {travel}", r.id),
            Direction::Contraction => assert!(travel < -0.05, "{} {travel}", r.id),
        }
        for (x, e) in r.inputs.iter().zip(&r.terminal_error_m) {
            assert!((x[1] - x[0] * lead / std::f64::consts::TAU).abs() < 1e-12, "nut speed through the lead");
            assert!(e.abs() < 2e-3, "terminal error {e} m");
        }
        // The direction of travel, taken from the telemetry's planned
        // position: the run's own direction from its first sample, held
        // through the standstill, and turned only where the next move's
        // plan starts, before the rod's speed crosses the run threshold
        // (at most 50 ms of samples at the end).
        let want = if r.direction == Direction::Elongation { 1.0 } else { -1.0 };
        // A file's first run opens with the hold before any planned move,
        // where the drive has no direction yet (0).
        let d: Vec<f64> = r.inputs.iter().map(|x| x[4]).collect();
        let unset = d.iter().take_while(|&&v| v == 0.0).count();
        assert!(unset == 0 || runs_opening_files.contains(&r.id.as_str()), "{}: no direction inside the file", r.id);
        let turn = unset + d[unset..].iter().position(|&v| v != want).unwrap_or(d.len() - unset);
        assert!(turn > unset && d[turn..].iter().all(|&v| v == -want), "{}: travel direction {d:?}", r.id);
        assert!(r.time_s[r.len() - 1] - r.time_s[turn.min(r.len() - 1)] < 0.05, "{}: turned {} s before the run's end", r.id, r.time_s[r.len() - 1] - r.time_s[turn.min(r.len() - 1)]);
    }
    assert_eq!((ds.inputs, s.inputs), (5, 5), "the telemetry gives the fifth input");
    assert!(s.travel_direction_from.iter().all(|f| f == "position_reference_m"), "{:?}", s.travel_direction_from);
    // Asked for the paper's four inputs only, the fifth slot is left empty.
    let (ds4, s4) = convert(&files, &LogOptions { static_inputs: true, ..options() }).unwrap();
    assert_eq!((ds4.inputs, s4.inputs), (4, 4));
    assert!(ds4.runs.iter().flat_map(|r| &r.inputs).all(|x| x[4] == 0.0));
    // Under full payload the rod sags below the motor side: the error has
    // the weight's sign and a size of tens of micrometres.
    let heavy: Vec<f64> = ds.runs.iter().filter(|r| r.source.ends_with("payload_2.csv")).flat_map(|r| r.terminal_error_m.clone()).collect();
    let mean = heavy.iter().sum::<f64>() / heavy.len() as f64;
    assert!(mean.abs() > 5e-6, "{mean}");
    // The written dataset is one the trainer loads: inputs and target only.
    let out = dir.path().join("dataset.csv");
    ds.write_csv(&out).unwrap();
    let back = Dataset::load(&out, &DatasetLimits::default()).unwrap();
    assert_eq!((back.runs.len(), back.inputs), (ds.runs.len(), 5));
    assert_eq!(back.runs[0].inputs[0][4], ds.runs[0].inputs[0][4]);
    assert!(back.runs[0].tilt_swing_deg.is_nan());
}

fn write(path: &Path, header: &str, rows: &[String]) {
    std::fs::write(path, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
}

/// A logger's CSV: moves of `amp` m at 0.1 m/s, out and back (`reverse`) or
/// out only, at a force `f` N.
fn logger_rows(moves: usize, reverse: bool, f: f64) -> Vec<String> {
    let lead = 0.005;
    let w = 0.1 / (lead / std::f64::consts::TAU);
    let mut rows = Vec::new();
    let mut t = 0.0;
    let mut x = 0.1;
    for m in 0..moves {
        let sign = if reverse && m % 2 == 1 { -1.0 } else { 1.0 };
        for _ in 0..100 {
            x += sign * 0.1 * 0.005;
            rows.push(format!("{t},{x},{},{},{f}", sign * w, x + 1e-5));
            t += 0.005;
        }
        for _ in 0..40 {
            rows.push(format!("{t},{x},0,{},{f}", x + 1e-5));
            t += 0.005;
        }
    }
    rows
}

const HEADER: &str = "time_s,motor_position_m,speed_rad_s,terminal_position_m,load_force_n";

#[test]
fn logs_that_lack_what_the_model_needs_are_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("log.csv");
    let mut o = options();
    o.load_range_n = (0.0, 1000.0);
    let err = |o: &LogOptions| convert(&[p.clone()], o).unwrap_err().to_string();
    // No terminal position: the column is named.
    write(&p, "time_s,motor_position_m,speed_rad_s,load_force_n", &["0,0.1,0,10".into()]);
    let e = err(&o);
    assert!(e.contains("missing column 'terminal_position_m'") && e.contains("log.csv line 1"), "{e}");
    // No force at all.
    write(&p, "time_s,motor_position_m,speed_rad_s,terminal_position_m", &["0,0.1,0,0.1".into()]);
    assert!(err(&o).contains("missing column 'load_force_n'"), "{}", err(&o));
    // A NaN scale reading: file, line and column.
    let mut rows = logger_rows(8, true, 500.0);
    rows[5] = "0.025,0.1025,125.6,NaN,500".into();
    write(&p, HEADER, &rows);
    let e = err(&o);
    assert!(e.contains("line 7") && e.contains("terminal_position_m") && e.contains("linear-scale"), "{e}");
    // Never moving, never reversing, too few runs.
    write(&p, HEADER, &(0..200).map(|k| format!("{},0.1,0,0.1,500", k as f64 * 0.005)).collect::<Vec<_>>());
    assert!(err(&o).contains("no move"), "{}", err(&o));
    write(&p, HEADER, &logger_rows(8, false, 500.0));
    assert!(err(&o).contains("never reverses") && err(&o).contains("no Contraction run"), "{}", err(&o));
    write(&p, HEADER, &logger_rows(4, true, 500.0));
    assert!(err(&o).contains("too short: 2 Elongation runs"), "{}", err(&o));
    // Enough moves, but all at one load: the missing end is named.
    write(&p, HEADER, &logger_rows(8, true, 500.0));
    let e = err(&o);
    assert!(e.contains("never reaches the loads") && e.contains("up to 1000 N") && e.contains("down to 0 N"), "{e}");
    // Time going backwards.
    let mut rows = logger_rows(8, true, 500.0);
    rows.swap(10, 11);
    write(&p, HEADER, &rows);
    assert!(err(&o).contains("does not increase"), "{}", err(&o));
    // The same moves over the loads asked for pass.
    let mut rows = logger_rows(8, true, 0.0);
    rows.extend(logger_rows(8, true, 1000.0).into_iter().map(|r| {
        let mut f: Vec<String> = r.split(',').map(String::from).collect();
        f[0] = format!("{}", f[0].parse::<f64>().unwrap() + 100.0);
        f.join(",")
    }));
    write(&p, HEADER, &rows);
    let (ds, s) = convert(&[p.clone()], &o).unwrap();
    assert_eq!((s.runs_elongation, s.runs_contraction), (8, 8));
    assert!(ds.runs.iter().all(|r| r.terminal_error_m.iter().all(|e| (e - 1e-5).abs() < 1e-12)));
}

#[test]
fn the_trainer_takes_a_dataset_of_inputs_and_target_only() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("d.csv");
    let mut rows = Vec::new();
    for run in 0..4 {
        let dir = if run % 2 == 0 { "Elongation" } else { "Contraction" };
        for k in 0..25 {
            rows.push(format!("r{run},{dir},{},1.0,0.01,0.2,100,1e-5", k as f64 * 0.01));
        }
    }
    let header = "run_id,direction,time_s,motor_speed_rad_s,nut_speed_m_s,nut_displacement_m,load_force_n,terminal_error_m";
    write(&p, header, &rows);
    let ds = Dataset::load(&p, &DatasetLimits::default()).unwrap();
    assert_eq!(ds.runs.len(), 4);
    assert!(ds.runs[0].terminal_length_m[0].is_nan() && ds.runs[0].payload_scale.is_nan());
    // Without a target: refused naming the column.
    write(&p, "run_id,direction,time_s,motor_speed_rad_s,nut_speed_m_s,nut_displacement_m,load_force_n", &["r0,Elongation,0,1,0.01,0.2,100".into()]);
    let e = Dataset::load(&p, &DatasetLimits::default()).unwrap_err();
    assert!(format!("{e:#}").contains("terminal_error_m"), "{e:#}");
}
