#!/usr/bin/env bash
# Warm tiles, `--send copy` against `--send splice`, on the same build in the same run: both
# servers start over one data directory (the demos), each caches the same 64 PNG tiles of the
# 100k chaos mosaic, then wrk runs against them in interleaved rounds (order alternating), at 8
# and 64 connections. Per run: tiles/s, p50, p99, and the server's CPU per tile (all threads,
# from /proc/PID/task/*/schedstat) with wrk's own (user + system), since both share the cores.
# Needs: wrk, curl, python3. Usage: bench/server/transport.sh [rounds, default 4] [seconds, default 5]
# (run it under `flock /tmp/vtex-bench.lock` on a shared machine; VTEX_BIN picks the binary)
set -euo pipefail
ROUNDS=${1:-4}
DUR=${2:-5}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
BIN=${VTEX_BIN:-$ROOT/target/release/vtex}
WORK=$(mktemp -d /tmp/vtex-transport.XXXXXX)
PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done; rm -rf "$WORK"; }
trap cleanup EXIT

declare -A URL PID
for send in copy splice; do
  VTEX_LOG=warn "$BIN" serve --bind 127.0.0.1:0 --data-dir "$WORK/data" --cache-mb 256 --send "$send" \
    --web-dir "$WORK/none" > "$WORK/$send.out" 2> "$WORK/$send.err" &
  PID[$send]=$!; PIDS+=($!)
  for _ in $(seq 1 600); do grep -q listening "$WORK/$send.out" 2>/dev/null && break; sleep 0.1; done
  URL[$send]=$(sed -n 's/^vtex listening on //p' "$WORK/$send.out")
done
ID=$(curl -s "${URL[copy]}/api/v1/textures" | python3 -c '
import json, sys
print(next(t["id"] for t in json.load(sys.stdin)["textures"] if t["width"] == 100000 and t["model"] == "chaos-mosaic"))')
{
  echo 'paths = {'
  for y in 0 1 2 3 4 5 6 7; do for x in 0 1 2 3 4 5 6 7; do
    P="/api/v1/textures/$ID/tiles/0/$((100 + x))/$((200 + y)).png"
    for send in copy splice; do curl -sf "${URL[$send]}$P" -o /dev/null; done
    echo "  \"$P\","
  done; done
  echo '}'
  echo 'i = 0'
  echo 'request = function() i = i + 1; return wrk.format("GET", paths[(i % #paths) + 1]) end'
} > "$WORK/warm.lua"

cpu_ns() { local t=0 a _ f; for f in /proc/"$1"/task/*/schedstat; do read -r a _ < "$f"; t=$((t + a)); done; echo "$t"; }
run() { # $1 = send, $2 = connections
  local c0 c1 n TIMEFORMAT='%U %S'
  c0=$(cpu_ns "${PID[$1]}")
  { time wrk -t2 -c"$2" -d"${DUR}s" --latency -s "$WORK/warm.lua" "${URL[$1]}" > "$WORK/wrk.txt"; } 2> "$WORK/wrk.time"
  c1=$(cpu_ns "${PID[$1]}")
  n=$(awk '/requests in/ {print $1}' "$WORK/wrk.txt")
  if grep -q Non-2xx "$WORK/wrk.txt"; then cat "$WORK/wrk.txt" >&2; exit 1; fi
  printf '| %s | %s | %s | %s | %s | %s | %s |\n' "$1" "$2" \
    "$(awk '/^Requests\/sec/ {printf "%.0f", $2}' "$WORK/wrk.txt")" \
    "$(awk '$1=="50%" {print $2}' "$WORK/wrk.txt")" "$(awk '$1=="99%" {print $2}' "$WORK/wrk.txt")" \
    "$(awk -v d=$((c1 - c0)) -v n="$n" 'BEGIN {printf "%.1f", d / 1000 / n}')" \
    "$(awk -v n="$n" '{printf "%.1f", ($1 + $2) * 1e6 / n}' "$WORK/wrk.time")"
}

echo "# --send copy vs splice, warm tiles — $(date -u +%FT%TZ), $(nproc) CPUs, ${DUR}s per run, load before: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| send | connections | tiles/s | p50 | p99 | server CPU µs/tile | wrk CPU µs/tile |"
echo "|---|---|---|---|---|---|---|"
for r in $(seq 1 "$ROUNDS"); do
  order="copy splice"; [ $((r % 2)) -eq 0 ] && order="splice copy"
  for c in 8 64; do for send in $order; do run "$send" "$c"; done; done
done
echo
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
