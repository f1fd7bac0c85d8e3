"""KTX2 pages of every demo, checked by an implementation independent of the server's.

Starts `vtex serve` (path in argv[1]) over a fresh data directory with the demos, then for a
few pages of every demo fetches the raw RGBA page and its KTX2 forms (BC7 and BC1, with and
without zstd supercompression). Each file is parsed here from the KTX 2.0 specification
(identifier, header, level index, data format descriptor), its levels are inflated with the
`zstandard` package and decoded with `texture2ddecoder` (Perfare's BCn decoders), and the
result is compared with the RGBA page: PSNR per codec and demo, held to floors every demo
keeps (BC7 ≥ 37 dB, BC1 ≥ 27 dB) and counted against the targets (BC7 ≥ 40 dB, BC1 ≥ 30 dB),
which the noisiest demos miss at coarse levels whatever the encoder's effort. A whole mip chain (`mips.ktx2`) is checked level by level against the regions it
stands for. Prints a table, then `N passed, M failed`; exits non-zero on any failure.

Usage: python check_pages.py target/release/vtex [--markdown]
"""

import json
import math
import struct
import subprocess
import sys
import tempfile
import urllib.request

import texture2ddecoder
import zstandard

IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
# vkFormat, DFD colour model, bytes per 4×4 block (0: one RGBA8 texel of 4 bytes).
CODECS = {
    "bc7": (146, 134, 16),
    "bc1": (132, 128, 8),
    "rgba8": (43, 1, 0),
}
TARGET_DB = {"bc7": 40.0, "bc1": 30.0}
FLOOR_DB = {"bc7": 37.0, "bc1": 27.0}
SIZE, BORDER = 128, 4


def get(base, path):
    with urllib.request.urlopen(base + path, timeout=120) as r:
        return r.read()


