//! The encoding bundle: one file per texture, a JSON manifest plus named binary sections.
//!
//! Layout (all integers little-endian):
//!
//! ```text
//! "VTEXBNDL"  magic, 8 bytes
//! u32         container version (1)
//! u32         manifest length, then the manifest: UTF-8 JSON {format, model, name, params,
//!             derived (optional)}
//! u32         section count, then per section:
//!             u8 name length, name ([a-z0-9._-]), u64 data length, data
//! ```
//!
//! Nothing may follow the last section. The bundle's id is the BLAKE3 hash of its bytes,
//! so a texture's URLs never change meaning. Parsing checks every length against the bytes
//! actually present before reading, so a truncated or lying bundle is an error, not a panic.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

pub const MAGIC: &[u8; 8] = b"VTEXBNDL";
pub const CONTAINER_VERSION: u32 = 1;
/// The manifest's `format` field for this version.
pub const FORMAT: &str = "vtex-bundle/1";
pub const MAX_MANIFEST_BYTES: usize = 1 << 20;
pub const MAX_SECTIONS: usize = 64;
/// Upper bound of a whole bundle. Encodings are kilobytes to a few megabytes.
pub const MAX_BUNDLE_BYTES: usize = 64 << 20;

/// The JSON part of a bundle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub format: String,
    /// Model id, as the registry lists it.
    pub model: String,
    /// Human-readable name shown by viewers.
    pub name: String,
    /// Model parameters as the user gave them (a JSON object; each model defines and
    /// validates its own): the recipe that a PATCH edits and `create` takes back.
    pub params: serde_json::Value,
    /// Parameters `create` derived from `params` and the input images, filled in where the
    /// user left them out (the cascade's value `range`, the mosaic's `seamless`, …). Kept
    /// apart so that a change of `params` derives them again instead of keeping stale ones;
    /// no key is in both. Absent from bundles made before it existed, whose `params` hold
    /// everything.
    #[serde(default, skip_serializing_if = "serde_json::Map::is_empty")]
    pub derived: serde_json::Map<String, serde_json::Value>,
}

impl Manifest {
    /// Every parameter a model reads when loading: `params` with `derived` beside them.
    pub fn full_params(&self) -> Result<serde_json::Value> {
        if self.derived.is_empty() {
            return Ok(self.params.clone());
        }
        let serde_json::Value::Object(given) = &self.params else {
            return Err(Error::bundle("params: must be a JSON object"));
        };
        if let Some(k) = self.derived.keys().find(|k| given.contains_key(*k)) {
            return Err(Error::bundle(format!("`{k}` is both in params and derived")));
        }
        let mut all = given.clone();
        all.extend(self.derived.clone());
        Ok(serde_json::Value::Object(all))
    }
}

