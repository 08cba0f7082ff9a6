//! Templates and poses (paper Sec. 3.3, template matching): one template per category (the
//! member that matches its copies best, or the user's choice; see [`matching_medoid`]), and
//! every instance's yaw and position relative to it, found by rotating the template's patch
//! onto the instance's ([`crate::yaw::estimate_yaw_weighted`]: coarse scan, golden-section
//! refinement from the lowest coarse minima, sub-texel offset). A category's patches are either cut from a
//! feature plane or, for objects standing on others, slabs of the opacity volume over each
//! object's own height range ([`PatchSource`]).
//!
//! Patches are cut around a detection's bounding box with a margin, padding outside the
//! plane by repeating the edge texels, so a patch's centre is always its box's centre. The
//! matching finds where the template's patch centre lands on an instance (the instance's
//! patch centre plus the offset of the rotated template); [`Poses::to_pivots`] then moves
//! every position to where the template's pivot lands (see [`crate::pivot`]).

use glam::Vec2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::agglomerative::DistanceMatrix;
use crate::detect::{Detection, Detections};
use crate::error::{MiningError, Result};
use crate::image::{Mask, PixelRect, PlaneImage};
use crate::medoid::medoid;
use crate::planes::{OpacityVolume, PlaneChoice, PlaneGrid};
use crate::yaw::{
    CompareRegion, YawFit, YawOptions, estimate_yaw_near, estimate_yaw_weighted,
    yaw_residual_weighted,
};
use assetfield_core::ground::yaw_difference;

/// A rectangle that may reach outside the plane (for padded crops), rows/cols as `i64`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PatchRect {
    pub r0: i64,
    pub c0: i64,
    pub rows: usize,
    pub cols: usize,
}

impl PatchRect {
    /// `rect` grown by `margin` on every side (not clipped).
    pub fn around(rect: PixelRect, margin: usize) -> Self {
        let m = margin as i64;
        PatchRect {
            r0: rect.r0 as i64 - m,
            c0: rect.c0 as i64 - m,
            rows: rect.rows() + 2 * margin,
            cols: rect.cols() + 2 * margin,
        }
    }

    /// `self` grown by the same number of texels on opposite sides (so its centre stays put)
    /// until it holds a disc of radius `radius` texels about its centre.
    pub fn holding_disc(&self, radius: f32) -> Self {
        let grow = |n: usize| ((2.0 * radius + 1.0 - n as f32) * 0.5).max(0.0).ceil() as usize;
        let (gr, gc) = (grow(self.rows), grow(self.cols));
        PatchRect {
            r0: self.r0 - gr as i64,
            c0: self.c0 - gc as i64,
            rows: self.rows + 2 * gr,
            cols: self.cols + 2 * gc,
        }
    }

    /// Half the diagonal, in texels: the radius of the disc a patch sweeps turning about
    /// its centre.
    pub fn half_diagonal(&self) -> f32 {
        0.5 * (self.rows as f32).hypot(self.cols as f32)
    }

    /// Continuous texel coordinates (column, row) of the patch centre.
    pub fn centre(&self) -> (f32, f32) {
        (
            self.c0 as f32 + (self.cols as f32 - 1.0) * 0.5,
            self.r0 as f32 + (self.rows as f32 - 1.0) * 0.5,
        )
    }
}

/// Cut `p` from a plane, repeating edge texels outside it.
pub fn padded_crop(plane: &PlaneImage, p: PatchRect) -> Result<PlaneImage> {
    plane.validate()?;
    let clamp = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize;
    PlaneImage::from_fn(p.rows, p.cols, plane.ch, |r, c, k| {
        let (rr, cc) = (clamp(p.r0 + r as i64, plane.rows), clamp(p.c0 + c as i64, plane.cols));
        plane.data[(rr * plane.cols + cc) * plane.ch + k]
    })
}

/// A detection's mask (`own` or `footprint`, over its rect) placed in patch `p`.
pub fn mask_in_patch(d: &Detection, mask: &Mask, p: PatchRect) -> Mask {
    Mask::from_fn(p.rows, p.cols, |r, c| {
        let (rr, cc) = (p.r0 + r as i64 - d.rect.r0 as i64, p.c0 + c as i64 - d.rect.c0 as i64);
        rr >= 0 && cc >= 0 && mask.get(rr as usize, cc as usize)
    })
}

