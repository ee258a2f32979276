//! Link setup for the firmware image, and nothing else.
//!
//! The build script of the firmware package (firmware/Cargo.toml); the
//! control core's library (`servo_core`, the root package) has none, since
//! the host simulator and the QEMU test runner link it with their own
//! scripts. Its link arguments go to binaries only (`rustc-link-arg-bins`).

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../memory.x");

    // The commit the image is built from, for the protocol's `Info`.
    let git_hash = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=GIT_HASH={git_hash}");

    // A build for a hosted target (e.g. `cargo check --target
    // x86_64-…`) has no use for the Cortex-M linker scripts.
    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }

    // Put memory.x where the linker finds it (cortex-m-rt's link.x includes it).
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let memory = fs::read("../memory.x").expect("memory.x at the repository root");
    fs::write(out.join("memory.x"), memory).expect("write memory.x to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());

    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
