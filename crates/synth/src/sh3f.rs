//! Sweet Home 3D furniture catalogs (`.sh3f`): real furniture meshes for ground truth.
//!
//! A catalog is a zip holding `PluginFurnitureCatalog.properties` (a Java properties index:
//! `id#N`, `name#N`, `model#N`, `width#N`, `depth#N`, `height#N` in centimetres, ...) and,
//! per model, an OBJ with its MTL and textures. Debian's `sweethome3d-furniture` installs
//! them in [`DEFAULT_DIR`]; [`DIR_ENV`] points elsewhere. Models are read straight from the
//! zip. Only the catalogs in [`ALLOWED_CATALOGS`] may be used.
//!
//! Sweet Home 3D's model frame is Y up with the model's front facing +Z (towards the
//! viewer); the catalog's `modelRotation` (a 3x3 matrix, rows first) turns the mesh first,
//! then its bounding box is scaled to width (x) x height (y) x depth (z). The asset frame is
//! Z up with the front facing +X, so a model point `(x, y, z)` becomes `(z, x, y)` (a
//! rotation: right-handed both ways): the catalog's depth runs along local x, its width
//! along local y. The footprint is centred on the origin and the model stands on z = 0.

use crate::assets::{MeshTransform, push_obj_models};
use crate::geometry::{AssetGeometry, Texture};
use glam::{Mat3, Vec3};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The catalogs that may be used (the others of the package are refused): their models are
/// under CC-BY licences whose attribution the ground truth records per object.
pub const ALLOWED_CATALOGS: [&str; 2] = ["BlendSwap-CC-BY", "KatorLegaz"];
/// Where Debian's `sweethome3d-furniture` puts the catalogs.
pub const DEFAULT_DIR: &str = "/usr/share/sweethome3d/furniture";
/// Environment variable naming another folder holding the `.sh3f` files.
pub const DIR_ENV: &str = "ASSETFIELD_SH3F_DIR";
/// The index file inside every catalog zip.
const INDEX_FILE: &str = "PluginFurnitureCatalog.properties";
/// Catalog sizes are in centimetres; assets are in metres.
const CM_PER_M: f32 = 100.0;
/// Smallest extent (model units) a mesh axis may have before it counts as flat: scaling a
/// zero-thickness box to a catalog size would divide by zero.
const MIN_MODEL_EXTENT: f32 = 1e-6;

/// Errors of catalog access; [`crate::SynthError::Catalog`] adds the script location.
#[derive(Debug, thiserror::Error)]
pub enum CatalogError {
    #[error("catalog \"{name}\" is not allowed (allowed catalogs: {})", ALLOWED_CATALOGS.join(", "))]
    NotAllowed { name: String },
    #[error(
        "furniture catalog {} not found: install it with `apt-get install sweethome3d-furniture`, or set {DIR_ENV} to the folder holding {name}.sh3f",
        path.display()
    )]
    Missing { name: String, path: PathBuf },
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: not a readable zip: {source}", path.display())]
    Zip {
        path: PathBuf,
        #[source]
        source: zip::result::ZipError,
    },
    #[error("{}: {INDEX_FILE}: {message}", path.display())]
    Index { path: PathBuf, message: String },
    #[error("catalog \"{catalog}\" has no model \"{id}\"{hint}")]
    UnknownModel { catalog: String, id: String, hint: String },
    #[error("catalog \"{catalog}\", model \"{id}\": broken mesh {entry}: {message}")]
    Mesh { catalog: String, id: String, entry: String, message: String },
}

/// The folder the catalogs are read from: `$ASSETFIELD_SH3F_DIR`, else [`DEFAULT_DIR`].
pub fn catalog_dir() -> PathBuf {
    match std::env::var_os(DIR_ENV) {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => PathBuf::from(DEFAULT_DIR),
    }
}

/// Whether every catalog of [`ALLOWED_CATALOGS`] is in `dir` (as `NAME.sh3f`).
pub fn catalogs_installed(dir: &Path) -> bool {
    ALLOWED_CATALOGS.iter().all(|c| dir.join(format!("{c}.sh3f")).is_file())
}

