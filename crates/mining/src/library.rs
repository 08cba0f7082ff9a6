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

use assetfield_core::fsx::{StagingDir, write_atomic};
use assetfield_core::{TensorData, TensorFile};
use assetfield_field::config::{MAX_BOX_COORD, MAX_FEATURE_CHANNELS, max_plane_res};
use assetfield_field::eval::FieldInfo;
use assetfield_field::{FieldConfig, FieldError, ModelKind};
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
    /// The configuration of the field the shared tensors belong to (metadata `config` of
    /// the shared file), checked against its bounds and against the shared tensors.
    pub config: FieldConfig,
    /// What the source field's training recorded (background, ground alignment, dataset),
    /// from the shared file's metadata.
    pub info: FieldInfo,
}

/// A field of configuration `config` with zero ground planes and every other tensor from
/// `shared` (a library's shared file): the one way a library's shared tensors become a
/// field (`train --share`, regrouping, the composer's canvases).
pub fn field_with_shared(
    config: FieldConfig,
    shared: &TensorFile,
) -> std::result::Result<assetfield_field::Field, assetfield_core::CoreError> {
    let mut field = assetfield_field::Field::new(config, 0);
    for spec in field.params.specs.clone() {
        let data = &mut field.params.data[spec.offset..spec.offset + spec.len];
        if FieldConfig::is_plane_tensor(&spec.name) {
            data.fill(0.0);
        } else {
            data.copy_from_slice(shared.get_f32(&spec.name, &spec.shape)?);
        }
    }
    Ok(field)
}

