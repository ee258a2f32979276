#!/usr/bin/env bash
# Every exception and interrupt the firmware does not serve ends in the safe
# state (bridge off, brake closed), read from the built image:
#
#   bash firmware-tests/vectors/check.sh
#
# Builds the firmware image (`cargo build --release` at the root), finds the
# chip's interrupt list in the stm32-metapac crate it was built with (through
# `cargo metadata`), and runs check.py on the ELF's vector table: the served
# vectors (Reset, HardFault, the seven interrupts listed in check.py) point
# at their own handlers, every other one at DefaultHandler, and both
# DefaultHandler and HardFault reach `safe_state`, which writes TIM1 and
# GPIOB. check.py's self-test then breaks the table five ways and fails if a
# rule misses one. Exit 0 only if all of that holds.
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
HOST="$(rustc -vV | sed -n 's/^host: //p')"
BIN="$(rustc --print sysroot)/lib/rustlib/$HOST/bin"
if [[ ! -x "$BIN/llvm-objdump" || ! -x "$BIN/llvm-nm" ]]; then
    echo "error: llvm-objdump/llvm-nm not found in $BIN: add the llvm-tools component" >&2
    exit 1
fi

echo ">>> building the firmware image: cargo build --release (root)"
(cd "$ROOT" && cargo build --release)
ELF="$ROOT/target/thumbv7em-none-eabihf/release/cylinder-servo"

# The chip feature of embassy-stm32 in firmware/Cargo.toml names the PAC file.
CHIP="$(grep -o '"stm32g4[0-9a-z]*"' "$ROOT/firmware/Cargo.toml" | head -n 1 | tr -d '"')"
METAPAC_DIR="$(cd "$ROOT" && cargo metadata --format-version 1 --manifest-path firmware/Cargo.toml 2>/dev/null \
    | python3 -c 'import json, os, sys
for p in json.load(sys.stdin)["packages"]:
    if p["name"] == "stm32-metapac":
        print(os.path.dirname(p["manifest_path"]))')"
PAC_RS="$METAPAC_DIR/src/chips/$CHIP/pac.rs"
if [[ -z "$CHIP" || ! -f "$PAC_RS" ]]; then
    echo "error: the interrupt list of '$CHIP' was not found (looked for $PAC_RS)" >&2
    exit 1
fi

echo ">>> reading the vector table ($CHIP)"
python3 "$HERE/check.py" "$ELF" "$PAC_RS" "$BIN" --self-test
