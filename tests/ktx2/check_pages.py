"""KTX2 pages of every demo, checked by an implementation independent of the server's.

Starts `vtex serve` (path in argv[1]) over a fresh data directory with the demos, then for a
few pages of every demo fetches the raw RGBA page and its KTX2 forms (BC7 and BC1, with and
without zstd supercompression). Each file is parsed here from the KTX 2.0 specification
(identifier, header, level index, data format descriptor), its levels are inflated with the
`zstandard` package and decoded with `texture2ddecoder` (Perfare's BCn decoders), and the
result is compared with the RGBA page: PSNR per codec and demo, held to floors every demo
keeps (BC7 ≥ 39 dB, BC1 ≥ 27.5 dB) and counted against the targets (BC7 ≥ 40 dB, BC1 ≥ 30 dB),
which the noisiest demos miss at coarse levels whatever the encoder's effort (the best BC7 and
BC1 encoders on crates.io included: docs/ktx2-quality.md). A whole mip chain (`mips.ktx2`) is checked level by level against the regions it
stands for.

Basis Universal pages (codec uastc, with and without zstd, and etc1s, BasisLZ) are parsed here
as far as the container goes (header, DFD: VK_FORMAT_UNDEFINED, the UASTC or ETC1S colour
model, sRGB) and transcoded to RGBA8 by `alktx2` (PyPI, a wrapper of Binomial's basisu), whose
own inspection must agree (format, sRGB); their PSNR is held to floors (UASTC ≥ 33 dB, ETC1S ≥
19 dB: the noisiest cascades' pages at level 3) and reported, with the JPEG page's (decoded by Pillow) beside them.
Normal-layer pages (`layer=normal`) of every demo are checked in every codec as linear data: the
_UNORM vkFormats, a linear DFD transfer, alktx2 reading them as not sRGB, and floors against
the raw normal page. Prints a table of
PSNR and bytes per demo (`--markdown`: docs/ktx2-quality.md's), then `N passed, M failed`;
exits non-zero on any failure.

Usage: python check_pages.py target/release/vtex [--markdown]
"""

import json
import math
import struct
import subprocess
import sys
import tempfile
import urllib.request

import io

import alktx2
import texture2ddecoder
import zstandard
from PIL import Image

IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
# vkFormat, DFD colour model, bytes per 4×4 block (0: one RGBA8 texel of 4 bytes).
CODECS = {
    "bc7": (146, 134, 16),
    "bc1": (132, 128, 8),
    "rgba8": (43, 1, 0),
}
# The same formats' _UNORM vkFormats, for the normal layer's linear data.
UNORM = {"bc7": 145, "bc1": 131, "rgba8": 37}
# KHR_DF_TRANSFER_SRGB and KHR_DF_TRANSFER_LINEAR.
SRGB, LINEAR = 2, 1
TARGET_DB = {"bc7": 40.0, "bc1": 30.0}
FLOOR_DB = {"bc7": 39.0, "bc1": 27.5}
# Basis Universal: the DFD colour model, the supercompression schemes served, the floors.
BASIS = {"uastc": (166, ("none", "zstd"), 33.0), "etc1s": (163, ("basislz",), 19.0)}
BASIS_NAMES = {"uastc": "UASTC LDR 4x4", "etc1s": "ETC1S"}
SIZE, BORDER = 128, 4
# Normal pages: lossless in RGBA8; the block codecs' floors lie under their worst demo (Cascade
# B's cliffs turn the normal through 140° between neighbours, which a colour line per 4×4
# block cannot follow); over all demos each must beat the flat normal by the margin.
NORMAL_FLOOR_DB = {"rgba8": float("inf"), "bc7": 20.0, "bc1": 15.0, "uastc": 20.0}
NORMAL_FLAT_MARGIN_DB = 6.0


def get(base, path):
    try:
        with urllib.request.urlopen(base + path, timeout=120) as r:
            return r.read()
    except urllib.error.HTTPError as e:
        raise AssertionError(f"{path}: {e.code} {e.read()[:300]!r}") from None


def parse_ktx2(f, codec, transfer=SRGB):
    """The levels of a KTX2 file as (width, height, texel bytes), checking every field."""
    assert f[:12] == IDENTIFIER, "identifier"
    vk, type_size, w, h, depth, layers, faces, nlevels, scheme = struct.unpack_from("<9I", f, 12)
    want_vk, want_model, block = CODECS[codec]
    want_vk = want_vk if transfer == SRGB else UNORM[codec]
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
    model, primaries, got_transfer, _flags = f[dfd_off + 12 : dfd_off + 16]
    assert (model, primaries, got_transfer) == (want_model, 1, transfer), f"model {model}, BT.709, transfer {transfer}"
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


