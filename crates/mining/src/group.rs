//! Unsupervised grouping of the detected objects into categories (paper Sec. 3.3).
//!
//! Every detection contributes [`Samples`]: by default ([`Samples::from_voxels`]) the
//! colours the field decodes on its own surface voxels, so that copies look alike whatever
//! stands under them; with the paper ([`Samples::from_plane`]) the features of the colour
//! plane (for I-AssetField the integrated RGB plane) at its own texels, weighted by their
//! opacity, each describing its whole column, the floor under the object included. The
//! samples of all objects, and only those (empty floor must not dominate the codebook), are
//! discretised with K-means. Every detection becomes a histogram of labels over its own
//! samples; two detections are compared with the Jensen-Shannon divergence of their
//! histograms **plus a shape term**, since objects with the same colours but different
//! shapes (two table sizes, a chair and a stool of the same red, a long dresser and a round
//! table of one wood) have near-identical histograms:
//!
//! ```text
//! d(i, j) = JSD(h_i, h_j)
//!         + w * max(0, |ln A_i/A_j| - 2 tol, |ln E_i/E_j| - 2 tol, |ln H_i/H_j| - tol)
//!         + v * JSD(p_i, p_j)
//! ```
//!
//! with `A` the footprint area, `E` the footprint's elongation (its long side over its short
//! side, from its second moments: [`elongation`]), `w` the shape weight and `tol` a dead zone
//! for reconstruction noise (twice it for an area and an elongation, which carry the noise of
//! two lengths), `p` the vertical profile (how the object's occupied voxels spread over the
//! levels above its base) and `v` its weight ([`GroupOptions::profile_weight`]). The height
//! `H` (top above base) is compared only where no profile is (the paper preset): the profile
//! holds the height and weighs every level by what occupies it, where the top is one level
//! that a few columns decide (a plant left undetected on a coffee table, haze over a sofa
//! made copies 0.3-0.7 apart at 8000 iterations). Average-linkage agglomerative clustering
//! follows; the dendrogram is cut at a given number of categories, at a distance, or
//! automatically at [`GroupOptions::min_separation`] ([`separation_cut`]): two groups of
//! objects further apart than the reconstruction noise between copies of one object are two
//! categories, however far other groups lie. The cut of highest mean *silhouette* among
//! those separated by the minimum ([`silhouette_cut`], [`GroupCut::Silhouette`]) and the
//! largest ratio of consecutive merge heights ([`auto_cut`], [`GroupCut::LargestRatio`])
//! are kept: both compare merge heights with each other, so one far group can decide them
//! for everyone.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::agglomerative::{Cut, Dendrogram, DistanceMatrix, Linkage, Merge, linkage};
use crate::detect::Detections;
use crate::error::{MiningError, Result};
use crate::histogram::jsd_matrix;
use crate::image::PlaneImage;
use crate::kmeans::{KMeansOptions, kmeans};
use crate::planes::OpacityVolume;
use assetfield_field::Field;
use assetfield_field::model::ColorWork;
use glam::Vec3;

/// Where to cut the dendrogram.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub enum GroupCut {
    /// Every merge below [`GroupOptions::min_separation`] applied, none above: groups of
    /// objects further apart than the reconstruction noise between copies of one object
    /// are categories.
    #[default]
    Separation,
    /// The cut of highest mean silhouette among those separated by at least
    /// [`GroupOptions::min_separation`] ([`silhouette_cut`]).
    Silhouette,
    /// The largest ratio between consecutive merge heights ([`auto_cut`]).
    LargestRatio,
    /// Exactly this many categories.
    Categories(usize),
    /// Merge everything closer than this distance.
    Distance(f64),
}

/// Parameters of [`group_samples`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupOptions {
    /// Number of K-means labels the samples' features are discretised into.
    pub labels: usize,
    /// Soft label memberships in the histograms (robust to a colour split between two
    /// labels); false = hard labels as in the paper.
    pub soft: bool,
    pub cut: GroupCut,
    /// Linkage of the agglomerative clustering (average in the paper).
    pub linkage: Linkage,
    /// Weight of the shape term (0: JSD only, as in the paper).
    pub shape_weight: f64,
    /// Weight of the vertical-profile term: the Jensen-Shannon divergence (bits) of how two
    /// objects' occupied voxels spread over the levels above their bases (a round table and
    /// a plant of one size and one colour differ there). 0: off, as in the paper.
    #[serde(default = "one")]
    pub profile_weight: f64,
    /// Dead zone of a length ratio in the shape term (log ratio; 0.15 tolerates 16%, the
    /// reconstruction noise between two instances of one object): heights (where no
    /// vertical profile is compared) within it, footprint areas within twice it (an area is
    /// a length squared; it was a value of its own, 0.3, twice this one).
    #[serde(alias = "height_tolerance")]
    pub length_tolerance: f64,
    /// Smallest merge height (JSD in bits plus the shape term) that can separate categories
    /// in the automatic cuts and across scenes ([`crate::regroup`]): two groups of objects
    /// closer than this are one category. Between instances of one object the distance is
    /// reconstruction noise, which grows where the field is young or the renderer shades
    /// copies differently (0.15-0.3 on the basis: a short run's stools, another renderer's
    /// crates; a few potted flowers further still); from a cut of 0.35 up, distinct
    /// categories of the basis merge.
    pub min_separation: f64,
    /// The most two copies of one object differ in colour or in vertical profile (JSD in
    /// bits, each term alone): [`crate::copies`] cuts a detection into copies of another, or
    /// into two other objects in contact (each piece against its object), only within it.
    /// Stricter than [`Self::min_separation`]: a false copy is a false object, where a
    /// category split only costs the grouping.
    #[serde(default = "copy_divergence")]
    pub copy_divergence: f64,
    /// At most this many samples fit the K-means codebook (the rest are only labelled).
    pub max_samples: usize,
    /// Cut a detection that is, in shape and colour, `k` copies of another into `k`
    /// objects ([`crate::copies`]: identical objects in contact).
    #[serde(default = "yes")]
    pub split_copies: bool,
    /// Join two categories whose members pair up one to one, each touching its partner in
    /// the same placement, into one object per pair ([`crate::halves`]: a two-tone object
    /// the colour split cut in two, every copy the same way).
    #[serde(default = "yes")]
    pub join_halves: bool,
    pub seed: u64,
}

impl Default for GroupOptions {
    fn default() -> Self {
        GroupOptions {
            labels: 24, // tuned: group.labels
            soft: true,
            cut: GroupCut::Separation,
            linkage: Linkage::Average,
            shape_weight: 1.0,
            profile_weight: 1.0,
            length_tolerance: 0.15, // tuned: group.length_tolerance
            min_separation: 0.25,   // tuned: group.min_separation
            copy_divergence: copy_divergence(),
            max_samples: 40_000, // fixed: a sample budget (80,000 mined the same)
            split_copies: true,
            join_halves: true,
            seed: crate::kmeans::DEFAULT_SEED,
        }
    }
}

fn copy_divergence() -> f64 {
    0.12 // tuned: group.copy_divergence
}

fn yes() -> bool {
    true
}

fn one() -> f64 {
    1.0
}

