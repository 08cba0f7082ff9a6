//! A library folder on disk: reading it (checked), writing it, and the field its shared
//! tensors make.

use assetfield_core::TensorFile;
use assetfield_core::fsx::write_atomic;
use assetfield_field::eval::FieldInfo;
use assetfield_field::{Field, FieldConfig, ModelKind};
use std::path::{Path, PathBuf};

use crate::check::validate;
use crate::error::{LibraryError, Result, check_interrupt};
use crate::index::{
    Category, Container, Entry, EntryKind, FORMAT, INDEX_FILE, LibraryIndex, PATCHES_FILE,
    SHARED_FILE, SHARED_FORMAT, SharedRef, content_hash, index_from_ron, index_to_ron,
};

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
) -> std::result::Result<Field, assetfield_core::CoreError> {
    let mut field = Field::new(config, 0);
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
    pub fn shared_field(&self) -> Result<Field> {
        field_with_shared(self.config.clone(), &self.shared).map_err(|e| LibraryError::Format {
            path: self.dir.join(&self.index.shared.file).display().to_string(),
            message: e.to_string(),
        })
    }
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

/// Read and check a library folder: the one loader of libraries, used by
/// `assetfield library check`, by merging and by the composer (see [`validate`]).
pub fn open_library(dir: &Path) -> Result<Library> {
    let ipath = dir.join(INDEX_FILE);
    let text = std::fs::read_to_string(&ipath).map_err(|e| {
        LibraryError::io(format!("{} (is this an asset library folder?)", ipath.display()), e)
    })?;
    let index = index_from_ron(&ipath, &text)?;
    let patches = TensorFile::load(&dir.join(&index.patches))?;
    let shared = TensorFile::load(&dir.join(&index.shared.file))?;
    let (config, info) = validate(&index, &patches, &shared, dir)?;
    Ok(Library { dir: dir.to_path_buf(), index, patches, shared, config, info })
}

/// A library's shared file for `field`: every tensor that is not a ground plane, with the
/// field's configuration (metadata `config`), model and the name of its `source` file.
pub fn shared_tensors(field: &Field, source: &str) -> Result<TensorFile> {
    let mut f = TensorFile::new();
    for s in &field.params.specs {
        if FieldConfig::is_plane_tensor(&s.name) {
            continue;
        }
        f.insert_f32(&s.name, &s.shape, field.params.data[s.offset..s.offset + s.len].to_vec());
    }
    f.set_meta("format", SHARED_FORMAT);
    f.set_meta("model", field.config.kind.name());
    f.set_meta("source", source);
    f.set_meta_json("config", &field.config)?;
    Ok(f)
}

/// Write a small but complete library into `dir` (created if needed), for tests and
/// examples of the crates that read libraries: an S-AssetField configuration with 2 density
/// and 4 colour channels on 0.1 texels, one category of two 2 x 3 entries (`obj000`, the
/// template, and `obj001`), one 4 x 5 container (the whole plane), and shared tensors from
/// a fresh field of that configuration, with `decoder.0.bias[0] = bias` (libraries with different `bias`
/// cannot be merged).
pub fn write_sample_library(dir: &Path, bias: f32) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| LibraryError::io(dir.display(), e))?;
    // a plane of 5 x 4 nodes 0.1 apart
    let world = assetfield_core::Aabb3::new(glam::Vec3::ZERO, glam::Vec3::new(0.4, 0.3, 0.3));
    let mut config = FieldConfig::new(ModelKind::Standard, world, 5);
    (config.density_channels, config.color_channels, config.basis_dim) = (2, 4, 3);
    config.decoder = assetfield_field::DecoderKind::Mlp { hidden: vec![4], view_freqs: 1 };
    let mut field = Field::new(config, 7);
    if let Some(s) = field.params.spec("decoder.0.bias").cloned() {
        field.params.data[s.offset] = bias;
    }
    let shared = shared_tensors(&field, "sample.safetensors")?;
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