/// One model of a catalog index.
#[derive(Debug, Clone, PartialEq)]
pub struct CatalogModel {
    /// The `N` of its `id#N` keys.
    pub index: u32,
    pub id: String,
    pub name: String,
    pub category: String,
    /// Path of its OBJ inside the zip (without a leading `/`).
    pub model: String,
    pub width_cm: f32,
    pub depth_cm: f32,
    pub height_cm: f32,
    /// Height above the floor it is placed at (wall-mounted, hanging); 0 when absent.
    pub elevation_cm: f32,
    pub door_or_window: bool,
    pub movable: bool,
    pub creator: String,
    /// Its own licence, else the catalog's.
    pub license: String,
    /// `modelRotation`: rows of the 3x3 matrix applied to the mesh first.
    pub model_rotation: Option<[f32; 9]>,
}

impl CatalogModel {
    /// Size in the asset frame, metres: (depth along x, width along y, height along z).
    pub fn size_m(&self) -> Vec3 {
        Vec3::new(self.depth_cm, self.width_cm, self.height_cm) / CM_PER_M
    }
}

/// A catalog's index (no mesh read yet).
#[derive(Debug, Clone)]
pub struct Catalog {
    /// File name without `.sh3f`.
    pub name: String,
    pub path: PathBuf,
    /// The catalog-wide `name=`.
    pub title: String,
    /// The catalog-wide `license=`.
    pub license: String,
    pub models: Vec<CatalogModel>,
}

/// Parse Java properties text (ISO-8859-1 bytes): `#`/`!` comments, `=`, `:` or blank
/// separators, lines continued by an odd number of trailing backslashes, `\uXXXX` and the
/// usual escapes. Later keys win.
pub fn parse_properties(bytes: &[u8]) -> BTreeMap<String, String> {
    // ISO-8859-1: every byte is the code point of the same value
    let text: String = bytes.iter().map(|&b| b as char).collect();
    let mut logical: Vec<String> = Vec::new();
    let mut pending: Option<String> = None;
    for raw in text.split('\n') {
        let raw = raw.strip_suffix('\r').unwrap_or(raw);
        let line = match pending.take() {
            Some(mut p) => {
                p.push_str(raw.trim_start());
                p
            }
            None => {
                let t = raw.trim_start();
                if t.is_empty() || t.starts_with('#') || t.starts_with('!') {
                    continue;
                }
                t.to_string()
            }
        };
        let trailing = line.chars().rev().take_while(|&c| c == '\\').count();
        if trailing % 2 == 1 {
            pending = Some(line[..line.len() - 1].to_string());
        } else {
            logical.push(line);
        }
    }
    if let Some(p) = pending {
        logical.push(p);
    }
    let mut out = BTreeMap::new();
    for line in logical {
        let chars: Vec<char> = line.chars().collect();
        let mut k = 0;
        let mut key_end = chars.len();
        while k < chars.len() {
            match chars[k] {
                '\\' => k += 2,
                '=' | ':' | ' ' | '\t' | '\x0c' => {
                    key_end = k;
                    break;
                }
                _ => k += 1,
            }
        }
        let mut v = key_end.min(chars.len());
        while v < chars.len() && matches!(chars[v], ' ' | '\t' | '\x0c') {
            v += 1;
        }
        if v < chars.len() && matches!(chars[v], '=' | ':') {
            v += 1;
        }
        while v < chars.len() && matches!(chars[v], ' ' | '\t' | '\x0c') {
            v += 1;
        }
        let key = unescape(&chars[..key_end.min(chars.len())]);
        let value = unescape(&chars[v.min(chars.len())..]);
        out.insert(key, value);
    }
    out
}

fn unescape(chars: &[char]) -> String {
    let mut s = String::with_capacity(chars.len());
    let mut k = 0;
    while k < chars.len() {
        let c = chars[k];
        k += 1;
        if c != '\\' || k >= chars.len() {
            s.push(c);
            continue;
        }
        let e = chars[k];
        k += 1;
        match e {
            't' => s.push('\t'),
            'n' => s.push('\n'),
            'r' => s.push('\r'),
            'f' => s.push('\x0c'),
            'u' => {
                let hex: String = chars[k..(k + 4).min(chars.len())].iter().collect();
                match u32::from_str_radix(&hex, 16).ok().and_then(char::from_u32) {
                    Some(ch) if hex.len() == 4 => {
                        s.push(ch);
                        k += 4;
                    }
                    _ => s.push('u'),
                }
            }
            other => s.push(other),
        }
    }
    s
}

fn zip_err(path: &Path) -> impl FnOnce(zip::result::ZipError) -> CatalogError + '_ {
    move |source| CatalogError::Zip { path: path.to_path_buf(), source }
}

