//! Golden vectors of the control core: the same inputs through the host
//! build and the target build.
//!
//! This crate is compiled twice. On the host, `golden-gen` calls each
//! family's [`Family::generate`] and writes the inputs and the host's outputs
//! to `golden/data/<family>.bin`. On the target (QEMU mps2-an386),
//! `firmware-tests/tests/golden.rs` reads those files, runs the very same
//! [`Family::eval`] on the inputs and compares its outputs with the host's
//! column by column, under the tolerance each [`Column`] states.
//!
//! Families: one FOC current-loop step over a sweep of angles and currents
//! ([`Foc`]), S-curve trajectory samples ([`Trajectory`]), the closed-loop
//! duty sequence of a recorded sensor sequence ([`ClosedLoop`]), the
//! error observer's outputs ([`Observer`]), and the drive's five-slot
//! observer network with a five-input model compiled in and uploaded
//! ([`Observer5`]).
//!
//! Why the two builds can agree bit for bit: the core is `f32` arithmetic,
//! which both targets do in IEEE single precision with round-to-nearest
//! (x86-64 SSE, Cortex-M4F FPv4-SP); Rust never contracts `a*b + c` into an
//! FMA on its own; the transcendental functions come from the same pure-Rust
//! `libm` on both sides (`sqrtf` is a hardware instruction on x86-64 and a
//! software routine on the M4, but both are correctly rounded). Nothing
//! here takes a different code path per target, so a difference means the
//! compiler, a dependency or the core itself started to treat the two
//! targets differently — which is what these vectors are for.
#![no_std]

pub mod observer5;
pub mod plant;
pub mod table;

use core::f32::consts::PI;

use servo_core::foc::current_loop::RotorState;
use servo_core::foc::{wrap_pi, CurrentLoop, CurrentTiming, Dq, SinCos};
use servo_core::motion::ScurveMove;
use servo_core::observer;
use servo_core::{Command, ControlParams, Controller, PwmCommand, SensorSample};

pub use observer5::{Observer5, FIVE_INPUT_MODEL};
pub use table::{agrees, header, ulps, Column, Table, Tol};

use plant::{Noise, RigidPlant};

/// One family of golden vectors.
pub trait Family {
    /// Stored in the table header.
    const ID: u32;
    /// Name, and file name `<NAME>.bin` under `golden/data/`.
    const NAME: &'static str;
    const IN_WORDS: usize;
    /// The output columns with their tolerances.
    const COLUMNS: &'static [Column];
    /// Why the host and the target could differ (printed with the figures).
    const WHY: &'static str;

    fn new() -> Self;

    /// Outputs of row `row` (rows are evaluated in order, from `new()`).
    fn eval(&mut self, row: usize, input: &[u32], out: &mut [u32]);

    /// Every (input, output) row, in order, as the host records them.
    fn generate(emit: &mut dyn FnMut(&[u32], &[u32]));
}

fn f(x: u32) -> f32 {
    f32::from_bits(x)
}

fn w(x: f32) -> u32 {
    x.to_bits()
}

fn flag(b: bool) -> u32 {
    b as u32
}

/// Generates rows of a stateless family from its input list.
fn emit_rows<F: Family>(
    inputs: &mut dyn FnMut(&mut dyn FnMut(&[u32])),
    emit: &mut dyn FnMut(&[u32], &[u32]),
) {
    let mut fam = F::new();
    let mut out = [0u32; 32];
    let n = F::COLUMNS.len();
    let mut row = 0usize;
    inputs(&mut |input: &[u32]| {
        fam.eval(row, input, &mut out[..n]);
        emit(input, &out[..n]);
        row += 1;
    });
}

// ---------------------------------------------------------------------------

/// One d-q current-loop period (Clarke, Park, two PI with decoupling and
/// back-EMF feedforward, voltage circle, inverse Park at the advanced angle,
/// SVPWM), plus `sin`/`cos` and `wrap_pi` of an unwrapped angle.
///
/// Inputs: `i_a, i_b, i_c` (A), loop angle (rad, in [−π, π)), electrical
/// speed (rad/s), `i_d*, i_q*` (A), bus (V), raw angle (rad, up to ±1000).
/// The loop runs two periods on the same input from a reset state, so the
/// outputs include one period of integrator state.
#[derive(Debug)]
pub struct Foc {
    p: ControlParams,
}