/// Reads an internally tagged enum's tag (`K`, a fieldless enum of its variant names) and its
/// other entries as a JSON value, as serde's derive of `#[serde(tag)]` reads them (a map, or a
/// sequence whose first element is the tag; the same errors at the same paths), for the
/// variant to be read from that value. The models' tagged parameter enums are read so: every
/// type below them is then deserialized by serde_json's value deserializer alone, not also
/// from the buffered `Content` of the derive, which keeps the WebAssembly modules small.
#[cfg(any(feature = "model-cascade", feature = "model-patterns"))]
pub(crate) fn tagged<'de, D, K>(
    d: D,
    tag: &'static str,
    expecting: &'static str,
) -> std::result::Result<(K, serde_json::Value), D::Error>
where
    D: serde::Deserializer<'de>,
    K: Deserialize<'de>,
{
    use serde::de::{Error, MapAccess, SeqAccess};
    struct Tagged<K> {
        tag: &'static str,
        expecting: &'static str,
        kind: std::marker::PhantomData<K>,
    }
    impl<'de, K: Deserialize<'de>> serde::de::Visitor<'de> for Tagged<K> {
        type Value = (K, serde_json::Value);

        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str(self.expecting)
        }

        fn visit_seq<S: SeqAccess<'de>>(self, mut seq: S) -> std::result::Result<Self::Value, S::Error> {
            let kind = seq.next_element()?.ok_or_else(|| S::Error::missing_field(self.tag))?;
            let mut rest = Vec::new();
            while let Some(v) = seq.next_element()? {
                rest.push(v);
            }
            Ok((kind, serde_json::Value::Array(rest)))
        }

        fn visit_map<M: MapAccess<'de>>(self, mut map: M) -> std::result::Result<Self::Value, M::Error> {
            let mut kind = None;
            let mut rest = serde_json::Map::new();
            while let Some(key) = map.next_key::<String>()? {
                if key != self.tag {
                    rest.insert(key, map.next_value()?);
                } else if kind.is_some() {
                    return Err(M::Error::duplicate_field(self.tag));
                } else {
                    kind = Some(map.next_value()?);
                }
            }
            let kind = kind.ok_or_else(|| M::Error::missing_field(self.tag))?;
            Ok((kind, serde_json::Value::Object(rest)))
        }
    }
    d.deserialize_any(Tagged { tag, expecting, kind: std::marker::PhantomData })
}

