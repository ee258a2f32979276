//! Interactive on-board test: encoder count direction without power. The
//! log asks you to turn the motor shaft a quarter turn or more in the
//! extending (positive) direction within 20 s; TIM4, set up by the
//! firmware's board module, must count by `encoder.direction` × that.
//!
//! Run: `cd firmware-tests/hardware && cargo test --release --test encoder_by_hand`.
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

#[allow(dead_code, unused_imports)]
#[path = "../../../src/board/mod.rs"]
mod board;

#[defmt_test::tests]
mod tests {
    use super::board::active as hw;
    use defmt::{assert, info, warn};
    use embassy_stm32::pac;
    use hardware_tests::{cycles, enable_cycle_counter};

    pub struct State {
        _board: hw::Board,
        cpu_hz: u32,
        counts_per_rev: u32,
        direction: i32,
    }

    #[init]
    fn init() -> State {
        let p = embassy_stm32::init(hw::clock_config());
        enable_cycle_counter();
        let params = *super::board::VALID_PARAMS.get();
        let b = match super::board::bring_up(p) {
            Ok(b) => b,
            Err(e) => defmt::panic!("board bring-up failed: {}", e),
        };
        let cpu_hz = b.cpu_hz();
        State {
            _board: b,
            cpu_hz,
            counts_per_rev: params.encoder.counts_per_rev,
            direction: params.encoder.direction,
        }
    }

    #[test]
    fn encoder_counts_up_when_turned_forward(s: &mut State) {
        let start = pac::TIM4.cnt().read().cnt();
        warn!("turn the motor shaft at least a quarter turn in the EXTENDING direction, within 20 s");
        let quarter = (s.counts_per_rev / 4) as i32;
        let t0 = cycles();
        let mut moved = 0i32;
        while cycles().wrapping_sub(t0) < 20 * s.cpu_hz {
            moved = pac::TIM4.cnt().read().cnt().wrapping_sub(start) as i16 as i32;
            if moved.abs() >= quarter {
                break;
            }
        }
        info!("TIM4 moved {=i32} counts (direction parameter {=i32})", moved, s.direction);
        assert!(moved.abs() >= quarter, "the shaft was not turned far enough (or the encoder is not counting)");
        assert!(moved.signum() == s.direction, "counts go the wrong way: flip control.encoder.direction");
    }
}
