//! Stable-toolchain fuzzing of every parser of untrusted input in vtex (bundle container, each
//! model's encoding, PNG inputs, query strings), and the load driver of the soak benchmark
//! (`src/bin/soak.rs`). See `docs/fuzzing.md`.

pub mod alloc;
pub mod harness;
pub mod mutate;
pub mod targets;
