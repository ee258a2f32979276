//! The plant's unmodelled-effect hooks (`plant/effects.rs`), each checked
//! against its closed form at the place it acts, and the default (no
//! effect) checked bit-identical to the nominal plant.

mod plant_support;

use host_sim::plant::mechanics::{Inputs, Model, StateVec, OMEGA_M, X_ROD};
use host_sim::plant::{Drive, Plant, PlantParams, UnmodelledEffects};
use plant_support::{aligned_duties, PWM_PERIOD_S};
use std::f64::consts::{PI, TAU};

fn params() -> PlantParams {
    PlantParams::default()
}

fn model_with(fx: &UnmodelledEffects) -> Model {
    let mut p = params();
    fx.apply_to_params(&mut p);
    let mut m = Model::new(&p);
    m.fx = fx.dynamics(&p);
    m
}

fn pwm_inputs(load_n: f64) -> Inputs {
    Inputs { drive: Drive::Pwm([0.5; 3]), bus_v: 48.0, load_force_n: load_n, open_phase: None, brake: Default::default() }
}

/// Drives a plant for `n` periods with a fixed rotor-frame voltage.
fn drive(plant: &mut Plant, n: usize, u_q: f64) -> Vec<StateVec> {
    (0..n)
        .map(|_| {
            let d = aligned_duties(plant, 0.0, u_q, PWM_PERIOD_S);
            plant.advance_duties(Some(d), 48.0, PWM_PERIOD_S);
            *plant.state_vector()
        })
        .collect()
}

#[test]
fn no_effect_is_bit_identical_to_the_nominal_plant() {
    let mut a = Plant::new(params(), 7);
    let mut b = Plant::with_effects(params(), UnmodelledEffects::default(), 7).unwrap();
    assert_eq!(a.params(), b.params());
    let (sa, sb) = (drive(&mut a, 400, 3.0), drive(&mut b, 400, 3.0));
    // Bit for bit, through a move (moving, loaded, with friction).
    for (x, y) in sa.iter().zip(&sb) {
        assert_eq!(x.map(f64::to_bits), y.map(f64::to_bits));
    }
    assert_eq!(a.state(), b.state());
    assert_eq!(a.sample(), b.sample());
}

#[test]
fn backlash_is_a_dead_zone_of_the_gap_width_in_the_nut_spring() {
    let b = 60e-6;
    let fx = UnmodelledEffects { backlash_m: b, ..Default::default() };
    let (m0, m1) = (model_with(&UnmodelledEffects::default()), model_with(&fx));
    // Rod at x0 + 0.2 m, screw turned so the nut spring is deflected by d
    // (the stroke-dependent compliance stays the same).
    let force = |m: &Model, d: f64| {
        let th_s = (0.2 + d) / m.metres_per_rad;
        let s: StateVec = [0.0, 0.0, th_s, 0.0, th_s, 0.0, m.origin_m + 0.2, 0.0];
        let mut g = 0.0;
        m.evaluate(&s, &pwm_inputs(0.0), &mut g).axial_spring_force
    };
    // Inside the gap: no contact, no force, either way.
    for d in [-0.49 * b, -0.2 * b, 0.0, 0.3 * b, 0.49 * b] {
        assert_eq!(force(&m1, d), 0.0, "deflection {d}");
    }
    // Outside: the nominal spring, shifted by half the gap.
    for d in [0.6 * b, 2.0 * b, 5e-4, -0.6 * b, -3e-4] {
        let expect = force(&m0, d - (0.5 * b).copysign(d));
        assert!((force(&m1, d) - expect).abs() <= 1e-9 * expect.abs().max(1.0), "{d}: {} vs {expect}", force(&m1, d));
    }
    // Dead-zone width = b: the force leaves zero at ±b/2.
    assert_eq!(force(&m1, 0.5 * b - 1e-9), 0.0);
    assert!(force(&m1, 0.5 * b + 1e-7) > 0.0);
}

#[test]
fn cogging_torque_has_its_amplitude_and_period() {
    let (a, c, n) = (0.05, -0.02, 12.0);
    let fx = UnmodelledEffects { cogging_sin_n_m: a, cogging_cos_n_m: c, cogging_periods_per_rev: n, ..Default::default() };
    let (m0, m1) = (model_with(&UnmodelledEffects::default()), model_with(&fx));
    let torque = |th: f64| {
        let s: StateVec = [0.0, 0.0, th, 0.0, th, 0.0, m0.origin_m + m0.metres_per_rad * th, 0.0];
        let (mut g0, mut g1) = (0.0, 0.0);
        let d0 = m0.evaluate(&s, &pwm_inputs(0.0), &mut g0).deriv[OMEGA_M];
        let d1 = m1.evaluate(&s, &pwm_inputs(0.0), &mut g1).deriv[OMEGA_M];
        // J_m ω̇ loses the cogging torque.
        (d0 - d1) * m0.j_m
    };
    let mut peak: f64 = 0.0;
    for k in 0..720 {
        let th = 100.0 + TAU * k as f64 / 720.0;
        let t = torque(th);
        assert!((t - (a * (n * th).sin() + c * (n * th).cos())).abs() < 1e-12, "θ {th}");
        // Period 2π/n.
        assert!((t - torque(th + TAU / n)).abs() < 1e-9);
        peak = peak.max(t.abs());
    }
    // (sampled 60 times a period: within 1 − cos(π/60) of the peak)
    assert!((peak - a.hypot(c)).abs() < 2e-3 * a.hypot(c), "peak {peak}");
}

