//! `--backend`: which renderer a command runs on (the GPU through wgpu, or the CPU reference
//! renderer), shared by `compose`, `edit` and the benches.

use anyhow::{Context, Result};
use assetfield_gpu::{Backend, BackendChoice, GpuContext, select_backend};
use clap::ValueEnum;

/// What renders: `gpu` (error without an adapter), `cpu`, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BackendArg {
    Gpu,
    Cpu,
    Auto,
}

/// The device for `--backend`: the GPU context, or `None` for the CPU (after the one line
/// saying why, when `auto` found no adapter).
pub(crate) fn device(choice: BackendArg) -> Result<Option<GpuContext>> {
    let choice = match choice {
        BackendArg::Gpu => BackendChoice::Gpu,
        BackendArg::Cpu => BackendChoice::Cpu,
        BackendArg::Auto => BackendChoice::Auto,
    };
    let found = select_backend(choice)
        .context("--backend gpu needs a wgpu adapter (--backend cpu or auto render on the CPU)")?;
    match found {
        Backend::Gpu(ctx) => Ok(Some(ctx)),
        Backend::Cpu { fallback } => {
            if let Some(note) = fallback {
                eprintln!("assetfield: {note}");
            }
            Ok(None)
        }
    }
}
