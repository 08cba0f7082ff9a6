//! Builders the unit tests share: detections and a scene of them made from plain masks.

use crate::detect::{Detection, Detections};
use crate::image::Mask;
use crate::planes::PlaneGrid;

/// A free detection of the set texels of `full` (a mask over the whole plane), on one-unit
/// texels: its box, that footprint as its own texels, base 0 and top 1.
pub(crate) fn detection(id: usize, grid: &PlaneGrid, full: &Mask) -> Detection {
    let rect = full.bbox().expect("a mask with a texel set");
    let footprint = full.crop(rect).expect("its box lies inside it");
    Detection {
        id,
        rect,
        own: footprint.clone(),
        area: footprint.count() as f32,
        footprint,
        world: grid.rect_to_world(rect),
        base: 0.0,
        top: 1.0,
        shape_top: 1.0,
        parent: None,
        children: Vec::new(),
    }
}

/// The detections of `masks` (each over the whole plane, one per detection, in order) on a
/// plane of one-unit texels with no floor.
pub(crate) fn scene(masks: &[Mask]) -> Detections {
    let (rows, cols) = (masks[0].rows, masks[0].cols);
    let grid = PlaneGrid { rows, cols, origin: [0.0, 0.0], texel: [1.0, 1.0] };
    Detections {
        grid,
        floor: None,
        start_level: 0,
        ground_level: 0,
        threshold: 0.5,
        voxel_threshold: 0.5,
        blur_levels: 3,
        evidence: vec![1.0; rows * cols],
        mask: Mask::from_fn(rows, cols, |r, c| masks.iter().any(|m| m.get(r, c))),
        detections: masks.iter().enumerate().map(|(i, m)| detection(i, &grid, m)).collect(),
        removed: Vec::new(),
    }
}

/// A `rows x cols` mask holding the rectangle of rows `r0..r1` and columns `c0..c1`.
pub(crate) fn rect_mask(
    rows: usize,
    cols: usize,
    r0: usize,
    c0: usize,
    r1: usize,
    c1: usize,
) -> Mask {
    Mask::from_fn(rows, cols, |r, c| (r0..r1).contains(&r) && (c0..c1).contains(&c))
}
