//! ST B-G431B-ESC1 (STM32G431CBU6, L6387E gate drivers, STL180N6F7 MOSFETs,
//! three 3 mΩ low-side shunts amplified by the MCU's own OPAMP1/2/3).
//!
//! Hardware facts come from the board's user manual (UM2516) and ST's Motor
//! Control SDK configuration for this board (MC Workbench "B-G431B-ESC1"
//! power/control board): pin map, shunt network gain 9.14, VBUS divider
//! 0.0963, NTC 1.4 V at 25 °C and 19 mV/°C, comparator overcurrent trip.
//!
//! | function                 | pin / resource                                   |
//! |--------------------------|--------------------------------------------------|
//! | PWM U/V/W high side      | PA8 / PA9 / PA10 = TIM1_CH1/2/3 (AF6)            |
//! | PWM U/V/W low side       | PC13 (AF4) / PA12 (AF6) / PB15 (AF4) = CH1N/2N/3N|
//! | shunt U: + / − / amp out | PA1 OPAMP1_VINP0 / PA3 VINM0 / PA2 → ADC1_IN3    |
//! | shunt V: + / − / amp out | PA7 OPAMP2_VINP0 / PA5 VINM0 / PA6 → ADC2_IN3    |
//! | shunt W: + / − / amp out | PB0 OPAMP3_VINP0 / PB2 VINM0 / PB1 → ADC1_IN12   |
//! | bus voltage              | PA0 → ADC2_IN1 (ADC12_IN1)                       |
//! | power-stage NTC          | PB14 → ADC1_IN5                                  |
//! | encoder A / B (Hall H1/H2)| PB6 / PB7 = TIM4_CH1/CH2 (AF2), x4 quadrature   |
//! | LED / button             | PC6 / PC10 (active low)                          |
//! | holding-brake release    | PB8 (Hall H3 / encoder Z pad): 10 kHz square wave = release, anything else = brake closed (see `brake`) |
//! | overcurrent              | COMP1/2/4 (+: PA1/PA7/PB0, −: DAC3) → TIM1 BRK   |
//! | CAN transceiver          | PC11 CAN_SHDN (low = on), PC14 CAN_TERM (high = 120 Ω in) |
//! | brake feedback (optional) | PA15 ("PWM" pad), pull-up, low = released     |
//!
//! The ESC1 has no external break pin wired; its overcurrent protection is
//! internal: the comparators watch the shunt amplifier inputs against a DAC3
//! threshold and drive TIM1's break input, which clears MOE in hardware
//! within the break filter time (no software in the path).
//!
//! # Timing
//!
//! TIM1 counts up and down (centre-aligned mode 1) at 170 MHz, ARR = 4250 for
//! 20 kHz. Channels 1–3 use PWM mode 2: the high side conducts around the
//! counter *peak*, the low sides (and so the shunts) around the *valley*. The
//! repetition counter (RCR = 1, phase-locked at start-up) makes the update
//! event happen only at the valley; TRGO2 = update starts the ADC injected
//! sequences there, exactly in the middle of the low-side conduction, and
//! the same update loads the preloaded CCRs, so every PWM pulse is symmetric
//! and a duty computed from the sample at valley k acts from valley k+1.
//! (Why not CH4: the update event already sits where the shunts conduct, and
//! it is also the instant the preloaded duties change; one event, no second
//! compare to keep aligned.)
//!
//! ADC1 and ADC2 run on the synchronous clock HCLK/4 = 42.5 MHz (no trigger
//! jitter). ADC1: I_U (6.5 cycles), I_W (6.5), NTC (47.5); ADC2: I_V (6.5),
//! VBUS (47.5). I_U and I_V are sampled together at the valley, I_W 0.45 µs
//! later; ADC1 ends last, at ≈ 2.3 µs, and its end-of-injected-sequence
//! interrupt (`ADC1_2`, priority 0, the highest) runs the control step.
//!
//! # Layout (one job per file)
//!
//! | file | what it does | runs in |
//! |---|---|---|
//! | `mod.rs` | board facts: pins, ratings, timing constants, clocks, limits | — |
//! | [`cal`] | raw code → SI unit constants (shunts, dividers, NTC, trip level) | — |
//! | `setup.rs` | bring-up: GPIO, OPAMP, DAC3/COMP, TIM1, ADC injected, encoder | thread mode, once |
//! | `isr.rs` | the `ADC1_2` interrupt: requests, sample conversion, controller step, duties | PWM interrupt |
//! | [`brake`] | the brake pin, its dynamic (toggled) release signal, the feedback input, the boot-pin check | PWM interrupt, `safe_state` |
//! | [`brake_feedback`] | the feedback's verdict per period (HAL-free) | PWM interrupt |
//! | [`exceptions`] | every unserved exception → `safe_state` (bridge off, brake closed) | any exception |
//! | [`comms`] | USART2, FDCAN1 and the transceiver pins, the transmit queue, the parameter record in flash | thread mode |
//! | [`comms_sizes`] | the transports' rates and sizes, the transmit queue's rule (HAL-free) | thread mode |
//! | [`can_stream`] | the CAN setpoint stream's receiving side | thread mode |
//! | `handle.rs` | [`Board`]: what thread mode holds and asks through the link | thread mode |

