//! Helpers for the on-board tests (B-G431B-ESC1, STM32G431CB at 170 MHz).
//!
//! The tests themselves (`tests/*.rs`) include the firmware's board module
//! (`src/board/`) by path and drive it like `main` does; these helpers are
//! what they share: the DWT cycle counter, bring-up, and the safety checks
//! that keep a powered bridge off unless a test is meant to drive a motor.
#![no_std]

use cortex_m::peripheral::DWT;

/// Starts the DWT cycle counter (the board's ISR figures read it too).
pub fn enable_cycle_counter() {
    // SAFETY: called once from `init`, before anything else uses DCB/DWT;
    // enabling trace and the counter has no other effect.
    let mut cp = unsafe { cortex_m::Peripherals::steal() };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
}

/// Core clock cycles since the counter started (wraps every 25 s at 170 MHz).
pub fn cycles() -> u32 {
    DWT::cycle_count()
}

/// Busy-waits `n` core cycles.
pub fn wait_cycles(n: u32) {
    let t0 = cycles();
    while cycles().wrapping_sub(t0) < n {}
}

/// Running statistics in cycles.
#[derive(Clone, Copy, Debug, defmt::Format)]
pub struct CycleStats {
    pub count: u32,
    pub sum: u64,
    pub min: u32,
    pub max: u32,
}

impl CycleStats {
    pub const fn new() -> Self {
        Self {
            count: 0,
            sum: 0,
            min: u32::MAX,
            max: 0,
        }
    }

    pub fn add(&mut self, c: u32) {
        self.count += 1;
        self.sum += c as u64;
        self.min = self.min.min(c);
        self.max = self.max.max(c);
    }

    pub fn mean(&self) -> u32 {
        if self.count == 0 {
            0
        } else {
            (self.sum / self.count as u64) as u32
        }
    }
}

impl Default for CycleStats {
    fn default() -> Self {
        Self::new()
    }
}

/// Bus voltage below which the bridge may be switched for a pin-level test
/// without any current flowing: the gate drivers and the power stage are
/// unsupplied (the board runs from the ST-LINK's USB).
pub const UNPOWERED_BUS_V: f32 = 2.0;