impl Family for Foc {
    const ID: u32 = 1;
    const NAME: &'static str = "foc";
    const IN_WORDS: usize = 9;
    const COLUMNS: &'static [Column] = &[
        Column::f32("sin", Tol::Ulps(0)),
        Column::f32("cos", Tol::Ulps(0)),
        Column::f32("wrap_pi", Tol::Ulps(0)),
        Column::f32("i_d", Tol::Ulps(0)),
        Column::f32("i_q", Tol::Ulps(0)),
        Column::f32("u_d", Tol::Ulps(0)),
        Column::f32("u_q", Tol::Ulps(0)),
        Column::f32("duty_a", Tol::Ulps(0)),
        Column::f32("duty_b", Tol::Ulps(0)),
        Column::f32("duty_c", Tol::Ulps(0)),
        Column::exact("voltage_limited"),
    ];
    const WHY: &'static str =
        "same f32 operations and the core's own f32 sin/cos on both, correctly rounded sqrt (vsqrt / sqrtf): bit-identical";

    fn new() -> Self {
        Self {
            p: ControlParams::DEFAULT,
        }
    }

    fn eval(&mut self, _row: usize, i: &[u32], out: &mut [u32]) {
        let currents = [f(i[0]), f(i[1]), f(i[2])];
        let rotor = RotorState {
            electrical_angle_rad: f(i[3]),
            electrical_speed_rad_s: f(i[4]),
        };
        let reference = Dq {
            d: f(i[5]),
            q: f(i[6]),
        };
        let bus = f(i[7]);
        let raw = f(i[8]);
        let sc = SinCos::of(raw);
        let mut cl = CurrentLoop::new();
        cl.step(&self.p, CurrentTiming::of(&self.p), currents, reference, rotor, bus);
        let o = cl.step(&self.p, CurrentTiming::of(&self.p), currents, reference, rotor, bus);
        let words = [
            w(sc.sin),
            w(sc.cos),
            w(wrap_pi(raw)),
            w(o.current_dq.d),
            w(o.current_dq.q),
            w(o.voltage_dq.d),
            w(o.voltage_dq.q),
            w(o.duty[0]),
            w(o.duty[1]),
            w(o.duty[2]),
            flag(o.voltage_limited),
        ];
        out.copy_from_slice(&words);
    }

    fn generate(emit: &mut dyn FnMut(&[u32], &[u32])) {
        emit_rows::<Self>(
            &mut |row: &mut dyn FnMut(&[u32])| {
                // 64 loop angles over [−π, π), 5 current amplitudes, and the
                // current vector's phase, the references, the speed and the
                // bus cycled with co-prime periods so their combinations vary.
                let amplitudes = [0.0f32, 0.5, 3.0, 12.0, 36.0];
                let phases = [0.0f32, 0.5 * PI, 2.0, -2.5];
                let references = [
                    (0.0f32, 0.0f32),
                    (0.0, 10.0),
                    (-5.0, -30.0),
                    (2.0, 36.0),
                    (0.0, -12.0),
                ];
                let speeds = [0.0f32, 400.0, -1200.0, 1250.0, -60.0, 2500.0, 30.0];
                let buses = [48.0f32, 24.0, 60.0];
                let raw_extra = [1000.0f32, -1000.0, 100.0, -20.5, 7.0, 3.0 * PI, -0.0, 1e-5];
                let mut k = 0usize;
                for ai in 0..64u32 {
                    let angle = -PI + ai as f32 * (2.0 * PI / 64.0);
                    for &amp in amplitudes.iter() {
                        let phase = phases[k % phases.len()];
                        let (rd, rq) = references[k % references.len()];
                        let speed = speeds[k % speeds.len()];
                        let bus = buses[k % buses.len()];
                        // The raw angle: the loop angle plus whole turns, or
                        // one of the extreme values.
                        let raw = if k % 5 == 4 {
                            raw_extra[(k / 5) % raw_extra.len()]
                        } else {
                            angle + 2.0 * PI * ((k % 7) as f32 - 3.0)
                        };
                        let th = angle + phase;
                        let ia = amp * libm::cosf(th);
                        let ib = amp * libm::cosf(th - 2.0 * PI / 3.0);
                        let ic = amp * libm::cosf(th + 2.0 * PI / 3.0);
                        row(&[
                            w(ia),
                            w(ib),
                            w(ic),
                            w(angle),
                            w(speed),
                            w(rd),
                            w(rq),
                            w(bus),
                            w(raw),
                        ]);
                        k += 1;
                    }
                }
            },
            emit,
        );
    }
}

// ---------------------------------------------------------------------------

/// Samples of jerk-limited moves (both directions, cruising and not, tiny).
///
/// Inputs: start (m), end (m), time since the move started (s). Outputs:
/// position, velocity, acceleration, the move's duration and peak velocity.
#[derive(Debug)]
pub struct Trajectory {
    p: ControlParams,
}

