//! Encode jobs: an upload becomes a job that parses and encodes on a blocking thread, then
//! stores the container in one atomic write. Until that write the asset does not exist; a job
//! that fails anywhere before it writes nothing. Without `replace=true` that write is
//! create-only, so it never replaces an asset another server created while the job ran.
//!
//! A place in the queue is taken ([`Jobs::reserve`]) before an upload's body is read, so a full
//! queue refuses at once; the body waits in a temporary file, not in memory. A job can be
//! cancelled (`DELETE /v1/jobs/{id}`): a queued one never starts, a running one stops at its
//! next frame or stage, and a cancelled job writes nothing.
//!
//! Jobs live in the memory of the server that accepted the upload (the asset itself goes to the
//! shared store): behind a load balancer, job URLs need that server (sticky routing), or a
//! client polls `GET /v1/assets/{id}` on any server until the asset appears.

use crate::store::PutMode;
use crate::upload::{UploadBody, UploadOptions};
use crate::{ApiError, AppState, AssetId, StoreError};
use pmcodec_container::{ContainerError, EncodeOptions, encode_until};
use serde::Serialize;
use std::collections::{HashMap, HashSet, VecDeque};
use std::ops::ControlFlow;
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
    Cancelled,
}

impl JobState {
    pub fn is_finished(self) -> bool {
        matches!(self, JobState::Succeeded | JobState::Failed | JobState::Cancelled)
    }
    pub fn name(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
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
    /// A `DELETE` asked for it to stop (it ends `cancelled` unless it had finished storing).
    pub cancel_requested: bool,
    /// What was uploaded.
    pub input: String,
    pub created_unix_ms: u64,
    pub finished_unix_ms: Option<u64>,
    /// The asset's metadata URL, once it exists.
    pub asset_url: Option<String>,
    pub status_url: String,
    pub events_url: String,
}

/// A job as the registry holds it: its status, and the flag its work checks between frames.
struct Entry {
    status: watch::Sender<JobStatus>,
    cancel: watch::Sender<bool>,
}

struct Inner {
    jobs: HashMap<String, Entry>,
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
        self.lock().jobs.get(job).map(|e| e.status.borrow().clone())
    }

    pub fn subscribe(&self, job: &str) -> Option<watch::Receiver<JobStatus>> {
        self.lock().jobs.get(job).map(|e| e.status.subscribe())
    }

    /// Asks a queued or running job to stop; the status it returns has `cancel_requested`
    /// set, and the job's events end with `cancelled` once it has. A job that has finished
    /// is a conflict.
    pub fn cancel(&self, job: &str) -> Result<JobStatus, ApiError> {
        let inner = self.lock();
        let e = inner.jobs.get(job).ok_or_else(|| ApiError::NotFound(format!("no job {job} on this server")))?;
        let state = e.status.borrow().state;
        if state.is_finished() {
            return Err(ApiError::Conflict(format!("job {job} has finished ({}); there is nothing to cancel", state.name())));
        }
        e.cancel.send_replace(true);
        e.status.send_modify(|s| s.cancel_requested = true);
        Ok(e.status.borrow().clone())
    }

    /// Takes a place in the queue for an upload of `asset`, before its body is read: errors
    /// at once when the queue is full or the asset has a job. The place is given back when the
    /// reservation is dropped unless [`Jobs::submit`] turned it into a job.
    pub fn reserve(&self, app: &AppState, asset: AssetId) -> Result<Reservation, ApiError> {
        let mut inner = self.lock();
        if inner.pending >= self.max_pending {
            return Err(ApiError::Busy(format!(
                "{} encode jobs are already queued, running or being uploaded (limits.max_pending_jobs); retry later",
                inner.pending
            )));
        }
        if inner.pending_assets.contains(&asset) {
            return Err(ApiError::Conflict(format!("an encode job for asset {asset} is already queued or running")));
        }
        inner.pending += 1;
        inner.pending_assets.insert(asset.clone());
        Ok(Reservation { app: app.clone(), asset: Some(asset) })
    }

    fn release(&self, asset: &AssetId) {
        let mut inner = self.lock();
        inner.pending = inner.pending.saturating_sub(1);
        inner.pending_assets.remove(asset);
    }

