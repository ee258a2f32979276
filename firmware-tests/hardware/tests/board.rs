//! Bench-safe on-board tests: the B-G431B-ESC1 on USB (ST-LINK) power, no
//! bus supply needed, no motor needed. Brings the board up with the
//! firmware's own board module (`src/board/`), the bridge off, and checks:
//!
//! - TIM1: centre-aligned PWM at the parameter set's frequency, the dead
//!   time register, outputs off (MOE = 0, all six gate signals low);
//! - dead time on the pins: with the bus unpowered, the six gate signals
//!   are sampled while the timer switches them, and no high/low pair is
//!   ever high together; the shortest gap between one switch turning off
//!   and its partner turning on is at least `DEAD_TIME_NS`;
//! - the ADC trigger: one interrupt per PWM period, entered after the
//!   injected sequence ends and before the PWM peak, never late, no overrun;
//! - cycles: the bridge-off ISR (DWT, from the board's own counters) and
//!   `Controller::step` in closed loop with the golden vectors' rigid plant
//!   (the plant not counted), per period kind, logged with defmt.
//!
//! Run: `cd firmware-tests/hardware && cargo test --release --test board`.
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

#[allow(dead_code, unused_imports)]
#[path = "../../../src/board/mod.rs"]
mod board;

/// Gate signals (high U/V/W, low U/V/W) as bits 0..6.
pub fn gates() -> u8 {
    let a = embassy_stm32::pac::GPIOA.idr().read().0;
    let b = embassy_stm32::pac::GPIOB.idr().read().0;
    let c = embassy_stm32::pac::GPIOC.idr().read().0;
    let bit = |port: u32, pin: u32| ((port >> pin) & 1) as u8;
    bit(a, 8) | bit(a, 9) << 1 | bit(a, 10) << 2 | bit(c, 13) << 3 | bit(a, 12) << 4 | bit(b, 15) << 5
}


#[defmt_test::tests]
mod tests {
    use super::board::{active as hw, ServoBoard, ISR_STATS};
    use core::sync::atomic::Ordering;
    use defmt::{assert, info};
    use embassy_stm32::interrupt::{self, InterruptExt};
    use embassy_stm32::pac;
    use embassy_stm32::pac::timer::vals::Cms;
    use golden::plant::RigidPlant;
    use golden::{CLOSED_LOOP_PERIODS, CLOSED_LOOP_SCRIPT};
    use super::gates;
    use hardware_tests::{cycles, enable_cycle_counter, wait_cycles, CycleStats, UNPOWERED_BUS_V};

    pub struct State {
        board: hw::Board,
        pwm_hz: f32,
        cpu_hz: u32,
        tim_hz: u32,
    }

    #[init]
    fn init() -> State {
        let p = embassy_stm32::init(hw::clock_config());
        enable_cycle_counter();
        let params = *super::board::VALID_PARAMS.get();
        let board = match super::board::bring_up(p) {
            Ok(b) => b,
            Err(e) => defmt::panic!("board bring-up failed: {}", e),
        };
        let pwm_hz = params.rates.pwm_frequency_hz;
        let cpu_hz = board.cpu_hz();
        let tim_hz = board.pwm_timer_hz();
        info!("{} up: CPU {=u32} Hz, TIM1 {=u32} Hz, PWM {=f32} Hz", hw::NAME, cpu_hz, tim_hz, pwm_hz);
        State { board, pwm_hz, cpu_hz, tim_hz }
    }

    /// TIM1 runs centre-aligned at the parameter set's PWM frequency.
    #[test]
    fn pwm_timer_frequency_and_mode(s: &mut State) {
        let t = pac::TIM1;
        assert!(t.cr1().read().cen(), "TIM1 not running");
        assert!(t.cr1().read().cms() == Cms::CENTER_ALIGNED1);
        let arr = t.arr().read().arr() as f32;
        let pwm_hz = s.tim_hz as f32 / (2.0 * arr);
        info!("TIM1 ARR {=f32} -> PWM {=f32} Hz (asked {=f32})", arr, pwm_hz, s.pwm_hz);
        assert!(((pwm_hz - s.pwm_hz) / s.pwm_hz).abs() < 1e-3);
    }

