#!/usr/bin/env bash
# Worst-case masking of the PWM interrupt by thread mode, in two parts:
#
#   bash firmware-tests/masking/check.sh
#
# 1. Measured: firmware-tests/masking (QEMU mps2-an386, -icount shift=7)
#    pends a priority-0 and a priority-1 interrupt inside the firmware's own
#    critical section (src/masking.rs, BASEPRI) and counts the instructions
#    until each handler runs (PRIMASK shown for contrast).
# 2. Scanned: the firmware image (`cargo build --release` at the root) is
#    disassembled and every instruction that can mask interrupts is listed:
#    `cpsid`, `msr primask`/`faultmask` (mask everything, the PWM interrupt
#    included) and `msr basepri_max` (with the value written, which must be
#    0x10: levels 1..15, never level 0).
# 3. Scanned: the call graph from the `ADC1_2` handler reaches no critical
#    section and no defmt function.
# Exit code 0 only if the measured delay at priority 0 is nil, priority 1 is
# held, no PRIMASK/FAULTMASK write exists outside the panic handler (on its
# way to HardFault), every BASEPRI_MAX write is 0x10 and the interrupt
# reaches neither a critical section nor the logger.
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
HOST="$(rustc -vV | sed -n 's/^host: //p')"
BIN="$(rustc --print sysroot)/lib/rustlib/$HOST/bin"
if [[ ! -x "$BIN/llvm-objdump" ]]; then
    echo "error: $BIN/llvm-objdump not found: add the llvm-tools component" >&2
    exit 1
fi
status=0

echo ">>> 1. measured in QEMU (firmware-tests/masking)"
(cd "$HERE" && cargo build --release)
if ! timeout 300 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
        -semihosting-config enable=on,target=native -icount shift=7 \
        -kernel "$HERE/target/thumbv7em-none-eabihf/release/masking" </dev/null; then
    status=1
fi

echo ">>> 2. scanned: the firmware image"
(cd "$ROOT" && cargo build --release)
ELF="$ROOT/target/thumbv7em-none-eabihf/release/cylinder-servo"
"$BIN/llvm-objdump" -d --no-show-raw-insn -C "$ELF" | awk '
    /^[0-9a-f]+ <.*>:$/ { fn = $0; sub(/^[0-9a-f]+ </, "", fn); sub(/>:$/, "", fn); delete imm; next }
    # Remember the last immediate moved into each register in this function.
    $2 ~ /^mov/ && $3 ~ /^r[0-9]+,$/ && $4 ~ /^#/ { r = $3; sub(/,$/, "", r); imm[r] = $4 }
    $2 == "cpsid" || ($2 == "msr" && ($3 ~ /^primask/ || $3 ~ /^faultmask/)) {
        if (fn ~ /rust_begin_unwind/) { panic_only++ } else { global++; print "  masks ALL interrupts: " $2 " " $3 " in " fn }
    }
    $2 == "msr" && $3 ~ /^basepri_max/ {
        r = $4; v = (r in imm) ? imm[r] : "?"; raised++
        if (v != "#0x10") { bad++; print "  BASEPRI_MAX <- " v " (not 0x10) in " fn }
    }
    $2 == "msr" && $3 ~ /^basepri,/ { restored++ }
    END {
        printf "PRIMASK/FAULTMASK writes outside the panic handler: %d (in the panic handler, on its way to HardFault: %d)\n", global, panic_only
        printf "BASEPRI_MAX writes: %d, of which not 0x10: %d; BASEPRI restores: %d\n", raised, bad, restored
        exit (global > 0 || bad > 0) ? 1 : 0
    }' || status=1

echo ">>> 3. scanned: what the PWM interrupt can reach (call graph from ADC1_2)"
# Direct calls and tail calls (bl/blx/b to another function's start) from
# every function; everything reachable from the handler must stay clear of
# critical sections and defmt (either would mean the interrupt waits on, or
# masks for, thread mode's logger).
# Mangled names (no -C): they hold no spaces or angle brackets.
"$BIN/llvm-objdump" -d --no-show-raw-insn "$ELF" | awk '
    /^[0-9a-f]+ <.*>:$/ { fn = $0; sub(/^[0-9a-f]+ </, "", fn); sub(/>:$/, "", fn); next }
    $2 ~ /^(bl|blx|b|b\.w)$/ && match($0, /<[^<>+ ]+>/) {
        t = substr($0, RSTART + 1, RLENGTH - 2)
        if (t != fn) { edges[fn] = edges[fn] SUBSEP t }
    }
    END {
        queue[1] = "ADC1_2"; seen["ADC1_2"] = 1; n = 1
        for (i = 1; i <= n; i++) {
            k = split(edges[queue[i]], next_fns, SUBSEP)
            for (j = 1; j <= k; j++) {
                t = next_fns[j]
                if (t != "" && !(t in seen)) { seen[t] = 1; queue[++n] = t }
            }
        }
        bad = 0
        for (f in seen) if (f ~ /critical_section|defmt|SEGGER/) { bad++; print "  the interrupt can reach " f }
        printf "functions reachable from ADC1_2: %d, of which critical-section or defmt: %d\n", n, bad
        exit bad > 0 ? 1 : 0
    }' || status=1

if ((status == 0)); then echo "masking: thread mode never masks the PWM interrupt"; else echo "masking: FAILED (see above)"; fi
exit $status
