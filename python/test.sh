#!/usr/bin/env bash
# The Python package's tests (issue 53), as CI runs them: a virtual
# environment, the wheel built from this checkout by maturin (`pip install
# .`), pytest and pyuff from PyPI, then python/tests against the
# `vibroscope` command built by `cargo build --release` (VIBROSCOPE_BIN).
#   bash python/test.sh [PYTEST ARGS]
# VENV: where the environment goes (default target/python-venv, or beside
# CARGO_TARGET_DIR's artifacts); it is reused when present.
set -euo pipefail
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-$PWD/target}
venv=${VENV:-$target/python-venv}
py=${PYTHON:-python3}
if ! "$py" -c 'import venv, ensurepip' 2>/dev/null; then
  echo "python/test.sh: $py has no venv/ensurepip module (Debian: apt-get install python3-venv)" >&2
  exit 2
fi
[ -x "$venv/bin/python" ] || "$py" -m venv "$venv"
"$venv/bin/python" -m pip install -q --upgrade pip
# The wheel: maturin compiles crates/python (and the library) in release.
"$venv/bin/python" -m pip install -q ".[test]"
# pyOMA-2 (operational modal analysis) for python/tests/test_pyoma2.py and
# examples/pyoma2_beam.py; where it cannot be installed that test skips
# with the reason.
"$venv/bin/python" -m pip install -q pyOMA-2 ||
  echo "python/test.sh: pyOMA-2 could not be installed from PyPI: test_pyoma2.py will skip" >&2
export VIBROSCOPE_BIN=${VIBROSCOPE_BIN:-$target/release/vibroscope}
[ -x "$VIBROSCOPE_BIN" ] || cargo build --release --bin vibroscope
"$venv/bin/python" -m pytest -q -rs python/tests "$@"
