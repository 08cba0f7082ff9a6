//! The asset library on disk (paper Sec. 3.4): feature patches of templates and instances,
//! an emptied container, and the tensors shared by every patch.
//!
//! A library is a folder:
//!
//! * `index.ron`: [`LibraryIndex`] (format `assetfield-library/1`): sources, model kind,
//!   texel size, categories (name, template entry, members), entries (name, category, kind,
//!   tensor names, patch size, world extents, base height, source box, yaw relative to the
//!   template, residual, support), the containers, and the shared-tensor file with a content
//!   hash of it.
//! * `patches.safetensors`: per entry `ENTRY.density` `[h, w, Nd]`, `ENTRY.color`
//!   `[h, w, Nc]` (f32) and `ENTRY.mask` `[h, w]` (u8, 1 = the object's own texels); per
//!   container `NAME.density`, `NAME.color` (the whole planes with the objects filled with
//!   the surrounding background) and `NAME.mask` (1 = texels that were filled).
//! * `shared.safetensors`: every non-plane tensor of the field (vertical axes, colour basis,
//!   guidance MLPs, decoders), with the field configuration (JSON) in the metadata key
//!   `config`.
//!
//! [`open_library`] checks the index against the tensors (a shape that differs names the
//! tensor, the expected and the actual shape) and the shared file against its hash;
//! [`merge_libraries`] builds a cross-scene library from libraries whose shared tensors are
//! identical and refuses, naming the first tensor that differs, otherwise.

use assetfield_core::TensorFile;
use assetfield_core::fsx::{StagingDir, write_atomic};
use glam::Vec2;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::error::{MiningError, Result, check_interrupt};

/// Format tag of `index.ron`.
pub const FORMAT: &str = "assetfield-library/1";
/// Format tag in the metadata of `shared.safetensors`.
pub const SHARED_FORMAT: &str = "assetfield-library-shared/1";
pub const INDEX_FILE: &str = "index.ron";
pub const PATCHES_FILE: &str = "patches.safetensors";
pub const SHARED_FILE: &str = "shared.safetensors";

/// Whether an entry is its category's template.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum EntryKind {
    Template,
    Instance,
}

/// One object patch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Entry")]
pub struct Entry {
    pub name: String,
    pub category: String,
    pub kind: EntryKind,
    /// Tensor names in `patches.safetensors`.
    pub density: String,
    pub color: String,
    pub mask: String,
    /// Patch size in texels `(h, w)` = (rows along y, columns along x).
    pub patch_size: (usize, usize),
    /// World size of the object: footprint along x and y (its bounding box in the source
    /// plane) and height above its base.
    pub extent: (f32, f32, f32),
    /// World height of the object's base (0 on the ground, the surface height for objects
    /// standing on another one).
    pub base: f32,
    /// The object's box in the source plane `[xmin, ymin, xmax, ymax]`.
    pub source_box: [f32; 4],
    /// World `(x, y)` where the template's origin (its pivot) lands on this object.
    pub position: (f32, f32),
    /// World `(x, y)` of this object's pivot, the point layouts place and turn it about
    /// (the centre of its ground contact, see [`crate::pivot`]); absent: its box centre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pivot: Option<(f32, f32)>,
    /// Counter-clockwise yaw taking the template onto this object, degrees.
    pub yaw_deg: f32,
    /// Template-matching residual (0 for the template, -1 when the patches could not be
    /// matched).
    pub residual: f32,
    /// The plane the residual was measured on (`"density"`, `"color"` or `"semantic"`):
    /// residuals are compared only with others measured on the same; absent in older
    /// libraries.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matched_on: Option<String>,
    /// The entry this object stands on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub supported_by: Option<String>,
    /// Index into [`LibraryIndex::sources`].
    #[serde(default)]
    pub source: usize,
}

impl Entry {
    /// World centre of the object's box (and of its patch).
    pub fn box_centre(&self) -> Vec2 {
        let b = self.source_box;
        Vec2::new(b[0] + b[2], b[1] + b[3]) * 0.5
    }

    /// World pivot (see [`Entry::pivot`]).
    pub fn pivot_world(&self) -> Vec2 {
        self.pivot.map_or_else(|| self.box_centre(), |(x, y)| Vec2::new(x, y))
    }

