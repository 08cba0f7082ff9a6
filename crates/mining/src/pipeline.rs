//! From a trained field to an asset library and a mined layout: [`mine`] runs detection
//! ([`crate::detect`]), grouping ([`crate::group`]), templates and poses ([`crate::pose`]),
//! writes the library ([`crate::library`]), the layout ([`crate::layout_out`]) and the
//! pictures ([`crate::picture`]), and with a ground truth measures the result
//! ([`crate::metrics`]). The output folder is assembled next to its final place and renamed
//! into place at the end, so an error or Ctrl-C never leaves half a library.

use assetfield_core::TensorFile;
use assetfield_core::canvas::Canvas;
use assetfield_core::fsx::{StagingDir, write_atomic};
use assetfield_core::plot::{colormap, pca_colors};
use assetfield_field::eval::{LoadedField, load_field};
use assetfield_field::{Field, ModelKind};
use assetfield_layout::GtLayout;
use glam::Vec2;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};

use crate::agglomerative::DistanceMatrix;
use crate::copies::{CopySplit, blurred, own_profile, profile_jsd, split_copies, vertical_profile};
use crate::detect::{DetectParams, Detection, Detections, FloorBand, detect_with_color_axis};
use crate::error::{MiningError, Result, check_interrupt};
use crate::fringe::FringeGrowth;
use crate::group::{GroupOptions, Grouping, Profiles, Samples, Shape, group_samples_profiled};
use crate::halves::{JoinedHalves, join_halves};
use crate::histogram;
use crate::image::{Mask, PlaneImage};
use crate::layout_out::{layout_script, script_text_checked};
use crate::metrics::{Metrics, Predicted, evaluate};
use crate::morphology::dilate;
use crate::picture::{BoxMark, TemplateTile, boxes_picture, categories_picture, picture_scale};
use crate::pivot::contact_pivots;
use crate::planes::{FieldPlanes, OpacityVolume, PlaneChoice, field_planes, semantic_plane};
use crate::pose::{
    PatchRect, PatchSource, PoseOptions, Poses, estimate_poses, mask_in_patch, padded_crop,
};
use assetfield_library::{
    Category, Container, Entry, EntryKind, FORMAT, LibraryIndex, PATCHES_FILE, SHARED_FILE,
    SharedRef, content_hash, shared_tensors, write_library_files,
};

/// Everything [`mine`] can be told.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MineOptions {
    pub detect: DetectParams,
    pub group: GroupOptions,
    /// What the grouping discretises: a plane's features or the objects' voxel colours.
    pub group_on: GroupOn,
    /// What is matched for the yaw: a plane's patches or the objects' own voxels.
    pub yaw_on: YawOn,
    pub pose: PoseOptions,
    /// Template overrides `(category, detection)`: category as `catK` or `K`.
    pub templates: Vec<(String, usize)>,
    /// Ground-truth layout to measure against.
    pub gt: Option<PathBuf>,
    /// IoU a detection needs to match a ground-truth box.
    pub iou: f32,
    /// Name the layout's instances after the ground-truth keys they match (with `gt`), so
    /// that an edit script written for the ground truth applies to the mined layout too.
    #[serde(default)]
    pub gt_names: bool,
    /// Instances whose template-matching residual exceeds this many times the median of the
    /// residuals measured on the same patches keep their own patch in layout.ron (0: every
    /// instance; infinity: none; fewer than three residuals of a kind: own patches).
    #[serde(default = "default_own_patch_residual")]
    pub own_patch_residual: f32,
    /// Replace an existing output folder.
    pub force: bool,
}

impl MineOptions {
    /// The options of a preset: [`Preset::Default`] is [`MineOptions::default`];
    /// [`Preset::Paper`] runs only the paper's steps: its detection
    /// ([`DetectParams::paper`]), grouping by histograms of the colour plane's features and
    /// shape alone (no vertical profile, no cutting of copies) and yaw on the density plane.
    pub fn preset(p: crate::detect::Preset) -> Self {
        let mut o = MineOptions { detect: DetectParams::preset(p), ..MineOptions::default() };
        if p == crate::detect::Preset::Paper {
            o.group_on = GroupOn::Color;
            o.yaw_on = YawOn::Density;
            o.group.split_copies = false;
            o.group.join_halves = false;
            o.group.profile_weight = 0.0;
            // the cut its baseline tables were measured with
            o.group.cut = crate::group::GroupCut::Silhouette;
        }
        o
    }
}

fn default_own_patch_residual() -> f32 {
    crate::layout_out::OWN_PATCH_RESIDUAL
}

impl Default for MineOptions {
    fn default() -> Self {
        MineOptions {
            detect: DetectParams::default(),
            group: GroupOptions::default(),
            group_on: GroupOn::Voxels,
            yaw_on: YawOn::Auto,
            pose: PoseOptions::default(),
            templates: Vec::new(),
            gt: None,
            iou: 0.5,
            gt_names: false,
            own_patch_residual: crate::layout_out::OWN_PATCH_RESIDUAL,
            force: false,
        }
    }
}

/// What the grouping's label histograms are built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum GroupOn {
    /// The colour plane's features at each object's own texels (the paper; I-AssetField:
    /// the integrated RGB plane). A texel's feature describes its whole column
    /// ([`Samples::from_plane`]): the floor or the support under the object too.
    Color,
    /// The semantic plane's features at each object's own texels.
    Semantic,
    /// The density plane's features at each object's own texels.
    Density,
    /// The colours the field decodes on each object's own surface voxels, from its base to
    /// its top ([`Samples::from_voxels`]): what the object looks like whatever stands under
    /// it (copies on a floor slab and beside it, on tiles of two colours, on a table and on
    /// the floor).
    #[default]
    Voxels,
}

impl GroupOn {
    /// The plane the samples come from (`None` for voxels).
    pub fn plane(self) -> Option<PlaneChoice> {
        match self {
            GroupOn::Color => Some(PlaneChoice::Color),
            GroupOn::Semantic => Some(PlaneChoice::Semantic),
            GroupOn::Density => Some(PlaneChoice::Density),
            GroupOn::Voxels => None,
        }
    }
}

/// Progress callbacks (the CLI draws a bar); every method has a no-op default.
pub trait Progress {
    /// A new step begins (`index` of `total`).
    fn step(&self, _index: usize, _total: usize, _what: &str) {}
}

/// No progress output.
#[derive(Debug, Clone, Copy, Default)]
pub struct Quiet;
impl Progress for Quiet {}

/// What [`mine`] did.
#[derive(Debug, Clone)]
pub struct MineReport {
    pub out: PathBuf,
    pub model: String,
    pub detections: usize,
    pub supported: usize,
    /// Detections cut as identical objects in contact ([`crate::copies`]), and the pieces
    /// they became.
    pub copies_cut: usize,
    pub copies_pieces: usize,
    /// Objects joined from two halves that recur together ([`crate::halves`]).
    pub halves_joined: usize,
    /// Objects grown by their faint fringe ([`crate::fringe`]).
    pub fringes_taken: usize,
    pub categories: usize,
    /// Regions dropped as background, with reasons.
    pub removed: Vec<String>,
    pub floor: Option<f32>,
    pub threshold: f32,
    pub cut: String,
    pub layout_instances: usize,
    pub metrics: Option<Metrics>,
    pub seconds: f64,
    /// What the user should know about the field's content (it lies in a vertical sheet:
    /// [`crate::content`]).
    pub content_note: Option<String>,
}

const STEPS: usize = 7; // fixed: progress steps

/// The detection evidence picture colours (row 0 = ymin).
fn evidence_colors(dets: &Detections) -> Vec<[u8; 3]> {
    dets.evidence.iter().map(|&v| colormap(v.clamp(0.0, 1.0))).collect()
}

