#!/usr/bin/env bash
# Load benchmarks of `vtex serve` on loopback, each beside a baseline in the same run:
#   1. warm tiles/s and p50/p99 at 8 and 64 connections, vtex vs nginx serving the same
#      tile bytes as static files;
#   2. cold 256² tiles per format over HTTP (every request a tile never seen before), beside
#      raw RGBA (synthesis + HTTP with no encoder);
#   3. resident memory after a long pan with a 256 MB cache, beside the bytes the cache holds;
#   4. start-up: opening an empty data directory (writing the demos) and reopening it.
# Needs: wrk, nginx, curl, python3 (apt-get install wrk nginx curl python3).
# Environment: BUILD_FLAGS, more `cargo build` flags (`--no-default-features`: the system
#   allocator instead of jemalloc).
# Usage: bench/server/run.sh [--only warm|cold|memory|startup] [--rounds N] [--tmpfs] [--reuseport]
#                            [seconds per run, default 10]
#   (--only runs one section, for quick comparisons; the default runs all four. --rounds
#   repeats the warm comparison N times, nginx and vtex interleaved, since single runs on a
#   shared machine swing widely. --tmpfs adds a third warm row: the same nginx serving a copy
#   of the tiles from /dev/shm, whose pages are all 4 KiB — the control for what the page size
#   of the tile bytes costs the client. --reuseport adds nginx listening with
#   `reuseport`: one socket per worker, so the kernel spreads connections over both workers
#   — the stronger baseline when the default's accept leaves one worker doing everything)
set -euo pipefail
ONLY=all
ROUNDS=1
TMPFS=""
REUSEPORT=""
while [ $# -gt 1 ]; do
  case "$1" in
    --only) ONLY=$2; shift 2;;
    --rounds) ROUNDS=$2; shift 2;;
    --tmpfs) TMPFS=$(mktemp -d /dev/shm/vtex-bench.XXXXXX); shift;;
    --reuseport) REUSEPORT=1; shift;;
    *) break;;
  esac
done
case "$ONLY" in all|warm|cold|memory|startup) ;; *) echo "--only takes warm, cold, memory or startup" >&2; exit 2;; esac
section() { [ "$ONLY" = all ] || [ "$ONLY" = "$1" ]; }
DUR=${1:-10}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
WORK=$(mktemp -d /tmp/vtex-bench.XXXXXX)
chmod 755 "$WORK" # nginx workers run unprivileged
VTEX_PID=""; NGINX_PID=""
cleanup() {
  [ -n "$VTEX_PID" ] && kill "$VTEX_PID" 2>/dev/null || true
  [ -n "$NGINX_PID" ] && kill "$NGINX_PID" 2>/dev/null || true
  rm -rf "$WORK"
  [ -z "$TMPFS" ] || rm -rf "$TMPFS"
}
trap cleanup EXIT

# shellcheck disable=SC2086
cargo build --release -q -p vtex-server --manifest-path "$ROOT/Cargo.toml" ${BUILD_FLAGS:-}
BIN="${CARGO_TARGET_DIR:-$ROOT/target}/release/vtex"

start_vtex() { # $1 = cache MB, $2 = data directory (default $WORK/data)
  VTEX_LOG=${LOG:-warn} "$BIN" serve --bind 127.0.0.1:0 --data-dir "${2:-$WORK/data}" --cache-mb "$1" \
    --web-dir "$WORK/none" > "$WORK/vtex.out" 2> "$WORK/vtex.err" &
  VTEX_PID=$!
  for _ in $(seq 1 600); do grep -q listening "$WORK/vtex.out" 2>/dev/null && break; sleep 0.1; done
  VTEX=$(sed -n 's/^vtex listening on //p' "$WORK/vtex.out")
}
stop_vtex() { kill -TERM "$VTEX_PID"; wait "$VTEX_PID" || true; VTEX_PID=""; }

# CPU time (ns) the given processes have run, all their threads summed (/proc/PID/task/*/schedstat).
cpu_ns() {
  local t=0 a _
  for p in "$@"; do for f in /proc/"$p"/task/*/schedstat; do read -r a _ < "$f"; t=$((t + a)); done; done
  echo "$t"
}
# Time (ns) the given processes' threads were runnable but waiting for a CPU (schedstat's
# second field): high when other work competes for the cores, which skews tiles/s.
wait_ns() {
  local t=0 _ w
  for p in "$@"; do for f in /proc/"$p"/task/*/schedstat; do read -r _ w _ < "$f"; t=$((t + w)); done; done
  echo "$t"
}
# Times the given processes' threads went to sleep (voluntary context switches): each is a
# wake-up someone pays for later — on loopback, often the client, in its kernel time.
sleeps() {
  local t=0 f v
  for p in "$@"; do for f in /proc/"$p"/task/*/status; do
    v=$(awk '/^voluntary_ctxt_switches/ {print $2}' "$f" 2>/dev/null); t=$((t + ${v:-0}))
  done; done
  echo "$t"
}
# "TID NS" for every thread of the given processes.
thread_ns() {
  local p f a _
  for p in "$@"; do for f in /proc/"$p"/task/*; do read -r a _ < "$f/schedstat"; echo "${f##*/} $a"; done; done
}

