#!/usr/bin/env bash
# Judges order-independent synthesis (exhaustive and k-coherence search) beside the chaos
# mosaic, a plain tiling and Embark's texture-synthesis on the quality reports' real samples
# (docs/models/order-independent.md, "Quality").
#
#   scripts/synthesis-report.sh [out-dir]      (default: target/synthesis-report)
#
# Embark's CLI is built from crates.io (texture-synthesis-cli, its own lock file) into
# target/embark on the first run; NO_EMBARK=1 leaves it out.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
out="${1:-$root/target/synthesis-report}"
cache=$("$root/scripts/quality-samples.sh")
cd "$root"
embark=()
if [ -z "${NO_EMBARK:-}" ]; then
    bin="$root/target/embark/bin/texture-synthesis"
    [ -x "$bin" ] || cargo install --locked --quiet texture-synthesis-cli --version 0.8.3 --root "$root/target/embark"
    embark=(--embark "$bin")
fi
cargo run --release -p vtex-quality --bin synthesis-report -- "${embark[@]}" \
    "$cache"/skimage-*.png "$cache"/gimp/*.pat --out "$out"