/// Fill the texels under `mask` with the nearest texel outside it (breadth-first from the
/// background), so that the emptied planes continue the surrounding floor.
pub fn fill_from_background(plane: &PlaneImage, mask: &Mask) -> Result<PlaneImage> {
    fill_from_background_by_class(plane, mask, None)
}

/// [`fill_from_background`], keeping classes apart: with `class` (one flag per texel), a
/// masked texel is filled from the nearest unmasked texel of its own class (the floor from
/// the floor, empty space from empty space), and from the nearest of any class when its class
/// has no unmasked texel. Objects overhanging the edge of a floor thus leave empty space
/// behind, not floor continued past its edge.
pub fn fill_from_background_by_class(
    plane: &PlaneImage,
    mask: &Mask,
    class: Option<&[bool]>,
) -> Result<PlaneImage> {
    plane.validate()?;
    if (mask.rows, mask.cols) != (plane.rows, plane.cols) {
        return Err(MiningError::SizeMismatch {
            what: "fill mask vs plane (texels)",
            left: mask.rows * mask.cols,
            right: plane.texels(),
        });
    }
    if let Some(cl) = class
        && cl.len() != mask.rows * mask.cols
    {
        return Err(MiningError::SizeMismatch {
            what: "fill classes vs plane (texels)",
            left: cl.len(),
            right: plane.texels(),
        });
    }
    let (rows, cols, ch) = (plane.rows, plane.cols, plane.ch);
    // nearest unmasked texel among those `keep` accepts (breadth-first, 4-connected)
    let nearest = |keep: &dyn Fn(usize) -> bool| -> Vec<Option<usize>> {
        let mut source: Vec<Option<usize>> = vec![None; rows * cols];
        let mut queue = VecDeque::new();
        for (i, s) in source.iter_mut().enumerate() {
            if !mask.data[i] && keep(i) {
                *s = Some(i);
                queue.push_back(i);
            }
        }
        while let Some(i) = queue.pop_front() {
            let (r, c) = (i / cols, i % cols);
            for (dr, dc) in [(0isize, 1isize), (0, -1), (1, 0), (-1, 0)] {
                let (nr, nc) = (r as isize + dr, c as isize + dc);
                if nr < 0 || nc < 0 || nr >= rows as isize || nc >= cols as isize {
                    continue;
                }
                let j = nr as usize * cols + nc as usize;
                if source[j].is_none() {
                    source[j] = source[i];
                    queue.push_back(j);
                }
            }
        }
        source
    };
    let any = nearest(&|_| true);
    let by_class = class.map(|cl| (nearest(&|i| cl[i]), nearest(&|i| !cl[i])));
    let mut out = plane.clone();
    for i in 0..rows * cols {
        if !mask.data[i] {
            continue;
        }
        let own = by_class
            .as_ref()
            .zip(class)
            .and_then(|((yes, no), cl)| if cl[i] { yes[i] } else { no[i] });
        if let Some(s) = own.or(any[i]) {
            let v: Vec<f32> = plane.data[s * ch..(s + 1) * ch].to_vec();
            out.data[i * ch..(i + 1) * ch].copy_from_slice(&v);
        }
    }
    Ok(out)
}

/// The fill of the container: every object's region of `mask` (the objects and their
/// halos) takes the per-channel median of the unmasked texels within `ring` texels of it, of
/// the masked texel's class where `class` is given (the floor from the floor, empty space
/// from empty space; the other class, then the nearest texel
/// ([`fill_from_background_by_class`]) where a region's ring holds none of it). A masked
/// texel's class is whether the floor in view continues under it ([`floor_under`]), not its
/// own: an object's solid base is opaque at the floor's levels wherever it stands (a
/// pedestal table beyond a floor's edge read as floor), and the floor under a solid body may
/// be missing from the field (never seen). A median,
/// not the nearest texel: the nearest copies whatever touches the region's edge (a kerb, a
/// neighbour's blur, the object's own haze) across it in streaks, which is the
/// object-shaped mark a vacated footprint must not keep. The regions and rings are found
/// once and applied to every plane of a field.
#[derive(Debug)]
pub struct RingFill<'a> {
    mask: &'a Mask,
    /// Per texel, its own class (unmasked texels) or whether the floor continues under it
    /// (masked texels, [`floor_under`]).
    class: Option<Vec<bool>>,
    /// Per texel, its region (masked texels) or the region whose ring it is in.
    region: Vec<u32>,
    /// Per region, the ring's texels of class 0 (empty space) and 1 (floor).
    members: Vec<[Vec<usize>; 2]>,
}

impl<'a> RingFill<'a> {
    /// One region per object: `mask` holds the objects (`objects`, 4-connected) and their
    /// halos, and each masked texel belongs to the nearest object (4-connected steps inside
    /// `mask`), so that objects whose halos touch (a row of trees along a kerb) are each
    /// filled from the ground around them, not from one median of the whole row's ring; each
    /// region's ring is the unmasked texels within `ring` 4-connected steps of it (a texel
    /// within reach of two regions joins the nearer).
    pub fn around_objects(
        mask: &'a Mask,
        objects: &Mask,
        class: Option<&[bool]>,
        ring: usize,
    ) -> Result<Self> {
        let (rows, cols) = (mask.rows, mask.cols);
        let n = rows * cols;
        if let Some(cl) = class
            && cl.len() != n
        {
            return Err(MiningError::SizeMismatch {
                what: "fill classes vs mask (texels)",
                left: cl.len(),
                right: n,
            });
        }
        let (mut region, sizes) = nearest_object(mask, objects)?;
        let mut dist = vec![usize::MAX; n];
        let mut queue: VecDeque<usize> = (0..n).filter(|&i| mask.data[i]).collect();
        for &i in &queue {
            dist[i] = 0;
        }
        while let Some(i) = queue.pop_front() {
            if dist[i] >= ring {
                continue;
            }
            for j in neighbours4(i, rows, cols) {
                if dist[j] == usize::MAX {
                    dist[j] = dist[i] + 1;
                    region[j] = region[i];
                    queue.push_back(j);
                }
            }
        }
        // under the mask, whether the floor in view continues there ([`floor_under`]); in
        // view, each texel's own class (the medians are of the floor's texels and of empty
        // space's)
        let class = match class {
            Some(cl) => Some(floor_under(mask, cl, ring)?),
            None => None,
        };
        let class_of = |i: usize| class.as_ref().map_or(0usize, |cl| usize::from(cl[i]));
        let mut members: Vec<[Vec<usize>; 2]> = vec![[Vec::new(), Vec::new()]; sizes.len()];
        for i in 0..n {
            if !mask.data[i] && region[i] != u32::MAX {
                members[region[i] as usize][class_of(i)].push(i);
            }
        }
        Ok(RingFill { mask, class, region, members })
    }

    /// `plane` with the masked texels filled.
    pub fn apply(&self, plane: &PlaneImage) -> Result<PlaneImage> {
        let ch = plane.ch;
        let median = |texels: &[usize]| -> Option<Vec<f32>> {
            if texels.is_empty() {
                return None;
            }
            let mut col = vec![0f32; texels.len()];
            Some(
                (0..ch)
                    .map(|k| {
                        for (v, &t) in col.iter_mut().zip(texels) {
                            *v = plane.data[t * ch + k];
                        }
                        col.sort_unstable_by(f32::total_cmp);
                        col[col.len() / 2]
                    })
                    .collect(),
            )
        };
        let medians: Vec<[Option<Vec<f32>>; 2]> =
            self.members.iter().map(|m| [median(&m[0]), median(&m[1])]).collect();
        // the nearest texel only where a region's ring holds neither class
        let mut out = if medians.iter().any(|m| m[0].is_none() && m[1].is_none()) {
            fill_from_background_by_class(plane, self.mask, self.class.as_deref())?
        } else {
            plane.validate()?;
            if (self.mask.rows, self.mask.cols) != (plane.rows, plane.cols) {
                return Err(MiningError::SizeMismatch {
                    what: "fill mask vs plane (texels)",
                    left: self.mask.rows * self.mask.cols,
                    right: plane.texels(),
                });
            }
            plane.clone()
        };
        for i in 0..self.region.len() {
            if !self.mask.data[i] {
                continue;
            }
            let [empty, floor] = &medians[self.region[i] as usize];
            let on_floor = self.class.as_ref().is_some_and(|cl| cl[i]);
            let (own, other) = if on_floor { (floor, empty) } else { (empty, floor) };
            if let Some(v) = own.as_ref().or(other.as_ref()) {
                out.data[i * ch..(i + 1) * ch].copy_from_slice(v);
            }
        }
        Ok(out)
    }
}