/// The pose of one detection relative to its category's template.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Counter-clockwise yaw taking the template onto this instance (0 for the template).
    pub yaw_deg: f32,
    /// Offset of the rotated template's centre from this patch's centre, in texels (x, y).
    pub offset: (f32, f32),
    /// Weighted mean squared feature difference at the optimum (0 for the template, -1 when
    /// the patches could not be matched).
    pub residual: f32,
    /// World position of the template's origin placed on this instance: its patch centre as
    /// [`estimate_poses`] returns it, its pivot after [`Poses::to_pivots`].
    pub position: Vec2,
}

/// Templates and poses of every detection.
#[derive(Debug, Clone)]
pub struct Poses {
    /// Template detection of every category.
    pub templates: Vec<usize>,
    /// Pose of every detection.
    pub poses: Vec<Pose>,
    /// What every category's residuals were measured on ([`PatchSource::kind`]).
    pub matched_on: Vec<&'static str>,
}

impl Poses {
    /// Move every position from where the template's patch centre lands to where its pivot
    /// lands (`pivots`: world pivot of every detection, see [`crate::pivot`]): the template
    /// asset turns about its pivot, so an instance placed there at its yaw covers the same
    /// texels as before.
    pub fn to_pivots(&mut self, dets: &Detections, category: &[usize], pivots: &[Vec2]) {
        for (i, pose) in self.poses.iter_mut().enumerate() {
            let Some(&t) = category.get(i).and_then(|&c| self.templates.get(c)) else { continue };
            let (Some(td), Some(&pt)) = (dets.detections.get(t), pivots.get(t)) else { continue };
            let offset = pt - crate::pivot::box_centre(td);
            pose.position += Vec2::from_angle(pose.yaw_deg.to_radians()).rotate(offset);
        }
    }
}

/// Texels added to the radius both patches of a pair are grown to (see [`estimate_poses`]),
/// past the offset search's bound: a bilinear tap reaches one texel further, and the disc is
/// rounded to whole texels (one more). Geometry, not a tuned value.
pub const ROTATION_SLACK_TEXELS: f32 = 2.0; // fixed: geometry

/// Two yaw estimates of a pair at most this many coarse steps apart are in the same basin
/// (see [`estimate_poses`]): golden-section refinement starts within one step of a coarse
/// minimum and may settle on either side of it, so two refinements of one basin end at most
/// two steps apart. Geometry, not a tuned value.
pub const SAME_BASIN_STEPS: f32 = 2.0; // fixed: geometry

/// How many times worse the tight pose must score than the wide search's pose, on the wide
/// patches, for [`match_pair`] to move to the wide pose's basin (a ratio of weighted mean
/// residuals). Round or square objects have many basins of nearly equal residual and keep
/// their tight pose: ratios of 1.0-1.1 measured on fountains, against 5.7 for a street lamp
/// that tight crops turned 114 degrees the wrong way.
pub const DECISIVE_RESIDUAL_RATIO: f32 = 2.0; // tuned: pose.decisive_residual_ratio

/// Parameters of [`estimate_poses`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseOptions {
    /// Patch margin around the bounding boxes, in texels. By default the field's blur,
    /// [`DetectParams::blur_levels`](crate::detect::DetectParams::blur_levels): a patch holds
    /// its object's blurred edge, which spreads as far across as up (the voxels are cubic).
    pub margin: usize,
    /// Template overrides: (category, detection).
    pub templates: Vec<(usize, usize)>,
    pub yaw: YawOptions,
}

impl Default for PoseOptions {
    fn default() -> Self {
        PoseOptions {
            margin: crate::detect::DetectParams::default().blur_levels,
            templates: Vec::new(),
            yaw: YawOptions::default(),
        }
    }
}