fn open_zip(path: &Path) -> Result<zip::ZipArchive<File>, CatalogError> {
    let f =
        File::open(path).map_err(|source| CatalogError::Io { path: path.to_path_buf(), source })?;
    zip::ZipArchive::new(f).map_err(zip_err(path))
}

fn read_entry(
    zip: &mut zip::ZipArchive<File>,
    path: &Path,
    name: &str,
) -> Result<Vec<u8>, CatalogError> {
    let mut f = zip.by_name(name).map_err(zip_err(path))?;
    let mut buf = Vec::with_capacity(f.size() as usize);
    f.read_to_end(&mut buf)
        .map_err(|source| CatalogError::Io { path: path.to_path_buf(), source })?;
    Ok(buf)
}

/// Join a relative reference onto a folder inside the zip, resolving `.` and `..`.
fn zip_join(dir: &str, rel: &str) -> String {
    let rel = rel.replace('\\', "/");
    let mut parts: Vec<&str> = if rel.starts_with('/') {
        Vec::new()
    } else {
        dir.split('/').filter(|p| !p.is_empty()).collect()
    };
    for p in rel.split('/') {
        match p {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            p => parts.push(p),
        }
    }
    parts.join("/")
}

fn parent(entry: &str) -> &str {
    entry.rfind('/').map(|k| &entry[..k]).unwrap_or("")
}

impl Catalog {
    /// Open an allowed catalog by name in [`catalog_dir`] and read its index.
    pub fn open(name: &str) -> Result<Catalog, CatalogError> {
        Catalog::open_in(&catalog_dir(), name)
    }

    /// Open an allowed catalog by name in `dir` and read its index.
    pub fn open_in(dir: &Path, name: &str) -> Result<Catalog, CatalogError> {
        if !ALLOWED_CATALOGS.contains(&name) {
            return Err(CatalogError::NotAllowed { name: name.to_string() });
        }
        let path = dir.join(format!("{name}.sh3f"));
        if !path.is_file() {
            return Err(CatalogError::Missing { name: name.to_string(), path });
        }
        let mut zip = open_zip(&path)?;
        let bytes = read_entry(&mut zip, &path, INDEX_FILE)?;
        let props = parse_properties(&bytes);
        Catalog::from_properties(name, &path, &props)
    }

    /// Build the index from parsed properties (`path` names the catalog in messages).
    pub fn from_properties(
        name: &str,
        path: &Path,
        props: &BTreeMap<String, String>,
    ) -> Result<Catalog, CatalogError> {
        let bad = |message: String| CatalogError::Index { path: path.to_path_buf(), message };
        let license = props.get("license").cloned().unwrap_or_default();
        let mut models = Vec::new();
        for (key, id) in props {
            let Some(n) = key.strip_prefix("id#") else { continue };
            let Ok(index) = n.parse::<u32>() else { continue };
            let get = |field: &str| props.get(&format!("{field}#{index}")).map(|s| s.trim());
            let number = |field: &str, required: bool| -> Result<f32, CatalogError> {
                match get(field) {
                    Some(v) => {
                        v.parse::<f32>().ok().filter(|x| x.is_finite()).ok_or_else(|| {
                            bad(format!("{field}#{index} = \"{v}\" is not a number"))
                        })
                    }
                    None if required => Err(bad(format!("model {id} has no {field}#{index}"))),
                    None => Ok(0.0),
                }
            };
            let model =
                get("model").ok_or_else(|| bad(format!("model {id} has no model#{index}")))?;
            let model_rotation = match get("modelRotation") {
                None => None,
                Some(v) => {
                    let m: Vec<f32> = v.split_whitespace().filter_map(|x| x.parse().ok()).collect();
                    let m: [f32; 9] = m.try_into().map_err(|_| {
                        bad(format!("modelRotation#{index} = \"{v}\" is not 9 numbers"))
                    })?;
                    Some(m)
                }
            };
            let (width_cm, depth_cm, height_cm) =
                (number("width", true)?, number("depth", true)?, number("height", true)?);
            if !(width_cm > 0.0 && depth_cm > 0.0 && height_cm > 0.0) {
                return Err(bad(format!("model {id} has a size that is not positive")));
            }
            models.push(CatalogModel {
                index,
                id: id.clone(),
                name: get("name").unwrap_or_default().to_string(),
                category: get("category").unwrap_or_default().to_string(),
                model: model.trim_start_matches('/').to_string(),
                width_cm,
                depth_cm,
                height_cm,
                elevation_cm: number("elevation", false)?,
                door_or_window: get("doorOrWindow") == Some("true"),
                movable: get("movable") != Some("false"),
                creator: get("creator").unwrap_or_default().to_string(),
                license: get("license").map(str::to_string).unwrap_or_else(|| license.clone()),
                model_rotation,
            });
        }
        models.sort_by_key(|m| m.index);
        Ok(Catalog {
            name: name.to_string(),
            path: path.to_path_buf(),
            title: props.get("name").cloned().unwrap_or_default(),
            license,
            models,
        })
    }

