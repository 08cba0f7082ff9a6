//! What mining reads from a trained field: the ground grid (texel <-> world mapping), the
//! ground feature planes as [`PlaneImage`]s, and the opacity volume of the density field.
//!
//! Grid convention (the field's): plane nodes align with the box corners, texel `(row r,
//! col c)` sits at world `x = min.x + c * ext.x / (nx - 1)`, `y = min.y + r * ext.y / (ny -
//! 1)`; row 0 is `y = ymin`. A texel stands for the cell of one texel size centred on its
//! node, so the pixel rectangle `rows r0..r1, cols c0..c1` covers the world rectangle
//! `[x(c0) - tx/2, x(c1 - 1) + tx/2] x [y(r0) - ty/2, y(r1 - 1) + ty/2]`.

use assetfield_core::Rect2;
use assetfield_field::{Field, FieldConfig, ModelKind};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{MiningError, Result};
use crate::image::{PixelRect, PlaneImage};

/// The ground grid of a field: size in texels, world position of texel (0, 0) and the texel
/// size.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlaneGrid {
    /// Texels along x (plane columns).
    pub cols: usize,
    /// Texels along y (plane rows).
    pub rows: usize,
    /// World (x, y) of texel (row 0, col 0).
    pub origin: [f32; 2],
    /// World size of one texel along x and y.
    pub texel: [f32; 2],
}

impl PlaneGrid {
    /// The grid of a field configuration.
    pub fn from_config(cfg: &FieldConfig) -> Result<Self> {
        let [nx, ny, _] = cfg.res;
        if nx < 2 || ny < 2 {
            return Err(MiningError::InvalidParameter {
                name: "field resolution",
                reason: format!("{:?} is too small for a ground grid", cfg.res),
            });
        }
        let a = cfg.aabb();
        let e = a.extent();
        Ok(PlaneGrid {
            cols: nx,
            rows: ny,
            origin: [a.min.x, a.min.y],
            texel: [e.x / (nx - 1) as f32, e.y / (ny - 1) as f32],
        })
    }

    /// World (x, y) of continuous texel coordinates (column, row).
    pub fn to_world(&self, col: f32, row: f32) -> Vec2 {
        Vec2::new(self.origin[0] + col * self.texel[0], self.origin[1] + row * self.texel[1])
    }

    /// Continuous texel coordinates (column, row) of a world point.
    pub fn to_texel(&self, p: Vec2) -> (f32, f32) {
        ((p.x - self.origin[0]) / self.texel[0], (p.y - self.origin[1]) / self.texel[1])
    }

    /// The world rectangle covered by the cells of a pixel rectangle.
    pub fn rect_to_world(&self, r: PixelRect) -> Rect2 {
        let (hx, hy) = (self.texel[0] * 0.5, self.texel[1] * 0.5);
        let a = self.to_world(r.c0 as f32, r.r0 as f32);
        let b = self.to_world(r.c1 as f32 - 1.0, r.r1 as f32 - 1.0);
        Rect2::new(Vec2::new(a.x - hx, a.y - hy), Vec2::new(b.x + hx, b.y + hy))
    }

    /// The pixel rectangle of the cells a world rectangle touches, clipped to the grid
    /// (`None` if it misses the grid).
    pub fn world_to_rect(&self, w: Rect2) -> Option<PixelRect> {
        let (c0, r0) = self.to_texel(w.min);
        let (c1, r1) = self.to_texel(w.max);
        // cell k covers [k - 0.5, k + 0.5); edges exactly on a cell border do not touch it
        // fixed: rounding slack, far below one texel
        let lo = |v: f32| (v + 0.5 + 1e-4).floor().max(0.0);
        // fixed: rounding slack, far below one texel
        let hi = |v: f32, n: usize| (v + 0.5 - 1e-4).ceil().min(n as f32);
        let rect = PixelRect::new(
            lo(r0) as usize,
            lo(c0) as usize,
            hi(r1, self.rows).max(0.0) as usize,
            hi(c1, self.cols).max(0.0) as usize,
        );
        (!rect.is_empty()).then_some(rect)
    }

    /// World area of one texel cell.
    pub fn texel_area(&self) -> f32 {
        self.texel[0] * self.texel[1]
    }

    /// Mean texel size (world units per texel).
    pub fn texel_size(&self) -> f32 {
        0.5 * (self.texel[0] + self.texel[1])
    }

