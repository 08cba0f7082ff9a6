//! Image-space algorithms for AssetField asset mining (paper Sec. 3.2-3.4), on plain arrays.
//!
//! The pipeline these pieces serve: binarise a density plane with K-means
//! ([`kmeans::object_mask_from_scalar`]), clean it ([`morphology`]), find objects with
//! Suzuki-Abe border following ([`contours::components`]), discretise an RGB/semantic plane
//! into labels ([`kmeans::discretize`]), compare object patches through label histograms and
//! the Jensen-Shannon divergence ([`histogram`]), group them with agglomerative clustering
//! ([`mod@agglomerative`]), pick a template per group ([`mod@medoid`]) and estimate each instance's
//! yaw relative to its template ([`yaw`], built on [`mod@rotate`]).
//!
//! Conventions: images are row-major with channels fastest; rows follow the ground **y** axis
//! and columns the ground **x** axis; texel centres sit at integer coordinates `(x, y) =
//! (col, row)`. Angles are in degrees, counter-clockwise in the x-right / y-up ground frame
//! (see [`mod@rotate`]). Nothing here panics on bad input; errors are [`MiningError`].

pub mod agglomerative;
pub mod content;
pub mod contours;
pub mod copies;
pub mod detect;
pub mod error;
pub mod fringe;
pub mod group;
pub mod halves;
pub mod histogram;
pub mod image;
pub mod kmeans;
pub mod layout_out;
pub mod medoid;
pub mod merge;
pub mod metrics;
pub mod morphology;
pub mod picture;
pub mod pipeline;
pub mod pivot;
pub mod planes;
pub mod pose;
pub mod regroup;
mod rng;
pub mod rotate;
#[cfg(test)]
mod test_support;
pub mod tuned;
pub mod yaw;

pub use agglomerative::{Cut, Dendrogram, DistanceMatrix, Linkage, Merge, agglomerative, linkage};
pub use contours::{Border, Region, components, find_borders, label_components};
pub use error::{MiningError, Result};
pub use histogram::{jsd, jsd_matrix, label_histogram, patch_histogram};
pub use image::{LabelImage, Mask, PixelRect, PlaneImage};
pub use kmeans::{
    BackgroundRule, Discretized, KMeans, KMeansOptions, discretize, kmeans, object_mask_from_plane,
    object_mask_from_scalar,
};
pub use medoid::{cluster_medoids, medoid};
pub use morphology::{close, dilate, erode, open, remove_small};
pub use rotate::{Rotated, rotate, rotate_with_coverage};
pub use yaw::{
    CompareRegion, YawFit, YawOptions, estimate_yaw, estimate_yaw_weighted, yaw_residual,
};
