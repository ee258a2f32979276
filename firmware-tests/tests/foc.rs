//! Field-oriented transforms and SVPWM against their closed forms, on the
//! target's FPU and libm.
#![no_std]
#![no_main]

use core::f32::consts::PI;
use firmware_tests::{check, check_close, test_main, Outcome};
use servo_core::foc::{
    clarke, inverse_clarke, inverse_park, park, svpwm, wrap_pi, AlphaBeta, SinCos,
};

const TAU: f32 = 2.0 * PI;
/// Angle sweep: −4π … +4π (several electrical turns, both signs).
const ANGLE_STEPS: u32 = 721;

fn sweep_angle(i: u32) -> f32 {
    -2.0 * TAU + 4.0 * TAU * i as f32 / (ANGLE_STEPS - 1) as f32
}

/// A balanced three-phase set of amplitude `amp` at angle `theta`.
fn balanced(amp: f32, theta: f32) -> [f32; 3] {
    [
        amp * libm::cosf(theta),
        amp * libm::cosf(theta - TAU / 3.0),
        amp * libm::cosf(theta + TAU / 3.0),
    ]
}

/// abc → Clarke → Park(θ) → inverse Park(θ) → inverse Clarke gives back any
/// zero-sum phase set, within 1e-5 per ampere of amplitude.
fn clarke_park_roundtrip() -> Outcome {
    // Balanced sets of several amplitudes and phases, plus unbalanced
    // zero-sum ones (what a real, slightly asymmetric machine gives).
    let sets: [[f32; 3]; 6] = [
        balanced(1.0, 0.3),
        balanced(0.25, -2.0),
        balanced(40.0, 1.1),
        [0.7, -0.2, -0.5],
        [-1.0, 1.0, 0.0],
        [12.5, -30.0, 17.5],
    ];
    for abc in sets {
        let scale = abc[0].abs().max(abc[1].abs()).max(abc[2].abs()).max(1.0);
        for i in 0..ANGLE_STEPS {
            let theta = sweep_angle(i);
            let sc = SinCos::of(theta);
            let dq = park(clarke(abc), sc);
            let back = inverse_clarke(inverse_park(dq, sc));
            for k in 0..3 {
                check_close!(
                    back[k],
                    abc[k],
                    1e-5 * scale,
                    "phase {} of {:?} at θ = {}",
                    k,
                    abc,
                    theta
                );
            }
        }
    }
    Ok(())
}

/// Amplitude-invariant transforms: a balanced set of amplitude I leading the
/// rotor angle θ by φ is the constant vector (I cos φ, I sin φ) in d-q.
fn synchronous_set_is_constant_in_dq() -> Outcome {
    for amp in [1.0f32, 12.0, 36.0] {
        for phi in [0.0f32, 0.5, PI / 2.0, -2.5] {
            for i in 0..ANGLE_STEPS {
                let theta = sweep_angle(i);
                let dq = park(clarke(balanced(amp, theta + phi)), SinCos::of(theta));
                let tol = 1e-5 * amp;
                check_close!(
                    dq.d,
                    amp * libm::cosf(phi),
                    tol,
                    "I = {}, φ = {}, θ = {}",
                    amp,
                    phi,
                    theta
                );
                check_close!(
                    dq.q,
                    amp * libm::sinf(phi),
                    tol,
                    "I = {}, φ = {}, θ = {}",
                    amp,
                    phi,
                    theta
                );
            }
        }
    }
    Ok(())
}

/// A common-mode offset on all three phases does not reach α-β.
fn clarke_rejects_common_mode() -> Outcome {
    let abc = [3.0f32, -1.0, -2.0];
    let plain = clarke(abc);
    let shifted = clarke(abc.map(|x| x + 0.75));
    check_close!(shifted.alpha, plain.alpha, 1e-6);
    check_close!(shifted.beta, plain.beta, 1e-6);
    // And inverse Clarke produces no common mode.
    let back = inverse_clarke(AlphaBeta {
        alpha: 2.0,
        beta: -1.5,
    });
    check_close!(back[0] + back[1] + back[2], 0.0, 1e-6);
    Ok(())
}

/// `wrap_pi` lands in [−π, π) and moves the angle by whole turns only.
fn wrap_pi_is_whole_turns_into_range() -> Outcome {
    for i in 0..ANGLE_STEPS {
        let theta = 3.0 * sweep_angle(i);
        let w = wrap_pi(theta);
        // [−π, π) up to rounding at the two ends.
        check!(
            (-PI - 1e-5..PI + 1e-5).contains(&w),
            "wrap_pi({}) = {}",
            theta,
            w
        );
        let turns = (theta - w) / TAU;
        check_close!(turns, libm::roundf(turns), 1e-4, "θ = {}", theta);
    }
    Ok(())
}

const BUSES_V: [f32; 3] = [12.0, 48.0, 60.0];