    /// The pivot relative to the patch centre (local x and y of the entry's own frame, which
    /// is the source scene's at yaw 0).
    pub fn pivot_offset(&self) -> Vec2 {
        self.pivot_world() - self.box_centre()
    }
}

/// A category of entries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Category")]
pub struct Category {
    pub name: String,
    pub template: String,
    pub members: Vec<String>,
}

/// A whole scene's planes with the objects removed (a canvas for composing).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Container")]
pub struct Container {
    pub name: String,
    pub density: String,
    pub color: String,
    pub mask: String,
    /// `(rows, cols)` in texels.
    pub size: (usize, usize),
    /// World box of the planes `[xmin, ymin, xmax, ymax]` (texel cells).
    pub world: [f32; 4],
    pub source: usize,
}

impl Container {
    /// A container whose tensors are `NAME.density`, `NAME.color` and `NAME.mask`.
    pub fn named(name: &str, size: (usize, usize), world: [f32; 4], source: usize) -> Self {
        Container {
            name: name.into(),
            density: format!("{name}.density"),
            color: format!("{name}.color"),
            mask: format!("{name}.mask"),
            size,
            world,
            source,
        }
    }
}

/// The shared-tensor file and its content hash.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Shared")]
pub struct SharedRef {
    pub file: String,
    /// `fnv1a64:` + 16 hex digits over every tensor's name, shape and values, in name order.
    pub hash: String,
    pub tensors: Vec<String>,
}

/// `index.ron`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Library")]
pub struct LibraryIndex {
    pub format: String,
    /// The field files the library was mined from.
    pub sources: Vec<String>,
    /// `s` or `i`.
    pub model: String,
    /// World size of one texel `(x, y)`.
    pub texel_size: (f32, f32),
    /// Feature channels of the density and colour planes.
    pub channels: (usize, usize),
    pub patches: String,
    pub shared: SharedRef,
    pub categories: Vec<Category>,
    pub entries: Vec<Entry>,
    pub containers: Vec<Container>,
}

impl LibraryIndex {
    pub fn entry(&self, name: &str) -> Option<&Entry> {
        self.entries.iter().find(|e| e.name == name)
    }
}

/// A library read by [`open_library`], checked.
#[derive(Debug, Clone)]
pub struct Library {
    pub dir: PathBuf,
    pub index: LibraryIndex,
    pub patches: TensorFile,
    pub shared: TensorFile,
}

fn ron_options() -> ron::Options {
    ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
}

/// Serialise an index as pretty RON.
pub fn index_to_ron(index: &LibraryIndex) -> Result<String> {
    let cfg = ron::ser::PrettyConfig::new().struct_names(true).depth_limit(4).indentor("    ");
    let body = ron_options()
        .to_string_pretty(index, cfg)
        .map_err(|e| MiningError::io("cannot serialise the library index", e))?;
    Ok(format!("#![enable(implicit_some)]\n{body}\n"))
}

/// Parse an index.
pub fn index_from_ron(path: &Path, text: &str) -> Result<LibraryIndex> {
    let index: LibraryIndex = ron_options().from_str(text).map_err(|e| MiningError::Format {
        path: path.display().to_string(),
        message: format!(
            "line {} column {}: {} (expected an asset library index written by `assetfield mine`)",
            e.span.start.line, e.span.start.col, e.code
        ),
    })?;
    if index.format != FORMAT {
        return Err(MiningError::Format {
            path: path.display().to_string(),
            message: format!("format is {:?}, expected {FORMAT:?}", index.format),
        });
    }
    Ok(index)
}

/// FNV-1a (64 bit) over every tensor's name, shape and raw values, in name order.
pub fn content_hash(file: &TensorFile) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for (name, t) in &file.tensors {
        eat(name.as_bytes());
        eat(&[0]);
        for &d in &t.shape {
            eat(&(d as u64).to_le_bytes());
        }
        eat(t.data.dtype_name().as_bytes());
        match &t.data {
            assetfield_core::TensorData::F32(v) => v.iter().for_each(|x| eat(&x.to_le_bytes())),
            assetfield_core::TensorData::U8(v) => eat(v),
            assetfield_core::TensorData::I64(v) => v.iter().for_each(|x| eat(&x.to_le_bytes())),
        }
    }
    format!("fnv1a64:{h:016x}")
}

