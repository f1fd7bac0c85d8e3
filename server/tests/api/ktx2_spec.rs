//! KTX2 files as the KTX 2.0 specification reads them. Every variant vtex serves — each codec,
//! with and without zstd supercompression, single pages (block-aligned and not) and whole mip
//! chains down to 1×1, colour (sRGB) and normals (linear) — is walked against the layout rules of
//! the specification's text, section by section, and read by the `ktx2` crate, a reader no one
//! here wrote.

use crate::support::*;

/// A served KTX2 file and the URL it came from.
struct File {
    url: String,
    bytes: Vec<u8>,
}

/// Every variant: pages of each codec and supercompression (136 px, a multiple of 4; 70 px,
/// not one), and mip chains from level 0 (240 px, so 15, 7, 3 and 1 px levels are partial
/// blocks) and from level 2; a normal page and a normal chain of each but ETC1S, which refuses
/// normals. ETC1S is always BasisLZ.
async fn variants() -> (Server, Vec<File>) {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(24, 10, 5)).await;
    let mut paths = Vec::new();
    for codec in ["bc7", "bc1", "rgba8", "uastc", "etc1s"] {
        let schemes: &[&str] = if codec == "etc1s" { &["basislz"] } else { &["none", "zstd"] };
        for &sc in schemes {
            let q = format!("codec={codec}&supercompression={sc}");
            paths.push(format!("pages/0/1/0.ktx2?size=128&border=4&{q}"));
            paths.push(format!("pages/3/0/0.ktx2?size=64&border={}&{q}", if codec == "rgba8" { 3 } else { 2 }));
            paths.push(format!("mips.ktx2?{q}"));
            paths.push(format!("mips.ktx2?level=2&{q}"));
            if codec != "etc1s" {
                paths.push(format!("pages/0/1/0.ktx2?size=128&border=4&layer=normal&{q}"));
                paths.push(format!("mips.ktx2?level=2&layer=normal&{q}"));
            }
        }
    }
    let mut files = Vec::new();
    for p in paths {
        let url = s.url(&format!("/api/v1/textures/{id}/{p}"));
        let (status, _, bytes) = get_bytes(&c, &url).await;
        assert_eq!(status, 200, "{url}: {}", String::from_utf8_lossy(&bytes));
        files.push(File { url, bytes });
    }
    std::mem::forget(dir);
    (s, files)
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    b.get(i..i + 4).map_or(0, |s| u32::from_le_bytes(s.try_into().unwrap()))
}

fn u64_at(b: &[u8], i: usize) -> u64 {
    b.get(i..i + 8).map_or(0, |s| u64::from_le_bytes(s.try_into().unwrap()))
}

/// What the Khronos Data Format specification defines for a `vkFormat`: texel block size in
/// bytes and pixels, its colour model, and its samples (bit offset, bit length − 1, channel
/// with qualifiers, lower, upper).
struct FormatDef {
    name: &'static str,
    /// The DFD's transferFunction the format requires: KHR_DF_TRANSFER_SRGB (2) for `_SRGB`
    /// formats, KHR_DF_TRANSFER_LINEAR (1) for the others; `None` for Basis Universal, which
    /// carries either.
    transfer: Option<u8>,
    block_bytes: usize,
    /// bytesPlane0: 0 for BasisLZ, whose slices have no fixed size.
    plane0: usize,
    block_side: u32,
    color_model: u8,
    samples: &'static [(u16, u8, u8, u32, u32)],
}

