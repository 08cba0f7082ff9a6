//! Fields, cameras and the device shared by the GPU tests.

#![allow(dead_code)]

use assetfield_core::{Aabb3, Camera, Distortion, Intrinsics};
use assetfield_field::params::Group;
use assetfield_field::{DecoderKind, Field, FieldConfig, ModelKind, Occupancy, render_view};
use assetfield_gpu::{FieldRenderer, GpuContext, GpuError};
use glam::Vec3;
use std::sync::OnceLock;

/// The device, made once per test binary; `Err` says why there is none.
pub fn context() -> Result<&'static GpuContext, &'static GpuError> {
    static CTX: OnceLock<Result<GpuContext, GpuError>> = OnceLock::new();
    CTX.get_or_init(|| {
        let c = GpuContext::new()?;
        eprintln!("wgpu adapter: {}", c.describe());
        Ok(c)
    })
    .as_ref()
}

/// The device, or `None` after saying on stderr that the test is skipped because there is no
/// adapter. Any other failure (an adapter that cannot make a device) fails the test.
pub fn context_or_skip(test: &str) -> Option<&'static GpuContext> {
    match context() {
        Ok(c) => Some(c),
        Err(GpuError::NoAdapter(reason)) => {
            eprintln!(
                "SKIPPED: no wgpu adapter ({reason}); {test} did not run (without a GPU, \
                 install mesa-vulkan-drivers and set XDG_RUNTIME_DIR)"
            );
            None
        }
        Err(e) => panic!("{test}: {e}"),
    }
}

pub const AABB_MIN: Vec3 = Vec3::new(-1.0, -1.0, 0.0);
pub const AABB_MAX: Vec3 = Vec3::new(1.0, 1.0, 0.8);

/// A field whose density is laid out by hand (opaque discs and a block, a semi-transparent
/// disc, a floating slab, over the random initialisation), with colour grids scaled up so
/// that the decoder sees varied features.
pub fn structured_field(kind: ModelKind, decoder: DecoderKind) -> Field {
    let aabb = Aabb3::new(AABB_MIN, AABB_MAX);
    let mut cfg = FieldConfig::new(kind, aabb, 40);
    cfg.density_channels = 10;
    cfg.color_channels = 12;
    cfg.decoder = decoder;
    let mut f = Field::new(cfg, 11);
    let c = f.density_components()[0];
    assert_eq!(c.axes, [0, 1, 2]);
    let e = aabb.extent();
    let data = &mut f.params.data;
    for r in 0..c.rows {
        for col in 0..c.cols {
            let x = AABB_MIN.x + e.x * col as f32 / (c.cols - 1) as f32;
            let y = AABB_MIN.y + e.y * r as f32 / (c.rows - 1) as f32;
            let disc = |cx: f32, cy: f32, rad: f32| {
                let d = ((x - cx).powi(2) + (y - cy).powi(2)).sqrt();
                ((rad - d) / 0.08).clamp(0.0, 1.0)
            };
            let block = ((0.3 - (x - 0.45).abs().max((y + 0.4).abs())) / 0.05).clamp(0.0, 1.0);
            let at = c.plane + (r * c.cols + col) * c.ch;
            // channel 0: tall opaque objects; channel 1: semi-transparent; 2: a floating slab
            data[at] = 16.0 * disc(-0.45, 0.35, 0.3) + 14.0 * block;
            data[at + 1] = 10.8 * disc(0.3, 0.45, 0.28);
            data[at + 2] = 13.0 * disc(-0.2, -0.3, 0.35);
        }
    }
    for k in 0..c.len {
        let z = AABB_MIN.z + e.z * k as f32 / (c.len - 1) as f32;
        let at = c.line.unwrap() + k * c.ch;
        data[at] = ((0.55 - z) / 0.05).clamp(0.0, 1.0);
        data[at + 1] = ((0.4 - z) / 0.1).clamp(0.0, 1.0);
        data[at + 2] = ((0.08 - (z - 0.65).abs()) / 0.03).clamp(0.0, 1.0);
    }
    for s in &f.params.specs {
        if s.group == Group::Grid && s.name.starts_with("color.") {
            for v in &mut f.params.data[s.offset..s.offset + s.len] {
                *v *= 6.0;
            }
        }
    }
    f
}

/// The occupancy grid training would build for `field`.
pub fn occupancy(field: &Field) -> Occupancy {
    let r = field.config.res;
    Occupancy::from_field(field, [r[0] / 2, r[1] / 2, r[2] / 2], 1e-4)
}

/// Views from around and above the box, one from inside it, one with lens distortion.
pub fn cameras(res: u32) -> Vec<Camera> {
    let k = Intrinsics::from_fov_x(res, res, 0.9);
    let target = Vec3::new(0.0, 0.0, 0.3);
    let mut cams: Vec<Camera> = [
        Vec3::new(2.6, 0.4, 1.2),
        Vec3::new(-1.5, 2.0, 1.8),
        Vec3::new(0.3, -2.2, 0.5),
        Vec3::new(0.05, 0.1, 3.0),
        Vec3::new(0.9, 0.9, 0.7),
    ]
    .into_iter()
    .map(|eye| Camera::look_at(k, eye, target, Vec3::Z))
    .collect();
    let mut distorted = Camera::look_at(k, Vec3::new(-2.2, -1.4, 1.0), target, Vec3::Z);
    distorted.intrinsics.distortion =
        Some(Distortion { k1: -0.08, k2: 0.01, p1: 0.001, p2: -0.0005, k3: 0.0 });
    cams.push(distorted);
    cams
}

/// Who renders.
#[derive(Debug, Clone, Copy)]
pub enum Backend<'a> {
    /// The CPU reference, `assetfield_field::render_view`.
    Cpu,
    Gpu(&'a FieldRenderer),
}

impl Backend<'_> {
    pub fn name(&self) -> &'static str {
        match self {
            Backend::Cpu => "cpu",
            Backend::Gpu(_) => "gpu",
        }
    }

    /// Render every camera: `[height][width][3]` per view.
    pub fn render(
        &self,
        field: &Field,
        occ: Option<&Occupancy>,
        cams: &[Camera],
        background: Vec3,
    ) -> Vec<Vec<f32>> {
        match self {
            Backend::Cpu => cams.iter().map(|c| render_view(field, occ, c, background)).collect(),
            Backend::Gpu(r) => r.render_batch(cams, background).expect("GPU render"),
        }
    }
}

/// PSNR (peak 1) between two images and the largest absolute difference per channel.
pub fn compare(a: &[f32], b: &[f32]) -> (f64, [f32; 3]) {
    assert_eq!(a.len(), b.len());
    let mut se = 0.0f64;
    let mut max = [0.0f32; 3];
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        let d = (x - y).abs();
        se += (d as f64).powi(2);
        max[k % 3] = max[k % 3].max(d);
    }
    let mse = se / a.len() as f64;
    (-10.0 * mse.max(1e-20).log10(), max)
}

/// Standard deviation of an image's values (a check that a comparison is not vacuous).
pub fn spread(a: &[f32]) -> f32 {
    let n = a.len() as f32;
    let m = a.iter().sum::<f32>() / n;
    (a.iter().map(|v| (v - m).powi(2)).sum::<f32>() / n).sqrt()
}
