//! Stage 2: binarisation. The evidence map (or a plane's features) is split with K-means;
//! the lowest cluster (for features: the largest) is background. Specks smaller than the
//! smallest object are removed.

use super::context::Ctx;
use super::params::Preset;
use crate::error::{MiningError, Result};
use crate::image::{Mask, PlaneImage};
use crate::kmeans::{BackgroundRule, KMeansOptions, kmeans, object_mask_from_plane};

/// Threshold between the background cluster and the next one of a 1-D K-means, and per
/// value whether it lies outside the background cluster.
pub(super) fn kmeans_threshold(values: &[f32], k: usize, seed: u64) -> Result<(f32, Vec<bool>)> {
    let km = kmeans(values, 1, None, &KMeansOptions { k, seed, ..Default::default() })?;
    let mut cents: Vec<(f32, usize)> =
        (0..km.k).filter(|&j| km.cluster_sizes()[j] > 0).map(|j| (km.centroid(j)[0], j)).collect();
    cents.sort_by(|a, b| a.0.total_cmp(&b.0));
    let tau = if cents.len() >= 2 { 0.5 * (cents[0].0 + cents[1].0) } else { f32::INFINITY };
    let bg = cents.first().map_or(u32::MAX, |c| c.1 as u32);
    Ok((tau, km.labels.iter().map(|&l| l != bg).collect()))
}

/// The first-round object mask: the evidence clusters above the background one, or (for
/// [`super::Evidence::PlaneFeatures`]) the plane's feature clusters other than the largest, among
/// the texels holding some density (half the evidence threshold), opened once against the
/// speckle of a noisy feature plane. Components smaller than the smallest object go.
pub(super) fn binarise(cx: &Ctx, feature: Option<&PlaneImage>) -> Result<Mask> {
    let (rows, cols) = (cx.grid.rows, cx.grid.cols);
    let p = cx.p;
    let mask = if p.needs_feature_plane() {
        let Some(plane) = feature else {
            return Err(MiningError::InvalidParameter {
                name: "detect-on",
                reason: format!("no {} plane was given", p.on.name()),
            });
        };
        if (plane.rows, plane.cols) != (rows, cols) {
            return Err(MiningError::SizeMismatch {
                what: "feature plane vs ground grid (texels)",
                left: plane.rows * plane.cols,
                right: rows * cols,
            });
        }
        if p.k > plane.texels() {
            return Err(MiningError::TooManyClusters { k: p.k, points: plane.texels() });
        }
        let m = object_mask_from_plane(plane, p.k, BackgroundRule::Largest, p.seed)?;
        if p.preset == Preset::Paper {
            // the paper's mask is the object clusters themselves
            m
        } else {
            let ev = &cx.evidence;
            let m =
                Mask::from_fn(rows, cols, |r, c| m.get(r, c) && ev[r * cols + c] >= 0.5 * cx.tau_e);
            crate::morphology::open(&m, 1)?
        }
    } else {
        Mask::new(rows, cols, cx.above.clone())?
    };
    cx.without_specks(&mask)
}