/// What the template and instance patches hold.
#[derive(Debug, Clone, Copy)]
pub enum PatchSource<'a> {
    /// Feature patches cut from a plane (each texel describes its whole column).
    Plane(PlaneChoice, &'a PlaneImage),
    /// The opacity of each object's own height range, one channel per level from the level
    /// above its base up to its shape top: what stands on a support is compared without the
    /// support's column beneath it (a table's crossbar under a laptop). The residual is
    /// reported on the `judge` plane's patches at the pose found: a layout places the
    /// template's plane patch, whole column included, so that is what must fit.
    Slab { vol: &'a OpacityVolume, judge: (PlaneChoice, &'a PlaneImage) },
}

/// Levels `[lo, hi]` of a detection's own height range in `vol`: from the level above its
/// base (the top of its floor or support; with no floor, the level below the ground) to its
/// shape top, as [`crate::group::voxel_sites`] takes.
fn own_levels(vol: &OpacityVolume, d: &Detection) -> (usize, usize) {
    vol.levels_between(d.base, d.shape_top)
}

/// A slab patch over `p` with `channels` channels: channel `j` is the opacity at level
/// `lo + j` up to the object's own `own` levels, zero above them (and above the volume), so
/// that a shorter object is not compared by what hangs over it; edge texels are repeated
/// outside the plane.
fn slab_crop(
    vol: &OpacityVolume,
    p: PatchRect,
    lo: usize,
    own: usize,
    channels: usize,
) -> Result<PlaneImage> {
    let clamp = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize;
    PlaneImage::from_fn(p.rows, p.cols, channels, |r, c, k| {
        let (rr, cc) = (clamp(p.r0 + r as i64, vol.rows), clamp(p.c0 + c as i64, vol.cols));
        if k < own { vol.column(rr, cc).get(lo + k).copied().unwrap_or(0.0) } else { 0.0 }
    })
}

impl PatchSource<'_> {
    /// The plane whose patches the reported residuals compare (residuals of different
    /// planes are not comparable).
    pub fn kind(&self) -> &'static str {
        match self {
            PatchSource::Plane(choice, _) | PatchSource::Slab { judge: (choice, _), .. } => {
                choice.name()
            }
        }
    }
}

/// One pair's patches and weights (`rows * cols` of the respective patch).
#[derive(Debug, Clone, Copy)]
pub struct Patches<'a> {
    pub template: &'a PlaneImage,
    pub template_weights: &'a [f32],
    pub instance: &'a PlaneImage,
    pub instance_weights: &'a [f32],
}

/// A template's and an instance's patch, each with its weights.
type PatchPair = ((PlaneImage, Vec<f32>), (PlaneImage, Vec<f32>));

impl<'a> Patches<'a> {
    fn of(((template, template_weights), (instance, instance_weights)): &'a PatchPair) -> Self {
        Patches { template, template_weights, instance, instance_weights }
    }

    fn fit(&self, opts: &YawOptions) -> Result<YawFit> {
        let (t, tw) = (self.template, Some(self.template_weights));
        estimate_yaw_weighted(t, tw, self.instance, Some(self.instance_weights), opts)
    }

    /// The search refined from `start_deg` only ([`estimate_yaw_near`]).
    fn fit_near(&self, start_deg: f32, opts: &YawOptions) -> Result<YawFit> {
        let (t, tw) = (self.template, Some(self.template_weights));
        estimate_yaw_near(t, tw, self.instance, Some(self.instance_weights), start_deg, opts)
    }

    /// The residual of `fit`'s pose on these patches (infinite where they do not overlap).
    fn residual_at(&self, fit: &YawFit, region: CompareRegion) -> f32 {
        let (t, tw) = (self.template, Some(self.template_weights));
        let (i, iw) = (self.instance, Some(self.instance_weights));
        yaw_residual_weighted(t, tw, i, iw, fit.yaw_deg, fit.offset, region)
            .unwrap_or(f32::INFINITY)
    }
}

