//! Bundles as objects `<prefix>/<id>.vtex` of an S3-compatible bucket (`--store s3://…`),
//! through `object_store`, with each replica's own copies in a [`LocalCache`].
//!
//! Credentials, region and endpoint come from the usual variables (`AWS_ACCESS_KEY_ID`,
//! `AWS_SECRET_ACCESS_KEY`, `AWS_REGION`, `AWS_ENDPOINT_URL`, `AWS_ALLOW_HTTP`, …). A bundle is
//! written once: an upload whose object exists writes nothing, and the write is a conditional
//! put (`If-None-Match: *`), so of concurrent identical uploads one writes and the others find
//! it there. A server that ignores the condition (Garage) lets racing uploads overwrite the
//! object with the same bytes: they still agree, each answering the same texture.
//!
//! Every call is bounded in time: each try by a timeout, the tries (with backoff) by the
//! deadline. A call that fails opens an outage of [`OUTAGE_SECS`] during which calls fail at
//! once rather than queue behind a store that does not answer; the first call after it tries
//! again, so the store recovers with no restart. The callers are blocking (the store's
//! index); the calls run on a small runtime of this backend's own.

use super::bundles::Listed;
use super::local_cache::LocalCache;
use super::location::Location;
use super::{StoreError, BUNDLE_EXT};
use futures::TryStreamExt;
use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey, S3ConditionalPut};
use object_store::path::Path as ObjectPath;
use object_store::{BackoffConfig, ClientConfigKey, ObjectStore, ObjectStoreExt, PutMode, PutOptions, RetryConfig};
use std::future::Future;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use vtex_synth::bundle::{id_of, MAX_BUNDLE_BYTES};

/// How long calls fail at once after one failed: the `Retry-After` of the 503s they become.
const OUTAGE_SECS: u64 = 1;

/// Where the bucket is and how calls to it are bounded.
#[derive(Clone, Debug)]
pub struct ObjectSettings {
    pub bucket: String,
    pub prefix: String,
    /// The local copies: this directory, at most this many bytes.
    pub cache_dir: PathBuf,
    pub cache_bytes: u64,
    /// The longest a call may take, its retries included.
    pub deadline: Duration,
}

pub struct ObjectBundles {
    bucket: Arc<dyn ObjectStore>,
    prefix: String,
    /// `s3://bucket/prefix`, for messages.
    url: String,
    cache: LocalCache,
    deadline: Duration,
    /// Until when calls fail at once, after one failed.
    outage: Mutex<Option<Instant>>,
    runtime: Option<tokio::runtime::Runtime>,
}

impl Drop for ObjectBundles {
    /// The runtime may be dropped from inside another (the server's): without waiting.
    fn drop(&mut self) {
        if let Some(runtime) = self.runtime.take() {
            runtime.shutdown_background();
        }
    }
}

impl ObjectBundles {
    /// Configures the client from the environment and opens the local copies; no request is
    /// made yet. The error names what is wrong.
    pub fn open(settings: &ObjectSettings) -> Result<ObjectBundles, String> {
        let url = Location::S3 { bucket: settings.bucket.clone(), prefix: settings.prefix.clone() }.to_string();
        let deadline = settings.deadline;
        // Three tries fit in the deadline, each bounded to a third of it. Set as configuration
        // keys, over the client options the environment gave (`AWS_ALLOW_HTTP`, proxies …).
        let millis = |d: Duration| format!("{}ms", d.as_millis().max(1));
        let connect_timeout = millis(deadline.mul_f64(0.2).min(Duration::from_secs(5)));
        let retry = RetryConfig {
            backoff: BackoffConfig {
                init_backoff: Duration::from_millis(50),
                max_backoff: Duration::from_secs(1),
                base: 2.0,
            },
            max_retries: 2,
            retry_timeout: deadline,
        };
        let bucket = AmazonS3Builder::from_env()
            .with_bucket_name(&settings.bucket)
            .with_config(AmazonS3ConfigKey::Client(ClientConfigKey::ConnectTimeout), connect_timeout)
            .with_config(AmazonS3ConfigKey::Client(ClientConfigKey::Timeout), millis(deadline / 3))
            .with_retry(retry)
            .with_conditional_put(S3ConditionalPut::ETagMatch)
            .build()
            .map_err(|e| format!("cannot configure the object store {url}: {e}"))?;
        let cache = LocalCache::open(&settings.cache_dir, settings.cache_bytes)
            .map_err(|e| format!("cannot open the local cache of encodings {}: {e}", settings.cache_dir.display()))?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("vtex-object-store")
            .enable_all()
            .build()
            .map_err(|e| format!("cannot start the object store's runtime: {e}"))?;
        Ok(ObjectBundles {
            bucket: Arc::new(bucket),
            prefix: settings.prefix.clone(),
            url,
            cache,
            deadline,
            outage: Mutex::new(None),
            runtime: Some(runtime),
        })
    }

    pub fn url(&self) -> &str {
        &self.url
    }

    /// The object of bundle `id`.
    fn path_of(&self, id: &str) -> ObjectPath {
        match self.prefix.is_empty() {
            true => ObjectPath::from(format!("{id}.{BUNDLE_EXT}")),
            false => ObjectPath::from(format!("{}/{id}.{BUNDLE_EXT}", self.prefix)),
        }
    }

    /// The URL of bundle `id`'s object, for messages.
    pub fn name_of(&self, id: &str) -> String {
        format!("{}/{id}.{BUNDLE_EXT}", self.url)
    }