/// The result of [`group_samples`].
#[derive(Debug, Clone)]
pub struct Grouping {
    /// Label histogram of every detection (over its own samples).
    pub histograms: Vec<Vec<f64>>,
    /// The labels the histograms count (none without detections): a piece of a detection
    /// is counted on them too ([`Codebook::histogram`]).
    pub codebook: Option<Codebook>,
    /// JSD between the histograms.
    pub jsd: DistanceMatrix,
    /// The distance actually clustered (JSD plus the shape term).
    pub distance: DistanceMatrix,
    pub merges: Vec<Merge>,
    /// Category of every detection, `0..n_categories`, in order of first appearance.
    pub category: Vec<usize>,
    pub n_categories: usize,
    /// How the dendrogram was cut, for the report.
    pub cut: String,
}

/// Size of a detection for the shape term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Shape {
    /// Area of the convex hull of the footprint (rotation invariant, and forgiving to
    /// footprints with gaps).
    pub area: f32,
    /// Height of the top above the base ([`crate::detect::Detection::shape_top`]: haze
    /// specks above the object do not count), compared only where no vertical profile is.
    pub height: f32,
    /// How much longer than wide the footprint is ([`elongation`]: from the second moments of
    /// its texels, rotation invariant, 1 for a square or a disc): a long dresser and a round
    /// table of one height and finish differ here. 1 (no term) where unknown.
    #[serde(default = "one_f32")]
    pub elongation: f32,
}

fn one_f32() -> f32 {
    1.0
}

impl Shape {
    /// A shape of `area` and `height` whose footprint is as long as wide.
    pub fn round(area: f32, height: f32) -> Shape {
        Shape { area, height, elongation: 1.0 }
    }

    /// The shape of a detection on a grid with the given texel size.
    pub fn of(d: &crate::detect::Detection, texel: [f32; 2]) -> Shape {
        Shape::of_footprint(&d.footprint, texel, (d.shape_top - d.base).max(0.0))
    }

    /// The shape of a footprint (texels of `texel` world size) rising `height` above its base.
    pub fn of_footprint(footprint: &crate::image::Mask, texel: [f32; 2], height: f32) -> Shape {
        Shape {
            area: hull_area(footprint) * texel[0] * texel[1],
            height,
            elongation: elongation(footprint),
        }
    }
}

/// How much longer a footprint is than wide: the square root of the ratio of the principal
/// second moments of its texels (1 for a disc or a square, 3 for a solid 3 x 1 rectangle;
/// at least 1; 1 for an empty mask). Moments weigh every texel, so a leaf or a blurred
/// corner moves it less than it moves a bounding rectangle. Measured in texels: the planes'
/// texels are square to within the rounding of the grid's size.
pub fn elongation(mask: &crate::image::Mask) -> f32 {
    let (mut n, mut sr, mut sc) = (0f64, 0f64, 0f64);
    for r in 0..mask.rows {
        for c in 0..mask.cols {
            if mask.get(r, c) {
                n += 1.0;
                sr += r as f64;
                sc += c as f64;
            }
        }
    }
    if n == 0.0 {
        return 1.0;
    }
    let (mr, mc) = (sr / n, sc / n);
    // a texel is a unit square: each adds its own second moment, 1/12 along each axis
    let (mut vrr, mut vcc, mut vrc) = (1.0 / 12.0, 1.0 / 12.0, 0f64); // fixed: a unit square's second moment
    for r in 0..mask.rows {
        for c in 0..mask.cols {
            if mask.get(r, c) {
                let (dr, dc) = (r as f64 - mr, c as f64 - mc);
                vrr += dr * dr / n;
                vcc += dc * dc / n;
                vrc += dr * dc / n;
            }
        }
    }
    let (big, small) = crate::content::symmetric_2x2_eigenvalues(vrr, vrc, vcc);
    (big / small.max(1e-12)).sqrt().max(1.0) as f32
}

/// Area (in texels) of the convex hull of the cells of a mask (each set texel a unit square).
pub fn hull_area(mask: &crate::image::Mask) -> f32 {
    let hull = mask.corner_hull(0, 0);
    // fixed: a polygon has 3 corners
    if hull.len() < 3 {
        return 0.0;
    }
    let mut twice = 0i64;
    for i in 0..hull.len() {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        twice += a.0 * b.1 - b.0 * a.1;
    }
    (twice.abs() as f32) * 0.5
}

/// The shape term (before its weight): how far the log ratio of the footprint areas or of
/// the elongations exceeds twice the length tolerance (an area is a length squared, an
/// elongation a ratio of two lengths), or, with `height`, that of the heights the tolerance;
/// the largest of them. `height` is for groupings without vertical profiles, which hold
/// the height more robustly (see the module docs).
pub fn shape_distance(a: Shape, b: Shape, length_tol: f64, height: bool) -> f64 {
    let lr = |x: f32, y: f32| (f64::from(x.max(1e-6)) / f64::from(y.max(1e-6))).ln().abs();
    // an elongation is a ratio of two lengths: its noise is two lengths', as an area's
    let footprint = (lr(a.area, b.area) - 2.0 * length_tol)
        .max(lr(a.elongation, b.elongation) - 2.0 * length_tol)
        .max(0.0);
    if height { footprint.max(lr(a.height, b.height) - length_tol) } else { footprint }
}

/// Number of merges to apply: the cut lies where the next merge height is largest relative
/// to the previous one, `(h[g] + eps) / (h[g-1] + eps)` with `h[-1] = 0` and `eps` =
/// `min_separation`, among merges at least `min_separation` high. No such merge: one
/// category (every merge applied).
pub fn auto_cut(merges: &[Merge], min_separation: f64) -> usize {
    let h: Vec<f64> = merges.iter().map(|m| m.distance).collect();
    let eps = min_separation.max(1e-9);
    let mut best: Option<(usize, f64)> = None;
    for g in 0..h.len() {
        if h[g] < min_separation {
            continue;
        }
        let below = if g == 0 { 0.0 } else { h[g - 1] };
        let ratio = (h[g] + eps) / (below + eps);
        if best.is_none_or(|(_, r)| ratio > r) {
            best = Some((g, ratio));
        }
    }
    best.map_or(h.len(), |(g, _)| g)
}

/// Mean silhouette of a labelling under a distance matrix: for every item `i` of a
/// category with other members, `(b - a) / max(a, b)` with `a` its mean distance to the other
/// members and `b` its mean distance to the nearest other category of two or more; items
/// alone in their category count 0 (Rousseeuw 1987), and so do all items when no second
/// category of two or more exists. `None` with fewer than two categories.
///
/// The nearest other category is looked for among categories of two or more because a lone
/// item far from everything (a speck, a mis-cut piece) would otherwise be every item's
/// nearest other category: against its distance every category looks tight, and the cut
/// that keeps only it apart (two categories: the speck and the rest) scores highest.
pub fn mean_silhouette(dist: &DistanceMatrix, labels: &[usize]) -> Option<f64> {
    let n = labels.len();
    let k = labels.iter().max().map_or(0, |&m| m + 1);
    if k < 2 || dist.n() != n {
        return None;
    }
    let mut count = vec![0usize; k];
    labels.iter().for_each(|&l| count[l] += 1);
    let mut sum = vec![0f64; k];
    let mut total = 0.0;
    for i in 0..n {
        sum.iter_mut().for_each(|s| *s = 0.0);
        for j in (0..n).filter(|&j| j != i) {
            sum[labels[j]] += dist.get(i, j).unwrap_or(0.0);
        }
        let own = labels[i];
        if count[own] < 2 {
            continue;
        }
        let a = sum[own] / (count[own] - 1) as f64;
        let b = (0..k)
            .filter(|&c| c != own && count[c] > 1)
            .map(|c| sum[c] / count[c] as f64)
            .fold(f64::INFINITY, f64::min);
        let m = a.max(b);
        if m > 0.0 && b.is_finite() {
            total += (b - a) / m;
        }
    }
    Some(total / n as f64)
}