    /// The model with this id, or an error with the closest id as a hint.
    pub fn model(&self, id: &str) -> Result<&CatalogModel, CatalogError> {
        if let Some(m) = self.models.iter().find(|m| m.id == id) {
            return Ok(m);
        }
        let ids: Vec<String> = self.models.iter().map(|m| m.id.clone()).collect();
        let hint = match assetfield_layout::resolve::closest(id, &ids) {
            Some(k) => format!("; did you mean \"{k}\"?"),
            None => format!(
                " ({} models, ids like \"{}\")",
                ids.len(),
                ids.first().cloned().unwrap_or_default()
            ),
        };
        Err(CatalogError::UnknownModel { catalog: self.name.clone(), id: id.to_string(), hint })
    }

    /// Read a model's mesh (OBJ, MTL and textures from the zip) as asset geometry, sized and
    /// oriented as the module docs say.
    pub fn load_geometry(&self, model: &CatalogModel) -> Result<AssetGeometry, CatalogError> {
        let mut g = AssetGeometry::default();
        self.load_into(&mut g, model)?;
        g.finish();
        Ok(g)
    }

    /// [`Self::load_geometry`], appending to `g` (call `g.finish()` afterwards).
    pub fn load_into(
        &self,
        g: &mut AssetGeometry,
        model: &CatalogModel,
    ) -> Result<(), CatalogError> {
        let mut zip = open_zip(&self.path)?;
        let mesh_err = |message: String| CatalogError::Mesh {
            catalog: self.name.clone(),
            id: model.id.clone(),
            entry: model.model.clone(),
            message,
        };
        let obj_bytes = read_entry(&mut zip, &self.path, &model.model)
            .map_err(|e| mesh_err(format!("cannot read it from the zip: {e}")))?;
        let obj_dir = parent(&model.model).to_string();
        // tobj reads lines as UTF-8; the meshes' comments may be Latin-1
        let obj_text = String::from_utf8_lossy(&obj_bytes).into_owned();
        let mut mtls: BTreeMap<String, Result<String, String>> = BTreeMap::new();
        let mut mtl_dir = obj_dir.clone();
        for line in obj_text.lines() {
            if let Some(rest) = line.trim_start().strip_prefix("mtllib") {
                for name in rest.split_whitespace() {
                    let entry = zip_join(&obj_dir, name);
                    if mtls.is_empty() {
                        mtl_dir = parent(&entry).to_string();
                    }
                    let text = read_entry(&mut zip, &self.path, &entry)
                        .map(|b| String::from_utf8_lossy(&b).into_owned())
                        .map_err(|e| e.to_string());
                    mtls.insert(name.to_string(), text);
                }
            }
        }
        let opts = tobj::LoadOptions {
            single_index: true,
            triangulate: true,
            ignore_points: true,
            ignore_lines: true,
        };
        let (models, materials) =
            tobj::load_obj_buf(&mut obj_text.as_bytes(), &opts, |p: &Path| {
                let key = p.to_string_lossy().into_owned();
                match mtls.get(&key) {
                    Some(Ok(text)) => tobj::load_mtl_buf(&mut text.as_bytes()),
                    _ => Err(tobj::LoadError::OpenFileFailed),
                }
            })
            .map_err(|e| mesh_err(e.to_string()))?;
        let materials = materials.map_err(|e| mesh_err(format!("material library: {e}")))?;

        // the mesh's bounds after modelRotation, in Sweet Home 3D's frame
        let rot = match model.model_rotation {
            Some(m) => Mat3::from_cols_array(&m).transpose(),
            None => Mat3::IDENTITY,
        };
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for m in &models {
            for p in m.mesh.positions.chunks_exact(3) {
                let q = rot * Vec3::new(p[0], p[1], p[2]);
                lo = lo.min(q);
                hi = hi.max(q);
            }
        }
        let extent = hi - lo;
        if !(extent.is_finite() && extent.min_element() > MIN_MODEL_EXTENT) {
            return Err(mesh_err(format!("its bounding box {extent} is empty or flat")));
        }
        // scale to width (x) x height (y) x depth (z), in metres
        let target = Vec3::new(model.width_cm, model.height_cm, model.depth_cm) / CM_PER_M;
        let scale = Mat3::from_diagonal(target / extent);
        // Sweet Home 3D (x right, y up, z front) -> asset (x front, y, z up): (x, y, z) -> (z, x, y)
        let axes = Mat3::from_cols(Vec3::Y, Vec3::Z, Vec3::X);
        let xf = MeshTransform { linear: axes * scale * rot, normal: axes * scale.inverse() * rot };
        let mut textures: BTreeMap<String, usize> = BTreeMap::new();
        // a texture named by a path of its author's machine is looked for by its file name
        // next to the MTL; one that is not in the zip at all leaves the plain colour (as Sweet
        // Home 3D shows it)
        let mut load_texture = |g: &mut AssetGeometry, mtl_dir: &str, name: &str| {
            let direct = zip_join(mtl_dir, name);
            let by_file_name =
                zip_join(mtl_dir, name.replace('\\', "/").rsplit('/').next().unwrap_or(name));
            let Some(entry) =
                [direct, by_file_name].into_iter().find(|e| zip.index_for_name(e).is_some())
            else {
                return Ok(None);
            };
            if let Some(k) = textures.get(&entry) {
                return Ok(Some(*k));
            }
            let bytes = read_entry(&mut zip, &self.path, &entry)
                .map_err(|e| format!("texture {entry}: {e}"))?;
            let t = texture_from_bytes(&bytes).map_err(|e| format!("texture {entry}: {e}"))?;
            g.textures.push(t);
            textures.insert(entry, g.textures.len() - 1);
            Ok(Some(g.textures.len() - 1))
        };
        // textures are relative to the MTL (one per model in these catalogs)
        push_obj_models(g, &models, &materials, &xf, true, |g, name| {
            load_texture(g, &mtl_dir, name)
        })
        .map_err(mesh_err)
    }
}

