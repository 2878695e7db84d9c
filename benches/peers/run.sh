#!/usr/bin/env bash
# Peer benchmark: run the same periodic particle cloud (scenes/peer_{merge,bounce}_N.json)
# in agglo and in REBOUND, one thread each, and append one CSV row per code per scene.
# scenes/peer_aggregation_N.json (ballistic aggregation, Maxwellian velocities) runs in
# agglo only: bench.py has no counterpart of its velocity draw.
#
# Usage (from anywhere):
#   benches/peers/run.sh [--with-rebound | --agglo-only] [--scenes "merge:1000 bounce:1000"]
#                        [--out FILE.csv] [--agglo PATH]
#
#   --with-rebound   run agglo, then REBOUND, for each scene (the default)
#   --agglo-only     skip REBOUND
#   --scenes LIST    space-separated VARIANT:N, VARIANT in {merge, bounce, aggregation};
#                    default "merge:1000 merge:10000 merge:100000 bounce:1000 bounce:10000"
#   --out FILE       CSV to append to (header written if the file is new or empty);
#                    default benches/peers/results.csv
#   --agglo PATH     agglo binary; default target/release/agglo under the repository root
#                    (built with `cargo build --release` if missing)
#
# Environment: PEER_REBOUND_VENV (venv made by rebound/setup.sh; default
# ${TMPDIR:-/tmp}/rebound-venv; setup.sh is run if the venv or its C helper is missing).
# Needs python3 (to read JSON) and GNU time at /usr/bin/time (process wall time, max RSS).
# Columns are described in benches/peers/README.md.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
SCENES_DIR="$HERE/scenes"
REBOUND_DIR="$HERE/rebound"
VENV="${PEER_REBOUND_VENV:-${TMPDIR:-/tmp}/rebound-venv}"
TIME_BIN=/usr/bin/time

WITH_REBOUND=1
SCENES="merge:1000 merge:10000 merge:100000 bounce:1000 bounce:10000"
OUT="$HERE/results.csv"
AGGLO="$ROOT/target/release/agglo"

usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'; }
die() { echo "run.sh: $*" >&2; exit 1; }
log() { echo "[peers] $*" >&2; }

while [ $# -gt 0 ]; do
    case "$1" in
        --with-rebound) WITH_REBOUND=1 ;;
        --agglo-only)   WITH_REBOUND=0 ;;
        --scenes)       [ $# -ge 2 ] || die "--scenes needs a value"; SCENES="$2"; shift ;;
        --scenes=*)     SCENES="${1#*=}" ;;
        --out)          [ $# -ge 2 ] || die "--out needs a value"; OUT="$2"; shift ;;
        --out=*)        OUT="${1#*=}" ;;
        --agglo)        [ $# -ge 2 ] || die "--agglo needs a value"; AGGLO="$2"; shift ;;
        --agglo=*)      AGGLO="${1#*=}" ;;
        -h|--help)      usage; exit 0 ;;
        *)              die "unknown argument '$1' (see --help)" ;;
    esac
    shift
done

# ---- checks -------------------------------------------------------------------------------
command -v python3 >/dev/null 2>&1 || die "python3 is needed to read the JSON outputs"
[ -x "$TIME_BIN" ] || die "GNU time not found at $TIME_BIN (apt-get install time)"

for s in $SCENES; do
    [[ "$s" =~ ^(merge|bounce|aggregation):[0-9]+$ ]] \
        || die "bad scene '$s' (want merge:N, bounce:N or aggregation:N)"
    f="$SCENES_DIR/peer_${s%%:*}_${s#*:}.json"
    [ -f "$f" ] || die "no scene file $f"
done

if [ ! -x "$AGGLO" ]; then
    if [ "$AGGLO" = "$ROOT/target/release/agglo" ]; then
        log "agglo binary missing; cargo build --release"
        (cd "$ROOT" && cargo build --release)
    fi
    [ -x "$AGGLO" ] || die "agglo binary not found: $AGGLO"
fi

