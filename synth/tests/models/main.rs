//! The models' own tests — what is specific to each paper — and those of what surrounds every
//! model (cost bounds, PATCH remakes, stopping renders): one module per file, in one binary,
//! built and linked once. What every model keeps is the conformance suite's
//! (`tests/conformance.rs`, a harness of its own); `tests/png_bombs.rs` bounds the whole
//! process's heap, so it runs alone.
//!
//! `cost` installs this binary's allocator, which counts the bytes each thread allocates.

mod cascade;
mod chaos_mosaic;
mod cost;
mod lcm;
mod lcm_pictures;
mod patch;
mod patterns;
mod stop;
