//! Building the geometry of a script's assets (primitives and OBJ meshes) and serving it as
//! the layout resolver's [`AssetCatalog`].

use crate::SynthError;
use crate::geometry::{AssetGeometry, Material, Shape, Texture};
use assetfield_layout::resolve::asset_info_from_bounds;
use assetfield_layout::script::{Axis, ObjSource};
use assetfield_layout::source::AssetEntry;
use assetfield_layout::{AssetCatalog, AssetInfo, LoadedScript};
use glam::{Mat3, Vec2, Vec3};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Every asset of a script, as geometry.
#[derive(Debug, Clone, Default)]
pub struct AssetSet {
    pub geometry: BTreeMap<String, Arc<AssetGeometry>>,
    infos: BTreeMap<String, AssetInfo>,
}

impl AssetSet {
    /// Build the geometry of every asset a script defines (loading OBJ files).
    pub fn from_script(script: &LoadedScript) -> Result<Self, SynthError> {
        let mut set = AssetSet::default();
        for (name, entry) in &script.assets {
            let g = build_asset(name, entry, script)?;
            let info = asset_info_from_bounds(name, &entry.def, g.bounds());
            set.infos.insert(name.clone(), info);
            set.geometry.insert(name.clone(), Arc::new(g));
        }
        Ok(set)
    }
}

impl AssetCatalog for AssetSet {
    fn asset_info(&self, name: &str) -> Option<AssetInfo> {
        self.infos.get(name).cloned()
    }
    fn asset_names(&self) -> Vec<String> {
        self.infos.keys().cloned().collect()
    }
}

fn build_asset(
    name: &str,
    entry: &AssetEntry,
    script: &LoadedScript,
) -> Result<AssetGeometry, SynthError> {
    if let Some(l) = &entry.def.library {
        return Err(SynthError::LibraryAsset {
            location: entry.location.clone(),
            asset: name.to_string(),
            library: l.path.clone(),
        });
    }
    let mut g = AssetGeometry::default();
    for p in &entry.def.parts {
        g.push_part(p);
    }
    if let Some(obj) = &entry.def.obj {
        let path = entry.base_dir(script).join(&obj.path);
        load_obj_into(&mut g, &path, obj).map_err(|message| SynthError::Obj {
            location: entry.location.clone(),
            asset: name.to_string(),
            path: path.clone(),
            message,
        })?;
    }
    if g.shapes.is_empty() {
        return Err(SynthError::EmptyAsset {
            location: entry.location.clone(),
            asset: name.to_string(),
        });
    }
    g.finish();
    Ok(g)
}

fn load_texture(path: &Path) -> Result<Texture, String> {
    let img = image::open(path).map_err(|e| format!("texture {}: {e}", path.display()))?.to_rgb8();
    let rgb =
        img.pixels().map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0).collect();
    Ok(Texture { width: img.width(), height: img.height(), rgb })
}

/// Load an OBJ (with its MTL diffuse colours and textures) into `g`, levelled, scaled and
/// recentred as `src` asks.
pub fn load_obj_into(g: &mut AssetGeometry, path: &Path, src: &ObjSource) -> Result<(), String> {
    if !path.exists() {
        return Err("file not found".into());
    }
    let opts = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, materials) = tobj::load_obj(path, &opts).map_err(|e| e.to_string())?;
    let materials = materials.map_err(|e| format!("material library: {e}"))?;
    let dir = path.parent().unwrap_or(Path::new("."));

    // OBJ materials -> ours (index shift by what the asset already has)
    let base = g.materials.len();
    for m in &materials {
        let color = m.diffuse.map(Vec3::from).unwrap_or(Vec3::splat(0.8));
        let texture = match &m.diffuse_texture {
            Some(t) if !t.is_empty() => {
                g.textures.push(load_texture(&dir.join(t.replace('\\', "/")))?);
                Some(g.textures.len() - 1)
            }
            _ => None,
        };
        g.materials.push(Material { color, texture });
    }
    let default_material = g.materials.len();
    g.materials.push(Material { color: Vec3::splat(0.8), texture: None });

    let level = match src.up {
        Axis::Z => Mat3::IDENTITY,
        // +Y up -> +Z up: (x, y, z) -> (x, -z, y)
        Axis::Y => Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2),
        // +X up -> +Z up
        Axis::X => Mat3::from_rotation_y(-std::f32::consts::FRAC_PI_2),
    };
    let rot = Mat3::from_rotation_z(src.yaw_deg.to_radians()) * level;
    let xf = |p: Vec3| rot * p * src.scale;

    let first_shape = g.shapes.len();
    let mut tri_count = 0usize;
    for model in &models {
        let m = &model.mesh;
        let pos = |i: u32| {
            Vec3::new(
                m.positions[3 * i as usize],
                m.positions[3 * i as usize + 1],
                m.positions[3 * i as usize + 2],
            )
        };
        let has_n = m.normals.len() == m.positions.len();
        let has_uv = m.texcoords.len() / 2 == m.positions.len() / 3;
        let mat = m
            .material_id
            .map(|k| base + k)
            .filter(|k| *k < default_material)
            .unwrap_or(default_material);
        for tri in m.indices.chunks_exact(3) {
            let [a, b, c] = [tri[0], tri[1], tri[2]];
            let (p0, p1, p2) = (xf(pos(a)), xf(pos(b)), xf(pos(c)));
            let nrm = |i: u32| {
                if has_n {
                    (rot * Vec3::new(
                        m.normals[3 * i as usize],
                        m.normals[3 * i as usize + 1],
                        m.normals[3 * i as usize + 2],
                    ))
                    .normalize_or_zero()
                } else {
                    Vec3::ZERO
                }
            };
            let uv = |i: u32| {
                if has_uv {
                    Vec2::new(m.texcoords[2 * i as usize], m.texcoords[2 * i as usize + 1])
                } else {
                    Vec2::ZERO
                }
            };
            g.shapes.push(Shape::Triangle {
                v0: p0,
                e1: p1 - p0,
                e2: p2 - p0,
                n: [nrm(a), nrm(b), nrm(c)],
                uv: [uv(a), uv(b), uv(c)],
                smooth: has_n,
            });
            g.shape_material.push(mat as u32);
            tri_count += 1;
        }
    }
    if tri_count == 0 {
        return Err("the mesh has no faces".into());
    }
    if src.recenter {
        let b = g.shapes[first_shape..]
            .iter()
            .fold(assetfield_core::Aabb3::EMPTY, |acc, s| acc.union(&s.bounds()));
        let c = b.center();
        let shift = Vec3::new(-c.x, -c.y, -b.min.z);
        for s in &mut g.shapes[first_shape..] {
            if let Shape::Triangle { v0, .. } = s {
                *v0 += shift;
            }
        }
    }
    Ok(())
}
