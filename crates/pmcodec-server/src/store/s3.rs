//! An S3-compatible bucket (AWS, MinIO, s3s-fs, ...) through the `object_store` crate, so that
//! any number of stateless servers can share one set of assets.
//!
//! Objects are `<prefix><id>.pmc`. A new asset is written with one PUT of the whole container:
//! S3 makes an object visible only once its upload has completed, so the PUT itself is the
//! atomic "put final" step (a temporary key plus a server-side copy would add two requests and
//! no safety). Containers are bounded by the upload limit, well inside a single PUT's 5 GiB.
//!
//! A create-only write is a conditional PUT (`If-None-Match: *`, `object_store`'s
//! `PutMode::Create`): the store itself refuses it when the key exists (412), so two servers
//! creating one asset cannot both win. AWS may also answer 409 while another conditional write
//! to the key is in flight; `object_store` reports that as AlreadyExists too, so there both
//! writes can fail (the job says so; uploading again works). AWS S3, MinIO and R2 support it, and so does s3s-fs (the test server), though it
//! checks the key and then writes, so two truly simultaneous creates can both pass there.
//! `object_store` sends the header unless conditional puts are switched off
//! (`AWS_CONDITIONAL_PUT=disabled`), in which case create-only writes fail with a
//! configuration error instead of falling back to a check that could race.

use super::{AssetStore, PutMode, StoreError, StoredObject};
use crate::AssetId;
use crate::config::S3Config;
use bytes::Bytes;
use futures_util::future::BoxFuture;
use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey};
use object_store::path::Path as ObjectPath;
use object_store::{ClientOptions, ObjectMeta, ObjectStore, ObjectStoreExt, PutOptions, RetryConfig};
use std::sync::Arc;
use std::time::Duration;

/// An S3-compatible bucket via `object_store`: puts are atomic objects, creates use `If-None-Match: *`.
pub struct S3Store {
    store: Arc<dyn ObjectStore>,
    bucket: String,
    /// The prefix as given, normalised to end in `/` unless empty.
    prefix: String,
}

impl S3Store {
    /// A client for `c`; fails with [`StoreError::Config`] on an empty bucket or a bad endpoint, without contacting the store.
    pub fn new(c: &S3Config) -> Result<S3Store, StoreError> {
        if c.bucket.trim().is_empty() {
            return Err(StoreError::Config("an S3 store needs a bucket name".into()));
        }
        // Start from the AWS_* environment so that instance roles and the usual variables work
        // when the configuration names no keys; explicit settings override it.
        let mut b = AmazonS3Builder::from_env().with_bucket_name(&c.bucket);
        if let Some(e) = &c.endpoint {
            b = b.with_endpoint(e);
        }
        b = b.with_region(c.region.clone().unwrap_or_else(|| "us-east-1".into()));
        if let (Some(k), Some(s)) = (&c.access_key_id, &c.secret_access_key) {
            b = b.with_access_key_id(k.expose()).with_secret_access_key(s.expose());
        }
        if b.get_config_value(&AmazonS3ConfigKey::ConditionalPut).is_some_and(|v| v.trim() == "disabled") {
            tracing::warn!(
                bucket = %c.bucket,
                "conditional puts are disabled (AWS_CONDITIONAL_PUT): uploads without replace=true will fail to store"
            );
        }
        // Requests must fail within a request's own time budget rather than retry for minutes.
        let retry = RetryConfig { max_retries: 2, retry_timeout: Duration::from_secs(15), ..RetryConfig::default() };
        let client = ClientOptions::new()
            .with_allow_http(c.allow_http)
            .with_connect_timeout(Duration::from_secs(5))
            .with_timeout(Duration::from_secs(120));
        let store = b
            .with_allow_http(c.allow_http)
            .with_retry(retry)
            .with_client_options(client)
            .build()
            .map_err(|e| StoreError::Config(format!("S3 store: {e}")))?;
        let prefix = c.prefix.trim_matches('/');
        let prefix = if prefix.is_empty() { String::new() } else { format!("{prefix}/") };
        Ok(S3Store { store: Arc::new(store), bucket: c.bucket.clone(), prefix })
    }

    fn key(&self, id: &AssetId) -> ObjectPath {
        ObjectPath::from(format!("{}{}", self.prefix, id.file_name()))
    }

    fn meta_key(&self, id: &AssetId) -> ObjectPath {
        ObjectPath::from(format!("{}{id}.meta.json", self.prefix))
    }

    fn object(id: &AssetId, meta: &ObjectMeta) -> StoredObject {
        let tag = meta.e_tag.clone().unwrap_or_else(|| format!("{}-{}", meta.last_modified.timestamp_nanos_opt().unwrap_or(0), meta.size));
        StoredObject { id: id.clone(), size: meta.size, tag }
    }

    fn err(&self, what: &str, e: object_store::Error) -> StoreError {
        StoreError::Io(format!("s3 bucket {}: {what}: {e}", self.bucket))
    }
}

impl AssetStore for S3Store {
    fn describe(&self) -> String {
        format!("s3 bucket {} prefix {:?}", self.bucket, self.prefix)
    }

