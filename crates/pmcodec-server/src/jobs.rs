//! Encode jobs: an upload becomes a job that parses and encodes on a blocking thread, then
//! stores the container in one atomic write. Until that write the asset does not exist; a job
//! that fails anywhere before it writes nothing. Without `replace=true` that write is
//! create-only, so it never replaces an asset another server created while the job ran.
//!
//! Jobs live in the memory of the server that accepted the upload (the asset itself goes to the
//! shared store): behind a load balancer, job URLs need that server (sticky routing), or a
//! client polls `GET /v1/assets/{id}` on any server until the asset appears.

use crate::store::PutMode;
use crate::upload::{UploadBody, UploadOptions};
use crate::{ApiError, AppState, AssetId, StoreError};
use pmcodec_container::{EncodeOptions, encode};
use serde::Serialize;
use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use tokio::sync::{Semaphore, watch};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum JobState {
    Queued,
    Running,
    Succeeded,
    Failed,
}

impl JobState {
    pub fn is_finished(self) -> bool {
        matches!(self, JobState::Succeeded | JobState::Failed)
    }
    pub fn name(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
        }
    }
}

/// What `GET /v1/jobs/{id}` returns and each SSE event carries.
#[derive(Clone, Debug, Serialize)]
pub struct JobStatus {
    pub id: String,
    pub asset: String,
    pub state: JobState,
    /// What the job is doing: queued, parsing, encoding, storing, done.
    pub stage: &'static str,
    /// 0 to 1.
    pub progress: f64,
    pub frames_done: u32,
    pub frames_total: Option<u32>,
    /// Why it failed.
    pub message: Option<String>,
    /// What was uploaded.
    pub input: String,
    pub created_unix_ms: u64,
    pub finished_unix_ms: Option<u64>,
    /// The asset's metadata URL, once it exists.
    pub asset_url: Option<String>,
    pub status_url: String,
    pub events_url: String,
}

struct Inner {
    jobs: HashMap<String, watch::Sender<JobStatus>>,
    finished: VecDeque<String>,
    pending: usize,
    pending_assets: HashSet<AssetId>,
}

pub struct Jobs {
    inner: Mutex<Inner>,
    /// Encodes running at once.
    permits: Arc<Semaphore>,
    max_pending: usize,
    keep_finished: usize,
}

fn now_ms() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_millis() as u64)
}

