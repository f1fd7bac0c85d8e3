//! The tile batch body (`application/x-vtex-tile-batch`): a sequence of frames, each a 32-byte
//! little-endian header and then the item's bytes (exactly the single-item endpoint's body) or,
//! for an item that failed, its `{"error": …}` JSON.
//!
//! | bytes | field |
//! |---|---|
//! | 0–3 | magic `vtb` and the format version, 1 |
//! | 4–7, 8–11, 12–15 | level, x, y |
//! | 16–17 | HTTP status of the item: 200, or its error's |
//! | 18 | the server's cache: 1 hit, 2 miss, 0 error or not told (a metatile's frames) |
//! | 19 | 0 |
//! | 20–23, 24–27 | width, height of the image (0 for an error) |
//! | 28–31 | length of what follows |

use std::ops::Range;

/// First bytes of every frame: `vtb` and the format version.
pub const MAGIC: [u8; 4] = *b"vtb\x01";
pub const HEADER_LEN: usize = 32;
/// The media type of a batch body.
pub const CONTENT_TYPE: &str = "application/x-vtex-tile-batch";
/// Most items one batch may ask for (a 4K screen of 256-px tiles needs ~150).
pub const MAX_TILES: usize = 256;

/// One item as a batch names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TileRef {
    pub level: u32,
    pub x: u32,
    pub y: u32,
}

/// A frame header (the table above).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameHeader {
    pub tile: TileRef,
    pub status: u16,
    /// 1 hit, 2 miss, 0 error or not told.
    pub cache: u8,
    pub width: u32,
    pub height: u32,
    pub len: u32,
}

impl FrameHeader {
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        b[0..4].copy_from_slice(&MAGIC);
        b[4..8].copy_from_slice(&self.tile.level.to_le_bytes());
        b[8..12].copy_from_slice(&self.tile.x.to_le_bytes());
        b[12..16].copy_from_slice(&self.tile.y.to_le_bytes());
        b[16..18].copy_from_slice(&self.status.to_le_bytes());
        b[18] = self.cache;
        b[20..24].copy_from_slice(&self.width.to_le_bytes());
        b[24..28].copy_from_slice(&self.height.to_le_bytes());
        b[28..32].copy_from_slice(&self.len.to_le_bytes());
        b
    }

    /// The header at the start of `b`, or `None` when `b` is short or the magic is wrong.
    pub fn decode(b: &[u8]) -> Option<FrameHeader> {
        if b.len() < HEADER_LEN || b[0..4] != MAGIC {
            return None;
        }
        let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
        Some(FrameHeader {
            tile: TileRef { level: u32_at(4), x: u32_at(8), y: u32_at(12) },
            status: u16::from_le_bytes([b[16], b[17]]),
            cache: b[18],
            width: u32_at(20),
            height: u32_at(24),
            len: u32_at(28),
        })
    }
}

/// Every frame of a complete batch body: its header and where its bytes are in `body`. A bad
/// header or a body cut short is an error naming the byte where it happens.
pub fn frames(body: &[u8]) -> Result<Vec<(FrameHeader, Range<usize>)>, String> {
    let mut out = Vec::new();
    let mut at = 0;
    while at < body.len() {
        let header =
            FrameHeader::decode(&body[at..]).ok_or_else(|| format!("bad or truncated frame header at byte {at}"))?;
        let start = at + HEADER_LEN;
        let end = start + header.len as usize;
        if end > body.len() {
            return Err(format!("frame at byte {at} is cut off ({} bytes announced)", header.len));
        }
        out.push((header, start..end));
        at = end;
    }
    Ok(out)
}

/// Frame `index` (from 0) of a body of whole frames, without reading the ones after it;
/// `None` when the body has fewer or a bad header comes first.
pub fn frame_at(body: &[u8], index: usize) -> Option<(FrameHeader, Range<usize>)> {
    let mut at = 0;
    for i in 0..=index {
        let header = FrameHeader::decode(body.get(at..)?)?;
        let start = at + HEADER_LEN;
        let end = start.checked_add(header.len as usize).filter(|&end| end <= body.len())?;
        if i == index {
            return Some((header, start..end));
        }
        at = end;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(level: u32, x: u32, y: u32, body: &[u8]) -> Vec<u8> {
        let tile = TileRef { level, x, y };
        let h = FrameHeader { tile, status: 200, cache: 2, width: 8, height: 8, len: body.len() as u32 };
        [&h.encode()[..], body].concat()
    }

    #[test]
    fn frames_in_sequence_and_truncation() {
        let body = [frame(0, 1, 2, b"abc"), frame(3, 4, 5, b"")].concat();
        let f = frames(&body).unwrap();
        assert_eq!((f[0].0.tile, &body[f[0].1.clone()]), (TileRef { level: 0, x: 1, y: 2 }, &b"abc"[..]));
        assert_eq!((f[1].0.tile, f[1].1.len(), f[1].0.cache), (TileRef { level: 3, x: 4, y: 5 }, 0, 2));
        assert_eq!(frame_at(&body, 1), Some(f[1].clone()));
        assert_eq!(frame_at(&body, 0), Some(f[0].clone()));
        assert_eq!(frame_at(&body, 2), None);
        assert_eq!(frame_at(&body[..body.len() - 1], 1), None, "a cut header");
        assert_eq!(frame_at(&body[..34], 0), None, "cut inside the first body");
        assert!(frames(&body[..body.len() - 1]).is_err());
        assert!(frames(&body[..10]).is_err());
        let mut bad = body.clone();
        bad[3] = 2;
        assert!(frames(&bad).is_err(), "another version");
    }

    #[test]
    fn a_header_decodes_to_what_was_encoded() {
        let h = FrameHeader {
            tile: TileRef { level: 7, x: 70_000, y: 3 },
            status: 503,
            cache: 0,
            width: 0,
            height: 0,
            len: 61,
        };
        assert_eq!(FrameHeader::decode(&h.encode()), Some(h));
    }
}
