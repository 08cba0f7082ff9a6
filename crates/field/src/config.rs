//! Model configuration: which factorisation, sizes, decoders. Saved inside every field file.

use crate::io::FieldError;
use assetfield_core::Aabb3;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Most samples along a side of a ground plane (x or y) by default ([`max_plane_res`] is the
/// bound in force). Trained fields use 128 to 1024; a 4096 x 4096 plane of 48 colour channels
/// is already 3 GiB of `f32`.
pub const MAX_PLANE_RES: usize = 4096;
/// Fewest samples along any axis: linear interpolation needs two nodes.
pub const MIN_RES: usize = 2;
/// Most feature channels of a density or colour component: the density backward pass keeps
/// one component's channels in stack buffers of this size ([`crate::model::MAX_CHANNELS`]).
pub const MAX_FEATURE_CHANNELS: usize = crate::model::MAX_CHANNELS;
/// Most channels of the semantic field: the widest per-pixel features in use (CLIP ViT-L:
/// 768, DINOv2 ViT-L: 1024).
pub const MAX_SEMANTIC_CHANNELS: usize = 1024;
/// Widest network layer (colour basis output, decoder and guidance hidden layers), in
/// units. The defaults are 27, 64 and 32.
pub const MAX_LAYER_WIDTH: usize = 1024;
/// Most hidden layers of the MLP decoder (the default has one).
pub const MAX_HIDDEN_LAYERS: usize = 8;
/// Most view-direction frequencies of the MLP decoder: `sin(2^k d)` for `k < 16` already
/// varies faster than any view-dependent effect (the default uses 2).
pub const MAX_VIEW_FREQS: usize = 16;
/// Highest spherical-harmonics degree: [`crate::model::sh_basis`] computes 9 coefficients.
pub const MAX_SH_DEGREE: usize = 2;
/// Smallest march step, in voxels (the default is 0.5, TensoRF's): below a twentieth of a
/// voxel a ray's samples (at most 2048, see [`crate::MarchSettings`]) run out before they
/// cross a 100-voxel scene, and renders come out empty.
pub const MIN_STEP_RATIO: f32 = 0.05;
/// Largest march step, in voxels: beyond 4 voxels samples step over thin geometry.
pub const MAX_STEP_RATIO: f32 = 4.0;
/// Largest |coordinate| of the scene box, in scene units (as the data crate's camera and
/// scene-box bounds: beyond it `f32` positions keep fewer than two decimals).
pub const MAX_BOX_COORD: f32 = 1.0e6;
/// Most values of all a field's tensors together by default ([`max_parameters`] is the bound
/// in force): twice a default-sized field at
/// [`MAX_PLANE_RES`] (4096^2 x (16 + 48) = 2^30 values); 8 GiB of `f32`.
pub const MAX_PARAMETERS: usize = 1 << 31;

/// The size bounds a user may move for one run (`assetfield --limit plane-res=N` or
/// `--limit parameters=N`): [`MAX_PLANE_RES`] (also the vertical axis's bound) and
/// [`MAX_PARAMETERS`] are their defaults. Values are clamped to 65,536 texels per side and
/// 2^40 parameters, where every size product still fits a `usize` with room.
static PLANE_RES_LIMIT: AtomicUsize = AtomicUsize::new(MAX_PLANE_RES);
static PARAMETERS_LIMIT: AtomicUsize = AtomicUsize::new(MAX_PARAMETERS);

/// Most samples per side of a plane (and along the vertical axis) for this run.
pub fn max_plane_res() -> usize {
    PLANE_RES_LIMIT.load(Ordering::Relaxed)
}

/// Most values of all a field's tensors together for this run.
pub fn max_parameters() -> usize {
    PARAMETERS_LIMIT.load(Ordering::Relaxed)
}

/// Move the size bounds for the rest of this process (the CLI's `--limit`); `None` keeps one.
pub fn set_size_limits_for_process(plane_res: Option<u64>, parameters: Option<u64>) {
    let clamp = |v: u64, max: usize| usize::try_from(v).unwrap_or(usize::MAX).clamp(MIN_RES, max);
    if let Some(v) = plane_res {
        PLANE_RES_LIMIT.store(clamp(v, 1 << 16), Ordering::Relaxed);
    }
    if let Some(v) = parameters {
        PARAMETERS_LIMIT.store(clamp(v, 1 << 40), Ordering::Relaxed);
    }
}

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
            distance_scale: distance_scale_for(aabb.extent().max_element()),
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
        self.resolution_for_voxel(e.x.max(e.y) / (plane_res.max(2) - 1) as f32)
    }

    /// Resolutions for cubic voxels of side `voxel` (world units): the box's extent over the
    /// voxel, rounded, plus one node; at least 2 samples along x and y and 32 along z.
    pub fn resolution_for_voxel(&self, voxel: f32) -> [usize; 3] {
        let e = self.aabb().extent();
        let n = |len: f32, min: usize| ((len / voxel).round() as usize + 1).max(min);
        [n(e.x, 2), n(e.y, 2), n(e.z, MIN_VERTICAL_RES)]
    }

    /// This configuration over another ground window: `cols` x `rows` plane nodes `texel`
    /// apart from `min` (world XY); the vertical range and resolution, networks and scales
    /// stay. A window that is this configuration's own keeps its box exactly.
    pub fn on_ground_window(
        &self,
        min: glam::Vec2,
        cols: usize,
        rows: usize,
        texel: glam::Vec2,
    ) -> FieldConfig {
        let mut config = self.clone();
        let same = config.res[0] == cols
            && config.res[1] == rows
            && (config.aabb[0][0] - min.x).abs() < 1e-4 * texel.x.max(1.0)
            && (config.aabb[0][1] - min.y).abs() < 1e-4 * texel.y.max(1.0);
        if !same {
            let max =
                min + glam::Vec2::new((cols - 1) as f32 * texel.x, (rows - 1) as f32 * texel.y);
            config.res[0] = cols;
            config.res[1] = rows;
            config.aabb[0][0] = min.x;
            config.aabb[0][1] = min.y;
            config.aabb[1][0] = max.x;
            config.aabb[1][1] = max.y;
        }
        config
    }

    /// Whether tensor `name` is one of the ground planes, which every scene has for itself;
    /// every other tensor (vertical axes, colour basis, guidance MLPs, decoders) is what
    /// several scenes can share (paper Sec. 3.4).
    pub fn is_plane_tensor(name: &str) -> bool {
        PLANE_TENSORS.contains(&name)
    }

    /// The first value that keeps two configurations from sharing their non-plane tensors:
    /// model, channels, networks, the vertical range and resolution, the density's shift and
    /// distance scale, the march step and the texel size must agree; the ground box and the
    /// plane resolution may differ. `None` when they can share.
    pub fn sharing_mismatch(&self, other: &FieldConfig) -> Option<SharingMismatch> {
        let differ = |key: &str, a: String, b: String| {
            Some(SharingMismatch { key: key.to_string(), first: a, second: b })
        };
        let close = |a: f32, b: f32, tol: f32| (a - b).abs() <= tol * a.abs().max(b.abs());
        if self.kind != other.kind {
            return differ("kind", self.kind.name().into(), other.kind.name().into());
        }
        let counts = |c: &FieldConfig| {
            [
                ("density_channels", c.density_channels),
                ("color_channels", c.color_channels),
                ("basis_dim", c.features_dim()),
                ("guide_hidden", c.guide_hidden),
                ("semantic_channels", c.semantic_dim()),
                ("res[2] (vertical axis samples)", c.res[2]),
            ]
        };
        for ((key, a), (_, b)) in counts(self).into_iter().zip(counts(other)) {
            if a != b {
                return differ(key, a.to_string(), b.to_string());
            }
        }
        if self.decoder != other.decoder {
            return differ(
                "decoder",
                format!("{:?}", self.decoder),
                format!("{:?}", other.decoder),
            );
        }
        let ez = (self.aabb[1][2] - self.aabb[0][2]).abs();
        for (key, a, b) in [
            ("aabb zmin", self.aabb[0][2], other.aabb[0][2]),
            ("aabb zmax", self.aabb[1][2], other.aabb[1][2]),
        ] {
            if (a - b).abs() > SHARE_TOLERANCE * ez {
                return differ(key, a.to_string(), b.to_string());
            }
        }
        for (key, a, b) in [
            ("density_shift", self.density_shift, other.density_shift),
            ("distance_scale", self.distance_scale, other.distance_scale),
            ("step_ratio", self.step_ratio, other.step_ratio),
        ] {
            if !close(a, b, SHARE_TOLERANCE) {
                return differ(key, a.to_string(), b.to_string());
            }
        }
        let (va, vb) = (self.voxel_size(), other.voxel_size());
        for (key, a, b) in [("texel size x", va.x, vb.x), ("texel size y", va.y, vb.y)] {
            if !close(a, b, SHARE_TOLERANCE) {
                return differ(key, a.to_string(), b.to_string());
            }
        }
        None
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

/// Fewest samples of the vertical axis: a low box still gets a usable height resolution.
pub const MIN_VERTICAL_RES: usize = 32;

/// The density's distance scale for a box whose largest extent is `extent` (world units):
/// TensoRF's 25 for its 3-unit box, so that opacities per voxel do not depend on the unit.
pub fn distance_scale_for(extent: f32) -> f32 {
    25.0 * 3.0 / extent.max(1e-6)
}

/// The ground-plane tensors of the S- and I-AssetField (see [`FieldConfig::is_plane_tensor`]).
pub const PLANE_TENSORS: [&str; 2] = ["density.plane", "color.plane"];

/// Relative tolerance of the values two configurations sharing tensors must agree on
/// (texel size, vertical range, distance scale): f32 rounding of boxes snapped to whole
/// voxels stays near 1e-6; a different grid differs by far more.
pub const SHARE_TOLERANCE: f32 = 1e-4;

/// Why two field configurations cannot share tensors: the key and both values.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SharingMismatch {
    pub key: String,
    pub first: String,
    pub second: String,
}