/// The format of a file: its `vkFormat`, or for `VK_FORMAT_UNDEFINED` the Basis Universal format
/// its DFD's colour model names (`model`), with alpha when its samples say so (`dfd_block_size`,
/// the sample's channel `channel0`).
fn format_def(vk_format: u32, model: u8, dfd_block_size: usize, channel0: u8) -> Option<FormatDef> {
    Some(match vk_format {
        // KTX 2.0, "Basis Universal": vkFormat undefined, the format in the DFD.
        0 if model == 166 => FormatDef {
            name: "UASTC (KHR_DF_MODEL_UASTC)",
            transfer: None,
            block_bytes: 16,
            plane0: 16,
            block_side: 4,
            color_model: 166,
            // KHR_DF_CHANNEL_UASTC_RGB (0) or _RGBA (3).
            samples: if channel0 == 3 { &[(0, 127, 3, 0, u32::MAX)] } else { &[(0, 127, 0, 0, u32::MAX)] },
        },
        0 if model == 163 => FormatDef {
            name: "ETC1S (KHR_DF_MODEL_ETC1S)",
            transfer: None,
            block_bytes: 8,
            plane0: 0,
            block_side: 4,
            color_model: 163,
            // KHR_DF_CHANNEL_ETC1S_RGB (0), then KHR_DF_CHANNEL_ETC1S_AAA (15) with alpha.
            samples: if dfd_block_size == 24 + 32 {
                &[(0, 63, 0, 0, u32::MAX), (64, 63, 15, 0, u32::MAX)]
            } else {
                &[(0, 63, 0, 0, u32::MAX)]
            },
        },
        146 | 145 => FormatDef {
            name: if vk_format == 146 { "VK_FORMAT_BC7_SRGB_BLOCK" } else { "VK_FORMAT_BC7_UNORM_BLOCK" },
            transfer: Some(if vk_format == 146 { 2 } else { 1 }),
            block_bytes: 16,
            plane0: 16,
            block_side: 4,
            color_model: 134, // KHR_DF_MODEL_BC7
            samples: &[(0, 127, 0, 0, u32::MAX)],
        },
        132 | 131 => FormatDef {
            name: if vk_format == 132 { "VK_FORMAT_BC1_RGB_SRGB_BLOCK" } else { "VK_FORMAT_BC1_RGB_UNORM_BLOCK" },
            transfer: Some(if vk_format == 132 { 2 } else { 1 }),
            block_bytes: 8,
            plane0: 8,
            block_side: 4,
            color_model: 128, // KHR_DF_MODEL_BC1A, channel 0 = COLOR
            samples: &[(0, 63, 0, 0, u32::MAX)],
        },
        43 => FormatDef {
            name: "VK_FORMAT_R8G8B8A8_SRGB",
            transfer: Some(2),
            block_bytes: 4,
            plane0: 4,
            block_side: 1,
            color_model: 1, // KHR_DF_MODEL_RGBSDA: R, G, B, then A (15) marked LINEAR (0x10)
            samples: &[(0, 7, 0, 0, 255), (8, 7, 1, 0, 255), (16, 7, 2, 0, 255), (24, 7, 0x1F, 0, 255)],
        },
        37 => FormatDef {
            name: "VK_FORMAT_R8G8B8A8_UNORM",
            transfer: Some(1),
            block_bytes: 4,
            plane0: 4,
            block_side: 1,
            color_model: 1, // KHR_DF_MODEL_RGBSDA: R, G, B, A (15), all linear
            samples: &[(0, 7, 0, 0, 255), (8, 7, 1, 0, 255), (16, 7, 2, 0, 255), (24, 7, 0x0F, 0, 255)],
        },
        _ => return None,
    })
}

