#!/usr/bin/env bash
# Judges the chaos mosaic against a plain tiling on real texture samples (docs/quality.md).
#
# The samples come from packages at run time (scripts/quality-samples.sh) — nothing is
# committed — then the Rust report binary writes report.md and the side-by-side PNGs.
#
#   scripts/quality-report.sh [out-dir]        (default: target/quality-report)
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
out="${1:-$root/target/quality-report}"
cache=$("$root/scripts/quality-samples.sh")
cd "$root"
# The paper's one block a tile, then two blocks a tile (see docs/quality.md for why).
for blocks in 1 2; do
    cargo run --release -p vtex-quality --bin quality-report -- --blocks-per-tile "$blocks" \
        "$cache"/skimage-*.png "$cache"/gimp/*.pat --out "$out/blocks-per-tile-$blocks"
done
