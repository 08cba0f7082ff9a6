//! Templates and poses (paper Sec. 3.3, template matching): one template per category (the
//! medoid under the grouping distance, or the user's choice), and every instance's yaw and
//! position relative to it, found by rotating the template's feature patch onto the
//! instance's ([`crate::yaw::estimate_yaw_weighted`]: coarse scan, golden-section
//! refinement, sub-texel offset).
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
use crate::planes::PlaneGrid;
use crate::yaw::{CompareRegion, YawOptions, estimate_yaw_weighted};

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

/// Parameters of [`estimate_poses`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseOptions {
    /// Patch margin around the bounding boxes, in texels.
    pub margin: usize,
    /// Template overrides: (category, detection).
    pub templates: Vec<(usize, usize)>,
    pub yaw: YawOptions,
}

impl Default for PoseOptions {
    fn default() -> Self {
        PoseOptions {
            margin: 3,
            templates: Vec::new(),
            yaw: YawOptions {
                step_deg: 4.0,
                period_deg: 360.0,
                tol_deg: 0.05,
                max_offset: 1.5,
                align_centroids: true,
                region: CompareRegion::Overlap,
                starts: 3,
            },
        }
    }
}

/// Choose templates (medoids unless overridden) and estimate every instance's pose on the
/// `feature` plane.
pub fn estimate_poses(
    grid: &PlaneGrid,
    dets: &Detections,
    feature: &PlaneImage,
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
    let mut templates = Vec::with_capacity(k);
    for c in 0..k {
        let members: Vec<usize> = (0..n).filter(|&i| category[i] == c).collect();
        templates.push(medoid(distance, &members)?);
    }
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
        templates[c] = d;
    }
    let patch = |i: usize| -> Result<(PlaneImage, Vec<f32>, PatchRect)> {
        let d = &dets.detections[i];
        let p = PatchRect::around(d.rect, opts.margin);
        let img = padded_crop(feature, p)?;
        let w = mask_in_patch(d, &d.own, p).to_weights();
        Ok((img, w, p))
    };
    let centre_world = |p: PatchRect| {
        let (cx, cy) = p.centre();
        grid.to_world(cx, cy)
    };
    let poses: Vec<Result<Pose>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let t = templates[category[i]];
            let (ip, iw, irect) = patch(i)?;
            if i == t {
                return Ok(Pose {
                    yaw_deg: 0.0,
                    offset: (0.0, 0.0),
                    residual: 0.0,
                    position: centre_world(irect),
                });
            }
            let (tp, tw, _) = patch(t)?;
            let c = centre_world(irect);
            // a pair that cannot be matched (no overlap at any pose) keeps the template's
            // orientation; its residual is marked -1
            let Ok(fit) = estimate_yaw_weighted(&tp, Some(&tw), &ip, Some(&iw), &opts.yaw) else {
                return Ok(Pose { yaw_deg: 0.0, offset: (0.0, 0.0), residual: -1.0, position: c });
            };
            Ok(Pose {
                yaw_deg: fit.yaw_deg,
                offset: fit.offset,
                residual: fit.residual,
                position: Vec2::new(
                    c.x + fit.offset.0 * grid.texel[0],
                    c.y + fit.offset.1 * grid.texel[1],
                ),
            })
        })
        .collect();
    let poses = poses.into_iter().collect::<Result<Vec<_>>>()?;
    Ok(Poses { templates, poses })
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