/// The keys this version of the specification defines ("keyAndValue": other keys starting
/// with `KTX` or `ktx` are reserved).
const DEFINED_KEYS: [&str; 10] = [
    "KTXcubemapIncomplete",
    "KTXorientation",
    "KTXglFormat",
    "KTXdxgiFormat__",
    "KTXmetalPixelFormat",
    "KTXswizzle",
    "KTXwriter",
    "KTXwriterScParams",
    "KTXastcDecodeMode",
    "KTXanimData",
];

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Every layout rule of the KTX 2.0 specification `f` breaks, each named by its section.
fn violations(f: &[u8]) -> Vec<String> {
    let mut bad = Vec::new();
    let mut rule = |ok: bool, what: String| {
        if !ok {
            bad.push(what);
        }
    };
    const IDENTIFIER: [u8; 12] = [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A];
    if f.len() < 80 || f[..12] != IDENTIFIER {
        return vec!["File Structure: a 12-byte identifier, a 36-byte header and a 32-byte index".into()];
    }
    let h: Vec<u32> = (0..9).map(|i| u32_at(f, 12 + 4 * i)).collect();
    let [vk_format, type_size, width, height, depth, layers, faces, level_count, scheme] = h[..] else {
        unreachable!()
    };
    let dfd_at = u32_at(f, 48) as usize;
    let model = f.get(dfd_at + 12).copied().unwrap_or(0);
    let (dfd_block, channel0) =
        ((u32_at(f, dfd_at + 8) >> 16) as usize, f.get(dfd_at + 4 + 24 + 3).copied().unwrap_or(0));
    let Some(def) = format_def(vk_format, model, dfd_block, channel0) else {
        return vec![format!("vkFormat: {vk_format} (colour model {model}) is not a format vtex writes")];
    };
    let basislz = def.color_model == 163;
    // Header fields.
    rule(type_size == 1, format!("typeSize: must be 1 for {} (got {type_size})", def.name));
    rule(width > 0, "pixelWidth: must not be 0".into());
    rule(height > 0, "pixelHeight: must not be 0 for block-compressed formats (and 2D textures)".into());
    rule(
        depth == 0 && layers == 0 && faces == 1,
        format!("Texture Type: 2D is depth 0, layers 0, faces 1 (got {depth}, {layers}, {faces})"),
    );
    let max_level = 31 - width.max(height).max(1).leading_zeros();
    rule(level_count >= 1, "levelCount: 0 is not allowed for block-compressed formats; vtex writes its levels".into());
    rule(
        level_count <= max_level + 1,
        format!("levelCount: level {} exceeds the maximum level {max_level}", level_count.saturating_sub(1)),
    );
    if basislz {
        rule(scheme == 1, format!("supercompressionScheme: ETC1S is BasisLZ (1), got {scheme}"));
    } else {
        rule(
            scheme == 0 || scheme == 2,
            format!("supercompressionScheme: vtex writes 0 or 2 (Zstandard), got {scheme}"),
        );
    }
    let levels = level_count.max(1) as usize;
    // Index.
    let (dfd_off, dfd_len, kvd_off, kvd_len) =
        (u32_at(f, 48) as usize, u32_at(f, 52) as usize, u32_at(f, 56) as usize, u32_at(f, 60) as usize);
    let (sgd_off, sgd_len) = (u64_at(f, 64), u64_at(f, 72));
    let level_index_end = 80 + 24 * levels;
    rule(
        dfd_off == level_index_end,
        format!("dfdByteOffset: the DFD follows the level index at {level_index_end} (got {dfd_off})"),
    );
    if basislz {
        rule(sgd_len > 0, "sgdByteLength: BasisLZ has global data".into());
        rule(sgd_off % 8 == 0, format!("sgdByteOffset: BasisLZ global data aligned to 8 bytes (got {sgd_off})"));
    } else {
        rule(sgd_len == 0, "sgdByteLength: must be 0 for schemes with no global data (none, Zstandard)".into());
    }
    rule(sgd_len > 0 || sgd_off == 0, "sgdByteOffset: must be 0 when sgdByteLength is 0".into());
    rule(kvd_len > 0 || kvd_off == 0, "kvdByteOffset: must be 0 when kvdByteLength is 0".into());
    // Data Format Descriptor: one basic descriptor block (Khronos Data Format).
    let dfd_total = u32_at(f, dfd_off) as usize;
    rule(dfd_len == dfd_total, format!("dfdByteLength: must equal dfdTotalSize ({dfd_len} ≠ {dfd_total})"));
    if kvd_len > 0 {
        rule(dfd_total == kvd_off - dfd_off, "dfdTotalSize: must equal kvdByteOffset − dfdByteOffset".into());
    }
    let b = dfd_off + 4;
    let (vendor_type, version_size) = (u32_at(f, b), u32_at(f, b + 4));
    let (version, block_size) = (version_size & 0xFFFF, (version_size >> 16) as usize);
    rule(vendor_type == 0, "dfdBlock: vendorId 0 (Khronos) and descriptorType 0 (basic)".into());
    rule(version == 2, format!("dfdBlock: versionNumber 2 (Data Format 1.3), got {version}"));
    rule(block_size % 4 == 0, "dfdBlock: descriptor_block_size is a multiple of 4".into());
    rule(4 + block_size == dfd_total, "dfdTotalSize: one descriptor block, and nothing after it".into());
    let byte = |i: usize| f.get(b + i).copied().unwrap_or(0);
    rule(
        byte(8) == def.color_model,
        format!("DFD Restrictions: colorModel {} for {} (got {})", def.color_model, def.name, byte(8)),
    );
    match def.transfer {
        Some(t) => {
            rule(byte(10) == t, format!("DFD Restrictions: transferFunction {t} for {} (got {})", def.name, byte(10)))
        }
        None => rule(
            matches!(byte(10), 1 | 2),
            format!("DFD: transferFunction KHR_DF_TRANSFER_LINEAR or _SRGB for {} (got {})", def.name, byte(10)),
        ),
    }
    rule(byte(11) == 0, "DFD: flags KHR_DF_FLAG_ALPHA_STRAIGHT (vtex's alpha is not premultiplied)".into());
    let dim = (def.block_side - 1) as u8;
    rule(
        [byte(12), byte(13), byte(14), byte(15)] == [dim, dim, 0, 0],
        format!("DFD Restrictions: texelBlockDimension of {}", def.name),
    );
    let planes: Vec<u8> = (16..24).map(byte).collect();
    rule(
        planes[0] as usize == def.plane0 && planes[1..].iter().all(|&p| p == 0),
        format!("DFD Restrictions: bytesPlane0 = {} for {}", def.plane0, def.name),
    );
    rule(
        block_size == 24 + 16 * def.samples.len(),
        format!("DFD Restrictions: {} samples for {}", def.samples.len(), def.name),
    );
    for (i, &(offset, len, channel, lower, upper)) in def.samples.iter().enumerate() {
        let s = b + 24 + 16 * i;
        let got = (
            u32_at(f, s) as u16,
            f.get(s + 2).copied().unwrap_or(0),
            f.get(s + 3).copied().unwrap_or(0),
            u32_at(f, s + 8),
            u32_at(f, s + 12),
        );
        rule(
            got == (offset, len, channel, lower, upper),
            format!(
                "DFD Restrictions: sample {i} of {} is {:?}, got {got:?}",
                def.name,
                (offset, len, channel, lower, upper)
            ),
        );
        rule(u32_at(f, s + 4) == 0, format!("DFD: sample {i}'s samplePosition is 0 for a block-sized sample"));
    }
    // Key/Value Data.
    let mut at = kvd_off;
    let (mut count, mut keys) = (0, Vec::<String>::new());
    while at < kvd_off + kvd_len && at + 4 <= f.len() {
        let n = u32_at(f, at) as usize;
        rule(n >= 2, format!("keyAndValueByteLength: at least 2 (got {n})"));
        let Some(kv) = f.get(at + 4..at + 4 + n) else {
            rule(false, "keyAndValue: runs past the end of the file".into());
            break;
        };
        let Some(nul) = kv.iter().position(|&c| c == 0) else {
            rule(false, "keyAndValue: the key must be terminated by a NUL".into());
            break;
        };
        match std::str::from_utf8(&kv[..nul]) {
            Ok(key) => {
                rule(!key.starts_with('\u{FEFF}'), "keyAndValue: key without a byte order mark".into());
                let reserved = key.starts_with("KTX") || key.starts_with("ktx");
                rule(
                    !reserved || DEFINED_KEYS.contains(&key),
                    format!("keyAndValue: `{key}` is a reserved key this specification does not define"),
                );
                if key == "KTXwriter" {
                    let value = &kv[nul + 1..];
                    rule(
                        value.last() == Some(&0) && std::str::from_utf8(&value[..value.len() - 1]).is_ok(),
                        "KTXwriter: a NUL-terminated UTF-8 string".into(),
                    );
                }
                keys.push(key.to_string());
            }
            Err(_) => rule(false, "keyAndValue: the key is UTF-8".into()),
        }
        let padded = (at + 4 + n).next_multiple_of(4);
        rule(
            f.get(at + 4 + n..padded).is_some_and(|p| p.iter().all(|&z| z == 0)),
            "valuePadding: 0 to 3 bytes of 0x00".into(),
        );
        at = padded;
        count += 1;
    }
    let counted = at - kvd_off;
    rule(
        counted == kvd_len,
        format!("kvdByteLength: Σ ⌈keyAndValueByteLength/4⌉·4 + 4n = {counted} for {count} pairs, not {kvd_len}"),
    );
    rule(keys.windows(2).all(|w| w[0] < w[1]), "Key/Value Data: sorted by the keys' code points, no key twice".into());
    // Mip Level Array and Level Index: smallest level first, each after the
    // minimal mipPadding of zeros, every byte of the file accounted for.
    let align = if scheme == 0 { def.block_bytes * 4 / gcd(def.block_bytes, 4) } else { 1 };
    let mut end = kvd_off + kvd_len;
    // BasisLZ Global Data: after the key/value data and zeros to 8 bytes, a header (endpoint and
    // selector counts, four byte lengths), one image descriptor a level (flags, then offset and
    // length of its colour slice and of its alpha slice in the level), then the four sections.
    let sgd = f.get(sgd_off as usize..(sgd_off + sgd_len) as usize).unwrap_or(&[]);
    if basislz {
        rule(
            f.get(end..sgd_off as usize).is_some_and(|pad| pad.iter().all(|&z| z == 0)) && sgd_off as usize - end < 8,
            "sgdPadding: 0 to 7 bytes of 0x00 before the global data".into(),
        );
        let sections: usize = (0..4).map(|i| u32_at(sgd, 4 + 4 * i) as usize).sum();
        rule(
            sgd.len() == 20 + 20 * levels + sections,
            format!("BasisLZ Global Data: 20 + 20 × {levels} images + {sections} bytes of sections, got {}", sgd.len()),
        );
        end = (sgd_off + sgd_len) as usize;
    }
    for p in (0..levels).rev() {
        let e = 80 + 24 * p;
        let (off, len, raw) = (u64_at(f, e) as usize, u64_at(f, e + 8) as usize, u64_at(f, e + 16) as usize);
        let start = end.next_multiple_of(align);
        rule(
            off == start,
            format!("mipPadding: level {p} starts at the next {align}-byte boundary, {start} (got {off})"),
        );
        rule(
            f.get(end..off.min(f.len())).is_some_and(|pad| pad.iter().all(|&z| z == 0)),
            format!("mipPadding: before level {p}, bytes of 0x00"),
        );
        if basislz {
            // The image descriptor of level p: its slices fill the level, colour first.
            let d = 20 + 20 * p;
            let (flags, rgb_off, rgb_len) = (u32_at(sgd, d), u32_at(sgd, d + 4) as usize, u32_at(sgd, d + 8) as usize);
            let (a_off, a_len) = (u32_at(sgd, d + 12) as usize, u32_at(sgd, d + 16) as usize);
            rule(flags == 0, format!("imageFlags: level {p} of a still texture is no P-frame"));
            rule(raw == 0, format!("levels[{p}].uncompressedByteLength: 0 for BasisLZ (got {raw})"));
            let two = def.samples.len() == 2;
            rule(
                rgb_off == 0 && rgb_len > 0 && (!two || (a_off == rgb_len && a_len > 0)) && (two || a_off + a_len == 0),
                format!("imageDescs[{p}]: the colour slice, then the alpha slice when the DFD has an AAA sample"),
            );
            rule(rgb_len + a_len == len, format!("imageDescs[{p}]: the slices fill levels[{p}] ({len} bytes)"));
            end = off + len;
            continue;
        }
        let side = |px: u32| ((px >> p).max(1)).div_ceil(def.block_side) as usize;
        let expect = side(width) * side(height) * def.block_bytes;
        rule(
            raw == expect,
            format!(
                "levels[{p}].uncompressedByteLength: num_blocks_x × num_blocks_y × {} = {expect} (got {raw})",
                def.block_bytes
            ),
        );
        match scheme {
            0 => rule(
                len == raw,
                format!("levels[{p}].byteLength: equals uncompressedByteLength without supercompression"),
            ),
            _ => match f.get(off..off + len).map(|z| zstd::bulk::decompress(z, raw + 1)) {
                Some(Ok(inflated)) => {
                    rule(inflated.len() == raw, format!("Zstandard: level {p} inflates to uncompressedByteLength"))
                }
                _ => rule(false, format!("Zstandard: level {p} is one zstd frame")),
            },
        }
        end = off + len;
    }
    rule(
        end == f.len(),
        format!("levels[0]: the largest level ends the file ({} bytes past it)", f.len() as i64 - end as i64),
    );
    bad
}

