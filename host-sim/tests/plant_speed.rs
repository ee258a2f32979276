//! The speed work on the plant keeps its numbers: the Halley cube root
//! against `f64::cbrt`, the tangent-warm-started force inversion against a
//! cold one, and the step rule (oscillatory modes |λh| ≤ 1, dissipative
//! relaxations ≤ 2.5) on the shipped rig and on one it must refuse.

use host_sim::plant::deformation::{cube_root, AxialWarmStart};
use host_sim::plant::{Plant, PlantParams};

#[test]
fn halley_cube_root_matches_cbrt_to_two_ulps() {
    let mut a: f64 = 1e-6;
    let mut warm = 0.0;
    while a < 1e9 {
        let exact = a.cbrt();
        for guess in [0.0, warm, exact * 1.05, exact * 0.97] {
            let t = cube_root(a, guess);
            assert!((t - exact).abs() <= 2.0 * f64::EPSILON * exact, "a = {a:e}, guess {guess}: {t} vs {exact}");
        }
        warm = exact;
        a *= 1.0137;
    }
}

#[test]
fn warm_started_force_inversion_agrees_with_a_cold_one() {
    let p = PlantParams::default();
    let plant = Plant::new(p, 1);
    let c = plant.compliance();
    let mut warm = AxialWarmStart::default();
    // A slow swing through zero and up to 1.5 × rated, as an axial
    // vibration would take the spring.
    for k in 0..20_000 {
        let t = k as f64 * 1e-4;
        let f_true = 2000.0 * (7.0 * t).sin() + 300.0 * (61.0 * t).sin();
        let x = 0.2 + 0.1 * (3.0 * t).sin();
        let d = c.axial_deflection_m(f_true, x);
        let hot = c.axial_force_warm(d, x, &mut warm);
        let cold = c.axial_force_n(d, x, 0.0);
        assert!((hot - cold).abs() <= 1e-9 * cold.abs().max(1.0), "step {k}: {hot} vs {cold}");
        assert!((hot - f_true).abs() <= 1e-9 * f_true.abs().max(1.0), "step {k}: {hot} vs {f_true}");
    }
}

#[test]
fn the_step_rule_separates_oscillatory_from_dissipative_modes() {
    let p = PlantParams::default();
    let h = p.max_step_s();
    let rates = p.fastest_rates_per_s();
    let rate = |name: &str| rates.iter().find(|(n, _)| *n == name).map(|(_, r)| *r).unwrap();
    // The shipped step (one per PWM period) leaves the screw friction
    // relaxation above 2 at three times the full weight (it is the reason
    // 2 and 4 substeps were used) but inside the dissipative limit, and
    // every oscillatory mode far below 1.
    assert_eq!(h, 50e-6);
    let friction = rate("screw friction regularisation") * h;
    assert!(friction > 2.0 && friction <= 2.5, "{friction}");
    for name in ["electrical R/L", "torsional mode", "axial mode", "end-stop contact"] {
        assert!(rate(name) * h < 0.3, "{name}: {}", rate(name) * h);
    }
    assert!(p.validate().is_ok());
    assert_eq!(p.substeps(), 1);
    // A stiffer end stop puts an oscillatory mode at |λh| ≈ 1.3 for one
    // step per period: the plant halves its step, though a dissipative
    // mode would have been left at that |λh|.
    let mut stiff = PlantParams::default();
    stiff.stroke.stop_stiffness_n_m = 1.0e11;
    assert!(stiff.validate().is_ok());
    let stop = stiff.fastest_rates_per_s().iter().find(|(n, _)| *n == "end-stop contact").unwrap().1;
    assert!(stop * 50e-6 > 1.0 && stop * 50e-6 < 2.5, "{}", stop * 50e-6);
    assert_eq!(stiff.substeps(), 2);
}

#[test]
fn rotated_sin_cos_stays_within_a_few_ulps_of_the_exact() {
    use host_sim::plant::frames::SinCosCache;
    let mut cache = SinCosCache::default();
    let mut worst: f64 = 0.0;
    // An electrical angle running up to 2300 rad in RK4-stage-sized steps
    // (a quarter of 0.031 rad, the fastest the rod moves), back and forth.
    let mut a = 0.0;
    for k in 0..400_000 {
        a += if (k / 50_000) % 2 == 0 { 0.0078 } else { -0.0031 };
        let (s, c) = cache.sin_cos(a);
        let (se, ce) = a.sin_cos();
        worst = worst.max((s - se).abs()).max((c - ce).abs());
    }
    assert!(worst <= 4.0 * f64::EPSILON, "worst {worst:e}");
}
