//! Firmware faults: the control core's own timing.

use super::*;

pub fn isr_overrun(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "isr_overrun",
        what: "the board reports a missed PWM period while moving",
        setup: base(rig),
        injections: vec![at(FAULT_AT_S, Injection::IsrOverrun)],
        commands: moving(),
        duration_s: 0.7,
        fault_at_s: None,
        expect: expect(FaultSet::ISR_OVERRUN, Mode::Fault, 0),
    }
}

/// The ISR stops while moving: the timer keeps the last duties until the
/// 100 ms watchdog resets the chip.
pub fn core_hang(rig: &RigConfig) -> Scenario {
    Scenario {
        name: "core_hang",
        what: "the current-loop ISR hangs while moving (duties frozen until the watchdog resets)",
        setup: base(rig),
        injections: vec![at(FAULT_AT_S, Injection::CoreHang)],
        commands: moving(),
        duration_s: 0.8,
        fault_at_s: None,
        expect: expect(FaultSet::WATCHDOG_RESET, Mode::Fault, 2000),
    }
}
