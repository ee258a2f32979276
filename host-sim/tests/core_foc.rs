//! The current-loop building blocks against closed forms.

use servo_core::foc::{clarke, inverse_clarke, inverse_park, park, svpwm, wrap_pi, AlphaBeta, Dq, SinCos};
use servo_core::params::PiGains;
use servo_core::pi::Pi;
use std::f32::consts::PI;

#[test]
fn balanced_currents_map_to_a_constant_dq_vector() {
    // i_x = I cos(θ − k·2π/3 + φ) is, in the frame at angle θ, the vector
    // I·(cos φ, sin φ): amplitude-invariant Clarke/Park.
    let (amp, phi) = (7.5_f32, 0.6_f32);
    for k in 0..360 {
        let theta = k as f32 * PI / 180.0;
        let abc = [0.0, 1.0, 2.0].map(|n: f32| amp * (theta - n * 2.0 * PI / 3.0 + phi).cos());
        let dq = park(clarke(abc), SinCos::of(theta));
        assert!((dq.d - amp * phi.cos()).abs() < 1e-4, "d at {theta}: {}", dq.d);
        assert!((dq.q - amp * phi.sin()).abs() < 1e-4, "q at {theta}: {}", dq.q);
    }
}

#[test]
fn park_and_clarke_invert() {
    for k in 0..100 {
        let theta = -7.0 + 0.14 * k as f32;
        let sc = SinCos::of(theta);
        let v = Dq { d: 3.0 - 0.05 * k as f32, q: -2.0 + 0.07 * k as f32 };
        let back = park(clarke(inverse_clarke(inverse_park(v, sc))), sc);
        assert!((back.d - v.d).abs() < 1e-5 && (back.q - v.q).abs() < 1e-5, "{v:?} -> {back:?}");
    }
}

#[test]
fn wrap_pi_stays_in_range_and_keeps_the_angle() {
    for k in -2000..2000 {
        let a = k as f32 * 0.0137;
        let w = wrap_pi(a);
        assert!((-PI..PI + 1e-6).contains(&w), "{a} -> {w}");
        assert!(((a - w) / (2.0 * PI) - ((a - w) / (2.0 * PI)).round()).abs() < 1e-4);
    }
}

#[test]
fn svpwm_reproduces_line_voltages_inside_the_circle() {
    let bus = 48.0_f32;
    let vmax = bus / 3f32.sqrt();
    for k in 0..720 {
        let ang = k as f32 * PI / 360.0;
        for frac in [0.0, 0.3, 0.7, 0.999] {
            let v = AlphaBeta { alpha: frac * vmax * ang.cos(), beta: frac * vmax * ang.sin() };
            let out = svpwm(v, bus);
            assert!(!out.limited);
            assert!(out.duty.iter().all(|d| (0.0..=1.0).contains(d)), "{:?}", out.duty);
            // Line-to-line voltages are what the motor sees; common mode is free.
            let want = inverse_clarke(v);
            for (x, y) in [(0, 1), (1, 2), (2, 0)] {
                let got = (out.duty[x] - out.duty[y]) * bus;
                assert!((got - (want[x] - want[y])).abs() < 2e-4 * bus, "leg {x}-{y} at {ang}: {got}");
            }
        }
    }
}

#[test]
fn svpwm_scales_an_oversized_request_back_along_its_direction() {
    let bus = 48.0_f32;
    let v = AlphaBeta { alpha: 60.0, beta: -35.0 };
    let out = svpwm(v, bus);
    assert!(out.limited);
    let l = inverse_clarke(AlphaBeta { alpha: v.alpha, beta: v.beta });
    let got = [(out.duty[0] - out.duty[1]) * bus, (out.duty[1] - out.duty[2]) * bus];
    // Same direction: the line voltages are proportional to the request's.
    let ratio0 = got[0] / (l[0] - l[1]);
    let ratio1 = got[1] / (l[1] - l[2]);
    assert!((ratio0 - ratio1).abs() < 1e-4 && ratio0 < 1.0 && ratio0 > 0.0);
    // And on the circle.
    let mag = (v.alpha * v.alpha + v.beta * v.beta).sqrt() * ratio0;
    assert!((mag - bus / 3f32.sqrt()).abs() < 1e-3);
}

#[test]
fn svpwm_with_no_bus_gives_zero_volts() {
    for bus in [0.0, -5.0, f32::NAN] {
        let out = svpwm(AlphaBeta { alpha: 1.0, beta: 1.0 }, bus);
        assert_eq!(out.duty, [0.5; 3]);
        assert!(out.limited);
    }
}

#[test]
fn pi_does_not_wind_up_while_saturated() {
    let g = PiGains { kp: 1.0, ki: 100.0 };
    let mut pi = Pi::new();
    // A long positive error against a ±1 limit.
    for _ in 0..10_000 {
        let o = pi.update(&g, 5.0, 0.0, -1.0, 1.0, 1e-3);
        assert_eq!(o.value, 1.0);
    }
    assert!(pi.integral() <= 1.0 + 1e-6, "integral wound up to {}", pi.integral());
    // The moment the error turns, the output leaves the limit.
    let o = pi.update(&g, -0.5, 0.0, -1.0, 1.0, 1e-3);
    assert!(o.value < 1.0 && !o.saturated, "{o:?}");
}

#[test]
fn pi_integrates_to_the_closed_form_when_unsaturated() {
    let g = PiGains { kp: 2.0, ki: 10.0 };
    let mut pi = Pi::new();
    let mut last = 0.0;
    for _ in 0..100 {
        last = pi.update(&g, 0.1, 0.25, -100.0, 100.0, 1e-3).value;
    }
    // kp·e + ki·e·t + ff with t = 0.1 s.
    assert!((last - (0.2 + 10.0 * 0.1 * 0.1 + 0.25)).abs() < 1e-5, "{last}");
}
