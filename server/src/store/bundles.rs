//! [`Bundles`]: where the store's bundles live — a data directory or an object store. Each
//! backend only lists, reads, creates and deletes bytes under ids; the index
//! ([`super::Store`]) checks every bundle it is given and decides what is served.

use super::dir::DirBundles;
use super::object::ObjectBundles;
use super::StoreError;

/// A bundle found by listing: the name it is stored under (checked by the index, like its
/// content) and a version that changes when its content may have (a file's length and time,
/// an object's ETag).
pub struct Listed {
    pub name: String,
    pub version: String,
}

pub enum Bundles {
    Dir(DirBundles),
    /// Boxed: it is large, and there is one per store.
    Object(Box<ObjectBundles>),
}

impl Bundles {
    pub fn list(&self) -> Result<Vec<Listed>, StoreError> {
        match self {
            Bundles::Dir(d) => d.list(),
            Bundles::Object(o) => o.list(),
        }
    }

    /// The bytes stored under `id`; `None` when there are none.
    pub fn read(&self, id: &str) -> Result<Option<Vec<u8>>, StoreError> {
        match self {
            Bundles::Dir(d) => d.read(id),
            Bundles::Object(o) => o.read(id),
        }
    }

    /// Whether bytes are stored under `id`.
    pub fn exists(&self, id: &str) -> Result<bool, StoreError> {
        match self {
            Bundles::Dir(d) => Ok(d.exists(id)),
            Bundles::Object(o) => o.exists(id),
        }
    }

    /// Whether bundle `id` is stored, when that is known without waiting on a network: a
    /// directory is asked at once, an object store not (`None`).
    pub fn exists_locally(&self, id: &str) -> Option<bool> {
        match self {
            Bundles::Dir(d) => Some(d.exists(id)),
            Bundles::Object(_) => None,
        }
    }

    /// Stores `bytes`, the bundle whose id is `id`, whole or not at all; false when another
    /// process had stored it first (as far as the backend can tell).
    pub fn create(&self, id: &str, bytes: &[u8]) -> Result<bool, StoreError> {
        match self {
            Bundles::Dir(d) => d.create(id, bytes).map(|()| true),
            Bundles::Object(o) => o.create(id, bytes),
        }
    }

    /// Deletes bundle `id`; false when none was stored.
    pub fn delete(&self, id: &str) -> Result<bool, StoreError> {
        match self {
            Bundles::Dir(d) => d.delete(id),
            Bundles::Object(o) => o.delete(id),
        }
    }

    /// Where bundle `id` is stored (a path or a URL), for messages.
    pub fn name_of(&self, id: &str) -> String {
        match self {
            Bundles::Dir(d) => d.path_of(id).display().to_string(),
            Bundles::Object(o) => o.name_of(id),
        }
    }

    /// Whether the bundles can be reached now (readiness): the directory can be listed. An
    /// object store that stopped answering does not make a replica unready: every replica
    /// shares it, so all would leave the balancer together while they can still serve the
    /// textures they hold; its failures are answered 503 one by one instead.
    pub fn reachable(&self) -> bool {
        match self {
            Bundles::Dir(d) => std::fs::read_dir(d.dir()).is_ok(),
            Bundles::Object(_) => true,
        }
    }
}

impl std::fmt::Display for Bundles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Bundles::Dir(d) => write!(f, "{}", d.dir().display()),
            Bundles::Object(o) => f.write_str(o.url()),
        }
    }
}