/// Write a library folder's files into `dir` (which must exist): index, patches, shared.
pub fn write_library_files(
    dir: &Path,
    index: &LibraryIndex,
    patches: &TensorFile,
    shared: &TensorFile,
) -> Result<()> {
    check_interrupt()?;
    patches.save(&dir.join(&index.patches))?;
    check_interrupt()?;
    shared.save(&dir.join(&index.shared.file))?;
    write_atomic(&dir.join(INDEX_FILE), index_to_ron(index)?.as_bytes())?;
    Ok(())
}

/// Check the index against the tensors: every entry's and container's tensors exist with the
/// shapes the index implies, and the shared file matches its hash.
pub fn validate(
    index: &LibraryIndex,
    patches: &TensorFile,
    shared: &TensorFile,
    dir: &Path,
) -> Result<()> {
    let ppath = dir.join(&index.patches).display().to_string();
    let (nd, nc) = index.channels;
    let check = |name: &str, expected: Vec<usize>| -> Result<()> {
        match patches.shape_of(name) {
            None => Err(MiningError::MissingTensor {
                source_name: ppath.clone(),
                name: name.to_string(),
                purpose: "an entry of the library index".into(),
            }),
            Some(actual) if actual != expected.as_slice() => Err(MiningError::LibraryMismatch {
                path: ppath.clone(),
                tensor: name.to_string(),
                expected,
                actual: actual.to_vec(),
            }),
            Some(_) => Ok(()),
        }
    };
    for e in &index.entries {
        let (h, w) = e.patch_size;
        check(&e.density, vec![h, w, nd])?;
        check(&e.color, vec![h, w, nc])?;
        check(&e.mask, vec![h, w])?;
        if let Some((x, y)) = e.pivot
            && !(x.is_finite() && y.is_finite())
        {
            return Err(MiningError::Format {
                path: dir.join(INDEX_FILE).display().to_string(),
                message: format!("entry {:?} has pivot ({x}, {y}), which is not finite", e.name),
            });
        }
    }
    for c in &index.containers {
        let (h, w) = c.size;
        check(&c.density, vec![h, w, nd])?;
        check(&c.color, vec![h, w, nc])?;
        check(&c.mask, vec![h, w])?;
    }
    let names: BTreeSet<&str> = index.entries.iter().map(|e| e.name.as_str()).collect();
    for c in &index.categories {
        for m in std::iter::once(&c.template).chain(&c.members) {
            if !names.contains(m.as_str()) {
                return Err(MiningError::Format {
                    path: dir.join(INDEX_FILE).display().to_string(),
                    message: format!(
                        "category {:?} names entry {m:?}, which does not exist",
                        c.name
                    ),
                });
            }
        }
    }
    let hash = content_hash(shared);
    if hash != index.shared.hash {
        return Err(MiningError::Format {
            path: dir.join(&index.shared.file).display().to_string(),
            message: format!(
                "content hash {hash} does not match the index ({}): the shared tensors were changed",
                index.shared.hash
            ),
        });
    }
    Ok(())
}

/// Read and check a library folder.
pub fn open_library(dir: &Path) -> Result<Library> {
    let ipath = dir.join(INDEX_FILE);
    let text = std::fs::read_to_string(&ipath).map_err(|e| {
        MiningError::io(format!("{} (is this an asset library folder?)", ipath.display()), e)
    })?;
    let index = index_from_ron(&ipath, &text)?;
    let patches = TensorFile::load(&dir.join(&index.patches))?;
    let shared = TensorFile::load(&dir.join(&index.shared.file))?;
    validate(&index, &patches, &shared, dir)?;
    Ok(Library { dir: dir.to_path_buf(), index, patches, shared })
}