    /// The whole plane as a world rectangle.
    pub fn world_rect(&self) -> Rect2 {
        self.rect_to_world(PixelRect::new(0, 0, self.rows, self.cols))
    }
}

/// Which plane carries features for a step (detection or grouping).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum PlaneChoice {
    /// The density plane (`density.plane`).
    #[default]
    Density,
    /// The colour plane (`color.plane`; for I-AssetField the integrated RGB plane).
    Color,
    /// The semantic features decoded from I-AssetField's integrated plane (fields trained
    /// with feature maps only).
    Semantic,
}

impl PlaneChoice {
    pub fn name(self) -> &'static str {
        match self {
            PlaneChoice::Density => "density",
            PlaneChoice::Color => "color",
            PlaneChoice::Semantic => "semantic",
        }
    }
}

/// The ground feature planes of a field, ready for mining.
#[derive(Debug, Clone)]
pub struct FieldPlanes {
    pub kind: ModelKind,
    pub grid: PlaneGrid,
    /// `density.plane`: `[rows][cols][Nd]`.
    pub density: PlaneImage,
    /// `color.plane`: `[rows][cols][Nc]` (I-AssetField: the integrated colour plane).
    pub color: PlaneImage,
    /// `color.axis`: `[nz][Nc]`, S-AssetField's vertical colour axis (a colour feature at
    /// height `k` is the plane's times the axis's, channel by channel); `None` for
    /// I-AssetField, whose colour plane has no axis.
    pub color_axis: Option<Vec<f32>>,
}

/// Refuse fields without a ground plane representation (the VM baseline).
pub fn check_minable(field: &Field) -> Result<()> {
    if field.config.kind == ModelKind::Vm {
        return Err(MiningError::UnsupportedModel {
            model: "TensoRF-VM (vm)".into(),
            reason: "it has no ground plane representation: its XY planes hold only one of \
                     three factors of the density and colour (train with --model s or i)"
                .into(),
        });
    }
    Ok(())
}

/// A `[rows, cols, ch]` tensor of the field as an image.
pub fn plane_image(field: &Field, name: &str, purpose: &str) -> Result<PlaneImage> {
    let missing = || MiningError::MissingTensor {
        source_name: "field".into(),
        name: name.to_string(),
        purpose: purpose.to_string(),
    };
    let spec = field.params.spec(name).ok_or_else(missing)?;
    match spec.shape.as_slice() {
        &[rows, cols, ch] => PlaneImage::new(
            rows,
            cols,
            ch,
            field.params.data[spec.offset..spec.offset + spec.len].to_vec(),
        ),
        other => Err(MiningError::Format {
            path: "field".into(),
            message: format!("tensor \"{name}\" has shape {other:?}, expected [rows, cols, ch]"),
        }),
    }
}

/// Read the density and colour planes (errors for VM fields or missing planes).
pub fn field_planes(field: &Field) -> Result<FieldPlanes> {
    check_minable(field)?;
    let grid = PlaneGrid::from_config(&field.config)?;
    let density = plane_image(field, "density.plane", "detection (the density ground plane)")?;
    let color = plane_image(field, "color.plane", "grouping (the colour ground plane)")?;
    for (what, p) in [("density.plane", &density), ("color.plane", &color)] {
        if (p.rows, p.cols) != (grid.rows, grid.cols) {
            return Err(MiningError::Format {
                path: "field".into(),
                message: format!(
                    "tensor \"{what}\" is {}x{} texels but the field resolution says {}x{}",
                    p.rows, p.cols, grid.rows, grid.cols
                ),
            });
        }
    }
    // S-AssetField's colour plane has an axis; I-AssetField's integrated plane has none
    let color_axis = (field.config.kind == ModelKind::Standard)
        .then(|| {
            let shape = [field.config.res[2], color.ch];
            tensor(field, "color.axis", &shape, "the colours at a height (the second round)")
        })
        .transpose()?
        .map(<[f32]>::to_vec);
    Ok(FieldPlanes { kind: field.config.kind, grid, density, color, color_axis })
}