/// Number of merges to apply: among the cuts whose next merge is at least `min_separation`
/// high (the categories it leaves apart are really apart), the one of highest
/// [`mean_silhouette`] (ties: fewer categories). No such cut: one category (every merge
/// applied).
pub fn silhouette_cut(dendro: &Dendrogram, dist: &DistanceMatrix, min_separation: f64) -> usize {
    let n = dendro.n;
    let mut best: Option<(usize, f64)> = None;
    for (m, merge) in dendro.merges.iter().enumerate().rev() {
        if merge.distance < min_separation {
            break;
        }
        let Some(s) = mean_silhouette(dist, &dendro.labels_after(m)) else { continue };
        if best.is_none_or(|(_, b)| s > b) {
            best = Some((m, s));
        }
    }
    best.map_or(n.saturating_sub(1), |(m, _)| m)
}

/// Number of merges to apply: those below `min_separation` (merge heights only grow along
/// an average-linkage dendrogram), so that every two groups of objects further apart than
/// the reconstruction noise between copies of one object stay two categories, however far
/// other groups are. (The silhouette compares distances: one group of objects far from
/// every other, such as several large vehicles joined into one detection, makes all the
/// others look alike and the silhouette's best cut keeps only that group apart.)
pub fn separation_cut(dendro: &Dendrogram, min_separation: f64) -> usize {
    dendro.merges.iter().take_while(|m| m.distance < min_separation).count()
}

/// What the label histograms are built from: feature vectors (`[len][dim]`), each with a
/// weight and the detection it belongs to.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Samples {
    pub dim: usize,
    pub points: Vec<f32>,
    pub weights: Vec<f32>,
    /// Index of the detection of every sample.
    pub owner: Vec<u32>,
    /// The texel (row, column) of every sample, where known (empty otherwise).
    pub at: Vec<(u32, u32)>,
}

impl Samples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.owner.len()
    }

    pub fn is_empty(&self) -> bool {
        self.owner.is_empty()
    }

    fn push(&mut self, owner: usize, weight: f32, point: &[f32]) {
        self.points.extend_from_slice(point);
        self.weights.push(weight);
        self.owner.push(owner as u32);
    }

    /// The paper's samples: every own texel of every detection, with its feature vector on
    /// `feature` (a ground plane) and its opacity (the first-round evidence) as weight.
    /// The feature of a texel describes its whole column, so an object standing on a
    /// support carries the support's features too.
    pub fn from_plane(dets: &Detections, feature: &PlaneImage) -> Result<Samples> {
        let (rows, cols, ch) = (feature.rows, feature.cols, feature.ch);
        if (rows, cols) != (dets.grid.rows, dets.grid.cols) {
            return Err(MiningError::SizeMismatch {
                what: "feature plane vs ground grid (texels)",
                left: rows * cols,
                right: dets.grid.rows * dets.grid.cols,
            });
        }
        let mut s = Samples { dim: ch, ..Default::default() };
        for d in &dets.detections {
            for (r, c) in own_texels(d) {
                let i = r * cols + c;
                // fixed: a weight floor (every texel counts)
                s.push(d.id, dets.evidence[i].max(1e-3), &feature.data[i * ch..(i + 1) * ch]);
                s.at.push((r as u32, c as u32));
            }
        }
        Ok(s)
    }

    /// Samples from the object itself rather than its columns: the colour the field decodes
    /// (seen along [`VOXEL_VIEW`]; in CIELAB, a perceptually uniform space) at the
    /// object's [`voxel_sites`], weighted by their opacity. A crate on a pallet then has the
    /// colours of a crate on the floor, and two cars that differ only in paint differ in
    /// most of their samples rather than in a mixed column feature.
    pub fn from_voxels(field: &Field, vol: &OpacityVolume, dets: &Detections) -> Result<Samples> {
        let [nx, ny, nz] = field.config.res;
        if (vol.rows, vol.cols, vol.nz) != (ny, nx, nz) {
            return Err(MiningError::SizeMismatch {
                what: "opacity volume vs field resolution",
                left: vol.rows * vol.cols * vol.nz,
                right: nx * ny * nz,
            });
        }
        let (a, v) = (field.config.aabb(), field.config.voxel_size());
        let sites = voxel_sites(vol, dets)?;
        let pos: Vec<Vec3> = sites
            .iter()
            .map(|x| {
                let (r, c, k) = x.at;
                Vec3::new(a.min.x + c as f32 * v.x, a.min.y + r as f32 * v.y, vol.height(k))
            })
            .collect();
        let mut s = Samples {
            dim: 3,                             // fixed: CIELAB has 3 axes
            points: vec![0.0; 3 * sites.len()], // fixed: CIELAB has 3 axes
            // fixed: a weight floor (every voxel counts)
            weights: sites.iter().map(|x| x.opacity.max(1e-3)).collect(),
            owner: sites.iter().map(|x| x.owner as u32).collect(),
            at: sites.iter().map(|x| (x.at.0 as u32, x.at.1 as u32)).collect(),
        };
        const TILE: usize = 4096; // fixed: a work size of the parallel loop
        // fixed: three CIELAB axes per point
        s.points.par_chunks_mut(TILE * 3).zip(pos.par_chunks(TILE)).for_each_init(
            ColorWork::default,
            |work, (rgb, p)| {
                work.clear();
                work.pos.extend_from_slice(p);
                work.dir.resize(p.len(), VOXEL_VIEW);
                field.color_forward(work);
                rgb.copy_from_slice(&work.rgb[..p.len() * 3]); // fixed: RGB
            },
        );
        // CIELAB, every axis over its span: the lightness weighs as much as the hue (it had
        // half the weight, a tuned number that went to keep mining within 25; each object's
        // lightness taken relative to its own mean, against shading that differs between
        // copies, grouped different objects of one hue: results, ninth session)
        // fixed: CIELAB has 3 axes
        s.points.par_chunks_mut(3).for_each(|p| {
            let [l, a, b] = srgb_to_lab([p[0], p[1], p[2]]);
            // fixed: CIELAB axes span about 100
            p.copy_from_slice(&[l / 100.0, a / 100.0, b / 100.0]);
        });
        Ok(s)
    }
}

/// A voxel that describes a detection in [`Samples::from_voxels`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelSite {
    /// The detection.
    pub owner: usize,
    /// Plane row, column and volume level.
    pub at: (usize, usize, usize),
    pub opacity: f32,
}

