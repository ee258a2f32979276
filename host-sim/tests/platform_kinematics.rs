//! Platform geometry and kinematics against closed forms and independent
//! references: the law of cosines for the home legs, FK∘IK round trip,
//! finite differences for the Jacobian, the quadratic gap between the
//! linearised and exact pose error, and the refusals.

use host_sim::platform::kinematics::FK_TOLERANCE_M;
use host_sim::platform::{Geometry, KinematicsError, Platform, Pose};
use nalgebra::{Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn pose(x: f64, y: f64, z: f64, r: f64, p: f64, w: f64) -> Pose {
    Pose::new(Vector3::new(x, y, z), Vector3::new(r.to_radians(), p.to_radians(), w.to_radians()))
}

/// Random poses about the neutral pose that stay inside the workspace.
fn workspace_poses(p: &Platform, n: usize) -> Vec<Pose> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let z0 = p.neutral().position_m.z;
    let mut out = Vec::new();
    while out.len() < n {
        let q = pose(
            rng.random_range(-0.1..0.1),
            rng.random_range(-0.1..0.1),
            z0 + rng.random_range(-0.12..0.12),
            rng.random_range(-12.0..12.0),
            rng.random_range(-12.0..12.0),
            rng.random_range(-12.0..12.0),
        );
        if p.inverse_checked(&q).is_ok() {
            out.push(q);
        }
    }
    out
}