fn tensor<'a>(field: &'a Field, name: &str, shape: &[usize], purpose: &str) -> Result<&'a [f32]> {
    let spec = field.params.spec(name).ok_or_else(|| MiningError::MissingTensor {
        source_name: "field".into(),
        name: name.to_string(),
        purpose: purpose.to_string(),
    })?;
    if spec.shape != shape {
        return Err(MiningError::Format {
            path: "field".into(),
            message: format!("tensor \"{name}\" has shape {:?}, expected {shape:?}", spec.shape),
        });
    }
    Ok(&field.params.data[spec.offset..spec.offset + spec.len])
}

/// `y = W x + b` with `W` stored `[out][inn]`.
fn dense(w: &[f32], b: &[f32], x: &[f32], y: &mut [f32]) {
    let inn = x.len();
    for (o, v) in y.iter_mut().enumerate() {
        *v = b[o] + w[o * inn..(o + 1) * inn].iter().zip(x).map(|(a, b)| a * b).sum::<f32>();
    }
}

/// The semantic ground plane of an I-AssetField trained with feature maps: per texel, the
/// semantic feature the field decodes at the height where the column is most opaque (the
/// integrated plane's feature, modulated by the semantic guidance of the density feature
/// there, through the semantic decoder). Errors for fields without a semantic head.
pub fn semantic_plane(field: &Field, vol: &OpacityVolume) -> Result<PlaneImage> {
    check_minable(field)?;
    let cfg = &field.config;
    let purpose = "--detect-on/--group-on semantic (train I-AssetField with feature maps)";
    if !field.has_semantic() {
        return Err(MiningError::MissingTensor {
            source_name: "field".into(),
            name: "semantic.decoder.weight".into(),
            purpose: purpose.into(),
        });
    }
    let (nd, gh, app, sem) =
        (cfg.density_channels, cfg.guide_hidden, cfg.app_dim(), cfg.semantic_dim());
    let [nx, ny, nz] = cfg.res;
    let dplane = tensor(field, "density.plane", &[ny, nx, nd], purpose)?;
    let daxis = tensor(field, "density.axis", &[nz, nd], purpose)?;
    let cplane = tensor(field, "color.plane", &[ny, nx, app], purpose)?;
    let w0 = tensor(field, "guide_semantic.0.weight", &[gh, nd], purpose)?;
    let b0 = tensor(field, "guide_semantic.0.bias", &[gh], purpose)?;
    let w1 = tensor(field, "guide_semantic.1.weight", &[app, gh], purpose)?;
    let b1 = tensor(field, "guide_semantic.1.bias", &[app], purpose)?;
    let wd = tensor(field, "semantic.decoder.weight", &[sem, app], purpose)?;
    let bd = tensor(field, "semantic.decoder.bias", &[sem], purpose)?;
    if (vol.rows, vol.cols, vol.nz) != (ny, nx, nz) {
        return Err(MiningError::SizeMismatch {
            what: "opacity volume vs field resolution",
            left: vol.rows * vol.cols * vol.nz,
            right: nx * ny * nz,
        });
    }
    let mut data = vec![0f32; ny * nx * sem];
    data.par_chunks_mut(nx * sem).enumerate().for_each(|(r, row)| {
        let (mut gin, mut hid, mut sv, mut sapp) =
            (vec![0f32; nd], vec![0f32; gh], vec![0f32; app], vec![0f32; app]);
        for c in 0..nx {
            let col = vol.column(r, c);
            let k = (0..nz).max_by(|&a, &b| col[a].total_cmp(&col[b])).unwrap_or(0);
            let i = r * nx + c;
            for j in 0..nd {
                gin[j] = dplane[i * nd + j] * daxis[k * nd + j];
            }
            dense(w0, b0, &gin, &mut hid);
            hid.iter_mut().for_each(|v| *v = v.max(0.0));
            dense(w1, b1, &hid, &mut sv);
            for j in 0..app {
                sapp[j] = cplane[i * app + j] * sv[j];
            }
            dense(wd, bd, &sapp, &mut row[c * sem..(c + 1) * sem]);
        }
    });
    PlaneImage::new(ny, nx, sem, data)
}

/// The opacity of one vertical grid spacing at every grid node of the field:
/// `1 - exp(-sigma * dz * distance_scale)` (the field's own opacity formula with the level
/// spacing as the step), 0 empty .. 1 opaque. Stored per column
/// (`data[(r * cols + c) * nz + k]`), level `k` at height `z0 + k * dz`.
#[derive(Debug, Clone, PartialEq)]
pub struct OpacityVolume {
    pub rows: usize,
    pub cols: usize,
    pub nz: usize,
    pub z0: f32,
    pub dz: f32,
    pub data: Vec<f32>,
}

