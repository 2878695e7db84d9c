#!/usr/bin/env bash
# Idempotent setup of the REBOUND side of the peer benchmark.
#   - a venv at $PEER_REBOUND_VENV (default: ${TMPDIR:-/tmp}/rebound-venv)
#   - rebound (pinned, override with REBOUND_VERSION) + numpy from PyPI
#   - libpeer_cor.so, built from cor.c (next to this script) into the venv:
#     the engine's restitution law and a periodic-aware merge resolver as C
#     callbacks, so the hardsphere variant does not pay a Python callback per
#     collision (bench.py falls back to a Python callback if it is missing;
#     --merge-impl pbc needs it).
# Usage: benches/peers/rebound/setup.sh     (from anywhere)
set -euo pipefail

VENV="${PEER_REBOUND_VENV:-${TMPDIR:-/tmp}/rebound-venv}"
REBOUND_VERSION="${REBOUND_VERSION:-5.2.2}"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

PY="${PYTHON:-python3}"
if [ ! -x "$VENV/bin/python" ]; then
    "$PY" -m venv "$VENV"
fi

if ! "$VENV/bin/python" -c "import rebound, numpy, sys; sys.exit(0 if rebound.__version__=='$REBOUND_VERSION' else 1)" 2>/dev/null; then
    "$VENV/bin/pip" install --quiet --disable-pip-version-check "rebound==$REBOUND_VERSION" numpy
fi

# C helpers (double f(sim*, double v) restitution; periodic merge resolver)
SO="$VENV/libpeer_cor.so"
if [ ! -f "$SO" ] || [ "$HERE/cor.c" -nt "$SO" ]; then
    if command -v cc >/dev/null 2>&1; then
        REB_INC="$("$VENV/bin/python" -c 'import os, rebound; print(os.path.join(os.path.dirname(os.path.dirname(rebound.__file__)), "src"))')"
        cc -O2 -shared -fPIC -I"$REB_INC" -o "$SO" "$HERE/cor.c" -lm
    else
        echo "warning: no C compiler; bench.py will use a (slower) Python restitution callback" >&2
    fi
fi

"$VENV/bin/python" -c "import rebound, numpy; print('rebound', rebound.__version__, '| numpy', numpy.__version__, '| venv $VENV')"
