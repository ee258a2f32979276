//! The host tool's test figures on loops whose answers are known: step
//! figures of first- and second-order responses, the H1 frequency response
//! of a closed loop under a chirp with its bandwidth and phase margin; and
//! the `drive log` conversion of the firmware's defmt text.

use host_sim::tool::analysis::{frf_figures, h1, step_figures};
use std::f64::consts::{PI, TAU};

const DT: f64 = 1.0 / 20_000.0;

/// Closed loop of `L(s) = ωn² / (s (s + 2ζωn))` (or `ωc/s` with `zeta`
/// None) driven by `r`, integrated at `DT`.
fn closed_loop(r: &[f64], wn: f64, zeta: Option<f64>) -> Vec<f64> {
    let (mut y, mut v) = (0.0, 0.0);
    r.iter()
        .map(|&rk| {
            match zeta {
                None => y += DT * wn * (rk - y),
                Some(z) => {
                    // ÿ + 2ζωn ẏ = ωn² (r − y), semi-implicit Euler.
                    v += DT * (wn * wn * (rk - y) - 2.0 * z * wn * v);
                    y += DT * v;
                }
            }
            y
        })
        .collect()
}

#[test]
fn step_figures_of_known_responses() {
    let n = 4000;
    let t0 = 0.01;
    let r: Vec<f64> = (0..n).map(|k| if k as f64 * DT >= t0 { 1.0 } else { 0.0 }).collect();
    // First order, τ = 10 ms: rise 2.197 τ, no overshoot, 2 % settling 3.91 τ.
    let tau = 0.01;
    let y = closed_loop(&r, 1.0 / tau, None);
    let f = step_figures(&y, DT, t0, 1.0);
    println!("{f:?}");
    assert!((f.rise_time_s.unwrap() - 2.197 * tau).abs() < 0.05 * tau, "{f:?}");
    assert!(f.overshoot_pct < 0.5, "{f:?}");
    assert!((f.settling_time_s.unwrap() - 3.91 * tau).abs() < 0.2 * tau, "{f:?}");
    // Second order, ζ = 0.5: overshoot exp(−πζ/√(1−ζ²)) = 16.3 %.
    let y = closed_loop(&r, TAU * 20.0, Some(0.5));
    let f = step_figures(&y, DT, t0, 1.0);
    println!("{f:?}");
    assert!((f.overshoot_pct - 16.3).abs() < 1.0, "{f:?}");
}

fn chirp(n: usize, f0: f64, f1: f64) -> Vec<f64> {
    let dur = n as f64 * DT;
    let k = (f1 / f0).ln() / dur;
    (0..n).map(|i| (TAU * f0 * (((k * i as f64 * DT).exp() - 1.0) / k)).sin()).collect()
}

#[test]
fn h1_gives_bandwidth_and_phase_margin_of_known_loops() {
    let n = 2 * 20_000 * 2;
    let r = chirp(n, 2.0, 600.0);
    // ωc/s: T first order at fc = 50 Hz, phase margin 90°, no phase crossover.
    let y = closed_loop(&r, TAU * 50.0, None);
    let frf = h1(&r, &y, DT, 4096);
    let f = frf_figures(&frf, 5.0, 500.0);
    println!("{f:?}");
    let bw = f.bandwidth_3db_hz.unwrap();
    assert!((bw - 50.0).abs() < 5.0, "{f:?}");
    assert!((f.phase_margin_deg.unwrap() - 90.0).abs() < 5.0, "{f:?}");
    assert!(f.gain_margin_db.is_none(), "{f:?}");
    // ωn²/(s(s+2ζωn)), ζ = 0.5: PM = atan(2ζ / √(√(1+4ζ⁴) − 2ζ²)) = 51.8°.
    let y = closed_loop(&r, TAU * 40.0, Some(0.5));
    let frf = h1(&r, &y, DT, 4096);
    let f = frf_figures(&frf, 5.0, 500.0);
    println!("{f:?}");
    let z: f64 = 0.5;
    let pm = (2.0 * z / ((1.0 + 4.0 * z.powi(4)).sqrt() - 2.0 * z * z).sqrt()).atan() * 180.0 / PI;
    assert!((f.phase_margin_deg.unwrap() - pm).abs() < 4.0, "{f:?} vs {pm}");
}

#[test]
fn drive_log_converts_defmt_text_to_the_diagnose_csv() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rtt.txt");
    let line = |t: f64, x: f64| {
        format!(
            "{t:.6} INFO  tlm Telemetry {{ time_s: {t}, mode: Running, position_reference_m: {x}, position_command_m: {x}, position_shift_m: 0.0, motor_position_m: {x}, motor_angle_rad: 125.66, speed_reference_rad_s: 0.0, speed_rad_s: 0.1, current_d_a: 0.0, current_q_a: 1.5, current_q_reference_a: 1.5, voltage_d_v: 0.0, voltage_q_v: 0.3, bus_voltage_v: 48.1, terminal_position_m: Some({x}), load_force_estimate_n: 1380.0, faults: FaultSet {{ bits: 0 }}, limits: LimitFlags {{ bits: 0 }}, readiness: Readiness(7) }}\n"
        )
    };
    let mut text = String::from("0.000000 INFO  heartbeat up 0 s\n");
    for k in 0..50 {
        text += &line(k as f64 * 1e-3, 0.1 + k as f64 * 1e-5);
    }
    std::fs::write(&input, text).unwrap();
    let out = dir.path().join("log.csv");
    let exe = env!("CARGO_BIN_EXE_host-sim");
    let st = std::process::Command::new(exe)
        .args(["drive", "log"])
        .arg(&input)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    let log = host_sim::diagnose::log::Log::read_csv(&out).unwrap();
    assert_eq!(log.len(), 50);
    for c in ["time_s", "position_reference_m", "motor_angle_rad", "terminal_position_m", "current_q_a", "bus_voltage_v"] {
        assert!(log.has(c), "{c}");
    }
    assert!(log.errors().next().is_none(), "{:?}", log.issues);
}
