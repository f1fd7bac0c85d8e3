//! The frames ([`vtex_wire::frame`]) of a metatile's or a batch's body, each with its bytes as a
//! slice of the body.

use crate::{Error, PageAddr};
use bytes::Bytes;

/// One frame of a metatile or a batch.
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

impl Frame {
    /// The page (or tile) it holds.
    pub fn addr(&self) -> PageAddr {
        PageAddr { level: self.level, x: self.x, y: self.y }
    }
}

/// Every frame of a complete body; a truncated body or a bad header is an error.
pub fn parse(body: &Bytes) -> Result<Vec<Frame>, Error> {
    let frames = vtex_wire::frame::frames(body).map_err(Error::Protocol)?;
    Ok(frames
        .into_iter()
        .map(|(h, at)| Frame {
            level: h.tile.level,
            x: h.tile.x,
            y: h.tile.y,
            status: h.status,
            cache: h.cache,
            width: h.width,
            height: h.height,
            body: body.slice(at),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    fn fixture(name: &str) -> Vec<u8> {
        std::fs::read(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../wire/fixtures").join(name)).unwrap()
    }

    /// The golden batch the server's tests write: every frame as they list it, its bytes where
    /// they say, and a body cut anywhere refused.
    #[test]
    fn the_golden_batch_parses_as_the_server_lists_it() {
        let body = Bytes::from(fixture("batch.bin"));
        let want: Vec<Value> = serde_json::from_slice(&fixture("batch.json")).unwrap();
        let got = parse(&body).unwrap();
        assert_eq!(got.len(), want.len());
        for (f, w) in got.iter().zip(&want) {
            let field = |k: &str| w[k].as_u64().unwrap();
            assert_eq!(
                (f.level, f.x, f.y, f.status, f.cache, f.width, f.height),
                (
                    field("level") as u32,
                    field("x") as u32,
                    field("y") as u32,
                    field("status") as u16,
                    field("cache") as u8,
                    field("width") as u32,
                    field("height") as u32
                )
            );
            let at = field("body_offset") as usize;
            assert_eq!(f.body, body.slice(at..at + field("body_length") as usize));
        }
        for cut in [1, 31, 32, 100, body.len() - 1] {
            assert!(parse(&body.slice(..cut)).is_err(), "cut at {cut}");
        }
    }

    /// The golden texture info reads as the client's type, whole.
    #[test]
    fn the_golden_texture_info_reads() {
        let info: crate::TextureInfo = serde_json::from_slice(&fixture("texture-info.json")).unwrap();
        let json: Value = serde_json::from_slice(&fixture("texture-info.json")).unwrap();
        assert_eq!(serde_json::to_value(&info).unwrap(), json, "no field lost or added");
        assert_eq!((crate::page_levels(&info), crate::page_grid(&info, 0, 16)), (7, (4, 4)));
    }
}