    /// Turns a reservation into a job and starts it.
    pub fn submit(&self, app: &AppState, mut place: Reservation, body: UploadBody, opts: UploadOptions) -> Result<JobStatus, ApiError> {
        let asset = place.asset.take().ok_or_else(|| ApiError::Internal("a reservation used twice".into()))?;
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
            cancel_requested: false,
            input: body.describe(),
            created_unix_ms: now_ms(),
            finished_unix_ms: None,
            asset_url: None,
            status_url: format!("/v1/jobs/{id}"),
            events_url: format!("/v1/jobs/{id}/events"),
        };
        let (tx, _) = watch::channel(status.clone());
        let (cancel, cancelled) = watch::channel(false);
        // The place reserved for this upload is the job's now (released in `finish`).
        self.lock().jobs.insert(id.clone(), Entry { status: tx.clone(), cancel });
        tracing::info!(job = %id, asset = %asset, input = %status.input, "encode job queued");
        // The job outlives the request: it gets a span of its own, not the request's.
        let span = tracing::info_span!(parent: None, "job", id = %id, asset = %asset);
        tokio::spawn(tracing::Instrument::instrument(run(app.clone(), tx, cancelled, asset, body, opts), span));
        Ok(status)
    }

    fn finish(&self, job: &str, asset: &AssetId) {
        self.release(asset);
        let mut inner = self.lock();
        inner.finished.push_back(job.to_string());
        // Each pass removes one finished job: bounded by the queue's length.
        while inner.finished.len() > self.keep_finished {
            if let Some(old) = inner.finished.pop_front() {
                inner.jobs.remove(&old);
            }
        }
    }
}

/// A place in the jobs queue held by an upload whose body is being read.
pub struct Reservation {
    app: AppState,
    /// `None` once a job holds the place.
    asset: Option<AssetId>,
}

impl Drop for Reservation {
    fn drop(&mut self) {
        if let Some(asset) = self.asset.take() {
            self.app.jobs.release(&asset);
        }
    }
}

fn created_meanwhile(asset: &AssetId) -> String {
    format!("asset {asset} was created while this job ran; upload again with replace=true to replace it")
}

/// Why the blocking part of a job stopped without a container.
enum Stopped {
    /// Cancelled between parsing and encoding, or between two encoded frames.
    Cancelled,
    /// Bad input or an encoder error; the message is the job's.
    Failed(String),
}

enum Outcome {
    Stored,
    Failed(String),
    Cancelled,
}

async fn run(
    app: AppState,
    tx: watch::Sender<JobStatus>,
    mut cancelled: watch::Receiver<bool>,
    asset: AssetId,
    body: UploadBody,
    opts: UploadOptions,
) {
    let job_id = tx.borrow().id.clone();
    // The semaphore is never closed, so acquiring only waits for a free slot (or a cancel).
    let permit = tokio::select! {
        p = app.jobs.permits.clone().acquire_owned() => p.ok(),
        _ = cancelled.wait_for(|c| *c) => None,
    };
    let outcome = match permit {
        None => {
            // Cancelled while queued: the body's temporary file goes with `body`.
            drop(body);
            Outcome::Cancelled
        }
        Some(permit) => {
            let outcome = encode_and_store(&app, &tx, cancelled, &asset, body, opts).await;
            drop(permit);
            outcome
        }
    };
    match &outcome {
        Outcome::Stored => {
            app.metrics.jobs_succeeded.fetch_add(1, Ordering::Relaxed);
            tracing::info!(job = %job_id, asset = %asset, "encode job succeeded");
        }
        Outcome::Failed(m) => {
            app.metrics.jobs_failed.fetch_add(1, Ordering::Relaxed);
            tracing::warn!(job = %job_id, asset = %asset, message = %m, "encode job failed");
        }
        Outcome::Cancelled => tracing::info!(job = %job_id, asset = %asset, "encode job cancelled"),
    }
    // Release the asset before announcing the outcome, so a client reacting to "succeeded"
    // or "failed" can submit the next job for it at once.
    app.jobs.finish(&job_id, &asset);
    tx.send_modify(|s| {
        s.finished_unix_ms = Some(now_ms());
        s.stage = "done";
        match outcome {
            Outcome::Stored => {
                s.state = JobState::Succeeded;
                s.progress = 1.0;
                s.asset_url = Some(format!("/v1/assets/{asset}"));
            }
            Outcome::Failed(m) => {
                s.state = JobState::Failed;
                s.message = Some(m);
            }
            Outcome::Cancelled => {
                s.state = JobState::Cancelled;
                s.message = Some("cancelled by a DELETE request; nothing was stored".into());
            }
        }
    });
}

