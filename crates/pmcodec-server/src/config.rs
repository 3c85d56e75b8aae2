//! Server configuration: defaults, then a TOML or JSON file, then `PMCODEC_*` environment
//! variables, then command-line flags (the CLI applies those last).

use serde::{Deserialize, Serialize};
use std::fmt;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Everything the server can be told. Every field has a default, so an empty file is valid.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Address to listen on.
    pub listen: SocketAddr,
    /// Folder of the built viewer served at `/`; `None` serves no viewer.
    pub viewer: Option<PathBuf>,
    /// Folder where upload bodies wait for their encode job (one temporary file per job,
    /// removed when the job ends); `None` is the system's temporary folder.
    pub upload_dir: Option<PathBuf>,
    /// Where assets live (`[store]`); the built-in samples by default.
    pub store: StoreConfig,
    /// Bearer tokens for writes and reads (`[auth]`).
    pub auth: AuthConfig,
    /// Body sizes, timeouts, queue depths and input limits (`[limits]`).
    pub limits: LimitsConfig,
    /// Memory budgets of the asset and decoder caches (`[cache]`).
    pub cache: CacheConfig,
    /// Origins allowed to call the API from a browser (`[cors]`).
    pub cors: CorsConfig,
    /// Frames between keyframes in containers encoded from uploads.
    pub keyframe_interval: u32,
    /// How containers encoded from uploads predict input vertices between keyframes:
    /// `keyframe-affine` (the default), `affine` (about 1% smaller, decoding about half again
    /// slower) or `mean` (about 20% larger).
    pub motion: pmcodec_container::Motion,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            viewer: None,
            upload_dir: None,
            store: StoreConfig::default(),
            auth: AuthConfig::default(),
            limits: LimitsConfig::default(),
            cache: CacheConfig::default(),
            cors: CorsConfig::default(),
            keyframe_interval: 16,
            motion: pmcodec_container::Motion::KeyframeAffine,
        }
    }
}

/// Where assets live.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum StoreConfig {
    /// The built-in sample animations, encoded at start and kept in memory (uploads too).
    #[default]
    Samples,
    /// An empty in-memory store (tests, throwaway servers).
    Memory,
    /// A folder of `<id>.pmc` files.
    Local {
        /// The folder; it must exist when the server starts.
        path: PathBuf,
    },
    /// An S3-compatible bucket, shared by any number of servers.
    S3(S3Config),
}

/// An S3-compatible bucket (`[store] kind = "s3"`).
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct S3Config {
    /// Bucket name; must not be empty.
    pub bucket: String,
    /// Endpoint URL for S3-compatible stores (MinIO, s3s-fs, ...); empty for AWS itself.
    pub endpoint: Option<String>,
    /// Region; `None` takes it from the environment (AWS_REGION), as the AWS SDKs do.
    pub region: Option<String>,
    /// Key prefix inside the bucket (e.g. `pmcodec/`), so a bucket can be shared.
    pub prefix: String,
    /// Credentials; without them the AWS_* environment variables and instance metadata apply.
    pub access_key_id: Option<Secret>,
    /// Secret of `access_key_id`; only used together with it.
    pub secret_access_key: Option<Secret>,
    /// Allow `http://` endpoints (a store on the same host or network).
    pub allow_http: bool,
}

/// Bearer tokens (`[auth]`); compared in constant time, never logged.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct AuthConfig {
    /// Bearer token for uploads and deletes; without one, writes are refused.
    pub write_token: Option<Secret>,
    /// Bearer token for reads under /v1; without one, reads are public.
    pub read_token: Option<Secret>,
}

