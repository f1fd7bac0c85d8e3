#!/usr/bin/env bash
# Fetches the quality reports' real samples into target/quality-samples (nothing is committed)
# and prints that directory: the texture patterns of Debian's gimp-data (GIMP .pat files) and
# brick, grass and gravel from the scikit-image wheel. A second run fetches nothing.
#
#   scripts/quality-samples.sh        → prints the cache directory on stdout
#
# Needs apt-get (as root or with sudo) unless /usr/share/gimp/2.0/patterns exists, and pip +
# unzip unless the scikit-image samples are cached already. SKIMAGE_VERSION pins the wheel.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
cache="$root/target/quality-samples"
skimage_version="${SKIMAGE_VERSION:-0.26.0}"
patterns=/usr/share/gimp/2.0/patterns
mkdir -p "$cache/gimp"

# GIMP patterns (Debian package gimp-data).
if ! ls "$cache"/gimp/*.pat >/dev/null 2>&1; then
    if [ ! -d "$patterns" ]; then
        sudo=""
        [ "$(id -u)" -eq 0 ] || sudo="sudo"
        export DEBIAN_FRONTEND=noninteractive
        $sudo apt-get install -y gimp-data >&2 || { $sudo apt-get update >&2 && $sudo apt-get install -y gimp-data >&2; }
    fi
    # Flattened into one directory: every pattern's file name is unique in gimp-data.
    find "$patterns" -name '*.pat' -exec cp {} "$cache/gimp/" \;
fi

# scikit-image's brick, grass and gravel (from the wheel; no Python import needed).
if [ ! -f "$cache/skimage-brick.png" ] || [ ! -f "$cache/skimage-grass.png" ] || [ ! -f "$cache/skimage-gravel.png" ]; then
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    python3 -m pip download --quiet --no-deps --only-binary :all: "scikit-image==$skimage_version" -d "$tmp" >&2
    for name in brick grass gravel; do
        unzip -o -q -j "$tmp"/scikit_image-*.whl "skimage/data/$name.png" -d "$tmp"
        mv "$tmp/$name.png" "$cache/skimage-$name.png"
    done
fi

echo "samples: $(ls "$cache"/gimp/*.pat | wc -l) GIMP patterns, 3 scikit-image photos in $cache" >&2
echo "$cache"
