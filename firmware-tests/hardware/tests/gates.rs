//! Gate waveforms for the oscilloscope: the bridge switching at 50 % on all
//! three legs for 20 s, with the bus at a low voltage and no motor, so the
//! dead time can be measured at the MOSFET gates (docs/firmware-bringup.md,
//! *Measuring the gate waveforms*) before anyone lowers `DEAD_TIME_NS`.
//!
//! Refuses to switch unless the bus reads 8–16 V (a current-limited bench
//! supply; the gate drivers need it, the MOSFETs see nothing worse than a
//! 16 V half-bridge with no load) and every phase current reads zero (no
//! motor connected). Stops at once if a phase current appears.
//!
//! Then the hardware break path, without any current: with the legs
//! switching, DAC3's threshold is dropped to 0 V, so the comparators see the
//! shunt amplifiers' idle bias (≈ 0.13 V) as an overcurrent; the break must
//! clear MOE in hardware and set BIF, and all six gate signals must go low.
//!
//! Run: `cd firmware-tests/hardware && cargo test --release --test gates`.
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

#[allow(dead_code, unused_imports)]
#[path = "../../../src/board/mod.rs"]
mod board;

#[defmt_test::tests]
mod tests {
    use super::board::{active as hw, ServoBoard};
    use defmt::{assert, info};
    use embassy_stm32::interrupt::{self, InterruptExt};
    use embassy_stm32::pac;
    use hardware_tests::{cycles, enable_cycle_counter};

    /// The bus window the test switches in.
    const BUS_MIN_V: f32 = 8.0;
    const BUS_MAX_V: f32 = 16.0;
    /// How long the legs switch, for the scope.
    const SWITCH_S: u32 = 20;

    pub struct State {
        board: hw::Board,
        cpu_hz: u32,
    }

    #[init]
    fn init() -> State {
        let p = embassy_stm32::init(hw::clock_config());
        enable_cycle_counter();
        let board = match super::board::bring_up(p) {
            Ok(b) => b,
            Err(e) => defmt::panic!("board bring-up failed: {}", e),
        };
        let cpu_hz = board.cpu_hz();
        State { board, cpu_hz }
    }

    /// 50 % on all legs, MOE set, for `SWITCH_S` seconds; the ADC interrupt
    /// is masked meanwhile (it would clear MOE: no controller is installed)
    /// and this loop watches the amplifier outputs instead.
    #[test]
    fn gate_waveforms_at_low_bus(s: &mut State) {
        let bus = s.board.status().bus_voltage_v;
        assert!(
            (BUS_MIN_V..=BUS_MAX_V).contains(&bus),
            "bus {=f32} V: this test switches the bridge only at 8-16 V from a current-limited supply",
            bus
        );
        assert!(pac::TIM1.bdtr().read().dtg() != 0, "no dead time programmed");
        info!(
            "switching all legs at 50 % for {=u32} s, dead time {=u32} ns: probe the gates now (docs/firmware-bringup.md)",
            SWITCH_S,
            hw::DEAD_TIME_NS
        );
        interrupt::ADC1_2.disable();
        let t = pac::TIM1;
        let half = t.arr().read().arr() / 2;
        for ch in 0..3 {
            t.ccr(ch).write(|w| w.set_ccr(half));
        }
        t.bdtr().modify(|w| w.set_moe(true));
        let t0 = cycles();
        let mut seconds = 0u32;
        let mut loaded = false;
        while seconds < SWITCH_S {
            // Any phase current means a motor (or a fault) on the outputs:
            // the amplifier outputs leave their zero-current code.
            let codes = [pac::ADC1.jdr(0).read().jdata(), pac::ADC2.jdr(0).read().jdata(), pac::ADC1.jdr(1).read().jdata()];
            if codes.iter().any(|&c| (f32::from(c) - hw::cal::CURRENT_OFFSET_NOMINAL_CODE).abs() > 100.0) {
                loaded = true;
                break;
            }
            if cycles().wrapping_sub(t0) / s.cpu_hz > seconds {
                seconds += 1;
            }
        }
        t.bdtr().modify(|w| w.set_moe(false));
        interrupt::ADC1_2.unpend();
        // SAFETY: re-enables the board's own handler, as Board::new does.
        unsafe { interrupt::ADC1_2.enable() };
        assert!(!loaded, "a phase current appeared: disconnect the motor; bridge switched off");
        info!("done: bridge off");
    }

    /// The comparator → BKIN → MOE path, forced by lowering the threshold.
    #[test]
    fn hardware_break_clears_moe(s: &mut State) {
        let bus = s.board.status().bus_voltage_v;
        assert!(bus <= BUS_MAX_V, "bus {=f32} V: run this at <= 16 V", bus);
        assert!(s.board.status().hw_overcurrent_armed, "the comparator break is not armed (self-test failed)");
        interrupt::ADC1_2.disable();
        let t = pac::TIM1;
        t.sr().modify(|w| w.set_bif(0, false));
        let half = t.arr().read().arr() / 2;
        for ch in 0..3 {
            t.ccr(ch).write(|w| w.set_ccr(half));
        }
        t.bdtr().modify(|w| w.set_moe(true));
        let on = t.bdtr().read().moe();
        let dac = pac::DAC3;
        let code = dac.dhr12r(0).read().dhr();
        let t0 = cycles();
        dac.dhr12r(0).write(|w| w.set_dhr(0));
        dac.dhr12r(1).write(|w| w.set_dhr(0));
        while t.bdtr().read().moe() && cycles().wrapping_sub(t0) < s.cpu_hz / 1000 {}
        let took = cycles().wrapping_sub(t0);
        let moe_after = t.bdtr().read().moe();
        let bif = t.sr().read().bif(0);
        let mut gates_seen = 0u8;
        let t1 = cycles();
        while cycles().wrapping_sub(t1) < s.cpu_hz / 10_000 {
            gates_seen |= super::gates();
        }
        dac.dhr12r(0).write(|w| w.set_dhr(code));
        dac.dhr12r(1).write(|w| w.set_dhr(code));
        t.bdtr().modify(|w| w.set_moe(false));
        t.sr().modify(|w| w.set_bif(0, false));
        interrupt::ADC1_2.unpend();
        // SAFETY: re-enables the board's own handler, as Board::new does.
        unsafe { interrupt::ADC1_2.enable() };
        info!("break: MOE cleared {=u32} cycles after the threshold dropped; BIF {=bool}", took, bif);
        assert!(on, "MOE would not set");
        assert!(!moe_after, "the comparators did not clear MOE");
        assert!(bif, "BIF not set");
        assert!(gates_seen == 0, "gate signals high after the break: {=u8:#08b}", gates_seen);
    }
}

/// Gate signals (high U/V/W, low U/V/W) as bits 0..6 (the pin map of
/// docs/firmware.md, as `board.rs` reads them).
pub fn gates() -> u8 {
    let a = embassy_stm32::pac::GPIOA.idr().read().0;
    let b = embassy_stm32::pac::GPIOB.idr().read().0;
    let c = embassy_stm32::pac::GPIOC.idr().read().0;
    let bit = |port: u32, pin: u32| ((port >> pin) & 1) as u8;
    bit(a, 8) | bit(a, 9) << 1 | bit(a, 10) << 2 | bit(c, 13) << 3 | bit(a, 12) << 4 | bit(b, 15) << 5
}