/// What one request, upload or job may cost (`[limits]`): every value has a default, so a file
/// sets only those it changes.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct LimitsConfig {
    /// Largest upload body.
    pub upload_bytes: u64,
    /// Largest body of any other request (they carry none).
    pub body_bytes: u64,
    /// Largest total of the files unpacked from an uploaded zip (zip bombs).
    pub unpacked_bytes: u64,
    /// Time to produce a response head; uploads get `upload_timeout_secs` for their body.
    pub request_timeout_secs: u64,
    /// Time an upload's body may take to arrive.
    pub upload_timeout_secs: u64,
    /// More ranges than this in one `Range` header get the whole representation.
    pub max_ranges: usize,
    /// Encode jobs queued or running at once; more get 503.
    pub max_pending_jobs: usize,
    /// Encode jobs running at once (each uses a blocking thread and memory).
    pub encode_concurrency: usize,
    /// Finished jobs remembered for `GET /v1/jobs/{id}`.
    pub finished_jobs_kept: usize,
    /// Requests waiting per decode worker; more get 503.
    pub decode_queue: usize,
    /// Time given to open connections after SIGINT/SIGTERM.
    pub shutdown_grace_secs: u64,
    /// Connections open at once; beyond it new ones wait in the listen backlog until one
    /// closes. Keep it well below the process's descriptor limit (`ulimit -n`).
    pub max_connections: usize,
    /// Time a client has to send a whole request head (slow-loris clients are disconnected).
    pub header_read_timeout_secs: u64,
    /// A connection with no request in progress and no byte moved for this long is closed
    /// (idle keep-alive connections). Keep it above 15 s, the job event streams' keep-alive.
    pub idle_timeout_secs: u64,
    /// Most frames an uploaded sequence may have (an OBJ per frame, or a glTF animation's
    /// duration times the frame rate).
    pub max_frames: u32,
    /// Vertices, triangles, frames and frames x vertices an upload may hold (`[limits.input]`).
    pub input: pmcodec_mesh::InputLimits,
}

impl Default for LimitsConfig {
    fn default() -> Self {
        LimitsConfig {
            upload_bytes: 512 << 20,
            body_bytes: 64 << 10,
            unpacked_bytes: 2 << 30,
            request_timeout_secs: 30,
            upload_timeout_secs: 600,
            max_ranges: 64,
            max_pending_jobs: 16,
            encode_concurrency: 1,
            finished_jobs_kept: 256,
            decode_queue: 256,
            shutdown_grace_secs: 10,
            max_connections: 512,
            header_read_timeout_secs: 10,
            idle_timeout_secs: 60,
            max_frames: 2000,
            input: pmcodec_mesh::InputLimits::default(),
        }
    }
}

impl LimitsConfig {
    /// `request_timeout_secs` as a duration, at least one second.
    pub fn request_timeout(&self) -> Duration {
        Duration::from_secs(self.request_timeout_secs.max(1))
    }
    /// `upload_timeout_secs` as a duration, at least one second.
    pub fn upload_timeout(&self) -> Duration {
        Duration::from_secs(self.upload_timeout_secs.max(1))
    }
    /// `header_read_timeout_secs` as a duration, at least one second.
    pub fn header_read_timeout(&self) -> Duration {
        Duration::from_secs(self.header_read_timeout_secs.max(1))
    }
    /// `idle_timeout_secs` as a duration, at least one second.
    pub fn idle_timeout(&self) -> Duration {
        Duration::from_secs(self.idle_timeout_secs.max(1))
    }
}

/// Memory budgets and workers of the in-process caches (`[cache]`).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct CacheConfig {
    /// Container bytes kept in memory (an LRU over assets).
    pub asset_bytes: u64,
    /// Decoder states kept in memory (an LRU over asset, level and keyframe), all workers.
    pub decode_bytes: u64,
    /// Decode worker threads; 0 = one per core.
    pub decode_workers: usize,
    /// How long an asset is served before the store is asked again whether it changed.
    pub revalidate_ms: u64,
}

impl Default for CacheConfig {
    fn default() -> Self {
        CacheConfig { asset_bytes: 512 << 20, decode_bytes: 256 << 20, decode_workers: 0, revalidate_ms: 1000 }
    }
}

/// Cross-origin requests (`[cors]`).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct CorsConfig {
    /// Origins allowed to call the API from a browser; `["*"]` allows any.
    pub allow_origins: Vec<String>,
}

impl Default for CorsConfig {
    fn default() -> Self {
        CorsConfig { allow_origins: vec!["*".into()] }
    }
}

/// A string that never appears in logs or `Debug` output (tokens, keys).
#[derive(Clone, Deserialize, Serialize, PartialEq, Eq)]
#[serde(transparent)]
pub struct Secret(pub String);

impl Secret {
    /// The text itself, for a constant-time comparison or a store client; never log it.
    pub fn expose(&self) -> &str {
        &self.0
    }
}

impl fmt::Debug for Secret {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Secret(***)")
    }
}

