//! How an LCM section stores its event bytes: one a point (`raw`), or with §6's coding of the
//! "no replication" zeros (`zeros`): "LCMs generated according to event tables Tab. 1 or
//! Tab. 3 have many regularly structured zero entries, thus they can be coded in a way which
//! can reduce the size of LCM representation approximately twice or even more".
//!
//! The event table says where the zeros are. A point whose cell never replicates stores
//! nothing (the staggered zeros of Tab. 1 and Tab. 3); one whose cell always replicates stores
//! its code; one whose cell may or may not stores one presence bit, and its code when present.
//! Section layout: the presence bits of the "may" points in row-major order (LSB first, padded
//! to a byte), then the codes of the present points in row-major order. A load unpacks the
//! mask once into its bytes, so rendering is unchanged. A mask may also not be stored at all
//! (`drawn`): the load draws it from its table and the seed.

use super::event::Event;
use super::table::{Cell, Table};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// How the `lcm.{n}` sections code their masks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum MaskCoding {
    /// One event byte a point.
    #[default]
    Raw,
    /// §6: the zeros the event table implies are not stored (needs every own mask's table).
    Zeros,
    /// No section: a load draws each mask again from its event table and the seed, as `create`
    /// drew it (needs every own mask's table). A drawn mask is noise its seed regenerates, as
    /// the chaos mosaic's block sequence is; storing it costs about its entropy.
    Drawn,
}

/// Whether a cell's points replicate: never, always, or by chance.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Presence {
    Never,
    Always,
    Maybe,
}

fn presence(cell: &Cell) -> Presence {
    match cell.sign[2] {
        p if p >= 1.0 => Presence::Never,
        p if p <= 0.0 => Presence::Always,
        _ => Presence::Maybe,
    }
}

/// The zero-coded section of `codes`, a `w`-wide mask drawn from `table` (so that its
/// "never" points are 0 and its "always" points are not).
pub fn pack(codes: &[u8], table: &Table, w: usize) -> Vec<u8> {
    let (mut bits, mut n_bits, mut present) = (Vec::new(), 0usize, Vec::new());
    for (i, &code) in codes.iter().enumerate() {
        let code = Event::canonical(code);
        match presence(table.cell(i % w, i / w)) {
            Presence::Never => debug_assert_eq!(code, 0, "a drawn mask replicates nowhere its table forbids"),
            Presence::Always => present.push(code),
            Presence::Maybe => {
                if n_bits % 8 == 0 {
                    bits.push(0);
                }
                if code != 0 {
                    *bits.last_mut().expect("pushed above") |= 1 << (n_bits % 8);
                    present.push(code);
                }
                n_bits += 1;
            }
        }
    }
    bits.extend(present);
    bits
}

/// The `w × h` event bytes of a zero-coded section, or what is wrong with it (`what` names it).
pub fn unpack(data: &[u8], table: &Table, w: usize, h: usize, what: &str) -> Result<Vec<u8>> {
    let kinds: Vec<Presence> = (0..w * h).map(|i| presence(table.cell(i % w, i / w))).collect();
    let n_bits = kinds.iter().filter(|&&k| k == Presence::Maybe).count();
    let bits = data.get(..n_bits.div_ceil(8)).ok_or_else(|| {
        Error::param(what, format!("{} bytes; its {n_bits} presence bits alone need more", data.len()))
    })?;
    let mut codes = data[bits.len()..].iter();
    let mut bit = 0;
    let mut out = Vec::with_capacity(w * h);
    for (i, kind) in kinds.into_iter().enumerate() {
        let stored = match kind {
            Presence::Never => false,
            Presence::Always => true,
            Presence::Maybe => {
                bit += 1;
                bits[(bit - 1) / 8] >> ((bit - 1) % 8) & 1 == 1
            }
        };
        if !stored {
            out.push(0);
            continue;
        }
        let point = || format!("point ({}, {})", i % w, i / w);
        let &code = codes.next().ok_or_else(|| Error::param(what, format!("ends before the code of {}", point())))?;
        if Event::is_none_code(code) {
            return Err(Error::param(what, format!("{}: stored code {code:#04x} replicates nothing", point())));
        }
        out.push(code);
    }
    if codes.len() > 0 {
        return Err(Error::param(what, format!("{} bytes after the last present point's code", codes.len())));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::lcm::demos;

    #[test]
    fn packing_round_trips_and_halves_staggered_tables() {
        let table = demos::table_random_rotation();
        let codes = table.generate([40, 30], 7, 0);
        let packed = pack(&codes, &table, 40);
        assert_eq!(packed.len(), 40 * 30 / 2, "Tab. 1 stores exactly its non-zero half");
        assert_eq!(unpack(&packed, &table, 40, 30, "lcm.0").unwrap(), codes);
        // One "may" cell: a presence bit a point plus the present codes.
        let sparse = Table::single(Cell { sign: [0.2, 0.1, 0.7], ..Cell::none() });
        let codes = sparse.generate([64, 64], 3, 1);
        let present = codes.iter().filter(|&&c| c != 0).count();
        let packed = pack(&codes, &sparse, 64);
        assert_eq!(packed.len(), 64 * 64 / 8 + present);
        assert_eq!(unpack(&packed, &sparse, 64, 64, "lcm.1").unwrap(), codes);
    }

    #[test]
    fn malformed_sections_are_named() {
        let table = Table::single(Cell { sign: [0.5, 0.0, 0.5], ..Cell::none() });
        let codes = table.generate([16, 16], 1, 0);
        let packed = pack(&codes, &table, 16);
        let err = |d: &[u8]| unpack(d, &table, 16, 16, "lcm.0").unwrap_err().to_string();
        assert!(err(&packed[..packed.len() - 1]).contains("ends before the code of point"));
        assert!(err(&[packed.as_slice(), &[1]].concat()).contains("1 bytes after"));
        assert!(err(&packed[..3]).contains("presence bits"));
        let mut zero = packed.clone();
        *zero.last_mut().unwrap() = 0;
        assert!(err(&zero).contains("replicates nothing"));
    }
}
