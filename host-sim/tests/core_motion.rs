//! Trajectory and encoder tracking against closed forms.

use servo_core::motion::{EncoderTracker, ScurveMove};
use servo_core::params::{ControlParams, TrajectoryParams};

const LIM: TrajectoryParams = TrajectoryParams { max_velocity_m_s: 0.25, max_acceleration_m_s2: 2.5, max_jerk_m_s3: 25.0 };

fn check_profile(m: &ScurveMove, start: f32, end: f32, lim: &TrajectoryParams) {
    let dt = 1e-4_f32;
    let n = (m.duration_s() / dt) as usize + 10;
    let mut prev = m.sample(0.0);
    assert!((prev.position_m - start).abs() < 1e-6);
    for k in 1..n {
        let s = m.sample(k as f32 * dt);
        assert!(s.velocity_m_s.abs() <= lim.max_velocity_m_s * (1.0 + 1e-4));
        assert!(s.acceleration_m_s2.abs() <= lim.max_acceleration_m_s2 * (1.0 + 1e-4));
        // Continuity: position is the integral of velocity, velocity of acceleration.
        let v_mid = 0.5 * (s.velocity_m_s + prev.velocity_m_s);
        assert!((s.position_m - prev.position_m - v_mid * dt).abs() < 2e-7, "position jump at {}", k as f32 * dt);
        let a_mid = 0.5 * (s.acceleration_m_s2 + prev.acceleration_m_s2);
        assert!((s.velocity_m_s - prev.velocity_m_s - a_mid * dt).abs() < 2e-5, "velocity jump at {}", k as f32 * dt);
        // Jerk bounded: acceleration changes by at most j·dt per step.
        assert!((s.acceleration_m_s2 - prev.acceleration_m_s2).abs() <= lim.max_jerk_m_s3 * dt * 1.01);
        prev = s;
    }
    let last = m.sample(m.duration_s() + 1.0);
    assert!((last.position_m - end).abs() < 1e-6 && last.velocity_m_s == 0.0 && last.acceleration_m_s2 == 0.0);
}

#[test]
fn long_move_reaches_the_limits_and_lasts_the_closed_form_time() {
    let m = ScurveMove::plan(0.0, 0.45, &LIM);
    // With cruise: T = D/v + v/a + a/j.
    let t = 0.45 / 0.25 + 0.25 / 2.5 + 2.5 / 25.0;
    assert!((m.duration_s() - t).abs() < 1e-5, "{} vs {t}", m.duration_s());
    assert!((m.peak_velocity_m_s() - 0.25).abs() < 1e-6);
    check_profile(&m, 0.0, 0.45, &LIM);
}

#[test]
fn backward_and_short_moves_respect_the_limits() {
    for (a, b) in [(0.45, 0.0), (0.1, 0.1005), (0.2, 0.17), (0.3, 0.31), (0.0, 0.002)] {
        let m = ScurveMove::plan(a, b, &LIM);
        check_profile(&m, a, b, &LIM);
    }
}

#[test]
fn very_short_move_is_pure_jerk_and_lasts_four_cube_roots() {
    // D < 2 a³/j²: T = 4 (D / 2j)^(1/3).
    let d = 1e-3_f32;
    let m = ScurveMove::plan(0.0, d, &LIM);
    let t = 4.0 * (d / (2.0 * 25.0)).cbrt();
    assert!((m.duration_s() - t).abs() < 1e-5);
}

#[test]
fn encoder_tracker_follows_a_constant_speed_through_counter_wraps() {
    let p = ControlParams::DEFAULT;
    let dt = 1.0 / p.rates.pwm_frequency_hz;
    let speed_counts_s = 150_000.0_f64; // 15 rev/s, wraps the 16-bit counter every 0.44 s
    let mut enc = EncoderTracker::new();
    let start: u16 = 65_000;
    for k in 0..40_000u32 {
        let true_counts = speed_counts_s * f64::from(k) * f64::from(dt);
        let raw = start.wrapping_add(true_counts.floor() as i64 as u16);
        let up = enc.update(&p.encoder, raw, dt, p.faults.encoder_max_step_counts, p.faults.encoder_max_innovation_counts);
        assert!(!up.implausible_step);
    }
    let true_counts = speed_counts_s * 39_999.0 * f64::from(dt);
    let speed = enc.speed_rad_s(&p.encoder) as f64 / (2.0 * std::f64::consts::PI) * 10_000.0;
    assert!((speed - speed_counts_s).abs() / speed_counts_s < 1e-3, "speed {speed}");
    // Quantisation lags half a count on average; the estimate sits within a count.
    assert!((f64::from(enc.position_counts()) - true_counts).abs() < 1.0, "{} vs {true_counts}", enc.position_counts());
}

#[test]
fn encoder_tracker_flags_an_impossible_jump() {
    let p = ControlParams::DEFAULT;
    let mut enc = EncoderTracker::new();
    enc.update(&p.encoder, 100, 5e-5, p.faults.encoder_max_step_counts, p.faults.encoder_max_innovation_counts);
    let up = enc.update(&p.encoder, 100 + 5_000, 5e-5, p.faults.encoder_max_step_counts, p.faults.encoder_max_innovation_counts);
    assert!(up.implausible_step);
}

/// The drive's friction feedforward against the nominal plant's own friction
/// laws: in steady motion well above the regularisation speed it must equal
/// the Coulomb torque the plant integrates (screw μ|F|·L/2π + nut drag + the
/// rod seal's Coulomb force through the lead), with the sign of the motion.
#[test]
fn friction_feedforward_matches_the_plants_coulomb_friction() {
    use host_sim::config::RigConfig;
    use host_sim::plant::friction::{RodFriction, ScrewFriction};
    use servo_core::motion::speed_loop::friction_feedforward_n_m;
    let rig = RigConfig::nominal().unwrap();
    let pp = &rig.plant;
    let screw = ScrewFriction::new(pp);
    let rod = RodFriction::new(pp);
    let r = pp.metres_per_rad();
    for &(v, load) in &[(0.1_f64, 1380.0_f64), (-0.1, 1380.0), (0.05, 600.0), (-0.2, 200.0)] {
        let omega = v / r;
        // Coulomb part only: subtract the viscous terms the plant adds.
        let screw_c = screw.coulomb_torque_n_m(omega, load);
        let rod_c = (rod.force_n(v) - pp.rod.viscous_friction_n_s_m * v) * r;
        let plant = screw_c + rod_c;
        let ff = f64::from(friction_feedforward_n_m(&rig.control, v as f32, load as f32));
        assert!((ff - plant).abs() < 0.02 * plant.abs(), "v {v}, load {load}: feedforward {ff}, plant {plant}");
    }
    // At rest the feedforward leaves the held load to the integrator, and a
    // non-finite load estimate cannot poison it.
    assert_eq!(friction_feedforward_n_m(&rig.control, 0.0, 1380.0), 0.0);
    assert!(friction_feedforward_n_m(&rig.control, 0.1, f32::NAN).is_finite());
}