    /// BDTR.DTG gives at least DEAD_TIME_NS, and not a step more.
    #[test]
    fn dead_time_register(s: &mut State) {
        let dtg = pac::TIM1.bdtr().read().dtg() as u32;
        // RM0440 (CKD = 1, t_DTS = 1 / f_TIM): four ranges of DTG[7:5].
        let (ticks, step) = match dtg >> 5 {
            0..=3 => (dtg & 0x7F, 1),
            4 | 5 => ((64 + (dtg & 0x3F)) * 2, 2),
            6 => ((32 + (dtg & 0x1F)) * 8, 8),
            _ => ((32 + (dtg & 0x1F)) * 16, 16),
        };
        let ns = ticks as f32 * 1e9 / s.tim_hz as f32;
        let step_ns = step as f32 * 1e9 / s.tim_hz as f32;
        info!("dead time: DTG {=u32:#x} = {=u32} ticks = {=f32} ns (asked {=u32} ns)", dtg, ticks, ns, hw::DEAD_TIME_NS);
        assert!(ns >= hw::DEAD_TIME_NS as f32 - 0.5);
        assert!(ns < hw::DEAD_TIME_NS as f32 + step_ns + 0.5);
    }

    /// With the bridge off (MOE = 0) all six gate signals stay low.
    #[test]
    fn outputs_off_until_enabled() {
        assert!(!pac::TIM1.bdtr().read().moe(), "MOE set with no controller installed");
        let t0 = cycles();
        let mut seen = 0u8;
        while cycles().wrapping_sub(t0) < 170_000 {
            seen |= gates();
        }
        assert!(seen == 0, "gate signals high with the bridge off: {=u8:#08b}", seen);
    }

    /// Dead time on the pins: sampled in a tight loop while the bridge
    /// switches at 50 % with the bus unpowered.
    #[test]
    fn dead_time_on_pins(s: &mut State) {
        let bus = s.board.status().bus_voltage_v;
        assert!(
            bus < UNPOWERED_BUS_V,
            "the bus is powered ({=f32} V): this test switches the bridge; run it on USB power only",
            bus
        );
        // Keep the ISR (which holds MOE clear with no controller) out of the way.
        interrupt::ADC1_2.disable();
        let t = pac::TIM1;
        let half = t.arr().read().arr() / 2;
        for ch in 0..3 {
            t.ccr(ch).write(|w| w.set_ccr(half));
        }
        t.bdtr().modify(|w| w.set_moe(true));
        // Sample for 2 ms: ~40 PWM periods, each sample stamped.
        let mut overlap = 0u8;
        let mut last = gates();
        let mut last_off_at = [0u32; 3];
        let mut last_off_valid = [false; 3];
        let mut min_gap = u32::MAX;
        let mut transitions = 0u32;
        let mut sample_cycles = CycleStats::new();
        let t0 = cycles();
        let mut prev_t = t0;
        while cycles().wrapping_sub(t0) < s.cpu_hz / 500 {
            let g = gates();
            let now = cycles();
            sample_cycles.add(now.wrapping_sub(prev_t));
            prev_t = now;
            for ph in 0..3 {
                let (hi, lo) = (1u8 << ph, 1u8 << (ph + 3));
                if g & hi != 0 && g & lo != 0 {
                    overlap |= hi;
                }
                let was = last & (hi | lo);
                let is = g & (hi | lo);
                if was != 0 && is == 0 {
                    last_off_at[ph] = now;
                    last_off_valid[ph] = true;
                }
                if was == 0 && is != 0 && last_off_valid[ph] {
                    min_gap = min_gap.min(now.wrapping_sub(last_off_at[ph]));
                    transitions += 1;
                }
            }
            last = g;
        }
        t.bdtr().modify(|w| w.set_moe(false));
        interrupt::ADC1_2.unpend();
        // SAFETY: re-enables the board's own handler, as Board::new does.
        unsafe { interrupt::ADC1_2.enable() };
        let ns_per_cycle = 1e9 / s.cpu_hz as f32;
        let resolution_ns = sample_cycles.max as f32 * ns_per_cycle;
        let gap_ns = min_gap as f32 * ns_per_cycle;
        info!(
            "dead time on the pins: shortest off->on gap {=f32} ns over {=u32} transitions (sampling every <= {=f32} ns), overlap mask {=u8:#05b}",
            gap_ns, transitions, resolution_ns, overlap
        );
        assert!(overlap == 0, "a high and a low side were on together (phases {=u8:#05b})", overlap);
        assert!(transitions >= 60, "too few transitions seen: {=u32}", transitions);
        assert!(gap_ns + resolution_ns >= hw::DEAD_TIME_NS as f32, "gap {=f32} ns shorter than the dead time", gap_ns);
    }

