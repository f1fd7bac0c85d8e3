#!/usr/bin/env bash
# Soak benchmark of `vtex serve` (not a timed test): a release server with the demos and set
# memory budgets, kept busy for SECONDS at CONNECTIONS connections by the load driver
# (fuzz/src/bin/soak.rs) mixing cached tiles, uncached tiles of every stored texture (every
# model, the dearest demo included), uploads of new textures, slow readers of a 16 MiB region
# and clients that never read; beside them, attackers hold as many silent sockets, and as many
# idle keep-alives, as the server's connection limit (MAX_CONNECTIONS), each made again once the
# server closes it. Reports each class's answers (0 errors expected for the well-behaved ones;
# 503/408/507 counted apart, and the slow readers' 503s when the in-flight budget is spent),
# p50/p99 of cached tiles, how long the attackers' sockets lived, and the server's RSS sampled
# every 100 ms against the budgets + 20 %. Appends to bench/results/soak-<date>.txt.
# Usage: flock /tmp/vtex-bench.lock bench/server/soak.sh [SECONDS, default 60]
# Environment: CACHE_MB (default 64), TEXTURES_MB (default 256), SYNTH_CACHE_MB (default 64),
#              INFLIGHT_MB (default 64: four of the slow readers' regions; regions are then
#              limited to their size, 2048², so that the budget holds the largest; uploads are
#              charged there too), CONNECTIONS (default 64), MAX_CONNECTIONS
#              (default 128: the server's limit), ATTACKERS (sockets each kind of attacker
#              holds, default MAX_CONNECTIONS: the limit filled twice over), SEED (default 1),
#              EXTRA_FLAGS (more `vtex serve` flags), BUILD_FLAGS (more `cargo build` flags:
#              `--no-default-features` for the system allocator instead of jemalloc).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
SECS=${1:-60}
CACHE_MB=${CACHE_MB:-64}
TEXTURES_MB=${TEXTURES_MB:-256}
SYNTH_CACHE_MB=${SYNTH_CACHE_MB:-64}
INFLIGHT_MB=${INFLIGHT_MB:-64}
CONNECTIONS=${CONNECTIONS:-64}
MAX_CONNECTIONS=${MAX_CONNECTIONS:-128}
SEED=${SEED:-1}
cd "$ROOT"
# shellcheck disable=SC2086
cargo build --release -q --locked -p vtex-server -p vtex-fuzz ${BUILD_FLAGS:-}
BIN="${CARGO_TARGET_DIR:-$ROOT/target}/release"
WORK=$(mktemp -d /tmp/vtex-soak.XXXXXX)
PID=""
cleanup() {
  [ -z "$PID" ] || kill "$PID" 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

flags=(--bind 127.0.0.1:0 --data-dir "$WORK/data" --cache-mb "$CACHE_MB" --web-dir "$WORK/none"
  --max-connections "$MAX_CONNECTIONS")
# RSS is held to the budgets together, + 20 %: the synthesis cache's once, as one model
# (order-independent) keeps one.
flags+=(--synth-cache-mb "$SYNTH_CACHE_MB")
budget=$((CACHE_MB + TEXTURES_MB + SYNTH_CACHE_MB))
note="budgets: tiles $CACHE_MB MiB, textures $TEXTURES_MB MiB, synthesis cache $SYNTH_CACHE_MB MiB"
if "$BIN/vtex" serve --help | grep -q -- '--textures-mb'; then
  flags+=(--textures-mb "$TEXTURES_MB")
else
  note="$note; this build has no --textures-mb, so loaded textures are not bounded"
fi
if "$BIN/vtex" serve --help | grep -q -- '--inflight-mb'; then
  flags+=(--inflight-mb "$INFLIGHT_MB" --max-region-pixels $((2048 * 2048)))
  budget=$((budget + INFLIGHT_MB))
  note="$note, bodies in flight $INFLIGHT_MB MiB"
else
  note="$note; this build has no --inflight-mb, so bodies in flight are not bounded"
fi
# shellcheck disable=SC2206
flags+=(${EXTRA_FLAGS:-})
VTEX_LOG=${VTEX_LOG:-warn} "$BIN/vtex" serve "${flags[@]}" > "$WORK/out" 2> "$WORK/err" &
PID=$!
for _ in $(seq 1 600); do grep -q listening "$WORK/out" 2>/dev/null && break; sleep 0.1; done
URL=$(sed -n 's/^vtex listening on //p' "$WORK/out")
[ -n "$URL" ] || { cat "$WORK/err" >&2; exit 1; }

out=bench/results/soak-$(date -u +%Y-%m-%d).txt
{
  echo "== $(date -u +%FT%TZ) $(git rev-parse --short HEAD)$(git diff --quiet || echo '+dirty') soak ${SECS}s, $(nproc) cores"
  echo "vtex serve ${flags[*]}"
  echo "($note)"
  "$BIN/soak" --url "$URL" --pid "$PID" --seconds "$SECS" --connections "$CONNECTIONS" --budget-mb "$budget" --seed "$SEED" \
    --attackers "${ATTACKERS:-$MAX_CONNECTIONS}"
  echo "server log lines: $(wc -l < "$WORK/err") (warnings and errors); server still running: $(kill -0 "$PID" 2>/dev/null && echo yes || echo NO)"
  echo
} | tee -a "$out"
