//! Six closed-loop legs follow a pose trajectory by streamed setpoints
//! (1 kHz): no fault and no limit; each core's reference is the setpoint
//! sent one interval earlier; the pose solved from the six rods stays
//! within what the rods' own errors allow through the Jacobian (Eq. 6);
//! bad options are refused with the option named.

use host_sim::config::RigConfig;
use host_sim::platform::six_legs::RigSpread;
use host_sim::platform::stream::{commanded, run_stream, scaled, StreamOptions};
use host_sim::platform::{Platform, Trajectory};
use nalgebra::Vector6;

fn short(compensation: bool) -> StreamOptions {
    StreamOptions { ramp_s: 0.5, duration_s: Some(1.5), ..StreamOptions::new(compensation, false, RigSpread::NONE) }
}

#[test]
fn six_legs_follow_a_streamed_cueing_profile() {
    let p = Platform::paper();
    let rig = RigConfig::nominal().unwrap();
    let full = Trajectory::combined(&p);
    let o = short(false);
    let r = run_stream(&p, &rig, &full, &o).unwrap();
    println!(
        "scale {:.3}: pose {:.4} mm / {:.5}° RMS, {:.4} mm / {:.5}° max; motor tracking {:?} µm; lag check {:?} µm; ×{:.1} real time",
        r.amplitude_scale, r.pose_error_position_rms_mm, r.pose_error_attitude_rms_deg, r.pose_error_position_max_mm, r.pose_error_attitude_max_deg,
        r.motor_tracking_rms_um, r.reference_lag_check_um, r.sim_realtime_factor
    );
    // The fitted amplitudes keep every leg inside the core's bounds.
    let v_max = f64::from(rig.control.trajectory.max_velocity_m_s);
    assert!(r.peak_leg_rate_streamed_m_s <= v_max, "{} m/s", r.peak_leg_rate_streamed_m_s);
    assert_eq!(r.limits_seen, "LimitFlags(0)", "no stroke or speed limit while streaming");
    // Lag: after the period that follows setpoint k the reference is
    // setpoint k − 1 (to f32 resolution); against setpoints k and k − 2 it
    // is off by one interval of leg motion, RMS |l̇| T_s.
    let traj = scaled(&full, r.amplitude_scale);
    let dt = 1e-3;
    let n = r.setpoints_per_leg;
    let rate_rms = ((2..n)
        .map(|k| {
            let s = commanded(&traj, o.ramp_s, k as f64 * dt);
            (p.pose_jacobian(&s.pose) * s.velocity).norm_squared()
        })
        .sum::<f64>()
        / (6 * (n - 2)) as f64)
        .sqrt();
    let [lag0, lag1, lag2] = r.reference_lag_check_um;
    assert!(lag1 < 0.1, "reference vs setpoint k − 1: {lag1} µm");
    for lag in [lag0, lag2] {
        assert!((lag / (rate_rms * dt * 1e6) - 1.0).abs() < 0.05, "{lag} µm against RMS |l̇| T_s = {} µm", rate_rms * dt * 1e6);
    }
    // Each drive tracks its own streamed reference as the single leg does
    // (core_stream: < 10 µm RMS).
    assert!(r.motor_tracking_rms_um.iter().all(|&e| e < 10.0), "{:?}", r.motor_tracking_rms_um);
    // The pose follows: at every period the pose error is what the rods'
    // errors make of it through J_q⁻¹ (|δp| ≤ ‖J⁻¹_p‖ |δl|, 5 % for the
    // linearisation), and the rods are off by their deformation under a
    // few hundred newtons, well under 1 % of the motion's amplitude.
    for (k, (e, dl)) in r.trace.pose_error.iter().zip(&r.trace.terminal_error_um).enumerate() {
        let q = commanded(&traj, o.ramp_s, k as f64 * dt).pose;
        let jinv = p.pose_jacobian(&q).try_inverse().unwrap();
        let jp = jinv.fixed_rows::<3>(0).into_owned();
        let bound = jp.norm() * Vector6::from(*dl).norm() * 1e-3;
        let dp = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
        assert!(dp <= 1.05 * bound + 1e-4, "period {k}: {dp} mm > {bound} mm");
    }
    let amplitude_mm = traj.sines[2].iter().map(|s| s.amplitude).sum::<f64>() * 1e3;
    assert!(r.pose_error_position_max_mm < 0.01 * amplitude_mm, "{} mm of {amplitude_mm} mm heave", r.pose_error_position_max_mm);
}

#[test]
fn bad_stream_options_are_refused_by_name() {
    let p = Platform::paper();
    let rig = RigConfig::nominal().unwrap();
    let traj = Trajectory::heave(&p);
    let bad = [
        (StreamOptions { ramp_s: f64::NAN, ..short(false) }, "ramp_s"),
        (StreamOptions { duration_s: Some(99.0), ..short(false) }, "duration_s"),
        (StreamOptions { amplitude_scale: Some(0.0), ..short(false) }, "amplitude_scale"),
    ];
    for (o, name) in bad {
        let e = run_stream(&p, &rig, &traj, &o).unwrap_err().to_string();
        assert!(e.contains(name), "{e}");
    }
    // At full amplitude the heave leaves the workspace or the drive's
    // bounds: the run is refused before any leg moves, or it is fitted.
    let e = run_stream(&p, &rig, &scaled(&traj, 3.0), &StreamOptions { amplitude_scale: Some(1.0), ..short(false) }).unwrap_err().to_string();
    assert!(e.contains("heave") && e.contains("leg"), "{e}");
}

