//! Where the instructions of `Controller::step` go: replays the recorded
//! closed-loop sequence (golden/data/closed_loop.bin) and marks periods
//! `FROM..TO` so `firmware-tests/profile.sh` can count, from QEMU's
//! one-instruction-per-block execution log, how many instructions each
//! function executed inside the marked window.
#![no_std]
#![no_main]

use core::hint::black_box;

use golden::{ClosedLoop, Family, Table};

const CLOSED_LOOP: &[u8] = include_bytes!("../golden/data/closed_loop.bin");
/// Periods 2000..2400: the move is under way (speed, position loops busy).
const FROM: usize = 2000;
const TO: usize = 2400;

// Window start and end: two tiny functions in assembly, so LTO can neither
// inline nor fold them; QEMU's execution log names them when they run.
core::arch::global_asm!(
    ".section .text.profile_window,\"ax\",%progbits",
    ".globl profile_window_start",
    ".type profile_window_start,%function",
    ".thumb_func",
    "profile_window_start:",
    "nop",
    "bx lr",
    ".size profile_window_start, . - profile_window_start",
    ".globl profile_window_end",
    ".type profile_window_end,%function",
    ".thumb_func",
    "profile_window_end:",
    "nop",
    "nop",
    "bx lr",
    ".size profile_window_end, . - profile_window_end",
);

extern "C" {
    fn profile_window_start();
    fn profile_window_end();
}

fn window_start() {
    // SAFETY: `nop; bx lr`.
    unsafe { profile_window_start() }
}

fn window_end() {
    // SAFETY: `nop; nop; bx lr`.
    unsafe { profile_window_end() }
}

#[firmware_tests::entry]
fn main() -> ! {
    let Ok(t) = Table::parse(CLOSED_LOOP) else {
        firmware_tests::exit(false)
    };
    let mut fam = ClosedLoop::new();
    let mut input = [0u32; 5];
    let mut out = [0u32; 8];
    for row in 0..TO {
        for (c, x) in input.iter_mut().enumerate() {
            *x = t.input(row, c);
        }
        if row == FROM {
            window_start();
        }
        fam.eval(row, black_box(&input), &mut out);
        black_box(&out);
    }
    window_end();
    firmware_tests::exit(true)
}