if [ "$WITH_REBOUND" = 1 ]; then
    if [ ! -x "$VENV/bin/python" ] || [ ! -f "$VENV/libpeer_cor.so" ]; then
        log "REBOUND venv incomplete at $VENV; running rebound/setup.sh"
        PEER_REBOUND_VENV="$VENV" "$REBOUND_DIR/setup.sh" >&2
    fi
fi

# ---- output ---------------------------------------------------------------------------------
HEADER="code,variant,n,wall_s,steps_or_collisions,collisions,final_bodies,bf_over_b0,max_rss_kb,process_wall_s,seconds_per_collision"
mkdir -p "$(dirname "$OUT")"
if [ ! -s "$OUT" ]; then
    echo "$HEADER" > "$OUT"
elif [ "$(head -n 1 "$OUT")" != "$HEADER" ]; then
    die "$OUT exists with a different header; use another --out"
fi

TMP="$(mktemp -d "${TMPDIR:-/tmp}/peers.XXXXXX")"
trap 'rm -rf "$TMP"' EXIT

# row CODE VARIANT N WALL STEPS COLLISIONS FINAL BF RSS PROCESS_WALL -> appends to $OUT
row() {
    local spc
    spc="$(python3 -c 'import sys; w, c = float(sys.argv[1]), int(sys.argv[2]); print(f"{w / c:.4e}" if c > 0 else "")' "$4" "$6")"
    local line="$1,$2,$3,$4,$5,$6,$7,$8,$9,${10},$spc"
    echo "$line" >> "$OUT"
    echo "$line"
}

# ---- runs -----------------------------------------------------------------------------------
for s in $SCENES; do
    variant="${s%%:*}"
    n="${s#*:}"
    scene="$SCENES_DIR/peer_${variant}_${n}.json"

    # agglo: wall_s is the stepping time the engine reports; process_wall_s the whole process.
    log "agglo   $variant N=$n"
    RAYON_NUM_THREADS=1 "$TIME_BIN" -o "$TMP/time" -f "%e,%M" \
        "$AGGLO" run "$scene" --quiet --summary "$TMP/summary.json" \
        || die "agglo failed on $scene"
    IFS=, read -r pwall rss < "$TMP/time"
    IFS=, read -r wall steps coll final bf < <(python3 - "$TMP/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print(f'{s["wall_seconds"]:.6g},{s["steps"]},{s["counters"]["impacts"]},{s["final_bodies"]},{s["growth"]["growth_ratio"]:.6g}')
PY
)
    row agglo "$variant" "$n" "$wall" "$steps" "$coll" "$final" "$bf" "$rss" "$pwall"

    [ "$WITH_REBOUND" = 1 ] || continue
    [ "$variant" != aggregation ] || { log "REBOUND: no aggregation scene (agglo only)"; continue; }

    # REBOUND: bench.py prints one JSON line; its wall_s excludes the (Python) placement.
    case "$variant" in
        merge)  flags=(--variant merge --merge-impl pbc) ;;
        bounce) flags=(--variant hardsphere --zohdi-H 3e7) ;;   # 3e7 = material.H0 of peer_bounce_N
    esac
    log "REBOUND $variant N=$n (${flags[*]})"
    RAYON_NUM_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
        "$TIME_BIN" -o "$TMP/time" -f "%e,%M" \
        "$VENV/bin/python" "$REBOUND_DIR/bench.py" --n "$n" "${flags[@]}" > "$TMP/rebound.out" \
        || die "bench.py failed on $variant N=$n"
    IFS=, read -r pwall rss < "$TMP/time"
    IFS=, read -r wall steps coll final bf < <(python3 - "$TMP/rebound.out" <<'PY'
import json, sys
lines = [l for l in open(sys.argv[1]) if l.lstrip().startswith("{")]
r = json.loads(lines[-1])
if not r.get("completed", True):
    print(f"warning: REBOUND run stopped at t = {r['t_reached']}", file=sys.stderr)
print(f'{r["wall_s"]:.6g},{r["steps"]},{r["collisions"]},{r["final_n"]},{r["bf_over_b0"]:.6g}')
PY
)
    row rebound "$variant" "$n" "$wall" "$steps" "$coll" "$final" "$bf" "$rss" "$pwall"
done

log "appended to $OUT"