/// Compare two shared files; the first difference as (tensor, detail).
pub fn shared_difference(a: &TensorFile, b: &TensorFile) -> Option<(String, String)> {
    let names: BTreeSet<&str> = a.names().chain(b.names()).collect();
    for n in names {
        match (a.tensors.get(n), b.tensors.get(n)) {
            (Some(_), None) => return Some((n.into(), "present only in the first".into())),
            (None, Some(_)) => return Some((n.into(), "present only in the second".into())),
            (Some(x), Some(y)) => {
                if x.shape != y.shape {
                    return Some((n.into(), format!("shape {:?} vs {:?}", x.shape, y.shape)));
                }
                match (&x.data, &y.data) {
                    (assetfield_core::TensorData::F32(p), assetfield_core::TensorData::F32(q)) => {
                        let diff = p.iter().zip(q).map(|(u, v)| (u - v).abs()).fold(0f32, f32::max);
                        if p.iter().zip(q).any(|(u, v)| u.to_bits() != v.to_bits()) {
                            return Some((
                                n.into(),
                                format!("values differ (max |a - b| = {diff:.3e})"),
                            ));
                        }
                    }
                    (p, q) if p != q => return Some((n.into(), "values differ".into())),
                    _ => {}
                }
            }
            (None, None) => {}
        }
    }
    for key in ["config", "model"] {
        if a.meta(key) != b.meta(key) {
            return Some((format!("metadata \"{key}\""), "the field configurations differ".into()));
        }
    }
    None
}

/// What [`merge_libraries`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct MergeReport {
    pub out: PathBuf,
    pub entries: usize,
    pub categories: usize,
    pub containers: usize,
}

