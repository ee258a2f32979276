#!/usr/bin/env bash
# Where the instructions of Controller::step go (a developer tool; the
# figures themselves come from cost.sh).
#
#   bash firmware-tests/profile.sh            # release profile, like the firmware
#
# Runs examples/profile.rs (a replay of golden/data/closed_loop.bin that
# marks periods 2000..2400, in the middle of the recorded move) in QEMU with
# one instruction per translation block and the execution log on, counts
# how often each instruction address ran inside the marked window, and
# attributes the counts to functions — the innermost inlined function when
# llvm-symbolizer (or llvm-addr2line) is installed, else the symbol QEMU
# names. The log is streamed through a pipe, never written to disk.
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$HERE"
cargo build --release --example profile
ELF="$HERE/target/thumbv7em-none-eabihf/release/examples/profile"
TMP="$(mktemp -d "${TMPDIR:-/tmp}/profile.XXXXXX")"
trap 'rm -rf "$TMP"' EXIT
mkfifo "$TMP/log"
awk '/ profile_window_start$/ { on = 1 } / profile_window_end$/ { on = 0 }
     on { split($4, f, "/"); n[f[2]]++ }
     END { for (pc in n) print pc, n[pc] }' "$TMP/log" > "$TMP/counts" &
qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
    -semihosting-config enable=on,target=native -singlestep -d exec,nochain -D "$TMP/log" \
    -kernel "$ELF" </dev/null
wait
total=$(awk '{ t += $2 } END { print t }' "$TMP/counts")
periods=400
echo "instructions in the window: $total over $periods periods = $((total / periods)) per period (replay glue included)"
SYM="$(command -v llvm-symbolizer || command -v llvm-symbolizer-14 || true)"
if [[ -n "$SYM" ]]; then
    # One query per address: the frames of the inlining chain, innermost
    # first, as (function, file:line) line pairs; a blank line ends each.
    # Attribution: code of a library routine (libm, compiler_builtins' soft
    # f64, fmaxf/fminf) goes to that routine; code of the control core, inlined
    # or not, goes to the innermost servo_core (or golden/profile) function.
    awk '{ print "0x" $1 }' "$TMP/counts" | "$SYM" --obj="$ELF" --inlining --demangle \
        | awk 'BEGIN { RS = ""; FS = "\n" }
            {
                container = $(NF - 1); own = ""; loc = $2
                for (i = 1; i < NF; i += 2) if (own == "" && $i ~ /^(servo_core|golden|profile)::/) { own = $i; loc = $(i + 1) }
                bucket = (container ~ /^(servo_core|golden|profile)::/ && own != "") ? own : container
                sub(/::h[0-9a-f]+$/, "", bucket)
                if (bucket ~ /^compiler_builtins::float/ || bucket ~ /^__aeabi_[dfi]/) bucket = "soft-float f64: " bucket
                sub(/:[0-9]+(:[0-9]+)?$/, "", loc); sub(/^.*\/(src|library)\//, "", loc)
                print bucket "\t" loc
            }' > "$TMP/frames"
    paste "$TMP/counts" "$TMP/frames" > "$TMP/joined"
    echo
    echo "instructions per period, by function (library routines whole, core code by innermost core function):"
    awk -F'\t' -v p=$periods '{ split($1, a, " "); n[$2] += a[2] } END { for (f in n) printf "%9.1f  %s\n", n[f] / p, f }' \
        "$TMP/joined" | sort -rn | head -40
    echo
    echo "instructions per period, by source file:"
    awk -F'\t' -v p=$periods '{ split($1, a, " "); n[$3] += a[2] } END { for (l in n) printf "%9.1f  %s\n", n[l] / p, l }' \
        "$TMP/joined" | sort -rn | head -25
else
    echo "(install llvm-symbolizer for inlined attribution; showing QEMU's symbol names)"
fi
