//! Views of a field that may change between them, on the GPU, with the CPU taking over when
//! the device fails and the command allows it (`--backend auto`): the one place that decides
//! when a GPU failure falls back, for `compose`, the benches and the editor alike.

use crate::{FieldRenderer, GpuContext, GpuError, fallback_note};
use assetfield_core::Camera;
use assetfield_field::{Field, Occupancy};
use glam::Vec3;

/// What [`GpuViews::render`] or [`GpuViews::prepare`] did.
#[derive(Debug)]
pub enum GpuView<T> {
    /// Done on the device.
    Done(T),
    /// The device failed in a way the CPU can take over (out of memory, a lost device) and
    /// falling back is allowed: this view and every later one belong to the CPU. `note` says
    /// why, in one line, for the user.
    FellBack { note: String },
}

/// A device and the renderer of the field version it last uploaded.
#[derive(Debug)]
pub struct GpuViews {
    ctx: GpuContext,
    renderer: Option<(u64, FieldRenderer)>,
    fallback: bool,
}

impl GpuViews {
    /// Views on `ctx`; `fallback`: a failure the CPU can take over hands over to it rather
    /// than being an error.
    pub fn new(ctx: GpuContext, fallback: bool) -> Self {
        GpuViews { ctx, renderer: None, fallback }
    }

    /// The device's description.
    pub fn describe(&self) -> String {
        self.ctx.describe()
    }

    /// Upload `field` (with its occupancy grid) as version `version`, unless that version is
    /// uploaded already.
    pub fn prepare(
        &mut self,
        field: &Field,
        occupancy: Option<&Occupancy>,
        version: u64,
    ) -> Result<GpuView<()>, GpuError> {
        if self.renderer.as_ref().is_some_and(|(at, _)| *at == version) {
            return Ok(GpuView::Done(()));
        }
        self.renderer = None;
        match FieldRenderer::new(&self.ctx, field, occupancy) {
            Ok(r) => {
                self.renderer = Some((version, r));
                Ok(GpuView::Done(()))
            }
            Err(e) => self.failed(e),
        }
    }

    /// One view of version `version` of `field` over `background`: linear RGB, row-major.
    pub fn render(
        &mut self,
        field: &Field,
        occupancy: Option<&Occupancy>,
        version: u64,
        camera: &Camera,
        background: Vec3,
    ) -> Result<GpuView<Vec<f32>>, GpuError> {
        if let GpuView::FellBack { note } = self.prepare(field, occupancy, version)? {
            return Ok(GpuView::FellBack { note });
        }
        let out = match &self.renderer {
            Some((_, r)) => r.render(camera, background),
            None => Err(GpuError::Unsupported("no renderer after an upload".into())),
        };
        match out {
            Ok(rgb) => Ok(GpuView::Done(rgb)),
            Err(e) => self.failed(e),
        }
    }

    /// A failure, explained by the device's state: handed to the CPU where allowed and
    /// possible, else the error.
    fn failed<T>(&mut self, e: GpuError) -> Result<GpuView<T>, GpuError> {
        let e = self.ctx.explain(e);
        if self.fallback && e.cpu_can_do_it() {
            self.renderer = None;
            Ok(GpuView::FellBack { note: fallback_note(&e) })
        } else {
            Err(e)
        }
    }
}