def parse_basis(f, codec, sc, transfer=SRGB):
    """The RGBA8 texels of a one-level Basis Universal KTX2 file: the container checked here
    against the KTX 2.0 specification, the texels transcoded by alktx2."""
    assert f[:12] == IDENTIFIER, "identifier"
    vk, type_size, w, h, depth, layers, faces, nlevels, scheme = struct.unpack_from("<9I", f, 12)
    want_model, _, _ = BASIS[codec]
    assert vk == 0, f"vkFormat {vk}: Basis Universal is VK_FORMAT_UNDEFINED"
    assert type_size == 1 and depth == 0 and layers == 0 and faces == 1 and nlevels == 1, "one 2D level"
    assert scheme == {"none": 0, "basislz": 1, "zstd": 2}[sc], f"supercompression scheme {scheme}"
    dfd_off, dfd_len, _, _ = struct.unpack_from("<4I", f, 48)
    sgd_off, sgd_len = struct.unpack_from("<2Q", f, 64)
    assert (sgd_len > 0 and sgd_off % 8 == 0) if codec == "etc1s" else sgd_len == 0, "global data for BasisLZ only"
    model, primaries, got_transfer, flags = f[dfd_off + 12 : dfd_off + 16]
    want = (want_model, 1, transfer, 0)
    assert (model, primaries, got_transfer, flags) == want, f"model {model}, BT.709, transfer {transfer}, straight alpha"
    assert tuple(f[dfd_off + 16 : dfd_off + 18]) == (3, 3), "4×4 blocks"
    assert f[dfd_off + 20] == (16 if codec == "uastc" else 0), "bytesPlane0"
    info = alktx2.inspect_ktx2(f)
    assert info["basis_tex_format_name"] == BASIS_NAMES[codec], info["basis_tex_format_name"]
    assert info["is_srgb"] == (transfer == SRGB), f"alktx2 reads is_srgb {info['is_srgb']}"
    assert (info["width"], info["height"]) == (w, h), "alktx2 reads the same size"
    tga, _ = alktx2.decode_ktx2_to_bytes(f, format="tga")
    return w, h, tga_rgba(tga, info["has_alpha"])


def tga_rgba(t, alpha):
    """RGBA8 rows, top first, of an uncompressed 24- or 32-bit TGA."""
    id_len, _, kind = t[0], t[1], t[2]
    w, h, bpp, desc = struct.unpack_from("<HHBB", t, 12)
    assert kind == 2 and bpp in (24, 32), f"uncompressed true-colour TGA, {bpp} bits"
    n = bpp // 8
    px = t[18 + id_len : 18 + id_len + w * h * n]
    rows = [px[y * w * n : (y + 1) * w * n] for y in range(h)]
    if not desc & 0x20:
        rows.reverse()
    out = bytearray(w * h * 4)
    for y, row in enumerate(rows):
        o = out[y * w * 4 : (y + 1) * w * 4]
        o[0::4], o[1::4], o[2::4] = row[2::n], row[1::n], row[0::n]
        o[3::4] = row[3::n] if n == 4 else bytes([255]) * w
        out[y * w * 4 : (y + 1) * w * 4] = o
    return bytes(out)


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


