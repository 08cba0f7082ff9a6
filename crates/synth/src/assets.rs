//! Building the geometry of a script's assets (primitives and OBJ meshes) and serving it as
//! the layout resolver's [`AssetCatalog`].

use crate::SynthError;
use crate::geometry::{AssetGeometry, Material, Shape, Texture};
use crate::sh3f::{Catalog, CatalogError, texture_from_bytes};
use assetfield_core::Rect2;
use assetfield_layout::resolve::asset_info_from_bounds;
use assetfield_layout::script::{Axis, ObjSource};
use assetfield_layout::source::AssetEntry;
use assetfield_layout::{AssetCatalog, AssetInfo, GtSource, LoadedScript};
use glam::{Mat3, Vec2, Vec3};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Every asset of a script, as geometry.
#[derive(Debug, Clone, Default)]
pub struct AssetSet {
    pub geometry: BTreeMap<String, Arc<AssetGeometry>>,
    infos: BTreeMap<String, AssetInfo>,
    /// Catalog, id, creator and licence of every asset that is a catalog model.
    pub sources: BTreeMap<String, GtSource>,
}

impl AssetSet {
    /// Build the geometry of every asset a script defines (loading OBJ files).
    pub fn from_script(script: &LoadedScript) -> Result<Self, SynthError> {
        let mut set = AssetSet::default();
        let mut catalogs = Catalogs::default();
        for (name, entry) in &script.assets {
            let (g, catalog) = build_asset(name, entry, script, &mut catalogs)?;
            let mut info = asset_info_from_bounds(name, &entry.def, g.bounds());
            if let Some((source, size)) = catalog {
                set.sources.insert(name.clone(), source);
                if entry.def.parts.is_empty() {
                    // the catalog's size exactly (the mesh is scaled to it; its triangle
                    // bounds differ by rounding), so layouts drawn from catalog sizes agree
                    info.footprint = Rect2::new(-0.5 * size.truncate(), 0.5 * size.truncate());
                    info.height = size.z;
                }
            }
            info.outline = g.ground_outline();
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

/// Catalog indexes opened while building a script's assets (each zip's index is read once).
#[derive(Debug, Default)]
struct Catalogs {
    open: BTreeMap<String, Catalog>,
}

impl Catalogs {
    fn get(&mut self, name: &str) -> Result<&Catalog, CatalogError> {
        if !self.open.contains_key(name) {
            let c = Catalog::open(name)?;
            self.open.insert(name.to_string(), c);
        }
        Ok(&self.open[name])
    }
}

fn build_asset(
    name: &str,
    entry: &AssetEntry,
    script: &LoadedScript,
    catalogs: &mut Catalogs,
) -> Result<(AssetGeometry, Option<(GtSource, Vec3)>), SynthError> {
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
    let mut source = None;
    match &entry.def.obj {
        Some(ObjSource::Obj { path: rel, scale, up, yaw_deg, recenter }) => {
            let path = entry.base_dir(script).join(rel);
            load_obj_into(&mut g, &path, *scale, *up, *yaw_deg, *recenter).map_err(|message| {
                SynthError::Obj {
                    location: entry.location.clone(),
                    asset: name.to_string(),
                    path: path.clone(),
                    message,
                }
            })?;
        }
        Some(ObjSource::Catalog { name: catalog, id }) => {
            let err = |source: CatalogError| SynthError::Catalog {
                location: entry.location.clone(),
                asset: name.to_string(),
                source: Box::new(source),
            };
            let c = catalogs.get(catalog).map_err(err)?;
            let model = c.model(id).map_err(err)?;
            c.load_into(&mut g, model).map_err(err)?;
            let gt = GtSource {
                catalog: c.name.clone(),
                id: model.id.clone(),
                name: model.name.clone(),
                creator: model.creator.clone(),
                license: model.license.clone(),
            };
            source = Some((gt, model.size_m()));
        }
        None => {}
    }
    if g.shapes.is_empty() {
        return Err(SynthError::EmptyAsset {
            location: entry.location.clone(),
            asset: name.to_string(),
        });
    }
    g.finish();
    Ok((g, source))
}

/// Largest mesh, material or texture file an asset may read (bytes): the catalogs' furniture
/// models and their textures are a few MB each; a quarter GiB leaves room for a detailed
/// scan, and a path that names `/dev/zero` or a growing file stops there.
pub const MAX_MESH_FILE_BYTES: u64 = 256 << 20;

/// Read a file an asset names: a regular file (a FIFO could block, a device never end) of
/// at most [`MAX_MESH_FILE_BYTES`], read through a bounded reader.
fn read_asset_file(path: &Path) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if !meta.is_file() {
        return Err("not a regular file (a folder, a FIFO or a device)".into());
    }
    let too_large =
        |n: u64| format!("{n} bytes, more than the {MAX_MESH_FILE_BYTES} an asset file may have");
    if meta.len() > MAX_MESH_FILE_BYTES {
        return Err(too_large(meta.len()));
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_MESH_FILE_BYTES + 1).read_to_end(&mut bytes))
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > MAX_MESH_FILE_BYTES {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

fn load_texture(path: &Path) -> Result<Texture, String> {
    let bytes = read_asset_file(path).map_err(|e| format!("texture {}: {e}", path.display()))?;
    texture_from_bytes(&bytes).map_err(|e| format!("texture {}: {e}", path.display()))
}

/// A linear map applied to mesh positions, and the one for its normals (the inverse
/// transpose, up to scale).
#[derive(Debug, Clone, Copy)]
pub struct MeshTransform {
    pub linear: Mat3,
    pub normal: Mat3,
}

/// Load an OBJ file (with its MTL diffuse colours and textures) into `g`: levelled so that
/// `up` points along +Z, turned by `yaw_deg`, scaled, and recentred on request.
pub fn load_obj_into(
    g: &mut AssetGeometry,
    path: &Path,
    scale: f32,
    up: Axis,
    yaw_deg: f32,
    recenter: bool,
) -> Result<(), String> {
    if !path.exists() {
        return Err("file not found".into());
    }
    let opts = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let dir = path.parent().unwrap_or(Path::new("."));
    let obj = read_asset_file(path)?;
    let (models, materials) = tobj::load_obj_buf(&mut obj.as_slice(), &opts, |mtl: &Path| {
        match read_asset_file(&dir.join(mtl)) {
            Ok(text) => tobj::load_mtl_buf(&mut text.as_slice()),
            Err(_) => Err(tobj::LoadError::OpenFileFailed),
        }
    })
    .map_err(|e| e.to_string())?;
    let materials = materials.map_err(|e| format!("material library: {e}"))?;
    let level = match up {
        Axis::Z => Mat3::IDENTITY,
        // +Y up -> +Z up: (x, y, z) -> (x, -z, y)
        Axis::Y => Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2),
        // +X up -> +Z up
        Axis::X => Mat3::from_rotation_y(-std::f32::consts::FRAC_PI_2),
    };
    let rot = Mat3::from_rotation_z(yaw_deg.to_radians()) * level;
    let xf = MeshTransform { linear: rot * scale, normal: rot };
    push_obj_models(g, &models, &materials, &xf, recenter, |g, t| {
        g.textures.push(load_texture(&dir.join(t.replace('\\', "/")))?);
        Ok(Some(g.textures.len() - 1))
    })
}

/// Append tobj meshes and their materials to `g` under `xf`; `texture` loads a diffuse
/// texture by its MTL name into `g.textures` and returns its index (`None`: the texture does
/// not exist and the material keeps its plain colour). With `recenter` the new
/// triangles are moved so that their footprint is centred on the origin and they stand on
/// z = 0.
pub fn push_obj_models(
    g: &mut AssetGeometry,
    models: &[tobj::Model],
    materials: &[tobj::Material],
    xf: &MeshTransform,
    recenter: bool,
    mut texture: impl FnMut(&mut AssetGeometry, &str) -> Result<Option<usize>, String>,
) -> Result<(), String> {
    // OBJ materials -> ours (index shift by what the asset already has)
    let base = g.materials.len();
    for m in materials {
        let color = m.diffuse.map(Vec3::from).unwrap_or(Vec3::splat(0.8));
        let texture = match &m.diffuse_texture {
            Some(t) if !t.is_empty() => texture(g, t)?,
            _ => None,
        };
        g.materials.push(Material { color, texture });
    }
    let default_material = g.materials.len();
    g.materials.push(Material { color: Vec3::splat(0.8), texture: None });

    let first_shape = g.shapes.len();
    let mut tri_count = 0usize;
    for model in models {
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
            if [a, b, c].iter().any(|&i| 3 * i as usize + 2 >= m.positions.len()) {
                return Err(format!(
                    "a face refers to vertex {} of {}",
                    a.max(b).max(c),
                    m.positions.len() / 3
                ));
            }
            let (p0, p1, p2) = (xf.linear * pos(a), xf.linear * pos(b), xf.linear * pos(c));
            let nrm = |i: u32| {
                if has_n {
                    (xf.normal
                        * Vec3::new(
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
    if recenter {
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