/// Per texel, whether most of the unmasked texels within `radius` texels (a square window)
/// are of class `true` (the floor); a texel with none in its window keeps its own class: the
/// floor's extent rather than its texels over the floor's threshold, which are noisy where
/// the floor is faint (texels under it amid the floor) and where haze lies beyond it (specks
/// over it). A majority over the field's blur; no value of its own.
fn class_areas(mask: &Mask, class: &[bool], radius: usize) -> Vec<bool> {
    let (rows, cols) = (mask.rows, mask.cols);
    // summed-area tables of unmasked texels and of unmasked floor texels
    let (w, mut seen, mut floor) =
        (cols + 1, vec![0u32; (rows + 1) * (cols + 1)], vec![0u32; (rows + 1) * (cols + 1)]);
    for r in 0..rows {
        for c in 0..cols {
            let i = r * cols + c;
            let (a, b) = (u32::from(!mask.data[i]), u32::from(!mask.data[i] && class[i]));
            let j = (r + 1) * w + c + 1;
            seen[j] = a + seen[j - 1] + seen[j - w] - seen[j - w - 1];
            floor[j] = b + floor[j - 1] + floor[j - w] - floor[j - w - 1];
        }
    }
    let sum = |t: &[u32], r0: usize, c0: usize, r1: usize, c1: usize| {
        t[r1 * w + c1] + t[r0 * w + c0] - t[r0 * w + c1] - t[r1 * w + c0]
    };
    (0..rows * cols)
        .map(|i| {
            let (r, c) = (i / cols, i % cols);
            let (r0, c0) = (r.saturating_sub(radius), c.saturating_sub(radius));
            let (r1, c1) = ((r + radius + 1).min(rows), (c + radius + 1).min(cols));
            let n = sum(&seen, r0, c0, r1, c1);
            if n == 0 { class[i] } else { 2 * sum(&floor, r0, c0, r1, c1) > n }
        })
        .collect()
}

/// Whether the floor lies under each masked texel: the floor in view (its area,
/// [`class_areas`] over `blur` texels) closed over the masked texels, with a square wide enough
/// to span every connected piece of the mask. An object on the floor, or on a floor's edge,
/// is a hole or a notch in the floor in view, which the closing fills (and a straight edge
/// through it stays straight); one beyond the floor's edge lies in no concavity of the floor
/// and stays empty space. Unmasked texels keep their own class.
fn floor_under(mask: &Mask, class: &[bool], blur: usize) -> Result<Vec<bool>> {
    let (rows, cols) = (mask.rows, mask.cols);
    if rows == 0 || cols == 0 {
        return Ok(class.to_vec());
    }
    let areas = class_areas(mask, class, blur);
    let in_view = Mask::from_fn(rows, cols, |r, c| !mask.get(r, c) && areas[r * cols + c]);
    // the widest piece of the mask, by the shorter side of its box
    let (labels, sizes) = crate::contours::label_components_4(mask)?;
    let mut boxes = vec![(usize::MAX, usize::MAX, 0usize, 0usize); sizes.len()];
    for (i, &l) in labels.iter().enumerate() {
        if l != u32::MAX {
            let (r, c) = (i / cols, i % cols);
            let b = &mut boxes[l as usize];
            *b = (b.0.min(r), b.1.min(c), b.2.max(r), b.3.max(c));
        }
    }
    let span = boxes.iter().map(|b| (b.2 - b.0 + 1).min(b.3 - b.1 + 1)).max().unwrap_or(0);
    // closed with the plane's edge texels continued outward (the plane's border neither
    // floor nor empty space: a margin of empty space along it stays a straight edge, a floor
    // cut by it stays floor)
    let r = span.div_ceil(2);
    let padded = Mask::from_fn(rows + 2 * r, cols + 2 * r, |pr, pc| {
        let (y, x) = (pr.saturating_sub(r).min(rows - 1), pc.saturating_sub(r).min(cols - 1));
        in_view.get(y, x)
    });
    let closed_padded = crate::morphology::close(&padded, r)?;
    let closed = Mask::from_fn(rows, cols, |y, x| closed_padded.get(y + r, x + r));
    Ok((0..rows * cols).map(|i| if mask.data[i] { closed.data[i] } else { class[i] }).collect())
}

/// The 4-neighbours of flat index `i` inside a `rows x cols` grid, as flat indices.
fn neighbours4(i: usize, rows: usize, cols: usize) -> impl Iterator<Item = usize> {
    let (r, c) = (i / cols, i % cols);
    [(0isize, 1isize), (0, -1), (1, 0), (-1, 0)].into_iter().filter_map(move |(dr, dc)| {
        let (nr, nc) = (r.wrapping_add_signed(dr), c.wrapping_add_signed(dc));
        (nr < rows && nc < cols).then(|| nr * cols + nc)
    })
}

/// Per texel of `mask`, the nearest object of `objects` (its 4-connected components inside
/// `mask`, by 4-connected steps inside `mask`), as labels and sizes like
/// [`crate::contours::label_components_4`]'s; masked texels no object reaches form regions
/// of their own.
fn nearest_object(mask: &Mask, objects: &Mask) -> Result<(Vec<u32>, Vec<usize>)> {
    let (rows, cols) = (mask.rows, mask.cols);
    let inside = Mask::from_fn(rows, cols, |r, c| mask.get(r, c) && objects.get(r, c));
    let (mut label, mut sizes) = crate::contours::label_components_4(&inside)?;
    let mut queue: VecDeque<usize> = (0..rows * cols).filter(|&i| label[i] != u32::MAX).collect();
    while let Some(i) = queue.pop_front() {
        for j in neighbours4(i, rows, cols) {
            if mask.data[j] && label[j] == u32::MAX {
                label[j] = label[i];
                sizes[label[i] as usize] += 1;
                queue.push_back(j);
            }
        }
    }
    let left = Mask::from_fn(rows, cols, |r, c| mask.get(r, c) && label[r * cols + c] == u32::MAX);
    if left.count() > 0 {
        let (extra, extra_sizes) = crate::contours::label_components_4(&left)?;
        let base = sizes.len() as u32;
        for (l, e) in label.iter_mut().zip(&extra) {
            if *e != u32::MAX {
                *l = base + e;
            }
        }
        sizes.extend(extra_sizes);
    }
    Ok((label, sizes))
}

/// Which texels hold the floor slab: opacity at least 0.5 at one of the floor's levels.
/// `None` without a floor.
pub fn floor_texels(vol: &OpacityVolume, floor: Option<&FloorBand>) -> Option<Vec<bool>> {
    let f = floor?;
    let n = vol.rows * vol.cols;
    Some(
        (0..n)
            .map(|i| {
                (f.lo..=f.hi.min(vol.nz.saturating_sub(1))).any(|k| vol.data[i * vol.nz + k] >= 0.5)
            })
            .collect(),
    )
}