/// The pose of one pair: searched on the `tight` patches (cut around each object's box),
/// checked on `wide` ones (the same centres, each holding the disc either object sweeps at
/// any turn).
///
/// Wide patches compare each object in full, at every angle, against the other patch's
/// texels, its object or its surroundings; tight crops compare only where the two patches
/// overlap, so a long thin object turned across the other is judged where the two cross and
/// a wrong quarter turn can score as well as the right one. But the neighbours that wide
/// patches take in pull the sub-texel optimum of objects whose surroundings differ, so the
/// tight fit stands unless the wide search finds another basin (more than
/// [`SAME_BASIN_STEPS`] coarse steps away) that beats the tight pose on the wide patches
/// decisively ([`DECISIVE_RESIDUAL_RATIO`]); then the tight search is refined in that basin.
pub fn match_pair(tight: Patches<'_>, wide: Patches<'_>, opts: &YawOptions) -> Result<YawFit> {
    let fit = tight.fit(opts)?;
    let Ok(other) = wide.fit(opts) else { return Ok(fit) };
    if yaw_difference(other.yaw_deg, fit.yaw_deg, opts.period_deg)
        <= SAME_BASIN_STEPS * opts.step_deg
    {
        return Ok(fit);
    }
    let at_fit = wide.residual_at(&fit, opts.region);
    let decisive = at_fit > other.residual * DECISIVE_RESIDUAL_RATIO;
    tracing::debug!(
        tight = fit.yaw_deg,
        wide = other.yaw_deg,
        ratio = at_fit / other.residual,
        decisive,
        "the wide patches put the pose in another basin"
    );
    if !decisive {
        return Ok(fit);
    }
    Ok(tight.fit_near(other.yaw_deg, opts).unwrap_or(fit))
}

/// The template of a category of `members`: the member whose pose fits against all the
/// others leave the least residual in sum (`residual(t, i)`: the weighted mean residual of
/// `i` posed against `t` as a template, `None` where the pair cannot be matched; pairs are
/// matched once each, in parallel; [`estimate_poses`] fits them on their tight patches).
/// A pair that cannot be matched counts against both members before any residual does;
/// ties, and categories of one or two members, where every member scores the same, keep
/// `fallback`.
///
/// The grouping distance compares descriptors that do not see orientation; the template is
/// what every copy is then turned onto, and a member whose patch differs from its copies'
/// (a neighbour pressed against it, haze on one side) can fit a nearly symmetric copy best
/// half a turn round. The member that fits its copies best is the one least unlike them
/// where it matters, in the matching itself (the paper picks templates at random or by
/// hand). Cost: `m (m - 1) / 2` more pair fits for `m` members (mining the basis takes a
/// quarter longer).
pub fn matching_medoid(
    members: &[usize],
    fallback: usize,
    residual: impl Fn(usize, usize) -> Result<Option<f32>> + Sync,
) -> Result<usize> {
    let alike = 2; // fixed: one or two members score the same, each the other's only pair
    if members.len() <= alike {
        return Ok(fallback);
    }
    // pairs of positions in `members`
    let m = members.len();
    let pairs: Vec<(usize, usize)> = (0..m).flat_map(|a| (a + 1..m).map(move |b| (a, b))).collect();
    let fits: Vec<Option<f32>> =
        pairs.par_iter().map(|&(a, b)| residual(members[a], members[b])).collect::<Result<_>>()?;
    // per member: (pairs that could not be matched, summed residual), compared in that order
    let mut score = vec![(0usize, 0f64); m];
    for (&(a, b), fit) in pairs.iter().zip(&fits) {
        for p in [a, b] {
            match fit {
                Some(r) => score[p].1 += f64::from(*r),
                None => score[p].0 += 1,
            }
        }
    }
    let lower = |x: (usize, f64), y: (usize, f64)| x.0 < y.0 || (x.0 == y.0 && x.1 < y.1);
    let mut best = fallback;
    let mut best_score = members
        .iter()
        .position(|&d| d == fallback)
        .map_or((usize::MAX, f64::INFINITY), |p| score[p]);
    for (&d, &s) in members.iter().zip(&score) {
        if lower(s, best_score) {
            (best, best_score) = (d, s);
        }
    }
    Ok(best)
}

