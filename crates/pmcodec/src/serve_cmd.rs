//! `pmcodec serve`: the HTTP server over a folder of `.pmc` files, or the built-in samples.

use crate::Exit;
use anyhow::Context;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Folder of .pmc files to serve (default: the built-in sample animations).
    #[arg(long, env = "PMCODEC_ASSETS")]
    pub assets: Option<PathBuf>,
    /// Address to listen on.
    #[arg(long, env = "PMCODEC_LISTEN", default_value = "127.0.0.1:8080")]
    pub listen: std::net::SocketAddr,
    /// Folder of the built viewer, served at / (default: web/dist when it exists).
    #[arg(long, env = "PMCODEC_VIEWER")]
    pub viewer: Option<PathBuf>,
}

pub fn run(args: ServeArgs, quiet: bool) -> Result<(), Exit> {
    let viewer = args.viewer.or_else(|| Some(PathBuf::from("web/dist")).filter(|p| p.is_dir()));
    let config = pmcodec_server::Config { assets: args.assets, listen: args.listen, viewer: viewer.clone() };
    let rt = tokio::runtime::Runtime::new().context("starting the async runtime")?;
    rt.block_on(pmcodec_server::serve(config, |addr| {
        if !quiet {
            eprintln!("pmcodec: serving on http://{addr}/ (viewer: {})", viewer.as_ref().map_or("none".into(), |p| p.display().to_string()));
        }
    }))
    .context("serving")?;
    Ok(())
}