impl Family for Trajectory {
    const ID: u32 = 2;
    const NAME: &'static str = "trajectory";
    const IN_WORDS: usize = 3;
    const COLUMNS: &'static [Column] = &[
        Column::f32("position_m", Tol::Ulps(0)),
        Column::f32("velocity_m_s", Tol::Ulps(0)),
        Column::f32("acceleration_m_s2", Tol::Ulps(0)),
        Column::f32("duration_s", Tol::Ulps(0)),
        Column::f32("peak_velocity_m_s", Tol::Ulps(0)),
    ];
    const WHY: &'static str =
        "same f32 operations and the same libm sqrtf/cbrtf on both: bit-identical";

    fn new() -> Self {
        Self {
            p: ControlParams::DEFAULT,
        }
    }

    fn eval(&mut self, _row: usize, i: &[u32], out: &mut [u32]) {
        let m = ScurveMove::plan(f(i[0]), f(i[1]), &self.p.trajectory);
        let s = m.sample(f(i[2]));
        let words = [
            w(s.position_m),
            w(s.velocity_m_s),
            w(s.acceleration_m_s2),
            w(m.duration_s()),
            w(m.peak_velocity_m_s()),
        ];
        out.copy_from_slice(&words);
    }

    fn generate(emit: &mut dyn FnMut(&[u32], &[u32])) {
        emit_rows::<Self>(
            &mut |row: &mut dyn FnMut(&[u32])| {
                let p = ControlParams::DEFAULT;
                let moves = [
                    (0.0f32, 0.01f32),
                    (0.1, 0.35),
                    (0.3, 0.05),
                    (0.2, 0.2001),
                    (0.0, 0.5),
                    (0.25, 0.2),
                    (0.45, 0.449),
                    (0.05, 0.05),
                ];
                for &(a, b) in moves.iter() {
                    let duration = ScurveMove::plan(a, b, &p.trajectory).duration_s();
                    for k in 0..80u32 {
                        // From 10 ms before the start to 10 ms after the end.
                        let t = -0.01 + (duration + 0.02) * k as f32 / 79.0;
                        row(&[w(a), w(b), w(t)]);
                    }
                }
            },
            emit,
        );
    }
}

// ---------------------------------------------------------------------------

/// Commands of the closed-loop sequence: (period, command), applied before
/// that period's `step`.
pub const CLOSED_LOOP_SCRIPT: &[(usize, Command)] = &[
    (1, Command::SetHome { position_m: 0.1 }),
    (1, Command::SetCompensation { enabled: true }),
    (1, Command::Enable),
    (10, Command::MoveTo { position_m: 0.11 }),
    (2500, Command::SetPositionShift { shift_m: 20e-6 }),
    (4900, Command::Disable),
];

/// Periods in the recorded sequence (0.25 s at 20 kHz).
pub const CLOSED_LOOP_PERIODS: usize = 5000;

/// The whole drive (`Controller::step`) replaying a sensor sequence recorded
/// in closed loop on the host (rigid PMSM plant, ADC-like noise): homing,
/// observer compensation on, enable, a 10 mm move, a setpoint shift,
/// disable. The position periods run the error observer.
///
/// Inputs per period: `i_a, i_b, i_c` (A), encoder counter, bus (V).
/// Outputs: the three duties, enable, latched faults, mode, and the tracked
/// speed and motor-side position.
#[derive(Debug)]
pub struct ClosedLoop {
    c: Controller,
}

impl ClosedLoop {
    fn sample(i: &[u32]) -> SensorSample {
        SensorSample {
            phase_current_a: [f(i[0]), f(i[1]), f(i[2])],
            encoder_count: i[3] as u16,
            bus_voltage_v: f(i[4]),
            terminal_position_m: None,
            load_cell_force_n: None,
            home_switch: None,
            power_stage_temperature_c: None,
        }
    }

    fn words(s: &SensorSample) -> [u32; 5] {
        let [a, b, c] = s.phase_current_a;
        [w(a), w(b), w(c), s.encoder_count as u32, w(s.bus_voltage_v)]
    }

    fn outputs(c: &Controller, o: &PwmCommand, out: &mut [u32]) {
        let words = [
            w(o.duty[0]),
            w(o.duty[1]),
            w(o.duty[2]),
            flag(o.enable),
            c.faults().bits() as u32,
            c.mode() as u32,
            w(c.speed_rad_s()),
            w(c.motor_position_m()),
        ];
        out.copy_from_slice(&words);
    }
}

