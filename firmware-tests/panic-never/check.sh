#!/usr/bin/env bash
# Link-time proof that the control path cannot panic (see src/main.rs).
#
#   bash firmware-tests/panic-never/check.sh
#
# Builds the panic-never binary with the firmware's release settings. Exit 0:
# it linked, so no panic is reachable from Controller::new/try_new/step/
# command/report_isr_overrun/telemetry and the getters, for any parameters
# and any sample. Exit 1: the link failed; the script relinks with the
# undefined symbol allowed and lists every function that still calls into
# core's panic machinery, with the call's source line where known.
# PANIC_NEVER_OVERFLOW=1 also links once with overflow checks on (report only).
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$HERE"
TARGET=thumbv7em-none-eabihf
HOST="$(rustc -vV | sed -n 's/^host: //p')"
BIN="$(rustc --print sysroot)/lib/rustlib/$HOST/bin"
LOG="$(mktemp "${TMPDIR:-/tmp}/panic-never.XXXXXX")"
trap 'rm -f "$LOG"' EXIT

callers() {
    # Each call into a panicking entry point from outside core/compiler_builtins,
    # and each branch into such a call (LLVM merges the panic calls of a
    # function into one), with the inlined frames at each site when
    # llvm-symbolizer is installed: the first frame in the control core is
    # the line to fix.
    local elf="$1" sym dis
    sym="$(command -v llvm-symbolizer || command -v llvm-symbolizer-14 || true)"
    dis="$(mktemp "${TMPDIR:-/tmp}/panic-never-dis.XXXXXX")"
    "$BIN/llvm-objdump" -d --no-show-raw-insn -C "$elf" >"$dis"
    awk '
        /^[0-9a-f]+ <.*>:$/ { fn = $0; sub(/^[0-9a-f]+ </, "", fn); sub(/>:$/, "", fn); next }
        /\tbl?\t/ && /<(core::panicking::|core::option::unwrap_failed|core::option::expect_failed|core::result::unwrap_failed|core::slice::index::|core::str::slice_error_fail|core::panic::|__panic_reachable)/ {
            t = $0; sub(/^.*</, "", t); sub(/>.*$/, "", t); sub(/::h[0-9a-f]+$/, "", t)
            f = fn; sub(/::h[0-9a-f]+$/, "", f)
            a = $1; sub(/:$/, "", a)
            if (f !~ /^(core::|compiler_builtins::|rust_begin_unwind|panic_never::panic)/) print a "\t" f "\t" t
        }' "$dis" | while IFS=$'\t' read -r addr fn target; do
            echo "  $fn calls $target (at 0x$addr)"
            [[ -n "$sym" ]] || continue
            { echo "$addr"; grep -E "	b[a-z.]*	0x0*$addr( |$)" "$dis" | awk '{ sub(/:$/, "", $1); print $1 }'; } \
                | while read -r site; do
                    "$sym" --obj="$elf" --inlining --demangle "0x$site" | paste - - | awk -F'\t' -v s="$site" '
                        NF == 2 && $1 != "" && !done {
                            f = $1; sub(/::h[0-9a-f]+$/, "", f); l = $2; sub(/^.*\/(src|library)\//, "", l)
                            chain = chain (chain == "" ? "" : "  <-  ") f " (" l ")"
                            if (f ~ /^servo_core::/) done = 1
                        }
                        END { if (chain != "") print "      0x" s ": " chain }'
                done | sort -u
        done
    rm -f "$dis"
}

echo ">>> cargo build --release (panic-never: firmware release profile, fat LTO)"
if cargo build --release 2>&1 | tee "$LOG"; then
    echo "panic-never: linked: no panic is reachable from the control path"
    status=0
else
    if ! grep -q "__panic_reachable_on_the_control_path" "$LOG"; then
        echo "panic-never: the build failed for another reason (see above)" >&2
        exit 1
    fi
    echo
    echo "panic-never: FAILED: a panic is reachable from the control path. Callers of the panic machinery:"
    CARGO_TARGET_DIR="$HERE/target/diagnose" RUSTFLAGS="-C link-arg=--unresolved-symbols=ignore-all" \
        cargo build --release -q 2>/dev/null
    callers "$HERE/target/diagnose/$TARGET/release/panic-never"
    status=1
fi

if [[ "${PANIC_NEVER_OVERFLOW:-0}" == 1 ]]; then
    echo
    echo ">>> with overflow checks on (information only)"
    if CARGO_TARGET_DIR="$HERE/target/overflow" CARGO_PROFILE_RELEASE_OVERFLOW_CHECKS=true cargo build --release -q 2>/dev/null; then
        echo "panic-never (overflow checks on): linked: no integer overflow is reachable either"
    else
        echo "panic-never (overflow checks on): an overflow check is reachable; callers:"
        CARGO_TARGET_DIR="$HERE/target/overflow-diagnose" CARGO_PROFILE_RELEASE_OVERFLOW_CHECKS=true \
            RUSTFLAGS="-C link-arg=--unresolved-symbols=ignore-all" cargo build --release -q 2>/dev/null
        callers "$HERE/target/overflow-diagnose/$TARGET/release/panic-never"
    fi
fi
exit $status