/// Parse a category given as `catK` or `K`.
fn parse_category(s: &str, n: usize) -> Result<usize> {
    let t = s.trim();
    let num = t.strip_prefix("cat").unwrap_or(t);
    let k: usize = num.parse().map_err(|_| MiningError::InvalidParameter {
        name: "template",
        reason: format!("category {s:?} is neither catK nor a number"),
    })?;
    if k >= n {
        return Err(MiningError::InvalidParameter {
            name: "template",
            reason: format!(
                "category {s:?} does not exist (there are {n}: cat0..cat{})",
                n.max(1) - 1
            ),
        });
    }
    Ok(k)
}

/// Entry name of detection `i`.
pub fn entry_name(i: usize) -> String {
    format!("obj{i:03}")
}

/// Category name of category `k`.
pub fn category_name(k: usize) -> String {
    format!("cat{k}")
}

/// What template matching compares to find each instance's yaw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum YawOn {
    /// The objects' own voxels for categories with a member standing on another object (a
    /// laptop on a table: the table's legs and crossbars, in the laptop's plane column, do
    /// not turn with the laptop) or holding one (a table with a monitor on it against a bare
    /// one), the density plane for the rest.
    #[default]
    Auto,
    /// The density plane's patches.
    Density,
    /// The colour plane's patches.
    Color,
    /// The semantic plane's patches.
    Semantic,
    /// The opacity of every object's own height range, one channel per level above its base.
    Voxels,
}

impl YawOn {
    /// The plane this choice reads, if it reads one for every category.
    pub fn plane(self) -> Option<PlaneChoice> {
        match self {
            YawOn::Density => Some(PlaneChoice::Density),
            YawOn::Color => Some(PlaneChoice::Color),
            YawOn::Semantic => Some(PlaneChoice::Semantic),
            YawOn::Auto | YawOn::Voxels => None,
        }
    }
}

/// The patches every category is matched on.
fn yaw_sources<'a>(
    yaw_on: YawOn,
    dets: &Detections,
    category: &[usize],
    planes: &'a FieldPlanes,
    semantic: &'a Option<PlaneImage>,
    vol: &'a OpacityVolume,
) -> Result<Vec<PatchSource<'a>>> {
    let k = category.iter().max().map_or(0, |&m| m + 1);
    // a category with a member on another object or holding one: a plane texel describes
    // its whole column, the other object's part of it too
    let mut stacked = vec![false; k];
    for (d, &c) in dets.detections.iter().zip(category) {
        stacked[c] |= d.parent.is_some() || !d.children.is_empty();
    }
    stacked
        .into_iter()
        .map(|on_other| {
            // slab poses are judged on the density plane, which is what a layout places
            let slab = PatchSource::Slab { vol, judge: (PlaneChoice::Density, &planes.density) };
            Ok(match yaw_on {
                YawOn::Voxels => slab,
                YawOn::Auto if on_other => slab,
                YawOn::Auto => PatchSource::Plane(PlaneChoice::Density, &planes.density),
                other => {
                    let choice = other.plane().unwrap_or_default();
                    PatchSource::Plane(choice, feature_plane(choice, planes, semantic)?)
                }
            })
        })
        .collect()
}

fn feature_plane<'a>(
    choice: PlaneChoice,
    planes: &'a FieldPlanes,
    semantic: &'a Option<PlaneImage>,
) -> Result<&'a PlaneImage> {
    match choice {
        PlaneChoice::Density => Ok(&planes.density),
        PlaneChoice::Color => Ok(&planes.color),
        PlaneChoice::Semantic => semantic.as_ref().ok_or_else(|| MiningError::MissingTensor {
            source_name: "field".into(),
            name: "semantic.decoder.weight".into(),
            purpose: "the semantic plane".into(),
        }),
    }
}

/// Mine `field_path` into the library folder `out` (see the module docs): load the field,
/// detect, group, pose, then write the library, the layout, the pictures and the reports
/// into a staging folder that replaces `out` at the end (or never, on an error or Ctrl-C).
pub fn mine(
    field_path: &Path,
    out: &Path,
    opts: &MineOptions,
    progress: &dyn Progress,
) -> Result<MineReport> {
    let t0 = std::time::Instant::now();
    if out.exists() && !opts.force {
        return Err(MiningError::OutputExists(out.display().to_string()));
    }
    let gt = match &opts.gt {
        Some(p) => Some(GtLayout::read(p).map_err(|e| MiningError::io("ground truth", e))?),
        None => None,
    };
    progress.step(0, STEPS, "loading the field");
    let loaded = load_field(field_path).map_err(|e| {
        MiningError::io(
            format!(
                "cannot read field {} (expected a .safetensors field file written by `assetfield train`)",
                field_path.display()
            ),
            e,
        )
    })?;
    let field = &loaded.field;
    let planes = field_planes(field)?;
    progress.step(1, STEPS, "evaluating the density volume");
    let vol = OpacityVolume::from_field(field)?;
    check_interrupt()?;
    let voxel = field.config.voxel_size().to_array();
    let orientation = crate::content::orientation(&vol, voxel);
    tracing::debug!(?orientation, "how the content lies");
    let content_note = orientation.and_then(|o| o.note());
    let off_the_ground = |e: MiningError| match &content_note {
        Some(note) => MiningError::OffTheGround { note: note.clone(), source: Box::new(e) },
        None => e,
    };
    let needs_semantic = [Some(opts.detect.on), opts.yaw_on.plane()]
        .contains(&Some(PlaneChoice::Semantic))
        || opts.group_on == GroupOn::Semantic;
    let semantic = if needs_semantic { Some(semantic_plane(field, &vol)?) } else { None };
    let cx = Context { opts, field, planes: &planes, vol: &vol, semantic: &semantic };

    progress.step(2, STEPS, "detecting objects");
    let mut dets = cx.detect(field_path).map_err(off_the_ground)?;
    check_interrupt()?;
    progress.step(3, STEPS, "grouping into categories"); // fixed: progress step
    let (grouping, copies, halves) = cx.group(&mut dets).map_err(off_the_ground)?;
    // after the grouping, which compares what the objects' cores look like (a fringe's
    // faint strokes differ from copy to copy); before the poses, so that each instance is
    // placed by the footprint its library entry holds
    let fringes = if opts.detect.stages.fringe {
        crate::fringe::grow_fringes(&mut dets, opts.detect.fringe_ring)
    } else {
        Vec::new()
    };
    check_interrupt()?;
    progress.step(4, STEPS, "matching templates (yaw)"); // fixed: progress step
    let (poses, pivots, margin) = cx.pose(&dets, &grouping).map_err(off_the_ground)?;
    check_interrupt()?;

    progress.step(5, STEPS, "writing the library"); // fixed: progress step
    let source = field_path.display().to_string();
    let found = Found { dets: &dets, grouping: &grouping, poses: &poses, pivots: &pivots };
    let (index, patches) = build_library(&source, field, &planes, &vol, &found, margin)?;
    let (index, shared) = with_shared_tensors(index, &loaded, &source)?;
    let staging = StagingDir::new(out, opts.force)?;
    let dir = staging.path();
    write_library_files(dir, &index, &patches, &shared)?;
    let metrics = gt.as_ref().map(|gt| score(&found, gt, opts.iou));
    let names = match (opts.gt_names, &metrics, &gt) {
        (true, Some(m), Some(gt)) => gt_keys(m, gt),
        _ => BTreeMap::new(),
    };
    let scene = field_path
        .file_stem()
        .map(|s| s.to_string_lossy().trim_end_matches(".ckpt").to_string())
        .unwrap_or_else(|| "mined".into());
    let world = planes.grid.world_rect();
    let script =
        layout_script(&index, &scene, world.to_array(), ".", &names, opts.own_patch_residual)?;
    let (text, layout_instances) = script_text_checked(&script, &out.join("layout.ron"))?;
    write_atomic(&dir.join("layout.ron"), text.as_bytes())?;
    check_interrupt()?;

    progress.step(6, STEPS, "pictures and metrics"); // fixed: progress step
    cx.write_pictures(dir, &found, margin)?;
    if let Some(m) = &metrics {
        write_metrics(dir, m, opts)?;
    }
    let removed = removed_lines(&dets);
    cx.write_report(dir, &source, &found, (&copies, &halves, &fringes), &removed)?;
    check_interrupt()?;
    let out = staging.commit()?;
    Ok(MineReport {
        out,
        model: field.config.kind.name().to_string(),
        detections: dets.detections.len(),
        supported: dets.detections.iter().filter(|d| d.parent.is_some()).count(),
        copies_cut: copies.len(),
        copies_pieces: copies.iter().map(|c| c.pieces).sum(),
        halves_joined: halves.len(),
        fringes_taken: fringes.len(),
        categories: grouping.n_categories,
        removed,
        floor: dets.floor.map(|f| f.z_top),
        threshold: dets.threshold,
        cut: grouping.cut.clone(),
        layout_instances,
        metrics,
        seconds: t0.elapsed().as_secs_f64(),
        content_note,
    })
}

