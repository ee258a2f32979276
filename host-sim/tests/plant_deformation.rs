//! Rigid–flexible deformation (paper §3): each term against its closed form,
//! the paper's Fig. 5 figures, and the force inversion the dynamics use.

use std::f64::consts::PI;

use host_sim::plant::{Compliance, PlantParams};
use proptest::prelude::*;

const RATED_N: f64 = 1380.0;
const STROKE_M: f64 = 0.5;

fn compliance() -> Compliance {
    Compliance::new(&PlantParams::default())
}

#[test]
fn each_term_matches_its_closed_form() {
    let p = PlantParams::default();
    let c = compliance();
    let d = &p.deformation;
    for &(f, x) in &[(RATED_N, 0.5), (1725.0, 0.2), (-900.0, 0.35), (40.0, 0.0)] {
        let got = c.static_deflection(f, x);
        let sgn = f64::signum(f);
        let a = f64::abs(f);
        // Eq. 21 with preload: C [(|F|+F_p)^(2/3) − F_p^(2/3)].
        let p1 = d.contact.preload_n;
        let d1 = sgn * d.contact.coefficient_m_per_n2_3 * ((a + p1).powf(2.0 / 3.0) - p1.powf(2.0 / 3.0));
        // Eq. 22: F x / (E_s A_s) (l0 = 0 in the rig).
        let d2 = f * (p.screw.nut_distance_at_zero_m + x) / (d.screw_axial.youngs_modulus_pa * d.screw_axial.area_m2);
        // Eq. 23.
        let d3 = f * d.rod.segment1_length_m / (d.rod.youngs_modulus_pa * d.rod.segment1_area_m2)
            + f * d.rod.segment2_length_m / (d.rod.youngs_modulus_pa * d.rod.segment2_area_m2);
        // Eq. 24.
        let p4 = d.bearing.preload_n;
        let k = d.bearing.exponent;
        let d4 = sgn * d.bearing.coefficient_m_per_n_k * ((a + p4).powf(k) - p4.powf(k));
        // Eq. 25 with T_s = F L/2π at standstill, shown at the nut × L/2π.
        let r = p.screw.lead_m / (2.0 * PI);
        let g = d.torsion.shear_modulus_pa;
        let twist = f * r
            * ((p.screw.nut_distance_at_zero_m + x) / (g * d.torsion.screw_polar_moment_m4)
                + d.torsion.fixed_end_length_m / (g * d.torsion.fixed_end_polar_moment_m4));
        let d5 = r * twist;
        let dc = r * (f * r) / p.coupling.torsional_stiffness_n_m_rad;
        let pairs = [
            (got.contact_m, d1),
            (got.screw_axial_m, d2),
            (got.rod_m, d3),
            (got.bearing_m, d4),
            (got.torsion_m, d5),
            (got.coupling_m, dc),
        ];
        for (i, (model, closed)) in pairs.iter().enumerate() {
            assert!((model - closed).abs() <= 1e-12 * closed.abs() + 1e-18, "term {i} at F={f}, x={x}: {model} vs {closed}");
        }
        let axial = c.axial_deflection_m(f, x);
        assert!((axial - (d1 + d2 + d3 + d4)).abs() < 1e-15, "axial spring = δ1+δ2+δ3+δ4");
    }
}

#[test]
fn fig5_rated_load_peaks_at_0_32_mm_at_the_end_of_stroke() {
    let c = compliance();
    let totals: Vec<f64> =
        (0..=100).map(|i| c.static_deflection(RATED_N, STROKE_M * f64::from(i) / 100.0).paper_total_m()).collect();
    // Grows along the stroke (δ2 and δ5 lengthen) ...
    assert!(totals.windows(2).all(|w| w[1] > w[0]));
    // ... to the paper's 0.32 mm at full stroke.
    let max = totals.iter().cloned().fold(f64::MIN, f64::max);
    assert!((max - 0.32e-3).abs() < 0.01 * 0.32e-3, "max over stroke {max:e} m");
    // The stroke-independent share (contact, rod, bearing, journal) is well
    // over half of it, so the error is not zero at x = 0.
    assert!(totals[0] > 0.5 * max && totals[0] < 0.7 * max, "at x = 0: {:e}", totals[0]);
}

#[test]
fn fig5_load_range_reaches_0_4_mm() {
    let c = compliance();
    let loads: Vec<f64> = (0..=50).map(|i| 1.25 * RATED_N * f64::from(i) / 50.0).collect();
    let totals: Vec<f64> = loads.iter().map(|&f| c.static_deflection(f, STROKE_M).paper_total_m()).collect();
    assert_eq!(totals[0], 0.0);
    assert!(totals.windows(2).all(|w| w[1] > w[0]), "monotone in load");
    let max = totals[totals.len() - 1];
    assert!((max - 0.4e-3).abs() < 0.03 * 0.4e-3, "at 1.25 × rated: {max:e} m");
    // Nearly linear, as Fig. 5's constant stiffness says: the preloaded
    // contacts soften the curve by only a few percent.
    let secant_ratio = (max / (1.25 * RATED_N)) / (totals[40] / RATED_N);
    assert!(secant_ratio > 0.95 && secant_ratio <= 1.0, "secant stiffness ratio {secant_ratio}");
}

#[test]
fn contact_stiffness_is_finite_at_zero_force_and_rises_with_load() {
    let c = compliance();
    let k0 = c.axial_stiffness_n_m(0.0, STROKE_M);
    let k_rated = c.axial_stiffness_n_m(RATED_N, STROKE_M);
    assert!(k0.is_finite() && k0 > 1e6, "k0 = {k0}");
    assert!(k_rated > k0, "preloaded Hertz contacts stiffen with load");
    // The slope matches a finite difference of δ(F).
    let h = 1e-3;
    let fd = 2.0 * h / (c.axial_deflection_m(RATED_N + h, STROKE_M) - c.axial_deflection_m(RATED_N - h, STROKE_M));
    assert!((fd - k_rated).abs() < 1e-6 * k_rated);
}

#[test]
fn axial_spring_energy_is_the_integral_of_force_over_deflection() {
    // V(δ) = ∫0^δ F dδ', computed by Simpson's rule over F ∈ [0, F1]
    // with dδ = δ'(F) dF, against the closed form F δ − ∫δ dF.
    let c = compliance();
    let f1 = 1.6 * RATED_N;
    let n = 2000;
    let h = f1 / n as f64;
    let integrand = |f: f64| f / c.axial_stiffness_n_m(f, 0.3);
    let mut sum = integrand(0.0) + integrand(f1);
    for i in 1..n {
        sum += integrand(h * i as f64) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    let numeric = sum * h / 3.0;
    let closed = c.axial_energy_j(f1, 0.3);
    assert!((numeric - closed).abs() < 1e-8 * closed, "{numeric} vs {closed}");
}

proptest! {
    #[test]
    fn force_inversion_round_trips(f in -6000.0f64..6000.0, x in -0.02f64..0.52, guess in -8000.0f64..8000.0) {
        let c = compliance();
        let delta = c.axial_deflection_m(f, x);
        let back = c.axial_force_n(delta, x, guess);
        prop_assert!((back - f).abs() <= 1e-9 * f.abs().max(1.0), "F {} → δ {:e} → {}", f, delta, back);
    }
}