impl OpacityVolume {
    /// Evaluate the field's density at every node (in parallel over rows).
    pub fn from_field(field: &Field) -> Result<Self> {
        check_minable(field)?;
        let cfg = &field.config;
        let [nx, ny, nz] = cfg.res;
        let a = cfg.aabb();
        let v = cfg.voxel_size();
        let delta = v.z * cfg.distance_scale;
        let mut data = vec![0f32; nx * ny * nz];
        data.par_chunks_mut(nx * nz).enumerate().for_each(|(r, row)| {
            let y = a.min.y + r as f32 * v.y;
            for c in 0..nx {
                let x = a.min.x + c as f32 * v.x;
                for k in 0..nz {
                    let sigma = field.density(Vec3::new(x, y, a.min.z + k as f32 * v.z));
                    row[c * nz + k] = 1.0 - (-sigma * delta).exp();
                }
            }
        });
        Ok(OpacityVolume { rows: ny, cols: nx, nz, z0: a.min.z, dz: v.z, data })
    }

    /// The opacities of column `(r, c)`, bottom to top.
    pub fn column(&self, r: usize, c: usize) -> &[f32] {
        let i = (r * self.cols + c) * self.nz;
        &self.data[i..i + self.nz]
    }

    /// Whether voxel `(r, c, k)` has a face neighbour below opacity `tau` (the grid's
    /// outside counts as empty): a surface voxel of the occupied set.
    pub fn exposed(&self, r: usize, c: usize, k: usize, tau: f32) -> bool {
        let at = |r: usize, c: usize, k: usize| self.data[(r * self.cols + c) * self.nz + k];
        r == 0
            || c == 0
            || k == 0
            || r + 1 >= self.rows
            || c + 1 >= self.cols
            || k + 1 >= self.nz
            || at(r - 1, c, k) < tau
            || at(r + 1, c, k) < tau
            || at(r, c - 1, k) < tau
            || at(r, c + 1, k) < tau
            || at(r, c, k - 1) < tau
            || at(r, c, k + 1) < tau
    }

    /// World height of level `k`.
    pub fn height(&self, k: usize) -> f32 {
        self.z0 + k as f32 * self.dz
    }

    /// World height of the level just below `k`: the surface an object whose lowest level
    /// is `k` stands on when nothing was found under it (below the volume for `k = 0`).
    pub fn height_below(&self, k: usize) -> f32 {
        self.z0 + (k as f32 - 1.0) * self.dz
    }

    /// The levels `lo..=hi` of an object standing on `base` and reaching up to `top`: from
    /// the first level above `base` (level 0 when `base` is below the volume) to the level
    /// of `top`, at least one level, clamped to the volume.
    pub fn levels_between(&self, base: f32, top: f32) -> (usize, usize) {
        let last = self.nz.saturating_sub(1) as i64;
        let level = |z: f32| {
            let k = ((z - self.z0) / self.dz).round();
            if k.is_finite() { (k as i64).clamp(-1, last) } else { -1 }
        };
        let lo = (level(base) + 1).clamp(0, last);
        let hi = level(top.max(base)).max(lo);
        (lo as usize, hi as usize)
    }

    /// Per texel, the opacity of the column over levels `from..` seen from above:
    /// `1 - prod(1 - o_k)`.
    pub fn accumulated_above(&self, from: usize) -> Vec<f32> {
        (0..self.rows * self.cols)
            .map(|i| {
                let col = &self.data[i * self.nz..(i + 1) * self.nz];
                1.0 - col.iter().skip(from).fold(1f32, |t, &o| t * (1.0 - o))
            })
            .collect()
    }

    /// Per texel, the largest opacity of `window` consecutive levels within `from..`:
    /// `max_k 1 - prod_{j = k .. k + window} (1 - o_j)`. A thin surface spread over a few
    /// levels reaches its full opacity; faint fog spread over the whole column does not.
    pub fn window_max_above(&self, from: usize, window: usize) -> Vec<f32> {
        (0..self.rows * self.cols)
            .map(|i| window_max(&self.data[i * self.nz..(i + 1) * self.nz], from, window))
            .collect()
    }

