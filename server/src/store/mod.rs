//! The encoding store: an index of the content-addressed bundles `<id>.vtex` — in a data
//! directory or an object store ([`Bundles`]) — and the textures loaded from them within a
//! memory budget.
//!
//! At open each bundle's container is parsed and its cost planned — no texture is built — so a
//! bundle over the bounds is rejected before it costs anything. A texture is loaded on its first
//! use, off the I/O threads, one load shared by concurrent first uses, and kept in an LRU charged
//! with the bytes its plan says it holds. A load reserves its charge before it starts, so what
//! loaded textures hold stays within the budget; evicting drops the store's reference only, and
//! requests in flight keep theirs.
//!
//! A bundle is validated completely (container and model) before it is written, and every
//! bundle read is checked against its id (its content hash) before it is served. Bundles are
//! immutable: an edit is a new bundle, a new id.
//!
//! In a data directory writes are atomic — a temporary file in the same directory, fsync,
//! rename, fsync of the directory — so a crash leaves either the whole bundle or nothing but a
//! temporary file, which the next start removes. Several processes may share one data
//! directory (replicas behind a proxy). A bundle another process wrote, or one copied in, is
//! found on the first request for its id ([`Store::find`], with a short memory of ids found
//! absent) and by the directory watch (`watch.rs`), which calls [`Store::refresh`] for every
//! bundle that appears or disappears. Temporary names are unique per process, and only
//! temporaries older than [`STALE_TEMP_AGE`] are taken for crashed writes, so replicas
//! starting together never remove each other's writes in progress.
//!
//! In an object store (`object.rs`) each bundle is one object written once; replicas share
//! nothing but the bucket, each keeping its own bounded copies (`local_cache.rs`). A bundle
//! another replica wrote is found on the first request for its id, and the list follows the
//! bucket by a poll ([`Store::rescan`]), within its interval.

mod atomic;
mod budget;
mod bundles;
mod dir;
mod index;
mod local_cache;
mod location;
mod object;
mod record;

pub use atomic::write_atomic;
pub use bundles::Bundles;
pub use index::{Bounds, OpenReport, Store, StoreError, ABSENT_TTL, STALE_TEMP_AGE};
pub use location::Location;
pub use object::{ObjectBundles, ObjectSettings};
pub use record::{Entry, Record, TextureInfo};

pub const BUNDLE_EXT: &str = "vtex";
/// Prefix of temporary files; anything carrying it at start-up is a crashed write.
pub const TEMP_PREFIX: &str = ".tmp-";
