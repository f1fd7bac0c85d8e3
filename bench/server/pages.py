"""Page latency, cold and warm, and bytes per format, beside 256² tiles from the same server in
the same run (the baseline).

Starts `vtex serve` (argv[1]) over a fresh data directory with the demos, then for each format
asks N distinct level-0 pages of the 100k chaos mosaic one after another on one keep-alive
connection (cold: every one a synthesis), then the same N again (warm: cache hits). Pages of
different formats sit at different places, so no format warms another. Prints a markdown table.

Run it alone: flock /tmp/vtex-bench.lock python3 bench/server/pages.py target/release/vtex [N]
"""

import http.client
import json
import os
import subprocess
import sys
import tempfile
import time

CASES = [
    # (label, path after the texture id, given column and row offset)
    ("tile 256² png (baseline)", "tiles/0/{x}/{y}.png", ""),
    ("tile 256² rgba (baseline)", "tiles/0/{x}/{y}.rgba", ""),
    ("page 128+4 rgba", "pages/0/{x}/{y}.rgba", "size=128&border=4"),
    ("page 128+4 png", "pages/0/{x}/{y}.png", "size=128&border=4"),
    ("page 128+4 ktx2 bc7", "pages/0/{x}/{y}.ktx2", "size=128&border=4&codec=bc7"),
    ("page 128+4 ktx2 bc7 zstd", "pages/0/{x}/{y}.ktx2", "size=128&border=4&codec=bc7&supercompression=zstd"),
    ("page 128+4 ktx2 bc1", "pages/0/{x}/{y}.ktx2", "size=128&border=4&codec=bc1"),
    ("page 128+4 ktx2 bc1 zstd", "pages/0/{x}/{y}.ktx2", "size=128&border=4&codec=bc1&supercompression=zstd"),
]


def pct(values, p):
    v = sorted(values)
    return v[round((len(v) - 1) * p)]


def main():
    binary = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    with tempfile.TemporaryDirectory(prefix="vtex-bench-pages-") as data:
        proc = subprocess.Popen(
            [binary, "serve", "--bind", "127.0.0.1:0", "--data-dir", data, "--web-dir", data],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        try:
            addr = proc.stdout.readline().split("//")[-1].strip()
            host, port = addr.split(":")
            conn = http.client.HTTPConnection(host, int(port))

            def get(path):
                t0 = time.perf_counter()
                conn.request("GET", path)
                r = conn.getresponse()
                body = r.read()
                assert r.status == 200, (path, r.status, body[:200])
                return time.perf_counter() - t0, len(body)

            conn.request("GET", "/api/v1/textures")
            textures = json.loads(conn.getresponse().read())["textures"]
            tid = next(t["id"] for t in textures if t["name"] == "Pebbles — chaos mosaic 100k")
            print(f"load average before: {os.getloadavg()[0]:.2f}", file=sys.stderr)
            print("| what | cold p50 ms | cold p95 ms | warm p50 ms | warm p95 ms | bytes (mean) |")
            print("|---|---|---|---|---|---|")
            for row, (label, path, query) in enumerate(CASES):
                urls = [
                    f"/api/v1/textures/{tid}/{path.format(x=10 + 3 * i, y=10 + 20 * row)}" + (f"?{query}" if query else "")
                    for i in range(n)
                ]
                cold = [get(u) for u in urls]
                warm = [get(u) for u in urls]
                ct, wt = [c[0] * 1e3 for c in cold], [w[0] * 1e3 for w in warm]
                mean_bytes = sum(c[1] for c in cold) / n
                print(
                    f"| {label} | {pct(ct, .5):.2f} | {pct(ct, .95):.2f} | {pct(wt, .5):.3f} | {pct(wt, .95):.3f} | {mean_bytes:,.0f} |"
                )
            print(f"load average after: {os.getloadavg()[0]:.2f}", file=sys.stderr)
        finally:
            proc.terminate()
            proc.wait()


if __name__ == "__main__":
    main()
