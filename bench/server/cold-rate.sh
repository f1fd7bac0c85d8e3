#!/usr/bin/env bash
# Cold tiles per second of one texture over HTTP (not a timed test): a fresh release
# `vtex serve` (empty tile cache, default synthesis cache) answers TILES distinct level-0 PNG
# tiles, four tiles apart so that no two share their synthesis, fetched by CONNECTIONS
# concurrent clients; then the same for the 100k chaos mosaic as the baseline of the run.
# Usage: flock /tmp/vtex-bench.lock bench/server/cold-rate.sh [TEXTURE, default order-independent]
#        (a name, id or model); environment: TILES (60), CONNECTIONS (2, one a core here),
#        EXTRA_FLAGS (more `vtex serve` flags, e.g. "--max-syntheses-per-texture 2": by default
#        one texture holds all synthesis slots but one, so on 2 cores it renders on one).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
TEXTURE=${1:-order-independent}
TILES=${TILES:-60}
CONNECTIONS=${CONNECTIONS:-2}
cd "$ROOT"
cargo build --release -q --locked -p vtex-server
BIN="${CARGO_TARGET_DIR:-$ROOT/target}/release/vtex"
WORK=$(mktemp -d /tmp/vtex-cold-rate.XXXXXX)
PID=""
cleanup() {
  [ -z "$PID" ] || kill "$PID" 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

# One pass: a fresh server, TILES cold tiles of the texture picked by $1, at most $2 at once.
pass() {
  local key=$1 label=$2
  rm -rf "$WORK/data"
  # shellcheck disable=SC2086
  VTEX_LOG=warn "$BIN" serve --bind 127.0.0.1:0 --data-dir "$WORK/data" --web-dir "$WORK/none" ${EXTRA_FLAGS:-} \
    > "$WORK/out" 2> "$WORK/err" &
  PID=$!
  for _ in $(seq 1 600); do grep -q listening "$WORK/out" 2>/dev/null && break; sleep 0.1; done
  local url
  url=$(sed -n 's/^vtex listening on //p' "$WORK/out")
  [ -n "$url" ] || { cat "$WORK/err" >&2; exit 1; }
  local id
  id=$(curl -s "$url/api/v1/textures" | python3 -c '
import json, sys
key = sys.argv[1]
ts = json.load(sys.stdin)["textures"]
big = lambda t: t["width"] >= 100000 and t["height"] >= 100000
t = next((t for t in ts if key in (t["id"], t["name"])), None) or next(t for t in ts if t["model"] == key and big(t))
print(t["id"], t["name"], sep="\t")' "$key")
  local name=${id#*$'\t'}
  id=${id%%$'\t'*}
  # Warm the texture itself (its load and any per-texture tables) on a tile the pass never asks.
  curl -sf -o /dev/null "$url/api/v1/textures/$id/tiles/0/1/3.png"
  seq 0 $((TILES - 1)) | awk -v u="$url/api/v1/textures/$id/tiles/0" '{ printf "%s/%d/%d.png\n", u, 8 + 4 * $1, 20 + 4 * $1 }' > "$WORK/urls"
  local t0 t1 codes
  t0=$(date +%s.%N)
  codes=$(xargs -P "$CONNECTIONS" -n 1 curl -s -o /dev/null -w '%{http_code}\n' < "$WORK/urls" | sort | uniq -c | tr -s ' ' | tr '\n' ';')
  t1=$(date +%s.%N)
  kill "$PID"; wait "$PID" 2>/dev/null || true; PID=""
  python3 -c 'import sys; n, a, b = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]); print(f"{sys.argv[4]}: {n} cold tiles in {b - a:.2f} s, {n / (b - a):.1f} tiles/s at {sys.argv[5]} connections; answers {sys.argv[6]}")' \
    "$TILES" "$t0" "$t1" "$label $name" "$CONNECTIONS" "$codes"
}

echo "== $(date -u +%FT%TZ) $(git rev-parse --short HEAD) cold-rate, $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg), flags: ${EXTRA_FLAGS:-none}"
pass "$TEXTURE" "texture"
pass chaos-mosaic "baseline"
