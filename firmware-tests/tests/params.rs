//! The shipped parameter set, validated and checked against the rating it is
//! meant to deliver (paper Table 1), on the target's f32 arithmetic.
#![no_std]
#![no_main]

use core::f32::consts::PI;
use firmware_tests::{check, check_close, test_main, Outcome};
use servo_core::{ControlParams, Controller};

/// Nominal DC-link voltage the defaults are designed for (params.rs: 48 V).
const NOMINAL_BUS_V: f32 = 48.0;
/// Paper Table 1: rated thrust and rod speed.
const RATED_THRUST_N: f32 = 1380.0;
const RATED_SPEED_M_S: f32 = 0.25;

fn default_params_validate() -> Outcome {
    let r = ControlParams::DEFAULT.validate();
    check!(r.is_ok(), "{:?}", r);
    check!(Controller::try_new(ControlParams::DEFAULT).is_ok());
    Ok(())
}

/// A broken value is refused with the TOML path of its field.
fn validate_names_the_bad_field() -> Outcome {
    let mut p = ControlParams::DEFAULT;
    p.rates.pwm_frequency_hz = f32::NAN;
    let r = p.validate();
    check!(
        matches!(r, Err(e) if e.field() == "control.rates.pwm_frequency_hz"),
        "{:?}",
        r
    );

    let mut p = ControlParams::DEFAULT;
    p.motor.phase_resistance_ohm = -0.1;
    let r = p.validate();
    check!(
        matches!(r, Err(e) if e.field() == "control.motor.phase_resistance_ohm"),
        "{:?}",
        r
    );

    let mut p = ControlParams::DEFAULT;
    p.rates.position_loop_divider = p.rates.speed_loop_divider + 1;
    let r = p.validate();
    check!(
        matches!(r, Err(e) if e.field() == "control.rates.position_loop_divider"),
        "{:?}",
        r
    );
    Ok(())
}

/// The defaults can make rated thrust at rated speed: the current for rated
/// torque `F L / (2π η)` fits the current limit, the speed limit covers the
/// rated rod speed, and the back-EMF there fits the linear SVPWM range.
fn defaults_reach_rated_operating_point() -> Outcome {
    let p = ControlParams::DEFAULT;
    let kt = 1.5 * p.motor.pole_pairs as f32 * p.motor.flux_linkage_wb;
    check_close!(p.torque_constant_n_m_a(), kt, 1e-6 * kt);
    let torque =
        RATED_THRUST_N * p.drive_train.screw_lead_m / (2.0 * PI * p.drive_train.screw_efficiency);
    let current = torque / kt;
    check!(
        current < p.current_limit_a(),
        "rated current {} A vs limit {} A",
        current,
        p.current_limit_a()
    );

    let speed = RATED_SPEED_M_S / p.metres_per_rad();
    check!(
        speed <= p.limits.speed_max_rad_s * (1.0 + 1e-5),
        "rated {} rad/s vs limit {}",
        speed,
        p.limits.speed_max_rad_s
    );
    let back_emf = p.motor.pole_pairs as f32 * speed * p.motor.flux_linkage_wb;
    let available = NOMINAL_BUS_V / libm::sqrtf(3.0) * p.limits.max_modulation;
    check!(
        back_emf < available,
        "back-EMF {} V vs {} V",
        back_emf,
        available
    );

    // Loop periods are whole PWM periods.
    check_close!(p.pwm_period_s() * p.rates.pwm_frequency_hz, 1.0, 1e-6);
    check_close!(
        p.position_period_s() / p.speed_period_s(),
        (p.rates.position_loop_divider / p.rates.speed_loop_divider) as f32,
        1e-5
    );
    Ok(())
}

test_main!(
    default_params_validate,
    validate_names_the_bad_field,
    defaults_reach_rated_operating_point
);
