//! The replication event of one point, coded in one byte as in §5 of the paper: 2 bits for
//! positive / negative / no replication, 2 bits for the rotation, 1 bit for mirroring and
//! 2 bits for the operation — seven bits in all.
//!
//! Layout (bit 0 lowest): `s s r r m o o 0`
//! * bits 0–1 sign: 0 none, 1 positive, 2 negative (3 is not an event)
//! * bits 2–3 rotation clockwise: 0°, 90°, 180°, 270°
//! * bit 4 mirroring (left–right, applied before the rotation)
//! * bits 5–6 operation: 0 addition, 1 non-zero application, 2 maximum application (3 is not one)
//! * bit 7 is always 0.
//!
//! Of the 128 seven-bit codes, 3 × 4 × 2 × 3 = 72 are events; the others are rejected when an
//! encoding is loaded, so the renderer never meets them.

use crate::{Error, Result};

/// Whether, and with which sign, the base element is replicated at a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Sign {
    None,
    Positive,
    Negative,
}

/// How a replication pixel `b` updates the current intensity `a` (paper §2.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Operation {
    /// a ← a + b.
    #[default]
    Add,
    /// a ← b where the element pixel is not transparent (non-zero), else a.
    NonZero,
    /// a ← a where |a| > |b|, else b (§2.2's two cases: a tie takes b).
    Maximum,
}

/// One replication event: everything the LCM byte of a point says.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Event {
    pub sign: Sign,
    /// Quarter turns clockwise, 0..=3.
    pub rotation: u8,
    pub mirror: bool,
    pub operation: Operation,
}

impl Event {
    /// "No replication": the canonical code 0.
    pub const NONE: Event = Event { sign: Sign::None, rotation: 0, mirror: false, operation: Operation::Add };

    /// The one-byte code of §5.
    pub fn encode(self) -> u8 {
        let s = match self.sign {
            Sign::None => 0,
            Sign::Positive => 1,
            Sign::Negative => 2,
        };
        let o = match self.operation {
            Operation::Add => 0,
            Operation::NonZero => 1,
            Operation::Maximum => 2,
        };
        s | (self.rotation & 3) << 2 | (self.mirror as u8) << 4 | o << 5
    }

    /// Decodes a code, or says why it is not an event.
    pub fn decode(code: u8) -> Result<Event> {
        if code & 0x80 != 0 {
            return Err(Error::param("lcm", format!("event code {code:#04x} has bit 7 set; codes are 7 bits")));
        }
        let sign = match code & 3 {
            0 => Sign::None,
            1 => Sign::Positive,
            2 => Sign::Negative,
            _ => return Err(Error::param("lcm", format!("event code {code:#04x} has sign bits 11, which is no sign"))),
        };
        let operation = match (code >> 5) & 3 {
            0 => Operation::Add,
            1 => Operation::NonZero,
            2 => Operation::Maximum,
            _ => {
                return Err(Error::param("lcm", format!("event code {code:#04x} has operation bits 11, which is none")))
            }
        };
        Ok(Event { sign, rotation: (code >> 2) & 3, mirror: code & 0x10 != 0, operation })
    }

    /// True when the code replicates nothing (whatever its other bits say).
    #[inline]
    pub fn is_none_code(code: u8) -> bool {
        code & 3 == 0
    }

    /// The orientation index 0..8 (mirror × 4 + rotation) of a valid code.
    #[inline]
    pub fn orientation_of(code: u8) -> usize {
        ((code >> 2) & 7) as usize
    }

    /// The operation bits of a valid code.
    #[inline]
    pub fn operation_of(code: u8) -> Operation {
        match (code >> 5) & 3 {
            0 => Operation::Add,
            1 => Operation::NonZero,
            _ => Operation::Maximum,
        }
    }

    /// −1 for a negative replication, 1 otherwise, of a valid code.
    #[inline]
    pub fn sign_of(code: u8) -> i32 {
        if code & 3 == 2 {
            -1
        } else {
            1
        }
    }

    /// The code of a point as far as rendering goes: every "no replication" code is 0.
    #[inline]
    pub fn canonical(code: u8) -> u8 {
        if Self::is_none_code(code) {
            0
        } else {
            code
        }
    }
}