#[test]
fn lead_error_shows_on_the_scale_with_its_amplitude_at_rest() {
    // Cumulative ε and once-per-revolution (a, b): at rest the rod sits
    // ε r θ + a sin θ + b cos θ further than on the nominal screw, and the
    // state is a true equilibrium (it stays there).
    let (eps, a, b) = (1e-4, 6e-6, -3e-6);
    let fx = UnmodelledEffects { lead_error_m_per_m: eps, lead_sin_m: a, lead_cos_m: b, ..Default::default() };
    let mut p0 = Plant::new(params(), 1);
    let mut p1 = Plant::with_effects(params(), fx, 1).unwrap();
    let r = p0.params().metres_per_rad();
    let mut ripple: Vec<f64> = Vec::new();
    for k in 0..16 {
        let th = 250.0 + TAU * k as f64 / 16.0;
        let tilt = p0.state().tilt_rad;
        p0.set_initial_state(th, tilt);
        p1.set_initial_state(th, tilt);
        let diff = p1.state().terminal_position_m - p0.state().terminal_position_m;
        // The thread's slope s = dx_s/dθ sets the holding torque s F and the
        // wind-up C s F, seen at the nut as s C s F (nominal: r C r F).
        let slope = r * (1.0 + eps) + a * th.cos() - b * th.sin();
        let x = p0.state().x_rod_m;
        let wind = p0.compliance().torsional_compliance_rad_per_n_m(x) * (slope * slope - r * r) * p0.load_force_n();
        // And the rod, shifted by the lead error, loads a longer screw.
        let f = p0.load_force_n();
        let longer = p0.static_deflection(f, x + diff).terminal_total_m() - p0.static_deflection(f, x).terminal_total_m();
        let expect = eps * r * th + a * th.sin() + b * th.cos() - wind - longer;
        assert!((diff - expect).abs() < 1e-9, "θ {th}: {diff} vs {expect}");
        ripple.push(diff - eps * r * th);
        // Held by the holding voltage, the rod does not move.
        let x = p1.state_vector()[X_ROD];
        let u_q = p1.params().motor.phase_resistance_ohm * p1.state().i_q_a;
        drive(&mut p1, 200, u_q);
        assert!((p1.state_vector()[X_ROD] - x).abs() < 2e-8, "drifted {}", p1.state_vector()[X_ROD] - x);
    }
    let pp = ripple.iter().cloned().fold(f64::MIN, f64::max) - ripple.iter().cloned().fold(f64::MAX, f64::min);
    assert!((pp - 2.0 * a.hypot(b)).abs() < 0.05 * 2.0 * a.hypot(b), "peak-to-peak {pp}");
}

#[test]
fn dead_time_costs_four_over_pi_volts_on_the_q_axis() {
    // Per-phase error V_dt = t_dt f_pwm V_bus against each phase current;
    // averaged over an electrical revolution its q component is −(4/π) V_dt
    // (the fundamental of three square waves).
    let t_dt = 1e-6;
    let fx = UnmodelledEffects { dead_time_s: t_dt, ..Default::default() };
    let (m0, m1) = (model_with(&UnmodelledEffects::default()), model_with(&fx));
    let v_dt = t_dt * params().integration.pwm_frequency_hz * 48.0;
    let n = 3600;
    let mut mean = 0.0;
    for k in 0..n {
        let th_e = TAU * (k as f64 + 0.5) / n as f64;
        let th = th_e / m0.motor.pole_pairs;
        let s: StateVec = [0.0, 10.0, th, 0.0, th, 0.0, m0.origin_m + m0.metres_per_rad * th, 0.0];
        let inp = Inputs { drive: Drive::Pwm([0.55, 0.5, 0.45]), ..pwm_inputs(0.0) };
        let (mut g0, mut g1) = (0.0, 0.0);
        mean += m1.evaluate(&s, &inp, &mut g1).u_q - m0.evaluate(&s, &inp, &mut g0).u_q;
    }
    mean /= n as f64;
    assert!((mean + 4.0 / PI * v_dt).abs() < 0.01 * v_dt, "mean u_q error {mean} V, V_dt {v_dt} V");
}