/// What every stage of [`mine`] reads: the options, the field, and the planes and opacity
/// volume made from it.
struct Context<'a> {
    opts: &'a MineOptions,
    field: &'a Field,
    planes: &'a FieldPlanes,
    vol: &'a OpacityVolume,
    /// The semantic plane, where a stage works on it.
    semantic: &'a Option<PlaneImage>,
}

impl Context<'_> {
    /// The objects on the ground planes; an error that says what each filter dropped when
    /// none is left.
    fn detect(&self, field_path: &Path) -> Result<Detections> {
        let opts = self.opts;
        let det_feature = if opts.detect.needs_feature_plane() {
            Some(feature_plane(opts.detect.on, self.planes, self.semantic)?)
        } else {
            None
        };
        let dets = detect_with_color_axis(
            &self.planes.grid,
            self.vol,
            &self.planes.color,
            self.planes.color_axis.as_deref(),
            det_feature,
            &opts.detect,
        )?;
        if dets.detections.is_empty() {
            return Err(nothing_found(&dets, field_path));
        }
        Ok(dets)
    }

    /// The grouping of `dets` into categories, with the samples it counted (the copies test
    /// counts a piece cut from a detection on the same labels). Objects on different bases
    /// compare their profiles blurred by the field's vertical blur (`blur_levels`: a base is
    /// estimated within it), objects on one base their sharp ones ([`Profiles`]).
    fn group_all(&self, dets: &Detections) -> Result<(Grouping, Samples)> {
        let opts = self.opts;
        let texel = self.planes.grid.texel;
        let shapes: Vec<Shape> = dets.detections.iter().map(|d| Shape::of(d, texel)).collect();
        let samples = match opts.group_on.plane() {
            Some(p) => Samples::from_plane(dets, feature_plane(p, self.planes, self.semantic)?)?,
            None => Samples::from_voxels(self.field, self.vol, dets)?,
        };
        let sharp: Vec<Vec<f64>> = dets
            .detections
            .iter()
            .map(|d| vertical_profile(self.vol, d, dets.voxel_threshold))
            .collect();
        let soft: Vec<Vec<f64>> =
            sharp.iter().map(|p| blurred(p, opts.detect.blur_levels)).collect();
        let base: Vec<f32> = dets.detections.iter().map(|d| d.base).collect();
        let profiles = Profiles { blurred: &soft, sharp: &sharp, base: &base };
        let grouping = group_samples_profiled(
            &samples,
            dets.detections.len(),
            &shapes,
            profiles,
            &opts.group,
        )?;
        Ok((grouping, samples))
    }

    /// Group the detections. Halves of one object that recur together (two categories
    /// whose members pair up, touching alike) are joined, identical objects in contact (a
    /// detection that is k copies of another, alike in colours and in the sharp vertical
    /// profile) are split into k objects, and the grouping is redone after each.
    fn group(
        &self,
        dets: &mut Detections,
    ) -> Result<(Grouping, Vec<CopySplit>, Vec<JoinedHalves>)> {
        let (mut grouping, mut samples) = self.group_all(dets)?;
        let halves = if self.opts.group.join_halves {
            join_halves(dets, &grouping.category, self.opts.group.length_tolerance)
        } else {
            Vec::new()
        };
        if !halves.is_empty() {
            tracing::debug!(?halves, "halves joined");
            (grouping, samples) = self.group_all(dets)?;
        }
        let copies = if self.opts.group.split_copies {
            let g = &self.opts.group;
            let tau = dets.voxel_threshold;
            // the copies test compares objects by their own columns alone
            let own: Vec<Vec<f64>> =
                dets.detections.iter().map(|d| own_profile(self.vol, d, tau)).collect();
            // every detection's samples, for the colours of a piece cut from it
            let mut by_owner: Vec<Vec<usize>> = vec![Vec::new(); dets.detections.len()];
            for (i, &o) in samples.owner.iter().enumerate() {
                by_owner[o as usize].push(i);
            }
            let piece_colours = |piece: &Detection| {
                let book = grouping.codebook.as_ref()?;
                let inside = |i: &usize| {
                    samples.at.get(*i).is_some_and(|&(r, c)| {
                        let (r, c) = (r as usize, c as usize);
                        piece.rect.contains(r, c)
                            && piece.own.get(r - piece.rect.r0, c - piece.rect.c0)
                    })
                };
                book.histogram(&samples, by_owner.get(piece.id)?.iter().copied().filter(inside))
            };
            split_copies(
                dets,
                |i, j| {
                    grouping
                        .jsd
                        .get(i, j)
                        .unwrap_or(f64::INFINITY)
                        .max(profile_jsd(&own[i], &own[j]))
                },
                // a piece: its own colours and sharp profile against the other detection's
                |piece, j| {
                    let colour = piece_colours(piece)
                        .and_then(|h| histogram::jsd(&h, &grouping.histograms[j]).ok())
                        .unwrap_or(f64::INFINITY);
                    colour.max(profile_jsd(&own_profile(self.vol, piece, tau), &own[j]))
                },
                g.copy_divergence,
                g.length_tolerance,
            )
        } else {
            Vec::new()
        };
        if !copies.is_empty() {
            grouping = self.group_all(dets)?.0;
        }
        Ok((grouping, copies, halves))
    }

    /// Templates, every object's yaw and position against its template, turned about the
    /// centre of its ground contact (a lamp about its pole); and the patches' margin.
    fn pose(&self, dets: &Detections, grouping: &Grouping) -> Result<(Poses, Vec<Vec2>, usize)> {
        let opts = self.opts;
        let mut pose_opts = opts.pose.clone();
        for (c, d) in &opts.templates {
            pose_opts.templates.push((parse_category(c, grouping.n_categories)?, *d));
        }
        let sources = yaw_sources(
            opts.yaw_on,
            dets,
            &grouping.category,
            self.planes,
            self.semantic,
            self.vol,
        )?;
        let mut poses = estimate_poses(
            &self.planes.grid,
            dets,
            &sources,
            &grouping.category,
            &grouping.distance,
            &pose_opts,
        )?;
        let pivots = contact_pivots(self.vol, dets, opts.pose.yaw.max_offset);
        poses.to_pivots(dets, &grouping.category, &pivots);
        Ok((poses, pivots, pose_opts.margin))
    }

    /// `boxes.png` (the detections over the evidence map, by category) and
    /// `categories.png` (the template patches over the colour plane's PCA).
    fn write_pictures(&self, dir: &Path, found: &Found<'_>, margin: usize) -> Result<()> {
        let Found { dets, grouping, poses, .. } = *found;
        let grid = self.planes.grid;
        let scale = picture_scale(grid.rows, grid.cols, 900); // fixed: picture size in pixels
        let boxes: Vec<BoxMark> = dets
            .detections
            .iter()
            .map(|d| BoxMark {
                world: d.world,
                category: grouping.category[d.id],
                label: d.id.to_string(),
                supported: d.parent.is_some(),
            })
            .collect();
        let legend: Vec<String> = (0..grouping.n_categories)
            .map(|k| {
                let n = grouping.category.iter().filter(|&&c| c == k).count();
                format!("{}: {n} (template {})", category_name(k), entry_name(poses.templates[k]))
            })
            .collect();
        boxes_picture(&grid, &evidence_colors(dets), scale, &boxes, &legend)
            .save_png(&dir.join("boxes.png"))?;
        let color = &self.planes.color;
        let colors = pca_colors(&color.data, grid.rows * grid.cols, color.ch);
        let tiles: Vec<TemplateTile> = poses
            .templates
            .iter()
            .enumerate()
            .map(|(k, &t)| {
                let d = &dets.detections[t];
                let patch = PatchRect::around(d.rect, margin);
                TemplateTile {
                    name: category_name(k),
                    patch,
                    mask: mask_in_patch(d, &d.own, patch),
                }
            })
            .collect();
        let cat_pic: Canvas = categories_picture(&grid, &colors, &tiles);
        cat_pic.save_png(&dir.join("categories.png"))?;
        Ok(())
    }

    /// `mining.json`: what was found and dropped, the grouping's distances and cut, the
    /// options, and what every file of the folder holds.
    fn write_report(
        &self,
        dir: &Path,
        source: &str,
        found: &Found<'_>,
        (copies, halves, fringes): (&[CopySplit], &[JoinedHalves], &[FringeGrowth]),
        removed: &[String],
    ) -> Result<()> {
        let Found { dets, grouping, .. } = *found;
        let grid = self.planes.grid;
        let matrix = |m: &DistanceMatrix| -> Vec<Vec<f64>> {
            (0..m.n()).map(|i| (0..m.n()).map(|j| m.get(i, j).unwrap_or(0.0)).collect()).collect()
        };
        let report = serde_json::json!({
            "field": source,
            "model": self.field.config.kind.name(),
            "plane_resolution": [grid.cols, grid.rows],
            "texel_size": grid.texel,
            "floor": dets.floor,
            "evidence_threshold": dets.threshold,
            "voxel_threshold": dets.voxel_threshold,
            "detections": dets.detections.len(),
            "removed_as_background": removed,
            "removed": dets.removed,
            "copies_split": copies,
            "halves_joined": halves,
            "fringes_taken": fringes,
            "detect_preset": self.opts.detect.preset.name(),
            "categories": grouping.n_categories,
            "cut": grouping.cut,
            "merge_heights": grouping.merges.iter().map(|m| m.distance).collect::<Vec<_>>(),
            "dendrogram": grouping.merges.iter().map(|m| (m.a, m.b, m.distance)).collect::<Vec<_>>(),
            "distance_matrix": matrix(&grouping.distance),
            "jsd_matrix": matrix(&grouping.jsd),
            "options": self.opts,
            "files": [
                "index.ron: the library index (assetfield-library/1)",
                "patches.safetensors: ENTRY.density / ENTRY.color / ENTRY.mask per entry, container.* (planes with the objects removed)",
                "shared.safetensors: vertical axes, basis, guidance MLPs and decoders, config in the metadata",
                "layout.ron: the mined layout (layout language, library assets)",
                "boxes.png: detections over the evidence map, coloured by category, numbered",
                "categories.png: template patches (colour plane PCA)",
                "metrics.json: with --gt only",
            ],
        });
        let text =
            serde_json::to_string_pretty(&report).map_err(|e| MiningError::io("report", e))?;
        write_atomic(&dir.join("mining.json"), text.as_bytes())?;
        Ok(())
    }
}

