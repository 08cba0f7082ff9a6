//! Grouping the entries of a cross-scene library again, together (paper Sec. 3.4, Fig. 8):
//! after `library merge`, each scene's entries keep the categories their own scene gave
//! them; [`regroup`] clusters all of them at once with the grouping every scene's mining
//! uses (label histograms of the colour-plane features at each object's own texels, their
//! Jensen-Shannon divergence plus the shape and vertical-profile terms, average linkage and
//! the separation cut), so that one category spans scenes, then picks each category's
//! template (the medoid) and poses every member relative to it (yaw search on the density
//! patches). It needs entries described in one feature space: libraries whose shared
//! tensors are identical (scenes trained together, or fitted with `train --share`).

use crate::agglomerative::DistanceMatrix;
use crate::copies::blurred;
use crate::error::{MiningError, Result, check_interrupt};
use crate::group::{GroupOptions, Grouping, Samples, Shape, group_samples_with, hull_area};
use crate::image::{Mask, PlaneImage};
use crate::library::{Category, Entry, EntryKind, Library};
use crate::medoid::medoid;
use crate::planes::OpacityVolume;
use crate::yaw::{YawOptions, estimate_yaw_weighted};
use assetfield_field::{Field, FieldConfig};
use glam::Vec2;
use rayon::prelude::*;

/// Opacity above which a voxel counts as occupied in an entry's vertical profile: a
/// library keeps no scene's own threshold, so the scale-free middle of the opacity range
/// (more likely opaque than not) stands for all of them.
pub const PROFILE_VOXEL_THRESHOLD: f32 = 0.5;

/// Smallest sample weight (opacity) of an own texel, so that a faint texel still counts.
const MIN_SAMPLE_WEIGHT: f32 = 1e-3;

/// What [`regroup`] measured and decided.
#[derive(Debug, Clone)]
pub struct Regrouped {
    /// New category of every entry (index into `categories`), in index order.
    pub category: Vec<usize>,
    pub categories: Vec<Category>,
    /// The entries with their new categories, kinds, yaws, positions and residuals.
    pub entries: Vec<Entry>,
    pub grouping: Grouping,
}

/// An entry's own patch as a small field over its texels with the library's shared
/// tensors (its density plane the entry's), to read its opacity columns.
fn entry_field(lib: &Library, shared: &Field, e: &Entry, density: &[f32]) -> Result<Field> {
    let (h, w) = e.patch_size;
    let mut config: FieldConfig = lib.config.clone();
    let t = Vec2::new(lib.index.texel_size.0, lib.index.texel_size.1);
    let min = e.box_centre() - Vec2::new((w - 1) as f32, (h - 1) as f32) * t * 0.5;
    // a patch of one texel still needs two nodes per axis
    let (cols, rows) = (w.max(2), h.max(2));
    config.res[0] = cols;
    config.res[1] = rows;
    config.aabb[0][0] = min.x;
    config.aabb[0][1] = min.y;
    config.aabb[1][0] = min.x + (cols - 1) as f32 * t.x;
    config.aabb[1][1] = min.y + (rows - 1) as f32 * t.y;
    let mut f = Field::new(config, 0);
    f.copy_shared_from(shared);
    let spec = f.params.spec("density.plane").cloned().ok_or(MiningError::MissingTensor {
        source_name: "shared field".into(),
        name: "density.plane".into(),
        purpose: "an entry's opacity".into(),
    })?;
    let nd = lib.index.channels.0;
    let plane = &mut f.params.data[spec.offset..spec.offset + spec.len];
    for r in 0..rows {
        for c in 0..cols {
            let src = (r.min(h - 1) * w + c.min(w - 1)) * nd;
            plane[(r * cols + c) * nd..][..nd].copy_from_slice(&density[src..src + nd]);
        }
    }
    Ok(f)
}

/// Per entry: its samples (colour features at its own texels, weighted by the column's
/// opacity), its shape and its vertical profile from its base up.
struct Described {
    colour: Vec<f32>,
    weights: Vec<f32>,
    shape: Shape,
    profile: Vec<f64>,
}

