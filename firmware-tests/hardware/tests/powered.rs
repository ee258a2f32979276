//! On-board tests with the power stage live: a motor with its encoder on
//! the B-G431B-ESC1 and a bus supply inside the parameter set's window
//! (`ControlParams::BENCH_24V`: 18–28 V). The motor turns: clamp it free.
//!
//! Runs the firmware's start-up sequence (current offsets, controller,
//! alignment, enable) with the board module that ships, then:
//! - encoder count direction: a +1 mm move (positive = extending) must move
//!   the TIM4 counter by +0.2 rev × counts/rev × `encoder.direction`, with
//!   no fault (a wrong direction runs away and trips the following error);
//! - current-loop ISR duration with the bridge switching, from the board's
//!   DWT counters, logged with defmt; it must fit in one PWM period with no
//!   overrun.
//!
//! Run: `cd firmware-tests/hardware && cargo test --release --test powered`.
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

#[allow(dead_code, unused_imports)]
#[path = "../../../src/board/mod.rs"]
mod board;

use board::link::{Reply, Request};
use board::ServoBoard;
use defmt::{assert, info};
use servo_core::{Command, Mode, Telemetry};

/// A command through the board's lock-free link, as `main` sends it.
fn send(b: &mut board::active::Board, cmd: Command) {
    let r = b.call(Request::Drive(cmd));
    info!("{} -> {}", cmd, r);
    assert!(matches!(r, Ok(Reply::Drive(Ok(_)))), "command refused");
}

/// The drive's newest telemetry (published by the interrupt every 1 ms).
fn telemetry(b: &mut board::active::Board) -> Option<Telemetry> {
    b.snapshot().drive().map(|(t, _)| t)
}

fn mode(b: &mut board::active::Board) -> Mode {
    telemetry(b).map_or(Mode::Fault, |t| t.mode)
}


#[defmt_test::tests]
mod tests {
    use super::board::{self, active as hw, Calibration, ServoBoard, ISR_STATS};
    use super::{mode, send, telemetry};
    use core::sync::atomic::Ordering;
    use defmt::{assert, info};
    use embassy_stm32::pac;
    use hardware_tests::{enable_cycle_counter, wait_cycles};
    use servo_core::{Command, Controller, Mode};

    pub struct State {
        board: hw::Board,
        params: servo_core::ControlParams,
        pwm_hz: f32,
        cpu_hz: u32,
    }

    #[init]
    fn init() -> State {
        let p = embassy_stm32::init(hw::clock_config());
        enable_cycle_counter();
        let params = *super::board::VALID_PARAMS.get();
        let mut b = match super::board::bring_up(p) {
            Ok(b) => b,
            Err(e) => defmt::panic!("board bring-up failed: {}", e),
        };
        let cpu_hz = b.cpu_hz();
        wait_cycles(cpu_hz / 100);
        let bus = b.status().bus_voltage_v;
        info!("bus {=f32} V", bus);
        assert!(
            bus > params.faults.bus_undervoltage_v && bus < params.faults.bus_overvoltage_v,
            "bus {=f32} V outside the parameter set's window: these tests need the power stage supplied",
            bus
        );
        assert!(b.begin_offset_calibration(2048).is_ok(), "the PWM interrupt did not take the calibration request");
        let t0 = hardware_tests::cycles();
        loop {
            match b.offset_calibration() {
                Calibration::Pending => {}
                Calibration::Done { offset_codes } => {
                    info!("current offsets {}", offset_codes);
                    break;
                }
                Calibration::Failed { offset_codes } => defmt::panic!("current offsets implausible: {}", offset_codes),
            }
            assert!(hardware_tests::cycles().wrapping_sub(t0) < cpu_hz, "offset calibration did not finish");
        }
        assert!(board::link::install_controller(Controller::new(params)).is_ok(), "controller installed twice");
        wait_cycles(cpu_hz / 100);
        send(&mut b, Command::Align);
        let t0 = hardware_tests::cycles();
        while mode(&mut b) == Mode::Aligning {
            assert!(hardware_tests::cycles().wrapping_sub(t0) < 2 * cpu_hz, "alignment did not finish");
        }
        assert!(mode(&mut b) == Mode::Disabled, "alignment ended in {}", mode(&mut b));
        send(&mut b, Command::Enable);
        wait_cycles(cpu_hz / 5);
        let pwm_hz = params.rates.pwm_frequency_hz;
        State { board: b, params, pwm_hz, cpu_hz }
    }

    /// A +1 mm move turns the counter by +0.2 rev × direction.
    #[test]
    fn encoder_count_direction(s: &mut State) {
        let start_raw = pac::TIM4.cnt().read().cnt();
        let start_m = telemetry(&mut s.board).map_or(0.0, |t| t.motor_position_m);
        send(&mut s.board, Command::MoveTo { position_m: start_m + 0.001 });
        wait_cycles(s.cpu_hz); // 1 s: the move takes ~0.1 s
        let faults = telemetry(&mut s.board).map_or(servo_core::FaultSet::INVALID_PARAMS, |t| t.faults);
        assert!(faults.is_empty(), "fault during the move (a reversed encoder trips the following error): {}", faults);
        let counts = pac::TIM4.cnt().read().cnt().wrapping_sub(start_raw) as i16 as i32;
        let expected = s.params.encoder.counts_per_rev as i32 / 5 * s.params.encoder.direction;
        info!("+1 mm: TIM4 moved {=i32} counts (expected {=i32})", counts, expected);
        assert!((counts - expected).abs() <= expected.abs() / 20 + 4);
    }

    /// The current-loop ISR with the bridge switching and the controller
    /// running: worst duration (DWT) logged; one period at most, no overrun.
    #[test]
    fn isr_cycles_running(s: &mut State) {
        ISR_STATS.worst_cycles.store(0, Ordering::Relaxed);
        let over0 = ISR_STATS.overruns.load(Ordering::Relaxed);
        wait_cycles(s.cpu_hz / 2);
        let worst = ISR_STATS.worst_cycles.load(Ordering::Relaxed);
        let period = (s.cpu_hz as f32 / s.pwm_hz) as u32;
        info!(
            "current-loop ISR (running): worst {=u32} cycles = {=f32} us of a {=f32} us period",
            worst,
            worst as f32 * 1e6 / s.cpu_hz as f32,
            1e6 / s.pwm_hz
        );
        assert!(ISR_STATS.overruns.load(Ordering::Relaxed) == over0, "ISR overrun");
        assert!(worst > 0 && worst < period);
    }

    #[teardown]
    fn teardown(s: &mut State) {
        let _ = s.board.call(board::link::Request::Drive(Command::Disable));
        info!("bridge off");
    }
}
