//! The library check: everything composing a library relies on, so that a library that
//! passes composes. [`validate`] runs the three files' checks in turn.

use assetfield_core::{TensorData, TensorFile};
use assetfield_field::config::{MAX_BOX_COORD, MAX_FEATURE_CHANNELS, PLANE_TENSORS, max_plane_res};
use assetfield_field::eval::FieldInfo;
use assetfield_field::{FieldConfig, FieldError, ModelKind};
use std::collections::BTreeSet;
use std::path::Path;

use crate::error::{LibraryError, Result};
use crate::index::{Container, Entry, INDEX_FILE, LibraryIndex, SHARED_FORMAT, content_hash};

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
    ) -> LibraryError {
        LibraryError::Value {
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
        Err(LibraryError::Value {
            path: self.path.clone(),
            place: place.to_string(),
            key: key.to_string(),
            expected: format!("finite numbers within {MAX_BOX_COORD:e} scene units"),
            actual: shown,
        })
    }

    /// A patch or container size `(rows, cols)`: `min` to [`max_plane_res`] texels per side.
    fn side(&self, place: &str, key: &str, (h, w): (usize, usize), min: usize) -> Result<()> {
        if [h, w].iter().all(|n| (min..=max_plane_res()).contains(n)) {
            return Ok(());
        }
        Err(self.value(
            place,
            key,
            (h, w),
            format!("(rows, cols) of {min} to {} texels", max_plane_res()),
        ))
    }

    /// An index into the index's sources.
    fn source(&self, index: &LibraryIndex, place: &str, s: usize) -> Result<()> {
        if s < index.sources.len() {
            return Ok(());
        }
        Err(self.value(
            place,
            "source",
            s,
            format!("an index into the {} source(s)", index.sources.len()),
        ))
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
            return Err(LibraryError::MissingTensor {
                source_name: self.path.clone(),
                name: name.to_string(),
                purpose: purpose.to_string(),
            });
        };
        if t.shape != expected && !by_index {
            return Err(LibraryError::Format {
                path: self.path.clone(),
                message: format!(
                    "tensor \"{name}\" has shape {:?}, expected {expected:?} (the shape {purpose} implies)",
                    t.shape
                ),
            });
        }
        if t.shape != expected {
            return Err(LibraryError::ShapeMismatch {
                path: self.path.clone(),
                tensor: name.to_string(),
                expected: expected.to_vec(),
                actual: t.shape.clone(),
            });
        }
        if t.data.dtype_name() != dtype {
            return Err(LibraryError::Format {
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
            return Err(LibraryError::NonFinite {
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
            return Err(LibraryError::Value {
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
fn config_error(path: &str, e: FieldError) -> LibraryError {
    match e {
        FieldError::Config { key, expected, actual, .. } => LibraryError::Value {
            path: path.to_string(),
            place: "metadata \"config\"".into(),
            key,
            expected,
            actual,
        },
        other => LibraryError::Format { path: path.to_string(), message: other.to_string() },
    }
}

/// Check a library: everything that composing it ([`crate::open_library`], the composer's loader)
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
    check_index(index, &ix)?;
    let pf = Checker { path: dir.join(&index.patches).display().to_string() };
    check_patches(index, patches, &pf)?;
    let sf = Checker { path: dir.join(&index.shared.file).display().to_string() };
    check_shared(index, shared, &dir.join(&index.shared.file), &ix, &sf)
}

/// `index.ron` alone: its top-level values, unique names, entries, containers, categories.
fn check_index(index: &LibraryIndex, ix: &Checker) -> Result<()> {
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
    for e in &index.entries {
        check_entry(index, e, &names, &categories, ix)?;
    }
    for c in &index.containers {
        check_container(index, c, ix)?;
    }
    for c in &index.categories {
        for m in std::iter::once(&c.template).chain(&c.members) {
            if !names.contains(m.as_str()) {
                return Err(LibraryError::Format {
                    path: ix.path.clone(),
                    message: format!(
                        "category {:?} names entry {m:?}, which does not exist",
                        c.name
                    ),
                });
            }
        }
    }

    Ok(())
}

/// One entry of the index, against the names of its entries and categories.
fn check_entry(
    index: &LibraryIndex,
    e: &Entry,
    names: &BTreeSet<&str>,
    categories: &BTreeSet<&str>,
    ix: &Checker,
) -> Result<()> {
    let (tx, ty) = index.texel_size;
    let place = format!("entry {:?}", e.name);
    ix.side(&place, "patch_size", e.patch_size, 1)?;
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
    ix.source(index, &place, e.source)?;
    if !categories.contains(e.category.as_str()) {
        return Err(ix.value(&place, "category", &e.category, "the name of a category"));
    }
    if let Some(s) = &e.supported_by
        && !names.contains(s.as_str())
    {
        return Err(ix.value(&place, "supported_by", s, "the name of an entry"));
    }
    Ok(())
}

/// One container of the index: its size, world box (whole texel cells) and source.
fn check_container(index: &LibraryIndex, c: &Container, ix: &Checker) -> Result<()> {
    let (tx, ty) = index.texel_size;
    let place = format!("container {:?}", c.name);
    ix.side(&place, "size", c.size, 2)?;
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
    ix.source(index, &place, c.source)?;
    Ok(())
}

/// The patches file: every entry's and container's tensors with the shapes the index implies.
fn check_patches(index: &LibraryIndex, patches: &TensorFile, pf: &Checker) -> Result<()> {
    let (nd, nc) = index.channels;
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

    Ok(())
}

/// The shared file: format, field configuration (against the index), tensors, content hash
/// and training metadata.
fn check_shared(
    index: &LibraryIndex,
    shared: &TensorFile,
    file: &Path,
    ix: &Checker,
    sf: &Checker,
) -> Result<(FieldConfig, FieldInfo)> {
    let (tx, ty) = index.texel_size;
    if shared.meta("format") != Some(SHARED_FORMAT) {
        return Err(sf.value(
            "",
            "metadata \"format\"",
            shared.meta("format"),
            format!("{SHARED_FORMAT:?} (the shared tensors of an asset library)"),
        ));
    }
    let config: FieldConfig = shared.meta_json("config").map_err(|e| LibraryError::Format {
        path: sf.path.clone(),
        message: format!("no usable field configuration in the metadata: {e}"),
    })?;
    config.validate(file).map_err(|e| config_error(&sf.path, e))?;
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
            return Err(LibraryError::MissingTensor {
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
        return Err(LibraryError::Format {
            path: sf.path.clone(),
            message: format!(
                "content hash {hash} does not match the index ({}): the shared tensors were changed",
                index.shared.hash
            ),
        });
    }
    let info = FieldInfo::read(shared)
        .map_err(|e| LibraryError::Format { path: sf.path.clone(), message: e.to_string() })?;
    Ok((config, info))
}