    /// Runs `call` on this backend's runtime within the deadline; a failure opens an outage.
    /// Blocking.
    fn call<T>(&self, call: impl Future<Output = object_store::Result<T>>) -> Result<T, StoreError> {
        if self.outage.lock().unwrap().is_some_and(|until| Instant::now() < until) {
            return Err(StoreError::Unavailable("the object store failed less than a second ago".into()));
        }
        let runtime = self.runtime.as_ref().expect("dropped only with the backend");
        // The timer is made inside the runtime: the caller may be a thread of no runtime (the poll).
        let result = match runtime.block_on(async { tokio::time::timeout(self.deadline, call).await }) {
            Ok(Ok(value)) => Ok(value),
            Ok(Err(e)) => Err(e.to_string()),
            Err(_) => Err(format!("no answer within {:.1} s", self.deadline.as_secs_f64())),
        };
        let mut outage = self.outage.lock().unwrap();
        match result {
            Ok(value) => {
                if outage.take().is_some() {
                    tracing::info!(store = %self.url, "the object store answers again");
                }
                Ok(value)
            }
            Err(why) => {
                if outage.is_none() {
                    tracing::warn!(store = %self.url, error = %why, "the object store failed; answering 503 until it answers again");
                }
                *outage = Some(Instant::now() + Duration::from_secs(OUTAGE_SECS));
                Err(StoreError::Unavailable(why))
            }
        }
    }

    /// The bundles under the prefix (not below it), with their ETags.
    pub fn list(&self) -> Result<Vec<Listed>, StoreError> {
        let prefix = (!self.prefix.is_empty()).then(|| ObjectPath::from(self.prefix.as_str()));
        let bucket = self.bucket.clone();
        let objects: Vec<_> = self.call(async move { bucket.list(prefix.as_ref()).try_collect::<Vec<_>>().await })?;
        let under = match self.prefix.is_empty() {
            true => String::new(),
            false => format!("{}/", self.prefix),
        };
        Ok(objects
            .into_iter()
            .filter_map(|meta| {
                let name = meta.location.as_ref().strip_prefix(&under)?.strip_suffix(&format!(".{BUNDLE_EXT}"))?;
                let version = meta.e_tag.unwrap_or_else(|| format!("{}-{}", meta.size, meta.last_modified));
                (!name.contains('/')).then(|| Listed { name: name.to_string(), version })
            })
            .collect())
    }

    /// Bundle `id`'s bytes: the local copy, else the object (kept locally when it matches its
    /// id). An object over the bundle size bound is not read.
    pub fn read(&self, id: &str) -> Result<Option<Vec<u8>>, StoreError> {
        if let Some(bytes) = self.cache.get(id) {
            return Ok(Some(bytes));
        }
        let (bucket, path) = (self.bucket.clone(), self.path_of(id));
        let got = self.call(async move {
            let got = match bucket.get(&path).await {
                Ok(got) => got,
                Err(object_store::Error::NotFound { .. }) => return Ok(None),
                Err(e) => return Err(e),
            };
            if got.meta.size > MAX_BUNDLE_BYTES as u64 {
                return Ok(Some(Err(got.meta.size)));
            }
            Ok(Some(Ok(got.bytes().await?.to_vec())))
        })?;
        match got {
            None => Ok(None),
            Some(Err(size)) => Err(StoreError::Invalid(vtex_synth::Error::bundle(format!(
                "the object holds {size} bytes, over the bound of {MAX_BUNDLE_BYTES} bytes of a bundle"
            )))),
            Some(Ok(bytes)) => {
                if id_of(&bytes) == id {
                    self.cache.put(id, &bytes);
                }
                Ok(Some(bytes))
            }
        }
    }

    pub fn exists(&self, id: &str) -> Result<bool, StoreError> {
        let (bucket, path) = (self.bucket.clone(), self.path_of(id));
        self.call(async move {
            match bucket.head(&path).await {
                Ok(_) => Ok(true),
                Err(object_store::Error::NotFound { .. }) => Ok(false),
                Err(e) => Err(e),
            }
        })
    }

    /// Writes bundle `id` unless its object exists; true when this call wrote it. The object
    /// is looked for first, since some servers (Garage) ignore the put's condition.
    pub fn create(&self, id: &str, bytes: &[u8]) -> Result<bool, StoreError> {
        let (bucket, path) = (self.bucket.clone(), self.path_of(id));
        let payload = bytes::Bytes::copy_from_slice(bytes).into();
        let created = self.call(async move {
            match bucket.head(&path).await {
                Ok(_) => return Ok(false),
                Err(object_store::Error::NotFound { .. }) => {}
                Err(e) => return Err(e),
            }
            let create = PutOptions { mode: PutMode::Create, ..Default::default() };
            match bucket.put_opts(&path, payload, create).await {
                Ok(_) => Ok(true),
                Err(object_store::Error::AlreadyExists { .. }) => Ok(false),
                Err(e) => Err(e),
            }
        })?;
        self.cache.put(id, bytes);
        Ok(created)
    }

    /// Deletes bundle `id`'s object and local copy; false when there was no object.
    pub fn delete(&self, id: &str) -> Result<bool, StoreError> {
        let (bucket, path) = (self.bucket.clone(), self.path_of(id));
        let existed = self.call(async move {
            let existed = match bucket.head(&path).await {
                Ok(_) => true,
                Err(object_store::Error::NotFound { .. }) => false,
                Err(e) => return Err(e),
            };
            match bucket.delete(&path).await {
                Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(existed),
                Err(e) => Err(e),
            }
        })?;
        self.cache.remove(id);
        Ok(existed)
    }
}
