"""Writes the raw RGBA pages that src/main.rs measures: for every demo of a fresh `vtex serve`
(path in argv[1]), pages of several levels and sizes, as OUT/DD_LEVEL_X_Y_SIDE.rgba, with each
demo's name in OUT/DD.name.

Usage: python3 dump_pages.py target/release/vtex OUT
"""

import json
import subprocess
import sys
import tempfile
import urllib.request

# (level, x, y, size, border): check_pages.py's two pages first, then other levels and sizes.
PAGES = [(0, 1, 1, 128, 4), (3, 0, 0, 128, 4), (1, 0, 0, 128, 4), (2, 1, 0, 128, 4), (4, 0, 0, 128, 4),
         (3, 0, 0, 256, 4), (2, 0, 0, 64, 2)]


def get(base, path):
    with urllib.request.urlopen(base + path, timeout=300) as r:
        return r.read()


def main():
    binary, out = sys.argv[1], sys.argv[2]
    with tempfile.TemporaryDirectory() as d:
        proc = subprocess.Popen([binary, "serve", "--bind", "127.0.0.1:0", "--data-dir", d, "--web-dir", d],
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        base = proc.stdout.readline().split()[-1]
        try:
            for i, t in enumerate(json.loads(get(base, "/api/v1/textures"))["textures"]):
                for level, x, y, size, border in PAGES:
                    rgba = get(base, f"/api/v1/textures/{t['id']}/pages/{level}/{x}/{y}.rgba?size={size}&border={border}")
                    side = size + 2 * border
                    assert len(rgba) == side * side * 4
                    with open(f"{out}/{i:02d}_{level}_{x}_{y}_{side}.rgba", "wb") as f:
                        f.write(rgba)
                with open(f"{out}/{i:02d}.name", "w") as f:
                    f.write(t["name"])
        finally:
            proc.kill()


main()