    /// One ADC interrupt per PWM period, entered after the injected sequence
    /// and before the PWM peak; no overrun, no late start.
    #[test]
    fn adc_trigger_timing(s: &mut State) {
        let n0 = ISR_STATS.periods.load(Ordering::Relaxed);
        let late0 = ISR_STATS.late.load(Ordering::Relaxed);
        let over0 = ISR_STATS.overruns.load(Ordering::Relaxed);
        // 100 ms
        wait_cycles(s.cpu_hz / 10);
        let n = ISR_STATS.periods.load(Ordering::Relaxed).wrapping_sub(n0);
        let expected = s.pwm_hz / 10.0;
        let latency = ISR_STATS.worst_latency_ticks.load(Ordering::Relaxed);
        let latency_us = latency as f32 * 1e6 / s.tim_hz as f32;
        // ADC1's injected sequence (98 ADC cycles at HCLK/4) ends ~2.3 us
        // after the valley; the interrupt cannot start before that, and must
        // start before the peak (half a period).
        let sequence_us = 98.0 * 4.0 * 1e6 / s.cpu_hz as f32;
        let half_period_us = 0.5e6 / s.pwm_hz;
        info!(
            "ADC interrupts: {=u32} in 100 ms (expect {=f32}); worst start {=f32} us after the valley (sequence {=f32} us, peak at {=f32} us)",
            n, expected, latency_us, sequence_us, half_period_us
        );
        assert!((n as f32 - expected).abs() <= 2.0);
        assert!(ISR_STATS.late.load(Ordering::Relaxed) == late0, "interrupt started after the PWM peak");
        assert!(ISR_STATS.overruns.load(Ordering::Relaxed) == over0, "ISR overrun");
        assert!(latency_us >= 0.9 * sequence_us && latency_us < half_period_us);
    }

    /// The interrupt's duration with the bridge off (DWT, the board's own
    /// figure), logged; it must fit in one PWM period.
    #[test]
    fn isr_cycles_bridge_off(s: &mut State) {
        let worst = ISR_STATS.worst_cycles.load(Ordering::Relaxed);
        let period = (s.cpu_hz as f32 / s.pwm_hz) as u32;
        info!("ISR (bridge off, no controller): worst {=u32} cycles of {=u32} per period", worst, period);
        assert!(worst > 0 && worst < period);
    }

    /// `Controller::step` on the chip (flash wait states, ART accelerator),
    /// in thread mode with the ADC interrupt masked: 0.25 s of the recorded
    /// closed-loop script (homing, enable, a 10 mm move, a setpoint shift)
    /// against the rigid PMSM plant of the golden vectors (not counted);
    /// cycles per period kind logged. Every step must fit in one PWM period.
    #[test]
    fn step_cycles_on_chip(s: &mut State) {
        let p = servo_core::ControlParams::DEFAULT;
        let (sd, pd) = (p.rates.speed_loop_divider as usize, p.rates.position_loop_divider as usize);
        interrupt::ADC1_2.disable();
        let mut c = servo_core::Controller::new(p);
        let mut plant = RigidPlant::new(p, 48.0);
        let mut out = servo_core::PwmCommand::OFF;
        let (mut cur, mut spd, mut pos) = (CycleStats::new(), CycleStats::new(), CycleStats::new());
        for k in 0..CLOSED_LOOP_PERIODS {
            for (_, cmd) in CLOSED_LOOP_SCRIPT.iter().filter(|(at, _)| *at == k) {
                let _ = c.command(*cmd);
            }
            plant.advance(&out);
            let sample = plant.sample();
            let running = c.mode() == servo_core::Mode::Running;
            let t0 = cycles();
            out = c.step(&sample);
            let dt = cycles().wrapping_sub(t0);
            let tick = k + 1;
            if !running {
            } else if tick % pd == 0 {
                pos.add(dt);
            } else if tick % sd == 0 {
                spd.add(dt);
            } else {
                cur.add(dt);
            }
        }
        interrupt::ADC1_2.unpend();
        // SAFETY: re-enables the board's own handler, as Board::new does.
        unsafe { interrupt::ADC1_2.enable() };
        let period = (s.cpu_hz as f32 / s.pwm_hz) as u32;
        info!("Controller::step cycles on the chip (period = {=u32} cycles):", period);
        info!("  current  mean {=u32} max {=u32} ({=u32} periods)", cur.mean(), cur.max, cur.count);
        info!("  speed    mean {=u32} max {=u32} ({=u32} periods)", spd.mean(), spd.max, spd.count);
        info!("  position mean {=u32} max {=u32} ({=u32} periods)", pos.mean(), pos.max, pos.count);
        assert!(c.faults().is_empty(), "fault in the closed-loop run: {}", c.faults());
        assert!(cur.count > 0 && pos.count > 0);
        assert!(pos.max < period && spd.max < period && cur.max < period);
    }
}
