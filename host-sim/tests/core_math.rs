//! The core's f32 maths against f64 references.

use servo_core::math::{atan2, cbrt, clamp, exp_neg, floor, round, sincos, sqrt, tan};

#[test]
fn sincos_is_within_2e7_of_f64_over_many_turns() {
    let mut worst: f64 = 0.0;
    for k in -200_000..200_000 {
        let x = k as f32 * 1.3e-3; // ±260 rad
        let (s, c) = sincos(x);
        let xd = f64::from(x);
        worst = worst.max((f64::from(s) - xd.sin()).abs()).max((f64::from(c) - xd.cos()).abs());
    }
    assert!(worst < 2e-7, "worst {worst:e}");
}

#[test]
fn exp_neg_is_within_3e7_relative_of_f64() {
    for k in 0..87_000 {
        let x = -(k as f32) * 1e-3;
        let want = f64::from(x).exp();
        let got = f64::from(exp_neg(x));
        assert!(((got - want) / want).abs() < 3e-7, "exp({x}) = {got} vs {want}");
    }
    assert_eq!(exp_neg(-100.0), 0.0);
    assert_eq!(exp_neg(f32::NAN), 0.0);
}

#[test]
fn exp_neg_above_zero_takes_the_same_path() {
    // A chirp's exponent can round a little above 0; no libm `expf` behind it.
    for k in 0..88_000 {
        let x = k as f32 * 1e-3;
        let want = f64::from(x).exp();
        let got = f64::from(exp_neg(x));
        assert!(((got - want) / want).abs() < 3e-7, "exp({x}) = {got} vs {want}");
    }
    assert_eq!(exp_neg(88.5), f32::INFINITY);
}

#[test]
fn cbrt_tan_sqrt_match_f64() {
    for k in 1..10_000 {
        let x = k as f32 * 1.7e-4;
        assert!((f64::from(cbrt(x)) - f64::from(x).cbrt()).abs() < 2e-7 * f64::from(x).cbrt(), "cbrt {x}");
        assert!((f64::from(cbrt(-x)) + f64::from(x).cbrt()).abs() < 2e-7 * f64::from(x).cbrt());
        assert_eq!(sqrt(x), libm::sqrtf(x), "sqrt must be the correctly rounded one");
        let t = x * 0.9; // < π/2
        assert!((f64::from(tan(t)) - f64::from(t).tan()).abs() < 1e-6 * (1.0 + f64::from(t).tan().powi(2)));
    }
}

#[test]
fn floor_round_clamp_never_surprise() {
    for (x, f, r) in [(2.5_f32, 2.0, 3.0), (-2.5, -3.0, -3.0), (-0.2, -1.0, 0.0), (7.0, 7.0, 7.0), (-7.0, -7.0, -7.0)] {
        assert_eq!(floor(x), f, "floor {x}");
        assert_eq!(round(x), r, "round {x}");
    }
    assert_eq!(clamp(f32::NAN, -1.0, 1.0), -1.0);
    assert_eq!(clamp(5.0, -1.0, 1.0), 1.0);
    assert_eq!(clamp(-5.0, -1.0, 1.0), -1.0);
    // Inverted bounds: no panic, and the result is one of them.
    for x in [-3.0, 0.0, 3.0, f32::NAN] {
        let y = clamp(x, 1.0, -1.0);
        assert!(y == 1.0 || y == -1.0, "{x} -> {y}");
    }
}

#[test]
fn atan2_is_within_3_5e7_of_f64_in_every_quadrant() {
    let mut worst: f64 = 0.0;
    let mut worst_libm: f64 = 0.0;
    for k in 0..400_000 {
        // Angles all round the circle, radii over six decades.
        let phi = k as f64 * (std::f64::consts::TAU / 400_000.0) - std::f64::consts::PI;
        let r = 10f64.powf((k % 61) as f64 * 0.1 - 3.0);
        let (y, x) = ((r * phi.sin()) as f32, (r * phi.cos()) as f32);
        let want = f64::from(y).atan2(f64::from(x));
        let got = f64::from(atan2(y, x));
        // On the circle: +π and −π are the same direction.
        let d = got - want;
        let err = if d.abs() > std::f64::consts::PI { (d.abs() - std::f64::consts::TAU).abs() } else { d.abs() };
        worst = worst.max(err);
        worst_libm = worst_libm.max((f64::from(libm::atan2f(y, x)) - want).abs());
    }
    // Near ±π an f32 ulp is 2.4e-7 (libm's atan2f is off by that much too).
    assert!(worst < 3.5e-7, "worst {worst:e} (libm's atan2f: {worst_libm:e})");
}

#[test]
fn atan2_edges_match_libm() {
    use std::f32::consts::{FRAC_PI_2, PI};
    for (y, x) in [(0.0f32, 1.0f32), (-0.0, 1.0), (0.0, -1.0), (-0.0, -1.0), (1.0, 0.0), (-1.0, 0.0), (1.0, -0.0)] {
        assert_eq!(atan2(y, x).to_bits(), libm::atan2f(y, x).to_bits(), "atan2({y}, {x})");
    }
    assert_eq!(atan2(0.0, 0.0).to_bits(), 0.0f32.to_bits());
    assert_eq!(atan2(-0.0, 0.0).to_bits(), (-0.0f32).to_bits());
    assert_eq!(atan2(0.0, -0.0), PI);
    assert_eq!(atan2(-0.0, -0.0), -PI);
    assert_eq!(atan2(1.0, f32::INFINITY), 0.0);
    assert_eq!(atan2(f32::INFINITY, 1.0), FRAC_PI_2);
    assert!(atan2(f32::NAN, 1.0).is_nan() && atan2(1.0, f32::NAN).is_nan());
}

/// The figures docs/architecture.md gives for keeping the core's sin/cos
/// over micromath's: the largest error of each against f64 over 200 000
/// angles in [-pi, pi) (`-- --nocapture` prints them).
#[test]
fn core_sincos_is_far_more_accurate_than_micromath() {
    use micromath::F32Ext;
    let (mut e_mm, mut e_core) = (0.0f64, 0.0f64);
    for i in 0..200_000 {
        let x = -std::f32::consts::PI + i as f32 * (2.0 * std::f32::consts::PI / 200_000.0);
        let (s, c) = (f64::from(x).sin(), f64::from(x).cos());
        e_mm = e_mm.max((f64::from(F32Ext::sin(x)) - s).abs()).max((f64::from(F32Ext::cos(x)) - c).abs());
        let (ps, pc) = sincos(x);
        e_core = e_core.max((f64::from(ps) - s).abs()).max((f64::from(pc) - c).abs());
    }
    println!("largest |error| on [-pi, pi): micromath {e_mm:.2e}, servo_core::math::sincos {e_core:.2e}");
    assert!(e_core < 2e-7, "core sin/cos error {e_core:e}");
    assert!(e_mm > 100.0 * e_core, "micromath {e_mm:e} against core {e_core:e}: the documented reason no longer holds");
}
