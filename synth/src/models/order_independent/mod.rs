//! `order-independent`: texture synthesis by example in which any pixel can be computed alone,
//! in any order, identically every time (Wei & Levoy 2002, *Order-Independent Texture
//! Synthesis*).

pub mod reference;
pub mod structure;
