//! How long does a thread-mode critical section delay the PWM interrupt?
//! Measured, in instructions, on QEMU's Cortex-M4 (mps2-an386) under
//! `-icount shift=7`, with the firmware's own critical section
//! (`src/masking.rs`, included by path: BASEPRI = 0x10).
//!
//! Two spare NVIC lines stand in for the firmware's interrupts: one at
//! priority 0 (the PWM interrupt, `ADC1_2` on the board) and one at
//! priority 1 (the highest level a critical section masks; the time driver
//! sits at 4). Each case pends an interrupt from thread mode, then runs a
//! section of known length ([`SECTION_LOOPS`] × 2 instructions), and the
//! handler stamps SysTick on entry. The delay is the number of instructions
//! from the pend to the handler, less the same figure with no critical
//! section at all (exception entry, the handler's prologue, QEMU's
//! translation-block boundary):
//!
//! - priority 0 inside `critical_section::with` (BASEPRI): must be 0;
//! - priority 1 inside it: must be held until the section ends (≈ the
//!   section's length) — the section does mask what it must;
//! - priority 0 inside `cortex_m::interrupt::free` (PRIMASK, what
//!   `critical-section-single-core` does): for contrast, ≈ the section.
//!
//! It also prices the interrupt's side of the lock-free link
//! (`src/mailbox.rs`, included by path): checking for a request, taking one,
//! publishing a snapshot-sized value (printed, not asserted).
//!
//! Run: `bash firmware-tests/masking/check.sh` (also scans the firmware image
//! for every instruction that can mask the PWM interrupt). Exit code 0 only
//! if the BASEPRI section delays priority 0 by nothing and holds priority 1.
#![no_std]
#![no_main]

#[allow(dead_code)]
#[path = "../../../src/masking.rs"]
mod masking;

#[allow(dead_code)]
#[path = "../../src/icount.rs"]
mod icount;

#[allow(dead_code)]
#[path = "../../../src/mailbox.rs"]
mod mailbox;

use core::arch::asm;
use core::panic::PanicInfo;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::{debug, hprintln};
use icount::Meter;

/// Spare external interrupt lines on mps2-an386 (no device drives them;
/// they fire only when pended by software).
const IRQ_PWM: u16 = 30;
const IRQ_LOW: u16 = 31;
/// NVIC priorities as stored (4 implemented bits on the STM32G4: level n is
/// n << 4). Level 0 = the PWM interrupt, level 1 = the highest masked level.
const PRIO_PWM: u8 = 0x00;
const PRIO_LOW: u8 = 0x10;
/// Length of the critical section: 2 instructions per loop.
const SECTION_LOOPS: u32 = 500;
/// A priority-0 delay of at most this many instructions counts as "none"
/// (QEMU takes a pended interrupt at the next translation-block boundary,
/// which can differ by an instruction or two between the cases).
const NONE_TOLERANCE_INSNS: f64 = 4.0;

/// SysTick value at the handler's entry.
static ENTRY: AtomicU32 = AtomicU32::new(0);

#[exception]
unsafe fn DefaultHandler(_irqn: i16) {
    ENTRY.store(icount::now(), Ordering::SeqCst);
}

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}

/// Register-only busy loop of exactly `2 n + 1` instructions.
#[inline(always)]
fn section_body(n: u32) {
    // SAFETY: register-only loop.
    unsafe {
        asm!("mov {i}, {n}", "2:", "subs {i}, {i}, #1", "bne 2b", n = in(reg) n, i = out(reg) _, options(nostack, nomem));
    }
}

fn nvic() -> &'static cortex_m::peripheral::nvic::RegisterBlock {
    // SAFETY: the NVIC is always present; this program is single-threaded
    // apart from the handler, which touches only ENTRY.
    unsafe { &*NVIC::PTR }
}

fn set_priority(irq: u16, prio: u8) {
    // SAFETY: byte write to the interrupt's priority register.
    unsafe { nvic().ipr[usize::from(irq)].write(prio) };
}

fn enable(irq: u16) {
    // SAFETY: set-enable bit for a line whose handler is DefaultHandler.
    unsafe { nvic().iser[usize::from(irq / 32)].write(1 << (irq % 32)) };
}

/// Pends `irq` and returns the SysTick value just before the pend.
#[inline(always)]
fn pend(irq: u16) -> u32 {
    let t = icount::now();
    // SAFETY: set-pending bit.
    unsafe { nvic().ispr[usize::from(irq / 32)].write(1 << (irq % 32)) };
    t
}

/// A payload the size of the firmware's `Snapshot` (telemetry + board
/// status, 160 bytes), to price the interrupt's side of the link.
#[derive(Clone, Copy)]
#[allow(dead_code)] // only ever copied: its size is the point
struct Payload([u32; 40]);

static REQUESTS: mailbox::Slot<[u32; 8]> = mailbox::Slot::new();
static SNAPSHOTS: mailbox::TripleBuffer<Payload> = mailbox::TripleBuffer::new(Payload([0; 40]));