use embassy_stm32::interrupt::Priority;
use embassy_stm32::time::Hertz;
use servo_core::params::{PowerStageRating, RatingLowered};
use servo_core::ControlParams;

pub mod brake;
pub mod brake_feedback;
pub mod cal;
pub mod can_stream;
pub mod comms;
pub mod exceptions;
mod handle;
mod isr;
mod setup;
pub mod comms_sizes;

pub use handle::Board;
pub use setup::set_interrupt_priorities;

/// Shown in the boot banner.
pub const NAME: &str = "B-G431B-ESC1 (STM32G431CB)";

/// The parameter set this board runs: the ESC1 takes at most a 6S (25.2 V)
/// pack, so the 24 V bench variant of the drive.
pub const PARAMS: ControlParams = ControlParams::BENCH_24V;

/// NVIC priority of the PWM interrupt (`ADC1_2`): the highest. Nothing else
/// may sit at this level: thread-mode critical sections mask by priority
/// (BASEPRI) and leave this level, and only this one, unmasked.
pub const PWM_IRQ_PRIORITY: Priority = Priority::P0;
/// NVIC priority of the DMA channel interrupts embassy enables at `init`
/// (unused here): below the PWM interrupt, inside what a critical section
/// masks. embassy's default would be 0, level with the PWM interrupt.
pub const DMA_IRQ_PRIORITY: Priority = Priority::P2;
/// NVIC priority of the transports' interrupts (USART2, FDCAN1_IT0/IT1):
/// below the PWM interrupt, masked by a thread-mode critical section.
pub const COMMS_IRQ_PRIORITY: Priority = Priority::P3;
/// NVIC priority of the embassy time driver (TIM2). Any level below the PWM
/// interrupt works; 4 leaves room for a future transport interrupt above it.
pub const TIME_DRIVER_PRIORITY: Priority = Priority::P4;


/// Dead time between one switch of a leg turning off and the other turning
/// on. The L6387E has interlocking but inserts no dead time, so TIM1 does.
///
/// 800 ns is the vendor's value: ST's Motor Control SDK ships 750–800 ns for
/// this board (MC Workbench, B-G431B-ESC1 power board) and other ESC1
/// firmware uses 800 ns. Data-sheet typicals alone give a shorter turn-off:
/// the L6387E's propagation delay (≈ 110 ns typical) plus discharging the
/// STL180N6F7's gate (≈ 120 nC through the driver's ≈ 0.65 A sink current
/// and the board's gate resistor, ≈ 200 ns) is ≈ 300 ns; the typicals do
/// not cover the spread over temperature, the gate resistors' tolerance, the
/// driver's maximum delay and the mismatch between its two channels, which
/// is what the vendor's margin pays for. The cost is small: 1.6 % of the
/// 50 µs period, ≈ 0.4 V of average voltage error at 24 V near current zero
/// crossings (the current loop's integrator takes it up).
///
/// Lower it only after measuring the gate waveforms of the board in hand
/// (docs/firmware-bringup.md, *Measuring the gate waveforms*), and never below
/// [`DEAD_TIME_FLOOR_NS`]: the build refuses that.
pub const DEAD_TIME_NS: u32 = 800;

/// The shortest dead time this firmware builds with: twice the ≈ 300 ns
/// turn-off estimated from data-sheet typicals (see [`DEAD_TIME_NS`]), the
/// usual factor between a typical and a worst case over temperature and
/// part spread. Below it, one slow gate on one board shoots a leg through
/// and destroys the bridge on the first enable; no measurement on a sample
/// board covers every board, so going lower means changing this floor in
/// review with the measured margin, not a setting.
pub const DEAD_TIME_FLOOR_NS: u32 = 600;

const _: () = assert!(
    DEAD_TIME_NS >= DEAD_TIME_FLOOR_NS,
    "DEAD_TIME_NS is below DEAD_TIME_FLOOR_NS (src/board/b_g431b_esc1/mod.rs): a shoot-through risk"
);

/// Above this duty (in the period that contains the sample), a phase's
/// low-side window around the valley is shorter than the ≈ 1 µs ringing
/// after switching, so its shunt reading is replaced by −(sum of the other
/// two). Cheap form of the MCSDK's per-sector choice of two shunts.
pub const RECONSTRUCT_ABOVE_DUTY: f32 = 0.90;

/// Largest high-side duty written to the timer. The L6387E high-side supply
/// is a bootstrap capacitor recharged while the low side conducts: keep at
/// least 1 µs of low-side time per period (2 % of 50 µs). The core's
/// modulation limit (0.95 of the linear range → duty ≤ 0.975) stays below it.
pub const MAX_DUTY: f32 = 0.98;