/// Every command, inside or far outside the voltage circle, gives finite
/// duties in [0, 1]; a bad bus voltage or vector gives 50 % everywhere.
fn svpwm_duties_always_in_unit_interval() -> Outcome {
    for bus in BUSES_V {
        let vmax = bus / libm::sqrtf(3.0);
        for m in [0.0f32, 0.3, 0.9, 0.999, 1.0, 1.001, 1.5, 10.0, 1e6] {
            for i in 0..ANGLE_STEPS {
                let theta = sweep_angle(i);
                let v = AlphaBeta {
                    alpha: m * vmax * libm::cosf(theta),
                    beta: m * vmax * libm::sinf(theta),
                };
                let out = svpwm(v, bus);
                for d in out.duty {
                    check!(
                        d.is_finite() && (0.0..=1.0).contains(&d),
                        "duty {} for |v| = {}·vmax, θ = {}, bus {}",
                        d,
                        m,
                        theta,
                        bus
                    );
                }
            }
        }
    }
    let v = AlphaBeta {
        alpha: 5.0,
        beta: 1.0,
    };
    for bus in [0.0f32, -48.0, f32::NAN, f32::INFINITY] {
        let out = svpwm(v, bus);
        check!(
            out.duty == [0.5; 3] && out.limited,
            "bus {}: {:?}",
            bus,
            out
        );
    }
    for v in [
        AlphaBeta {
            alpha: f32::NAN,
            beta: 0.0,
        },
        AlphaBeta {
            alpha: 0.0,
            beta: f32::INFINITY,
        },
    ] {
        let out = svpwm(v, 48.0);
        check!(out.duty == [0.5; 3] && out.limited, "{:?}: {:?}", v, out);
    }
    Ok(())
}

/// Inside the circle `|v| < V_bus/√3` the duties reproduce the commanded
/// line-to-line voltages, `(d_x − d_y)·V_bus = v_x − v_y`, are not flagged
/// as limited, and split the zero vectors evenly (max + min duty = 1).
fn svpwm_reproduces_line_voltages_inside_circle() -> Outcome {
    for bus in BUSES_V {
        let vmax = bus / libm::sqrtf(3.0);
        let tol = 1e-5 * bus;
        for m in [0.0f32, 0.05, 0.5, 0.866, 0.99, 0.999] {
            for i in 0..ANGLE_STEPS {
                let theta = sweep_angle(i);
                let v = AlphaBeta {
                    alpha: m * vmax * libm::cosf(theta),
                    beta: m * vmax * libm::sinf(theta),
                };
                let out = svpwm(v, bus);
                check!(
                    !out.limited,
                    "|v| = {}·vmax, θ = {} flagged limited",
                    m,
                    theta
                );
                let [va, vb, vc] = inverse_clarke(v);
                let [da, db, dc] = out.duty;
                let ctx = (m, theta, bus);
                check_close!(
                    (da - db) * bus,
                    va - vb,
                    tol,
                    "v_ab, (m, θ, bus) = {:?}",
                    ctx
                );
                check_close!(
                    (db - dc) * bus,
                    vb - vc,
                    tol,
                    "v_bc, (m, θ, bus) = {:?}",
                    ctx
                );
                check_close!(
                    (dc - da) * bus,
                    vc - va,
                    tol,
                    "v_ca, (m, θ, bus) = {:?}",
                    ctx
                );
                let hi = da.max(db).max(dc);
                let lo = da.min(db).min(dc);
                check_close!(hi + lo, 1.0, 1e-6, "centring, (m, θ, bus) = {:?}", ctx);
            }
        }
    }
    Ok(())
}

/// Outside the circle the command is scaled back onto it along its own
/// direction: the produced vector has magnitude `V_bus/√3` and the
/// commanded angle, and the output says it was limited.
fn svpwm_outside_circle_keeps_direction() -> Outcome {
    for bus in BUSES_V {
        let vmax = bus / libm::sqrtf(3.0);
        for m in [1.01f32, 2.0, 100.0] {
            for i in 0..ANGLE_STEPS {
                let theta = sweep_angle(i);
                let v = AlphaBeta {
                    alpha: m * vmax * libm::cosf(theta),
                    beta: m * vmax * libm::sinf(theta),
                };
                let out = svpwm(v, bus);
                check!(out.limited, "|v| = {}·vmax, θ = {} not flagged", m, theta);
                let made = clarke(out.duty.map(|d| d * bus));
                let mag = libm::sqrtf(made.alpha * made.alpha + made.beta * made.beta);
                check_close!(mag, vmax, 1e-5 * bus, "(m, θ, bus) = {:?}", (m, theta, bus));
                // Same direction: unit vectors agree.
                check_close!(
                    made.alpha / mag,
                    libm::cosf(theta),
                    1e-4,
                    "(m, θ, bus) = {:?}",
                    (m, theta, bus)
                );
                check_close!(
                    made.beta / mag,
                    libm::sinf(theta),
                    1e-4,
                    "(m, θ, bus) = {:?}",
                    (m, theta, bus)
                );
            }
        }
    }
    Ok(())
}

/// Zero command: 50 % on every leg (zero average phase voltage).
fn svpwm_zero_vector_is_half_duty() -> Outcome {
    let out = svpwm(AlphaBeta::default(), 48.0);
    for d in out.duty {
        check_close!(d, 0.5, 1e-7);
    }
    Ok(())
}

test_main!(
    clarke_park_roundtrip,
    synchronous_set_is_constant_in_dq,
    clarke_rejects_common_mode,
    wrap_pi_is_whole_turns_into_range,
    svpwm_duties_always_in_unit_interval,
    svpwm_reproduces_line_voltages_inside_circle,
    svpwm_outside_circle_keeps_direction,
    svpwm_zero_vector_is_half_duty,
);
