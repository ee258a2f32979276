//! Puts this crate's `memory.x` (QEMU mps2-an386) where cortex-m-rt's `link.x`
//! finds it, and links every binary and test with `link.x`.
//!
//! Link arguments come from here rather than from `rustflags` in
//! `.cargo/config.toml`: rustflags arrays from the root config would be
//! concatenated with ours, and a `RUSTFLAGS` variable would replace both.

use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(out.join("memory.x"), include_bytes!("memory.x")).expect("write memory.x to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    // Applies to the test binaries too (`rustc-link-arg` covers bins, tests,
    // examples and benches).
    println!("cargo:rustc-link-arg=-Tlink.x");
}