#[test]
fn current_sensor_gain_offset_and_encoder_eccentricity_are_in_the_readings() {
    let fx = UnmodelledEffects {
        current_gain_error: 0.05,
        current_offset_alpha_a: 0.3,
        current_offset_beta_a: -0.2,
        encoder_ecc_sin_rad: 4e-3,
        encoder_ecc_cos_rad: 0.0,
        ..Default::default()
    };
    let mut p = params();
    p.sensors.current_noise_a = 0.0;
    let mut plant = Plant::with_effects(p.clone(), fx.clone(), 3).unwrap();
    let th = 123.4;
    let tilt = plant.state().tilt_rad;
    plant.set_initial_state(th, tilt);
    let s = plant.sample();
    let truth = plant.state().phase_current_a;
    let o = [0.3, -0.5 * 0.3 + 0.75f64.sqrt() * -0.2, -0.5 * 0.3 - 0.75f64.sqrt() * -0.2];
    let lsb = 2.0 * p.sensors.current_full_scale_a / 2f64.powi(p.sensors.adc_bits as i32);
    for k in 0..3 {
        let expect = 1.05 * truth[k] + o[k];
        assert!((f64::from(s.phase_current_a[k]) - expect).abs() <= 0.51 * lsb, "phase {k}");
    }
    // The encoder reads θ + e_s sin θ (4e-3 rad is 6.4 counts), to a count.
    let cpr = f64::from(p.sensors.encoder_counts_per_rev);
    let ahead = (i64::from(s.encoder_count) - (th * cpr / TAU).round() as i64 + (1 << 15)).rem_euclid(1 << 16) - (1 << 15);
    assert!((ahead as f64 - 4e-3 * th.sin() * cpr / TAU).abs() <= 1.0, "{ahead} counts");
}

#[test]
fn stiffness_effects_add_their_closed_form_deflection() {
    // Screw compliance c: + c F x; Hertz ΔC: + ΔC((|F|+F_p)^⅔ − F_p^⅔);
    // coupling compliance: + r c T with T = r F at rest.
    let (c_s, d_c, c_c) = (5e-8, 2e-7, 5e-3);
    let f = 1200.0;
    let x = 0.4;
    let base = Plant::new(params(), 1);
    let defl = |fx: UnmodelledEffects| {
        let p = Plant::with_effects(params(), fx, 1).unwrap();
        p.static_deflection(f, x).terminal_total_m() - base.static_deflection(f, x).terminal_total_m()
    };
    let r = params().metres_per_rad();
    let fp = params().deformation.contact.preload_n;
    let screw = defl(UnmodelledEffects { screw_compliance_m_per_n_m: c_s, ..Default::default() });
    assert!((screw - c_s * f * x).abs() < 1e-3 * c_s * f * x, "{screw}");
    let hertz = defl(UnmodelledEffects { contact_coefficient_m_per_n2_3: d_c, ..Default::default() });
    let h = d_c * ((f + fp).powf(2.0 / 3.0) - fp.powf(2.0 / 3.0));
    assert!((hertz - h).abs() < 1e-6 * h, "{hertz} vs {h}");
    let coupling = defl(UnmodelledEffects { coupling_compliance_rad_per_n_m: c_c, ..Default::default() });
    assert!((coupling - r * c_c * r * f).abs() < 1e-6 * r * c_c * r * f, "{coupling}");
}

#[test]
fn friction_thermal_and_load_offset_act_where_they_should() {
    // Asymmetric Coulomb + Stribeck on the screw: at ω_s ≫ ω_ε the extra
    // torque is c₊ + T_s e^{−(ω/ω_s)²} moving up, −c₋ − … moving down.
    let fx = UnmodelledEffects {
        coulomb_pos_n_m: 0.1,
        coulomb_neg_n_m: 0.02,
        stribeck_torque_n_m: 0.05,
        stribeck_speed_rad_s: 10.0,
        viscous_pos_n_m_s_rad: 1e-3,
        ..Default::default()
    };
    let d = fx.dynamics(&params());
    for (w, expect) in [(10.0, 0.1 + 0.05 * (-1.0f64).exp() + 1e-2), (-10.0, -0.02 - 0.05 * (-1.0f64).exp())] {
        assert!((d.screw_friction_n_m(w) - expect).abs() < 1e-9, "{w}");
    }
    // Thermal strain: κ (t − t₀) from the warm-up start, lengthening the lead.
    let th = UnmodelledEffects { thermal_strain_per_s: 2e-5, thermal_start_s: 1.0, ..Default::default() };
    assert_eq!(th.thermal_strain(0.5), 0.0);
    assert!((th.thermal_strain(3.0) - 4e-5).abs() < 1e-15);
    // Load offset: an unmeasured force the holding current carries.
    let lo = UnmodelledEffects { load_offset_n: 150.0, ..Default::default() };
    let (p0, p1) = (Plant::new(params(), 1), Plant::with_effects(params(), lo, 1).unwrap());
    let di = p1.state().i_q_a - p0.state().i_q_a;
    assert!((di - p0.holding_current_a(150.0)).abs() < 1e-9, "{di}");
}
