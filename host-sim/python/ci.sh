#!/usr/bin/env bash
# The Python package's CI step (called by .ci/test-all after the host tests,
# which built host-sim and its dependencies into host-sim/target):
#   1. a virtual environment in host-sim/target/py-venv (kept with the target
#      folder, so CI's cache of it keeps the installed packages too);
#   2. maturin, pytest, numpy, matplotlib from PyPI (skipped when present);
#   3. the package, built with maturin into host-sim/target (its dependencies
#      shared with host-sim) and installed: `pip install ./host-sim/python`;
#   4. the pytest suite against the simulated drive;
#   5. the examples (Agg backend, PNGs in out/python/);
#   6. the benchmark: out/python-bench/summary.json.
# Prints `python: P passed, F failed` (pytest's counts plus one per example
# and benchmark) and exits non-zero on any failure.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT" || exit 1
VENV="$ROOT/host-sim/target/py-venv"
PY="$VENV/bin/python"
PASSED=0
FAILED=0
fail() { echo "python: $*" >&2; FAILED=$((FAILED + 1)); }

if [[ ! -x "$PY" ]]; then
    if ! python3 -m venv "$VENV" 2>/dev/null; then
        # Debian's python3 ships venv separately.
        rm -rf "$VENV"
        if command -v apt-get >/dev/null 2>&1; then
            ver="$(python3 -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
            apt-get -o DPkg::Lock::Timeout=600 update -q && apt-get -o DPkg::Lock::Timeout=600 install -y -q --no-install-recommends "python$ver-venv" \
                || apt-get install -y -q --no-install-recommends python3-venv
        fi
        python3 -m venv "$VENV" || { echo "error: cannot make a Python virtual environment (python3 -m venv; on Debian: apt-get install python3-venv)" >&2; echo "python: 0 passed, 1 failed"; exit 1; }
    fi
fi
t=$SECONDS
"$PY" -m pip install -q --upgrade "maturin>=1.8,<2" pytest numpy matplotlib || { echo "python: 0 passed, 1 failed"; exit 1; }
echo ">>> tools installed in $((SECONDS - t)) s"

t=$SECONDS
# The README's install line, into the environment.
if ! "$PY" -m pip install -q --force-reinstall --no-deps ./host-sim/python; then
    echo "python: 0 passed, 1 failed"
    exit 1
fi
BUILD_S=$((SECONDS - t))
echo ">>> package built and installed in $BUILD_S s"
mkdir -p out/python-bench
printf '%s\n' "$BUILD_S" > out/python-bench/build_install_s.txt

log="$(mktemp)"
(cd host-sim/python && "$PY" -m pytest -q -p no:cacheprovider tests) 2>&1 | tee "$log"
p=$(grep -oE '[0-9]+ passed' "$log" | tail -n 1 | cut -d' ' -f1)
f=$(grep -oE '[0-9]+ (failed|error)' "$log" | awk '{s += $1} END {print s + 0}')
rm -f "$log"
PASSED=$((PASSED + ${p:-0}))
FAILED=$((FAILED + ${f:-0}))
[[ -n "${p:-}" ]] || fail "pytest did not run"

for ex in examples/*.py; do
    [[ -e "$ex" ]] || continue
    case "$ex" in examples/bench_*.py) continue ;; esac
    echo ">>> $ex"
    if MPLBACKEND=Agg timeout 600 "$PY" "$ex" --out out/python; then PASSED=$((PASSED + 1)); else fail "$ex failed"; fi
done
if [[ -f examples/bench_python.py ]]; then
    echo ">>> examples/bench_python.py"
    if MPLBACKEND=Agg timeout 900 "$PY" examples/bench_python.py --out out/python-bench --build-install-s "$BUILD_S"; then
        PASSED=$((PASSED + 1))
    else
        fail "examples/bench_python.py failed"
    fi
fi
echo "python: $PASSED passed, $FAILED failed"
((FAILED == 0))
