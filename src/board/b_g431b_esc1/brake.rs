//! The holding brake's release signal: dynamic, so that only a running
//! current loop can hold the brake open.
//!
//! The brake is spring-applied: coil off = closed. The release signal is a
//! square wave, not a level: while the controller asks for release, the PWM
//! interrupt toggles the pin once per period (10 kHz at 20 kHz PWM); in every
//! other case the pin stays low. The external driver is AC-coupled (charge
//! pump or transformer into the coil switch's gate, with a pull-down on that
//! gate; see docs/firmware-brake.md), so it energises the coil only
//! while the edges keep coming. A static level — high or low, driven or
//! pulled — cannot hold the brake open. So every way the loop can stop closes
//! the brake within the driver's hold-up time (≈ 1 ms):
//!
//! | event | pin | brake |
//! |---|---|---|
//! | reset, power-up, flashing, watchdog reset | input, pulled high by the ESC1's 10 kΩ H3 pull-up | closed (static) |
//! | before the controller asks, or bridge off | output low | closed |
//! | debugger halt | frozen at its last level (core stopped, no toggling) | closed |
//! | interrupt stalled / too slow / not firing | static | closed |
//! | any fault or unserved exception, panic (panic-probe → `udf` → HardFault) | driven low by [`force_closed`] in `exceptions::safe_state` | closed |
//! | release asked, bridge on | 10 kHz square wave | open |
//!
//! # Pin choice: PB8 (ESC1 encoder connector, H3 / Z)
//!
//! No free ESC1 pin is low through reset (UM2516 and ST's answers on the
//! board): PB8 carries the connector's 10 kΩ pull-up to 3.3 V and is also
//! BOOT0; PA15 (the "PWM" input pad) is JTDI with its internal pull-up at
//! reset; PB3/PB4 are USART2 to the ST-LINK virtual COM port (PB4 = NJTRST,
//! pull-up at reset); PA11/PB9 go to the CAN transceiver. With a dynamic
//! release the reset level no longer matters, so PB8 stays: it sits on the
//! connector already wired for the encoder, and nothing else uses it (the
//! encoder's Z / Hall H3 must not be connected). Its BOOT0 role is inert as
//! long as the option bytes keep nSWBOOT0 = 0 (boot selected by nBOOT0, not
//! by the pin), as ST ships the board; [`boot_pin_ignored`] checks that at
//! start-up. Were nSWBOOT0 = 1, the pull-up would select the system
//! bootloader: the firmware would not run, and the brake would still be
//! closed (no edges).

use embassy_stm32::pac;

/// The brake pin's port, number and embassy token: one place for all three
/// (the interrupt and the HardFault handler write BSRR directly).
pub const PORT: pac::gpio::Gpio = pac::GPIOB;
pub const PIN: usize = 8;
pub type Pin = embassy_stm32::peripherals::PB8;

/// Drives the pin low and stops the release signal for good (until the
/// interrupt toggles it again). One store to BSRR: atomic, usable from any
/// context, including HardFault with a corrupted stack.
#[inline(always)]
pub fn force_closed() {
    PORT.bsrr().write(|w| w.set_br(PIN, true));
}

/// Configures the pin as a push-pull output, low (brake closed). Called
/// first thing in bring-up, so the pin is driven low rather than left to the
/// pull-up as early as possible (the AC-coupled driver ignores either level;
/// driving it low also keeps the encoder connector's line quiet).
pub fn configure_closed() {
    force_closed();
    PORT.otyper().modify(|w| w.set_ot(PIN, pac::gpio::vals::Ot::PUSH_PULL));
    PORT.ospeedr().modify(|w| w.set_ospeedr(PIN, pac::gpio::vals::Ospeedr::LOW_SPEED));
    PORT.pupdr().modify(|w| w.set_pupdr(PIN, pac::gpio::vals::Pupdr::FLOATING));
    PORT.moder().modify(|w| w.set_moder(PIN, pac::gpio::vals::Moder::OUTPUT));
}

/// The release signal, driven from the PWM interrupt once per period.
#[derive(Debug, Default)]
pub struct ReleaseSignal {
    high: bool,
}

impl ReleaseSignal {
    pub const fn new() -> Self {
        Self { high: false }
    }

    /// `release`: toggle the pin (one edge per period); otherwise hold it
    /// low. One BSRR store either way.
    #[inline(always)]
    pub fn drive(&mut self, release: bool) {
        self.high = release && !self.high;
        let high = self.high;
        PORT.bsrr().write(|w| if high { w.set_bs(PIN, true) } else { w.set_br(PIN, true) });
    }
}

/// The brake's state feedback: a contact that closes to ground while the
/// armature is pulled in (brake released), on PA15 (the ESC1's "PWM" input
/// pad, free when the drive takes its commands over USART2/CAN) with the
/// internal pull-up: high = brake applied (or the feedback wire broken),
/// low = released. docs/firmware-brake.md has the circuit.
/// False: no feedback fitted, the pin left alone.
pub const FEEDBACK_FITTED: bool = false;
pub const FEEDBACK_PORT: pac::gpio::Gpio = pac::GPIOA;
pub const FEEDBACK_PIN: usize = 15;

pub use super::brake_feedback::{FeedbackVerdict, FeedbackWatch};

/// Configures the feedback input (pull-up, input mode) if one is fitted.
pub fn configure_feedback() {
    if FEEDBACK_FITTED {
        FEEDBACK_PORT.pupdr().modify(|w| w.set_pupdr(FEEDBACK_PIN, pac::gpio::vals::Pupdr::PULL_UP));
        FEEDBACK_PORT.moder().modify(|w| w.set_moder(FEEDBACK_PIN, pac::gpio::vals::Moder::INPUT));
    }
}

/// Whether the feedback says the brake is released (contact closed, pin low).
#[inline(always)]
pub fn feedback_released() -> bool {
    FEEDBACK_PORT.idr().read().idr(FEEDBACK_PIN) == pac::gpio::vals::Idr::LOW
}

/// True if the option bytes make the chip ignore the BOOT0 pin (nSWBOOT0 =
/// 0) and boot from flash (nBOOT0 = 1), as the ESC1 ships: then the brake
/// driver's load on PB8 cannot change how the chip boots.
pub fn boot_pin_ignored() -> bool {
    let optr = pac::FLASH.optr().read();
    !optr.n_swboot0() && optr.n_boot0()
}