impl Library {
    /// A field of the library's shared configuration holding its shared tensors (vertical
    /// axes, basis, guidance MLPs, decoders) and zero ground planes: what a new scene is
    /// fitted against (`train --share LIB`).
    pub fn shared_field(&self) -> Result<assetfield_field::Field> {
        field_with_shared(self.config.clone(), &self.shared).map_err(|e| MiningError::Format {
            path: self.dir.join(&self.index.shared.file).display().to_string(),
            message: e.to_string(),
        })
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
            TensorData::F32(v) => v.iter().for_each(|x| eat(&x.to_le_bytes())),
            TensorData::U8(v) => eat(v),
            TensorData::I64(v) => v.iter().for_each(|x| eat(&x.to_le_bytes())),
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

/// The ground-plane tensors of a field, which a library keeps per entry and container
/// rather than in its shared file.
use assetfield_field::config::PLANE_TENSORS;

/// Builds the errors of one file of a library.
struct Checker {
    path: String,
}

impl Checker {
    fn value(
        &self,
        place: &str,
        key: &str,
        actual: impl std::fmt::Debug,
        expected: impl Into<String>,
    ) -> MiningError {
        MiningError::LibraryValue {
            path: self.path.clone(),
            place: place.to_string(),
            key: key.to_string(),
            expected: expected.into(),
            actual: format!("{actual:?}"),
        }
    }

    /// World coordinates or sizes: finite and within [`MAX_BOX_COORD`].
    fn finite(&self, place: &str, key: &str, values: &[f32]) -> Result<()> {
        if values.iter().all(|v| v.is_finite() && v.abs() <= MAX_BOX_COORD) {
            return Ok(());
        }
        let shown =
            if values.len() == 1 { format!("{:?}", values[0]) } else { format!("{values:?}") };
        Err(MiningError::LibraryValue {
            path: self.path.clone(),
            place: place.to_string(),
            key: key.to_string(),
            expected: format!("finite numbers within {MAX_BOX_COORD:e} scene units"),
            actual: shown,
        })
    }

    /// An angle in degrees: finite.
    fn angle(&self, place: &str, key: &str, v: f32) -> Result<()> {
        if v.is_finite() {
            return Ok(());
        }
        Err(self.value(place, key, v, "a finite angle in degrees"))
    }

    /// Tensor `name` of `file`: present, `expected` shape, element type `dtype`, and (for
    /// `f32`) finite values. `purpose` says what needs it; `by_index`: whether the index
    /// (rather than the shared configuration) implies the shape.
    fn tensor(
        &self,
        file: &TensorFile,
        name: &str,
        expected: &[usize],
        dtype: &str,
        purpose: &str,
        by_index: bool,
    ) -> Result<()> {
        let Some(t) = file.tensors.get(name) else {
            return Err(MiningError::MissingTensor {
                source_name: self.path.clone(),
                name: name.to_string(),
                purpose: purpose.to_string(),
            });
        };
        if t.shape != expected && !by_index {
            return Err(MiningError::Format {
                path: self.path.clone(),
                message: format!(
                    "tensor \"{name}\" has shape {:?}, expected {expected:?} (the shape {purpose} implies)",
                    t.shape
                ),
            });
        }
        if t.shape != expected {
            return Err(MiningError::LibraryMismatch {
                path: self.path.clone(),
                tensor: name.to_string(),
                expected: expected.to_vec(),
                actual: t.shape.clone(),
            });
        }
        if t.data.dtype_name() != dtype {
            return Err(MiningError::Format {
                path: self.path.clone(),
                message: format!(
                    "tensor \"{name}\" has dtype {}, expected {dtype} ({purpose})",
                    t.data.dtype_name()
                ),
            });
        }
        if let TensorData::F32(v) = &t.data
            && let Some((index, value)) = assetfield_core::first_non_finite(v)
        {
            return Err(MiningError::NonFinite {
                path: self.path.clone(),
                tensor: name.to_string(),
                index,
                value,
            });
        }
        // patches and shared tensors are field parameters: the field's bound holds for them
        let limit = assetfield_field::io::MAX_PARAMETER_MAGNITUDE;
        if let TensorData::F32(v) = &t.data
            && let Some(index) = v.iter().position(|x| x.abs() > limit)
        {
            return Err(MiningError::LibraryValue {
                path: self.path.clone(),
                place: format!("tensor \"{name}\""),
                key: format!("value {index}"),
                expected: format!("within {limit:e} (a field's parameters stay within it)"),
                actual: v[index].to_string(),
            });
        }
        Ok(())
    }
}

/// `FieldError`s of the shared configuration as the library errors that name the file.
fn config_error(path: &str, e: FieldError) -> MiningError {
    match e {
        FieldError::Config { key, expected, actual, .. } => MiningError::LibraryValue {
            path: path.to_string(),
            place: "metadata \"config\"".into(),
            key,
            expected,
            actual,
        },
        other => MiningError::Format { path: path.to_string(), message: other.to_string() },
    }
}

/// Check a library: everything that composing it ([`open_library`], the composer's loader)
/// and `assetfield library check` rely on, so that a library that passes composes. Returns
/// the shared field's configuration and training metadata.
///
/// - `index.ron`: model `s` or `i`; texel size positive and finite; channel counts 1 to
///   [`MAX_FEATURE_CHANNELS`]; unique entry, category and container names; per entry a
///   patch size of 1 to [`max_plane_res`] texels per side, finite non-negative extents,
///   finite base, box, position and yaw, a pivot within the box, a known source, support and
///   category; per container 2 to [`max_plane_res`] texels per side (a field needs two
///   nodes) and a finite, non-empty world box; categories whose template and members exist.
/// - the patches file: every entry's and container's tensors present, with the shapes the
///   index implies, `f32` (masks `u8`), finite.
/// - the shared file: its format tag; a field configuration (metadata `config`) within the
///   field bounds ([`FieldConfig::validate`]) of the index's model and channels; every
///   tensor the index lists and every non-plane tensor the configuration implies present,
///   with the implied shapes, finite; the content hash of the index; readable training
///   metadata.
///
/// Every error names the file, and the entry, container, category or tensor.
pub fn validate(
    index: &LibraryIndex,
    patches: &TensorFile,
    shared: &TensorFile,
    dir: &Path,
) -> Result<(FieldConfig, FieldInfo)> {
    let ix = Checker { path: dir.join(INDEX_FILE).display().to_string() };
    if !matches!(index.model.as_str(), "s" | "i") {
        return Err(ix.value(
            "",
            "model",
            &index.model,
            "\"s\" or \"i\" (the fields with ground planes)",
        ));
    }
    let (tx, ty) = index.texel_size;
    if !(tx.is_finite() && ty.is_finite() && tx > 0.0 && ty > 0.0) {
        return Err(ix.value(
            "",
            "texel_size",
            index.texel_size,
            "the world size of a texel (x, y), positive and finite",
        ));
    }
    let (nd, nc) = index.channels;
    for (what, n) in [("density", nd), ("colour", nc)] {
        if !(1..=MAX_FEATURE_CHANNELS).contains(&n) {
            return Err(ix.value(
                "",
                "channels",
                index.channels,
                format!("(density, colour) channel counts of 1 to {MAX_FEATURE_CHANNELS} ({what})"),
            ));
        }
    }
    let mut names = BTreeSet::new();
    for e in &index.entries {
        if !names.insert(e.name.as_str()) {
            return Err(ix.value("", "entries", &e.name, "unique entry names"));
        }
    }
    let categories: BTreeSet<&str> = index.categories.iter().map(|c| c.name.as_str()).collect();
    if categories.len() != index.categories.len() {
        return Err(ix.value("", "categories", index.categories.len(), "unique category names"));
    }
    let containers: BTreeSet<&str> = index.containers.iter().map(|c| c.name.as_str()).collect();
    if containers.len() != index.containers.len() {
        return Err(ix.value("", "containers", index.containers.len(), "unique container names"));
    }
    let side = |place: &str, key: &str, (h, w): (usize, usize), min: usize| -> Result<()> {
        if [h, w].iter().all(|n| (min..=max_plane_res()).contains(n)) {
            return Ok(());
        }
        Err(ix.value(
            place,
            key,
            (h, w),
            format!("(rows, cols) of {min} to {} texels", max_plane_res()),
        ))
    };
    let source = |place: &str, s: usize| -> Result<()> {
        if s < index.sources.len() {
            return Ok(());
        }
        Err(ix.value(
            place,
            "source",
            s,
            format!("an index into the {} source(s)", index.sources.len()),
        ))
    };
    for e in &index.entries {
        let place = format!("entry {:?}", e.name);
        side(&place, "patch_size", e.patch_size, 1)?;
        let (ex, ey, ez) = e.extent;
        ix.finite(&place, "extent", &[ex, ey, ez])?;
        if [ex, ey, ez].iter().any(|v| *v < 0.0) {
            return Err(ix.value(&place, "extent", e.extent, "non-negative sizes (x, y, height)"));
        }
        ix.finite(&place, "base", &[e.base])?;
        ix.finite(&place, "source_box", &e.source_box)?;
        let b = e.source_box;
        if b[0] > b[2] || b[1] > b[3] {
            return Err(ix.value(&place, "source_box", b, "[xmin, ymin, xmax, ymax], min <= max"));
        }
        ix.finite(&place, "position", &[e.position.0, e.position.1])?;
        if let Some((x, y)) = e.pivot {
            ix.finite(&place, "pivot", &[x, y])?;
            // the centre of the object's ground contact, so within its box (a texel of slack)
            if x < b[0] - tx || x > b[2] + tx || y < b[1] - ty || y > b[3] + ty {
                return Err(ix.value(
                    &place,
                    "pivot",
                    (x, y),
                    format!("a point of the entry's source_box {b:?}"),
                ));
            }
        }
        ix.angle(&place, "yaw_deg", e.yaw_deg)?;
        source(&place, e.source)?;
        if !categories.contains(e.category.as_str()) {
            return Err(ix.value(&place, "category", &e.category, "the name of a category"));
        }
        if let Some(s) = &e.supported_by
            && !names.contains(s.as_str())
        {
            return Err(ix.value(&place, "supported_by", s, "the name of an entry"));
        }
    }
    for c in &index.containers {
        let place = format!("container {:?}", c.name);
        side(&place, "size", c.size, 2)?;
        ix.finite(&place, "world", &c.world)?;
        let w = c.world;
        let (rows, cols) = c.size;
        // the box covers whole texel cells: cols x rows texels
        let fits = |len: f32, n: usize, texel: f32| {
            let want = n as f32 * texel;
            (len - want).abs() <= 1e-3 * want
        };
        if !(fits(w[2] - w[0], cols, tx) && fits(w[3] - w[1], rows, ty)) {
            return Err(ix.value(
                &place,
                "world",
                w,
                format!(
                    "[xmin, ymin, xmax, ymax] of {cols} x {rows} texel cells of {tx} x {ty} ({} x {} in all)",
                    cols as f32 * tx,
                    rows as f32 * ty
                ),
            ));
        }
        source(&place, c.source)?;
    }
    for c in &index.categories {
        for m in std::iter::once(&c.template).chain(&c.members) {
            if !names.contains(m.as_str()) {
                return Err(MiningError::Format {
                    path: ix.path.clone(),
                    message: format!(
                        "category {:?} names entry {m:?}, which does not exist",
                        c.name
                    ),
                });
            }
        }
    }

    // the patches file
    let pf = Checker { path: dir.join(&index.patches).display().to_string() };
    for (what, name, density, color, mask, (h, w)) in index
        .entries
        .iter()
        .map(|e| ("entry", &e.name, &e.density, &e.color, &e.mask, e.patch_size))
        .chain(
            index
                .containers
                .iter()
                .map(|c| ("container", &c.name, &c.density, &c.color, &c.mask, c.size)),
        )
    {
        let purpose = format!("{what} {name:?} of the library index");
        pf.tensor(patches, density, &[h, w, nd], "F32", &purpose, true)?;
        pf.tensor(patches, color, &[h, w, nc], "F32", &purpose, true)?;
        pf.tensor(patches, mask, &[h, w], "U8", &purpose, true)?;
    }

    // the shared file
    let sf = Checker { path: dir.join(&index.shared.file).display().to_string() };
    if shared.meta("format") != Some(SHARED_FORMAT) {
        return Err(sf.value(
            "",
            "metadata \"format\"",
            shared.meta("format"),
            format!("{SHARED_FORMAT:?} (the shared tensors of an asset library)"),
        ));
    }
    let config: FieldConfig = shared.meta_json("config").map_err(|e| MiningError::Format {
        path: sf.path.clone(),
        message: format!("no usable field configuration in the metadata: {e}"),
    })?;
    config.validate(&dir.join(&index.shared.file)).map_err(|e| config_error(&sf.path, e))?;
    if config.kind == ModelKind::Vm {
        return Err(sf.value(
            "metadata \"config\"",
            "kind",
            config.kind,
            "Standard or Integrated (a TensoRF-VM field has no ground planes to compose)",
        ));
    }
    if config.kind.name() != index.model {
        return Err(ix.value(
            "",
            "model",
            &index.model,
            format!("{:?}, the model of the shared configuration", config.kind.name()),
        ));
    }
    if (config.density_channels, config.color_channels) != index.channels {
        return Err(ix.value(
            "",
            "channels",
            index.channels,
            format!(
                "{:?}, the channels of the shared configuration",
                (config.density_channels, config.color_channels)
            ),
        ));
    }
    // the texels are the source field's plane texels
    let voxel = config.voxel_size();
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-4 * b;
    if !(close(tx, voxel.x) && close(ty, voxel.y)) {
        return Err(ix.value(
            "",
            "texel_size",
            index.texel_size,
            format!(
                "({}, {}), the plane texel of the shared configuration (its box over its resolution)",
                voxel.x, voxel.y
            ),
        ));
    }
    for name in &index.shared.tensors {
        if !shared.tensors.contains_key(name) {
            return Err(MiningError::MissingTensor {
                source_name: sf.path.clone(),
                name: name.clone(),
                purpose: "the shared tensors the library index lists".into(),
            });
        }
    }
    for (name, shape) in config.tensor_shapes() {
        if PLANE_TENSORS.contains(&name.as_str()) {
            continue;
        }
        sf.tensor(shared, &name, &shape, "F32", "the shared configuration", false)?;
    }
    let hash = content_hash(shared);
    if hash != index.shared.hash {
        return Err(MiningError::Format {
            path: sf.path.clone(),
            message: format!(
                "content hash {hash} does not match the index ({}): the shared tensors were changed",
                index.shared.hash
            ),
        });
    }
    let info = FieldInfo::read(shared)
        .map_err(|e| MiningError::Format { path: sf.path.clone(), message: e.to_string() })?;
    Ok((config, info))
}

/// Read and check a library folder: the one loader of libraries, used by
/// `assetfield library check`, by merging and by the composer (see [`validate`]).
pub fn open_library(dir: &Path) -> Result<Library> {
    let ipath = dir.join(INDEX_FILE);
    let text = std::fs::read_to_string(&ipath).map_err(|e| {
        MiningError::io(format!("{} (is this an asset library folder?)", ipath.display()), e)
    })?;
    let index = index_from_ron(&ipath, &text)?;
    let patches = TensorFile::load(&dir.join(&index.patches))?;
    let shared = TensorFile::load(&dir.join(&index.shared.file))?;
    let (config, info) = validate(&index, &patches, &shared, dir)?;
    Ok(Library { dir: dir.to_path_buf(), index, patches, shared, config, info })
}

/// Write a small but complete library into `dir` (created if needed), for tests and
/// examples of the crates that read libraries: an S-AssetField configuration with 2 density
/// and 4 colour channels on 0.1 texels, one category of two 2 x 3 entries (`obj000`, the
/// template, and `obj001`), one 4 x 5 container (the whole plane), and shared tensors from
/// a fresh field of that configuration, with `decoder.0.bias[0] = bias` (libraries with different `bias`
/// cannot be merged).
pub fn write_sample_library(dir: &Path, bias: f32) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| MiningError::io(dir.display(), e))?;
    // a plane of 5 x 4 nodes 0.1 apart
    let world = assetfield_core::Aabb3::new(glam::Vec3::ZERO, glam::Vec3::new(0.4, 0.3, 0.3));
    let mut config = FieldConfig::new(ModelKind::Standard, world, 5);
    (config.density_channels, config.color_channels, config.basis_dim) = (2, 4, 3);
    config.decoder = assetfield_field::DecoderKind::Mlp { hidden: vec![4], view_freqs: 1 };
    let mut field = assetfield_field::Field::new(config, 7);
    if let Some(s) = field.params.spec("decoder.0.bias").cloned() {
        field.params.data[s.offset] = bias;
    }
    let shared = crate::pipeline::shared_tensors(&field, "sample.safetensors")?;
    let (nd, nc) = (2, 4);
    let mut patches = TensorFile::new();
    patches.set_meta("format", FORMAT);
    let mut entries = Vec::new();
    for (k, name) in ["obj000", "obj001"].iter().enumerate() {
        patches.insert_f32(format!("{name}.density"), &[2, 3, nd], vec![0.1; 6 * nd]);
        patches.insert_f32(format!("{name}.color"), &[2, 3, nc], vec![0.2; 6 * nc]);
        patches.insert_u8(format!("{name}.mask"), &[2, 3], vec![1; 6]);
        entries.push(Entry {
            kind: if k == 0 { EntryKind::Template } else { EntryKind::Instance },
            patch_size: (2, 3),
            extent: (0.3, 0.2, 0.5),
            source_box: [0.0, 0.0, 0.3, 0.2],
            position: (0.15, 0.1),
            yaw_deg: 90.0 * k as f32,
            ..Entry::named(name, "cat0")
        });
    }
    patches.insert_f32("container.density", &[4, 5, nd], vec![0.0; 20 * nd]);
    patches.insert_f32("container.color", &[4, 5, nc], vec![0.0; 20 * nc]);
    patches.insert_u8("container.mask", &[4, 5], vec![0; 20]);
    let index = LibraryIndex {
        format: FORMAT.into(),
        sources: vec!["sample.safetensors".into()],
        model: "s".into(),
        texel_size: (0.1, 0.1),
        channels: (nd, nc),
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
        containers: vec![Container::named("container", (4, 5), [-0.05, -0.05, 0.45, 0.35], 0)],
    };
    write_library_files(dir, &index, &patches, &shared)
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
                    (TensorData::F32(p), TensorData::F32(q)) => {
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
    if a.meta("model") != b.meta("model") {
        return Some(("metadata \"model\"".into(), "the models differ".into()));
    }
    // the configurations may differ in their ground boxes (scenes trained together), not in
    // what the shared tensors mean
    match (a.meta_json::<FieldConfig>("config"), b.meta_json::<FieldConfig>("config")) {
        (Ok(x), Ok(y)) => {
            x.sharing_mismatch(&y).map(|m| ("metadata \"config\"".to_string(), m.to_string()))
        }
        _ => Some(("metadata \"config\"".into(), "a field configuration is unreadable".into())),
    }
}

/// What [`merge_libraries`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct MergeReport {
    pub out: PathBuf,
    pub entries: usize,
    pub categories: usize,
    pub containers: usize,
    /// With ground truth: what `metrics.json` holds.
    pub metrics: Option<crate::metrics::CrossSceneMetrics>,
}