/// The error of a detection that found nothing: what each filter took, so that the user
/// knows which one to question.
fn nothing_found(dets: &Detections, field_path: &Path) -> MiningError {
    let mut by_filter: Vec<(&str, usize)> = Vec::new();
    for r in &dets.removed {
        match by_filter.iter_mut().find(|(f, _)| *f == r.reason.filter()) {
            Some((_, n)) => *n += 1,
            None => by_filter.push((r.reason.filter(), 1)),
        }
    }
    let dropped = if by_filter.is_empty() {
        "no region was left after the first K-means and the minimum area (--min-area, \
         texels)"
            .to_string()
    } else {
        let list: Vec<String> = by_filter.iter().map(|(f, n)| format!("{n} by {f}")).collect();
        format!(
            "{} region(s) dropped: {}; `--no-filter FILTER` keeps what a filter drops",
            dets.removed.len(),
            list.join(", ")
        )
    };
    MiningError::InvalidParameter {
        name: "detection",
        reason: format!(
            "no object found in {} (evidence threshold {:.3}; {dropped})",
            field_path.display(),
            dets.threshold,
        ),
    }
}

/// The shared file of the library mined from `loaded` (its non-plane tensors, and what
/// rendering the library needs besides: the background the field was trained on and the
/// ground alignment of its dataset's cameras), and the index recording its hash and names.
fn with_shared_tensors(
    mut index: LibraryIndex,
    loaded: &LoadedField,
    source: &str,
) -> Result<(LibraryIndex, TensorFile)> {
    let mut shared = shared_tensors(&loaded.field, source)?;
    assetfield_field::eval::FieldInfo {
        background: loaded.info.background,
        ground_transform: loaded.info.ground_transform,
        dataset: loaded.info.dataset.clone(),
        ..Default::default()
    }
    .write(&mut shared)
    .map_err(|e| MiningError::io("cannot describe the shared tensors", e))?;
    index.shared.hash = content_hash(&shared);
    index.shared.tensors = shared.names().map(str::to_string).collect();
    Ok((index, shared))
}

/// The mining result scored against a ground truth.
fn score(found: &Found<'_>, gt: &GtLayout, iou: f32) -> Metrics {
    let Found { dets, grouping, poses, .. } = *found;
    let preds: Vec<Predicted> = dets
        .detections
        .iter()
        .map(|d| Predicted {
            world: d.world,
            category: grouping.category[d.id],
            template: poses.templates[grouping.category[d.id]],
            yaw_rel: poses.poses[d.id].yaw_deg,
            position: poses.poses[d.id].position,
        })
        .collect();
    evaluate(&preds, gt, iou)
}

/// Entry names to the keys of the ground-truth objects they matched (`--gt-names`).
fn gt_keys(m: &Metrics, gt: &GtLayout) -> BTreeMap<String, String> {
    let mut names = BTreeMap::new();
    for inst in &m.per_instance {
        if let Some(g) = inst.gt_id.and_then(|id| gt.instances.iter().find(|g| g.id == id)) {
            names.insert(entry_name(inst.detection), g.key.clone());
        }
    }
    names
}

/// `metrics.json`: the scores, their summary and the ground truth's file.
fn write_metrics(dir: &Path, m: &Metrics, opts: &MineOptions) -> Result<()> {
    let mut v = serde_json::to_value(m).map_err(|e| MiningError::io("metrics", e))?;
    if let Some(o) = v.as_object_mut() {
        o.insert("summary".into(), serde_json::Value::String(m.summary()));
        o.insert(
            "ground_truth_file".into(),
            serde_json::Value::String(
                opts.gt.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
            ),
        );
    }
    let text = serde_json::to_string_pretty(&v).map_err(|e| MiningError::io("metrics", e))?;
    write_atomic(&dir.join("metrics.json"), text.as_bytes())?;
    Ok(())
}

