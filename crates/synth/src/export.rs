//! The scene as meshes, for rendering it with another renderer (`scripts/blender_render.py`
//! renders the dataset's cameras with Blender's Cycles: soft shadows, its own shading and
//! texture filtering): every instance of a resolved layout, containers included, written as
//! one Wavefront OBJ in world coordinates (Z up, the scene's units), primitives tessellated,
//! with an MTL of diffuse colours and each textured material's texture as a PNG.
//!
//! Colours go to the MTL as linear values (`Kd`, from the sRGB colours this renderer shades
//! with), so that a linear renderer with a standard view transform shows them as they are
//! here; a textured material's colour is multiplied into its texture.

use crate::assets::AssetSet;
use crate::error::SynthError;
use crate::geometry::{AssetGeometry, Shape, Texture, from_axis_frame};
use assetfield_core::CoreError;
use assetfield_core::canvas::srgb_to_linear;
use assetfield_core::fsx::{save_png, write_atomic};
use assetfield_layout::ResolvedLayout;
use glam::{Affine3A, Vec2, Vec3};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Segments around a tessellated cylinder, cone or sphere: fine enough that a 256-pixel view
/// of a room shows no facets on a table's rim (a 0.5 m rim: 5 cm chords).
const ROUND_SEGMENTS: usize = 32;
/// Latitude bands of a tessellated sphere.
const SPHERE_BANDS: usize = 16;

/// What [`export_obj`] wrote.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshExport {
    pub vertices: usize,
    pub triangles: usize,
    pub materials: usize,
    pub textures: usize,
}

/// Triangles of one material in world coordinates: positions, normals, texture coordinates.
#[derive(Default)]
struct Batch {
    p: Vec<Vec3>,
    n: Vec<Vec3>,
    uv: Vec<Vec2>,
}

impl Batch {
    fn tri(&mut self, p: [Vec3; 3], n: [Vec3; 3], uv: [Vec2; 3]) {
        self.p.extend(p);
        self.n.extend(n);
        self.uv.extend(uv);
    }

    /// A flat quad `a b c d` (counter-clockwise seen from outside).
    fn quad(&mut self, a: Vec3, b: Vec3, c: Vec3, d: Vec3) {
        let n = (b - a).cross(d - a).normalize_or_zero();
        self.tri([a, b, c], [n; 3], [Vec2::ZERO; 3]);
        self.tri([a, c, d], [n; 3], [Vec2::ZERO; 3]);
    }
}

/// The local triangles of one shape, into `b` (local frame; the caller transforms).
fn tessellate(shape: &Shape, b: &mut Batch) {
    match *shape {
        Shape::Box { center, half, cos, sin } => {
            let corner = |sx: f32, sy: f32, sz: f32| {
                let (x, y) = (sx * half.x, sy * half.y);
                center + Vec3::new(cos * x - sin * y, sin * x + cos * y, sz * half.z)
            };
            let c = |i: usize| {
                let s = |bit: usize| if i >> bit & 1 == 1 { 1.0 } else { -1.0 };
                corner(s(0), s(1), s(2))
            };
            // faces by corner index (bit 0: x, bit 1: y, bit 2: z), outward windings
            for [a, bb, cc, d] in
                [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
            {
                b.quad(c(a), c(bb), c(cc), c(d));
            }
        }
        Shape::Frustum { base, axis, r0, r1, height } => {
            let frame = |v: Vec3| base + from_axis_frame(axis, v);
            let ring = |r: f32, z: f32, i: usize| {
                let a = std::f32::consts::TAU * i as f32 / ROUND_SEGMENTS as f32;
                frame(Vec3::new(r * a.cos(), r * a.sin(), z))
            };
            let (bottom, top) = (frame(Vec3::ZERO), frame(Vec3::new(0.0, 0.0, height)));
            for i in 0..ROUND_SEGMENTS {
                let (a0, a1) = (ring(r0, 0.0, i), ring(r0, 0.0, i + 1));
                let (b0, b1) = (ring(r1, height, i), ring(r1, height, i + 1));
                if r0 > 0.0 || r1 > 0.0 {
                    b.quad(a0, a1, b1, b0);
                }
                if r0 > 0.0 {
                    let n = (a0 - a1).cross(bottom - a1).normalize_or_zero();
                    b.tri([a1, a0, bottom], [n; 3], [Vec2::ZERO; 3]);
                }
                if r1 > 0.0 {
                    let n = (b1 - b0).cross(top - b0).normalize_or_zero();
                    b.tri([b0, b1, top], [n; 3], [Vec2::ZERO; 3]);
                }
            }
        }
        Shape::Sphere { center, radius } => {
            let at = |band: usize, seg: usize| {
                let th = std::f32::consts::PI * band as f32 / SPHERE_BANDS as f32;
                let ph = std::f32::consts::TAU * seg as f32 / ROUND_SEGMENTS as f32;
                Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos())
            };
            for band in 0..SPHERE_BANDS {
                for seg in 0..ROUND_SEGMENTS {
                    let q = [
                        at(band, seg),
                        at(band + 1, seg),
                        at(band + 1, seg + 1),
                        at(band, seg + 1),
                    ];
                    let p = q.map(|u| center + u * radius);
                    b.tri([p[0], p[1], p[2]], [q[0], q[1], q[2]], [Vec2::ZERO; 3]);
                    b.tri([p[0], p[2], p[3]], [q[0], q[2], q[3]], [Vec2::ZERO; 3]);
                }
            }
        }
        Shape::Triangle { v0, e1, e2, n, uv, smooth } => {
            let flat = e1.cross(e2).normalize_or_zero();
            b.tri([v0, v0 + e1, v0 + e2], if smooth { n } else { [flat; 3] }, uv);
        }
    }
}