#[inline(never)]
fn take_request(rx: &mut mailbox::SlotReceiver<'_, [u32; 8]>) -> Option<[u32; 8]> {
    rx.try_take()
}

#[inline(never)]
fn publish(w: &mut mailbox::TripleWriter<'_, Payload>, p: Payload) {
    w.publish(p)
}

/// What the interrupt pays per call for the lock-free link (instructions,
/// call and return included): no request waiting (every period), one
/// request waiting, one snapshot published (every 20 periods).
fn link_costs(m: &Meter) -> (u32, u32, u32) {
    let insns = |ticks: u32| m.insns(u64::from(ticks)) as u32;
    let (Some((mut tx, mut rx)), Some((mut w, _r))) = (REQUESTS.split(), SNAPSHOTS.split()) else {
        return (0, 0, 0);
    };
    let mut empty = 0;
    let mut full = 0;
    let mut snap = 0;
    for round in 0..3u32 {
        let (_, t) = m.measure(|| take_request(&mut rx));
        empty = insns(t);
        let _ = tx.try_put([round; 8]);
        let (_, t) = m.measure(|| take_request(&mut rx));
        full = insns(t);
        let (_, t) = m.measure(|| publish(&mut w, Payload([round; 40])));
        snap = insns(t);
    }
    (empty, full, snap)
}

/// Instructions from the pend to the handler's entry.
fn delay(m: &Meter, pend_at: u32) -> f64 {
    let entry = ENTRY.load(Ordering::SeqCst);
    m.insns(u64::from(m.ticks(pend_at, entry)))
}

#[entry]
fn main() -> ! {
    let m = Meter::calibrate();
    if !m.deterministic {
        hprintln!("error: SysTick is not instruction-driven: run under -icount");
        debug::exit(debug::EXIT_FAILURE);
    }
    // How many priority bits QEMU implements (the arithmetic needs ≥ 4).
    set_priority(IRQ_PWM, 0xFF);
    let implemented = nvic().ipr[usize::from(IRQ_PWM)].read();
    set_priority(IRQ_PWM, PRIO_PWM);
    set_priority(IRQ_LOW, PRIO_LOW);
    enable(IRQ_PWM);
    enable(IRQ_LOW);

    // Warm up QEMU's translation of every path once.
    for _ in 0..3 {
        let _ = pend(IRQ_PWM);
        critical_section::with(|_| {
            let _ = pend(IRQ_PWM);
            section_body(SECTION_LOOPS);
        });
        critical_section::with(|_| {
            let _ = pend(IRQ_LOW);
            section_body(SECTION_LOOPS);
        });
        cortex_m::interrupt::free(|_| {
            let _ = pend(IRQ_PWM);
            section_body(SECTION_LOOPS);
        });
    }

    let t = pend(IRQ_PWM);
    let baseline = delay(&m, t);

    let mut t = 0;
    critical_section::with(|_| {
        t = pend(IRQ_PWM);
        section_body(SECTION_LOOPS);
    });
    let basepri_pwm = delay(&m, t) - baseline;

    critical_section::with(|_| {
        t = pend(IRQ_LOW);
        section_body(SECTION_LOOPS);
    });
    let basepri_low = delay(&m, t) - baseline;

    cortex_m::interrupt::free(|_| {
        t = pend(IRQ_PWM);
        section_body(SECTION_LOOPS);
    });
    let primask_pwm = delay(&m, t) - baseline;

    let (empty, full, snap) = link_costs(&m);
    let section = f64::from(2 * SECTION_LOOPS + 1);
    hprintln!("priority bits implemented (IPR readback of 0xFF): {:#04x}", implemented);
    hprintln!("BASEPRI in a critical section: {:#04x}", masking::MASK_BASEPRI);
    hprintln!("critical section body: {:.0} instructions", section);
    hprintln!("pend -> handler with no critical section: {:.1} instructions (baseline, subtracted below)", baseline);
    hprintln!("priority 0 (PWM) pended inside critical_section::with (BASEPRI): delayed {:.1} instructions", basepri_pwm);
    hprintln!("priority 1 pended inside critical_section::with (BASEPRI): delayed {:.1} instructions (held to the end)", basepri_low);
    hprintln!("priority 0 pended inside interrupt::free (PRIMASK, for contrast): delayed {:.1} instructions", primask_pwm);

    hprintln!(
        "the interrupt's side of the link: no request {} instructions, a request taken {}, a 160-byte snapshot published {}",
        empty,
        full,
        snap
    );
    let ok = implemented & 0xF0 == 0xF0
        && basepri_pwm.abs() <= NONE_TOLERANCE_INSNS
        && basepri_low >= section - NONE_TOLERANCE_INSNS;
    hprintln!("{}", if ok { "masking: PASS" } else { "masking: FAIL" });
    debug::exit(if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    loop {}
}