/// One line per region detection dropped: its box and why.
fn removed_lines(dets: &Detections) -> Vec<String> {
    dets.removed
        .iter()
        .map(|r| {
            let b = r.world.to_array();
            format!(
                "[{:.2}, {:.2}, {:.2}, {:.2}]: {} (filter {})",
                b[0],
                b[1],
                b[2],
                b[3],
                r.reason,
                r.reason.filter()
            )
        })
        .collect()
}

/// What mining found in a field: the detections, their grouping, poses and pivots.
struct Found<'a> {
    dets: &'a Detections,
    grouping: &'a Grouping,
    poses: &'a Poses,
    pivots: &'a [Vec2],
}

/// The library index and patch tensors of a mining result (the shared part is separate);
/// patches reach `margin` texels past each box.
fn build_library(
    source: &str,
    field: &Field,
    planes: &FieldPlanes,
    vol: &OpacityVolume,
    found: &Found<'_>,
    margin: usize,
) -> Result<(LibraryIndex, TensorFile)> {
    let Found { dets, grouping, poses, pivots } = *found;
    let grid = planes.grid;
    let floor = floor_texels(vol, dets.floor.as_ref()).filter(|f| f.len() == grid.rows * grid.cols);
    let floor = floor.as_deref();
    let mut patches = TensorFile::new();
    patches.set_meta("format", FORMAT);
    patches.set_meta("source", source);
    // the ring each entry's patch carries and the container fills around each object: the
    // field blurs an edge `blur_levels` texels to either side, so an object's blur reaches
    // twice that past a footprint cut inside its blurred edge (with the 2 texels of the
    // composer's old default, the object's blur beyond them stayed in the container; against
    // the ground 7-10 texels out, beyond this halo, `container_residue` on the basis's
    // 6000-iteration libraries counted 40 of 271 vacated footprints over 10% above it, 25
    // with this halo and each object filled from its own ground)
    let halo = 2 * dets.blur_levels.max(1);
    let mut entries = Vec::with_capacity(dets.detections.len());
    for d in &dets.detections {
        let name = entry_name(d.id);
        // the patch holds the ring around the mask (the box's margin at least the halo)
        let p = PatchRect::around(d.rect, margin.max(halo));
        let dens = padded_crop(&planes.density, p)?;
        let col = padded_crop(&planes.color, p)?;
        let mask = mask_in_patch(d, &d.own, p);
        patches.insert_f32(format!("{name}.density"), &[p.rows, p.cols, dens.ch], dens.data);
        patches.insert_f32(format!("{name}.color"), &[p.rows, p.cols, col.ch], col.data);
        patches.insert_u8(
            format!("{name}.mask"),
            &[p.rows, p.cols],
            mask.data.iter().map(|&b| u8::from(b)).collect(),
        );
        let cat = grouping.category[d.id];
        let pose = poses.poses[d.id];
        let size = d.world.size();
        entries.push(Entry {
            density: format!("{name}.density"),
            color: format!("{name}.color"),
            mask: format!("{name}.mask"),
            name,
            category: category_name(cat),
            kind: if poses.templates[cat] == d.id {
                EntryKind::Template
            } else {
                EntryKind::Instance
            },
            patch_size: (p.rows, p.cols),
            extent: (size.x, size.y, (d.top - d.base).max(0.0)),
            base: if d.parent.is_some() { d.base } else { 0.0 },
            source_box: d.world.to_array(),
            position: (pose.position.x, pose.position.y),
            pivot: pivots.get(d.id).map(|p| (p.x, p.y)),
            yaw_deg: pose.yaw_deg,
            residual: pose.residual,
            matched_on: poses.matched_on.get(cat).map(|k| k.to_string()),
            supported_by: d.parent.map(entry_name),
            source: 0,
        });
    }
    let categories = (0..grouping.n_categories)
        .map(|k| Category {
            name: category_name(k),
            template: entry_name(poses.templates[k]),
            members: (0..dets.detections.len())
                .filter(|&i| grouping.category[i] == k)
                .map(entry_name)
                .collect(),
        })
        .collect();
    // the container: planes with every object and its halo filled with the median of the
    // empty ground around it, the floor from the floor and empty space from empty space
    // (on the basis's 6000-iteration libraries, `container_residue`: 89 of 251 vacated
    // footprints held over 10% more column opacity than the ground around them when the
    // fill copied the nearest texel, 25 with the median, with a halo of 2)
    let (rows, cols) = (grid.rows, grid.cols);
    let mut objects = Mask::empty(rows, cols)?;
    for d in &dets.detections {
        objects.paste_at(&d.footprint, d.rect.r0, d.rect.c0);
    }
    // (the halo is the ring each entry's patch carries with it when composed, so an entry
    // placed back where it was mined restores the trained planes; the ring of samples is the
    // field's blur)
    let zone = dilate(&objects, halo)?;
    let ring = dets.blur_levels.max(1);
    let fill = RingFill::around_objects(&zone, &objects, floor, ring)?;
    let (dens, col) = (fill.apply(&planes.density)?, fill.apply(&planes.color)?);
    patches.insert_f32("container.density", &[rows, cols, dens.ch], dens.data);
    patches.insert_f32("container.color", &[rows, cols, col.ch], col.data);
    patches.insert_u8(
        "container.mask",
        &[rows, cols],
        zone.data.iter().map(|&b| u8::from(b)).collect(),
    );
    let index = LibraryIndex {
        format: FORMAT.into(),
        sources: vec![source.to_string()],
        model: match field.config.kind {
            ModelKind::Standard => "s",
            ModelKind::Integrated => "i",
            ModelKind::Vm => "vm",
        }
        .into(),
        texel_size: (grid.texel[0], grid.texel[1]),
        channels: (planes.density.ch, planes.color.ch),
        patches: PATCHES_FILE.into(),
        shared: SharedRef { file: SHARED_FILE.into(), hash: String::new(), tensors: Vec::new() },
        categories,
        entries,
        containers: vec![
            Container::named("container", (rows, cols), grid.world_rect().to_array(), 0)
                .with_halo(halo),
        ],
    };
    Ok((index, patches))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_preset_runs_only_the_papers_steps() {
        let paper = MineOptions::preset(crate::detect::Preset::Paper);
        assert_eq!(paper.detect, DetectParams::paper());
        assert_eq!(paper.yaw_on, YawOn::Density);
        assert!(!paper.group.split_copies && paper.group.profile_weight == 0.0);
        // the paper groups on the colour plane; the default on the objects' own voxels
        assert_eq!(paper.group_on, GroupOn::Color);
        let default = MineOptions::preset(crate::detect::Preset::Default);
        assert_eq!(default.detect, DetectParams::default());
        assert!(default.group.split_copies && default.group.profile_weight > 0.0);
        assert_eq!(default.group_on, GroupOn::Voxels);
    }

    #[test]
    fn background_fill_copies_the_nearest_outside_texel() {
        let plane = PlaneImage::from_fn(3, 5, 1, |_, c, _| c as f32).unwrap();
        let mask = Mask::from_fn(3, 5, |_, c| (1..=3).contains(&c));
        let f = fill_from_background(&plane, &mask).unwrap();
        assert_eq!(f.channel(0).unwrap()[..5], [0.0, 0.0, 0.0, 4.0, 4.0]);
        assert!(fill_from_background(&plane, &Mask::empty(2, 2).unwrap()).is_err());
    }

    #[test]
    fn background_fill_keeps_floor_and_empty_space_apart() {
        // columns 0..=2 floor (value 1), 3..=5 empty (value 0); an object over columns 2..=3
        let plane = PlaneImage::from_fn(3, 6, 1, |_, c, _| if c <= 2 { 1.0 } else { 0.0 }).unwrap();
        let mask = Mask::from_fn(3, 6, |_, c| (2..=3).contains(&c));
        let class: Vec<bool> = (0..18).map(|i| i % 6 <= 2).collect();
        let f = fill_from_background_by_class(&plane, &mask, Some(&class)).unwrap();
        assert_eq!(f.channel(0).unwrap()[..6], [1.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
        // without classes, the nearest texel wins whichever it is
        let g = fill_from_background(&plane, &mask).unwrap();
        assert_eq!(g.channel(0).unwrap()[..6], [1.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
        // a class with no unmasked texel falls back to the nearest of any class
        let all_floor = vec![true; 18];
        let mask2 = Mask::from_fn(3, 6, |_, c| c <= 2);
        let h = fill_from_background_by_class(&plane, &mask2, Some(&all_floor)).unwrap();
        assert_eq!(h.channel(0).unwrap()[..6], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert!(fill_from_background_by_class(&plane, &mask, Some(&class[..5])).is_err());
    }

    #[test]
    fn a_vacated_footprint_takes_the_median_of_the_ground_around_it_not_what_touches_its_edge() {
        // ground of value 1 with a little texture, an object (value 5) over rows 4..8 and
        // columns 4..8, and a kerb (value 9) touching its left edge at row 5
        let plane = PlaneImage::from_fn(12, 12, 1, |r, c, _| {
            if (4..8).contains(&r) && (4..8).contains(&c) {
                5.0
            } else if r == 5 && c == 3 {
                9.0
            } else {
                1.0 + 0.01 * ((r + c) % 3) as f32
            }
        })
        .unwrap();
        let mask = Mask::from_fn(12, 12, |r, c| (4..8).contains(&r) && (4..8).contains(&c));
        // the nearest texel carries the kerb across the footprint in a streak
        let nearest = fill_from_background(&plane, &mask).unwrap();
        assert_eq!(nearest.channel(0).unwrap()[5 * 12 + 4], 9.0);
        let fill = |plane: &PlaneImage, mask: &Mask, class: Option<&[bool]>, ring: usize| {
            RingFill::around_objects(mask, mask, class, ring).unwrap().apply(plane).unwrap()
        };
        let f = fill(&plane, &mask, None, 3);
        let v = f.channel(0).unwrap();
        for r in 4..8 {
            for c in 4..8 {
                assert!((v[r * 12 + c] - 1.01).abs() < 1e-6, "({r}, {c}): {}", v[r * 12 + c]);
            }
        }
        // outside the mask nothing changes
        assert_eq!(v[5 * 12 + 3], 9.0);
        // two regions take their own rings; classes keep the floor from empty space
        let plane = PlaneImage::from_fn(4, 12, 1, |_, c, _| if c < 6 { 1.0 } else { 0.0 }).unwrap();
        let mask = Mask::from_fn(4, 12, |_, c| c == 2 || c == 6 || c == 9);
        let class: Vec<bool> = (0..48).map(|i| i % 12 < 6).collect();
        let f = fill(&plane, &mask, Some(&class), 2);
        let row = &f.channel(0).unwrap()[..12];
        assert_eq!((row[2], row[6], row[9]), (1.0, 0.0, 0.0));
    }

    #[test]
    fn what_lies_under_an_object_is_the_ground_around_it() {
        // a floor (value 1) on columns 0..8 and empty space (0) beyond; a pedestal table
        // beyond the floor's edge (columns 11..14), whose base is opaque at the floor's
        // levels (its own texels read as floor), and a cabinet on the floor (columns 2..5)
        // under which the field has no floor (its texels read as empty)
        let (rows, cols) = (6, 16);
        let on_floor = |c: usize| c < 8;
        let table = |r: usize, c: usize| (1..5).contains(&r) && (11..14).contains(&c);
        let cabinet = |r: usize, c: usize| (1..5).contains(&r) && (2..5).contains(&c);
        let plane = PlaneImage::from_fn(rows, cols, 1, |r, c, _| {
            if table(r, c) || cabinet(r, c) { 7.0 } else { f32::from(u8::from(on_floor(c))) }
        })
        .unwrap();
        let mask = Mask::from_fn(rows, cols, |r, c| table(r, c) || cabinet(r, c));
        let class: Vec<bool> = (0..rows * cols)
            .map(|i| {
                (on_floor(i % cols) || table(i / cols, i % cols)) && !cabinet(i / cols, i % cols)
            })
            .collect();
        let under = floor_under(&mask, &class, 2).unwrap();
        for r in 1..5 {
            assert!(!under[r * cols + 12] && under[r * cols + 3], "row {r}");
        }
        let f =
            RingFill::around_objects(&mask, &mask, Some(&class), 2).unwrap().apply(&plane).unwrap();
        let v = f.channel(0).unwrap();
        for r in 1..5 {
            assert_eq!((v[r * cols + 3], v[r * cols + 12]), (1.0, 0.0), "row {r}");
        }
        // a table over the floor's edge (a notch in the floor in view): the edge continues
        // under it
        let edge = Mask::from_fn(rows, cols, |r, c| (1..5).contains(&r) && (6..10).contains(&c));
        let all: Vec<bool> = (0..rows * cols).map(|i| edge.data[i] || on_floor(i % cols)).collect();
        let under = floor_under(&edge, &all, 2).unwrap();
        assert_eq!((under[2 * cols + 6], under[2 * cols + 9]), (true, false));
        // classes as areas: a faint floor's texels under the threshold (every third) are the
        // floor's, specks of haze over it beyond the floor (every fifth) are empty space's
        let noisy: Vec<bool> = (0..rows * cols)
            .map(|i| if on_floor(i % cols) { i % 3 != 0 } else { i % 5 == 0 })
            .collect();
        let none = Mask::empty(rows, cols).unwrap();
        let areas = class_areas(&none, &noisy, 2);
        for i in 0..rows * cols {
            let c = i % cols;
            if !(7..=8).contains(&c) {
                assert_eq!(areas[i], on_floor(c), "texel {i}");
            }
        }
    }

    #[test]
    fn objects_whose_halos_touch_are_filled_from_their_own_ground() {
        // ground of value 1 on the left half and 3 on the right; two objects (columns 4 and
        // 7, value 9) whose halos of 1 join into one region across the boundary
        let plane = PlaneImage::from_fn(5, 12, 1, |r, c, _| {
            if r == 2 && (c == 4 || c == 7) {
                9.0
            } else if c < 6 {
                1.0
            } else {
                3.0
            }
        })
        .unwrap();
        let objects = Mask::from_fn(5, 12, |r, c| r == 2 && (c == 4 || c == 7));
        let zone = Mask::from_fn(5, 12, |r, c| (1..=3).contains(&r) && (3..=8).contains(&c));
        let v = |f: &PlaneImage, r: usize, c: usize| f.channel(0).unwrap()[r * 12 + c];
        // one region (the zone as one object): both objects take the median of the whole ring
        // (left and right ground)
        let one = RingFill::around_objects(&zone, &zone, None, 2).unwrap().apply(&plane).unwrap();
        assert_eq!(v(&one, 2, 4), v(&one, 2, 7));
        // one region per object: each takes its own side's ground
        let own =
            RingFill::around_objects(&zone, &objects, None, 2).unwrap().apply(&plane).unwrap();
        assert_eq!((v(&own, 2, 4), v(&own, 2, 7)), (1.0, 3.0));
        assert_eq!((v(&own, 1, 3), v(&own, 3, 8)), (1.0, 3.0));
    }

    #[test]
    fn categories_parse() {
        assert_eq!(parse_category("cat2", 3).unwrap(), 2);
        assert_eq!(parse_category("1", 3).unwrap(), 1);
        assert!(parse_category("cat3", 3).is_err());
        assert!(parse_category("chair", 3).is_err());
    }
}