def check_normals(base, textures, check):
    """Normal-layer pages (page 0/1/1 of every demo) in each KTX2 codec that takes them (etc1s
    refuses them): linear transfer, the
    _UNORM vkFormats, alktx2 reading them as linear, texels near the raw RGBA normal page —
    each page over its codec's floor, and over all demos nearer than the flat normal
    (128, 128, 255) is by NORMAL_FLAT_MARGIN_DB. Returns the PSNR over all demos per codec,
    the flat normal's included."""
    sums = {}
    q = f"size={SIZE}&border={BORDER}&layer=normal"
    for t in textures:
        page = f"/api/v1/textures/{t['id']}/pages/0/1/1"
        rgba = get(base, f"{page}.rgba?{q}")
        candidates = {"flat": bytes([128, 128, 255, 255]) * (len(rgba) // 4)}
        for codec in ("bc7", "bc1", "rgba8", "uastc"):
            f = get(base, f"{page}.ktx2?{q}&codec={codec}")
            try:
                if codec in BASIS:
                    _, _, candidates[codec] = parse_basis(f, codec, "none", LINEAR)
                else:
                    ((_, _, candidates[codec]),) = parse_ktx2(f, codec, LINEAR)
            except AssertionError as e:
                check(False, f"{t['name']} normal {codec}: {e}")
        for codec, texels in candidates.items():
            se, n = squared_error(texels, rgba)
            a, b = sums.get(codec, (0, 0))
            sums[codec] = (a + se, b + n)
            db = psnr(se, n)
            floor = NORMAL_FLOOR_DB.get(codec, 0)
            check(db >= floor, f"{t['name']} normal {codec}: {db:.2f} dB < {floor} dB")
    db = {c: psnr(*v) for c, v in sums.items()}
    for codec in db:
        if codec != "flat":
            margin = db[codec] - db["flat"]
            check(margin >= NORMAL_FLAT_MARGIN_DB, f"normal {codec}: {margin:.2f} dB over the flat normal")
    return db


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
            table = []
            for t in textures:
                tid = t["id"]
                sums = {}
                sizes = {}
                for level, px, py in [(0, 1, 1), (3, 0, 0)]:
                    q = f"size={SIZE}&border={BORDER}"
                    page = f"/api/v1/textures/{tid}/pages/{level}/{px}/{py}"
                    rgba = get(base, f"{page}.rgba?{q}")
                    jpg = get(base, f"{page}.jpg?{q}")
                    sizes["jpg"] = sizes.get("jpg", 0) + len(jpg)
                    se, n = squared_error(Image.open(io.BytesIO(jpg)).convert("RGBA").tobytes(), rgba)
                    a, b = sums.get("jpg", (0, 0))
                    sums["jpg"] = (a + se, b + n)
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
                            sizes[f"{codec}/{sc}"] = sizes.get(f"{codec}/{sc}", 0) + len(f)
                            if sc == "none":
                                se, n = squared_error(texels, rgba)
                                a, b = sums.get(codec, (0, 0))
                                sums[codec] = (a + se, b + n)
                            else:
                                check(texels == plain_texels, f"{t['name']} {codec}: zstd holds the same blocks")
                            plain_texels = texels
                    for codec, (_, schemes, _) in BASIS.items():
                        for sc in schemes:
                            f = get(base, f"{page}.ktx2?{q}&codec={codec}&supercompression={sc}")
                            try:
                                w, h, texels = parse_basis(f, codec, sc)
                            except AssertionError as e:
                                check(False, f"{t['name']} {codec}/{sc}: {e}")
                                continue
                            check((w, h) == (SIZE + 2 * BORDER,) * 2, f"{t['name']} {codec}/{sc}: size {w}×{h}")
                            sizes[f"{codec}/{sc}"] = sizes.get(f"{codec}/{sc}", 0) + len(f)
                            se, n = squared_error(texels, rgba)
                            a, b = sums.get(f"{codec}/{sc}", (0, 0))
                            sums[f"{codec}/{sc}"] = (a + se, b + n)
                db = {c: psnr(*sums[c]) for c in sums}
                floors = dict(FLOOR_DB)
                for codec, (_, schemes, floor) in BASIS.items():
                    floors.update({f"{codec}/{sc}": floor for sc in schemes})
                for c, floor in floors.items():
                    db.setdefault(c, float("nan"))
                    check(db[c] >= floor, f"{t['name']} {c}: {db[c]:.2f} dB < {floor} dB")
                rows.append((t["name"], t["model"], db["bc7"], db["bc1"], db["uastc/none"], db["etc1s/basislz"]))
                table.append((t["name"], t["model"], db, sizes))

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
            normal_db = check_normals(base, textures, check)
        finally:
            proc.terminate()
            proc.wait()

    fmt = lambda v: "∞" if v == float("inf") else f"{v:.2f}"
    # PSNR (dB) and bytes of both pages, per codec: KTX2 without supercompression but ETC1S's
    # BasisLZ, UASTC with zstd beside it, and the JPEG page.
    columns = [("BC7", "bc7/none", "bc7"), ("BC1", "bc1/none", "bc1"), ("UASTC", "uastc/none", "uastc/none"),
               ("UASTC+zstd", "uastc/zstd", None), ("ETC1S", "etc1s/basislz", "etc1s/basislz"), ("JPEG", "jpg", "jpg")]
    if markdown:
        head = " | ".join(f"{c} dB | {c} bytes" if k else f"{c} bytes" for c, _, k in columns)
        print(f"| demo | model | {head} |")
        print("|---|---|" + "---|" * sum(2 if k else 1 for _, _, k in columns))
    for name, model, db, sizes in table:
        cells = [f"{fmt(db[k])} | {sizes[b]}" if k else f"{sizes[b]}" for _, b, k in columns]
        print(f"| {name} | {model} | {' | '.join(cells)} |" if markdown else f"{' '.join(cells)}  {name}")
    totals = {b: sum(sz[b] for _, _, _, sz in table) for _, b, _ in columns}
    print("\nbytes over all demos: " + ", ".join(f"{c} {totals[b]}" for c, b, _ in columns))
    bc7 = [r[2] for r in rows]
    bc1 = [r[3] for r in rows]
    print(f"\n{len(rows)} demos, pages 0/1/1 and 3/0/0 of {SIZE}² + {BORDER} px borders:")
    for c, values in (("BC7", bc7), ("BC1", bc1)):
        target = TARGET_DB[c.lower()]
        met = sum(v >= target for v in values)
        median = sorted(values)[len(values) // 2]
        print(f"{c}: min {fmt(min(values))} dB, median {fmt(median)} dB; {met} of {len(values)} at or over {target:g} dB")
    for c, i in (("UASTC", 4), ("ETC1S", 5)):
        values = sorted(r[i] for r in rows)
        print(f"{c} (alktx2's transcoder): min {fmt(values[0])} dB, median {fmt(values[len(values) // 2])} dB")
    print(f"mip chain of {small['name']} ({len(levels)} levels, BC7 + zstd): min {fmt(min(chain_db))} dB")
    print("normal pages 0/1/1, PSNR over all demos: " + ", ".join(f"{c} {fmt(v)} dB" for c, v in normal_db.items()))
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
