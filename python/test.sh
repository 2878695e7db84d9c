#!/usr/bin/env bash
# The Python front's tests: build and install the package into a fresh virtual
# environment (pip fetches maturin, the build backend, itself), then run the pytest
# suite and the tutorial. Needs the agglo binary built first (`cargo build`), which the
# tests compare against; $AGGLO_BIN overrides where it is.
#   usage: python/test.sh            (from anywhere; VENV=dir to choose the environment)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="${VENV:-$root/target/python-venv}"
# The test extra installs DustPy 1.0.9, which PyPI has as source only: its build needs
# gfortran (Debian/Ubuntu: apt-get install gfortran), installed here when missing and
# this runs as root with apt-get (as on CI).
if ! command -v gfortran >/dev/null; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gfortran >/dev/null
    else
        echo "python/test.sh: DustPy (the test extra) needs gfortran to build: install it (apt-get install gfortran)" >&2
        exit 1
    fi
fi
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
start=$(date +%s)
# The dev profile (opt-level 1) reuses what `cargo build` compiled for the Rust tests; a
# user's `pip install ./python` builds the release profile (full speed). Set
# MATURIN_PEP517_ARGS= (empty) to test the release build.
export MATURIN_PEP517_ARGS="${MATURIN_PEP517_ARGS---profile=dev}"
"$venv/bin/pip" install --quiet "$root/python[test]"
echo "pip install ./python[test]: $(( $(date +%s) - start )) s"
export AGGLO_BIN="${AGGLO_BIN:-$root/target/debug/agglo}"
cd "$root"
"$venv/bin/python" -m pytest -q python/tests
# The tutorial, run and compared with what docs/python.md says it prints
# (docs/results/python_tutorial.txt; `docs/regenerate.py --only tutorial` rewrites it).
"$venv/bin/python" docs/regenerate.py --check --only tutorial