/// Why a configuration could not be loaded: the message names the file or variable at fault.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The configuration file could not be read.
    #[error("reading {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The configuration file is not valid TOML or JSON for [`Config`] (unknown keys are errors too).
    #[error("{path}: {detail}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message, with line and column.
        detail: String,
    },
    /// A `PMCODEC_*` variable's value does not parse as its field's type.
    #[error("environment variable {name}={value:?}: {detail}")]
    Env {
        /// The variable.
        name: &'static str,
        /// Its value.
        value: String,
        /// Why it does not parse.
        detail: String,
    },
}

impl Config {
    /// Defaults, then the file (TOML, or JSON when it ends in `.json`), then the environment.
    pub fn load(file: Option<&Path>) -> Result<Config, ConfigError> {
        let mut config = match file {
            Some(path) => Self::from_file(path)?,
            None => Config::default(),
        };
        config.apply_env(|name| std::env::var(name).ok())?;
        Ok(config)
    }

    /// Defaults, then the file alone (TOML, or JSON when it ends in `.json`); no environment.
    pub fn from_file(path: &Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read { path: path.into(), source })?;
        let parse_err = |detail: String| ConfigError::Parse { path: path.into(), detail };
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) {
            serde_json::from_str(&text).map_err(|e| parse_err(e.to_string()))
        } else {
            toml::from_str(&text).map_err(|e| parse_err(e.to_string()))
        }
    }

    /// Applies `PMCODEC_*` variables (the table is in proto/http.md). `get` is the environment,
    /// passed in so that tests need not touch the process's own.
    pub fn apply_env(&mut self, get: impl Fn(&str) -> Option<String>) -> Result<(), ConfigError> {
        fn parsed<T: std::str::FromStr>(name: &'static str, value: String) -> Result<T, ConfigError>
        where
            T::Err: fmt::Display,
        {
            value.trim().parse().map_err(|e: T::Err| ConfigError::Env { name, value, detail: e.to_string() })
        }
        fn flag(name: &'static str, value: String) -> Result<bool, ConfigError> {
            match value.trim().to_ascii_lowercase().as_str() {
                "1" | "true" | "yes" | "on" => Ok(true),
                "0" | "false" | "no" | "off" | "" => Ok(false),
                _ => Err(ConfigError::Env { name, value, detail: "use true or false".into() }),
            }
        }
        let non_empty = |name: &str| get(name).filter(|v| !v.trim().is_empty());

        if let Some(v) = non_empty("PMCODEC_LISTEN") {
            self.listen = parsed("PMCODEC_LISTEN", v)?;
        }
        if let Some(v) = get("PMCODEC_VIEWER") {
            // An empty value or "none" turns the viewer off.
            self.viewer = (!v.trim().is_empty() && v.trim() != "none").then(|| PathBuf::from(v.trim()));
        }
        if let Some(v) = non_empty("PMCODEC_STORE") {
            self.store = match v.trim() {
                "samples" => StoreConfig::Samples,
                "memory" => StoreConfig::Memory,
                "local" => match &self.store {
                    s @ StoreConfig::Local { .. } => s.clone(),
                    _ => StoreConfig::Local { path: PathBuf::from("assets") },
                },
                "s3" => match &self.store {
                    s @ StoreConfig::S3(_) => s.clone(),
                    _ => StoreConfig::S3(S3Config::default()),
                },
                _ => return Err(ConfigError::Env { name: "PMCODEC_STORE", value: v, detail: "use samples, memory, local or s3".into() }),
            };
        }
        if let Some(v) = non_empty("PMCODEC_ASSETS") {
            self.store = StoreConfig::Local { path: PathBuf::from(v.trim()) };
        }
        if let Some(v) = non_empty("PMCODEC_S3_BUCKET")
            && !matches!(self.store, StoreConfig::S3(_))
        {
            self.store = StoreConfig::S3(S3Config { bucket: v, ..Default::default() });
        }
        if let StoreConfig::S3(s3) = &mut self.store {
            if let Some(v) = non_empty("PMCODEC_S3_BUCKET") {
                s3.bucket = v.trim().to_string();
            }
            if let Some(v) = non_empty("PMCODEC_S3_ENDPOINT") {
                s3.endpoint = Some(v.trim().to_string());
            }
            if let Some(v) = non_empty("PMCODEC_S3_REGION") {
                s3.region = Some(v.trim().to_string());
            }
            if let Some(v) = get("PMCODEC_S3_PREFIX") {
                s3.prefix = v.trim().to_string();
            }
            if let Some(v) = non_empty("PMCODEC_S3_ACCESS_KEY_ID") {
                s3.access_key_id = Some(Secret(v));
            }
            if let Some(v) = non_empty("PMCODEC_S3_SECRET_ACCESS_KEY") {
                s3.secret_access_key = Some(Secret(v));
            }
            if let Some(v) = get("PMCODEC_S3_ALLOW_HTTP") {
                s3.allow_http = flag("PMCODEC_S3_ALLOW_HTTP", v)?;
            }
        }
        if let Some(v) = non_empty("PMCODEC_WRITE_TOKEN") {
            self.auth.write_token = Some(Secret(v));
        }
        if let Some(v) = non_empty("PMCODEC_READ_TOKEN") {
            self.auth.read_token = Some(Secret(v));
        }
        if let Some(v) = non_empty("PMCODEC_UPLOAD_LIMIT_BYTES") {
            self.limits.upload_bytes = parsed("PMCODEC_UPLOAD_LIMIT_BYTES", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_REQUEST_TIMEOUT_SECS") {
            self.limits.request_timeout_secs = parsed("PMCODEC_REQUEST_TIMEOUT_SECS", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_MAX_CONNECTIONS") {
            self.limits.max_connections = parsed("PMCODEC_MAX_CONNECTIONS", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_HEADER_READ_TIMEOUT_SECS") {
            self.limits.header_read_timeout_secs = parsed("PMCODEC_HEADER_READ_TIMEOUT_SECS", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_IDLE_TIMEOUT_SECS") {
            self.limits.idle_timeout_secs = parsed("PMCODEC_IDLE_TIMEOUT_SECS", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_MAX_PENDING_JOBS") {
            self.limits.max_pending_jobs = parsed("PMCODEC_MAX_PENDING_JOBS", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_MAX_FRAMES") {
            self.limits.max_frames = parsed("PMCODEC_MAX_FRAMES", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_UPLOAD_DIR") {
            self.upload_dir = Some(PathBuf::from(v.trim()));
        }
        if let Some(v) = non_empty("PMCODEC_ASSET_CACHE_BYTES") {
            self.cache.asset_bytes = parsed("PMCODEC_ASSET_CACHE_BYTES", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_DECODE_CACHE_BYTES") {
            self.cache.decode_bytes = parsed("PMCODEC_DECODE_CACHE_BYTES", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_DECODE_WORKERS") {
            self.cache.decode_workers = parsed("PMCODEC_DECODE_WORKERS", v)?;
        }
        if let Some(v) = non_empty("PMCODEC_CORS_ORIGINS") {
            self.cors.allow_origins = v.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect();
        }
        Ok(())
    }

    /// Checks what serde cannot: values that parse but make no sense.
    pub fn validate(&self) -> Result<(), String> {
        if let StoreConfig::S3(s3) = &self.store
            && s3.bucket.trim().is_empty()
        {
            return Err("store.kind = \"s3\" needs store.bucket (or PMCODEC_S3_BUCKET)".into());
        }
        let l = &self.limits;
        if l.upload_bytes == 0 || l.max_pending_jobs == 0 || l.encode_concurrency == 0 || l.max_connections == 0 || l.max_frames == 0 {
            return Err("limits.upload_bytes, max_pending_jobs, encode_concurrency, max_connections and max_frames must be positive".into());
        }
        // An empty token would be matched by `Authorization: Bearer ` (or by nothing at all).
        for (name, token) in [("write_token", &self.auth.write_token), ("read_token", &self.auth.read_token)] {
            if token.as_ref().is_some_and(|t| t.expose().trim().is_empty()) {
                return Err(format!("auth.{name} is empty: give a token, or leave the setting out"));
            }
        }
        if self.cors.allow_origins.iter().any(|o| o != "*" && axum::http::HeaderValue::from_str(o).is_err()) {
            return Err(format!("cors.allow_origins {:?}: not valid header values", self.cors.allow_origins));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: HashMap<String, String> = pairs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        move |k| map.get(k).cloned()
    }

    #[test]
    fn toml_file_then_environment() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("server.toml");
        std::fs::write(
            &path,
            "listen = \"0.0.0.0:9000\"\n[store]\nkind = \"s3\"\nbucket = \"meshes\"\nendpoint = \"http://127.0.0.1:9100\"\nallow_http = true\n[limits]\nupload_bytes = 1000\n",
        )
        .unwrap();
        let mut c = Config::from_file(&path).unwrap();
        assert_eq!(c.listen.port(), 9000);
        assert_eq!(c.limits.upload_bytes, 1000);
        assert_eq!(c.limits.body_bytes, LimitsConfig::default().body_bytes, "unset fields keep defaults");
        c.apply_env(env(&[("PMCODEC_S3_PREFIX", "team/"), ("PMCODEC_WRITE_TOKEN", "tok"), ("PMCODEC_LISTEN", "127.0.0.1:1")])).unwrap();
        let StoreConfig::S3(s3) = &c.store else { panic!("{:?}", c.store) };
        assert_eq!((s3.bucket.as_str(), s3.prefix.as_str(), s3.allow_http), ("meshes", "team/", true));
        assert_eq!(c.auth.write_token, Some(Secret("tok".into())));
        assert_eq!(c.listen.port(), 1);
        assert!(c.validate().is_ok());
        assert!(!format!("{c:?}").contains("tok\""), "secrets stay out of Debug output");
    }

    #[test]
    fn json_files_and_bad_values_are_reported() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.json");
        std::fs::write(&path, r#"{"store": {"kind": "local", "path": "/srv/assets"}, "cache": {"decode_workers": 3}, "motion": "affine"}"#)
            .unwrap();
        let c = Config::from_file(&path).unwrap();
        assert_eq!(c.store, StoreConfig::Local { path: "/srv/assets".into() });
        assert_eq!(c.motion, pmcodec_container::Motion::Affine);
        assert_eq!(c.cache.decode_workers, 3);
        std::fs::write(&path, r#"{"lisen": "x"}"#).unwrap();
        let e = Config::from_file(&path).unwrap_err().to_string();
        assert!(e.contains("lisen"), "unknown keys are named: {e}");
        let mut c = Config::default();
        let e = c.apply_env(env(&[("PMCODEC_UPLOAD_LIMIT_BYTES", "lots")])).unwrap_err().to_string();
        assert!(e.contains("PMCODEC_UPLOAD_LIMIT_BYTES"), "{e}");
        c.apply_env(env(&[("PMCODEC_STORE", "s3")])).unwrap();
        assert!(c.validate().unwrap_err().contains("bucket"));
    }

    #[test]
    fn connection_and_job_bounds_from_environment_and_empty_tokens_refused() {
        let mut c = Config::default();
        c.apply_env(env(&[
            ("PMCODEC_MAX_CONNECTIONS", "7"),
            ("PMCODEC_HEADER_READ_TIMEOUT_SECS", "3"),
            ("PMCODEC_IDLE_TIMEOUT_SECS", "20"),
            ("PMCODEC_MAX_PENDING_JOBS", "2"),
            ("PMCODEC_MAX_FRAMES", "90"),
            ("PMCODEC_UPLOAD_DIR", "/var/tmp"),
        ]))
        .unwrap();
        let l = &c.limits;
        assert_eq!((l.max_connections, l.header_read_timeout_secs, l.idle_timeout_secs), (7, 3, 20));
        assert_eq!((l.max_pending_jobs, l.max_frames), (2, 90));
        assert_eq!(c.upload_dir, Some(PathBuf::from("/var/tmp")));
        assert!(c.validate().is_ok());
        c.limits.max_connections = 0;
        assert!(c.validate().unwrap_err().contains("max_connections"));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, "[auth]\nwrite_token = \"\"\n").unwrap();
        let c = Config::from_file(&path).unwrap();
        assert!(c.validate().unwrap_err().contains("auth.write_token is empty"));
    }

    #[test]
    fn assets_folder_and_viewer_from_environment() {
        let mut c = Config { viewer: Some("web/dist".into()), ..Default::default() };
        c.apply_env(env(&[("PMCODEC_ASSETS", "/data"), ("PMCODEC_VIEWER", "none")])).unwrap();
        assert_eq!(c.store, StoreConfig::Local { path: "/data".into() });
        assert_eq!(c.viewer, None);
    }
}