/// Every variant satisfies every rule.
#[tokio::test]
async fn every_variant_follows_the_specification() {
    let (_s, files) = variants().await;
    let mut failures = Vec::new();
    for file in &files {
        for v in violations(&file.bytes) {
            failures.push(format!("{}: {v}", file.url));
        }
    }
    assert!(failures.is_empty(), "{} rules broken:\n{}", failures.len(), failures.join("\n"));
}

/// The `ktx2` crate reads every variant: its header, every level's bytes where the index puts
/// them, the DFD's colour model and transfer function, and the writer's key.
#[tokio::test]
async fn the_ktx2_crate_reads_every_variant() {
    let (_s, files) = variants().await;
    for file in &files {
        let r = ktx2::Reader::new(&file.bytes[..]).unwrap_or_else(|e| panic!("{}: {e:?}", file.url));
        let h = r.header();
        let blocks: Vec<_> = r.dfd_blocks().collect();
        assert_eq!(blocks.len(), 1, "{}: one descriptor block", file.url);
        let basic = ktx2::DfdBlockBasic::parse(blocks[0].data).expect("a basic descriptor block");
        let model = basic.header.color_model.map_or(0, |m| m.value());
        let first: Vec<_> = basic.sample_information().map(|s| s.channel_type).collect();
        // vkFormat undefined (the crate's None) for Basis Universal, named by the DFD.
        let vk = h.format.map_or(0, |f| f.value());
        let def = format_def(vk, model, 24 + 16 * first.len(), first.first().copied().unwrap_or(0))
            .expect("a format vtex writes");
        assert_eq!((h.type_size, h.pixel_depth, h.layer_count, h.face_count), (1, 0, 0, 1), "{}", file.url);
        let levels: Vec<_> = r.levels().collect();
        assert_eq!(levels.len(), h.level_count as usize, "{}", file.url);
        for (p, level) in levels.iter().enumerate() {
            let side = |px: u32| ((px >> p).max(1)).div_ceil(def.block_side) as u64;
            let want = side(h.pixel_width) * side(h.pixel_height) * def.block_bytes as u64;
            if h.supercompression_scheme == Some(ktx2::SupercompressionScheme::BasisLZ) {
                assert_eq!(level.uncompressed_byte_length, 0, "{} level {p}: BasisLZ", file.url);
                assert!(!level.data.is_empty(), "{} level {p}", file.url);
                continue;
            }
            assert_eq!(level.uncompressed_byte_length, want, "{} level {p}", file.url);
            let raw = match h.supercompression_scheme {
                None => level.data.to_vec(),
                Some(ktx2::SupercompressionScheme::Zstandard) => {
                    zstd::bulk::decompress(level.data, want as usize).unwrap()
                }
                Some(other) => panic!("{}: unexpected scheme {other:?}", file.url),
            };
            assert_eq!(raw.len() as u64, want, "{} level {p}", file.url);
        }
        assert_eq!(basic.header.color_model.map(|m| m.value()), Some(def.color_model), "{}", file.url);
        // Colour is sRGB-encoded; normals are linear data.
        let transfer = if file.url.contains("layer=normal") {
            ktx2::TransferFunction::Linear
        } else {
            ktx2::TransferFunction::SRGB
        };
        assert_eq!(basic.header.transfer_function, Some(transfer), "{}", file.url);
        let dim = def.block_side as u8;
        assert_eq!(basic.header.texel_block_dimensions.map(|d| d.get()), [dim, dim, 1, 1], "{}", file.url);
        let samples: Vec<_> = basic
            .sample_information()
            .map(|s| {
                (
                    s.bit_offset,
                    s.bit_length.get() - 1,
                    s.channel_type | s.channel_type_qualifiers.bits() << 4,
                    s.lower,
                    s.upper,
                )
            })
            .collect();
        assert_eq!(samples, def.samples, "{}", file.url);
        let kv: Vec<_> = r.key_value_data().collect();
        assert_eq!(kv.len(), 1, "{}: the key/value data holds exactly the writer's key", file.url);
        assert_eq!(kv[0].0, "KTXwriter", "{}", file.url);
    }
}
