//! A tiny on-target test runner for the control core on a Cortex-M4F.
//!
//! Every file in `tests/` is one binary that QEMU (`mps2-an386`) runs through
//! the runner in `.cargo/config.toml`. It prints one line per test through
//! semihosting and ends QEMU with exit code 0 only if every test passed, so
//! `cargo test` fails on the first failing binary.
//!
//! A test is a plain `fn() -> Outcome`; [`check!`] and [`check_close!`]
//! report the first broken expectation (file, line, values) and fail the test.
//! A panic or a hard fault fails the whole binary with the test's name.
//!
//! ```ignore
//! #![no_std]
//! #![no_main]
//! use firmware_tests::{check, test_main, Outcome};
//! fn adds() -> Outcome { check!(1 + 1 == 2); Ok(()) }
//! test_main!(adds);
//! ```
#![no_std]

pub mod icount;

use core::fmt;
use core::panic::PanicInfo;
use core::ptr;
use core::sync::atomic::{AtomicBool, AtomicPtr, Ordering};

use cortex_m_rt::{exception, ExceptionFrame};
use cortex_m_semihosting::{debug, hprint, hprintln};

pub use cortex_m_rt::entry;

/// A test failed; the reason has already been printed.
#[derive(Debug)]
pub struct Failed;

/// What a test returns.
pub type Outcome = Result<(), Failed>;

/// One test: its name (as printed) and its function.
#[derive(Debug)]
pub struct Test {
    pub name: &'static str,
    pub run: fn() -> Outcome,
}

/// The test running now, for the panic and fault handlers.
static CURRENT: AtomicPtr<Test> = AtomicPtr::new(ptr::null_mut());
/// A "test NAME ... " line is open and waits for its verdict.
static LINE_OPEN: AtomicBool = AtomicBool::new(false);

fn close_line() {
    if LINE_OPEN.swap(false, Ordering::SeqCst) {
        hprintln!();
    }
}

fn current() -> Option<&'static Test> {
    let p = CURRENT.load(Ordering::SeqCst);
    // SAFETY: only `run` stores here, and only pointers into a `&'static [Test]`.
    if p.is_null() {
        None
    } else {
        Some(unsafe { &*p })
    }
}

/// Ends QEMU (semihosting `SYS_EXIT`) with success or failure.
pub fn exit(success: bool) -> ! {
    debug::exit(if success {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    // Only reached without a semihosting host (e.g. a board without a probe).
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Runs every test in order, prints `SUITE: N passed, M failed` and exits
/// QEMU: code 0 if all passed, 1 otherwise.
pub fn run(suite: &str, tests: &'static [Test]) -> ! {
    hprintln!("running {} tests ({})", tests.len(), suite);
    let (mut passed, mut failed) = (0u32, 0u32);
    for t in tests {
        CURRENT.store(t as *const Test as *mut Test, Ordering::SeqCst);
        hprint!("test {} ... ", t.name);
        LINE_OPEN.store(true, Ordering::SeqCst);
        let ok = (t.run)().is_ok();
        let verdict = if ok { "PASS" } else { "FAIL" };
        if LINE_OPEN.swap(false, Ordering::SeqCst) {
            hprintln!("{}", verdict);
        } else {
            hprintln!("test {} ... {}", t.name, verdict);
        }
        if ok {
            passed += 1
        } else {
            failed += 1
        }
    }
    CURRENT.store(ptr::null_mut(), Ordering::SeqCst);
    hprintln!("{}: {} passed, {} failed", suite, passed, failed);
    exit(failed == 0)
}

/// Prints why a check failed (used by the macros).
#[doc(hidden)]
pub fn report(file: &str, line: u32, what: &str, detail: fmt::Arguments) {
    close_line();
    hprintln!("    {}:{}: check failed: {}", file, line, what);
    hprintln!("        {}", detail);
}

/// Prints an information line (indented, under the running test).
pub fn note(what: fmt::Arguments) {
    close_line();
    hprintln!("    {}", what);
}

/// `check!(condition)` or `check!(condition, "format", args..)`: on false,
/// prints the location and message and returns `Err(Failed)` from the test.
#[macro_export]
macro_rules! check {
    ($cond:expr $(,)?) => {
        $crate::check!($cond, "(no detail)")
    };
    ($cond:expr, $($arg:tt)+) => {
        if !$cond {
            $crate::report(file!(), line!(), stringify!($cond), format_args!($($arg)+));
            return Err($crate::Failed);
        }
    };
}

/// `check_close!(actual, expected, tolerance, "context", args..)`: both finite
/// and `|actual − expected| <= tolerance`, else fail with all three values.
#[macro_export]
macro_rules! check_close {
    ($actual:expr, $expected:expr, $tol:expr $(,)?) => {
        $crate::check_close!($actual, $expected, $tol, "")
    };
    ($actual:expr, $expected:expr, $tol:expr, $($arg:tt)+) => {{
        let (a, e, t): (f32, f32, f32) = ($actual, $expected, $tol);
        if !(a.is_finite() && e.is_finite() && (a - e).abs() <= t) {
            $crate::report(
                file!(),
                line!(),
                concat!(stringify!($actual), " ≈ ", stringify!($expected)),
                format_args!(
                    "actual {:e}, expected {:e}, |diff| {:e} > tol {:e}; {}",
                    a, e, (a - e).abs(), t, format_args!($($arg)+)
                ),
            );
            return Err($crate::Failed);
        }
    }};
}

/// The entry point of a test binary: `test_main!(test_a, test_b, ...);` runs
/// the listed `fn() -> Outcome` in order under the binary's crate name.
#[macro_export]
macro_rules! test_main {
    ($($test:path),+ $(,)?) => {
        #[$crate::entry]
        fn main() -> ! {
            static TESTS: &[$crate::Test] = &[
                $($crate::Test { name: stringify!($test), run: $test }),+
            ];
            $crate::run(env!("CARGO_CRATE_NAME"), TESTS)
        }
    };
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    close_line();
    match current() {
        Some(t) => hprintln!("test {} ... FAIL (panic: {})", t.name, info),
        None => hprintln!("panic outside any test: {}", info),
    }
    exit(false)
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    close_line();
    // SAFETY: a read of the fault status registers, nothing else is running.
    let (cfsr, hfsr) = unsafe {
        let scb = &*cortex_m::peripheral::SCB::PTR;
        (scb.cfsr.read(), scb.hfsr.read())
    };
    let name = current().map_or("(none)", |t| t.name);
    hprintln!(
        "test {} ... FAIL (HardFault: pc={:#010x} lr={:#010x} cfsr={:#010x} hfsr={:#010x})",
        name,
        frame.pc(),
        frame.lr(),
        cfsr,
        hfsr
    );
    exit(false)
}

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    close_line();
    let name = current().map_or("(none)", |t| t.name);
    hprintln!(
        "test {} ... FAIL (unexpected exception/interrupt {})",
        name,
        irqn
    );
    exit(false)
}