def parse_ktx2(f, codec):
    """The levels of a KTX2 file as (width, height, texel bytes), checking every field."""
    assert f[:12] == IDENTIFIER, "identifier"
    vk, type_size, w, h, depth, layers, faces, nlevels, scheme = struct.unpack_from("<9I", f, 12)
    want_vk, want_model, block = CODECS[codec]
    assert vk == want_vk, f"vkFormat {vk}, expected {want_vk}"
    assert type_size == 1 and depth == 0 and layers == 0 and faces == 1, "a 2D texture"
    assert scheme in (0, 2), f"supercompression scheme {scheme}"
    dfd_off, dfd_len, kvd_off, kvd_len = struct.unpack_from("<4I", f, 48)
    sgd_off, sgd_len = struct.unpack_from("<2Q", f, 64)
    assert sgd_len == 0, "no global data for zstd"
    # Data format descriptor: total size, then one basic block.
    (total,) = struct.unpack_from("<I", f, dfd_off)
    assert total == dfd_len, "dfdTotalSize"
    vendor_type, version, block_size = struct.unpack_from("<IHH", f, dfd_off + 4)
    assert vendor_type == 0 and version == 2, "Khronos basic descriptor, version 1.3"
    model, primaries, transfer, _flags = f[dfd_off + 12 : dfd_off + 16]
    assert (model, primaries, transfer) == (want_model, 1, 2), f"model {model}, BT.709, sRGB"
    dims = f[dfd_off + 16 : dfd_off + 20]
    assert tuple(dims[:2]) == ((3, 3) if block else (0, 0)), f"texel block {tuple(dims)}"
    assert f[dfd_off + 20] == (block or 4), "bytesPlane0"
    assert block_size == 24 + 16 * (1 if block else 4), "samples"
    # Key/value data: the writer.
    (kv_len,) = struct.unpack_from("<I", f, kvd_off)
    key = f[kvd_off + 4 : kvd_off + 4 + kv_len].split(b"\0")[0]
    assert key == b"KTXwriter", key
    levels = []
    offsets = []
    for i in range(nlevels):
        off, length, raw_len = struct.unpack_from("<3Q", f, 80 + 24 * i)
        assert off + length <= len(f), "level inside the file"
        lw, lh = max(1, w >> i), max(1, h >> i)
        want_raw = ((lw + 3) // 4) * ((lh + 3) // 4) * block if block else lw * lh * 4
        assert raw_len == want_raw, f"level {i}: {raw_len} bytes, expected {want_raw}"
        data = f[off : off + length]
        if scheme == 2:
            data = zstandard.ZstdDecompressor().decompress(data, max_output_size=raw_len)
        else:
            assert off % max(block or 4, 4) == 0, "aligned level"
            assert length == raw_len
        assert len(data) == raw_len
        offsets.append(off)
        levels.append((lw, lh, decode(data, lw, lh, codec)))
    assert offsets == sorted(offsets, reverse=True), "levels stored smallest first"
    return levels


def decode(data, w, h, codec):
    """RGBA8 texels of one level."""
    if codec == "rgba8":
        return data
    pw, ph = (w + 3) // 4 * 4, (h + 3) // 4 * 4
    bgra = (texture2ddecoder.decode_bc7 if codec == "bc7" else texture2ddecoder.decode_bc1)(data, pw, ph)
    out = bytearray(w * h * 4)
    for y in range(h):
        row = bgra[y * pw * 4 : (y * pw + w) * 4]
        out[y * w * 4 : (y + 1) * w * 4] = row
    out[0::4], out[2::4] = out[2::4], out[0::4]
    return bytes(out)


def squared_error(a, b):
    """Sum of squared differences of the colour channels, and the channel count."""
    se = 0
    for c in range(3):
        se += sum((x - y) * (x - y) for x, y in zip(a[c::4], b[c::4]))
    return se, len(a) // 4 * 3


def psnr(se, n):
    return float("inf") if se == 0 else 10 * math.log10(255 * 255 * n / se)


def start_server(binary, data_dir):
    proc = subprocess.Popen(
        [binary, "serve", "--bind", "127.0.0.1:0", "--data-dir", data_dir, "--web-dir", data_dir],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    line = proc.stdout.readline()
    assert line.startswith("vtex listening on "), line
    return proc, line.split()[-1]


def main():
    binary = sys.argv[1]
    markdown = "--markdown" in sys.argv
    passed, failed = 0, 0

    def check(ok, what):
        nonlocal passed, failed
        if ok:
            passed += 1
        else:
            failed += 1
            print(f"FAIL {what}", file=sys.stderr)

    with tempfile.TemporaryDirectory(prefix="vtex-ktx2-") as data_dir:
        proc, base = start_server(binary, data_dir)
        try:
            textures = json.loads(get(base, "/api/v1/textures"))["textures"]
            rows = []
            for t in textures:
                tid = t["id"]
                sums = {}
                for level, px, py in [(0, 1, 1), (3, 0, 0)]:
                    q = f"size={SIZE}&border={BORDER}"
                    page = f"/api/v1/textures/{tid}/pages/{level}/{px}/{py}"
                    rgba = get(base, f"{page}.rgba?{q}")
                    for codec in ("bc7", "bc1"):
                        for sc in ("none", "zstd"):
                            f = get(base, f"{page}.ktx2?{q}&codec={codec}&supercompression={sc}")
                            try:
                                ((w, h, texels),) = parse_ktx2(f, codec)
                                ok = (w, h) == (SIZE + 2 * BORDER,) * 2
                            except AssertionError as e:
                                check(False, f"{t['name']} {codec}/{sc}: {e}")
                                continue
                            check(ok, f"{t['name']} {codec}/{sc}: size {w}×{h}")
                            if sc == "none":
                                se, n = squared_error(texels, rgba)
                                a, b = sums.get(codec, (0, 0))
                                sums[codec] = (a + se, b + n)
                            else:
                                check(texels == plain_texels, f"{t['name']} {codec}: zstd holds the same blocks")
                            plain_texels = texels
                db = {c: psnr(*sums[c]) for c in sums}
                for c, floor in FLOOR_DB.items():
                    db.setdefault(c, float("nan"))
                    check(db[c] >= floor, f"{t['name']} {c}: {db[c]:.2f} dB < {floor} dB")
                rows.append((t["name"], t["model"], db["bc7"], db["bc1"]))

            # A whole mip chain of a small demo, level by level against its regions.
            small = min((t for t in textures if t["model"] == "lcm"), key=lambda t: t["width"])
            chain = get(base, f"/api/v1/textures/{small['id']}/mips.ktx2?codec=bc7&supercompression=zstd")
            levels = parse_ktx2(chain, "bc7")
            check(levels[-1][:2] == (1, 1), "the chain ends at 1×1")
            chain_db = []
            for i, (w, h, texels) in enumerate(levels):
                region = get(base, f"/api/v1/textures/{small['id']}/region?level={i}&x=0&y=0&w={w}&h={h}&format=rgba")
                se, n = squared_error(texels, region)
                chain_db.append(psnr(se, n))
                check(chain_db[-1] >= TARGET_DB["bc7"], f"mip chain level {i}: {chain_db[-1]:.2f} dB")
        finally:
            proc.terminate()
            proc.wait()

    fmt = lambda v: "∞" if v == float("inf") else f"{v:.2f}"
    if markdown:
        print("| demo | model | BC7 PSNR (dB) | BC1 PSNR (dB) |")
        print("|---|---|---|---|")
    for name, model, a, b in rows:
        print(f"| {name} | {model} | {fmt(a)} | {fmt(b)} |" if markdown else f"{fmt(a):>7} {fmt(b):>7}  {name}")
    bc7 = [r[2] for r in rows]
    bc1 = [r[3] for r in rows]
    print(f"\n{len(rows)} demos, pages 0/1/1 and 3/0/0 of {SIZE}² + {BORDER} px borders:")
    for c, values in (("BC7", bc7), ("BC1", bc1)):
        target = TARGET_DB[c.lower()]
        met = sum(v >= target for v in values)
        median = sorted(values)[len(values) // 2]
        print(f"{c}: min {fmt(min(values))} dB, median {fmt(median)} dB; {met} of {len(values)} at or over {target:g} dB")
    print(f"mip chain of {small['name']} ({len(levels)} levels, BC7 + zstd): min {fmt(min(chain_db))} dB")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
