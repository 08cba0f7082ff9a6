//! Model configuration: which factorisation, sizes, decoders. Saved inside every field file.

use assetfield_core::Aabb3;
use serde::{Deserialize, Serialize};

/// Which factorisation of the radiance field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ModelKind {
    /// S-AssetField: density plane + axis, colour plane + axis (paper Sec. 3.1).
    Standard,
    /// I-AssetField: density plane + axis; one integrated colour plane without an axis, decoded
    /// with geometry guidance from the density features (paper Sec. 3.3).
    Integrated,
    /// TensoRF-VM baseline: three plane-line pairs (XY-Z, XZ-Y, YZ-X) for density and colour.
    Vm,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Standard => "s",
            ModelKind::Integrated => "i",
            ModelKind::Vm => "vm",
        }
    }
}

/// How colour features become RGB.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum DecoderKind {
    /// A small MLP on the basis features plus the view direction and its sin/cos encoding.
    Mlp { hidden: Vec<usize>, view_freqs: usize },
    /// Spherical harmonics of the given degree (0..=2): the basis outputs 3 x (degree+1)^2
    /// coefficients, `rgb = sigmoid(SH(d) . coefficients)`.
    Sh { degree: usize },
}

/// Everything that fixes the shapes and the meaning of a field's tensors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FieldConfig {
    pub kind: ModelKind,
    /// Scene bounds `[min, max]`; the ground plane is the XY face.
    pub aabb: [[f32; 3]; 2],
    /// Ground plane resolution (x, y) and vertical axis resolution (z), in samples.
    pub res: [usize; 3],
    /// Feature channels of the density field (per component).
    pub density_channels: usize,
    /// Feature channels of the colour field (per component).
    pub color_channels: usize,
    /// Output size of the colour basis (the decoder's feature input).
    pub basis_dim: usize,
    pub decoder: DecoderKind,
    /// Hidden width of the I-AssetField guidance MLPs (density features -> colour feature,
    /// and -> semantic feature).
    pub guide_hidden: usize,
    /// I-AssetField only: channels of the semantic field decoded from the integrated plane
    /// (0: no semantic field). Set to the channel count of the training feature maps.
    #[serde(default)]
    pub semantic_channels: usize,
    /// Added to the density feature before softplus (keeps empty space empty at the start).
    pub density_shift: f32,
    /// Multiplies sample spacing in the opacity `1 - exp(-sigma * step * scale)`.
    pub distance_scale: f32,
    /// Sample step as a fraction of the mean voxel size.
    pub step_ratio: f32,
}

impl FieldConfig {
    /// Defaults in TensoRF's style for a scene with these bounds, plane resolution `plane_res`
    /// (the vertical axis gets the same voxel size, at least 32 samples).
    pub fn new(kind: ModelKind, aabb: Aabb3, plane_res: usize) -> Self {
        let mut c = FieldConfig {
            kind,
            aabb: [aabb.min.to_array(), aabb.max.to_array()],
            res: [plane_res; 3],
            density_channels: 16,
            color_channels: 48,
            basis_dim: 27,
            decoder: DecoderKind::Mlp { hidden: vec![64], view_freqs: 2 },
            guide_hidden: 32,
            semantic_channels: 0,
            density_shift: -10.0,
            distance_scale: 25.0 * 3.0 / aabb.extent().max_element().max(1e-6),
            step_ratio: 0.5,
        };
        c.res = c.resolution_for(plane_res);
        c
    }

    pub fn aabb(&self) -> Aabb3 {
        Aabb3::new(self.aabb[0].into(), self.aabb[1].into())
    }

    /// Resolutions for a plane of `plane_res` samples along its longer side: cubic voxels.
    pub fn resolution_for(&self, plane_res: usize) -> [usize; 3] {
        let e = self.aabb().extent();
        let voxel = e.x.max(e.y) / (plane_res.max(2) - 1) as f32;
        let n = |len: f32, min: usize| ((len / voxel).round() as usize + 1).max(min);
        [n(e.x, 2), n(e.y, 2), n(e.z, 32)]
    }

    /// World size of one voxel along each axis.
    pub fn voxel_size(&self) -> glam::Vec3 {
        let e = self.aabb().extent();
        glam::Vec3::new(
            e.x / (self.res[0] - 1) as f32,
            e.y / (self.res[1] - 1) as f32,
            e.z / (self.res[2] - 1) as f32,
        )
    }

    /// Ray marching step in world units.
    pub fn step_size(&self) -> f32 {
        let v = self.voxel_size();
        (v.x + v.y + v.z) / 3.0 * self.step_ratio
    }

    /// Size of the view-direction encoding fed to the MLP decoder.
    pub fn view_encoding_dim(&self) -> usize {
        match &self.decoder {
            DecoderKind::Mlp { view_freqs, .. } => 3 + 6 * view_freqs,
            DecoderKind::Sh { .. } => 0,
        }
    }

    /// Basis output size actually used (SH fixes it to 3 x (degree+1)^2).
    pub fn features_dim(&self) -> usize {
        match &self.decoder {
            DecoderKind::Mlp { .. } => self.basis_dim,
            DecoderKind::Sh { degree } => 3 * (degree + 1) * (degree + 1),
        }
    }

    /// Semantic channels the model actually has (only I-AssetField decodes them).
    pub fn semantic_dim(&self) -> usize {
        if self.kind == ModelKind::Integrated { self.semantic_channels } else { 0 }
    }

    /// Colour feature size before the basis (per-component channels times components).
    pub fn app_dim(&self) -> usize {
        match self.kind {
            ModelKind::Vm => 3 * self.color_channels,
            _ => self.color_channels,
        }
    }
}
