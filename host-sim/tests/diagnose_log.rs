//! Input of `host-sim diagnose`: the CSV schema, defmt telemetry and the
//! validation that names the row of every problem (bad input).

use host_sim::diagnose::log::{parse_defmt, Log, Severity};
use std::io::Write;

fn csv(text: &str) -> Log {
    let mut f = tempfile::NamedTempFile::with_suffix(".csv").unwrap();
    f.write_all(text.as_bytes()).unwrap();
    Log::read_csv(f.path()).unwrap()
}

fn errors(log: &Log) -> Vec<String> {
    log.errors().map(|i| i.to_string()).collect()
}

#[test]
fn clean_csv_has_no_errors_and_names_ruled_out_analyses() {
    let log = csv("time_s,position_reference_m,terminal_position_m,current_q_a,extra\n0,0.1,0.1,1.0,7\n0.001,0.1,0.1,1.0,7\n0.002,0.1,0.1,1.0,7\n");
    assert!(errors(&log).is_empty(), "{:?}", errors(&log));
    assert!(log
        .issues
        .iter()
        .any(|i| i.severity == Severity::Note && i.column.as_deref() == Some("extra")));
    let ruled = log.ruled_out().join("\n");
    assert!(ruled.contains("no motor_angle_rad"), "{ruled}");
    assert!(ruled.contains("no voltage_q_v"), "{ruled}");
    assert!(!ruled.contains("no current"), "{ruled}");
}

#[test]
fn unsorted_duplicate_nan_and_unit_mistakes_are_reported_with_rows() {
    let log = csv("time_s,terminal_position_m,current_q_a\n\
         0.000,0.10,1\n\
         0.001,0.10,1\n\
         0.001,0.10,1\n\
         0.0005,0.10,1\n\
         0.002,,1\n\
         0.003,120.0,1\n\
         0.004,0.10,abc\n\
         0.010,0.10,1\n\
         0.011,0.10,1\n");
    let e = errors(&log);
    let has = |row: usize, what: &str| {
        e.iter()
            .any(|s| s.contains(&format!("row {row} ")) && s.contains(what))
    };
    assert!(has(3, "duplicate timestamp"), "{e:#?}");
    assert!(has(4, "unsorted"), "{e:#?}");
    assert!(has(5, "NaN"), "{e:#?}");
    assert!(has(6, "mm given as m"), "{e:#?}");
    assert!(has(7, "not a number"), "{e:#?}");
    // The gap is a warning with its row, and splits the run.
    assert!(
        log.issues.iter().any(|i| i.severity == Severity::Warning
            && i.row == Some(8)
            && i.message.contains("gap")),
        "{:#?}",
        log.issues
    );
}

#[test]
fn diagnose_refuses_a_log_with_errors_and_lists_them() {
    let log = csv("time_s,terminal_position_m,current_q_a\n0,0.1,1\n0,0.1,1\n");
    let p = host_sim::diagnose::residual::Physics::from_rig(
        &host_sim::config::RigConfig::nominal().unwrap(),
    );
    let Err(err) = host_sim::diagnose::diagnose(
        &log,
        None,
        host_sim::diagnose::residual::Nominal::Physics(p),
        90.0,
    ) else {
        panic!("a log with errors was diagnosed");
    };
    let msg = format!("{err:#}");
    assert!(msg.contains("row 2") && msg.contains("duplicate"), "{msg}");
}

#[test]
fn defmt_telemetry_lines_become_rows() {
    let text = "\
INFO  cylinder-servo 0.1.0 on nucleo
└─ cylinder_servo::__cortex_m_rt_main @ src/main.rs:58
0.000100 INFO  tlm Telemetry { time_s: 0.001, mode: Running, position_reference_m: 0.1, position_command_m: 0.1, position_shift_m: 0.0, motor_position_m: 0.1, motor_angle_rad: 125.66, speed_reference_rad_s: 0.0, speed_rad_s: 0.1, current_d_a: 0.0, current_q_a: 1.5, current_q_reference_a: 1.5, voltage_d_v: 0.0, voltage_q_v: 0.3, bus_voltage_v: 48.1, terminal_position_m: Some(0.0999), load_force_estimate_n: 1380.0, faults: FaultSet { bits: 0 }, limits: LimitFlags { bits: 0 }, new_field: 3 }
0.001100 INFO  tlm Telemetry { time_s: 0.002, mode: Running, position_reference_m: 0.1, position_command_m: 0.1, position_shift_m: 0.0, motor_position_m: 0.1, motor_angle_rad: 125.67, speed_reference_rad_s: 0.0, speed_rad_s: 0.1, current_d_a: 0.0, current_q_a: 1.6, current_q_reference_a: 1.5, voltage_d_v: 0.0, voltage_q_v: 0.3, bus_voltage_v: 48.1, terminal_position_m: None, load_force_estimate_n: 1380.0, faults: FaultSet { bits: 0 }, limits: LimitFlags { bits: 0 }, new_field: 3 }
";
    let log = parse_defmt(text, "rtt.log").unwrap();
    assert_eq!(log.len(), 2);
    assert_eq!(log.get("current_q_a").unwrap(), &[1.5, 1.6]);
    assert_eq!(log.get("motor_angle_rad").unwrap(), &[125.66, 125.67]);
    // `None` on one row: NaN, reported with the row and the input line.
    let scale = log.get("terminal_position_m").unwrap();
    assert_eq!(scale[0], 0.0999);
    assert!(scale[1].is_nan());
    assert!(
        log.errors()
            .any(|i| i.row == Some(2) && i.message.contains("line 4")),
        "{:#?}",
        log.issues
    );
    assert!(log
        .issues
        .iter()
        .any(|i| i.column.as_deref() == Some("new_field") && i.message.contains("unknown")));
}