/// The voxels that describe each detection: the surface voxels (above the voxel threshold,
/// with a face neighbour below it: the inside of a solid object was never seen, so its colour
/// means nothing) of its own texels, from the level above its base up to its shape top (haze
/// specks above an object do not count). The base level is left out: it is the floor's or
/// the support's top (exposed under a chair's seat), or with no floor the level below the
/// ground. A detection without such a voxel (fainter than the voxel
/// threshold there) gets the most opaque voxel of each of its own columns, over the whole
/// column if need be, so that every detection with own texels has samples.
pub fn voxel_sites(vol: &OpacityVolume, dets: &Detections) -> Result<Vec<VoxelSite>> {
    if (vol.rows, vol.cols) != (dets.grid.rows, dets.grid.cols) {
        return Err(MiningError::SizeMismatch {
            what: "opacity volume vs ground grid (texels)",
            left: vol.rows * vol.cols,
            right: dets.grid.rows * dets.grid.cols,
        });
    }
    if vol.nz == 0 {
        return Err(MiningError::ZeroDimension { what: "volume levels" });
    }
    let tau = dets.voxel_threshold;
    let mut sites = Vec::new();
    for d in &dets.detections {
        let (lo, hi) = vol.levels_between(d.base, d.shape_top);
        let start = sites.len();
        for (r, c) in own_texels(d) {
            for (k, &o) in vol.column(r, c).iter().enumerate().take(hi + 1).skip(lo) {
                if o >= tau && vol.exposed(r, c, k, tau) {
                    sites.push(VoxelSite { owner: d.id, at: (r, c, k), opacity: o });
                }
            }
        }
        if sites.len() == start {
            for (r, c) in own_texels(d) {
                let col = vol.column(r, c);
                let strongest = |range: std::ops::Range<usize>| {
                    range.max_by(|&x, &y| col[x].total_cmp(&col[y])).filter(|&k| col[k] > 0.0)
                };
                if let Some(k) = strongest(lo..hi + 1).or_else(|| strongest(0..vol.nz)) {
                    sites.push(VoxelSite { owner: d.id, at: (r, c, k), opacity: col[k] });
                }
            }
        }
    }
    Ok(sites)
}

/// CIELAB (D65) of an sRGB colour with components in 0..1: `[L*, a*, b*]`, L* in 0..100.
pub fn srgb_to_lab(rgb: [f32; 3]) -> [f32; 3] {
    let [r, g, b] = rgb.map(assetfield_core::canvas::srgb_to_linear);
    // fixed: sRGB's primaries and D65 white (IEC 61966-2-1)
    let x = (0.412_456_4 * r + 0.357_576_1 * g + 0.180_437_5 * b) / 0.950_47;
    // fixed: sRGB's primaries and D65 white (IEC 61966-2-1)
    let y = 0.212_672_9 * r + 0.715_152_2 * g + 0.072_175 * b;
    // fixed: sRGB's primaries and D65 white (IEC 61966-2-1)
    let z = (0.019_333_9 * r + 0.119_192 * g + 0.950_304_1 * b) / 1.088_83;
    let f = |t: f32| {
        const E: f32 = 216.0 / 24389.0; // fixed: CIELAB (CIE 15)
        const K: f32 = 24389.0 / 27.0; // fixed: CIELAB (CIE 15)
        if t > E { t.cbrt() } else { (K * t + 16.0) / 116.0 } // fixed: CIELAB (CIE 15)
    };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)] // fixed: CIELAB (CIE 15)
}

/// The direction the colours of [`Samples::from_voxels`] are decoded along: looking down at
/// 45 degrees, as most training cameras of a ground scene do.
pub const VOXEL_VIEW: Vec3 =
    Vec3::new(0.0, std::f32::consts::FRAC_1_SQRT_2, -std::f32::consts::FRAC_1_SQRT_2);

/// The own texels of a detection, as plane `(row, col)`.
fn own_texels(d: &crate::detect::Detection) -> impl Iterator<Item = (usize, usize)> + '_ {
    (0..d.rect.rows()).flat_map(move |r| {
        (0..d.rect.cols())
            .filter(move |&c| d.own.get(r, c))
            .map(move |c| (d.rect.r0 + r, d.rect.c0 + c))
    })
}

/// Cluster `n` detections from their samples: K-means labels over the samples (fitted on at
/// most [`GroupOptions::max_samples`] of them), a label histogram per detection, the JSD
/// plus the shape term, average linkage and the cut.
pub fn group_samples(
    samples: &Samples,
    n: usize,
    shapes: &[Shape],
    opts: &GroupOptions,
) -> Result<Grouping> {
    group_samples_with(samples, n, shapes, &[], opts)
}

/// Every detection's vertical profile ([`crate::copies::vertical_profile`]) as the grouping
/// compares them: sharp where two objects stand on one base (the same floor or surface
/// height: their levels line up), blurred by the field's vertical blur where they stand on
/// different bases, each estimated within that blur
/// ([`crate::copies::blurred`]). Empty: no profiles.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Profiles<'a> {
    /// The blurred profiles, one per detection.
    pub blurred: &'a [Vec<f64>],
    /// The sharp profiles and the bases' heights (world units), one per detection; empty:
    /// every pair compares blurred profiles (objects of different scenes).
    pub sharp: &'a [Vec<f64>],
    pub base: &'a [f32],
}

impl<'a> Profiles<'a> {
    /// Blurred profiles only: every pair compares them.
    pub fn blurred_only(blurred: &'a [Vec<f64>]) -> Self {
        Profiles { blurred, ..Default::default() }
    }

    /// Number of detections described (0: none).
    pub fn len(&self) -> usize {
        self.blurred.len()
    }

    pub fn is_empty(&self) -> bool {
        self.blurred.is_empty()
    }

    /// The Jensen-Shannon divergence of detections `i` and `j`: of their sharp profiles on
    /// one base (bases of one volume are levels of it: equal, or a level or more apart),
    /// of their blurred ones otherwise.
    pub fn jsd(&self, i: usize, j: usize) -> f64 {
        let one_base = self.base.len() == self.len() && self.base[i] == self.base[j];
        if one_base && self.sharp.len() == self.len() {
            crate::copies::profile_jsd(&self.sharp[i], &self.sharp[j])
        } else {
            crate::copies::profile_jsd(&self.blurred[i], &self.blurred[j])
        }
    }
}

/// [`group_samples`] with every detection's vertical profile, blurred
/// ([`crate::copies::blurred`]; empty: none): see [`group_samples_profiled`].
pub fn group_samples_with(
    samples: &Samples,
    n: usize,
    shapes: &[Shape],
    profiles: &[Vec<f64>],
    opts: &GroupOptions,
) -> Result<Grouping> {
    group_samples_profiled(samples, n, shapes, Profiles::blurred_only(profiles), opts)
}

/// [`group_samples`] with every detection's vertical profile: their Jensen-Shannon
/// divergence ([`Profiles::jsd`]), times [`GroupOptions::profile_weight`], joins the distance.
pub fn group_samples_profiled(
    samples: &Samples,
    n: usize,
    shapes: &[Shape],
    profiles: Profiles<'_>,
    opts: &GroupOptions,
) -> Result<Grouping> {
    check_inputs(samples, n, shapes, &profiles, opts)?;
    if n == 0 {
        return Ok(Grouping {
            histograms: Vec::new(),
            codebook: None,
            jsd: DistanceMatrix::new(0, Vec::new())?,
            distance: DistanceMatrix::new(0, Vec::new())?,
            merges: Vec::new(),
            category: Vec::new(),
            n_categories: 0,
            cut: "no detections".into(),
        });
    }
    let (histograms, codebook) = label_histograms(samples, n, opts)?;
    let jsd = jsd_matrix(&histograms)?;
    // the profile holds the height where there is one; the height stands in for it otherwise
    let profiled = !profiles.is_empty() && opts.profile_weight > 0.0;
    let distance = DistanceMatrix::from_fn(n, |i, j| {
        let shape = shape_distance(shapes[i], shapes[j], opts.length_tolerance, !profiled);
        jsd.get(i, j).unwrap_or(0.0)
            + opts.shape_weight * shape
            + if profiled { opts.profile_weight * profiles.jsd(i, j) } else { 0.0 }
    })?;
    let dendro = linkage(&distance, opts.linkage);
    let (cut, desc) = choose_cut(&dendro, &distance, n, opts);
    let category = dendro.cut(cut)?;
    let n_categories = category.iter().max().map_or(0, |&m| m + 1);
    Ok(Grouping {
        histograms,
        codebook: Some(codebook),
        jsd,
        distance,
        merges: dendro.merges,
        category,
        n_categories,
        cut: desc,
    })
}