/// What reading `v` as `T` gives — the value (as Debug shows it, which leaves out the enum's
/// name) or the error, directly and by path as `parse_params` reads — for the tests that hold
/// a reader made with [`tagged`] to the derive it replaces.
#[cfg(all(test, any(feature = "model-cascade", feature = "model-patterns")))]
pub(crate) fn read_both_ways<T: serde::de::DeserializeOwned + std::fmt::Debug>(v: &serde_json::Value) -> [String; 2] {
    let direct = serde_json::from_value::<T>(v.clone()).map(|t| format!("{t:?}")).map_err(|e| e.to_string());
    let path = serde_path_to_error::deserialize::<_, T>(v)
        .map(|t| format!("{t:?}"))
        .map_err(|e| format!("{}: {}", e.path(), e.inner()));
    [format!("{direct:?}"), format!("{path:?}")]
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Section {
    pub name: String,
    pub data: Vec<u8>,
}

/// A parsed (or about to be written) encoding.
#[derive(Clone, Debug, PartialEq)]
pub struct Bundle {
    pub manifest: Manifest,
    pub sections: Vec<Section>,
}

impl Bundle {
    pub fn new(model: &str, name: &str, params: serde_json::Value) -> Self {
        Self {
            manifest: Manifest {
                format: FORMAT.into(),
                model: model.into(),
                name: name.into(),
                params,
                derived: Default::default(),
            },
            sections: Vec::new(),
        }
    }

    /// A bundle of what `create` made: `given`, the params as the user gave them, and
    /// `complete`, the same with the fields it derived filled in. Those fields are kept as
    /// [`Manifest::derived`]; `complete` changes nothing that was given.
    pub fn created(model: &str, name: &str, given: serde_json::Value, complete: serde_json::Value) -> Self {
        let mut bundle = Self::new(model, name, given);
        if let (serde_json::Value::Object(given), serde_json::Value::Object(complete)) =
            (&bundle.manifest.params, complete)
        {
            debug_assert!(given.iter().all(|(k, v)| complete.get(k) == Some(v)), "create changed a given param");
            bundle.manifest.derived = complete.into_iter().filter(|(k, _)| !given.contains_key(k)).collect();
        }
        bundle
    }

    pub fn with_section(mut self, name: &str, data: Vec<u8>) -> Self {
        self.sections.push(Section { name: name.into(), data });
        self
    }

    /// The section called `name`, or an error naming it.
    pub fn section(&self, name: &str) -> Result<&[u8]> {
        self.sections
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.data.as_slice())
            .ok_or_else(|| Error::bundle(format!("missing section `{name}`")))
    }

    /// The model parameters, given and derived ([`Manifest::full_params`]), decoded into the
    /// model's own type.
    pub fn params<T: serde::de::DeserializeOwned>(&self) -> Result<T> {
        serde_json::from_value(self.manifest.full_params()?).map_err(|e| Error::bundle(format!("params: {e}")))
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let manifest = serde_json::to_vec(&self.manifest).expect("a manifest always serializes");
        let mut out =
            Vec::with_capacity(32 + manifest.len() + self.sections.iter().map(|s| s.data.len() + 16).sum::<usize>());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&CONTAINER_VERSION.to_le_bytes());
        out.extend_from_slice(&(manifest.len() as u32).to_le_bytes());
        out.extend_from_slice(&manifest);
        out.extend_from_slice(&(self.sections.len() as u32).to_le_bytes());
        for s in &self.sections {
            out.push(s.name.len() as u8);
            out.extend_from_slice(s.name.as_bytes());
            out.extend_from_slice(&(s.data.len() as u64).to_le_bytes());
            out.extend_from_slice(&s.data);
        }
        out
    }

    /// Parses and checks the container. Model-level validation happens in
    /// [`crate::models::load`].
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        if bytes.len() > MAX_BUNDLE_BYTES {
            return Err(Error::bundle(format!("{} bytes; at most {MAX_BUNDLE_BYTES}", bytes.len())));
        }
        let mut r = Reader { bytes, pos: 0 };
        if r.take(8, "magic")? != MAGIC {
            return Err(Error::bundle("not a vtex bundle (bad magic)"));
        }
        let version = r.u32("container version")?;
        if version != CONTAINER_VERSION {
            return Err(Error::bundle(format!("container version {version}; this build reads {CONTAINER_VERSION}")));
        }
        let manifest_len = r.u32("manifest length")? as usize;
        if manifest_len > MAX_MANIFEST_BYTES {
            return Err(Error::bundle(format!("manifest of {manifest_len} bytes; at most {MAX_MANIFEST_BYTES}")));
        }
        // Read as a JSON value first: then serde_json's value deserializer, which reads the
        // models' parameters, is the only one a type is read by.
        let manifest: serde_json::Value = serde_json::from_slice(r.take(manifest_len, "manifest")?)
            .map_err(|e| Error::bundle(format!("manifest: {e}")))?;
        let manifest: Manifest =
            serde_json::from_value(manifest).map_err(|e| Error::bundle(format!("manifest: {e}")))?;
        if manifest.format != FORMAT {
            return Err(Error::bundle(format!("manifest format `{}`; expected `{FORMAT}`", manifest.format)));
        }
        if manifest.name.chars().count() > 200 {
            return Err(Error::bundle("name longer than 200 characters"));
        }
        let count = r.u32("section count")? as usize;
        if count > MAX_SECTIONS {
            return Err(Error::bundle(format!("{count} sections; at most {MAX_SECTIONS}")));
        }
        let mut sections: Vec<Section> = Vec::with_capacity(count);
        for i in 0..count {
            let name_len = r.take(1, "section name length")?[0] as usize;
            let name = std::str::from_utf8(r.take(name_len, "section name")?)
                .ok()
                .filter(|n| valid_section_name(n))
                .ok_or_else(|| Error::bundle(format!("section {i} has an invalid name")))?
                .to_string();
            if sections.iter().any(|s| s.name == name) {
                return Err(Error::bundle(format!("section `{name}` appears twice")));
            }
            let len = r.u64("section length")?;
            let data = r.take(usize::try_from(len).unwrap_or(usize::MAX), &format!("section `{name}`"))?.to_vec();
            sections.push(Section { name, data });
        }
        if r.pos != bytes.len() {
            return Err(Error::bundle(format!("{} unexpected bytes after the last section", bytes.len() - r.pos)));
        }
        Ok(Self { manifest, sections })
    }
}

/// The content id of bundle bytes: lowercase hex BLAKE3, 64 characters.
pub fn id_of(bytes: &[u8]) -> String {
    blake3::hash(bytes).to_hex().to_string()
}