    /// Per texel, the largest opacity over levels `from..` (the whole column for 0).
    pub fn max_above(&self, from: usize) -> Vec<f32> {
        (0..self.rows * self.cols)
            .map(|i| {
                let col = &self.data[i * self.nz..(i + 1) * self.nz];
                col.iter().skip(from).fold(0f32, |m, &v| m.max(v))
            })
            .collect()
    }
}

/// The largest opacity of `window` consecutive levels of one column within `from..`
/// (see [`OpacityVolume::window_max_above`]).
pub fn window_max(col: &[f32], from: usize, window: usize) -> f32 {
    let (w, nz) = (window.max(1), col.len());
    let mut best = 0f32;
    for k in from..nz {
        let t = col[k..(k + w).min(nz)].iter().fold(1f32, |t, &o| t * (1.0 - o));
        best = best.max(1.0 - t);
    }
    best
}

/// Test volumes: empty, then boxes of one opacity.
#[cfg(test)]
impl OpacityVolume {
    pub(crate) fn empty(rows: usize, cols: usize, nz: usize, dz: f32) -> Self {
        OpacityVolume { rows, cols, nz, z0: 0.0, dz, data: vec![0.0; rows * cols * nz] }
    }

    /// Set rows `r`, columns `c`, levels `k` to opacity `o`.
    pub(crate) fn fill_box(
        &mut self,
        r: std::ops::Range<usize>,
        c: std::ops::Range<usize>,
        k: std::ops::Range<usize>,
        o: f32,
    ) {
        for rr in r {
            for cc in c.clone() {
                for kk in k.clone() {
                    self.data[(rr * self.cols + cc) * self.nz + kk] = o;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use assetfield_core::Aabb3;

    #[test]
    fn only_voxels_with_an_empty_neighbour_are_exposed() {
        // a solid 3x3x3 cube in the middle of a 5x5x5 volume
        let n = 5;
        let inside = |i: usize| (1..4).contains(&i);
        let mut data = vec![0f32; n * n * n];
        for r in 0..n {
            for c in 0..n {
                for k in 0..n {
                    if inside(r) && inside(c) && inside(k) {
                        data[(r * n + c) * n + k] = 0.9;
                    }
                }
            }
        }
        let vol = OpacityVolume { rows: n, cols: n, nz: n, z0: 0.0, dz: 0.1, data };
        assert!(!vol.exposed(2, 2, 2, 0.5), "the centre is enclosed");
        for (r, c, k) in
            [(1, 2, 2), (3, 2, 2), (2, 1, 2), (2, 3, 2), (2, 2, 1), (2, 2, 3), (1, 1, 1)]
        {
            assert!(vol.exposed(r, c, k, 0.5), "({r}, {c}, {k}) is on the surface");
        }
        // at a threshold above the cube's opacity every neighbour counts as empty
        assert!(vol.exposed(2, 2, 2, 0.95));
        // the grid's border counts as outside
        let full = OpacityVolume { data: vec![1.0; n * n * n], ..vol };
        assert!(full.exposed(0, 2, 2, 0.5) && full.exposed(2, 2, 4, 0.5));
        assert!(!full.exposed(2, 2, 2, 0.5));
    }

    fn grid() -> PlaneGrid {
        let cfg = FieldConfig::new(
            ModelKind::Standard,
            Aabb3::new(Vec3::new(-2.0, -1.0, 0.0), Vec3::new(2.0, 1.0, 1.0)),
            41,
        );
        PlaneGrid::from_config(&cfg).unwrap()
    }

    #[test]
    fn texel_world_round_trip() {
        let g = grid();
        assert_eq!((g.cols, g.rows), (41, 21));
        assert!((g.texel[0] - 0.1).abs() < 1e-6 && (g.texel[1] - 0.1).abs() < 1e-6);
        // texel (row 0, col 0) is the box corner, row grows with y
        assert_eq!(g.to_world(0.0, 0.0), Vec2::new(-2.0, -1.0));
        let p = g.to_world(40.0, 20.0);
        assert!((p - Vec2::new(2.0, 1.0)).length() < 1e-5);
        let p = g.to_world(10.0, 5.0);
        assert!((p - Vec2::new(-1.0, -0.5)).length() < 1e-5);
        let (c, r) = g.to_texel(Vec2::new(0.25, 0.35));
        assert!((c - 22.5).abs() < 1e-4 && (r - 13.5).abs() < 1e-4);
        // a rectangle of cells covers half a texel beyond the outer nodes
        let w = g.rect_to_world(PixelRect::new(5, 10, 7, 13));
        assert!((w.min - Vec2::new(-1.05, -0.55)).length() < 1e-5, "{w:?}");
        assert!((w.max - Vec2::new(-0.75, -0.35)).length() < 1e-5, "{w:?}");
        assert_eq!(g.world_to_rect(w), Some(PixelRect::new(5, 10, 7, 13)));
        // clipped at the border, None outside
        let r = g.world_to_rect(Rect2::new(Vec2::new(1.9, 0.9), Vec2::new(5.0, 5.0))).unwrap();
        assert_eq!((r.r1, r.c1), (21, 41));
        assert!(g.world_to_rect(Rect2::new(Vec2::splat(5.0), Vec2::splat(6.0))).is_none());
    }

    #[test]
    fn vm_fields_are_refused_with_a_reason() {
        let aabb = Aabb3::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let f = Field::new(FieldConfig::new(ModelKind::Vm, aabb, 8), 1);
        let e = field_planes(&f).unwrap_err().to_string();
        assert!(e.contains("ground plane representation"), "{e}");
        assert!(OpacityVolume::from_field(&f).is_err());
        let f = Field::new(FieldConfig::new(ModelKind::Integrated, aabb, 8), 1);
        let p = field_planes(&f).unwrap();
        let v = OpacityVolume::from_field(&f).unwrap();
        let e = semantic_plane(&f, &v).unwrap_err().to_string();
        assert!(e.contains("semantic.decoder.weight"), "{e}");
        let mut cfg = FieldConfig::new(ModelKind::Integrated, aabb, 8);
        cfg.semantic_channels = 5;
        let fs = Field::new(cfg, 1);
        let sp = semantic_plane(&fs, &OpacityVolume::from_field(&fs).unwrap()).unwrap();
        assert_eq!((sp.rows, sp.cols, sp.ch), (8, 8, 5));
        assert_eq!((p.density.rows, p.density.cols, p.density.ch), (8, 8, 16));
        assert_eq!(p.color.ch, 48);
        assert!(p.color_axis.is_none(), "I-AssetField's colour plane has no axis");
        // S-AssetField: the colour axis, one row of colour channels per level
        let fs = Field::new(FieldConfig::new(ModelKind::Standard, aabb, 8), 1);
        let ps = field_planes(&fs).unwrap();
        let axis = ps.color_axis.as_ref().expect("S-AssetField's colour axis");
        assert_eq!(axis.len(), fs.config.res[2] * ps.color.ch);
        assert_eq!(axis.len(), OpacityVolume::from_field(&fs).unwrap().nz * ps.color.ch);
    }

    #[test]
    fn volume_matches_the_field_density() {
        let aabb = Aabb3::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let f = Field::new(FieldConfig::new(ModelKind::Standard, aabb, 6), 3);
        let v = OpacityVolume::from_field(&f).unwrap();
        let cfg = &f.config;
        let vox = cfg.voxel_size();
        let delta = vox.z * cfg.distance_scale;
        let (r, c, k) = (2, 4, 3);
        let p =
            Vec3::new(-1.0 + c as f32 * vox.x, -1.0 + r as f32 * vox.y, -1.0 + k as f32 * vox.z);
        let want = 1.0 - (-f.density(p) * delta).exp();
        assert!((v.column(r, c)[k] - want).abs() < 1e-6);
        assert!((v.height(k) - p.z).abs() < 1e-6);
        let acc = v.accumulated_above(2)[r * v.cols + c];
        let want = 1.0 - v.column(r, c)[2..].iter().fold(1.0, |t, o| t * (1.0 - o));
        assert!((acc - want).abs() < 1e-6);
        assert!(v.max_above(0)[r * v.cols + c] >= v.column(r, c)[k]);
        let w = v.window_max_above(0, 2)[r * v.cols + c];
        let col = v.column(r, c);
        assert!(w >= 1.0 - (1.0 - col[k]) * (1.0 - col[k + 1]) - 1e-6);
        assert!(w <= acc.max(v.accumulated_above(0)[r * v.cols + c]) + 1e-6);
    }
}