/// Parses, encodes and stores, checking for a cancel between stages and frames.
async fn encode_and_store(
    app: &AppState,
    tx: &watch::Sender<JobStatus>,
    cancelled: watch::Receiver<bool>,
    asset: &AssetId,
    body: UploadBody,
    opts: UploadOptions,
) -> Outcome {
    if *cancelled.borrow() {
        return Outcome::Cancelled;
    }
    tx.send_modify(|s| {
        s.state = JobState::Running;
        s.stage = "parsing";
    });
    let encode_opts =
        EncodeOptions { keyframe_interval: app.config.keyframe_interval, motion: app.config.motion, ..EncodeOptions::default() };
    let progress_tx = tx.clone();
    let replace = opts.replace;
    let stop = cancelled.clone();
    let work = tokio::task::spawn_blocking(move || -> Result<Vec<u8>, Stopped> {
        let seq = body.into_sequence(&opts).map_err(Stopped::Failed)?;
        // The body's temporary file is gone with `body`; only the parsed frames remain.
        let frames = seq.frame_count() as u32;
        if *stop.borrow() {
            return Err(Stopped::Cancelled);
        }
        progress_tx.send_modify(|s| {
            s.stage = "encoding";
            s.frames_total = Some(frames);
        });
        encode_until(&seq, &encode_opts, |f| {
            if *stop.borrow() {
                return ControlFlow::Break(());
            }
            progress_tx.send_modify(|s| {
                s.frames_done = (f as u32 + 1).min(frames);
                // Storing is the last few percent.
                s.progress = 0.95 * s.frames_done as f64 / frames.max(1) as f64;
            });
            ControlFlow::Continue(())
        })
        .map_err(|e| match e {
            ContainerError::Cancelled => Stopped::Cancelled,
            e => Stopped::Failed(format!("encoding: {e}")),
        })
    })
    .await;
    let bytes = match work {
        Ok(Ok(bytes)) => bytes,
        Ok(Err(Stopped::Cancelled)) => return Outcome::Cancelled,
        Ok(Err(Stopped::Failed(message))) => return Outcome::Failed(message),
        Err(join) if join.is_panic() => {
            tracing::error!("the encoder panicked (a bug)");
            return Outcome::Failed("the encoder stopped unexpectedly (a bug); the server log has the details".into());
        }
        Err(join) => return Outcome::Failed(format!("the encoder stopped unexpectedly: {join}")),
    };
    // The last point where a cancel is honoured: the store write below is one atomic step.
    if *cancelled.borrow() {
        return Outcome::Cancelled;
    }
    // Without replace=true, an asset that appeared while the job ran (an upload through
    // another server sharing the store) is kept, and the job fails saying so. This check
    // only saves the write; the create-only write below is what keeps the asset when
    // another server creates it after this check.
    if !replace && matches!(app.store.head(asset).await, Ok(Some(_))) {
        return Outcome::Failed(created_meanwhile(asset));
    }
    tx.send_modify(|s| s.stage = "storing");
    // The one write of the job: atomic in every store, so the asset appears whole.
    let mode = if replace { PutMode::Overwrite } else { PutMode::Create };
    match app.store.put(asset, bytes.into(), mode).await {
        Ok(_) => {
            app.assets.forget(asset);
            // Describe it now, which also writes its listing metadata, so that no
            // server has to read the container to list it (best effort: the asset is
            // stored either way).
            if let Err(e) = app.assets.describe(asset).await {
                tracing::warn!(asset = %asset, error = %e, "describing the stored asset failed");
            }
            Outcome::Stored
        }
        Err(StoreError::AlreadyExists(_)) => Outcome::Failed(created_meanwhile(asset)),
        Err(e) => {
            tracing::error!(error = %e, "storing the encoded asset failed");
            Outcome::Failed("storing the asset failed; the server log has the details".to_string())
        }
    }
}