/// Decode a PNG or JPEG texture.
pub fn texture_from_bytes(bytes: &[u8]) -> Result<Texture, String> {
    let img = image::load_from_memory(bytes).map_err(|e| e.to_string())?.to_rgb8();
    let rgb =
        img.pixels().map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0).collect();
    Ok(Texture { width: img.width(), height: img.height(), rgb })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn properties_escapes_continuations_and_latin1() {
        let text = b"# comment\n! other\nid#1=Kator Legaz#chair\nname#1 = Caf\\u00e9 chair\nlicense=Copyright \xa9 2008\nlong = one \\\n    two\nkey\\=with = v\nempty\n";
        let p = parse_properties(text);
        assert_eq!(p["id#1"], "Kator Legaz#chair");
        assert_eq!(p["name#1"], "Caf\u{e9} chair");
        assert_eq!(p["license"], "Copyright \u{a9} 2008");
        assert_eq!(p["long"], "one two");
        assert_eq!(p["key=with"], "v");
        assert_eq!(p["empty"], "");
    }

    #[test]
    fn zip_paths_resolve_relative_parts() {
        assert_eq!(zip_join("a/b", "c.mtl"), "a/b/c.mtl");
        assert_eq!(zip_join("a/b", "../t/x.jpg"), "a/t/x.jpg");
        assert_eq!(zip_join("a/b", "./x.jpg"), "a/b/x.jpg");
        assert_eq!(zip_join("a/b", "/root/x.jpg"), "root/x.jpg");
    }

    #[test]
    fn other_catalogs_are_refused_naming_the_allowed_ones() {
        let e = Catalog::open_in(Path::new("/nowhere"), "Scopia").unwrap_err().to_string();
        assert!(e.contains("Scopia") && e.contains("BlendSwap-CC-BY, KatorLegaz"), "{e}");
        let e = Catalog::open_in(Path::new("/nowhere"), "KatorLegaz").unwrap_err().to_string();
        assert!(e.contains("apt-get install sweethome3d-furniture") && e.contains(DIR_ENV), "{e}");
    }
}