/// Job ids are UUIDs in their 32-hex-digit form.
pub fn valid_job_id(s: &str) -> bool {
    s.len() == 32 && s.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

impl Jobs {
    pub fn new(concurrency: usize, max_pending: usize, keep_finished: usize) -> Jobs {
        Jobs {
            inner: Mutex::new(Inner { jobs: HashMap::new(), finished: VecDeque::new(), pending: 0, pending_assets: HashSet::new() }),
            permits: Arc::new(Semaphore::new(concurrency.max(1))),
            max_pending: max_pending.max(1),
            keep_finished,
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        // Each critical section leaves the maps consistent before anything can panic.
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub fn pending(&self) -> usize {
        self.lock().pending
    }

    pub fn is_pending(&self, id: &AssetId) -> bool {
        self.lock().pending_assets.contains(id)
    }

    pub fn status(&self, job: &str) -> Option<JobStatus> {
        self.lock().jobs.get(job).map(|s| s.borrow().clone())
    }

    pub fn subscribe(&self, job: &str) -> Option<watch::Receiver<JobStatus>> {
        self.lock().jobs.get(job).map(|s| s.subscribe())
    }

    /// Registers a job and starts it; errors when too many are pending or the asset already
    /// has one.
    pub fn submit(&self, app: &AppState, asset: AssetId, body: UploadBody, opts: UploadOptions) -> Result<JobStatus, ApiError> {
        let id = uuid::Uuid::new_v4().simple().to_string();
        let status = JobStatus {
            id: id.clone(),
            asset: asset.to_string(),
            state: JobState::Queued,
            stage: "queued",
            progress: 0.0,
            frames_done: 0,
            frames_total: None,
            message: None,
            input: body.describe(),
            created_unix_ms: now_ms(),
            finished_unix_ms: None,
            asset_url: None,
            status_url: format!("/v1/jobs/{id}"),
            events_url: format!("/v1/jobs/{id}/events"),
        };
        let (tx, _) = watch::channel(status.clone());
        {
            let mut inner = self.lock();
            if inner.pending >= self.max_pending {
                return Err(ApiError::Busy(format!("{} encode jobs are already queued or running; retry later", inner.pending)));
            }
            if inner.pending_assets.contains(&asset) {
                return Err(ApiError::Conflict(format!("an encode job for asset {asset} is already queued or running")));
            }
            inner.pending += 1;
            inner.pending_assets.insert(asset.clone());
            inner.jobs.insert(id.clone(), tx.clone());
        }
        tracing::info!(job = %id, asset = %asset, input = %status.input, "encode job queued");
        // The job outlives the request: it gets a span of its own, not the request's.
        let span = tracing::info_span!(parent: None, "job", id = %id, asset = %asset);
        tokio::spawn(tracing::Instrument::instrument(run(app.clone(), tx, asset, body, opts), span));
        Ok(status)
    }

    fn finish(&self, job: &str, asset: &AssetId) {
        let mut inner = self.lock();
        inner.pending = inner.pending.saturating_sub(1);
        inner.pending_assets.remove(asset);
        inner.finished.push_back(job.to_string());
        // Each pass removes one finished job: bounded by the queue's length.
        while inner.finished.len() > self.keep_finished {
            if let Some(old) = inner.finished.pop_front() {
                inner.jobs.remove(&old);
            }
        }
    }
}

fn created_meanwhile(asset: &AssetId) -> String {
    format!("asset {asset} was created while this job ran; upload again with replace=true to replace it")
}

async fn run(app: AppState, tx: watch::Sender<JobStatus>, asset: AssetId, body: UploadBody, opts: UploadOptions) {
    let job_id = tx.borrow().id.clone();
    // The semaphore is never closed, so acquiring only waits for a free slot.
    let permit = app.jobs.permits.clone().acquire_owned().await;
    tx.send_modify(|s| {
        s.state = JobState::Running;
        s.stage = "parsing";
    });
    let encode_opts =
        EncodeOptions { keyframe_interval: app.config.keyframe_interval, motion: app.config.motion, ..EncodeOptions::default() };
    let progress_tx = tx.clone();
    let replace = opts.replace;
    let work = tokio::task::spawn_blocking(move || -> Result<Vec<u8>, String> {
        let seq = body.into_sequence(&opts)?;
        let frames = seq.frame_count() as u32;
        progress_tx.send_modify(|s| {
            s.stage = "encoding";
            s.frames_total = Some(frames);
        });
        encode(&seq, &encode_opts, |f| {
            progress_tx.send_modify(|s| {
                s.frames_done = (f as u32 + 1).min(frames);
                // Storing is the last few percent.
                s.progress = 0.95 * s.frames_done as f64 / frames.max(1) as f64;
            })
        })
        .map_err(|e| format!("encoding: {e}"))
    })
    .await;
    drop(permit);
    let result = match work {
        // Without replace=true, an asset that appeared while the job ran (an upload through
        // another server sharing the store) is kept, and the job fails saying so. This check
        // only saves the write; the create-only write below is what keeps the asset when
        // another server creates it after this check.
        Ok(Ok(_)) if !replace && matches!(app.store.head(&asset).await, Ok(Some(_))) => Err(created_meanwhile(&asset)),
        Ok(Ok(bytes)) => {
            tx.send_modify(|s| s.stage = "storing");
            // The one write of the job: atomic in every store, so the asset appears whole.
            let mode = if replace { PutMode::Overwrite } else { PutMode::Create };
            match app.store.put(&asset, bytes.into(), mode).await {
                Ok(_) => {
                    app.assets.forget(&asset);
                    // Describe it now, which also writes its listing metadata, so that no
                    // server has to read the container to list it (best effort: the asset is
                    // stored either way).
                    if let Err(e) = app.assets.describe(&asset).await {
                        tracing::warn!(asset = %asset, error = %e, "describing the stored asset failed");
                    }
                    Ok(())
                }
                Err(StoreError::AlreadyExists(_)) => Err(created_meanwhile(&asset)),
                Err(e) => {
                    tracing::error!(error = %e, "storing the encoded asset failed");
                    Err("storing the asset failed; the server log has the details".to_string())
                }
            }
        }
        Ok(Err(message)) => Err(message),
        Err(join) => Err(format!("the encoder stopped unexpectedly: {join}")),
    };
    match &result {
        Ok(()) => {
            app.metrics.jobs_succeeded.fetch_add(1, Ordering::Relaxed);
            tracing::info!(job = %job_id, asset = %asset, "encode job succeeded");
        }
        Err(m) => {
            app.metrics.jobs_failed.fetch_add(1, Ordering::Relaxed);
            tracing::warn!(job = %job_id, asset = %asset, message = %m, "encode job failed");
        }
    }
    // Release the asset before announcing the outcome, so a client reacting to "succeeded"
    // or "failed" can submit the next job for it at once.
    app.jobs.finish(&job_id, &asset);
    tx.send_modify(|s| {
        s.finished_unix_ms = Some(now_ms());
        s.stage = "done";
        match result {
            Ok(()) => {
                s.state = JobState::Succeeded;
                s.progress = 1.0;
                s.asset_url = Some(format!("/v1/assets/{asset}"));
            }
            Err(m) => {
                s.state = JobState::Failed;
                s.message = Some(m);
            }
        }
    });
}
