//! Every exception the firmware does not serve ends in the safe state: TIM1's
//! main output off (all six switches off) and the brake's release signal
//! stopped (pin low, brake closed), then a wait for the watchdog.
//!
//! | vector | handler |
//! |---|---|
//! | HardFault (a panic too: panic-probe ends in `udf`) | [`HardFault`] → [`safe_state`] |
//! | NMI, MemManage, BusFault, UsageFault, SVCall, DebugMonitor, PendSV, SysTick | `DefaultHandler` → [`safe_state`] |
//! | every device interrupt but the seven the image serves | `DefaultHandler` → [`safe_state`] |
//! | `ADC1_2` (PWM), `TIM2` (time driver), `USART2`, `DMA1_CHANNEL1/2`, `FDCAN1_IT0/IT1` | their drivers |
//!
//! cortex-m-rt points every vector nobody defines at `DefaultHandler`, so
//! the one definition below covers NMI and every unbound interrupt.
//! MemManage, BusFault and UsageFault are enabled ([`enable_fault_exceptions`])
//! so that each reports as itself; they end the same way. `HardFault` takes
//! no trampoline and reads nothing from the stack; if even the one push on
//! the way to the two register stores faults (a stack pointer gone wild),
//! the core locks up, and a lockup reaches TIM1's break in hardware.
//!
//! `firmware-tests/vectors/check.sh` reads the built ELF's vector table and
//! fails if any entry other than the served ones points anywhere but these
//! two handlers, or if either of them does not call [`safe_state`].
//!
//! The hardware half: a core lockup, a flash double-ECC error, an SRAM
//! parity error and the supply monitor reach TIM1's break input directly
//! (`setup.rs`, SYSCFG_CFGR2), with no software in the path.

use cortex_m::peripheral::scb::Exception;
use cortex_m::peripheral::SCB;
use cortex_m_rt::exception;
use embassy_stm32::pac;

use super::brake;

/// Bridge off (MOE clear: TIM1 drives every output to its idle level, low,
/// as set up), brake release stopped (pin low), then nothing: the
/// independent watchdog, if started, resets the chip within its timeout,
/// and the firmware comes back with the bridge off, the brake closed and
/// the watchdog fault latched. Two register stores and a loop.
/// With a debugger attached, probe-rs halts here; the DBGMCU freeze has
/// disabled TIM1's outputs already.
#[inline(never)]
#[no_mangle]
pub extern "C" fn safe_state() -> ! {
    pac::TIM1.bdtr().modify(|w| w.set_moe(false));
    brake::force_closed();
    loop {
        cortex_m::asm::nop();
    }
}

/// Any fault that escalates, and any panic (panic-probe's `udf`).
#[exception(trampoline = false)]
unsafe fn HardFault() -> ! {
    safe_state()
}

/// NMI, the configurable faults, the system exceptions the image does not
/// use, and every device interrupt it does not serve.
#[exception]
unsafe fn DefaultHandler(_irqn: i16) -> ! {
    safe_state()
}

/// MemManage, BusFault and UsageFault on (reset leaves them off, so they
/// escalate to HardFault): a fault then runs `DefaultHandler` under its own
/// name in the debugger, with the same end.
pub fn enable_fault_exceptions(scb: &mut SCB) {
    scb.enable(Exception::MemoryManagement);
    scb.enable(Exception::BusFault);
    scb.enable(Exception::UsageFault);
}
