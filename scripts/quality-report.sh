#!/usr/bin/env bash
# Judges the chaos mosaic against a plain tiling on real texture samples (docs/quality.md).
#
# The samples come from packages at run time — nothing is committed: the texture patterns of
# Debian's gimp-data (GIMP .pat files) and brick, grass and gravel from the scikit-image wheel.
# They are cached under target/quality-samples (a second run fetches nothing), then the Rust
# report binary writes report.md and the side-by-side PNGs.
#
#   scripts/quality-report.sh [out-dir]        (default: target/quality-report)
#
# Needs apt-get (as root or with sudo) unless /usr/share/gimp/2.0/patterns exists, and pip +
# unzip unless the scikit-image samples are cached already. SKIMAGE_VERSION pins the wheel.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
cache="$root/target/quality-samples"
out="${1:-$root/target/quality-report}"
skimage_version="${SKIMAGE_VERSION:-0.26.0}"
patterns=/usr/share/gimp/2.0/patterns
mkdir -p "$cache/gimp"

# GIMP patterns (Debian package gimp-data).
if ! ls "$cache"/gimp/*.pat >/dev/null 2>&1; then
    if [ ! -d "$patterns" ]; then
        sudo=""
        [ "$(id -u)" -eq 0 ] || sudo="sudo"
        export DEBIAN_FRONTEND=noninteractive
        $sudo apt-get install -y gimp-data || { $sudo apt-get update && $sudo apt-get install -y gimp-data; }
    fi
    # Flattened into one directory: every pattern's file name is unique in gimp-data.
    find "$patterns" -name '*.pat' -exec cp {} "$cache/gimp/" \;
fi

# scikit-image's brick, grass and gravel (from the wheel; no Python import needed).
if [ ! -f "$cache/skimage-brick.png" ] || [ ! -f "$cache/skimage-grass.png" ] || [ ! -f "$cache/skimage-gravel.png" ]; then
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    python3 -m pip download --quiet --no-deps --only-binary :all: "scikit-image==$skimage_version" -d "$tmp"
    for name in brick grass gravel; do
        unzip -o -q -j "$tmp"/scikit_image-*.whl "skimage/data/$name.png" -d "$tmp"
        mv "$tmp/$name.png" "$cache/skimage-$name.png"
    done
fi

echo "samples: $(ls "$cache"/gimp/*.pat | wc -l) GIMP patterns, 3 scikit-image photos in $cache" >&2
cd "$root"
# The paper's one block a tile, then two blocks a tile (see docs/quality.md for why).
for blocks in 1 2; do
    cargo run --release -p vtex-quality --bin quality-report -- --blocks-per-tile "$blocks" \
        "$cache"/skimage-*.png "$cache"/gimp/*.pat --out "$out/blocks-per-tile-$blocks"
done
