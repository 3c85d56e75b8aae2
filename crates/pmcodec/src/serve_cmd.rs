//! `pmcodec serve`: the HTTP server (crates/pmcodec-server) over a folder of `.pmc` files, an S3
//! bucket (configuration file or environment), or the built-in samples.
//!
//! Settings apply in this order, later ones winning: defaults, `--config FILE`, `PMCODEC_*`
//! environment variables, then the flags given here.

use crate::Exit;
use anyhow::Context;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Folder of <id>.pmc files to serve and to store uploads in (default: the built-in sample
    /// animations, encoded at start and kept in memory).
    #[arg(long, value_name = "DIR")]
    pub assets: Option<PathBuf>,
    /// Address to listen on [default: 127.0.0.1:8080].
    #[arg(long, value_name = "ADDR")]
    pub listen: Option<std::net::SocketAddr>,
    /// Configuration file, TOML (or JSON when it ends in .json); see proto/http.md.
    #[arg(long, value_name = "FILE", env = "PMCODEC_CONFIG")]
    pub config: Option<PathBuf>,
    /// Folder of the built viewer, served at / [default: web/dist when it exists].
    #[arg(long, value_name = "DIR")]
    pub viewer: Option<PathBuf>,
    /// Serve no viewer even if web/dist exists.
    #[arg(long, conflicts_with = "viewer")]
    pub no_viewer: bool,
    /// Connections open at once; more wait in the listen backlog [default: 512].
    #[arg(long, value_name = "N")]
    pub max_connections: Option<usize>,
    /// Seconds a client has to send a request head [default: 10].
    #[arg(long, value_name = "SECS")]
    pub header_read_timeout: Option<u64>,
    /// Seconds after which a connection with nothing in progress is closed [default: 60].
    #[arg(long, value_name = "SECS")]
    pub idle_timeout: Option<u64>,
    /// Most frames an uploaded sequence may have [default: 2000].
    #[arg(long, value_name = "N")]
    pub max_frames: Option<u32>,
    /// Folder where upload bodies wait for their encode job [default: the system's temporary
    /// folder].
    #[arg(long, value_name = "DIR")]
    pub upload_dir: Option<PathBuf>,
}

pub fn run(args: ServeArgs, quiet: bool) -> Result<(), Exit> {
    let mut config = pmcodec_server::Config::load(args.config.as_deref()).map_err(|e| Exit(crate::EXIT_BAD_INPUT, e.into()))?;
    if let Some(dir) = args.assets {
        config.store = pmcodec_server::config::StoreConfig::Local { path: dir };
    }
    if let Some(addr) = args.listen {
        config.listen = addr;
    }
    let l = &mut config.limits;
    if let Some(n) = args.max_connections {
        l.max_connections = n;
    }
    if let Some(s) = args.header_read_timeout {
        l.header_read_timeout_secs = s;
    }
    if let Some(s) = args.idle_timeout {
        l.idle_timeout_secs = s;
    }
    if let Some(n) = args.max_frames {
        l.max_frames = n;
    }
    if let Some(dir) = args.upload_dir {
        config.upload_dir = Some(dir);
    }
    if args.no_viewer {
        config.viewer = None;
    } else if let Some(dir) = args.viewer {
        config.viewer = Some(dir);
    } else if config.viewer.is_none() && std::env::var_os("PMCODEC_VIEWER").is_none() {
        // The default viewer folder, unless the environment turned the viewer off
        // (PMCODEC_VIEWER=none or empty).
        config.viewer = Some(PathBuf::from("web/dist")).filter(|p| p.is_dir());
    }
    config.validate().map_err(|e| Exit(crate::EXIT_BAD_INPUT, anyhow::anyhow!("configuration: {e}")))?;
    let viewer = config.viewer.clone();
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build().context("starting the async runtime")?;
    rt.block_on(pmcodec_server::run(config, |addr| {
        if !quiet {
            eprintln!(
                "pmcodec: serving on http://{addr}/ (viewer: {})",
                viewer.as_ref().map_or("none".into(), |p| p.display().to_string())
            );
        }
    }))
    .context("serving")?;
    Ok(())
}
