//! Merging libraries that share their vertical axes, basis and decoders into one.

use assetfield_core::fsx::StagingDir;
use assetfield_core::{TensorData, TensorFile};
use assetfield_field::FieldConfig;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::error::{LibraryError, Result, check_interrupt};
use crate::files::{Library, open_library, write_library_files};
use crate::index::{Category, Container, Entry, FORMAT, LibraryIndex, PATCHES_FILE, SHARED_FILE};

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

/// Libraries merged in memory: one index whose entry, category and container names carry
/// their source folder's name as a prefix (`STEM/NAME`), the patches renamed to match, and
/// the shared tensors every input has.
#[derive(Debug, Clone)]
pub struct Merged {
    /// The merged library; its `dir` is the folder it is meant for (not yet written).
    pub library: Library,
    /// The input every entry came from, in entry order.
    pub scene_of: Vec<usize>,
}

/// Read, check and merge `inputs` (at least two) into a library meant for `out`. Refuses
/// libraries whose shared tensors, channels or model differ, naming the first tensor that
/// differs. Nothing is written.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<Merged> {
    if inputs.len() < 2 {
        return Err(LibraryError::InvalidParameter {
            name: "libraries",
            reason: format!("merging needs at least two libraries, got {}", inputs.len()),
        });
    }
    let libs: Vec<Library> = inputs.iter().map(|p| open_library(p)).collect::<Result<_>>()?;
    check_shared(inputs, &libs)?;
    let prefixes = unique_prefixes(inputs);
    let first = &libs[0];
    let mut index = LibraryIndex {
        format: FORMAT.into(),
        sources: Vec::new(),
        model: first.index.model.clone(),
        texel_size: first.index.texel_size,
        channels: first.index.channels,
        patches: PATCHES_FILE.into(),
        shared: first.index.shared.clone(),
        categories: Vec::new(),
        entries: Vec::new(),
        containers: Vec::new(),
    };
    index.shared.file = SHARED_FILE.into();
    let mut patches = TensorFile::new();
    patches.set_meta("format", FORMAT);
    let mut scene_of = Vec::new();
    for (k, (lib, prefix)) in libs.iter().zip(&prefixes).enumerate() {
        check_interrupt()?;
        append(&mut index, &mut patches, lib, prefix)?;
        scene_of.extend(std::iter::repeat_n(k, lib.index.entries.len()));
    }
    let library = Library {
        dir: out.to_path_buf(),
        index,
        patches,
        shared: first.shared.clone(),
        config: first.config.clone(),
        info: first.info.clone(),
    };
    Ok(Merged { library, scene_of })
}

/// [`merge`] and write the result to `out` (replaced only with `force`; written whole or
/// not at all). Returns the folder written.
pub fn merge_libraries(inputs: &[PathBuf], out: &Path, force: bool) -> Result<PathBuf> {
    if out.exists() && !force {
        return Err(LibraryError::OutputExists(out.display().to_string()));
    }
    let merged = merge(inputs, out)?;
    let staging = StagingDir::new(out, force)?;
    let lib = &merged.library;
    write_library_files(staging.path(), &lib.index, &lib.patches, &lib.shared)?;
    check_interrupt()?;
    Ok(staging.commit()?)
}

/// Every library's shared tensors, channels and model are the first's.
fn check_shared(inputs: &[PathBuf], libs: &[Library]) -> Result<()> {
    let first = &libs[0];
    for (i, l) in libs.iter().enumerate().skip(1) {
        let differs = |tensor: String, detail: String| LibraryError::SharedTensorDiffers {
            a: inputs[0].display().to_string(),
            b: inputs[i].display().to_string(),
            tensor,
            detail,
        };
        if let Some((tensor, detail)) = shared_difference(&first.shared, &l.shared) {
            return Err(differs(tensor, detail));
        }
        if l.index.channels != first.index.channels || l.index.model != first.index.model {
            return Err(differs(
                "plane channels / model".into(),
                format!(
                    "{} {:?} vs {} {:?}",
                    first.index.model, first.index.channels, l.index.model, l.index.channels
                ),
            ));
        }
    }
    Ok(())
}

/// One prefix per input, from its folder's name (`lib` for none), numbered where two agree.
fn unique_prefixes(inputs: &[PathBuf]) -> Vec<String> {
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
    prefixes
}

/// Append `lib`'s sources, entries, categories and containers to `index`, and their
/// tensors to `patches`, every name prefixed with `prefix/`.
fn append(
    index: &mut LibraryIndex,
    patches: &mut TensorFile,
    lib: &Library,
    prefix: &str,
) -> Result<()> {
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
    Ok(())
}
