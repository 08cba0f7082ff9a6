//! `--backend`: which renderer a command runs on (the GPU through wgpu, or the CPU reference
//! renderer), shared by `compose`, `edit` and the benches.

use anyhow::{Context, Result};
use assetfield_core::Camera;
use assetfield_gpu::{Backend, BackendChoice, GpuContext, GpuView, GpuViews, select_backend};
use assetfield_scene::Composition;
use clap::ValueEnum;
use glam::Vec3;

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

/// Renders views of one composition on the `--backend` device: the GPU where there is one
/// and the field uploads, else the CPU reference renderer. Under `auto`, a GPU failure the
/// CPU can take over (out of memory, a lost device) moves this and every later view to the
/// CPU, with one line saying why; any other failure is an error ([`GpuViews`] decides).
pub(crate) struct ViewRenderer {
    gpu: Option<GpuViews>,
    device: Option<String>,
}

/// The one version of the composition a [`ViewRenderer`] renders.
const VERSION: u64 = 0;

impl ViewRenderer {
    /// The device for `choice`, with `comp`'s field uploaded to it.
    pub(crate) fn new(choice: BackendArg, comp: &Composition) -> Result<Self> {
        let ctx = device(choice)?;
        let device = ctx.as_ref().map(|c| c.describe());
        let mut gpu = ctx.map(|c| GpuViews::new(c, choice == BackendArg::Auto));
        if let Some(views) = &mut gpu {
            match views.prepare(&comp.field, comp.occupancy.as_ref(), VERSION) {
                Ok(GpuView::Done(())) => {}
                Ok(GpuView::FellBack { note }) => {
                    eprintln!("assetfield: {note}");
                    gpu = None;
                }
                Err(e) => {
                    return Err(anyhow::anyhow!(e))
                        .context(format!("uploading to {}", views.describe()));
                }
            }
        }
        Ok(ViewRenderer { gpu, device })
    }

    /// `gpu` or `cpu`: where the views render now.
    pub(crate) fn backend(&self) -> &'static str {
        if self.gpu.is_some() { "gpu" } else { "cpu" }
    }

    /// The device's description, where there is a GPU context.
    pub(crate) fn device(&self) -> Option<String> {
        self.device.clone()
    }

    /// One view of `comp` (the composition `new` uploaded) over `bg`: linear RGB, row-major.
    pub(crate) fn render(
        &mut self,
        comp: &Composition,
        cam: &Camera,
        bg: Vec3,
    ) -> Result<Vec<f32>> {
        if let Some(views) = &mut self.gpu {
            match views.render(&comp.field, comp.occupancy.as_ref(), VERSION, cam, bg) {
                Ok(GpuView::Done(rgb)) => return Ok(rgb),
                Ok(GpuView::FellBack { note }) => {
                    eprintln!("assetfield: {note}");
                    self.gpu = None;
                }
                Err(e) => {
                    return Err(anyhow::anyhow!(e))
                        .context(format!("rendering on {}", views.describe()));
                }
            }
        }
        Ok(comp.render(cam, bg))
    }
}
