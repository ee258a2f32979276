//! Sensor models: quantisation, wrap-around, noise statistics, determinism.

mod plant_support;

use std::f64::consts::TAU;

use host_sim::plant::inverter::duties_for_dq;
use host_sim::plant::sensors::encoder_count;
use host_sim::plant::{Plant, PlantParams};
use plant_support::{noiseless, PWM_PERIOD_S};

#[test]
fn encoder_counts_the_nearest_edge_and_wraps_like_a_16_bit_timer() {
    let cpr = 10_000u32;
    let count_angle = TAU / f64::from(cpr);
    assert_eq!(encoder_count(0.0, cpr), 0);
    assert_eq!(encoder_count(0.49 * count_angle, cpr), 0);
    assert_eq!(encoder_count(0.51 * count_angle, cpr), 1);
    assert_eq!(encoder_count(-0.51 * count_angle, cpr), u16::MAX);
    // 6.5536 revolutions = 65 536 counts: back to zero.
    assert_eq!(encoder_count(65_536.0 * count_angle, cpr), 0);
    assert_eq!(encoder_count(70_000.0 * count_angle, cpr), (70_000 - 65_536) as u16);
    assert_eq!(encoder_count(-70_000.0 * count_angle, cpr), (2 * 65_536 - 70_000) as u16);

    // Through the plant: the count follows θ_m at a stroke position.
    let mut plant = Plant::new(PlantParams::default(), 2);
    let theta = 90.0 * TAU + 0.123; // 90 revolutions: 450 mm of stroke
    plant.set_initial_state(theta, 0.0);
    let expected = ((theta / count_angle).round() as i64).rem_euclid(65_536) as u16;
    assert_eq!(plant.sample().encoder_count, expected);
}

#[test]
fn phase_currents_are_12_bit_codes_within_half_an_lsb() {
    let p = noiseless(PlantParams::default());
    let fs = p.sensors.current_full_scale_a;
    let lsb = 2.0 * fs / 4096.0;
    let mut plant = Plant::new(p, 3);
    plant.set_initial_state(0.2, 0.0);
    let d = duties_for_dq(1.0, 0.7, 0.2 * 4.0, 48.0);
    for _ in 0..50 {
        plant.advance_duties(Some(d), 48.0, PWM_PERIOD_S);
        let truth = plant.state().phase_current_a;
        let s = plant.sample();
        for (k, (&read, &true_a)) in s.phase_current_a.iter().zip(truth.iter()).enumerate() {
            let read = f64::from(read);
            let code = (read + fs) / lsb;
            assert!((code - code.round()).abs() < 1e-4, "reading {read} is not on an ADC code");
            assert!((read - true_a).abs() <= 0.5 * lsb + 1e-6, "phase {k}: {read} vs {true_a}");
        }
    }
    // Beyond the span the ADC saturates at its end code instead of wrapping.
    let mut p = noiseless(PlantParams::default());
    p.sensors.current_full_scale_a = 5.0;
    let mut plant = Plant::new(p, 3);
    assert!(plant.state().i_q_a > 10.0, "holding current exceeds the 5 A span");
    let s = plant.sample();
    let max = s.phase_current_a.iter().cloned().fold(f32::MIN, f32::max);
    let min = s.phase_current_a.iter().cloned().fold(f32::MAX, f32::min);
    assert!(f64::from(max) <= 5.0 && f64::from(min) >= -5.0);
    assert!(f64::from(max) > 4.99 || f64::from(min) < -4.99, "a saturated phase reads the end code");
}

#[test]
fn current_noise_has_the_configured_spread() {
    let p = PlantParams::default();
    let sigma = p.sensors.current_noise_a;
    let lsb = 2.0 * p.sensors.current_full_scale_a / 4096.0;
    let mut plant = Plant::new(p, 4);
    plant.set_initial_state(0.0, 0.0); // zero current
    let n = 20_000;
    let mut sum = 0.0;
    let mut sum2 = 0.0;
    for _ in 0..n {
        let x = f64::from(plant.sample().phase_current_a[1]);
        sum += x;
        sum2 += x * x;
    }
    let mean = sum / n as f64;
    // Quantisation adds lsb²/12 to the variance.
    let var_expected = sigma * sigma + lsb * lsb / 12.0;
    let var = sum2 / n as f64 - mean * mean;
    assert!(mean.abs() < 4.0 * sigma / (n as f64).sqrt(), "mean {mean}");
    assert!((var / var_expected - 1.0).abs() < 0.05, "variance {var} vs {var_expected}");
}

#[test]
fn same_seed_same_samples_other_seed_other_samples() {
    let record = |seed: u64| {
        let mut plant = Plant::new(PlantParams::default(), seed);
        let d = duties_for_dq(0.0, 2.0, 0.0, 48.0);
        (0..200)
            .map(|_| {
                plant.advance_duties(Some(d), 48.0, PWM_PERIOD_S);
                plant.sample()
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(record(9), record(9));
    assert_ne!(record(9), record(10));
}

#[test]
fn linear_scale_reads_the_rod_to_the_nearest_micrometre() {
    let mut plant = Plant::new(noiseless(PlantParams::default()), 5);
    for &theta in &[0.0, 1.7, 40.0, 400.0] {
        plant.set_initial_state(theta, 1.2);
        let x = plant.state().x_rod_m;
        let read = f64::from(plant.sample().terminal_position_m.expect("scale fitted"));
        let microns = read / 1e-6;
        // f32 carries 0.3 m to ±0.03 µm.
        assert!((microns - microns.round()).abs() < 0.1, "{read} is not a whole µm");
        assert!((read - x).abs() <= 0.5e-6 + 1e-7, "{read} vs {x}");
    }
    let mut p = PlantParams::default();
    p.sensors.linear_scale_enabled = false;
    p.sensors.load_cell_enabled = false;
    let s = Plant::new(p, 5).sample();
    assert_eq!(s.terminal_position_m, None);
    assert_eq!(s.load_cell_force_n, None);
}

#[test]
fn bus_voltage_reads_what_the_scenario_applied() {
    let mut plant = Plant::new(noiseless(PlantParams::default()), 6);
    let lsb = 72.0 / 4096.0;
    assert!((f64::from(plant.sample().bus_voltage_v) - 48.0).abs() <= 0.5 * lsb + 1e-5);
    plant.advance_duties(Some([0.5; 3]), 44.0, PWM_PERIOD_S);
    assert!((f64::from(plant.sample().bus_voltage_v) - 44.0).abs() <= 0.5 * lsb + 1e-5);
}
