//! Cost of the control core on a Cortex-M4F, in executed instructions.
//!
//! Run by `firmware-tests/cost.sh` under `qemu-system-arm -icount shift=7`
//! (see `firmware_tests::icount` and docs/cost.md). Not a test: it asserts
//! no budget, it prints figures — a table for people and one `JSON {...}`
//! line that cost.sh puts into `out/cost/summary.json`.
//!
//! What is measured:
//! - `Controller::step` in closed loop with a rigid PMSM plant during a
//!   10 mm move (the plant is not counted), split by period kind: current
//!   loop only, speed + current, position + speed + current (+ telemetry);
//!   and a step with the bridge off;
//! - the error observer's forward pass (`observer::evaluate`), which the
//!   position period will run once it is wired into the controller;
//! - the pieces, one call at a time, to show where the instructions go;
//! - the core's single-precision sin/cos and `vsqrt.f32` next to the libm
//!   routines they replaced, to show what they saved.
//!
//! Every figure is the mean over many calls with varying inputs; each call
//! is counted exactly (one SysTick read before, one after; the read itself
//! is subtracted). Calls go through `#[inline(never)]` wrappers, so each
//! figure includes one call and return, as the ISR pays them.
#![no_std]
#![no_main]

use core::f32::consts::PI;
use core::hint::black_box;

use cortex_m_semihosting::hprintln;
use firmware_tests::icount::{Meter, Stats};
use golden::plant::{Noise, RigidPlant};
use golden::CLOSED_LOOP_SCRIPT;
use servo_core::foc::current_loop::RotorState;
use servo_core::foc::{
    clarke, inverse_park, park, svpwm, wrap_pi, AlphaBeta, CurrentLoop, CurrentTiming, Dq, SinCos,
};
use servo_core::motion::{position_step, EncoderTracker, ScurveMove, SpeedLoop};
use servo_core::capture::CaptureStore;
use servo_core::observer;
use servo_core::params::ValidatedParams;
use servo_core::protocol::{CaptureConfig, CaptureState, CaptureTrigger, Signal, TestSignal};
use servo_core::pi::Pi;
use servo_core::{ControlParams, Controller, Mode, PwmCommand, SensorSample};

/// `Controller::step` runs the error observer in its position periods
/// (with compensation on, which the closed-loop script switches on), so the
/// position period's figure includes it.
const OBSERVER_IN_STEP: bool = true;

mod pieces;
mod scenarios;

use pieces::*;
use scenarios::*;

// ---- report ----------------------------------------------------------------

struct Row {
    key: &'static str,
    what: &'static str,
    mean: f64,
    min: f64,
    max: f64,
    calls: u32,
}

fn row(m: &Meter, key: &'static str, what: &'static str, s: &Stats) -> Row {
    let (mean, min, max) = s.insns(m);
    Row {
        key,
        what,
        mean,
        min,
        max,
        calls: s.count,
    }
}

/// Measures `call(input(i))` for `i in 0..n`, one call at a time; the
/// input is prepared outside the measurement.
fn each<I>(m: &Meter, n: u32, mut input: impl FnMut(u32) -> I, mut call: impl FnMut(I)) -> Stats {
    let mut s = Stats::new();
    for i in 0..n {
        let x = black_box(input(i));
        let (_, t) = m.measure(|| call(x));
        s.add(t);
    }
    s
}