/// The inputs of [`group_samples_profiled`] agree with each other and with `n` detections.
fn check_inputs(
    samples: &Samples,
    n: usize,
    shapes: &[Shape],
    profiles: &Profiles<'_>,
    opts: &GroupOptions,
) -> Result<()> {
    if !profiles.is_empty() && profiles.len() != n {
        return Err(MiningError::SizeMismatch {
            what: "profiles vs detections",
            left: profiles.len(),
            right: n,
        });
    }
    for (what, len) in [
        ("sharp profiles vs detections", profiles.sharp.len()),
        ("profiles' bases vs detections", profiles.base.len()),
    ] {
        if len != 0 && len != profiles.len() {
            return Err(MiningError::SizeMismatch { what, left: len, right: profiles.len() });
        }
    }
    if shapes.len() != n {
        return Err(MiningError::SizeMismatch {
            what: "shapes vs detections",
            left: shapes.len(),
            right: n,
        });
    }
    if opts.labels == 0 {
        return Err(MiningError::ZeroDimension { what: "number of labels" });
    }
    if n == 0 {
        return Ok(());
    }
    let ch = samples.dim;
    if samples.points.len() != samples.len() * ch {
        return Err(MiningError::SizeMismatch {
            what: "sample points vs owners times the dimension",
            left: samples.points.len(),
            right: samples.len() * ch,
        });
    }
    if samples.weights.len() != samples.len() {
        return Err(MiningError::SizeMismatch {
            what: "sample weights vs owners",
            left: samples.weights.len(),
            right: samples.len(),
        });
    }
    if let Some(&o) = samples.owner.iter().find(|&&o| o as usize >= n) {
        return Err(MiningError::InvalidParameter {
            name: "samples",
            reason: format!("a sample belongs to detection {o} but there are {n} detections"),
        });
    }
    if opts.labels > samples.len() {
        return Err(MiningError::InvalidParameter {
            name: "labels",
            reason: format!(
                "{} labels requested but the detected objects give only {} samples",
                opts.labels,
                samples.len()
            ),
        });
    }
    Ok(())
}

/// The colour labels of a grouping: the K-means centroids over the samples, and how a
/// sample is spread over them ([`Codebook::add`]).
#[derive(Debug, Clone)]
pub struct Codebook {
    dim: usize,
    centroids: Vec<f32>,
    /// The mean squared distance of the fitted points to their centroid.
    s2: f64,
    soft: bool,
}

impl Codebook {
    /// Number of labels.
    pub fn labels(&self) -> usize {
        self.centroids.len().checked_div(self.dim).unwrap_or(0)
    }

    /// Add `point` with weight `wt` to `hist` (one bin per label): to its nearest label, or
    /// soft memberships `exp(-(d_j^2 - d_min^2) / (2 s^2))`, so that a colour the codebook
    /// happens to split between two labels does not make identical objects look different.
    /// `d` is scratch of one value per label.
    fn add(&self, point: &[f32], wt: f64, hist: &mut [f64], d: &mut [f32]) {
        for (j, dj) in d.iter_mut().enumerate() {
            let c = &self.centroids[j * self.dim..(j + 1) * self.dim];
            *dj = c.iter().zip(point).map(|(a, b)| (a - b) * (a - b)).sum();
        }
        let (best, dmin) = d
            .iter()
            .enumerate()
            .fold((0usize, f32::INFINITY), |b, (j, &v)| if v < b.1 { (j, v) } else { b });
        if self.soft {
            let e = |v: f32| (-(f64::from(v - dmin)) / (2.0 * self.s2)).exp();
            let t: f64 = d.iter().map(|&v| e(v)).sum();
            hist.iter_mut().zip(d.iter()).for_each(|(h, &v)| *h += wt * e(v) / t);
        } else {
            hist[best] += wt;
        }
    }

    /// The normalised label histogram of the samples `which` (indices into `samples`, whose
    /// points must have this codebook's dimension); `None` when they weigh nothing.
    pub fn histogram(
        &self,
        samples: &Samples,
        which: impl IntoIterator<Item = usize>,
    ) -> Option<Vec<f64>> {
        let (k, ch) = (self.labels(), samples.dim);
        if ch != self.dim || k == 0 {
            return None;
        }
        let (mut hist, mut d) = (vec![0f64; k], vec![0f32; k]);
        for i in which {
            let p = samples.points.get(i * ch..(i + 1) * ch)?;
            self.add(p, f64::from(samples.weights[i]), &mut hist, &mut d);
        }
        let total: f64 = hist.iter().sum();
        (total > 0.0).then(|| hist.into_iter().map(|h| h / total).collect())
    }
}

/// Every detection's normalised label histogram, and the codebook: K-means labels fitted on
/// at most [`GroupOptions::max_samples`] of the samples, then every sample's label (or soft
/// memberships) added to its owner's histogram with the sample's weight.
fn label_histograms(
    samples: &Samples,
    n: usize,
    opts: &GroupOptions,
) -> Result<(Vec<Vec<f64>>, Codebook)> {
    let ch = samples.dim;
    let stride = samples.len().div_ceil(opts.max_samples.max(opts.labels)).max(1);
    let fit: Vec<usize> = (0..samples.len()).step_by(stride).collect();
    let pts: Vec<f32> =
        fit.iter().flat_map(|&i| samples.points[i * ch..(i + 1) * ch].iter().copied()).collect();
    let w: Vec<f32> = fit.iter().map(|&i| samples.weights[i]).collect();
    let k = opts.labels.min(fit.len());
    let km = kmeans(
        &pts,
        ch,
        Some(&w),
        &KMeansOptions { k, seed: opts.seed, ..KMeansOptions::default() },
    )?;
    // s^2 of the soft memberships: the mean squared distance of the points to their centroid
    let s2 = (km.inertia / w.iter().map(|&x| f64::from(x)).sum::<f64>().max(1e-12)).max(1e-12);
    let book = Codebook {
        dim: ch,
        centroids: (0..k).flat_map(|j| km.centroid(j).iter().copied()).collect(),
        s2,
        soft: opts.soft,
    };
    const CHUNK: usize = 8192; // fixed: a work size of the parallel loop
    let mut histograms: Vec<Vec<f64>> = (0..samples.len())
        .into_par_iter()
        .step_by(CHUNK)
        .map(|from| {
            let mut hist = vec![0f64; n * k];
            let mut d = vec![0f32; k];
            for i in from..(from + CHUNK).min(samples.len()) {
                let p = &samples.points[i * ch..(i + 1) * ch];
                let h = &mut hist[samples.owner[i] as usize * k..][..k];
                book.add(p, f64::from(samples.weights[i]), h, &mut d);
            }
            hist
        })
        // summed in chunk order, so that the result does not depend on the thread count
        .collect::<Vec<_>>()
        .into_iter()
        .fold(vec![0f64; n * k], |mut a, b| {
            a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
            a
        })
        .chunks(k)
        .map(<[f64]>::to_vec)
        .collect();
    for hist in &mut histograms {
        let total: f64 = hist.iter().sum();
        if total.is_nan() || total <= 0.0 {
            return Err(MiningError::ZeroWeight { what: "label histogram" });
        }
        hist.iter_mut().for_each(|h| *h /= total);
    }
    Ok((histograms, book))
}