/// How [`merge_libraries_with`] merges.
#[derive(Debug, Clone, Default)]
pub struct MergeOptions {
    /// Group all entries again, together ([`crate::regroup`]), so that one category spans
    /// scenes; `None` keeps every scene's own categories (prefixed).
    pub regroup: Option<crate::regroup::RegroupOptions>,
    /// One ground truth per input library, in the same order (empty: none): the merged
    /// library's `metrics.json` gets the cross-scene ARI and every scene's scores.
    pub gt: Vec<assetfield_layout::GtLayout>,
    /// BEV IoU an entry needs to match a ground-truth box.
    pub iou_threshold: f32,
}

/// Merge libraries that share their vertical axes, basis and decoders into one: entry,
/// category and container names get the source folder's name as a prefix (`STEM/NAME`).
/// Refuses libraries whose shared tensors differ, naming the tensor.
pub fn merge_libraries(inputs: &[PathBuf], out: &Path, force: bool) -> Result<MergeReport> {
    merge_libraries_with(
        inputs,
        out,
        force,
        &MergeOptions { iou_threshold: 0.5, ..Default::default() },
    )
}

/// [`merge_libraries`] with options: regrouping across scenes and ground truth.
pub fn merge_libraries_with(
    inputs: &[PathBuf],
    out: &Path,
    force: bool,
    opts: &MergeOptions,
) -> Result<MergeReport> {
    if !opts.gt.is_empty() && opts.gt.len() != inputs.len() {
        return Err(MiningError::InvalidParameter {
            name: "gt",
            reason: format!(
                "one ground truth per library, in the same order: {} libraries, {} ground truths",
                inputs.len(),
                opts.gt.len()
            ),
        });
    }
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
    // which input every entry came from
    let mut scene_of = Vec::with_capacity(index.entries.len());
    for (k, lib) in libs.iter().enumerate() {
        scene_of.extend(std::iter::repeat_n(k, lib.index.entries.len()));
    }
    if let Some(r) = &opts.regroup {
        // the merged library as it will be written (moved in and out, not copied)
        let mut merged = Library {
            dir: out.to_path_buf(),
            index,
            patches,
            shared: libs[0].shared.clone(),
            config: libs[0].config.clone(),
            info: libs[0].info.clone(),
        };
        let g = crate::regroup::regroup(&merged, r)?;
        merged.index.entries = g.entries;
        merged.index.categories = g.categories;
        (index, patches) = (merged.index, merged.patches);
    }
    let metrics = (!opts.gt.is_empty()).then(|| {
        let names: Vec<String> = inputs.iter().map(|p| p.display().to_string()).collect();
        crate::metrics::cross_scene_metrics(&index, &scene_of, &names, &opts.gt, opts.iou_threshold)
    });
    let staging = StagingDir::new(out, force)?;
    write_library_files(staging.path(), &index, &patches, &libs[0].shared)?;
    if let Some(m) = &metrics {
        let text = serde_json::to_string_pretty(m)
            .map_err(|e| MiningError::io("cannot serialise the merge metrics", e))?;
        write_atomic(&staging.path().join("metrics.json"), text.as_bytes())?;
    }
    check_interrupt()?;
    let out = staging.commit()?;
    Ok(MergeReport {
        out,
        entries: index.entries.len(),
        categories: index.categories.len(),
        containers: index.containers.len(),
        metrics,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn write_tiny(dir: &Path, bias: f32) {
        write_sample_library(dir, bias).unwrap();
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