# wrk: $1 = connections, $2 = lua script, $3 = base URL, $4 = wrk threads, $5.. = server PIDs
# → "req/s p50 p99 server-CPU-µs/req wrk-CPU-µs/req/wrk-system-µs/req split wait-µs/req sleeps/1000-req" (the server figures "-" without
# PIDs). wrk's own CPU per request (user + system, from bash's `time`) is as much part of the
# result as the server's: both share the 2 cores. "split" is the share of the server's CPU
# each of its busy threads or worker processes took, largest first (e.g. 51/49): a lopsided
# split means one core served most connections.
run_wrk() {
  local threads=${4:-2}; [ "$1" -lt "$threads" ] && threads=$1
  local c0 c1 pids=("${@:5}")
  [ ${#pids[@]} -gt 0 ] && { c0=$(cpu_ns "${pids[@]}"); w0=$(wait_ns "${pids[@]}"); s0=$(sleeps "${pids[@]}"); thread_ns "${pids[@]}" > "$WORK/threads0"; }
  local TIMEFORMAT='%U %S'
  { time wrk -t"$threads" -c"$1" -d"${DUR}s" --latency -s "$2" "$3" > "$WORK/wrk.txt"; } 2> "$WORK/wrk.time"
  [ ${#pids[@]} -gt 0 ] && { c1=$(cpu_ns "${pids[@]}"); w1=$(wait_ns "${pids[@]}"); s1=$(sleeps "${pids[@]}"); thread_ns "${pids[@]}" > "$WORK/threads1"; }
  local rps p50 p99 non2xx n cpu=- wcpu wsys split=- wait=- slept=-
  rps=$(awk '/^Requests\/sec/ {print $2}' "$WORK/wrk.txt")
  p50=$(awk '$1=="50%" {print $2}' "$WORK/wrk.txt")
  p99=$(awk '$1=="99%" {print $2}' "$WORK/wrk.txt")
  n=$(awk '/requests in/ {print $1}' "$WORK/wrk.txt")
  non2xx=$(awk '/Non-2xx/ {print $NF}' "$WORK/wrk.txt")
  [ -n "$non2xx" ] && { echo "wrk saw $non2xx non-2xx responses" >&2; cat "$WORK/wrk.txt" >&2; exit 1; }
  wcpu=$(awk -v n="$n" '{printf "%.1f", ($1 + $2) * 1e6 / n}' "$WORK/wrk.time")
  wsys=$(awk -v n="$n" '{printf "%.1f", $2 * 1e6 / n}' "$WORK/wrk.time")
  if [ ${#pids[@]} -gt 0 ]; then
    cpu=$(awk -v d=$((c1 - c0)) -v n="$n" 'BEGIN {printf "%.1f", d / 1000 / n}')
    wait=$(awk -v d=$((w1 - w0)) -v n="$n" 'BEGIN {printf "%.1f", d / 1000 / n}')
    slept=$(awk -v d=$((s1 - s0)) -v n="$n" 'BEGIN {printf "%.0f", d * 1000 / n}')
    split=$(awk 'NR == FNR {a[$1] = $2; next} $2 > a[$1] {printf "%d\n", $2 - a[$1]}' "$WORK/threads0" "$WORK/threads1" |
      sort -rn | awk '{v[NR] = $1; t += $1} END {for (i = 1; i <= NR; i++) if (v[i] * 50 > t) s = s (i > 1 ? "/" : "") sprintf("%d", v[i] * 100 / t + 0.5); print s}')
  fi
  echo "$rps $p50 $p99 $cpu $wcpu/$wsys ${split:--} $wait $slept"
}

echo "# vtex server benchmarks — $(date -u +%FT%TZ), $(nproc) CPUs, loopback, ${DUR}s per run"
echo
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
if [ "$ONLY" != startup ]; then
start_vtex 256
ID=$(curl -s "$VTEX/api/v1/textures" | python3 -c '
import json, sys
print(next(t["id"] for t in json.load(sys.stdin)["textures"] if t["width"] == 100000 and t["model"] == "chaos-mosaic"))')
fi

if section warm; then
# 1. Warm tiles: 64 PNG tiles of the 100k mosaic, fetched once into vtex's cache and
#    written to nginx's root at the same paths.
mkdir -p "$WORK/www"
URLS=()
for y in 0 1 2 3 4 5 6 7; do for x in 0 1 2 3 4 5 6 7; do
  P="/api/v1/textures/$ID/tiles/0/$((100 + x))/$((200 + y)).png"
  mkdir -p "$WORK/www$(dirname "$P")"
  curl -sf "$VTEX$P" -o "$WORK/www$P"
  URLS+=("$P")
done; done
{
  echo 'local paths = {'
  for p in "${URLS[@]}"; do echo "  \"$p\","; done
  echo '}'
  echo 'local i = 0'
  echo 'request = function() i = i + 1; return wrk.format("GET", paths[(i % #paths) + 1]) end'
} > "$WORK/warm.lua"
chmod -R a+rX "$WORK/www"
TMPFS_SERVER=""
if [ -n "$TMPFS" ]; then
  chmod 755 "$TMPFS"; cp -r "$WORK/www" "$TMPFS/www"
  TMPFS_SERVER="server { listen 127.0.0.1:18090; root $TMPFS/www; etag on;
           add_header Cache-Control \"public, max-age=31536000, immutable\"; }"
fi
REUSEPORT_SERVER=""
if [ -n "$REUSEPORT" ]; then
  REUSEPORT_SERVER="server { listen 127.0.0.1:18091 reuseport; root $WORK/www; etag on;
           add_header Cache-Control \"public, max-age=31536000, immutable\"; }"
fi
cat > "$WORK/nginx.conf" <<NGINX
worker_processes auto;
pid $WORK/nginx.pid;
error_log $WORK/nginx.err warn;
events { worker_connections 1024; }
http {
  access_log off;
  sendfile on; tcp_nopush on; tcp_nodelay on;
  keepalive_requests 1000000;
  open_file_cache max=1000;
  types { image/png png; }
  server { listen 127.0.0.1:18089; root $WORK/www; etag on;
           add_header Cache-Control "public, max-age=31536000, immutable"; }
  $TMPFS_SERVER
  $REUSEPORT_SERVER
}
NGINX
nginx -c "$WORK/nginx.conf" -g 'daemon off;' & NGINX_PID=$!
sleep 0.5
TILE_BYTES=$(du -sb "$WORK/www" | cut -f1)
echo
echo "## Warm tiles (64 distinct 256² PNG tiles, $((TILE_BYTES / 64)) bytes each on average)"
echo
echo "Server CPU: µs of CPU time the server (all its threads or worker processes) spent per tile;"
echo "wrk CPU: the same for wrk (user + system / system alone). Both share the 2 cores, so their sum decides"
echo "throughput and is less noisy than tiles/s. Split: the server's CPU per busy thread (vtex's"
echo "runtimes) or worker process (nginx), in %, largest first (above 2 % each). Server wait: µs"
echo "per tile the server's threads were runnable but waiting for a core — high when something"
echo "else competes for the CPUs (then tiles/s says more about the scheduler than the server)."
echo "Server sleeps: times per 1000 tiles a server thread went idle and had to be woken again."
echo
echo "| server | connections | tiles/s | p50 | p99 | server CPU µs/tile | wrk CPU / sys µs/tile | split % | server wait µs/tile | server sleeps /1000 tiles |"
echo "|---|---|---|---|---|---|---|---|---|---|"
NGINX_WORKERS=$(pgrep -P "$NGINX_PID" | tr '\n' ' ')
for _ in $(seq 1 "$ROUNDS"); do for c in 8 64; do
  # shellcheck disable=SC2086 # one PID per word
  read -r rps p50 p99 cpu wcpu split wait slept < <(run_wrk "$c" "$WORK/warm.lua" "http://127.0.0.1:18089" 2 $NGINX_WORKERS)
  echo "| nginx (static files) | $c | $rps | $p50 | $p99 | $cpu | $wcpu | $split | $wait | $slept |"
  if [ -n "$TMPFS" ]; then
    # shellcheck disable=SC2086 # one PID per word
    read -r rps p50 p99 cpu wcpu split wait slept < <(run_wrk "$c" "$WORK/warm.lua" "http://127.0.0.1:18090" 2 $NGINX_WORKERS)
    echo "| nginx (tmpfs files) | $c | $rps | $p50 | $p99 | $cpu | $wcpu | $split | $wait | $slept |"
  fi
  if [ -n "$REUSEPORT" ]; then
    # shellcheck disable=SC2086 # one PID per word
    read -r rps p50 p99 cpu wcpu split wait slept < <(run_wrk "$c" "$WORK/warm.lua" "http://127.0.0.1:18091" 2 $NGINX_WORKERS)
    echo "| nginx (reuseport) | $c | $rps | $p50 | $p99 | $cpu | $wcpu | $split | $wait | $slept |"
  fi
  read -r rps p50 p99 cpu wcpu split wait slept < <(run_wrk "$c" "$WORK/warm.lua" "$VTEX" 2 "$VTEX_PID")
  echo "| vtex (tile cache) | $c | $rps | $p50 | $p99 | $cpu | $wcpu | $split | $wait | $slept |"
done; done
kill "$NGINX_PID"; wait "$NGINX_PID" 2>/dev/null || true; NGINX_PID=""
fi

if section cold; then
# 2. Cold tiles: every request is a new tile of level 0 (391² tiles exist).
echo
echo "## Cold 256² tiles over HTTP (synthesis + encode + HTTP; 1 connection, then 2)"
echo
echo "| format | connections | tiles/s | p50 | p99 |"
echo "|---|---|---|---|---|"
RUN=0
for fmt in png webp jpg rgba; do
  for c in 1 2; do
    # One wrk thread walks disjoint stretches of tiles per run, so no request repeats a key.
    RUN=$((RUN + 1))
    cat > "$WORK/cold.lua" <<LUA
local n = $((RUN * 19000))
request = function()
  n = n + 1
  local k = n % (391 * 391)
  return wrk.format("GET", "/api/v1/textures/$ID/tiles/0/" .. (k % 391) .. "/" .. math.floor(k / 391) .. ".$fmt")
end
LUA
    read -r rps p50 p99 _ < <(run_wrk "$c" "$WORK/cold.lua" "$VTEX" 1)
    echo "| $fmt | $c | $rps | $p50 | $p99 |"
  done
done
fi
[ -z "$VTEX_PID" ] || stop_vtex

if section memory; then
# 3. Memory: a long pan over level 0 (every request a new PNG tile) with a 256 MB cache.
start_vtex 256
RSS0=$(awk '/VmRSS/ {print $2}' "/proc/$VTEX_PID/status")
cat > "$WORK/pan.lua" <<LUA
local n = 0
request = function()
  n = n + 1
  local k = n % (391 * 391)
  return wrk.format("GET", "/api/v1/textures/$ID/tiles/0/" .. (k % 391) .. "/" .. math.floor(k / 391) .. ".png")
end
LUA
PAN_DUR=$((DUR * 6))
wrk -t1 -c8 -d"${PAN_DUR}s" -s "$WORK/pan.lua" "$VTEX" > "$WORK/pan.txt"
RSS1=$(awk '/VmRSS/ {print $2}' "/proc/$VTEX_PID/status")
HWM=$(awk '/VmHWM/ {print $2}' "/proc/$VTEX_PID/status")
M=$(curl -s "$VTEX/metrics")
CACHE=$(echo "$M" | awk '/^vtex_tile_cache_bytes / {print $2}')
BUDGET=$(echo "$M" | awk '/^vtex_tile_cache_budget_bytes / {print $2}')
MAPPED=$(echo "$M" | awk '/^vtex_tile_cache_mapped_bytes / {print $2}')
SENT=$(echo "$M" | awk '/^vtex_http_response_bytes_total / {print $2}')
REQS=$(awk '/requests in/ {print $1}' "$WORK/pan.txt")
echo
echo "## Resident memory after a ${PAN_DUR}s pan (8 connections, $REQS new PNG tiles, $((${SENT%.*} / 1048576)) MiB sent)"
echo
echo "| cache budget | cache bytes held | mapped for them | RSS at start | RSS after pan | peak RSS |"
echo "|---|---|---|---|---|---|"
echo "| $((${BUDGET%.*} / 1048576)) MiB | $((${CACHE%.*} / 1048576)) MiB | $((${MAPPED%.*} / 1048576)) MiB | $((RSS0 / 1024)) MiB | $((RSS1 / 1024)) MiB | $((HWM / 1024)) MiB |"
stop_vtex
fi
if section startup; then
# 4. Start-up: the store's own timing of opening the data directory, from its log line
#    ("store opened … ms=N"): first with an empty directory (the demos are written, then
#    loaded), then the same directory again (loaded and validated).
startup_ms() { sed 's/\x1b\[[0-9;]*m//g' "$WORK/vtex.err" | sed -n 's/.*store opened.* ms=\([0-9]*\).*/\1/p'; }
LOG=info start_vtex 256 "$WORK/data-startup"; FIRST=$(startup_ms); stop_vtex
LOG=info start_vtex 256 "$WORK/data-startup"; AGAIN=$(startup_ms); stop_vtex
echo
echo "## Start-up (the store opened, ms)"
echo
echo "| empty data directory (demos written and loaded) | same directory again (loaded and validated) |"
echo "|---|---|"
echo "| $FIRST | $AGAIN |"
fi
echo
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