/// Where to cut the dendrogram of `n` detections, and a description of the cut.
fn choose_cut(
    dendro: &Dendrogram,
    distance: &DistanceMatrix,
    n: usize,
    opts: &GroupOptions,
) -> (Cut, String) {
    match opts.cut {
        GroupCut::Categories(c) => (Cut::Clusters(c), format!("{c} categories (given)")),
        GroupCut::Distance(t) => (Cut::Distance(t), format!("distance {t} (given)")),
        GroupCut::Separation => {
            let t = opts.min_separation;
            let k = n - separation_cut(dendro, t);
            let desc = format!(
                "automatic: groups of objects at least {t} apart are categories, {k} categories"
            );
            (Cut::Clusters(k), desc)
        }
        GroupCut::Silhouette => {
            let m = silhouette_cut(dendro, distance, opts.min_separation);
            let k = n - m;
            let desc = match mean_silhouette(distance, &dendro.labels_after(m)) {
                Some(s) => format!(
                    "automatic: highest mean silhouette ({s:.3}) among cuts separated by at least {}, {k} categories",
                    opts.min_separation
                ),
                None => format!("automatic: {k} category (no merge above {})", opts.min_separation),
            };
            (Cut::Clusters(k), desc)
        }
        GroupCut::LargestRatio => {
            let m = auto_cut(&dendro.merges, opts.min_separation);
            let k = n - m;
            let at = dendro.merges.get(m).map(|x| x.distance);
            let desc = match at {
                Some(h) => format!(
                    "automatic: largest ratio of merge heights, {k} categories (next merge at {h:.3})"
                ),
                None => format!("automatic: {k} category (no merge above {})", opts.min_separation),
            };
            (Cut::Clusters(k), desc)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn merges(h: &[f64]) -> Vec<Merge> {
        h.iter().map(|&d| Merge { a: 0, b: 1, distance: d, size: 2 }).collect()
    }

    /// Items on a line: distance |x_i - x_j|.
    fn line(x: &[f64]) -> DistanceMatrix {
        DistanceMatrix::from_fn(x.len(), |i, j| (x[i] - x[j]).abs()).unwrap()
    }

    fn silhouette_categories(x: &[f64]) -> usize {
        let d = line(x);
        let dendro = linkage(&d, Linkage::Average);
        let m = silhouette_cut(&dendro, &d, 0.12);
        x.len() - m
    }

    #[test]
    fn silhouette_of_two_tight_groups_is_near_one_and_singletons_count_zero() {
        let d = line(&[0.0, 0.01, 1.0, 1.01]);
        let s = mean_silhouette(&d, &[0, 0, 1, 1]).unwrap();
        assert!(s > 0.98 && s < 1.0, "{s}");
        // a wrong labelling scores below zero
        assert!(mean_silhouette(&d, &[0, 1, 0, 1]).unwrap() < 0.0);
        // every item alone: 0; one category: undefined
        assert_eq!(mean_silhouette(&d, &[0, 1, 2, 3]), Some(0.0));
        assert_eq!(mean_silhouette(&d, &[0, 0, 0, 0]), None);
    }

    #[test]
    fn silhouette_cut_keeps_fine_categories_next_to_coarse_ones() {
        // red chairs, blue chairs (0.4 apart), tables far away (3.0)
        let x = [0.0, 0.01, 0.02, 0.4, 0.41, 0.42, 3.0, 3.01, 3.02];
        assert_eq!(silhouette_categories(&x), 3);
        // everything within the minimum separation: one category
        assert_eq!(silhouette_categories(&[0.0, 0.02, 0.05, 0.03]), 1);
        // two items far apart stay apart
        assert_eq!(silhouette_categories(&[0.0, 0.9]), 2);
    }

    #[test]
    fn a_far_outlier_does_not_merge_the_categories_as_the_ratio_rule_does() {
        // four categories of three, 0.5 apart, and one speck 20 away: the largest ratio of
        // merge heights lies at the speck's merge, so the ratio rule keeps only it apart
        let mut x: Vec<f64> = (0..4)
            .flat_map(|c| (0..3).map(move |i| f64::from(c) * 0.5 + f64::from(i) * 0.01))
            .collect();
        x.push(20.0);
        let d = line(&x);
        let dendro = linkage(&d, Linkage::Average);
        assert_eq!(x.len() - auto_cut(&dendro.merges, 0.12), 2);
        assert_eq!(silhouette_categories(&x), 5);
    }

    #[test]
    fn a_far_lone_item_is_nobody_s_nearest_category() {
        // four loose categories of three (members 0.12 apart, categories 1.0 apart) and one
        // speck 20 away: were the speck a candidate nearest category, every category would
        // look tight against it and the cut keeping only the speck apart would score highest
        let mut x: Vec<f64> =
            (0..4).flat_map(|c| (0..3).map(move |i| f64::from(c) + f64::from(i) * 0.12)).collect();
        x.push(20.0);
        let d = line(&x);
        let speck_alone: Vec<usize> = (0..13).map(|i| usize::from(i == 12)).collect();
        assert_eq!(mean_silhouette(&d, &speck_alone), Some(0.0));
        let categories: Vec<usize> = (0..13).map(|i| i / 3).collect();
        assert!(mean_silhouette(&d, &categories).unwrap() > 0.7);
        assert_eq!(silhouette_categories(&x), 5);
    }

    #[test]
    fn a_far_group_keeps_nobody_else_together_with_the_separation_cut() {
        // four categories of three (0.5 apart) and, 20 away, a pair of unlike large objects
        // (1.5 apart): the silhouette's best cut keeps only the far pair apart, the
        // separation cut keeps every category
        let mut x: Vec<f64> = (0..4)
            .flat_map(|c| (0..3).map(move |i| f64::from(c) * 0.5 + f64::from(i) * 0.01))
            .collect();
        x.extend([20.0, 21.5]);
        let d = line(&x);
        let dendro = linkage(&d, Linkage::Average);
        assert_eq!(silhouette_categories(&x), 2);
        assert_eq!(x.len() - separation_cut(&dendro, 0.12), 6);
        // and groups within the minimum separation are one category
        let x = [0.0, 0.02, 0.05, 0.03, 0.9];
        let dendro = linkage(&line(&x), Linkage::Average);
        assert_eq!(x.len() - separation_cut(&dendro, 0.12), 2);
    }

    #[test]
    fn auto_cut_prefers_relative_gaps() {
        // noise merges, then a fine split (0.4), then a coarse one (1.2)
        let m = merges(&[0.02, 0.03, 0.05, 0.4, 1.2]);
        assert_eq!(auto_cut(&m, 0.12), 3);
        // everything alike: one category
        assert_eq!(auto_cut(&merges(&[0.01, 0.02, 0.05]), 0.12), 3);
        // two items far apart stay apart
        assert_eq!(auto_cut(&merges(&[0.9]), 0.12), 0);
        assert_eq!(auto_cut(&[], 0.12), 0);
    }

    #[test]
    fn lab_of_known_colours() {
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 0.05);
        assert!(close(srgb_to_lab([1.0, 1.0, 1.0]), [100.0, 0.0, 0.0]));
        assert!(close(srgb_to_lab([0.0, 0.0, 0.0]), [0.0, 0.0, 0.0]));
        // sRGB primaries (published CIELAB D65 values)
        assert!(
            close(srgb_to_lab([1.0, 0.0, 0.0]), [53.24, 80.09, 67.20]),
            "{:?}",
            srgb_to_lab([1.0, 0.0, 0.0])
        );
        assert!(close(srgb_to_lab([0.0, 0.0, 1.0]), [32.30, 79.19, -107.86]));
        // the linear segment of L* near black: L* = (24389 / 27) Y
        assert!((srgb_to_lab([0.05; 3])[0] - 3.554).abs() < 0.01);
        // a grey has no colour, whatever its lightness
        let [l, a, b] = srgb_to_lab([0.5, 0.5, 0.5]);
        assert!((l - 53.39).abs() < 0.05 && a.abs() < 0.01 && b.abs() < 0.01);
    }

    /// Samples of `n` detections: detection `i` draws its points around `centres[i]`.
    fn samples(centres: &[[f32; 2]], per: usize) -> Samples {
        let mut s = Samples { dim: 2, ..Default::default() };
        for (i, c) in centres.iter().enumerate() {
            for j in 0..per {
                let t = j as f32 / per as f32 - 0.5;
                s.push(i, 1.0, &[c[0] + 0.02 * t, c[1] - 0.02 * t]);
            }
        }
        s
    }

    #[test]
    fn a_piece_is_counted_on_the_groupings_labels() {
        // two red detections, one blue; a fourth half red, half blue
        let (red, blue) = ([1.0, 0.0], [0.0, 1.0]);
        let mut s = samples(&[red, red, blue], 40);
        for j in 0..40 {
            s.push(3, 1.0, if j < 20 { &red } else { &blue });
        }
        let shapes = vec![Shape::round(1.0, 1.0); 4];
        let opts = GroupOptions { labels: 4, ..Default::default() };
        let g = group_samples(&s, 4, &shapes, &opts).unwrap();
        let book = g.codebook.as_ref().unwrap();
        // a detection's own samples give its histogram
        let owner = &s.owner;
        let of = |d: u32| (0..owner.len()).filter(move |&i| owner[i] == d);
        let whole = book.histogram(&s, of(3)).unwrap();
        assert!(crate::histogram::jsd(&whole, &g.histograms[3]).unwrap() < 1e-12);
        // its red half looks like the red ones, not the blue one
        let half = book.histogram(&s, of(3).take(20)).unwrap();
        assert!(crate::histogram::jsd(&half, &g.histograms[0]).unwrap() < 0.05);
        assert!(crate::histogram::jsd(&half, &g.histograms[2]).unwrap() > 0.5);
        assert!(book.histogram(&s, std::iter::empty()).is_none());
    }

    #[test]
    fn detections_with_the_same_samples_share_a_category() {
        // two red, one blue, one red again, one blue: two categories
        let (red, blue) = ([1.0, 0.0], [0.0, 1.0]);
        let s = samples(&[red, red, blue, red, blue], 50);
        let shapes = vec![Shape::round(1.0, 1.0); 5];
        let opts = GroupOptions { labels: 4, ..Default::default() };
        let g = group_samples(&s, 5, &shapes, &opts).unwrap();
        assert_eq!(g.n_categories, 2, "{}", g.cut);
        assert_eq!(g.category, vec![0, 0, 1, 0, 1]);
        assert!(g.jsd.get(0, 2).unwrap() > 0.5 && g.jsd.get(0, 1).unwrap() < 1e-3);
        // the shape term splits same-coloured objects of different sizes
        let mut shapes = shapes;
        shapes[3].area = 4.0;
        let g = group_samples(&s, 5, &shapes, &opts).unwrap();
        assert_eq!(g.category, vec![0, 0, 1, 2, 1]);
        // more labels than samples, mismatched shapes, and a detection without samples
        let few = samples(&[red], 3);
        assert!(matches!(
            group_samples(&few, 1, &shapes[..1], &opts),
            Err(MiningError::InvalidParameter { name: "labels", .. })
        ));
        assert!(group_samples(&s, 5, &shapes[..4], &opts).is_err());
        assert!(matches!(
            group_samples(&s, 6, &[shapes.clone(), shapes[..1].to_vec()].concat(), &opts),
            Err(MiningError::ZeroWeight { .. })
        ));
    }

    #[test]
    fn voxel_sites_are_the_objects_own_surface() {
        use crate::detect::{DetectParams, detect};
        use crate::planes::PlaneGrid;
        // a floor slab (levels 0..=1), a box on it (levels 2..=7) and a speck of haze above it
        let (rows, cols, nz) = (30, 30, 20);
        let mut vol = OpacityVolume::empty(rows, cols, nz, 0.05);
        vol.fill_box(0..30, 0..30, 0..2, 0.95);
        vol.fill_box(10..17, 10..17, 2..8, 0.95);
        vol.fill_box(13..14, 13..14, 14..15, 0.95);
        let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
        let color = PlaneImage::from_fn(rows, cols, 3, |_, _, k| k as f32).unwrap();
        let opts = DetectParams { min_area_texels: 4, ..Default::default() };
        let dets = detect(&grid, &vol, &color, None, &opts).unwrap();
        assert_eq!(dets.detections.len(), 1);
        let sites = voxel_sites(&vol, &dets).unwrap();
        let at: std::collections::HashSet<_> = sites.iter().map(|x| x.at).collect();
        assert!(sites.iter().all(|x| x.owner == 0 && x.opacity == 0.95));
        // the box's base is its lowest level (2), the first level it could share with what it
        // stands on; its shape top is level 7 (the speck at 14 is haze)
        let d = &dets.detections[0];
        assert_eq!(((d.base / 0.05).round(), (d.shape_top / 0.05).round()), (2.0, 7.0));
        assert!(at.iter().all(|&(_, _, k)| (3..=7).contains(&k)), "floor or haze: {at:?}");
        // the top and the sides, not the inside
        assert!(
            at.contains(&(13, 13, 7)) && at.contains(&(10, 13, 4)) && at.contains(&(16, 16, 3))
        );
        assert!(!at.contains(&(13, 13, 4)) && !at.contains(&(11, 11, 6)));
        assert_eq!(sites.len(), (7 * 7 - 5 * 5) * 5 + 5 * 5);

        // nothing occupied in the range (a detection above everything): the most opaque voxel
        // of each own column instead
        let mut lifted = dets.clone();
        let d = &mut lifted.detections[0];
        (d.base, d.top, d.shape_top) = (0.6, 0.6, 0.6);
        let sites = voxel_sites(&vol, &lifted).unwrap();
        assert_eq!(sites.len(), lifted.detections[0].own.count());
        assert!(sites.iter().all(|x| x.opacity == 0.95));
        // a volume that does not match the grid
        let small =
            OpacityVolume { rows: 3, cols: 3, nz, z0: 0.0, dz: 0.05, data: vec![0.0; 9 * nz] };
        assert!(voxel_sites(&small, &dets).is_err());
    }

    #[test]
    fn histograms_do_not_depend_on_the_thread_count() {
        // more samples than one chunk of the parallel accumulation
        let mut s = Samples { dim: 2, ..Default::default() };
        for i in 0..30_000usize {
            let t = (i as f32 * 0.618_034).fract();
            s.push(i % 3, 0.5 + t, &[t, (i % 3) as f32 + 0.3 * t]);
        }
        let shapes = vec![Shape::round(1.0, 1.0); 3];
        let opts = GroupOptions { labels: 6, ..Default::default() };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| group_samples(&s, 3, &shapes, &opts).unwrap().histograms)
        };
        let one = run(1);
        assert_eq!(one, run(4));
        assert_eq!(one, run(3));
        // an owner out of range is refused, not a panic
        let mut bad = s.clone();
        bad.owner[7] = 3;
        assert!(group_samples(&bad, 3, &shapes, &opts).is_err());
    }

    #[test]
    fn hull_area_of_masks() {
        use crate::image::Mask;
        let square = Mask::from_fn(4, 4, |_, _| true);
        assert_eq!(hull_area(&square), 16.0);
        // an L fills to its hull: a 4x4 square minus a 3x3 corner triangle... of half-cells
        let l = Mask::from_fn(4, 4, |r, c| r == 0 || c == 0);
        assert_eq!(hull_area(&l), 16.0 - 4.5);
        assert_eq!(hull_area(&Mask::from_fn(1, 1, |_, _| true)), 1.0);
        assert_eq!(hull_area(&Mask::from_fn(2, 2, |_, _| false)), 0.0);
    }

    #[test]
    fn shape_term_has_a_dead_zone() {
        let a = Shape::round(1.0, 1.0);
        assert_eq!(shape_distance(a, Shape::round(1.3, 0.95), 0.15, true), 0.0);
        let d = shape_distance(a, Shape::round(2.0, 1.0), 0.15, true);
        assert!((d - (2f64.ln() - 0.3)).abs() < 1e-6);
        let d = shape_distance(a, Shape::round(1.0, 0.5), 0.15, true);
        assert!((d - (2f64.ln() - 0.15)).abs() < 1e-6);
        // an elongation is a ratio of two lengths: the area's dead zone
        let long = |e: f32| Shape { elongation: e, ..a };
        assert_eq!(shape_distance(a, long(1.3), 0.15, true), 0.0);
        let d = shape_distance(a, long(3.0), 0.15, true);
        assert!((d - (3f64.ln() - 0.3)).abs() < 1e-6, "{d}");
        // the largest term counts, not their sum
        let d = shape_distance(a, Shape { area: 2.0, height: 1.0, elongation: 3.0 }, 0.15, true);
        assert!((d - (3f64.ln() - 0.3)).abs() < 1e-6, "{d}");
        // without the height (a profile holds it), only the footprint counts
        assert_eq!(shape_distance(a, Shape::round(1.0, 0.5), 0.15, false), 0.0);
        let d = shape_distance(a, Shape::round(2.0, 0.5), 0.15, false);
        assert!((d - (2f64.ln() - 0.3)).abs() < 1e-6, "{d}");
    }

    #[test]
    fn profiles_compare_sharp_on_one_base_and_blurred_across_bases() {
        // one object's profile and the same a level higher (a base estimated a level lower)
        let a = vec![0.0, 0.5, 0.5, 0.0, 0.0, 0.0];
        let b = vec![0.0, 0.0, 0.5, 0.5, 0.0, 0.0];
        let blur = |p: &Vec<f64>| crate::copies::blurred(p, 2);
        let (blurred, sharp) = (vec![blur(&a), blur(&b)], vec![a.clone(), b.clone()]);
        let one = Profiles { blurred: &blurred, sharp: &sharp, base: &[0.5, 0.5] };
        let two = Profiles { base: &[0.5, 0.55], ..one };
        let sharp = crate::copies::profile_jsd(&a, &b);
        assert_eq!(one.jsd(0, 1), sharp);
        assert!(two.jsd(0, 1) < 0.5 * sharp, "{} vs {sharp}", two.jsd(0, 1));
        assert_eq!(Profiles::blurred_only(&blurred).jsd(0, 1), two.jsd(0, 1));
        // sharp profiles or bases of another length are refused
        let s = samples(&[[0.0, 0.0], [1.0, 1.0]], 20);
        let shapes = [Shape::round(1.0, 1.0); 2];
        let bad = Profiles { base: &[0.5], ..one };
        assert!(group_samples_profiled(&s, 2, &shapes, bad, &GroupOptions::default()).is_err());
        assert!(group_samples_profiled(&s, 2, &shapes, one, &GroupOptions::default()).is_ok());
    }

    #[test]
    fn the_profile_holds_the_height_where_there_is_one() {
        // two identical objects, one of them with a few columns of something faint on top
        // (its top twice as high), and a third of another height throughout
        let s = samples(&[[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], 40);
        let shapes = [Shape::round(1.0, 1.0), Shape::round(1.0, 2.0), Shape::round(1.0, 2.0)];
        let low = vec![0.1, 0.3, 0.3, 0.3, 0.0, 0.0, 0.0, 0.0];
        let speck = vec![0.1, 0.3, 0.3, 0.29, 0.0, 0.0, 0.0, 0.01];
        let tall = vec![0.05, 0.05, 0.05, 0.05, 0.2, 0.2, 0.2, 0.2];
        let opts = GroupOptions::default();
        let with = group_samples_with(&s, 3, &shapes, &[low, speck, tall], &opts).unwrap();
        assert_eq!(with.category[0], with.category[1]);
        assert_ne!(with.category[0], with.category[2]);
        // with no profiles, the heights decide: the speck's top counts
        let without = group_samples(&s, 3, &shapes, &opts).unwrap();
        assert_ne!(without.category[0], without.category[1]);
        assert_eq!(without.category[1], without.category[2]);
    }

    #[test]
    fn elongation_of_footprints_whatever_their_turn() {
        use crate::image::Mask;
        let disc = Mask::from_fn(21, 21, |r, c| {
            (r as f32 - 10.0).powi(2) + (c as f32 - 10.0).powi(2) <= 100.0
        });
        assert!((elongation(&disc) - 1.0).abs() < 0.02, "{}", elongation(&disc));
        assert_eq!(elongation(&Mask::from_fn(6, 6, |_, _| true)), 1.0);
        // a solid 30 x 10 rectangle, upright and turned by about 30 degrees
        let upright = Mask::from_fn(10, 30, |_, _| true);
        assert!((elongation(&upright) - 3.0).abs() < 0.01, "{}", elongation(&upright));
        let (ca, sa) = (30f32.to_radians().cos(), 30f32.to_radians().sin());
        let turned = Mask::from_fn(40, 40, |r, c| {
            let (x, y) = (c as f32 + 0.5 - 20.0, r as f32 + 0.5 - 20.0);
            (x * ca + y * sa).abs() <= 15.0 && (-x * sa + y * ca).abs() <= 5.0
        });
        assert!((elongation(&turned) - 3.0).abs() < 0.1, "{}", elongation(&turned));
        // a one-texel leaf sticking out of a disc moves it little
        let leaf = Mask::from_fn(21, 26, |r, c| {
            disc.data.get(r * 21 + c).is_some_and(|&d| d && c < 21) || (r == 10 && c >= 21)
        });
        assert!(elongation(&leaf) < 1.1, "{}", elongation(&leaf));
        // no texels: no term
        assert_eq!(elongation(&Mask::from_fn(3, 3, |_, _| false)), 1.0);
    }
}