/// True for strings that look like an id from [`id_of`]; anything else never reaches a path.
pub fn is_valid_id(id: &str) -> bool {
    id.len() == 64 && id.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

fn valid_section_name(n: &str) -> bool {
    !n.is_empty() && n.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b"._-".contains(&b))
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let left = self.bytes.len() - self.pos;
        if n > left {
            return Err(Error::bundle(format!("truncated: {what} needs {n} bytes, {left} left")));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }

    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Bundle {
        Bundle::new("test", "a test", serde_json::json!({"k": 1}))
            .with_section("sample.png", vec![1, 2, 3])
            .with_section("blocks", vec![9; 40])
    }

    #[test]
    fn round_trip_and_id() {
        let b = sample();
        let bytes = b.to_bytes();
        assert_eq!(Bundle::from_bytes(&bytes).unwrap(), b);
        let id = id_of(&bytes);
        assert!(is_valid_id(&id));
        assert_eq!(id, id_of(&b.to_bytes()), "serialization is deterministic");
    }

    #[test]
    fn derived_params_are_kept_apart_and_read_beside_the_given() {
        use serde_json::json;
        let b = Bundle::created("test", "t", json!({"seed": 1}), json!({"seed": 1, "range": [0, 1]}));
        assert_eq!(b.manifest.params, json!({"seed": 1}));
        assert_eq!(b.manifest.full_params().unwrap(), json!({"seed": 1, "range": [0, 1]}));
        assert_eq!(Bundle::from_bytes(&b.to_bytes()).unwrap(), b);
        // Nothing derived: the manifest is written as it was before `derived` existed.
        let plain = Bundle::created("test", "t", json!({"seed": 1}), json!({"seed": 1}));
        assert_eq!(plain, Bundle::new("test", "t", json!({"seed": 1})));
        assert!(!String::from_utf8_lossy(&plain.to_bytes()).contains("derived"));
        let mut both = b.clone();
        both.manifest.params["range"] = json!([0, 2]);
        assert!(both.manifest.full_params().unwrap_err().to_string().contains("`range` is both"), "{both:?}");
    }

    #[test]
    fn every_truncation_is_an_error() {
        let bytes = sample().to_bytes();
        for cut in 0..bytes.len() {
            assert!(Bundle::from_bytes(&bytes[..cut]).is_err(), "truncated at {cut} parsed");
        }
    }

    #[test]
    fn trailing_garbage_and_lies_are_errors() {
        let mut bytes = sample().to_bytes();
        bytes.push(0);
        assert!(Bundle::from_bytes(&bytes).unwrap_err().to_string().contains("unexpected bytes"));

        let mut lying = sample().to_bytes();
        let n = lying.len();
        // The last section's length field sits 8 + 40 bytes from the end: claim 2^63 bytes.
        lying[n - 48..n - 40].copy_from_slice(&(1u64 << 63).to_le_bytes());
        assert!(Bundle::from_bytes(&lying).unwrap_err().to_string().contains("truncated"));
    }

    #[test]
    fn bad_names_and_formats() {
        let b = Bundle::new("m", "n", serde_json::json!({})).with_section("../x", vec![]);
        assert!(Bundle::from_bytes(&b.to_bytes()).unwrap_err().to_string().contains("invalid name"));
        let mut b = sample();
        b.manifest.format = "other/9".into();
        assert!(Bundle::from_bytes(&b.to_bytes()).unwrap_err().to_string().contains("format"));
        let twice = sample().with_section("blocks", vec![]);
        assert!(Bundle::from_bytes(&twice.to_bytes()).unwrap_err().to_string().contains("twice"));
        assert!(Bundle::from_bytes(b"PNG....").is_err());
    }

    #[test]
    fn ids_are_checked() {
        assert!(!is_valid_id("../../etc/passwd"));
        assert!(!is_valid_id(&"A".repeat(64)));
        assert!(is_valid_id(&"0a".repeat(32)));
    }
}