/// Choose templates (the members that match their copies best, [`matching_medoid`], unless
/// overridden) and estimate every instance's pose, matching the patches of
/// `sources[category]` (one source per category).
pub fn estimate_poses(
    grid: &PlaneGrid,
    dets: &Detections,
    sources: &[PatchSource<'_>],
    category: &[usize],
    distance: &DistanceMatrix,
    opts: &PoseOptions,
) -> Result<Poses> {
    let n = dets.detections.len();
    if category.len() != n || distance.n() != n {
        return Err(MiningError::SizeMismatch {
            what: "categories / distances vs detections",
            left: category.len(),
            right: n,
        });
    }
    let k = category.iter().max().map_or(0, |&m| m + 1);
    if sources.len() < k {
        return Err(MiningError::SizeMismatch {
            what: "patch sources vs categories",
            left: sources.len(),
            right: k,
        });
    }
    let mut chosen: Vec<Option<usize>> = vec![None; k];
    for &(c, d) in &opts.templates {
        if c >= k {
            return Err(MiningError::InvalidParameter {
                name: "template",
                reason: format!("category {c} does not exist (there are {k})"),
            });
        }
        if d >= n || category[d] != c {
            return Err(MiningError::InvalidParameter {
                name: "template",
                reason: format!(
                    "detection {d} is not a member of category {c} (members: {:?})",
                    (0..n).filter(|&i| category[i] == c).collect::<Vec<_>>()
                ),
            });
        }
        chosen[c] = Some(d);
    }
    // the patches of a pair: for slabs, as many levels as the taller of the two holds
    let patch = |i: usize, p: PatchRect, levels: usize| -> Result<(PlaneImage, Vec<f32>)> {
        let d = &dets.detections[i];
        let img = match sources[category[i]] {
            PatchSource::Plane(_, plane) => padded_crop(plane, p)?,
            PatchSource::Slab { vol, .. } => {
                let (lo, hi) = own_levels(vol, d);
                slab_crop(vol, p, lo, hi - lo + 1, levels)?
            }
        };
        let w = mask_in_patch(d, &d.own, p).to_weights();
        Ok((img, w))
    };
    let levels = |i: usize| match sources[category[i]] {
        PatchSource::Plane(..) => 0,
        PatchSource::Slab { vol, .. } => {
            let (lo, hi) = own_levels(vol, &dets.detections[i]);
            hi - lo + 1
        }
    };
    let centre_world = |p: PatchRect| {
        let (cx, cy) = p.centre();
        grid.to_world(cx, cy)
    };
    // the pose of instance `i` against template `t` on their tight and wide patches, with
    // the tight patches' weights; `None` when the pair cannot be matched (no overlap at any
    // pose)
    let rects = |t: usize, i: usize| {
        let irect = PatchRect::around(dets.detections[i].rect, opts.margin);
        let trect = PatchRect::around(dets.detections[t].rect, opts.margin);
        (trect, irect, levels(i).max(levels(t)))
    };
    let tight_of = |t: usize, i: usize, (trect, irect, k): (PatchRect, PatchRect, usize)| {
        Ok::<PatchPair, MiningError>((patch(t, trect, k)?, patch(i, irect, k)?))
    };
    let tight_pair = |t: usize, i: usize| tight_of(t, i, rects(t, i));
    let fit_pair = |t: usize, i: usize| -> Result<(Option<YawFit>, Vec<f32>, Vec<f32>)> {
        let (trect, irect, k) = rects(t, i);
        let tight = tight_of(t, i, (trect, irect, k))?;
        let reach = irect.half_diagonal().max(trect.half_diagonal())
            + opts.yaw.max_offset
            + ROTATION_SLACK_TEXELS;
        let wide =
            (patch(t, trect.holding_disc(reach), k)?, patch(i, irect.holding_disc(reach), k)?);
        let fit = match_pair(Patches::of(&tight), Patches::of(&wide), &opts.yaw).ok();
        let ((_, tw), (_, iw)) = tight;
        Ok((fit, tw, iw))
    };
    let mut templates = Vec::with_capacity(k);
    for (c, chosen) in chosen.into_iter().enumerate() {
        let members: Vec<usize> = (0..n).filter(|&i| category[i] == c).collect();
        let template = match chosen {
            Some(d) => d,
            // the choice compares pairs on their tight patches only: the wide patches'
            // check costs as much again and chose the same templates on the whole basis
            None => matching_medoid(&members, medoid(distance, &members)?, |t, i| {
                let tight = tight_pair(t, i)?;
                Ok(Patches::of(&tight).fit(&opts.yaw).ok().map(|f| f.residual))
            })?,
        };
        templates.push(template);
    }
    let poses: Vec<Result<Pose>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let t = templates[category[i]];
            let irect = PatchRect::around(dets.detections[i].rect, opts.margin);
            if i == t {
                return Ok(Pose {
                    yaw_deg: 0.0,
                    offset: (0.0, 0.0),
                    residual: 0.0,
                    position: centre_world(irect),
                });
            }
            let trect = PatchRect::around(dets.detections[t].rect, opts.margin);
            let c = centre_world(irect);
            // a pair that cannot be matched (no overlap at any pose) keeps the template's
            // orientation; its residual is marked -1
            let (Some(fit), tw, iw) = fit_pair(t, i)? else {
                return Ok(Pose { yaw_deg: 0.0, offset: (0.0, 0.0), residual: -1.0, position: c });
            };
            tracing::trace!(instance = i, template = t, yaw = fit.yaw_deg, "pose");
            let residual = match sources[category[i]] {
                PatchSource::Plane(..) => fit.residual,
                PatchSource::Slab { judge: (_, plane), .. } => yaw_residual_weighted(
                    &padded_crop(plane, trect)?,
                    Some(&tw),
                    &padded_crop(plane, irect)?,
                    Some(&iw),
                    fit.yaw_deg,
                    fit.offset,
                    opts.yaw.region,
                )
                .unwrap_or(-1.0),
            };
            Ok(Pose {
                yaw_deg: fit.yaw_deg,
                offset: fit.offset,
                residual,
                position: Vec2::new(
                    c.x + fit.offset.0 * grid.texel[0],
                    c.y + fit.offset.1 * grid.texel[1],
                ),
            })
        })
        .collect();
    let poses = poses.into_iter().collect::<Result<Vec<_>>>()?;
    let matched_on = sources[..k].iter().map(PatchSource::kind).collect();
    Ok(Poses { templates, poses, matched_on })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_template_is_the_member_that_fits_its_copies_best() {
        // members 3, 5, 7, 9; 3 (the grouping's medoid, say) fits every other badly, 7 fits
        // every other well
        let typical = |m: usize| match m {
            7 => 0.1,
            3 => 2.0,
            _ => 0.5,
        };
        let residual = |t: usize, i: usize| Ok(Some(typical(t) + typical(i)));
        assert_eq!(matching_medoid(&[3, 5, 7, 9], 3, residual).unwrap(), 7);
        // every pair matched once, as (earlier, later) in the members' order
        let seen = std::sync::Mutex::new(Vec::new());
        matching_medoid(&[3, 5, 7], 3, |t, i| {
            seen.lock().unwrap().push((t, i));
            Ok(Some(1.0))
        })
        .unwrap();
        let mut seen = seen.into_inner().unwrap();
        seen.sort_unstable();
        assert_eq!(seen, vec![(3, 5), (3, 7), (5, 7)]);
        // ties keep the fallback; one or two members keep it without matching
        assert_eq!(matching_medoid(&[3, 5, 7], 5, |_, _| Ok(Some(1.0))).unwrap(), 5);
        let never = |_: usize, _: usize| -> Result<Option<f32>> { panic!("no pair to match") };
        assert_eq!(matching_medoid(&[4, 8], 8, never).unwrap(), 8);
        assert_eq!(matching_medoid(&[4], 4, never).unwrap(), 4);
        // a pair that cannot be matched counts before any residual: 7 fits best where it
        // matches but cannot be matched with 9
        let residual = |t: usize, i: usize| {
            Ok(if (t, i) == (7, 9) { None } else { Some(typical(t) + typical(i)) })
        };
        assert_eq!(matching_medoid(&[3, 5, 7, 9], 3, residual).unwrap(), 5);
        // an error in any pair is returned
        let failing = |_: usize, _: usize| -> Result<Option<f32>> {
            Err(MiningError::Empty { what: "patch" })
        };
        assert!(matching_medoid(&[3, 5, 7], 3, failing).is_err());
    }

    #[test]
    fn padded_crops_repeat_edges_and_keep_centres() {
        let img = PlaneImage::from_fn(4, 5, 1, |r, c, _| (r * 10 + c) as f32).unwrap();
        let p = PatchRect::around(PixelRect::new(0, 0, 2, 2), 1);
        assert_eq!((p.r0, p.c0, p.rows, p.cols), (-1, -1, 4, 4));
        assert_eq!(p.centre(), (0.5, 0.5));
        let crop = padded_crop(&img, p).unwrap();
        assert_eq!(crop.get(0, 0).unwrap(), &[0.0]);
        assert_eq!(crop.get(1, 1).unwrap(), &[0.0]);
        assert_eq!(crop.get(2, 3).unwrap(), &[12.0]);
        assert_eq!(crop.get(3, 3).unwrap(), &[22.0]);
    }

    #[test]
    fn wide_patches_decide_which_way_round_a_long_object_is() {
        // A long thin bar (3 x 53 texels, channel 0) with a block beside its middle (channel
        // 1). The instance is the template at yaw 0 except that its block is turned a
        // quarter: crops of the middle alone see the block best matched a quarter turn
        // away, crops holding the whole bar see the bar decide.
        let block = |dx: i64, dy: i64| (2..=4).contains(&dx) && (-3..=1).contains(&dy);
        let object = |turned: bool| {
            move |dx: i64, dy: i64, k: usize| -> f32 {
                let on_block = if turned { block(-dy, dx) } else { block(dx, dy) };
                match k {
                    0 if dx.abs() <= 1 && (-40..=12).contains(&dy) && !on_block => 1.0,
                    1 if on_block => 1.5,
                    _ => 0.0,
                }
            }
        };
        let crop = |half: i64, f: &dyn Fn(i64, i64, usize) -> f32| {
            let n = (2 * half + 1) as usize;
            let img =
                PlaneImage::from_fn(n, n, 2, |r, c, k| f(c as i64 - half, r as i64 - half, k))
                    .unwrap();
            let w = (0..n * n)
                .map(|j| {
                    let (r, c) = ((j / n) as i64 - half, (j % n) as i64 - half);
                    if f(c, r, 0) + f(c, r, 1) > 0.0 { 1.0 } else { 0.0 }
                })
                .collect::<Vec<f32>>();
            (img, w)
        };
        let (t, i) = (object(false), object(true));
        let tight: PatchPair = (crop(5, &t), crop(5, &i));
        let wide: PatchPair = (crop(44, &t), crop(44, &i));
        let opts = PoseOptions::default().yaw;
        let off_zero = |yaw: f32| yaw_difference(yaw, 0.0, 360.0);
        let trap = Patches::of(&tight).fit(&opts).unwrap();
        assert!(off_zero(trap.yaw_deg) > 45.0, "the middle alone should mislead: {trap:?}");
        let fit = match_pair(Patches::of(&tight), Patches::of(&wide), &opts).unwrap();
        // the basin of the bar (the tight refinement there still leans a little towards
        // the block)
        assert!(off_zero(fit.yaw_deg) < 5.0, "{fit:?}");
        // a disc has no way round: whatever the wide search finds is not decisive, and the
        // tight fit stands
        let disc = |dx: i64, dy: i64, k: usize| -> f32 {
            if k == 0 && dx * dx + dy * dy <= 16 { 1.0 } else { 0.0 }
        };
        let tight: PatchPair = (crop(6, &disc), crop(6, &disc));
        let wide: PatchPair = (crop(12, &disc), crop(12, &disc));
        let alone = Patches::of(&tight).fit(&opts).unwrap();
        let fit = match_pair(Patches::of(&tight), Patches::of(&wide), &opts).unwrap();
        assert_eq!(fit, alone);
        // patches grown to hold a disc keep their centre
        let p = PatchRect { r0: 10, c0: -3, rows: 4, cols: 31 };
        let g = p.holding_disc(p.half_diagonal() + 1.0);
        assert_eq!(g.centre(), p.centre());
        assert!(g.rows as f32 >= 2.0 * (p.half_diagonal() + 1.0) + 1.0);
        assert!(g.cols as f32 >= 2.0 * (p.half_diagonal() + 1.0) + 1.0);
        assert_eq!(p.holding_disc(1.0), p);
    }

    #[test]
    fn slabs_turn_a_laptop_on_a_table_the_right_way_round() {
        use crate::yaw::estimate_yaw;
        // A table top (levels 8-9) over a crossbar (levels 2-7) along column 8, and two
        // laptops on the table (base level 9: deck at 10-11, screen up to 16 along one long
        // edge), the second turned by 180 degrees. The crossbar lies under both laptops on
        // the same side, so column features (here: column sums, as the density plane
        // describes a column) hold the laptop's orientation and the crossbar's.
        let (rows, cols, nz) = (40, 24, 20);
        let mut vol = OpacityVolume::empty(rows, cols, nz, 0.05);
        vol.fill_box(2..38, 2..22, 8..10, 0.95);
        vol.fill_box(2..38, 7..10, 2..8, 0.95);
        vol.fill_box(8..15, 6..17, 10..12, 0.95);
        vol.fill_box(8..9, 6..17, 10..17, 0.95); // screen at the laptop's low-row edge
        vol.fill_box(25..32, 6..17, 10..12, 0.95);
        vol.fill_box(31..32, 6..17, 10..17, 0.95); // turned: screen at the high-row edge
        let template = PatchRect { r0: 5, c0: 3, rows: 13, cols: 17 };
        let instance = PatchRect { r0: 22, c0: 3, rows: 13, cols: 17 };
        let columns = |p: PatchRect| {
            PlaneImage::from_fn(p.rows, p.cols, 1, |r, c, _| {
                vol.column(p.r0 as usize + r, p.c0 as usize + c).iter().sum()
            })
            .unwrap()
        };
        let opts = YawOptions::default();
        let fit = estimate_yaw(&columns(template), &columns(instance), &opts).unwrap();
        let off_by = |yaw: f32, want: f32| {
            let d = (yaw - want).rem_euclid(360.0);
            d.min(360.0 - d)
        };
        assert!(off_by(fit.yaw_deg, 0.0) < 2.0, "columns: {fit:?}");
        // the slabs from the level above the base (9, the table top) to the screen's top
        let (lo, hi) = vol.levels_between(0.45, 0.8);
        assert_eq!((lo, hi), (10, 16));
        let slab = |p| slab_crop(&vol, p, lo, hi - lo + 1, 9).unwrap();
        let fit = estimate_yaw(&slab(template), &slab(instance), &opts).unwrap();
        assert!(off_by(fit.yaw_deg, 180.0) < 2.0, "slabs: {fit:?}");
        assert!(fit.residual < 1e-3, "slabs: {fit:?}");
        // level ranges stay inside the volume and never end below their start
        assert_eq!(vol.levels_between(0.45, 0.3), (10, 10));
        assert_eq!(vol.levels_between(0.45, 5.0), (10, 19));
        assert_eq!(vol.levels_between(2.0, 5.0), (19, 19));
        // with no floor, a base is the level below the ground, so a ground at the bottom
        // of the volume is kept
        assert_eq!(vol.levels_between(vol.height_below(0), 0.3), (0, 6));
        assert_eq!(vol.levels_between(vol.height_below(4), 0.3), (4, 6));
        assert_eq!(vol.levels_between(f32::NAN, 0.3), (0, 6));
        // channels past the object's own levels are zero, and so are levels above the
        // volume; outside the plane the edge texels repeat
        vol.data[18] = 0.5; // row 0, column 0, level 18
        vol.data[19] = 0.7;
        let edge = PatchRect { r0: -2, c0: -1, rows: 3, cols: 2 };
        let crop = slab_crop(&vol, edge, 18, 2, 4).unwrap();
        for (r, c) in [(0, 0), (2, 0), (2, 1), (0, 1)] {
            assert_eq!(crop.get(r, c).unwrap(), [0.5, 0.7, 0.0, 0.0], "texel {r} {c}");
        }
        assert_eq!(slab_crop(&vol, edge, 18, 1, 2).unwrap().get(2, 1).unwrap(), [0.5, 0.0]);
        assert_eq!(slab_crop(&vol, edge, 19, 3, 3).unwrap().get(2, 1).unwrap(), [0.7, 0.0, 0.0]);
    }
}
