//! Cross-scene libraries: libraries merged by the library format
//! ([`assetfield_library::merge()`]), then optionally grouped again across scenes
//! ([`crate::regroup`]) and scored against each scene's ground truth.

use assetfield_core::fsx::{StagingDir, write_atomic};
use assetfield_library::{merge, write_library_files};
use std::path::{Path, PathBuf};

use crate::error::{MiningError, Result, check_interrupt};

/// What [`merge_libraries_with`] did.
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

/// Merge libraries that share their vertical axes, basis and decoders into `out` (entry,
/// category and container names get the source folder's name as a prefix, `STEM/NAME`),
/// regrouping across scenes and scoring against ground truth as `opts` says. Refuses
/// libraries whose shared tensors differ, naming the tensor; writes all or nothing.
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
    if out.exists() && !force {
        return Err(MiningError::OutputExists(out.display().to_string()));
    }
    let merged = merge(inputs, out)?;
    let mut lib = merged.library;
    if let Some(r) = &opts.regroup {
        let g = crate::regroup::regroup(&lib, r)?;
        lib.index.entries = g.entries;
        lib.index.categories = g.categories;
    }
    let metrics = (!opts.gt.is_empty()).then(|| {
        let names: Vec<String> = inputs.iter().map(|p| p.display().to_string()).collect();
        crate::metrics::cross_scene_metrics(
            &lib.index,
            &merged.scene_of,
            &names,
            &opts.gt,
            opts.iou_threshold,
        )
    });
    let staging = StagingDir::new(out, force)?;
    write_library_files(staging.path(), &lib.index, &lib.patches, &lib.shared)?;
    if let Some(m) = &metrics {
        let text = serde_json::to_string_pretty(m)
            .map_err(|e| MiningError::io("cannot serialise the merge metrics", e))?;
        write_atomic(&staging.path().join("metrics.json"), text.as_bytes())?;
    }
    check_interrupt()?;
    let out = staging.commit()?;
    Ok(MergeReport {
        out,
        entries: lib.index.entries.len(),
        categories: lib.index.categories.len(),
        containers: lib.index.containers.len(),
        metrics,
    })
}