#[firmware_tests::entry]
fn main() -> ! {
    let m = Meter::calibrate();
    hprintln!(
        "calibration: {} SysTick ticks per instruction, reading the counter costs {} ticks ({})",
        m.ticks_per_insn,
        m.read_ticks,
        if m.deterministic {
            "deterministic: -icount is on"
        } else {
            "NOT deterministic: run under -icount"
        }
    );
    if !m.deterministic {
        firmware_tests::exit(false);
    }

    let p = ControlParams::DEFAULT;
    let mut rows: [Option<Row>; 28] = Default::default();
    let mut n_rows = 0usize;
    let mut push = |r: Row| {
        if let Some(slot) = rows.get_mut(n_rows) {
            *slot = Some(r);
            n_rows += 1;
        }
    };

    // ---- Controller::step in closed loop ---------------------------------
    let (cur, spd, pos, off, faults_seen) = closed_loop(&m, p, false, None);
    // The same run with a capture recording four signals every period
    // (re-armed whenever it is done): what the scope costs while it records.
    let (cap_cur, cap_spd, cap_pos, _, _) = closed_loop(&m, p, true, None);
    // The same run with an uploaded five-input model (the direction of
    // travel used): the longest forward pass the drive can be given.
    let (_, five_spd, five_pos, _, five_faults) = closed_loop(&m, p, false, Some(&golden::FIVE_INPUT_MODEL));
    let faults_seen = faults_seen || five_faults;
    push(row(
        &m,
        "step_current",
        "Controller::step, current loop only (19 of 20 periods minus speed)",
        &cur,
    ));
    push(row(
        &m,
        "step_speed",
        "Controller::step, speed + current loop (every 4th)",
        &spd,
    ));
    push(row(
        &m,
        "step_position",
        "Controller::step, position + speed + current + telemetry (every 20th)",
        &pos,
    ));
    push(row(
        &m,
        "step_position_five_input",
        "Controller::step, position + speed + current + telemetry, an uploaded five-input observer model",
        &five_pos,
    ));
    push(row(
        &m,
        "step_bridge_off",
        "Controller::step, bridge off (disabled)",
        &off,
    ));
    push(row(
        &m,
        "step_current_capturing",
        "Controller::step, current loop only, a 4-signal capture recording every period",
        &cap_cur,
    ));
    push(row(
        &m,
        "step_speed_capturing",
        "Controller::step, speed + current loop, the same capture recording",
        &cap_spd,
    ));
    push(row(
        &m,
        "step_position_capturing",
        "Controller::step, position + speed + current + telemetry, the same capture recording",
        &cap_pos,
    ));

    // ---- the longest period with bulk requests ---------------------------
    // Each request kind served wherever it lands, and as the firmware
    // serves it (in current-only periods); [current, speed, position].
    let ops = [(Bulk::ApplyParams, "apply_params"), (Bulk::CaptureConfigure, "capture_configure"), (Bulk::TestStart, "test_start")];
    let mut any_period = [[0u32; 3]; 3];
    let mut current_only = [[0u32; 3]; 3];
    let mut accepted = [[0u32; 2]; 3];
    for (i, (op, _)) in ops.iter().enumerate() {
        let (w, a) = worst_with_bulk(&m, p, *op, Serve::AnyPeriod, false);
        let (w2, a2) = worst_with_bulk(&m, p, *op, Serve::Firmware, false);
        if let (Some(x), Some(y), Some(acc)) = (any_period.get_mut(i), current_only.get_mut(i), accepted.get_mut(i)) {
            *x = w;
            *y = w2;
            *acc = [a, a2];
        }
    }
    let worst_of = |table: &[[u32; 3]; 3]| table.iter().flat_map(|r| r.iter()).copied().max().unwrap_or(0);
    // A parameter set while short captures end one after another: served
    // before any current-only period (a capture's end among them), and as
    // the firmware serves it (never beside a capture's batch).
    let (cap_current_only, cap_acc0) = worst_with_bulk(&m, p, Bulk::ApplyParams, Serve::CurrentOnly, true);
    let (cap_firmware, cap_acc1) = worst_with_bulk(&m, p, Bulk::ApplyParams, Serve::Firmware, true);
    let worst_any = worst_of(&any_period);
    let worst_fw = worst_of(&current_only).max(cap_firmware.iter().copied().max().unwrap_or(0));
    let position_max = pos.insns(&m).2;

    // ---- observer ---------------------------------------------------------
    let model = &observer::model::MODEL;
    let obs_input = |i: u32| {
        let mut x = [0.0f32; 4];
        for (j, xj) in x.iter_mut().enumerate() {
            let frac = ((i * (7 + 2 * j as u32)) % 101) as f32 / 100.0;
            *xj = model.input_min[j] + frac * (model.input_max[j] - model.input_min[j]);
        }
        x
    };
    let obs_stats = each(&m, 400, obs_input, |x| {
        black_box(observe(x));
    });
    push(row(
        &m,
        "observer_evaluate",
        "observer::evaluate (the generated RBF model, 4 inputs)",
        &obs_stats,
    ));
    let net_input = |i: u32| {
        let [a, b, c, d] = obs_input(i);
        [a, b, c, d, if i % 2 == 0 { 1.0 } else { -1.0 }]
    };
    let net_stats = each(&m, 400, net_input, |x| {
        black_box(observe_network(x));
    });
    push(row(
        &m,
        "observer_network",
        "observer::evaluate in the drive's five-slot network (the compiled model, fifth input unused), as the position loop runs it",
        &net_stats,
    ));
    push(row(
        &m,
        "observer_network_five_input",
        "observer::evaluate in the five-slot network, a five-input model (the direction of travel used)",
        &each(&m, 400, net_input, |x| {
            black_box(observe_five_input(x));
        }),
    ));

    // ---- pieces -----------------------------------------------------------
    let angle = |i: u32| -PI + (i % 997) as f32 * (2.0 * PI / 997.0);
    push(row(
        &m,
        "libm_sincosf",
        "libm::sincosf, angles in [-pi, pi) (f64 inside: soft-float on the M4)",
        &each(&m, 997, angle, |x| {
            black_box(sincos(x));
        }),
    ));
    push(row(
        &m,
        "poly_sincosf",
        "servo_core::math::sincos (f32 polynomial), same angles",
        &each(&m, 997, angle, |x| {
            black_box(sincos_poly(x));
        }),
    ));
    push(row(
        &m,
        "micromath_sincosf",
        "micromath F32Ext sin + cos, same angles",
        &each(&m, 997, angle, |x| {
            black_box(sincos_micromath(x));
        }),
    ));
    push(row(
        &m,
        "libm_sqrtf",
        "libm::sqrtf (software on this target)",
        &each(
            &m,
            500,
            |i| 1.0 + i as f32 * 3.7,
            |x| {
                black_box(sqrt(x));
            },
        ),
    ));
    push(row(
        &m,
        "vsqrt",
        "servo_core::math::sqrt (vsqrt.f32)",
        &each(
            &m,
            500,
            |i| 1.0 + i as f32 * 3.7,
            |x| {
                black_box(vsqrt(x));
            },
        ),
    ));
    push(row(
        &m,
        "libm_expf",
        "libm::expf (for comparison; the observer has its own f32 exp2)",
        &each(
            &m,
            500,
            |i| -(i as f32) * 0.01,
            |x| {
                black_box(expf(x));
            },
        ),
    ));
    push(row(
        &m,
        "wrap_pi",
        "wrap_pi (f32 floor)",
        &each(
            &m,
            500,
            |i| angle(i) * 3.0,
            |x| {
                black_box(wrap(x));
            },
        ),
    ));
    let sc = SinCos { sin: 0.6, cos: 0.8 };
    push(row(
        &m,
        "clarke_park",
        "clarke + park",
        &each(
            &m,
            500,
            |i| [i as f32 * 0.01, -1.0, 0.5],
            |x| {
                black_box(clarke_park(x, sc));
            },
        ),
    ));
    push(row(
        &m,
        "inverse_park",
        "inverse park",
        &each(
            &m,
            500,
            |i| Dq {
                d: 1.0,
                q: i as f32 * 0.01,
            },
            |x| {
                black_box(inverse_park_call(x, sc));
            },
        ),
    ));
    let mut pi = Pi::new();
    push(row(
        &m,
        "pi_update",
        "Pi::update (one axis)",
        &each(
            &m,
            500,
            |i| (i % 50) as f32 * 0.1 - 2.5,
            |x| {
                black_box(pi_update(&mut pi, &p, x));
            },
        ),
    ));
    let ab = |i: u32| {
        let a = angle(i);
        AlphaBeta {
            alpha: 10.0 * libm::cosf(a),
            beta: 10.0 * libm::sinf(a),
        }
    };
    push(row(
        &m,
        "svpwm",
        "svpwm (min-max injection, inside the circle)",
        &each(&m, 500, ab, |x| {
            black_box(svpwm_call(x, 48.0));
        }),
    ));
    let mut cl = CurrentLoop::new();
    let cl_input = |i: u32| {
        let a = angle(i);
        let abc = [
            3.0 * libm::cosf(a),
            3.0 * libm::cosf(a - 2.1),
            3.0 * libm::cosf(a + 2.1),
        ];
        (
            abc,
            RotorState {
                electrical_angle_rad: a,
                electrical_speed_rad_s: 400.0,
            },
        )
    };
    push(row(
        &m,
        "current_loop",
        "CurrentLoop::step (1 sin/cos + advance rotation, vsqrt, 2 PI, SVPWM)",
        &each(&m, 997, cl_input, |(abc, rotor)| {
            black_box(current_loop(
                &mut cl,
                &p,
                abc,
                Dq { d: 0.0, q: 3.0 },
                rotor,
                48.0,
            ));
        }),
    ));
    let mut enc = EncoderTracker::new();
    push(row(
        &m,
        "encoder_update",
        "EncoderTracker::update (unwrap + PLL)",
        &each(
            &m,
            500,
            |i| (i * 13) as u16,
            |x| {
                black_box(encoder(&mut enc, &p, x));
            },
        ),
    ));
    let mut sl = SpeedLoop::new(&p);
    push(row(
        &m,
        "speed_loop",
        "SpeedLoop::step (PI + feedforward + torque filter)",
        &each(
            &m,
            500,
            |i| 95.0 + (i % 10) as f32,
            |x| {
                black_box(speed_loop(&mut sl, &p, 100.0, x));
            },
        ),
    ));
    let mv = ScurveMove::plan(0.1, 0.11, &p.trajectory);
    let dur = mv.duration_s();
    push(row(
        &m,
        "trajectory_sample",
        "ScurveMove::sample",
        &each(
            &m,
            500,
            |i| dur * i as f32 / 500.0,
            |x| {
                black_box(trajectory(&mv, x));
            },
        ),
    ));
    push(row(
        &m,
        "position_step",
        "position_step (P + feedforward)",
        &each(
            &m,
            500,
            |i| 0.1 + i as f32 * 1e-6,
            |x| {
                black_box(position(&p, 0.1, x));
            },
        ),
    ));

    // ---- derived figures -------------------------------------------------
    let mean = |st: &Stats| st.insns(&m).0;
    let speed_increment = mean(&spd) - mean(&cur);
    let position_increment = mean(&pos) - mean(&spd);
    let position_with_observer = mean(&pos);
    let position_increment_with_observer = position_increment;
    let position_increment_five = mean(&five_pos) - mean(&five_spd);

    // ---- print --------------------------------------------------------------
    hprintln!(
        "{:<20} {:>9} {:>8} {:>8} {:>6}  what",
        "figure",
        "mean",
        "min",
        "max",
        "calls"
    );
    for r in rows.iter().flatten() {
        hprintln!(
            "{:<20} {:>9.1} {:>8.0} {:>8.0} {:>6}  {}",
            r.key,
            r.mean,
            r.min,
            r.max,
            r.calls,
            r.what
        );
    }
    hprintln!(
        "speed loop alone (speed period - current period):         {:>8.1}",
        speed_increment
    );
    hprintln!(
        "position loop alone (position period - speed period):    {:>8.1}",
        position_increment
    );
    hprintln!(
        "position period with the observer: {:>8.1}  (position loop alone with it: {:.1}; with a five-input model: {:.1})",
        position_with_observer,
        position_increment_with_observer,
        position_increment_five
    );
    hprintln!("longest PWM period with a bulk request served before the step (instructions; current / speed / position periods):");
    for (i, (_, name)) in ops.iter().enumerate() {
        if let (Some(a), Some(f), Some(acc)) = (any_period.get(i), current_only.get(i), accepted.get(i)) {
            hprintln!(
                "  {:<18} wherever it lands: {:>5} {:>5} {:>5}   current-only periods (firmware): {:>5} {:>5} {:>5}   ({} / {} accepted)",
                name, a[0], a[1], a[2], f[0], f[1], f[2], acc[0], acc[1]
            );
        }
    }
    hprintln!(
        "  apply_params while captures end: current-only periods {:>5} {:>5} {:>5}   firmware (no capture batch) {:>5} {:>5} {:>5}   ({} / {} accepted)",
        cap_current_only[0], cap_current_only[1], cap_current_only[2], cap_firmware[0], cap_firmware[1], cap_firmware[2], cap_acc0, cap_acc1
    );
    hprintln!(
        "worst PWM period: {} with requests wherever they land, {} as the firmware serves them (period 8500 cycles; 40 % = 3400); longest position period without a request {:.0}",
        worst_any, worst_fw, position_max
    );
    if faults_seen {
        hprintln!("warning: a fault latched during the closed-loop run: the step figures are not of a running drive");
    }
    // A request the controller refused every time costs only its refusal:
    // the worst period would not be the request's.
    let mut refused = false;
    for ((_, name), _) in ops.iter().zip(accepted.iter()).filter(|(_, a)| a.contains(&0)) {
        hprintln!("error: every `{}` request was refused in one of the two runs: its worst period measures a refusal, not the request", name);
        refused = true;
    }
    // One JSON object for cost.sh, line by line behind a `JSON ` prefix.
    hprintln!("JSON {{");
    hprintln!("JSON   \"method\": \"qemu-system-arm -machine mps2-an386 -icount shift=7, SysTick (processor clock) read before and after each call, calibrated on a loop of known length\",");
    hprintln!("JSON   \"icount_ticks_per_insn\": {},", m.ticks_per_insn);
    hprintln!("JSON   \"closed_loop_faults\": {},", faults_seen);
    hprintln!("JSON   \"observer_in_step\": {},", OBSERVER_IN_STEP);
    hprintln!("JSON   \"worst_period\": {{");
    hprintln!("JSON     \"note\": \"longest PWM period (step + a bulk request served before it) over the golden closed loop, one request every 7th period; firmware = served only before a current-only period without a capture batch, as the PWM interrupt does\",");
    hprintln!("JSON     \"firmware\": {},", worst_fw);
    hprintln!("JSON     \"requests_in_any_period\": {},", worst_any);
    hprintln!("JSON     \"position_period_max_without_request\": {:.0},", position_max);
    hprintln!(
        "JSON     \"apply_params_capturing\": {{\"current_only\": [{}, {}, {}], \"firmware\": [{}, {}, {}], \"accepted\": [{}, {}]}},",
        cap_current_only[0], cap_current_only[1], cap_current_only[2], cap_firmware[0], cap_firmware[1], cap_firmware[2], cap_acc0, cap_acc1
    );
    for (i, (_, name)) in ops.iter().enumerate() {
        if let (Some(a), Some(f), Some(acc)) = (any_period.get(i), current_only.get(i), accepted.get(i)) {
            hprintln!(
                "JSON     \"{}\": {{\"any_period\": [{}, {}, {}], \"current_only\": [{}, {}, {}], \"accepted\": [{}, {}]}}{}",
                name, a[0], a[1], a[2], f[0], f[1], f[2], acc[0], acc[1],
                if i + 1 < ops.len() { "," } else { "" }
            );
        }
    }
    hprintln!("JSON   }},");
    hprintln!("JSON   \"per_period\": {{");
    hprintln!("JSON     \"current\": {:.1},", mean(&cur));
    hprintln!("JSON     \"speed\": {:.1},", mean(&spd));
    hprintln!("JSON     \"current_capturing\": {:.1},", mean(&cap_cur));
    // Where a capture encodes its staged frames (src/capture/mod.rs).
    hprintln!("JSON     \"speed_capturing\": {:.1},", mean(&cap_spd));
    hprintln!("JSON     \"position_capturing\": {:.1},", mean(&cap_pos));
    hprintln!("JSON     \"position\": {:.1},", mean(&pos));
    hprintln!(
        "JSON     \"position_with_observer\": {:.1},",
        position_with_observer
    );
    hprintln!("JSON     \"speed_loop_alone\": {:.1},", speed_increment);
    hprintln!(
        "JSON     \"position_loop_alone\": {:.1},",
        position_increment
    );
    hprintln!(
        "JSON     \"position_loop_alone_with_observer\": {:.1},",
        position_increment_with_observer
    );
    hprintln!("JSON     \"position_five_input\": {:.1},", mean(&five_pos));
    hprintln!("JSON     \"position_max_five_input\": {:.0},", five_pos.insns(&m).2);
    hprintln!("JSON     \"position_capturing_max\": {:.0},", cap_pos.insns(&m).2);
    hprintln!("JSON     \"speed_capturing_max\": {:.0},", cap_spd.insns(&m).2);
    hprintln!(
        "JSON     \"position_loop_alone_five_input\": {:.1}",
        position_increment_five
    );
    hprintln!("JSON   }},");
    hprintln!("JSON   \"insns\": {{");
    let n = rows.iter().flatten().count();
    for (i, r) in rows.iter().flatten().enumerate() {
        hprintln!(
            "JSON     \"{}\": {{\"mean\": {:.1}, \"min\": {:.0}, \"max\": {:.0}, \"calls\": {}}}{}",
            r.key,
            r.mean,
            r.min,
            r.max,
            r.calls,
            if i + 1 < n { "," } else { "" }
        );
    }
    hprintln!("JSON   }}");
    hprintln!("JSON }}");
    firmware_tests::exit(!faults_seen && !refused)
}