#[test]
fn home_legs_follow_the_law_of_cosines() {
    let g = Geometry::paper();
    // Base joint at α_b/2, top joint at 60° − α_p/2: horizontal offset by the
    // law of cosines, then Pythagoras with the height.
    let gap = (60.0 - g.top_short_side_angle_deg / 2.0 - g.base_short_side_angle_deg / 2.0).to_radians();
    let d2 = g.top_radius_m.powi(2) + g.base_radius_m.powi(2) - 2.0 * g.top_radius_m * g.base_radius_m * gap.cos();
    let expected = (d2 + g.home_height_m.powi(2)).sqrt();
    let p = Platform::paper();
    let legs = p.inverse(&p.home());
    for l in legs.lengths_m {
        assert!((l - expected).abs() < 1e-12, "home leg {l} vs closed form {expected}");
    }
    for u in legs.units {
        assert!((u.norm() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn symmetric_heave_gives_equal_legs() {
    let p = Platform::paper();
    for z in [0.6, 0.7, 0.8, 0.9] {
        let l = p.inverse(&pose(0.0, 0.0, z, 0.0, 0.0, 0.0)).lengths_m;
        let spread = l.iter().fold(f64::NEG_INFINITY, |a, b| a.max(*b)) - l.iter().fold(f64::INFINITY, |a, b| a.min(*b));
        assert!(spread < 1e-12, "z = {z}: legs {l:?}");
    }
}

#[test]
fn forward_inverts_inverse_within_a_micrometre() {
    let p = Platform::paper();
    let mut worst: f64 = 0.0;
    for q in workspace_poses(&p, 200) {
        let l = p.inverse(&q).lengths_m;
        let s = p.forward(&l, &p.neutral()).expect("a workspace pose has a forward solution");
        assert!(s.residual_m <= FK_TOLERANCE_M);
        let d = s.pose.to_vector() - q.to_vector();
        worst = worst.max(d.fixed_rows::<3>(0).norm()).max(d.fixed_rows::<3>(3).norm() * p.geometry.top_radius_m);
    }
    println!("FK∘IK worst round trip over 200 poses: {:.3e} m", worst);
    assert!(worst < 1e-6, "round trip {worst} m");
}

#[test]
fn jacobian_matches_finite_differences() {
    let p = Platform::paper();
    for q in workspace_poses(&p, 20) {
        let j = p.pose_jacobian(&q);
        for k in 0..6 {
            let h = 1e-6;
            let mut a = q.to_vector();
            let mut b = q.to_vector();
            a[k] += h;
            b[k] -= h;
            let la = Vector6::from(p.inverse(&Pose::from_vector(&a)).lengths_m);
            let lb = Vector6::from(p.inverse(&Pose::from_vector(&b)).lengths_m);
            let fd = (la - lb) / (2.0 * h);
            let err = (fd - j.column(k)).amax();
            assert!(err < 1e-8, "column {k}: {err}");
        }
    }
}

#[test]
fn linear_pose_error_departs_from_exact_quadratically() {
    let p = Platform::paper();
    let nominal = p.inverse(&p.neutral()).lengths_m;
    let pattern = [0.3, -0.7, 0.5, 0.9, -0.4, 0.2];
    let gap = |scale: f64| {
        let e = pattern.map(|v| v * scale);
        let est = p.pose_error(&nominal, &e, &p.neutral()).unwrap();
        est.difference().to_vector().amax()
    };
    // The exact error agrees with the linear one to first order...
    let tiny = p.pose_error(&nominal, &pattern.map(|v| v * 1e-6), &p.neutral()).unwrap();
    assert!((tiny.exact.to_vector() - tiny.linear.to_vector()).amax() < 1e-11);
    // ...and the gap is second order: halving the leg error quarters it.
    let (g1, g2) = (gap(2e-3), gap(1e-3));
    assert!(g1 > 0.0 && (g1 / g2 - 4.0).abs() < 0.1, "gap ratio {}", g1 / g2);
}

#[test]
fn a_pose_beyond_the_stroke_is_refused_naming_leg_and_limit() {
    let p = Platform::paper();
    let too_high = pose(0.0, 0.0, 1.2, 0.0, 0.0, 0.0);
    match p.inverse_checked(&too_high) {
        Err(KinematicsError::LegLimit { leg, limit, .. }) => {
            assert_eq!((leg, limit), (1, "leg_max_length_m"));
        }
        other => panic!("expected a leg-limit refusal, got {other:?}"),
    }
    let err = p.inverse_checked(&pose(0.0, 0.0, 0.5, 0.0, 0.0, 0.0)).unwrap_err().to_string();
    assert!(err.contains("leg 1") && err.contains("leg_min_length_m"), "{err}");
    // Forward kinematics refuses lengths beyond the stroke too.
    let mut l = p.inverse(&p.neutral()).lengths_m;
    l[3] = 1.2;
    let err = p.forward(&l, &p.neutral()).unwrap_err().to_string();
    assert!(err.contains("leg 4") && err.contains("leg_max_length_m"), "{err}");
}

#[test]
fn a_singular_configuration_is_refused() {
    // Yawing the top plate by 90° lines every leg's moment arm up with its
    // direction (the classic Stewart yaw singularity). Widen the stroke so
    // the lengths alone do not refuse the pose first.
    let mut g = Geometry::paper();
    g.leg_max_length_m = 2.0;
    let p = Platform::new(g).unwrap();
    let z = p.neutral().position_m.z;
    let worst = (0..1800)
        .map(|k| k as f64 * 0.1)
        .min_by(|a, b| {
            let c = |w: f64| p.pose_jacobian(&pose(0.0, 0.0, z, 0.0, 0.0, w)).determinant().abs();
            c(*a).total_cmp(&c(*b))
        })
        .unwrap();
    match p.inverse_checked(&pose(0.0, 0.0, z, 0.0, 0.0, worst)) {
        Err(KinematicsError::Singular { leg, inverse_condition, .. }) => {
            assert!((1..=6).contains(&leg) && inverse_condition < 1e-3, "yaw {worst}°");
        }
        other => panic!("yaw {worst}°: expected a singular refusal, got {other:?}"),
    }
}

#[test]
fn impossible_lengths_report_non_convergence_with_the_residual() {
    let p = Platform::paper();
    // Legs 1 and 2 end on top joints 0.15 m apart; stretched to opposite
    // ends of the stroke from base joints at 15° and 105°, with the other
    // four short, no rigid plate fits.
    let l = [1.05, 0.60, 1.05, 0.60, 1.05, 0.60];
    match p.newton(&l, &p.neutral()) {
        Err(KinematicsError::NoConvergence { residual_m, .. }) => assert!(residual_m > FK_TOLERANCE_M),
        Ok(s) => {
            // If Newton did land, the assembly must really give these lengths.
            let back = p.inverse(&s.pose).lengths_m;
            assert!(back.iter().zip(l).all(|(a, b)| (a - b).abs() < 1e-9), "{s:?}");
            panic!("expected no assembly for {l:?}, found {:?}", s.pose);
        }
        Err(e) => panic!("expected non-convergence, got {e}"),
    }
}

#[test]
fn impossible_layouts_are_refused_naming_the_field() {
    let text = host_sim::platform::geometry::PAPER_GEOMETRY_TOML;
    let cases = [
        ("base_short_side_angle_deg = 30.0", "base_short_side_angle_deg = 0.0", "base_short_side_angle_deg"),
        ("top_short_side_angle_deg = 26.68", "top_short_side_angle_deg = 120.0", "top_short_side_angle_deg"),
        ("home_height_m = 0.596", "home_height_m = 0.3", "home_height_m"),
        ("home_height_m = 0.596", "home_height_m = 1.2", "home_height_m"),
        ("leg_min_length_m = 0.60", "leg_min_length_m = 1.10", "leg_min_length_m"),
        ("top_radius_m = 0.325", "top_radius_m = 0.0", "top_radius_m"),
        ("payload_mass_kg = 85.0", "payload_mass_kg = -1.0", "payload_mass_kg"),
        ("payload_inertia_kg_m2 = [2.528, 2.528, 4.489]", "payload_inertia_kg_m2 = [1.0, 1.0, 4.0]", "payload_inertia_kg_m2"),
        ("upper_leg_mass_kg = 13.0", "upper_leg_mas_kg = 13.0", "upper_leg_mas_kg"),
    ];
    for (from, to, field) in cases {
        assert!(text.contains(from), "fixture drifted: {from}");
        let err = Geometry::from_toml(&text.replace(from, to), "test.toml").unwrap_err().to_string();
        assert!(err.contains(field), "{to}: {err}");
    }
    assert!(Geometry::from_toml(text, "test.toml").is_ok());
}