/// A texture times a colour, as an RGB8 image.
fn tinted(t: &Texture, color: Vec3) -> image::RgbImage {
    image::RgbImage::from_fn(t.width, t.height, |x, y| {
        let c = t.rgb[(y * t.width + x) as usize] * color;
        image::Rgb(c.to_array().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
    })
}

/// Write `dir/scene.obj`, `dir/scene.mtl` and `dir/textures/*.png` (see the module docs).
pub fn export_obj(
    layout: &ResolvedLayout,
    assets: &AssetSet,
    dir: &Path,
) -> Result<MeshExport, SynthError> {
    std::fs::create_dir_all(dir.join("textures")).map_err(|e| CoreError::io(dir, e))?;
    // every asset tessellated once, per material, in its own frame
    let mut local: BTreeMap<&str, BTreeMap<usize, Batch>> = BTreeMap::new();
    for inst in &layout.instances {
        let Some(g) = assets.geometry.get(&inst.asset) else { continue };
        local.entry(inst.asset.as_str()).or_insert_with(|| {
            let mut per_material: BTreeMap<usize, Batch> = BTreeMap::new();
            for (shape, &m) in g.shapes.iter().zip(&g.shape_material) {
                tessellate(shape, per_material.entry(m as usize).or_default());
            }
            per_material
        });
    }
    // one batch per (asset, material) in world coordinates, so that the MTL lists each
    // material once
    let mut batches: BTreeMap<(&str, usize), Batch> = BTreeMap::new();
    for inst in &layout.instances {
        let Some(per_material) = local.get(inst.asset.as_str()) else { continue };
        let world: Affine3A = inst.transform.to_affine();
        for (&m, b) in per_material {
            let out = batches.entry((inst.asset.as_str(), m)).or_default();
            out.p.extend(b.p.iter().map(|&p| world.transform_point3(p)));
            out.n.extend(b.n.iter().map(|&n| world.transform_vector3(n).normalize_or_zero()));
            out.uv.extend(&b.uv);
        }
    }
    let mut mtl = String::new();
    let mut obj = String::from("# assetfield scene: world coordinates, Z up\nmtllib scene.mtl\n");
    let (mut vertices, mut textures) = (0usize, 0usize);
    for (i, ((asset, m), b)) in batches.iter().enumerate() {
        let g: &AssetGeometry = &assets.geometry[*asset];
        let mat = &g.materials[*m];
        let name = format!("m{i}");
        let lin = mat.color.to_array().map(srgb_to_linear);
        let _ = writeln!(
            mtl,
            "newmtl {name}\nKd {:.6} {:.6} {:.6}\nKs 0 0 0\nillum 1",
            lin[0], lin[1], lin[2]
        );
        if let Some(t) = mat.texture.and_then(|t| g.textures.get(t)) {
            let file = format!("textures/{name}.png");
            save_png(&dir.join(&file), &image::DynamicImage::ImageRgb8(tinted(t, mat.color)))?;
            let _ = writeln!(mtl, "map_Kd {file}");
            textures += 1;
        }
        let _ =
            writeln!(obj, "o {name}_{}\nusemtl {name}", asset.replace(char::is_whitespace, "_"));
        for p in &b.p {
            let _ = writeln!(obj, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z);
        }
        for n in &b.n {
            let _ = writeln!(obj, "vn {:.5} {:.5} {:.5}", n.x, n.y, n.z);
        }
        for uv in &b.uv {
            let _ = writeln!(obj, "vt {:.6} {:.6}", uv.x, uv.y);
        }
        for t in 0..b.p.len() / 3 {
            let k = |j: usize| vertices + 3 * t + j + 1;
            let _ = writeln!(obj, "f {0}/{0}/{0} {1}/{1}/{1} {2}/{2}/{2}", k(0), k(1), k(2));
        }
        vertices += b.p.len();
    }
    write_atomic(&dir.join("scene.mtl"), mtl.as_bytes())?;
    write_atomic(&dir.join("scene.obj"), obj.as_bytes())?;
    Ok(MeshExport { vertices, triangles: vertices / 3, materials: batches.len(), textures })
}