impl std::fmt::Display for SharingMismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} is {} in the first and {} in the second", self.key, self.first, self.second)
    }
}

/// A `FieldConfig` check's findings: the key, what was expected and what was found.
struct Check<'a> {
    path: &'a Path,
}

impl Check<'_> {
    fn fail(&self, key: &str, expected: impl Into<String>, actual: impl ToString) -> FieldError {
        FieldError::Config {
            path: self.path.to_path_buf(),
            key: key.to_string(),
            expected: expected.into(),
            actual: actual.to_string(),
        }
    }

    fn range(&self, key: &str, v: usize, lo: usize, hi: usize) -> Result<(), FieldError> {
        if v < lo || v > hi {
            return Err(self.fail(key, format!("{lo} to {hi}"), v));
        }
        Ok(())
    }
}

impl FieldConfig {
    /// Check every value against the bounds above (resolutions, channel counts, layer
    /// widths, decoder, scene box, render settings), before anything is allocated from it;
    /// `path` names the file in the error ([`FieldError::Config`]: key, expected, actual).
    pub fn validate(&self, path: &Path) -> Result<(), FieldError> {
        let c = Check { path };
        let side = max_plane_res();
        for (axis, &r) in self.res.iter().enumerate() {
            if !(MIN_RES..=side).contains(&r) {
                return Err(c.fail(
                    &format!("res[{axis}]"),
                    format!("{MIN_RES} to {side} (raise the bound with --limit plane-res=N)"),
                    r.to_string(),
                ));
            }
        }
        c.range("density_channels", self.density_channels, 1, MAX_FEATURE_CHANNELS)?;
        c.range("color_channels", self.color_channels, 1, MAX_FEATURE_CHANNELS)?;
        c.range("semantic_channels", self.semantic_channels, 0, MAX_SEMANTIC_CHANNELS)?;
        if self.kind == ModelKind::Integrated {
            c.range("guide_hidden", self.guide_hidden, 1, MAX_LAYER_WIDTH)?;
        }
        match &self.decoder {
            DecoderKind::Mlp { hidden, view_freqs } => {
                c.range("basis_dim", self.basis_dim, 1, MAX_LAYER_WIDTH)?;
                c.range("decoder.Mlp.hidden (layers)", hidden.len(), 0, MAX_HIDDEN_LAYERS)?;
                for (k, &h) in hidden.iter().enumerate() {
                    c.range(&format!("decoder.Mlp.hidden[{k}]"), h, 1, MAX_LAYER_WIDTH)?;
                }
                c.range("decoder.Mlp.view_freqs", *view_freqs, 0, MAX_VIEW_FREQS)?;
            }
            DecoderKind::Sh { degree } => {
                c.range("decoder.Sh.degree", *degree, 0, MAX_SH_DEGREE)?;
            }
        }
        let [lo, hi] = self.aabb;
        let shown = || format!("[{lo:?}, {hi:?}]");
        if lo.iter().chain(&hi).any(|v| !(v.is_finite() && v.abs() <= MAX_BOX_COORD)) {
            return Err(c.fail(
                "aabb",
                format!("finite coordinates within {MAX_BOX_COORD:e}"),
                shown(),
            ));
        }
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            if lo[axis] >= hi[axis] {
                return Err(c.fail(
                    "aabb",
                    format!(
                        "[[xmin, ymin, zmin], [xmax, ymax, zmax]] with {name}min below {name}max"
                    ),
                    shown(),
                ));
            }
        }
        if !self.density_shift.is_finite() {
            return Err(c.fail(
                "density_shift",
                "a finite number",
                format!("{:?}", self.density_shift),
            ));
        }
        if !(self.distance_scale.is_finite() && self.distance_scale > 0.0) {
            return Err(c.fail(
                "distance_scale",
                "a positive finite number",
                format!("{:?}", self.distance_scale),
            ));
        }
        if !(MIN_STEP_RATIO..=MAX_STEP_RATIO).contains(&self.step_ratio) {
            return Err(c.fail(
                "step_ratio",
                format!("a march step of {MIN_STEP_RATIO} to {MAX_STEP_RATIO} voxels"),
                format!("{:?}", self.step_ratio),
            ));
        }
        // the bounds above keep every product below far from overflowing
        let total: usize =
            self.tensor_shapes().iter().map(|(_, s)| s.iter().product::<usize>()).sum();
        let most = max_parameters();
        if total > most {
            return Err(c.fail(
                "res and channels",
                format!(
                    "at most {most} parameters in all (raise the bound with --limit parameters=N)"
                ),
                format!("{total} parameters"),
            ));
        }
        // a field holds its parameters once; a machine that cannot even do that is told so
        // before anything is allocated
        let bytes = total as u64 * 4;
        if let Some(free) = assetfield_core::fsx::available_memory()
            && bytes > free
        {
            return Err(c.fail(
                "res and channels",
                format!(
                    "parameters that fit the {:.1} GiB of memory available",
                    free as f64 / (1u64 << 30) as f64
                ),
                format!("{total} parameters ({:.1} GiB)", bytes as f64 / (1u64 << 30) as f64),
            ));
        }
        Ok(())
    }

    /// Name and shape of every tensor a field of this configuration has, in the order of
    /// its parameter buffer (what [`crate::Field::new`] builds). Call on a validated
    /// configuration ([`FieldConfig::validate`]), whose sizes cannot overflow.
    pub fn tensor_shapes(&self) -> Vec<(String, Vec<usize>)> {
        let mut out = Vec::new();
        let vm = self.kind == ModelKind::Vm;
        let sets: &[[usize; 3]] =
            if vm { &[[0, 1, 2], [0, 2, 1], [1, 2, 0]] } else { &[[0, 1, 2]] };
        const AXES: [&str; 3] = ["x", "y", "z"];
        let mut comps = |prefix: &str, ch: usize, with_line: bool| {
            for a in sets {
                let (cols, rows, len) = (self.res[a[0]], self.res[a[1]], self.res[a[2]]);
                let (plane, line) = if vm {
                    (
                        format!("{prefix}.plane_{}{}", AXES[a[0]], AXES[a[1]]),
                        format!("{prefix}.line_{}", AXES[a[2]]),
                    )
                } else {
                    (format!("{prefix}.plane"), format!("{prefix}.axis"))
                };
                out.push((plane, vec![rows, cols, ch]));
                if with_line {
                    out.push((line, vec![len, ch]));
                }
            }
        };
        comps("density", self.density_channels, true);
        comps("color", self.color_channels, self.kind != ModelKind::Integrated);
        let mut dense = |name: &str, inn: usize, out_dim: usize, bias: bool| {
            out.push((format!("{name}.weight"), vec![out_dim, inn]));
            if bias {
                out.push((format!("{name}.bias"), vec![out_dim]));
            }
        };
        let (nd, gh, app) = (self.density_channels, self.guide_hidden, self.app_dim());
        if self.kind == ModelKind::Integrated {
            dense("guide.0", nd, gh, true);
            dense("guide.1", gh, self.color_channels, true);
        }
        dense("color.basis", app, self.features_dim(), false);
        if let DecoderKind::Mlp { hidden, .. } = &self.decoder {
            let mut inn = self.features_dim() + self.view_encoding_dim();
            for (k, &h) in hidden.iter().chain(std::iter::once(&3)).enumerate() {
                dense(&format!("decoder.{k}"), inn, h, true);
                inn = h;
            }
        }
        let sem = self.semantic_dim();
        if sem > 0 {
            dense("guide_semantic.0", nd, gh, true);
            dense("guide_semantic.1", gh, app, true);
            dense("semantic.decoder", app, sem, true);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Field;
    use glam::Vec3;

    #[test]
    fn tensor_shapes_are_the_fields_layout() {
        let aabb = Aabb3::new(Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 2.0, 0.7));
        for kind in [ModelKind::Standard, ModelKind::Integrated, ModelKind::Vm] {
            for decoder in [
                DecoderKind::Mlp { hidden: vec![16, 8], view_freqs: 3 },
                DecoderKind::Mlp { hidden: vec![], view_freqs: 0 },
                DecoderKind::Sh { degree: 1 },
            ] {
                for semantic in [0, 5] {
                    let mut c = FieldConfig::new(kind, aabb, 12);
                    (c.decoder, c.semantic_channels) = (decoder.clone(), semantic);
                    (c.density_channels, c.color_channels) = (3, 5);
                    c.validate(Path::new("t")).unwrap();
                    let f = Field::new(c.clone(), 0);
                    let specs: Vec<(String, Vec<usize>)> =
                        f.params.specs.iter().map(|s| (s.name.clone(), s.shape.clone())).collect();
                    assert_eq!(c.tensor_shapes(), specs, "{kind:?} {decoder:?} {semantic}");
                }
            }
        }
    }

    #[test]
    fn defaults_are_valid_and_bounds_name_the_key() {
        let aabb = Aabb3::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let mut c = FieldConfig::new(ModelKind::Standard, aabb, 300);
        assert!(c.validate(Path::new("f.safetensors")).is_ok());
        c.res[2] = 1;
        let e = c.validate(Path::new("f.safetensors")).unwrap_err().to_string();
        assert_eq!(
            e,
            "f.safetensors: config \"res[2]\" is 1, expected 2 to 4096 (raise the bound with --limit plane-res=N)"
        );
        c.res = [4096, 4096, 4096];
        (c.density_channels, c.color_channels) = (256, 256);
        let e = c.validate(Path::new("f.safetensors")).unwrap_err().to_string();
        assert!(e.contains("config \"res and channels\"") && e.contains("parameters"), "{e}");
    }
}