fn describe(lib: &Library, shared: &Field, e: &Entry, blur: usize) -> Result<Described> {
    let (h, w) = e.patch_size;
    let (nd, nc) = lib.index.channels;
    let d = lib.patches.get_f32(&e.density, &[h, w, nd])?;
    let c = lib.patches.get_f32(&e.color, &[h, w, nc])?;
    let m = lib.patches.get_u8(&e.mask, &[h, w])?;
    let mask = Mask::from_fn(h, w, |r, col| m[r * w + col] != 0);
    let field = entry_field(lib, shared, e, d)?;
    let vol = OpacityVolume::from_field(&field)?;
    let base = (((e.base - vol.z0) / vol.dz).round().max(0.0) as usize).min(vol.nz);
    let mut profile = vec![0f64; vol.nz];
    let (mut colour, mut weights) = (Vec::new(), Vec::new());
    for r in 0..h {
        for col in 0..w {
            if !mask.get(r, col) {
                continue;
            }
            let column = vol.column(r, col);
            for (k, v) in column[base..].iter().enumerate() {
                if *v > PROFILE_VOXEL_THRESHOLD {
                    profile[k] += 1.0;
                }
            }
            let opacity = column.iter().copied().fold(0.0f32, f32::max);
            weights.push(opacity.max(MIN_SAMPLE_WEIGHT));
            colour.extend_from_slice(&c[(r * w + col) * nc..][..nc]);
        }
    }
    let total: f64 = profile.iter().sum();
    if total > 0.0 {
        profile.iter_mut().for_each(|x| *x /= total);
    }
    let t = lib.index.texel_size;
    Ok(Described {
        colour,
        weights,
        shape: Shape { area: hull_area(&mask) * t.0 * t.1, height: e.extent.2 },
        profile: blurred(&profile, blur),
    })
}

/// Group every entry of `lib` (a merged library) again, together, with `opts` (the
/// grouping of `assetfield mine`; `blur` is its vertical blur in levels), then choose
/// templates and pose the members (`yaw`). Entries are renamed nowhere; categories become
/// `cat000`, `cat001`, ... in order of first appearance.
pub fn regroup(
    lib: &Library,
    opts: &GroupOptions,
    blur: usize,
    yaw: &YawOptions,
) -> Result<Regrouped> {
    let entries = &lib.index.entries;
    let n = entries.len();
    if n == 0 {
        return Err(MiningError::InvalidParameter {
            name: "library",
            reason: "the library has no entries to group".into(),
        });
    }
    let shared = lib.shared_field()?;
    let described: Vec<Described> =
        entries.par_iter().map(|e| describe(lib, &shared, e, blur)).collect::<Result<_>>()?;
    check_interrupt()?;
    let nc = lib.index.channels.1;
    let mut samples = Samples { dim: nc, ..Default::default() };
    for (i, d) in described.iter().enumerate() {
        samples.points.extend_from_slice(&d.colour);
        samples.weights.extend_from_slice(&d.weights);
        samples.owner.extend(std::iter::repeat_n(i as u32, d.weights.len()));
    }
    if let Some(i) = described.iter().position(|d| d.weights.is_empty()) {
        return Err(MiningError::InvalidParameter {
            name: "library",
            reason: format!(
                "entry {:?} has an empty mask: nothing to group it by",
                entries[i].name
            ),
        });
    }
    let shapes: Vec<Shape> = described.iter().map(|d| d.shape).collect();
    let profiles: Vec<Vec<f64>> = described.iter().map(|d| d.profile.clone()).collect();
    let mut gopts = opts.clone();
    gopts.labels = gopts.labels.min(samples.len());
    let grouping = group_samples_with(&samples, n, &shapes, &profiles, &gopts)?;
    check_interrupt()?;
    let poses = pose_members(lib, &grouping.category, &grouping.distance, yaw)?;
    let mut out = entries.clone();
    let k = grouping.n_categories;
    let mut categories: Vec<Category> = (0..k)
        .map(|c| Category {
            name: format!("cat{c:03}"),
            template: entries[poses.templates[c]].name.clone(),
            members: Vec::new(),
        })
        .collect();
    for (i, e) in out.iter_mut().enumerate() {
        let c = grouping.category[i];
        let t = poses.templates[c];
        categories[c].members.push(e.name.clone());
        e.category = categories[c].name.clone();
        e.kind = if t == i { EntryKind::Template } else { EntryKind::Instance };
        let (yaw_deg, offset, residual) = poses.fits[i];
        e.yaw_deg = yaw_deg;
        e.residual = residual;
        e.matched_on = Some("density".into());
        // where the template's pivot lands on this entry
        let texel = Vec2::new(lib.index.texel_size.0, lib.index.texel_size.1);
        let centre = entries[i].box_centre() + Vec2::from(offset) * texel;
        let p = centre + Vec2::from_angle(yaw_deg.to_radians()).rotate(entries[t].pivot_offset());
        e.position = (p.x, p.y);
    }
    Ok(Regrouped { category: grouping.category.clone(), categories, entries: out, grouping })
}