impl Family for ClosedLoop {
    const ID: u32 = 3;
    const NAME: &'static str = "closed_loop";
    const IN_WORDS: usize = 5;
    const COLUMNS: &'static [Column] = &[
        Column::f32("duty_a", Tol::Ulps(0)),
        Column::f32("duty_b", Tol::Ulps(0)),
        Column::f32("duty_c", Tol::Ulps(0)),
        Column::exact("enable"),
        Column::exact("faults"),
        Column::exact("mode"),
        Column::f32("speed_rad_s", Tol::Ulps(0)),
        Column::f32("motor_position_m", Tol::Ulps(0)),
    ];
    const WHY: &'static str =
        "same f32 operations and the core's own f32 maths on both, replayed from the same samples: bit-identical";

    fn new() -> Self {
        // The rigid plant carries no load and has no brake: nothing to
        // preload, no brake to wait for.
        let mut p = ControlParams::DEFAULT.commissioned();
        p.startup.expected_load_force_n = 0.0;
        p.brake.fitted = false;
        Self { c: Controller::new(p) }
    }

    fn eval(&mut self, row: usize, i: &[u32], out: &mut [u32]) {
        for (_, cmd) in CLOSED_LOOP_SCRIPT.iter().filter(|(k, _)| *k == row) {
            let _ = self.c.command(*cmd);
        }
        let o = self.c.step(&Self::sample(i));
        Self::outputs(&self.c, &o, out);
    }

    fn generate(emit: &mut dyn FnMut(&[u32], &[u32])) {
        let p = ControlParams::DEFAULT;
        let mut plant = RigidPlant::new(p, 48.0);
        let mut noise = Noise::new(20_250_317);
        let mut fam = Self::new();
        let mut out = [0u32; 8];
        let mut cmd = PwmCommand::OFF;
        for k in 0..CLOSED_LOOP_PERIODS {
            plant.advance(&cmd);
            let mut s = plant.sample();
            // ≈ ±1 ADC code of current noise (29 mA), ±0.1 V on the bus.
            for i in s.phase_current_a.iter_mut() {
                *i += 0.03 * noise.next();
            }
            s.bus_voltage_v += 0.1 * noise.next();
            let input = Self::words(&s);
            fam.eval(k, &input, &mut out);
            cmd = PwmCommand {
                duty: [f(out[0]), f(out[1]), f(out[2])],
                enable: out[3] != 0,
                // The golden rigid plant has no brake: the output acts on nothing.
                brake_release: true,
            };
            emit(&input, &out);
        }
    }
}

// ---------------------------------------------------------------------------

/// The dynamic-error observer (the generated RBF model in
/// `src/observer/model.rs`) over a grid of its four inputs, inside and
/// outside the trained range, and with a NaN.
///
/// Inputs: motor speed (rad/s), nut speed (m/s), displacement (m), load (N).
/// Outputs: predicted value (m), clamped, valid.
#[derive(Debug)]
pub struct Observer;

impl Family for Observer {
    const ID: u32 = 4;
    const NAME: &'static str = "observer";
    const IN_WORDS: usize = observer::model::INPUTS;
    const COLUMNS: &'static [Column] = &[
        Column::f32("value_m", Tol::Ulps(0)),
        Column::exact("clamped"),
        Column::exact("valid"),
    ];
    const WHY: &'static str = "same f32 operations and the core's own f32 exp2 on both: bit-identical";

    fn new() -> Self {
        Self
    }

    fn eval(&mut self, _row: usize, i: &[u32], out: &mut [u32]) {
        let mut x = [0.0f32; observer::model::INPUTS];
        for (xi, &wi) in x.iter_mut().zip(i.iter()) {
            *xi = f(wi);
        }
        let pr = observer::evaluate(&observer::model::MODEL, x);
        out.copy_from_slice(&[w(pr.value_m), flag(pr.clamped), flag(pr.valid)]);
    }

    fn generate(emit: &mut dyn FnMut(&[u32], &[u32])) {
        emit_rows::<Self>(
            &mut |row: &mut dyn FnMut(&[u32])| {
                let m = &observer::model::MODEL;
                const N: usize = observer::model::INPUTS;
                // 6 points per input from 10 % below to 10 % above the
                // trained range: 6^N rows (1296 for 4 inputs).
                let levels = 6u32;
                let total = levels.pow(N as u32);
                for code in 0..total {
                    let mut x = [0u32; N];
                    let mut c = code;
                    for (j, xj) in x.iter_mut().enumerate() {
                        let level = (c % levels) as f32;
                        c /= levels;
                        let (lo, hi) = (m.input_min[j], m.input_max[j]);
                        let span = hi - lo;
                        *xj = w(lo - 0.1 * span + level * (1.2 * span / (levels - 1) as f32));
                    }
                    row(&x);
                }
                let mut nan = [0u32; N];
                for (j, xj) in nan.iter_mut().enumerate() {
                    *xj = w(if j == 0 {
                        f32::NAN
                    } else {
                        0.5 * (m.input_min[j] + m.input_max[j])
                    });
                }
                row(&nan);
            },
            emit,
        );
    }
}
