#!/usr/bin/env bash
# Panic lints of the control core (the `servo_core` library), for the
# firmware's target and for the host:
#
#   bash firmware-tests/lints/check.sh
#
# On top of the crate's own #![deny(clippy::unwrap_used, clippy::expect_used,
# clippy::panic, clippy::indexing_slicing)] this denies the other ways to
# write a panic (unreachable!, todo!, unimplemented!, integer arithmetic that
# can overflow or divide by zero) and the panicking methods listed in
# clippy.toml beside this script (f32::clamp, rem_euclid, ...). The
# link-time proof (panic-never/) is the final word; these lints point at the
# line while the code is written.
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
cd "$ROOT"
# Given as warnings and counted from the output for src/ only: on the
# command line they would also reach build.rs, which may use expect().
LINTS=(
    -W clippy::unwrap_used -W clippy::expect_used -W clippy::panic -W clippy::indexing_slicing
    -W clippy::unreachable -W clippy::todo -W clippy::unimplemented
    -W clippy::arithmetic_side_effects -W clippy::integer_division_remainder_used
    -W clippy::disallowed_methods
)
HOST="$(rustc -vV | sed -n 's/^host: //p')"
status=0
for target in thumbv7em-none-eabihf "$HOST"; do
    echo ">>> cargo clippy --lib --no-default-features --target $target"
    out="$(CLIPPY_CONF_DIR="$HERE" cargo clippy --lib --no-default-features --target "$target" --color never -- "${LINTS[@]}" 2>&1)"
    rc=$?
    # Each diagnostic: its header line, then "  --> file:line:col".
    found="$(awk '/^(warning|error)/ { head = $0; next }
                  /^ *--> / && head != "" { if ($2 ~ /^src\//) print $2 ": " head; head = "" }' <<<"$out" | sort -u)"
    if ((rc != 0)); then
        printf '%s\n' "$out"
        status=1
    elif [[ -n "$found" ]]; then
        printf '%s\n' "$found"
        status=1
    fi
done
if ((status == 0)); then echo "lints: control core clean"; else echo "lints: FAILED (see above)"; fi
exit $status