/// Merge libraries that share their vertical axes, basis and decoders into one: entry,
/// category and container names get the source folder's name as a prefix (`STEM/NAME`).
/// Refuses libraries whose shared tensors differ, naming the tensor.
pub fn merge_libraries(inputs: &[PathBuf], out: &Path, force: bool) -> Result<MergeReport> {
    if inputs.len() < 2 {
        return Err(MiningError::InvalidParameter {
            name: "libraries",
            reason: format!("merging needs at least two libraries, got {}", inputs.len()),
        });
    }
    if out.exists() && !force {
        return Err(MiningError::OutputExists(out.display().to_string()));
    }
    let libs: Vec<Library> = inputs.iter().map(|p| open_library(p)).collect::<Result<_>>()?;
    for (i, l) in libs.iter().enumerate().skip(1) {
        if let Some((tensor, detail)) = shared_difference(&libs[0].shared, &l.shared) {
            return Err(MiningError::SharedTensorDiffers {
                a: inputs[0].display().to_string(),
                b: inputs[i].display().to_string(),
                tensor,
                detail,
            });
        }
        if l.index.channels != libs[0].index.channels || l.index.model != libs[0].index.model {
            return Err(MiningError::SharedTensorDiffers {
                a: inputs[0].display().to_string(),
                b: inputs[i].display().to_string(),
                tensor: "plane channels / model".into(),
                detail: format!(
                    "{} {:?} vs {} {:?}",
                    libs[0].index.model, libs[0].index.channels, l.index.model, l.index.channels
                ),
            });
        }
    }
    // unique prefixes from the folder names
    let mut prefixes: Vec<String> = Vec::new();
    for p in inputs {
        let stem = p
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.is_empty() && s != "." && s != "..")
            .unwrap_or_else(|| "lib".into());
        let mut name = stem.clone();
        let mut k = 2;
        while prefixes.contains(&name) {
            name = format!("{stem}{k}");
            k += 1;
        }
        prefixes.push(name);
    }
    let mut index = LibraryIndex {
        format: FORMAT.into(),
        sources: Vec::new(),
        model: libs[0].index.model.clone(),
        texel_size: libs[0].index.texel_size,
        channels: libs[0].index.channels,
        patches: PATCHES_FILE.into(),
        shared: libs[0].index.shared.clone(),
        categories: Vec::new(),
        entries: Vec::new(),
        containers: Vec::new(),
    };
    index.shared.file = SHARED_FILE.into();
    let mut patches = TensorFile::new();
    patches.set_meta("format", FORMAT);
    for (lib, prefix) in libs.iter().zip(&prefixes) {
        check_interrupt()?;
        let base = index.sources.len();
        index.sources.extend(lib.index.sources.iter().cloned());
        let rename = |n: &str| format!("{prefix}/{n}");
        let mut copy = |from: &str, to: String| -> Result<String> {
            let t = lib.patches.get(from)?.clone();
            patches.insert(to.clone(), t);
            Ok(to)
        };
        for e in &lib.index.entries {
            let name = rename(&e.name);
            index.entries.push(Entry {
                density: copy(&e.density, format!("{name}.density"))?,
                color: copy(&e.color, format!("{name}.color"))?,
                mask: copy(&e.mask, format!("{name}.mask"))?,
                name,
                category: rename(&e.category),
                supported_by: e.supported_by.as_deref().map(rename),
                source: base + e.source,
                ..e.clone()
            });
        }
        for c in &lib.index.categories {
            index.categories.push(Category {
                name: rename(&c.name),
                template: rename(&c.template),
                members: c.members.iter().map(|m| rename(m)).collect(),
            });
        }
        for c in &lib.index.containers {
            let name = rename(&c.name);
            index.containers.push(Container {
                density: copy(&c.density, format!("{name}.density"))?,
                color: copy(&c.color, format!("{name}.color"))?,
                mask: copy(&c.mask, format!("{name}.mask"))?,
                name,
                source: base + c.source,
                ..c.clone()
            });
        }
    }
    let staging = StagingDir::new(out, force)?;
    write_library_files(staging.path(), &index, &patches, &libs[0].shared)?;
    check_interrupt()?;
    let out = staging.commit()?;
    Ok(MergeReport {
        out,
        entries: index.entries.len(),
        categories: index.categories.len(),
        containers: index.containers.len(),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A small but complete library in `dir` (one category of two entries, one container),
    /// with shared tensor `decoder.0.bias = [bias]`.
    pub(crate) fn write_tiny(dir: &Path, bias: f32) {
        std::fs::create_dir_all(dir).unwrap();
        let mut shared = TensorFile::new();
        shared.insert_f32("decoder.0.bias", &[2], vec![bias, 0.5]);
        shared.insert_f32("density.axis", &[3, 2], vec![1.0; 6]);
        shared.set_meta("format", SHARED_FORMAT);
        shared.set_meta("config", "{}");
        let mut patches = TensorFile::new();
        let mut entries = Vec::new();
        for (k, name) in ["obj000", "obj001"].iter().enumerate() {
            patches.insert_f32(format!("{name}.density"), &[2, 3, 2], vec![0.1; 12]);
            patches.insert_f32(format!("{name}.color"), &[2, 3, 4], vec![0.2; 24]);
            patches.insert_u8(format!("{name}.mask"), &[2, 3], vec![1; 6]);
            entries.push(Entry {
                name: name.to_string(),
                category: "cat0".into(),
                kind: if k == 0 { EntryKind::Template } else { EntryKind::Instance },
                density: format!("{name}.density"),
                color: format!("{name}.color"),
                mask: format!("{name}.mask"),
                patch_size: (2, 3),
                extent: (0.3, 0.2, 0.5),
                base: 0.0,
                source_box: [0.0, 0.0, 0.3, 0.2],
                position: (0.15, 0.1),
                pivot: None,
                matched_on: None,
                yaw_deg: 90.0 * k as f32,
                residual: 0.0,
                supported_by: None,
                source: 0,
            });
        }
        patches.insert_f32("container.density", &[4, 5, 2], vec![0.0; 40]);
        patches.insert_f32("container.color", &[4, 5, 4], vec![0.0; 80]);
        patches.insert_u8("container.mask", &[4, 5], vec![0; 20]);
        let index = LibraryIndex {
            format: FORMAT.into(),
            sources: vec!["f.safetensors".into()],
            model: "s".into(),
            texel_size: (0.1, 0.1),
            channels: (2, 4),
            patches: PATCHES_FILE.into(),
            shared: SharedRef {
                file: SHARED_FILE.into(),
                hash: content_hash(&shared),
                tensors: shared.names().map(str::to_string).collect(),
            },
            categories: vec![Category {
                name: "cat0".into(),
                template: "obj000".into(),
                members: vec!["obj000".into(), "obj001".into()],
            }],
            entries,
            containers: vec![Container::named("container", (4, 5), [0.0, 0.0, 0.5, 0.4], 0)],
        };
        write_library_files(dir, &index, &patches, &shared).unwrap();
    }

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("assetfield-mining-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn index_round_trips_and_validates() {
        let root = scratch("lib-rt");
        let a = root.join("a");
        write_tiny(&a, 0.25);
        let lib = open_library(&a).unwrap();
        assert_eq!(lib.index.entries.len(), 2);
        let text = std::fs::read_to_string(a.join(INDEX_FILE)).unwrap();
        assert!(text.contains("assetfield-library/1") && text.contains("Template"), "{text}");
        let again =
            index_from_ron(&a.join(INDEX_FILE), &index_to_ron(&lib.index).unwrap()).unwrap();
        assert_eq!(again, lib.index);
        // an index written before entries had pivots reads as pivots at the box centres, and
        // a pivot round-trips
        assert!(!text.contains("pivot"), "{text}");
        let e = &lib.index.entries[0];
        assert_eq!((e.pivot, e.pivot_offset()), (None, Vec2::ZERO));
        let mut index = lib.index.clone();
        index.entries[0].pivot = Some((0.05, 0.1));
        let text = index_to_ron(&index).unwrap();
        let again = index_from_ron(&a.join(INDEX_FILE), &text).unwrap();
        assert_eq!(again.entries[0].pivot, Some((0.05, 0.1)));
        let offset = again.entries[0].pivot_offset() - Vec2::new(0.05 - 0.15, 0.1 - 0.1);
        assert!(offset.length() < 1e-6, "{offset}");
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn index_tensor_mismatch_names_expected_and_actual() {
        let root = scratch("lib-mismatch");
        let a = root.join("a");
        write_tiny(&a, 0.25);
        let mut index = open_library(&a).unwrap().index;
        index.entries[1].patch_size = (3, 3);
        write_atomic(&a.join(INDEX_FILE), index_to_ron(&index).unwrap().as_bytes()).unwrap();
        let e = open_library(&a).unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(&e, MiningError::LibraryMismatch { tensor, expected, actual, .. }
                if tensor == "obj001.density" && expected == &vec![3, 3, 2] && actual == &vec![2, 3, 2]),
            "{msg}"
        );
        assert!(
            msg.contains("obj001.density")
                && msg.contains("[3, 3, 2]")
                && msg.contains("[2, 3, 2]"),
            "{msg}"
        );
        // a missing tensor, an unknown member and a changed shared file are reported too
        index.entries[1].patch_size = (2, 3);
        index.entries[1].mask = "nope.mask".into();
        write_atomic(&a.join(INDEX_FILE), index_to_ron(&index).unwrap().as_bytes()).unwrap();
        assert!(open_library(&a).unwrap_err().to_string().contains("nope.mask"));
        index.entries[1].mask = "obj001.mask".into();
        index.shared.hash = "fnv1a64:0000000000000000".into();
        write_atomic(&a.join(INDEX_FILE), index_to_ron(&index).unwrap().as_bytes()).unwrap();
        assert!(open_library(&a).unwrap_err().to_string().contains("content hash"));
        std::fs::write(a.join(INDEX_FILE), "Library(format: \"x\")").unwrap();
        assert!(open_library(&a).is_err());
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn merge_accepts_equal_shared_tensors_and_refuses_others() {
        let root = scratch("lib-merge");
        let (a, b, c) = (root.join("a"), root.join("b"), root.join("c"));
        write_tiny(&a, 0.25);
        write_tiny(&b, 0.25);
        write_tiny(&c, 0.75);
        let out = root.join("ab");
        let r = merge_libraries(&[a.clone(), b.clone()], &out, false).unwrap();
        assert_eq!((r.entries, r.categories, r.containers), (4, 2, 2));
        let m = open_library(&out).unwrap();
        assert!(m.index.entry("a/obj000").is_some() && m.index.entry("b/obj001").is_some());
        assert_eq!(m.index.categories[1].template, "b/obj000");
        assert_eq!(m.index.sources.len(), 2);
        // the output exists: refused without force
        assert!(matches!(
            merge_libraries(&[a.clone(), b.clone()], &out, false),
            Err(MiningError::OutputExists(_))
        ));
        let e = merge_libraries(&[a.clone(), c.clone()], &root.join("ac"), false).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("decoder.0.bias") && msg.contains("differs"), "{msg}");
        assert!(!root.join("ac").exists(), "nothing may be written on refusal");
        std::fs::remove_dir_all(&root).unwrap();
    }
}