    fn list(&self) -> BoxFuture<'_, Result<Vec<StoredObject>, StoreError>> {
        Box::pin(async move {
            let prefix = (!self.prefix.is_empty()).then(|| ObjectPath::from(self.prefix.trim_end_matches('/')));
            // One level only: objects in "sub-folders" of the prefix are not assets.
            let listing = self.store.list_with_delimiter(prefix.as_ref()).await.map_err(|e| self.err("listing", e))?;
            let mut out: Vec<StoredObject> = listing
                .objects
                .iter()
                .filter_map(|m| {
                    let name = m.location.filename()?;
                    let id = AssetId::from_file_name(name);
                    if id.is_none() && name.ends_with(".pmc") {
                        tracing::warn!(key = %m.location, "skipping a .pmc whose name is not a valid asset id");
                    }
                    id.map(|id| Self::object(&id, m))
                })
                .collect();
            out.sort_by(|a, b| a.id.cmp(&b.id));
            Ok(out)
        })
    }

    fn head<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<StoredObject>, StoreError>> {
        Box::pin(async move {
            match self.store.head(&self.key(id)).await {
                Ok(meta) => Ok(Some(Self::object(id, &meta))),
                Err(object_store::Error::NotFound { .. }) => Ok(None),
                Err(e) => Err(self.err("head", e)),
            }
        })
    }

    fn get<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<(StoredObject, Bytes)>, StoreError>> {
        Box::pin(async move {
            let result = match self.store.get(&self.key(id)).await {
                Ok(r) => r,
                Err(object_store::Error::NotFound { .. }) => return Ok(None),
                Err(e) => return Err(self.err("get", e)),
            };
            let obj = Self::object(id, &result.meta);
            let bytes = result.bytes().await.map_err(|e| self.err("get", e))?;
            Ok(Some((StoredObject { size: bytes.len() as u64, ..obj }, bytes)))
        })
    }

    fn put<'a>(&'a self, id: &'a AssetId, bytes: Bytes, mode: PutMode) -> BoxFuture<'a, Result<StoredObject, StoreError>> {
        Box::pin(async move {
            let size = bytes.len() as u64;
            let opts = PutOptions {
                mode: match mode {
                    PutMode::Overwrite => object_store::PutMode::Overwrite,
                    PutMode::Create => object_store::PutMode::Create,
                },
                ..PutOptions::default()
            };
            let r = match self.store.put_opts(&self.key(id), bytes.into(), opts).await {
                Ok(r) => r,
                // object_store turns a refused `If-None-Match: *` (412, or 304 from some
                // stores) and a 409 into AlreadyExists; a bare Precondition (412) is taken to
                // mean the same, should a store or a later object_store report it that way.
                Err(object_store::Error::AlreadyExists { .. } | object_store::Error::Precondition { .. }) if mode == PutMode::Create => {
                    return Err(StoreError::AlreadyExists(id.clone()));
                }
                Err(e @ object_store::Error::NotImplemented { .. }) => {
                    return Err(StoreError::Config(format!(
                        "s3 bucket {}: a create-only put needs conditional puts, which are disabled (AWS_CONDITIONAL_PUT): {e}",
                        self.bucket
                    )));
                }
                Err(e) => return Err(self.err("put", e)),
            };
            // Some stores answer a PUT without an ETag; ask once so that the tag matches what
            // a listing or a HEAD will report.
            let tag = match r.e_tag {
                Some(t) => t,
                None => self.head(id).await?.map(|o| o.tag).unwrap_or_default(),
            };
            Ok(StoredObject { id: id.clone(), size, tag })
        })
    }

    fn delete<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<bool, StoreError>> {
        Box::pin(async move {
            // S3's DELETE succeeds on missing keys, so ask first to answer 404 for those.
            if self.head(id).await?.is_none() {
                return Ok(false);
            }
            // The metadata first: without its container it would only be a stale cache. (S3
            // answers a DELETE of a missing key with success; some compatible stores with 404.)
            match self.store.delete(&self.meta_key(id)).await {
                Ok(()) | Err(object_store::Error::NotFound { .. }) => {}
                Err(e) => return Err(self.err("delete", e)),
            }
            self.store.delete(&self.key(id)).await.map_err(|e| self.err("delete", e))?;
            Ok(true)
        })
    }

    fn get_meta<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<Bytes>, StoreError>> {
        Box::pin(async move {
            match self.store.get(&self.meta_key(id)).await {
                Ok(r) => Ok(Some(r.bytes().await.map_err(|e| self.err("get", e))?)),
                Err(object_store::Error::NotFound { .. }) => Ok(None),
                Err(e) => Err(self.err("get", e)),
            }
        })
    }

    fn put_meta<'a>(&'a self, id: &'a AssetId, bytes: Bytes) -> BoxFuture<'a, Result<(), StoreError>> {
        Box::pin(async move {
            self.store.put(&self.meta_key(id), bytes.into()).await.map_err(|e| self.err("put", e))?;
            Ok(())
        })
    }

    fn check(&self) -> BoxFuture<'_, Result<(), StoreError>> {
        Box::pin(async move {
            use futures_util::StreamExt;
            // The first page of a listing: it fails for a missing bucket or a bad signature,
            // where a HEAD of a missing key would answer 404 either way.
            let prefix = (!self.prefix.is_empty()).then(|| ObjectPath::from(self.prefix.trim_end_matches('/')));
            match self.store.list(prefix.as_ref()).next().await {
                None | Some(Ok(_)) => Ok(()),
                Some(Err(e)) => Err(self.err("readiness probe", e)),
            }
        })
    }
}