/// Clock tree: 8 MHz crystal, PLL ×85/2/2 → 170 MHz SYSCLK = HCLK = PCLK1/2,
/// range-1 boost (needed above 150 MHz).
pub fn clock_config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::{Hse, HseMode, Pll, PllMul, PllPreDiv, PllRDiv, PllSource, Sysclk};
    let mut config = embassy_stm32::Config::default();
    config.rcc.hse = Some(Hse { freq: Hertz(8_000_000), mode: HseMode::Oscillator });
    config.rcc.pll = Some(Pll {
        source: PllSource::HSE,
        prediv: PllPreDiv::DIV2,
        mul: PllMul::MUL85,
        divp: None,
        divq: None,
        divr: Some(PllRDiv::DIV2),
    });
    config.rcc.sys = Sysclk::PLL1_R;
    config.rcc.boost = true;
    // USART2's DMA channels (`comms`); embassy enables every DMA vector.
    config.bdma_interrupt_priority = DMA_IRQ_PRIORITY;
    // FDCAN1 from PCLK1 (170 MHz): exact 1 and 5 Mbit/s (`comms`).
    config.rcc.mux.fdcansel = embassy_stm32::rcc::mux::Fdcansel::PCLK1;
    config
}

/// The ESC1 switches a 120 Ω CAN bus terminator with PC14 (CAN_TERM), so
/// it can drive either value of `control.stream.can_termination`. A board
/// without the switch sets this false, and then refuses a set that asks
/// for termination.
pub const CAN_TERMINATION_SWITCHABLE: bool = true;

/// Whether this board can do the bus termination `params` asks for.
pub const fn can_drive_termination(params: &ControlParams) -> bool {
    !params.stream.can_termination || CAN_TERMINATION_SWITCHABLE
}

const _: () = assert!(
    can_drive_termination(&PARAMS),
    "control.stream.can_termination: this board cannot switch a CAN bus terminator"
);

/// Flash prefetch and the instruction and data caches on (reset leaves
/// them off; embassy's `init` sets only the wait states, 4 at 170 MHz):
/// without them every fetch of the PWM interrupt's code from flash waits
/// 4 cycles. The parameter store switches the data cache off around an
/// erase and resets it after (`comms`).
pub fn enable_flash_acceleration() {
    embassy_stm32::pac::FLASH.acr().modify(|w| {
        w.set_prften(true);
        w.set_icen(true);
        w.set_dcen(true);
    });
}

/// The ESC1's power stage: its bus rating, the current its MOSFETs and
/// shunts carry, and the comparator break's trip (`cal.rs`).
pub const RATING: PowerStageRating = PowerStageRating {
    bus_max_v: cal::BOARD_MAX_BUS_V,
    current_max_a: cal::BOARD_MAX_CURRENT_A,
    overcurrent_trip_max_a: cal::HW_OCP_TRIP_A,
};

/// What [`apply_board_limits`] lowered.
pub type BoardLimitsApplied = RatingLowered;

/// Lowers (never raises) the limits of `params` to what this power stage
/// survives, and says what it lowered. `const`, so the firmware's set is
/// lowered and then validated at compile time: a set made for a higher bus
/// than the board's may become invalid (undervoltage above overvoltage), and
/// the build then fails naming the field.
pub const fn apply_board_limits(params: ControlParams) -> (ControlParams, BoardLimitsApplied) {
    RATING.lower(params)
}

/// Why the board could not be brought up. The bridge stays off in every case.
#[derive(Clone, Copy, Debug, PartialEq, defmt::Format)]
pub enum BoardError {
    /// The PWM frequency gives an auto-reload outside 1000..=65535 or off by
    /// more than 0.1 %.
    PwmFrequency { requested_hz: f32 },
    /// The dead time does not fit TIM1's DTG encoding.
    DeadTime,
    /// An ADC did not finish calibration / become ready in time.
    AdcStartup { adc: u8 },
    /// The update event could not be locked to the counter valley.
    PwmPhaseLock,
    /// `Board::new` ran before in this reset: the interrupt's state and the
    /// link exist once.
    AlreadyUp,
}

// ADC channel numbers (RM0440 / device pin table), see the table above.
const ADC1_CH_I_U: u8 = 3; // PA2, OPAMP1 output
const ADC1_CH_I_W: u8 = 12; // PB1, OPAMP3 output
const ADC1_CH_NTC: u8 = 5; // PB14
const ADC2_CH_I_V: u8 = 3; // PA6, OPAMP2 output
const ADC2_CH_VBUS: u8 = 1; // PA0
/// JEXTSEL for TIM1_TRGO2 on ADC1/2 (RM0440, injected trigger table).
const JEXTSEL_TIM1_TRGO2: u8 = 8;

