//! Instruction counting on QEMU's emulated Cortex-M4 with SysTick.
//!
//! Under `qemu-system-arm -icount shift=N` the virtual clock advances
//! exactly 2^N ns per guest instruction, and SysTick (clock source = the
//! processor clock, `SYST_CSR.CLKSOURCE = 1`, which QEMU's mps2-an386 feeds
//! from its 25 MHz system clock) counts down on that virtual clock. So the
//! SysTick difference across a piece of code is proportional to the number
//! of instructions it executed, with no noise: the same binary gives the
//! same figures on every machine and every run.
//!
//! [`Meter::calibrate`] measures the ticks per instruction with a loop of
//! known length instead of trusting the clock frequency and the shift, and
//! the cost of reading the counter twice in a row; [`Meter::insns`] turns a
//! tick difference into instructions. With `shift=7` (128 ns per
//! instruction) one instruction is 3.2 ticks, so a single measurement is
//! exact to the instruction. Without `-icount` the figures are meaningless
//! (QEMU then runs SysTick on the host's real time); the calibration notices
//! that and says so.

use core::arch::asm;

const SYST_CSR: *mut u32 = 0xE000_E010 as *mut u32;
const SYST_RVR: *mut u32 = 0xE000_E014 as *mut u32;
const SYST_CVR: *mut u32 = 0xE000_E018 as *mut u32;
/// SysTick is a 24-bit down-counter.
const MASK: u32 = 0x00FF_FFFF;

/// Reads the SysTick current value. Written as `asm!` without `nomem`, so
/// the compiler treats it as touching all memory and moves no load or store
/// across it: what lies between two reads is what ran between them.
#[inline(always)]
pub fn now() -> u32 {
    let v: u32;
    // SAFETY: a 32-bit load from the always-present SysTick CVR register.
    unsafe {
        asm!("ldr {v}, [{a}]", a = in(reg) SYST_CVR, v = lateout(reg) v, options(nostack, preserves_flags));
    }
    v
}

/// Ticks elapsed from `start` to `end` (down-counter, one wrap allowed).
#[inline(always)]
pub fn elapsed(start: u32, end: u32) -> u32 {
    start.wrapping_sub(end) & MASK
}

/// Runs exactly `2 n + 1` instructions (`mov`, then `n` × `subs; bne`)
/// between two counter reads; returns the ticks.
#[inline(never)]
fn known_loop(n: u32) -> u32 {
    let (t0, t1): (u32, u32);
    // SAFETY: register-only loop plus two SysTick reads.
    unsafe {
        asm!(
            "ldr {t0}, [{a}]",
            "mov {i}, {n}",
            "2:",
            "subs {i}, {i}, #1",
            "bne 2b",
            "ldr {t1}, [{a}]",
            a = in(reg) SYST_CVR,
            n = in(reg) n,
            i = out(reg) _,
            t0 = out(reg) t0,
            t1 = out(reg) t1,
            options(nostack),
        );
    }
    elapsed(t0, t1)
}

/// Two reads back to back: the counter cost of one `ldr` between them.
#[inline(never)]
fn back_to_back() -> u32 {
    let (t0, t1): (u32, u32);
    // SAFETY: two SysTick reads.
    unsafe {
        asm!(
            "ldr {t0}, [{a}]",
            "ldr {t1}, [{a}]",
            a = in(reg) SYST_CVR,
            t0 = out(reg) t0,
            t1 = out(reg) t1,
            options(nostack, preserves_flags),
        );
    }
    elapsed(t0, t1)
}

/// Converts SysTick differences into instruction counts.
#[derive(Clone, Copy, Debug)]
pub struct Meter {
    /// SysTick ticks per executed instruction.
    pub ticks_per_insn: f64,
    /// Ticks of two back-to-back reads (subtracted from every measurement).
    pub read_ticks: u32,
    /// The calibration loop gave the same ratio at two lengths: the clock
    /// is instruction-driven (`-icount`), not real time.
    pub deterministic: bool,
}

impl Meter {
    /// Starts SysTick (processor clock, full 24-bit range, no interrupt) and
    /// calibrates it against loops of known length.
    pub fn calibrate() -> Self {
        // SAFETY: SysTick belongs to this benchmark; nothing else uses it.
        unsafe {
            SYST_CSR.write_volatile(0);
            SYST_RVR.write_volatile(MASK);
            SYST_CVR.write_volatile(0);
            SYST_CSR.write_volatile(0b101); // ENABLE | CLKSOURCE = processor clock
        }
        // Warm up QEMU's translation of the code below.
        let _ = known_loop(10);
        let _ = back_to_back();
        let read_ticks = back_to_back();
        let n_long = 200_000u32;
        let n_short = 50_000u32;
        let long = known_loop(n_long).saturating_sub(read_ticks);
        let short = known_loop(n_short).saturating_sub(read_ticks);
        // The loop body adds 2 instructions per iteration plus the `mov`.
        let ticks_per_insn = long as f64 / (2 * n_long + 1) as f64;
        let short_ratio = short as f64 / (2 * n_short + 1) as f64;
        let deterministic =
            ticks_per_insn > 0.0 && ((short_ratio - ticks_per_insn) / ticks_per_insn).abs() < 1e-4;
        Self {
            ticks_per_insn,
            read_ticks,
            deterministic,
        }
    }

    /// Ticks of one measurement (`start = now()` … `end = now()`) less the
    /// cost of the reads themselves.
    #[inline(always)]
    pub fn ticks(&self, start: u32, end: u32) -> u32 {
        elapsed(start, end).saturating_sub(self.read_ticks)
    }

    /// Instructions for a number of ticks.
    pub fn insns(&self, ticks: u64) -> f64 {
        ticks as f64 / self.ticks_per_insn
    }

    /// Measures one call of `f` in instructions (rounded; `f` should be an
    /// `#[inline(never)]` function so what is counted is the call itself).
    #[inline(always)]
    pub fn measure<R>(&self, f: impl FnOnce() -> R) -> (R, u32) {
        let t0 = now();
        let r = f();
        let t1 = now();
        (r, self.ticks(t0, t1))
    }
}

/// Running statistics of one measured quantity, in ticks.
#[derive(Clone, Copy, Debug)]
pub struct Stats {
    pub count: u32,
    pub sum: u64,
    pub min: u32,
    pub max: u32,
}

impl Stats {
    pub const fn new() -> Self {
        Self {
            count: 0,
            sum: 0,
            min: u32::MAX,
            max: 0,
        }
    }

    pub fn add(&mut self, ticks: u32) {
        self.count += 1;
        self.sum += ticks as u64;
        self.min = self.min.min(ticks);
        self.max = self.max.max(ticks);
    }

    /// (mean, min, max) in instructions.
    pub fn insns(&self, m: &Meter) -> (f64, f64, f64) {
        if self.count == 0 {
            return (0.0, 0.0, 0.0);
        }
        (
            m.insns(self.sum) / self.count as f64,
            m.insns(self.min as u64),
            m.insns(self.max as u64),
        )
    }
}

impl Default for Stats {
    fn default() -> Self {
        Self::new()
    }
}
