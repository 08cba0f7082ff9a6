//! `index.ron`: what a library holds (sources, categories, entries, containers, the shared
//! file) and its RON form; the content hash that ties the index to its shared tensors.

use assetfield_core::TensorData;
use assetfield_core::TensorFile;
use glam::Vec2;
use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::error::{LibraryError, Result};

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
    /// (the centre of its ground contact, see mining's pivots); absent: its box centre.
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
    /// An instance of `category` whose tensors are `NAME.density`, `NAME.color` and
    /// `NAME.mask`: one texel at the origin, unposed, from the first source; set the rest
    /// with struct update syntax.
    pub fn named(name: &str, category: &str) -> Self {
        Entry {
            name: name.into(),
            category: category.into(),
            kind: EntryKind::Instance,
            density: format!("{name}.density"),
            color: format!("{name}.color"),
            mask: format!("{name}.mask"),
            patch_size: (1, 1),
            extent: (0.0, 0.0, 0.0),
            base: 0.0,
            source_box: [0.0; 4],
            position: (0.0, 0.0),
            pivot: None,
            yaw_deg: 0.0,
            residual: 0.0,
            matched_on: None,
            supported_by: None,
            source: 0,
        }
    }

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
    /// Texels around each entry's mask that mining filled in this container, and so the
    /// ring each entry's patch of this source covers when composed (an entry placed back
    /// where it was mined restores the trained planes). Libraries written before it was
    /// recorded filled [`crate::DEFAULT_HALO`].
    #[serde(default = "default_halo")]
    pub halo: usize,
}

fn default_halo() -> usize {
    crate::DEFAULT_HALO
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
            halo: crate::DEFAULT_HALO,
        }
    }

    /// The container with its patches' halo (texels).
    pub fn with_halo(self, halo: usize) -> Self {
        Container { halo, ..self }
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

fn ron_options() -> ron::Options {
    ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
}

/// Serialise an index as pretty RON.
pub fn index_to_ron(index: &LibraryIndex) -> Result<String> {
    let cfg = ron::ser::PrettyConfig::new().struct_names(true).depth_limit(4).indentor("    ");
    let body = ron_options()
        .to_string_pretty(index, cfg)
        .map_err(|e| LibraryError::io("cannot serialise the library index", e))?;
    Ok(format!("#![enable(implicit_some)]\n{body}\n"))
}

/// Parse an index.
pub fn index_from_ron(path: &Path, text: &str) -> Result<LibraryIndex> {
    let index: LibraryIndex = ron_options().from_str(text).map_err(|e| LibraryError::Format {
        path: path.display().to_string(),
        message: format!(
            "line {} column {}: {} (expected an asset library index written by `assetfield mine`)",
            e.span.start.line, e.span.start.col, e.code
        ),
    })?;
    if index.format != FORMAT {
        return Err(LibraryError::Format {
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
            TensorData::F32(v) => v.iter().for_each(|x| eat(&x.to_le_bytes())),
            TensorData::U8(v) => eat(v),
            TensorData::I64(v) => v.iter().for_each(|x| eat(&x.to_le_bytes())),
        }
    }
    format!("fnv1a64:{h:016x}")
}
