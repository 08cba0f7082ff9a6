//! `--backend`: which renderer a command runs on (the GPU through wgpu, or the CPU reference
//! renderer), shared by `compose`, `edit` and the benches.

use anyhow::{Context, Result};
use assetfield_core::Camera;
use assetfield_gpu::{
    Backend, BackendChoice, FieldRenderer, GpuContext, fallback_note, select_backend,
};
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
/// CPU, with one line saying why; any other failure is an error.
pub(crate) struct ViewRenderer {
    ctx: Option<GpuContext>,
    gpu: Option<FieldRenderer>,
    auto: bool,
}

impl ViewRenderer {
    /// The device for `choice`, with `comp`'s field uploaded to it.
    pub(crate) fn new(choice: BackendArg, comp: &Composition) -> Result<Self> {
        let ctx = device(choice)?;
        let auto = choice == BackendArg::Auto;
        let gpu = match &ctx {
            None => None,
            Some(c) => match FieldRenderer::new(c, &comp.field, comp.occupancy.as_ref()) {
                Ok(r) => Some(r),
                Err(e) => {
                    let e = c.explain(e);
                    if !(auto && e.cpu_can_do_it()) {
                        return Err(anyhow::anyhow!(e))
                            .context(format!("uploading to {}", c.describe()));
                    }
                    eprintln!("assetfield: {}", fallback_note(&e));
                    None
                }
            },
        };
        Ok(ViewRenderer { ctx, gpu, auto })
    }

    /// `gpu` or `cpu`: where the views render now.
    pub(crate) fn backend(&self) -> &'static str {
        if self.gpu.is_some() { "gpu" } else { "cpu" }
    }

    /// The device's description, where there is a GPU context.
    pub(crate) fn device(&self) -> Option<String> {
        self.ctx.as_ref().map(|c| c.describe())
    }

    /// One view of `comp` (the composition `new` uploaded) over `bg`: linear RGB, row-major.
    pub(crate) fn render(
        &mut self,
        comp: &Composition,
        cam: &Camera,
        bg: Vec3,
    ) -> Result<Vec<f32>> {
        if let (Some(r), Some(c)) = (&self.gpu, &self.ctx) {
            match r.render(cam, bg) {
                Ok(rgb) => return Ok(rgb),
                Err(e) => {
                    let e = c.explain(e);
                    if !(self.auto && e.cpu_can_do_it()) {
                        return Err(anyhow::anyhow!(e))
                            .context(format!("rendering on {}", c.describe()));
                    }
                    eprintln!("assetfield: {}", fallback_note(&e));
                    self.gpu = None;
                }
            }
        }
        Ok(comp.render(cam, bg))
    }
}
