//! `assetfield edit`: the scene editor in the browser, served from this process.

use super::backend::{BackendArg, device};
use anyhow::{Context, Result, bail};
use assetfield_editor::{EditSession, SessionOptions};
use clap::Args;
use std::io::Write;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct EditArgs {
    /// The asset library to edit (written by `assetfield mine`, `refine` or `library merge`).
    pub library: PathBuf,
    /// The file Save writes (default: LIB/edited.ron). If it exists the session starts from
    /// it: an edit script (`Scene(base: ..., edits: [...])`) continues its edits, a whole
    /// layout script is edited in place. Otherwise the session starts from LIB/layout.ron and
    /// Save writes `Scene(base: "<path to LIB/layout.ron>", edits: [...])`.
    #[arg(long, value_name = "FILE")]
    pub layout: Option<PathBuf>,
    /// Port to listen on (0: any free port; the first line on stdout says which).
    #[arg(long, default_value_t = 8737)]
    pub port: u16,
    /// Address to listen on. The default serves this machine only; anything else exposes
    /// the editor (token-guarded, unencrypted) to the network.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: IpAddr,
    /// Where to render: gpu (wgpu; an error without an adapter), cpu, or auto: the GPU when
    /// a hardware wgpu adapter exists, else the CPU with one line saying so.
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
    /// Seconds a render on the CPU may take before it is cancelled (the request then
    /// answers 400 and the session goes on). Edits are bounded by the layout limits: a
    /// session's layout holds at most 20,000 instances (or twice its starting count) unless
    /// `--limit instances=N` says otherwise.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    pub render_budget: f64,
}

pub fn edit(a: EditArgs) -> Result<()> {
    if !a.library.is_dir() {
        bail!(
            "{} is not a folder (the asset library written by `assetfield mine`)",
            a.library.display()
        );
    }
    let gpu = device(a.backend)?.map(|ctx| (ctx, a.backend == BackendArg::Auto));
    if !(a.render_budget.is_finite() && a.render_budget > 0.0) {
        bail!("--render-budget must be a positive number of seconds, got {}", a.render_budget);
    }
    let opts = SessionOptions {
        layout: a.layout.clone(),
        render_budget: Some(std::time::Duration::from_secs_f64(a.render_budget.min(86_400.0))),
        ..Default::default()
    };
    let session = EditSession::open(&a.library, &opts, gpu)
        .with_context(|| format!("opening {} for editing", a.library.display()))?;
    let backend = session.backend();
    let save = session.save_path().display().to_string();
    let instances = session.layout().objects().count();
    if !a.host.is_loopback() {
        eprintln!(
            "assetfield: listening on {} makes the editor reachable from other machines (anyone with the URL can edit)",
            a.host
        );
    }
    let token = assetfield_editor::random_token();
    assetfield_editor::run(
        session,
        SocketAddr::new(a.host, a.port),
        token,
        |url| {
            // the first line on stdout is the URL, for people and for scripts
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "listening on {url}");
            let _ = out.flush();
            eprintln!(
                "editing {} ({instances} instances, rendering on the {backend}); Save writes {save}; Ctrl-C stops",
                a.library.display()
            );
        },
        assetfield_core::interrupt::requested,
    )
    .with_context(|| format!("serving on {}:{}", a.host, a.port))?;
    assetfield_core::interrupt::reset();
    Ok(())
}