/// Templates (medoids) and every member's (yaw, offset in texels, residual) against its
/// template's density patch.
struct MemberPoses {
    templates: Vec<usize>,
    fits: Vec<(f32, (f32, f32), f32)>,
}

fn pose_members(
    lib: &Library,
    category: &[usize],
    distance: &DistanceMatrix,
    yaw: &YawOptions,
) -> Result<MemberPoses> {
    let n = category.len();
    let k = category.iter().max().map_or(0, |&m| m + 1);
    let templates: Vec<usize> = (0..k)
        .map(|c| medoid(distance, &(0..n).filter(|&i| category[i] == c).collect::<Vec<_>>()))
        .collect::<Result<_>>()?;
    let nd = lib.index.channels.0;
    let patch = |i: usize| -> Result<(PlaneImage, Vec<f32>)> {
        let e = &lib.index.entries[i];
        let (h, w) = e.patch_size;
        let d = lib.patches.get_f32(&e.density, &[h, w, nd])?.to_vec();
        let m = lib.patches.get_u8(&e.mask, &[h, w])?;
        Ok((PlaneImage::new(h, w, nd, d)?, m.iter().map(|&b| f32::from(b.min(1))).collect()))
    };
    let fits = (0..n)
        .into_par_iter()
        .map(|i| {
            let t = templates[category[i]];
            if t == i {
                return Ok((0.0, (0.0, 0.0), 0.0));
            }
            let (tp, tw) = patch(t)?;
            let (ip, iw) = patch(i)?;
            // a pair that cannot be matched keeps the template's orientation, residual -1
            Ok(match estimate_yaw_weighted(&tp, Some(&tw), &ip, Some(&iw), yaw) {
                Ok(fit) => (fit.yaw_deg, fit.offset, fit.residual),
                Err(_) => (0.0, (0.0, 0.0), -1.0),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(MemberPoses { templates, fits })
}

/// Parameters of a regrouping: the grouping, vertical blur and yaw search of `mine`.
#[derive(Debug, Clone, Default)]
pub struct RegroupOptions {
    pub group: GroupOptions,
    /// The vertical blur of the profiles, in levels (`DetectParams::blur_levels`).
    pub blur_levels: usize,
    pub yaw: YawOptions,
}

impl RegroupOptions {
    /// The settings `assetfield mine` groups and poses with by default.
    pub fn from_mining(opts: &crate::pipeline::MineOptions) -> Self {
        RegroupOptions {
            group: opts.group.clone(),
            blur_levels: opts.detect.blur_levels,
            yaw: opts.pose.yaw,
        }
    }
}

/// One scene's scores in a merged library (its entries against its ground truth).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SceneScore {
    pub library: String,
    pub entries: usize,
    pub ground_truth: usize,
    pub matched: usize,
    pub precision: f32,
    pub recall: f32,
    pub f1: f32,
    /// ARI of the scene's matched entries under the merged library's categories.
    pub ari: f32,
}

/// `metrics.json` of a merged library with ground truth.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CrossSceneMetrics {
    /// ARI over the matched entries of every scene together, against their ground-truth
    /// categories (category names shared between the scenes' ground truths).
    pub cross_scene_ari: f32,
    /// Matched entries of all scenes.
    pub matched: usize,
    pub categories: usize,
    /// Categories with members from more than one scene.
    pub categories_spanning_scenes: usize,
    /// Ground-truth categories found in more than one scene, and how many of them the
    /// merged library puts in one category (all their matched entries together).
    pub shared_gt_categories: usize,
    pub shared_gt_categories_united: usize,
    pub iou_threshold: f32,
    pub per_scene: Vec<SceneScore>,
    /// Per matched entry: (entry, ground-truth category, merged category).
    pub matches: Vec<(String, String, String)>,
}

/// Score a merged library: each scene's entries (`scene_of[i]`: the input of entry `i`)
/// against that scene's ground truth (BEV IoU at least `iou_threshold`), and the ARI over
/// all matched entries together.
pub fn cross_scene_metrics(
    index: &crate::library::LibraryIndex,
    scene_of: &[usize],
    names: &[String],
    gts: &[assetfield_layout::GtLayout],
    iou_threshold: f32,
) -> CrossSceneMetrics {
    use crate::metrics::{Predicted, adjusted_rand_index, evaluate};
    use assetfield_core::Rect2;
    use std::collections::{BTreeMap, BTreeSet};
    let cat_index: BTreeMap<&str, usize> =
        index.categories.iter().enumerate().map(|(k, c)| (c.name.as_str(), k)).collect();
    let mut matches = Vec::new();
    let mut per_scene = Vec::new();
    for (s, gt) in gts.iter().enumerate() {
        let ids: Vec<usize> =
            (0..index.entries.len()).filter(|&i| scene_of.get(i) == Some(&s)).collect();
        let local: BTreeMap<&str, usize> =
            ids.iter().enumerate().map(|(k, &i)| (index.entries[i].name.as_str(), k)).collect();
        let preds: Vec<Predicted> = ids
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let e = &index.entries[i];
                let b = e.source_box;
                let category = cat_index.get(e.category.as_str()).copied().unwrap_or(usize::MAX);
                let template = index
                    .categories
                    .get(category)
                    .and_then(|c| local.get(c.template.as_str()).copied())
                    .unwrap_or(k);
                Predicted {
                    world: Rect2::new(Vec2::new(b[0], b[1]), Vec2::new(b[2], b[3])),
                    category,
                    template,
                    yaw_rel: e.yaw_deg,
                    position: e.pivot_world(),
                }
            })
            .collect();
        let m = evaluate(&preds, gt, iou_threshold);
        for inst in &m.per_instance {
            if let Some(g) = &inst.gt_category {
                let e = &index.entries[ids[inst.detection]];
                matches.push((e.name.clone(), g.clone(), e.category.clone()));
            }
        }
        per_scene.push(SceneScore {
            library: names.get(s).cloned().unwrap_or_default(),
            entries: ids.len(),
            ground_truth: m.ground_truth,
            matched: m.matched,
            precision: m.precision,
            recall: m.recall,
            f1: m.f1,
            ari: m.ari,
        });
    }
    let gt_labels: Vec<&str> = matches.iter().map(|m| m.1.as_str()).collect();
    let ours: Vec<&str> = matches.iter().map(|m| m.2.as_str()).collect();
    let cross_scene_ari =
        if matches.is_empty() { 0.0 } else { adjusted_rand_index(&ours, &gt_labels) };
    let scene_by_name: BTreeMap<&str, usize> = index
        .entries
        .iter()
        .enumerate()
        .map(|(i, e)| (e.name.as_str(), scene_of.get(i).copied().unwrap_or(0)))
        .collect();
    let spanning = index
        .categories
        .iter()
        .filter(|c| {
            c.members
                .iter()
                .filter_map(|m| scene_by_name.get(m.as_str()))
                .collect::<BTreeSet<_>>()
                .len()
                > 1
        })
        .count();
    // ground-truth categories matched in several scenes, and whether they stay together
    let mut by_gt: BTreeMap<&str, (BTreeSet<usize>, BTreeSet<&str>)> = BTreeMap::new();
    for (name, g, c) in &matches {
        let e = by_gt.entry(g.as_str()).or_default();
        e.0.insert(scene_by_name.get(name.as_str()).copied().unwrap_or(0));
        e.1.insert(c.as_str());
    }
    let shared: Vec<_> = by_gt.values().filter(|(scenes, _)| scenes.len() > 1).collect();
    CrossSceneMetrics {
        cross_scene_ari,
        matched: matches.len(),
        categories: index.categories.len(),
        categories_spanning_scenes: spanning,
        shared_gt_categories: shared.len(),
        shared_gt_categories_united: shared.iter().filter(|(_, cats)| cats.len() == 1).count(),
        iou_threshold,
        per_scene,
        matches,
    }
}
