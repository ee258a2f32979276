//! The fixed-step RK4 integration converges at fourth order on a smooth run
//! of the full model (all springs, friction, deformation, load).

mod plant_support;

use host_sim::plant::{Plant, PlantParams, StateVec};
use plant_support::{aligned_duties, PWM_PERIOD_S};

const BUS_V: f64 = 48.0;

/// Lifts the rated load from rest for 20 ms with a q-voltage above holding
/// (state-feedback commutation in f64, so every run sees a smooth map) and
/// returns the final state vector.
fn lift(substeps: u32) -> StateVec {
    let mut p = PlantParams::default();
    p.integration.substeps_per_pwm_period = substeps;
    let mut plant = Plant::new(p, 1);
    // One revolution out (x ≈ 5 mm): clear of x = 0, where the loaded
    // screw length max(x, 0) has a kink, and small enough that rounding of
    // x stays far below the errors measured.
    plant.set_initial_state(2.0 * std::f64::consts::PI, std::f64::consts::FRAC_PI_2);
    let u_q = plant.params().motor.phase_resistance_ohm * plant.state().i_q_a + 6.0;
    for _ in 0..400 {
        let d = aligned_duties(&plant, 0.0, u_q, PWM_PERIOD_S);
        plant.advance_duties(Some(d), BUS_V, PWM_PERIOD_S);
    }
    assert!(plant.state().v_rod_m_s > 0.02, "the run must move the load");
    *plant.state_vector()
}

#[test]
fn rk4_global_error_falls_sixteen_fold_per_halving() {
    let reference = lift(256);
    let runs: Vec<StateVec> = [4, 8, 16].iter().map(|&n| lift(n)).collect();
    // The electrical and rotating states carry the truncation error (1e-6
    // to 1e-12 here). The rod's own errors are already ~1e-14 m at the
    // coarsest step, at the rounding floor of x += h·v, so they cannot show
    // an order; they are driven by the states checked here.
    let names = ["i_d", "i_q", "theta_m", "omega_m", "theta_s", "omega_s"];
    for (idx, name) in names.iter().enumerate() {
        let err: Vec<f64> = runs.iter().map(|s| (s[idx] - reference[idx]).abs()).collect();
        for w in err.windows(2) {
            let order = (w[0] / w[1]).log2();
            assert!((3.7..=4.3).contains(&order), "{name}: errors {err:?} give order {order}");
        }
    }
}

#[test]
fn a_long_interval_is_split_into_steps_no_longer_than_the_limit() {
    // One advance of 10 periods must equal 10 advances of one period: the
    // plant splits it into the same 25 µs steps.
    let mut a = Plant::new(PlantParams::default(), 1);
    let mut b = Plant::new(PlantParams::default(), 1);
    let d = aligned_duties(&a, 0.0, 3.0, PWM_PERIOD_S);
    a.advance_duties(Some(d), BUS_V, 10.0 * PWM_PERIOD_S);
    for _ in 0..10 {
        b.advance_duties(Some(d), BUS_V, PWM_PERIOD_S);
    }
    let (sa, sb) = (a.state_vector(), b.state_vector());
    for k in 0..sa.len() {
        assert!((sa[k] - sb[k]).abs() <= 1e-12 * sa[k].abs().max(1e-9), "state {k}: {} vs {}", sa[k], sb[k]);
    }
    assert!((a.state().time_s - 10.0 * PWM_PERIOD_S).abs() < 1e-15);
}

/// Holds the rated load vertically, with `extra_weights` times its weight
/// more as an external force, and drives a q-voltage swinging about the
/// holding voltage at 100 Hz for 60 ms, so the screw stops and reverses
/// every 5 ms: each reversal crosses the friction regularisation's steep
/// tanh region, the model's stiffest relaxation (steeper under more load).
/// Returns (motor-side position, rod position, i_q, ω_s) every period.
fn reversals(substeps: u32, extra_weights: f64) -> Vec<[f64; 4]> {
    let mut p = PlantParams::default();
    p.integration.substeps_per_pwm_period = substeps;
    let mut plant = Plant::new(p, 1);
    let weight = plant.load_force_n();
    plant.set_external_force_n(extra_weights * weight);
    plant.set_initial_state(2.0 * std::f64::consts::PI, std::f64::consts::FRAC_PI_2);
    let hold = plant.params().motor.phase_resistance_ohm * plant.state().i_q_a;
    (0..1200)
        .map(|k| {
            let t = k as f64 * PWM_PERIOD_S;
            let u_q = hold + 3.0 * (2.0 * std::f64::consts::PI * 100.0 * t).sin();
            let d = aligned_duties(&plant, 0.0, u_q, PWM_PERIOD_S);
            plant.advance_duties(Some(d), BUS_V, PWM_PERIOD_S);
            let s = plant.state();
            [s.motor_side_position_m, s.x_rod_m, s.i_q_a, s.omega_s_rad_s]
        })
        .collect()
}

#[test]
fn one_step_per_period_follows_a_fine_step_reference_through_friction_reversals() {
    // The shipped rig integrates one 50 µs RK4 step per PWM period. Against
    // 64 steps per period (0.8 µs, every rate resolved to |λh| < 0.04), on
    // a run that keeps stopping in the friction's tanh region, at the rated
    // load (|λh| ≈ 0.8 there) and at three times it (|λh| ≈ 2.1, the load
    // `params_check` judges the rate at): positions agree to under a third
    // of the 0.5 µm encoder count (and of the 1 µm scale), i_q to under the
    // 24 mA ADC step and the 30 mA noise. (Measured: 43–53 nm and 6 mA at
    // rated load, 81–91 nm and 12 mA at three times it; 8 nm and 1 mA at
    // rated load with the former two steps per period: the reversals'
    // kinks hold the order below four.)
    for extra_weights in [0.0, 2.0] {
        let fine = reversals(64, extra_weights);
        let coarse = reversals(1, extra_weights);
        let reversals_seen = fine.windows(2).filter(|w| w[0][3] * w[1][3] < 0.0).count();
        assert!(reversals_seen >= 10, "load ×{}: only {reversals_seen} reversals", 1.0 + extra_weights);
        let worst = |i: usize| coarse.iter().zip(&fine).map(|(c, f)| (c[i] - f[i]).abs()).fold(0.0, f64::max);
        let (motor, rod, i_q) = (worst(0), worst(1), worst(2));
        eprintln!("load ×{}: motor side {motor:e} m, rod {rod:e} m, i_q {i_q:e} A", 1.0 + extra_weights);
        assert!(
            motor < 1.5e-7 && rod < 1.5e-7,
            "load ×{}: motor side off by {motor:e} m, rod by {rod:e} m",
            1.0 + extra_weights
        );
        assert!(i_q < 2e-2, "load ×{}: i_q off by {i_q:e} A", 1.0 + extra_weights);
    }
}
