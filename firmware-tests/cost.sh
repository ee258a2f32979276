#!/usr/bin/env bash
# Cost figures of the control core and the firmware image, in one command:
#
#   bash firmware-tests/cost.sh [--out DIR]      (default DIR: out/cost at the repository root)
#
# 1. Instructions per control period on a Cortex-M4F, and the longest PWM
#    period with a bulk request in it: builds
#    firmware-tests/examples/cost/ with the release profile (the
#    firmware's: opt-level "s", fat LTO) and runs it in
#    `qemu-system-arm -machine mps2-an386 -icount shift=7`, where SysTick
#    counts executed instructions exactly (docs/cost.md explains the method).
# 2. Flash and static RAM of the real firmware image for the STM32G431CB:
#    `cargo build --release` at the root, then llvm-size (flash = text + data,
#    static RAM = data + bss; the stack is the rest of RAM and is not counted).
# Prints the figures and writes DIR/summary.json. These are benchmark
# figures: nothing here fails because a budget is exceeded (the budgets are
# printed next to the figures and recorded in the JSON).
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/.." && pwd)"
OUT="$ROOT/out/cost"
while (($#)); do
    case "$1" in
        --out) OUT="$2"; shift 2 ;;
        -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
        *) echo "error: unknown argument '$1' (try --help)" >&2; exit 2 ;;
    esac
done
mkdir -p "$OUT"
OUT="$(cd "$OUT" && pwd)"
QEMU_TIMEOUT_S="${QEMU_TIMEOUT_S:-600}"
TARGET=thumbv7em-none-eabihf
HOST="$(rustc -vV | sed -n 's/^host: //p')"
SIZE="$(rustc --print sysroot)/lib/rustlib/$HOST/bin/llvm-size"
if [[ ! -x "$SIZE" ]]; then
    echo "error: $SIZE not found: add the llvm-tools component (rust-toolchain.toml lists it)" >&2
    exit 1
fi

# ---- 1. instructions (QEMU -icount) ----------------------------------------
echo ">>> building the cost benchmark (release profile)"
(cd "$HERE" && cargo build --release --example cost)
ELF="$HERE/target/$TARGET/release/examples/cost"
echo ">>> running it: qemu-system-arm -machine mps2-an386 -icount shift=7"
LOG="$OUT/qemu-cost.log"
if ! timeout "$QEMU_TIMEOUT_S" qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
        -semihosting-config enable=on,target=native -icount shift=7 -kernel "$ELF" </dev/null >"$LOG" 2>&1; then
    cat "$LOG"
    echo "error: the cost benchmark failed in QEMU (log: $LOG)" >&2
    exit 1
fi
grep -v '^JSON' "$LOG"
BENCH_JSON="$(sed -n 's/^JSON //p' "$LOG")"
if [[ -z "$BENCH_JSON" ]]; then
    echo "error: no figures in the benchmark's output ($LOG)" >&2
    exit 1
fi

# ---- 2. firmware image size -------------------------------------------------
echo ">>> building the firmware image: cargo build --release (root)"
(cd "$ROOT" && cargo build --release)
FW="$ROOT/target/$TARGET/release/cylinder-servo"
read -r text data bss < <("$SIZE" -B "$FW" | awk 'NR == 2 { print $1, $2, $3 }')
flash=$((text + data))
ram=$((data + bss))
echo
echo "firmware image $FW"
"$SIZE" -A "$FW" | awk '$1 ~ /^\.(vector_table|text|rodata|data|bss|uninit)$/ { printf "  %-14s %7d bytes\n", $1, $2 }'
# Budgets: 96 KiB of the chip's 128 KiB flash (the rest: the parameter
# record's two pages and room for a CAN bootloader), 16 KiB static RAM.
printf '  flash (text + data)      %7d bytes = %5.1f KiB   budget 96 KiB\n' "$flash" "$(awk -v b=$flash 'BEGIN { print b / 1024 }')"
printf '  static RAM (data + bss)  %7d bytes = %5.1f KiB   budget 16 KiB\n' "$ram" "$(awk -v b=$ram 'BEGIN { print b / 1024 }')"

# ---- 3. summary.json -------------------------------------------------------
num() { sed -n "s/^ *\"$1\": \\([0-9.]*\\),\\{0,1\\}$/\\1/p" <<<"$BENCH_JSON" | head -n 1; }
current=$(num current)
capturing=$(num current_capturing)
worst=$(num firmware)
position_obs=$(num position_with_observer)
position_alone_obs=$(num position_loop_alone_with_observer)
position_alone_five=$(num position_loop_alone_five_input)
within() { awk -v v="$1" -v b="$2" 'BEGIN { print (v <= b) ? "true" : "false" }'; }
{
    echo "{"
    echo "  \"command\": \"bash firmware-tests/cost.sh\","
    echo "  \"toolchain\": \"$(rustc --version)\","
    echo "  \"qemu\": \"$(qemu-system-arm --version | head -n 1)\","
    printf '  "instructions": %s,\n' "$BENCH_JSON"
    echo "  \"firmware\": {"
    echo "    \"elf\": \"target/$TARGET/release/cylinder-servo\","
    echo "    \"text_bytes\": $text, \"data_bytes\": $data, \"bss_bytes\": $bss,"
    echo "    \"flash_bytes\": $flash,"
    echo "    \"static_ram_bytes\": $ram"
    echo "  },"
    echo "  \"budgets\": {"
    echo "    \"current_period_insns\": {\"budget\": 450, \"figure\": $current, \"within\": $(within "$current" 450)},"
    echo "    \"current_period_capturing_insns\": {\"budget\": 500, \"figure\": $capturing, \"within\": $(within "$capturing" 500), \"note\": \"a 4-signal capture recording every period\"},"
    echo "    \"worst_pwm_period_insns\": {\"budget\": 3400, \"figure\": $worst, \"within\": $(within "$worst" 3400), \"note\": \"40 % of the 8500-cycle PWM period: the longest step plus a bulk request (parameter set, capture configure, test start) as the PWM interrupt serves them\"},"
    echo "    \"position_loop_alone_with_observer_insns\": {\"budget\": 1500, \"figure\": $position_alone_obs, \"within\": $(within "$position_alone_obs" 1500), \"note\": \"position period minus speed period\"},"
    echo "    \"position_loop_alone_five_input_insns\": {\"budget\": 1500, \"figure\": $position_alone_five, \"within\": $(within "$position_alone_five" 1500), \"note\": \"the same with an uploaded five-input observer model, the longest forward pass the drive runs\"},"
    echo "    \"flash_bytes\": {\"budget\": 98304, \"figure\": $flash, \"within\": $(within "$flash" 98304)},"
    echo "    \"static_ram_bytes\": {\"budget\": 16384, \"figure\": $ram, \"within\": $(within "$ram" 16384)}"
    echo "  }"
    echo "}"
} >"$OUT/summary.json"
echo
echo "wrote $OUT/summary.json"
