//! The batch body's frames (`application/x-vtex-tile-batch`, docs/server.md): a 32-byte
//! little-endian header, then the item's bytes or its `{"error": …}`.

use crate::Error;
use bytes::Bytes;

pub const HEADER_LEN: usize = 32;
const MAGIC: [u8; 4] = *b"vtb\x01";

/// One frame of a batch.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    pub level: u32,
    pub x: u32,
    pub y: u32,
    /// 200, or the HTTP status of this item's error.
    pub status: u16,
    /// The server's cache: 1 hit, 2 miss, 0 for an error.
    pub cache: u8,
    pub width: u32,
    pub height: u32,
    /// The item's bytes (exactly the single-item endpoint's body), or an error's JSON.
    pub body: Bytes,
}

/// Every frame of a complete batch body; a truncated body or a bad header is an error.
pub fn parse(body: &Bytes) -> Result<Vec<Frame>, Error> {
    let mut frames = Vec::new();
    let mut at = 0;
    while at < body.len() {
        let b = &body[at..];
        if b.len() < HEADER_LEN || b[..4] != MAGIC {
            return Err(Error::Protocol(format!("bad or truncated frame header at byte {at}")));
        }
        let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
        let len = u32_at(28) as usize;
        if b.len() < HEADER_LEN + len {
            return Err(Error::Protocol(format!("frame at byte {at} is cut off ({len} bytes announced)")));
        }
        frames.push(Frame {
            level: u32_at(4),
            x: u32_at(8),
            y: u32_at(12),
            status: u16::from_le_bytes([b[16], b[17]]),
            cache: b[18],
            width: u32_at(20),
            height: u32_at(24),
            body: body.slice(at + HEADER_LEN..at + HEADER_LEN + len),
        });
        at += HEADER_LEN + len;
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(level: u32, x: u32, y: u32, body: &[u8]) -> Vec<u8> {
        let mut h = MAGIC.to_vec();
        for v in [level, x, y] {
            h.extend_from_slice(&v.to_le_bytes());
        }
        h.extend_from_slice(&200u16.to_le_bytes());
        h.extend_from_slice(&[2, 0]);
        for v in [8u32, 8, body.len() as u32] {
            h.extend_from_slice(&v.to_le_bytes());
        }
        h.extend_from_slice(body);
        h
    }

    #[test]
    fn frames_in_sequence_and_truncation() {
        let body = Bytes::from([frame(0, 1, 2, b"abc"), frame(3, 4, 5, b"")].concat());
        let f = parse(&body).unwrap();
        assert_eq!((f[0].level, f[0].x, f[0].y, &f[0].body[..]), (0, 1, 2, &b"abc"[..]));
        assert_eq!((f[1].level, f[1].x, f[1].y, f[1].body.len(), f[1].cache), (3, 4, 5, 0, 2));
        assert!(parse(&body.slice(..body.len() - 1)).is_err());
        assert!(parse(&body.slice(..10)).is_err());
        let mut bad = body.to_vec();
        bad[3] = 2;
        assert!(parse(&Bytes::from(bad)).is_err(), "another version");
    }
}
