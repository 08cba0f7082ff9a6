//! Tests of the stages on synthetic opacity volumes (5 cm texels and levels, so "a box of
//! six levels" is 0.3 m tall in the comments).

use super::merge::{fragments_merged, group_merged};
use super::shape::{Part, is_thin};
use super::split::{encloses_an_inside, holds_an_object, stands};
use super::unpack::{height_weights, normalised_axis};
use super::*;
use crate::image::{Mask, PixelRect};
use assetfield_core::Rect2;
use glam::Vec2;

/// The parameters for these volumes: the defaults' lengths re-expressed at their 5 cm
/// texels (the defaults count texels of 2.8 cm: an 8 cm window is 3 levels there and 2
/// here), and a minimum area of 4 texels (0.01 m^2).
fn params() -> DetectParams {
    DetectParams {
        min_area_texels: 4,
        blur_levels: 2,
        wall_half_thickness_texels: 2.0,
        bridge_radius_texels: 1,
        ..Default::default()
    }
}

/// A volume with a floor slab at levels 0..=1 and boxes standing on it.
fn scene() -> OpacityVolume {
    let (rows, cols, nz) = (40, 60, 20);
    let mut data = vec![0f32; rows * cols * nz];
    let mut fill = |r0: usize, r1: usize, c0: usize, c1: usize, k0: usize, k1: usize| {
        for r in r0..r1 {
            for c in c0..c1 {
                for k in k0..k1 {
                    data[(r * cols + c) * nz + k] = 0.9;
                }
            }
        }
    };
    fill(0, 40, 0, 60, 0, 2); // floor
    fill(5, 12, 5, 12, 2, 8); // a box
    fill(5, 12, 20, 27, 2, 8); // another
    fill(20, 34, 10, 40, 9, 10); // table top
    fill(20, 21, 10, 11, 2, 9); // a leg
    fill(25, 29, 20, 26, 10, 14); // an object on the table
    fill(0, 1, 0, 60, 2, 10); // a wall along the bottom edge
    OpacityVolume { rows, cols, nz, z0: 0.0, dz: 0.05, data }
}

#[test]
fn floor_objects_walls_and_supported_objects() {
    let vol = scene();
    let f = floor_band(&vol, &params()).unwrap();
    assert_eq!((f.lo, f.hi), (0, 1));
    let grid = PlaneGrid { cols: 60, rows: 40, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let color = PlaneImage::from_fn(40, 60, 3, |r, c, k| {
        if (25..29).contains(&r) && (20..26).contains(&c) { 1.0 } else { k as f32 * 0.1 }
    })
    .unwrap();
    let opts = params();
    let d = detect(&grid, &vol, &color, None, &opts).unwrap();
    let boxes: Vec<(PixelRect, Option<usize>)> =
        d.detections.iter().map(|x| (x.rect, x.parent)).collect();
    assert_eq!(d.detections.len(), 4, "{boxes:?} removed {:?}", d.removed);
    assert_a_wall_removed(&d);
    let on_table = d.detections.iter().find(|x| x.parent.is_some()).unwrap();
    assert_eq!(on_table.rect, PixelRect::new(25, 20, 29, 26));
    let table = &d.detections[on_table.parent.unwrap()];
    assert_eq!(table.rect, PixelRect::new(20, 10, 34, 40));
    assert!((on_table.base - 0.45).abs() < 1e-4, "{}", on_table.base);
    assert!((table.top - 0.45).abs() < 1e-4);
    // a box on the floor has its own levels from the ground level (one level of margin
    // above the floor's top, against haze on the floor) up
    assert_eq!(d.ground_level, 3);
    let boxd = d.detections.iter().find(|x| x.rect == PixelRect::new(5, 5, 12, 12)).unwrap();
    assert!((boxd.base - vol.height(2)).abs() < 1e-6, "{}", boxd.base);
    assert_eq!(vol.levels_between(boxd.base, boxd.shape_top), (3, 7));
    assert!(table.own.count() < table.footprint.count());
}

#[test]
fn touching_objects_separate_in_3d() {
    // a low box under the edge of a high slab on its own legs: one region in 2D, two
    // objects in 3D
    let (rows, cols, nz) = (30, 40, 20);
    let mut data = vec![0f32; rows * cols * nz];
    let mut fill = |r0: usize, r1: usize, c0: usize, c1: usize, k0: usize, k1: usize| {
        for r in r0..r1 {
            for c in c0..c1 {
                for k in k0..k1 {
                    data[(r * cols + c) * nz + k] = 0.9;
                }
            }
        }
    };
    fill(5, 25, 5, 25, 14, 15); // table top
    fill(5, 7, 5, 25, 0, 14); // its legs (two walls)
    fill(23, 25, 5, 25, 0, 14);
    fill(10, 20, 20, 35, 0, 8); // a box partly under the top
    let vol = OpacityVolume { rows, cols, nz, z0: 0.0, dz: 0.05, data };
    let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let color = PlaneImage::zeros(rows, cols, 2).unwrap();
    let opts = params();
    let d = detect(&grid, &vol, &color, None, &opts).unwrap();
    let mut rects: Vec<PixelRect> = d.detections.iter().map(|x| x.rect).collect();
    rects.sort_by_key(|r| r.c0);
    assert_eq!(rects, vec![PixelRect::new(5, 5, 25, 25), PixelRect::new(10, 20, 20, 35)]);
    // the table's own texels leave out the box partly under it; the box keeps them
    let table = d.detections.iter().find(|x| x.rect.c0 == 5).unwrap();
    let boxd = d.detections.iter().find(|x| x.rect.c0 == 20).unwrap();
    assert!(!table.own.get(15 - 5, 22 - 5) && table.own.get(15 - 5, 10 - 5));
    assert!(boxd.own.get(15 - 10, 22 - 20));
    // with no floor, both stand on the level below the ground, so their own levels
    // start at their lowest one
    assert!(d.floor.is_none());
    for x in [table, boxd] {
        assert!((x.base - vol.height_below(0)).abs() < 1e-6, "{}", x.base);
    }
    assert_eq!(vol.levels_between(boxd.base, boxd.shape_top), (0, 7));
    let unsplit = DetectParams {
        stages: Stages {
            split_3d: false,
            split_bridges: false,
            split_colour: false,
            ..Stages::ALL
        },
        ..opts
    };
    assert_eq!(detect(&grid, &vol, &color, None, &unsplit).unwrap().detections.len(), 1);
}

/// An empty volume with a floor slab at levels 0..=1.
fn floor_volume(rows: usize, cols: usize, nz: usize) -> OpacityVolume {
    let mut v = OpacityVolume::empty(rows, cols, nz, 0.05);
    fill(&mut v, (0, rows), (0, cols), (0, 2), 0.95);
    v
}

/// [`floor_volume`] 30 levels high with a room's walls round it: two texels thick, levels
/// 2..20.
fn walled_room(rows: usize, cols: usize) -> OpacityVolume {
    let mut v = floor_volume(rows, cols, 30);
    fill(&mut v, (0, rows), (0, cols), (2, 20), 0.95);
    fill(&mut v, (2, rows - 2), (2, cols - 2), (2, 20), 0.0);
    v
}

/// The sides of a long object whose top the field did not learn, over box `b`: walls three
/// texels thick, levels 2..16, nothing inside.
fn roofless_shell(v: &mut OpacityVolume, b: PixelRect) {
    fill(v, (b.r0, b.r1), (b.c0, b.c1), (2, 16), 0.95);
    fill(v, (b.r0 + 3, b.r1 - 3), (b.c0 + 3, b.c1 - 3), (2, 16), 0.0);
}

/// The boxes of three long objects (20 x 40 texels) in contact with their top-left corner at
/// `(r, c)`: the second below the first, touching it along 25 texels, the third continuing
/// the first end to end.
fn three_shells_in_contact(r: usize, c: usize) -> [PixelRect; 3] {
    [
        PixelRect::new(r, c, r + 20, c + 40),
        PixelRect::new(r + 20, c + 15, r + 40, c + 55),
        PixelRect::new(r, c + 40, r + 20, c + 80),
    ]
}

/// Something was removed as a wall.
fn assert_a_wall_removed(d: &Detections) {
    assert!(
        d.removed.iter().any(|r| matches!(r.reason, RemovalReason::Wall { .. })),
        "{:?}",
        d.removed
    );
}

/// The detections are `want`, each within a texel, and nothing else.
fn assert_found_exactly(d: &Detections, want: &[PixelRect]) {
    let boxes = rects(d);
    for &w in want {
        assert!(boxes.iter().any(|&r| within_a_texel(r, w)), "{w:?} in {boxes:?}");
    }
    assert_eq!(boxes.len(), want.len(), "{boxes:?} removed {:?}", d.removed);
}

/// Whether two boxes agree within one texel on every side.
fn within_a_texel(r: PixelRect, want: PixelRect) -> bool {
    r.r0.abs_diff(want.r0) <= 1
        && r.c0.abs_diff(want.c0) <= 1
        && r.r1.abs_diff(want.r1) <= 1
        && r.c1.abs_diff(want.c1) <= 1
}

/// A pallet over rows 10..30, columns 10..34: three runners (level 2) under a deck
/// (level 3), 1.0 x 1.2 m.
fn pallet(v: &mut OpacityVolume) {
    for r0 in [10, 19, 28] {
        fill(v, (r0, r0 + 2), (10, 34), (2, 3), 0.95);
    }
    fill(v, (10, 30), (10, 34), (3, 4), 0.95);
}

/// The crate of the pallet tests (rows 12..28, columns 14..30) in one colour, the rest
/// in another.
fn crate_colour() -> PlaneImage {
    painted(50, 50, (12..28, 14..30), [0.8, 0.6, 0.3], [0.5, 0.4, 0.3])
}

/// The crate is found standing on the pallet, give or take the one-texel margin its
/// colour cluster may take along.
fn assert_the_crate_unpacks(v: &OpacityVolume) {
    let d = detect_small(v, &crate_colour());
    let r = only_child(&d).rect;
    assert!(within_a_texel(r, PixelRect::new(12, 14, 28, 30)), "{r:?}");
}

fn fill(v: &mut OpacityVolume, r: (usize, usize), c: (usize, usize), k: (usize, usize), o: f32) {
    v.fill_box(r.0..r.1, c.0..c.1, k.0..k.1, o);
}

/// A colour plane of `rows x cols`: `inside` over the texel rectangle `rect` (rows,
/// columns), `outside` elsewhere.
fn painted(
    rows: usize,
    cols: usize,
    rect: (std::ops::Range<usize>, std::ops::Range<usize>),
    inside: [f32; 3],
    outside: [f32; 3],
) -> PlaneImage {
    painted_where(rows, cols, |r, c| rect.0.contains(&r) && rect.1.contains(&c), inside, outside)
}

/// A colour plane of `rows x cols`: `inside` where `at(row, column)` holds, `outside`
/// elsewhere.
fn painted_where(
    rows: usize,
    cols: usize,
    at: impl Fn(usize, usize) -> bool,
    inside: [f32; 3],
    outside: [f32; 3],
) -> PlaneImage {
    PlaneImage::from_fn(rows, cols, 3, |r, c, k| if at(r, c) { inside[k] } else { outside[k] })
        .unwrap()
}

/// Detection at 5 cm texels with a small minimum area (the unpacking tests).
fn detect_small(v: &OpacityVolume, color: &PlaneImage) -> Detections {
    let grid = PlaneGrid { cols: v.cols, rows: v.rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let opts = params();
    detect(&grid, v, color, None, &opts).unwrap()
}

/// The one object [`detect_small`] finds standing on another lies within a texel of
/// `expected`.
fn assert_child_within_a_texel(v: &OpacityVolume, color: &PlaneImage, expected: PixelRect) {
    let d = detect_small(v, color);
    let r = only_child(&d).rect;
    assert!(within_a_texel(r, expected), "{r:?}");
}

/// The one object standing on another, of exactly two detections.
fn only_child(d: &Detections) -> &Detection {
    let boxes: Vec<(PixelRect, Option<usize>)> =
        d.detections.iter().map(|x| (x.rect, x.parent)).collect();
    assert_eq!(d.detections.len(), 2, "{boxes:?}");
    d.detections.iter().find(|x| x.parent.is_some()).unwrap()
}

fn rects(d: &Detections) -> Vec<PixelRect> {
    let mut v: Vec<PixelRect> = d.detections.iter().map(|x| x.rect).collect();
    v.sort_by_key(|r| (r.c0, r.r0));
    v
}

#[test]
fn an_object_found_twice_keeps_the_copy_standing_on_its_host() {
    let det = |id: usize, rect: PixelRect, top: f32, parent: Option<usize>| {
        let mut footprint = Mask::empty(rect.rows(), rect.cols()).unwrap();
        footprint.data.fill(true);
        Detection {
            id,
            rect,
            own: footprint.clone(),
            footprint,
            world: Rect2::EMPTY,
            area: 0.0,
            base: 0.0,
            top,
            shape_top: top,
            parent,
            children: Vec::new(),
        }
    };
    let mut table = det(0, PixelRect::new(0, 0, 20, 30), 0.75, None);
    table.children = vec![1, 3];
    let lamp = det(1, PixelRect::new(5, 5, 12, 12), 1.2, Some(0));
    // the lamp's column again, from the ground: dropped
    let twice = det(2, PixelRect::new(5, 5, 13, 12), 1.2, None);
    // a laptop over a chair pushed under the table: kept (the chair is much larger)
    let laptop = det(3, PixelRect::new(14, 20, 17, 24), 0.8, Some(0));
    let chair = det(4, PixelRect::new(12, 18, 24, 30), 0.8, None);
    let kept = drop_duplicates(vec![table, lamp, twice, laptop, chair], 0.1);
    let rects: Vec<PixelRect> = kept.iter().map(|d| d.rect).collect();
    assert_eq!(rects.len(), 4, "{rects:?}");
    assert!(!rects.contains(&PixelRect::new(5, 5, 13, 12)));
    // renumbered: the laptop is now 2 and still the table's child
    assert_eq!(kept[0].children, vec![1, 2]);
    assert_eq!((kept[2].id, kept[2].parent), (2, Some(0)));
    assert_eq!((kept[3].id, kept[3].parent), (3, None));
}

#[test]
fn pivots_sit_at_the_centre_of_the_ground_contact() {
    let (rows, cols) = (40, 60);
    let mut v = floor_volume(rows, cols, 20);
    // a street lamp: a pole at one end of its box, an arm and a head reaching over
    fill(&mut v, (10, 12), (10, 12), (2, 18), 0.95);
    fill(&mut v, (9, 12), (10, 30), (17, 19), 0.95);
    fill(&mut v, (6, 15), (22, 30), (14, 19), 0.95);
    // paint on the floor under the head: one level, not a contact
    fill(&mut v, (7, 14), (23, 29), (3, 4), 0.95);
    // a table on four legs: turns about its centre
    for (r, c) in [(25, 10), (25, 28), (33, 10), (33, 28)] {
        fill(&mut v, (r, r + 2), (c, c + 2), (2, 9), 0.95);
    }
    fill(&mut v, (25, 35), (10, 30), (9, 10), 0.95);
    // a chair whose foot is lost in the floor, touching down only along a thin panel at
    // one edge: a strip is no post, it turns about its centre
    fill(&mut v, (8, 16), (40, 50), (5, 12), 0.95);
    fill(&mut v, (8, 16), (40, 41), (2, 12), 0.95);
    let color = PlaneImage::from_fn(rows, cols, 3, |_, _, k| k as f32 * 0.3).unwrap();
    let d = detect_small(&v, &color);
    assert_eq!(
        rects(&d),
        vec![
            PixelRect::new(6, 10, 15, 30),
            PixelRect::new(25, 10, 35, 30),
            PixelRect::new(8, 40, 16, 50)
        ],
        "{:?}",
        d.removed
    );
    let pivots = crate::pivot::contact_pivots(&v, &d, crate::yaw::YawOptions::default().max_offset);
    for (det, p) in d.detections.iter().zip(&pivots) {
        let centre = crate::pivot::box_centre(det);
        if det.rect.r0 == 6 {
            // the pole's centre: texels 10..12 at 5 cm, between the centres of 10 and 11
            assert!((*p - Vec2::new(0.525, 0.525)).length() < 1e-4, "lamp pivot {p}");
            assert!((centre.x - p.x) > 0.4, "the box centre {centre} is out on the arm");
        } else {
            assert_eq!(*p, centre, "{:?}: pivot at the box centre", det.rect);
        }
    }
}

#[test]
fn thin_bridges_and_colour_boundaries_separate_objects() {
    let (rows, cols) = (40, 60);
    let mut v = floor_volume(rows, cols, 20);
    fill(&mut v, (5, 15), (5, 15), (2, 10), 0.95); // a box
    fill(&mut v, (5, 15), (25, 35), (2, 10), 0.95); // another
    fill(&mut v, (9, 10), (15, 25), (3, 5), 0.95); // a one-texel haze bridge between them
    // an L of two differently coloured boxes of different heights that touch along a
    // short edge
    fill(&mut v, (22, 36), (5, 13), (2, 12), 0.95);
    fill(&mut v, (22, 30), (13, 27), (2, 8), 0.95);
    // the red in one colour, the rest in another
    let color = painted(rows, cols, (22..30, 13..27), [1.0, 0.1, 0.1], [0.1, 0.2, 0.9]);
    let d = detect_small(&v, &color);
    assert_eq!(
        rects(&d),
        vec![
            PixelRect::new(5, 5, 15, 15),
            PixelRect::new(22, 5, 36, 13),
            PixelRect::new(22, 13, 30, 27),
            PixelRect::new(5, 25, 15, 35),
        ],
        "{:?}",
        d.removed
    );
    // without separation: the bridged pair and the L are one object each
    let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let joined = DetectParams {
        stages: Stages {
            split_3d: false,
            split_bridges: false,
            split_colour: false,
            ..Stages::ALL
        },
        ..params()
    };
    assert_eq!(detect(&grid, &v, &color, None, &joined).unwrap().detections.len(), 2);
}

#[test]
fn neighbours_of_one_height_and_different_colours_separate() {
    let (rows, cols) = (40, 60);
    // two blocks of one height and different colours touching along a short edge (a
    // tenth of the smaller one's outline), as an armchair's arm against a sofa's
    let mut v = floor_volume(rows, cols, 20);
    fill(&mut v, (2, 26), (5, 15), (2, 10), 0.95);
    fill(&mut v, (16, 36), (15, 35), (2, 10), 0.95);
    let color = painted(rows, cols, (2..26, 5..15), [0.9, 0.6, 0.2], [0.35, 0.47, 0.4]);
    let d = detect_small(&v, &color);
    assert_eq!(
        rects(&d),
        vec![PixelRect::new(2, 5, 26, 15), PixelRect::new(16, 15, 36, 35)],
        "{:?}",
        d.removed
    );
}

#[test]
fn neighbours_of_one_colour_and_different_heights_separate() {
    // a tall bookcase (6 x 30 texels, levels 2..20) with a low chest against its front
    // (14 x 14, levels 2..8), one colour: two objects; a chair of the same colour (a seat
    // with its back along one side, both one outline) stays one
    let (rows, cols) = (60, 60);
    let mut v = floor_volume(rows, cols, 30);
    fill(&mut v, (10, 16), (10, 40), (2, 20), 0.95);
    fill(&mut v, (16, 30), (20, 34), (2, 8), 0.95);
    fill(&mut v, (40, 52), (40, 52), (2, 6), 0.95); // the seat
    fill(&mut v, (40, 42), (40, 52), (6, 14), 0.95); // the back
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    let want = [
        PixelRect::new(10, 10, 16, 40),
        PixelRect::new(16, 20, 30, 34),
        PixelRect::new(40, 40, 52, 52),
    ];
    assert_found_exactly(&d, &want);
}

#[test]
fn a_colour_split_along_an_object_s_own_colours_is_not_made() {
    // a two-tone sofa (its back, rows 0..8, in one colour; its seat, rows 8..16, in another)
    // with a chair of the seat's colour pushed against its front: the region is concave
    // (0.86), and the back differs in colour, stands, and shares under half its outline.
    // Cut off, it would leave the seat and the chair, less convex (0.78) than the whole: the
    // cut follows the sofa's colours, not two objects, and is not made
    let (rows, cols) = (40, 50);
    let mut v = floor_volume(rows, cols, 20);
    fill(&mut v, (10, 26), (10, 40), (2, 10), 0.95);
    fill(&mut v, (26, 34), (21, 29), (2, 10), 0.95);
    let color = painted(rows, cols, (10..18, 10..40), [0.9, 0.6, 0.2], [0.2, 0.4, 0.6]);
    let d = detect_small(&v, &color);
    assert_eq!(rects(&d), vec![PixelRect::new(10, 10, 34, 40)], "{:?}", d.removed);
}

#[test]
fn a_convex_object_with_a_coloured_inside_stays_whole() {
    let (rows, cols) = (40, 60);
    let mut v = floor_volume(rows, cols, 20);
    fill(&mut v, (5, 25), (5, 25), (2, 10), 0.95); // a sofa-like block
    // the cushion in one colour, the rest in another
    let color = painted(rows, cols, (8..22, 8..22), [0.9, 0.8, 0.1], [0.1, 0.5, 0.2]);
    let d = detect_small(&v, &color);
    assert_eq!(rects(&d), vec![PixelRect::new(5, 5, 25, 25)], "{:?}", d.removed);
}

#[test]
fn empty_fields_and_bad_options_are_errors() {
    let v = floor_volume(20, 20, 10);
    let grid = PlaneGrid { cols: 20, rows: 20, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let color = PlaneImage::zeros(20, 20, 2).unwrap();
    let e = detect(&grid, &v, &color, None, &params()).unwrap_err();
    assert!(e.to_string().contains("nothing stands on the floor"), "{e}");
    let mut v2 = v.clone();
    fill(&mut v2, (5, 10), (5, 10), (2, 6), 0.9);
    let k1 = DetectParams { k: 1, ..params() };
    assert!(detect(&grid, &v2, &color, None, &k1).is_err());
    let big = DetectParams { k: 10_000, ..params() };
    assert!(detect(&grid, &v2, &color, None, &big).unwrap_err().to_string().contains("distinct"));
    let wrong = PlaneImage::zeros(10, 20, 2).unwrap();
    assert!(detect(&grid, &v2, &wrong, None, &params()).is_err());
}

/// A 60 x 80 floor with a desk-like solid body (rows 5..29, columns 10..50, levels 2..=12)
/// and a monitor on its top over `rows` x `cols` (levels 13..20), dark on a light plane.
fn desk_with_a_dark_monitor(
    rows: (usize, usize),
    cols: (usize, usize),
) -> (OpacityVolume, PlaneImage) {
    let mut v = floor_volume(60, 80, 24);
    fill(&mut v, (5, 29), (10, 50), (2, 13), 0.95);
    fill(&mut v, rows, cols, (13, 20), 0.95);
    let color = painted(60, 80, (rows.0..rows.1, cols.0..cols.1), [0.1; 3], [0.9, 0.9, 0.85]);
    (v, color)
}

#[test]
fn objects_on_a_solid_body_unpack_but_specks_do_not() {
    // a desk-like solid body (levels 2..=12 over its whole footprint) with a dark monitor
    // standing on its top away from the rim, and a one-texel speck of haze above it
    let (rows, cols) = (60, 80);
    let (mut v, color) = desk_with_a_dark_monitor((12, 22), (25, 29));
    fill(&mut v, (8, 9), (45, 46), (14, 16), 0.95);
    let d = detect_small(&v, &color);
    let child = only_child(&d);
    assert_eq!(child.rect, PixelRect::new(12, 25, 22, 29));
    assert!((child.base - v.height(12)).abs() < 1e-4, "{}", child.base);
    // a body whose top is mostly covered (a chair's seat under its back) is no support
    let mut v2 = floor_volume(rows, cols, 24);
    fill(&mut v2, (5, 20), (10, 25), (2, 13), 0.95);
    fill(&mut v2, (8, 17), (13, 22), (13, 20), 0.95);
    let d2 = detect_small(&v2, &color);
    assert_eq!(d2.detections.len(), 1, "{:?}", rects(&d2));
}

#[test]
fn what_covers_most_of_a_solid_body_is_its_own_shape() {
    // a car-like solid body (levels 2..=12 over 60 x 100 texels, a fifth of the plane) and
    // on it a dark cabin whose glass the field leaves empty (opaque pillars and sills round
    // its outline, two texels thick), bonnet and boot free around it: over 55% of the
    // footprint the cabin is the body's own shape (one object); over 40% of it, an object
    // standing on the body
    let body = |cabin: (std::ops::Range<usize>, std::ops::Range<usize>)| {
        let mut v = floor_volume(140, 220, 24);
        fill(&mut v, (40, 100), (60, 160), (2, 13), 0.95);
        let (r, c) = (&cabin.0, &cabin.1);
        fill(&mut v, (r.start, r.end), (c.start, c.end), (13, 20), 0.95);
        fill(&mut v, (r.start + 2, r.end - 2), (c.start + 2, c.end - 2), (13, 20), 0.0);
        let color = painted(140, 220, cabin, [0.1; 3], [0.8, 0.1, 0.1]);
        detect_small(&v, &color)
    };
    let cabin = (46..94, 85..154);
    assert!(cabin.0.len() * cabin.1.len() * 100 > 55 * 60 * 100, "over half the footprint");
    let d = body(cabin);
    assert_eq!(d.detections.len(), 1, "{:?}", rects(&d));
    let d = body((50..90, 90..150));
    assert_eq!(only_child(&d).rect, PixelRect::new(50, 90, 90, 150));
}

#[test]
fn a_cabin_between_bonnet_and_boot_is_the_body_s_own_shape() {
    // the car-like body of the test above with a cabin under half its footprint (40 of its
    // 100 columns) that spans its width but for the rim band: the free top is a bonnet and
    // a boot, two pieces, so the cabin is the body's own shape; the same cabin with free
    // top all round it (rows 50..90) stands on the body
    let body = |rows: std::ops::Range<usize>| {
        let mut v = floor_volume(140, 220, 24);
        fill(&mut v, (40, 100), (60, 160), (2, 13), 0.95);
        fill(&mut v, (rows.start, rows.end), (90, 130), (13, 20), 0.95);
        let color = painted(140, 220, (rows, 90..130), [0.1; 3], [0.8, 0.1, 0.1]);
        detect_small(&v, &color)
    };
    assert_eq!(rects(&body(42..98)), vec![PixelRect::new(40, 60, 100, 160)]);
    assert_eq!(only_child(&body(50..90)).rect, PixelRect::new(50, 90, 90, 130));
}

#[test]
fn what_stands_on_a_small_solid_top_is_found_where_it_leaves_room() {
    // a solid side table 24 texels across (levels 2..=12) with a box 7 texels across on its
    // middle (levels 13..19): its rim band is two fifths of the footprint, and the free top
    // round the box a quarter of the footprint (under the 30% share once asked), one piece
    let table = |r: (usize, usize), k: (usize, usize)| {
        let mut v = floor_volume(40, 40, 24);
        fill(&mut v, (8, 32), (8, 32), (2, 13), 0.95);
        fill(&mut v, r, r, k, 0.95);
        v
    };
    let color = painted(40, 40, (17..24, 17..24), [0.1; 3], [0.8, 0.7, 0.5]);
    assert_child_within_a_texel(&table((17, 24), (13, 20)), &color, PixelRect::new(17, 17, 24, 24));
    // a box whose blurred fringe covers the whole top judged away from the band leaves no
    // room: the top is covered, as a seat under its chair's back
    let wide = painted(40, 40, (14..26, 14..26), [0.1; 3], [0.8, 0.7, 0.5]);
    assert_eq!(detect_small(&table((14, 26), (13, 20)), &wide).detections.len(), 1);
    // what stands there rises past a second blur window over the top (levels 15 and 16 for
    // these volumes' blur of 2): a bump of the top's own (a canopy's crown) to level 15 is no
    // object, a box to level 16 is
    assert_eq!(detect_small(&table((17, 24), (13, 16)), &color).detections.len(), 1);
    assert_child_within_a_texel(&table((17, 24), (13, 17)), &color, PixelRect::new(17, 17, 24, 24));
}

#[test]
fn what_stands_in_the_middle_of_a_narrow_solid_top_is_found_and_a_longer_cut_is_its_shape() {
    // a solid counter 16 texels deep and 60 long (levels 2..=12): judged away from its rim
    // band it is 10 deep, and the blurred fringe of a box 8 texels across on its middle
    // reaches the band on both sides, cutting the free top in two parts of 200 texels; the
    // box and its fringe take 140, less than either part: it stands on the counter
    let counter = |c: (usize, usize)| {
        let mut v = floor_volume(36, 80, 24);
        fill(&mut v, (10, 26), (10, 70), (2, 13), 0.95);
        fill(&mut v, (14, 22), c, (13, 20), 0.95);
        v
    };
    let colour =
        |c: std::ops::Range<usize>| painted(36, 80, (14..22, c), [0.1; 3], [0.8, 0.7, 0.5]);
    assert_child_within_a_texel(
        &counter((36, 44)),
        &colour(36..44),
        PixelRect::new(14, 36, 22, 44),
    );
    // 30 texels long, its fringe takes 360 texels of the top and leaves two parts of 90:
    // the counter's own shape, as a car's cabin between its bonnet and its boot
    assert_eq!(
        rects(&detect_small(&counter((25, 55)), &colour(25..55))),
        vec![PixelRect::new(10, 10, 26, 70)]
    );
}

#[test]
fn a_crate_covering_most_of_a_thin_slab_unpacks() {
    // a pallet: runners (levels 2..=3) under a deck (level 3), 1.0 x 1.2 m; a crate of
    // 0.8 x 0.8 m on it (levels 4..=19) covers 53% of it, with a 0.1 m margin
    let mut v = floor_volume(50, 50, 24);
    pallet(&mut v);
    fill(&mut v, (12, 28), (14, 30), (4, 20), 0.95);
    assert_the_crate_unpacks(&v);
    // the same crate on a table of the pallet's size, its top (level 9) on four legs: a
    // thin slab carries what stands on it however high it is
    let mut t = floor_volume(50, 50, 24);
    for (r, c) in [(10, 10), (10, 33), (29, 10), (29, 33)] {
        fill(&mut t, (r, r + 1), (c, c + 1), (2, 9), 0.95);
    }
    fill(&mut t, (10, 30), (10, 34), (9, 10), 0.95);
    fill(&mut t, (12, 28), (14, 30), (10, 20), 0.95);
    assert_the_crate_unpacks(&t);
    // the same box standing on a tall solid body (a car's cabin on its body) stays one
    let mut v2 = floor_volume(50, 50, 24);
    fill(&mut v2, (10, 30), (10, 34), (2, 12), 0.95);
    fill(&mut v2, (12, 28), (14, 30), (12, 20), 0.95);
    let d2 = detect_small(&v2, &crate_colour());
    assert_eq!(d2.detections.len(), 1, "{:?}", rects(&d2));
}

#[test]
fn a_hollow_crate_on_a_slatted_pallet_unpacks() {
    // the pallet of the test above with gaps between the deck's slats under the crate,
    // and a crate whose walls are one texel thick under a lid: the lid (256 texels) covers
    // more than 60% of the slatted deck, so it is the highest dense surface, with nothing
    // on it; the deck below it is the support
    let mut v = floor_volume(50, 50, 24);
    pallet(&mut v);
    for gap in [13, 17, 21] {
        fill(&mut v, (gap, gap + 2), (14, 30), (3, 4), 0.0);
    }
    let hollow_box = |v: &mut OpacityVolume, k0: usize| {
        fill(v, (12, 28), (14, 15), (k0, 19), 0.95);
        fill(v, (12, 28), (29, 30), (k0, 19), 0.95);
        fill(v, (12, 13), (14, 30), (k0, 19), 0.95);
        fill(v, (27, 28), (14, 30), (k0, 19), 0.95);
        fill(v, (12, 28), (14, 30), (19, 20), 0.95);
    };
    hollow_box(&mut v, 4);
    assert_the_crate_unpacks(&v);
    // the same hollow box standing on the floor, nothing on its lid: one object
    let mut v2 = floor_volume(50, 50, 24);
    hollow_box(&mut v2, 2);
    let d2 = detect_small(&v2, &crate_colour());
    assert_eq!(d2.detections.len(), 1, "{:?}", rects(&d2));
}

#[test]
fn soft_tops_unpack_and_a_screen_raised_on_them_is_found() {
    // a body whose top is soft (every texel opaque at one of three levels, so that no
    // single level covers it) with a laptop: a raised screen, a hinge row of the
    // surface's colour, and a dark keyboard lying on the top. The screen is found; the
    // keyboard, flat on the top beyond a row of the top's colour, is not joined to it (a
    // jump over such a row, made for one suite scene's laptops, went: no dev field changed)
    let (rows, cols) = (60, 80);
    let mut v = floor_volume(rows, cols, 24);
    fill(&mut v, (5, 35), (10, 50), (2, 10), 0.95);
    for r in 5..35 {
        for c in 10..50 {
            let k = 10 + (r + c) % 3;
            v.data[(r * cols + c) * v.nz + k] = 0.95;
        }
    }
    fill(&mut v, (12, 14), (25, 33), (14, 20), 0.95); // the screen
    fill(&mut v, (15, 19), (25, 33), (13, 14), 0.95); // the keyboard
    let color = PlaneImage::from_fn(rows, cols, 3, |r, c, k| {
        let keyboard = (15..19).contains(&r) && (25..33).contains(&c);
        let screen = (12..14).contains(&r) && (25..33).contains(&c);
        if keyboard {
            [0.1, 0.1, 0.1][k]
        } else if screen {
            [0.5, 0.5, 0.5][k]
        } else {
            [0.9, 0.9, 0.85][k]
        }
    })
    .unwrap();
    let d = detect_small(&v, &color);
    let child = only_child(&d);
    assert_eq!(child.rect, PixelRect::new(12, 25, 14, 33));
}

#[test]
fn a_solid_body_with_a_faint_level_is_no_table() {
    // a car-like body (levels 2..=9 with one faint level) with a cabin over half of it:
    // one object, not a cabin standing on a table
    let (rows, cols) = (60, 80);
    let mut v = floor_volume(rows, cols, 24);
    fill(&mut v, (10, 40), (10, 30), (2, 10), 0.95);
    fill(&mut v, (10, 40), (10, 30), (6, 7), 0.05);
    fill(&mut v, (20, 30), (13, 27), (10, 16), 0.95);
    // the cabin in one colour, the rest in another
    let color = painted(rows, cols, (20..30, 13..27), [0.2, 0.3, 0.4], [0.8, 0.1, 0.1]);
    let d = detect_small(&v, &color);
    assert_eq!(rects(&d), vec![PixelRect::new(10, 10, 40, 30)]);
}

fn part(r0: usize, c0: usize, rows: usize, cols: usize, f: impl Fn(usize, usize) -> bool) -> Part {
    Part {
        rect: PixelRect::new(r0, c0, r0 + rows, c0 + cols),
        footprint: Mask::from_fn(rows, cols, f),
        kmin: 0,
        kmax: 5,
    }
}

#[test]
fn three_fragments_of_one_object_merge_where_no_two_do() {
    // a round table top (radius 10) cut into three sectors of 120 degrees: each is convex,
    // any two make a shape with a wedge missing (solidity about 0.83), all three the disc
    let sector = |k: usize| {
        move |r: usize, c: usize| {
            let (y, x) = (r as f32 - 10.0, c as f32 - 10.0);
            let a = y.atan2(x).rem_euclid(std::f32::consts::TAU);
            let third = std::f32::consts::TAU / 3.0;
            x * x + y * y <= 100.0 && (a / third).floor() as usize % 3 == k
        }
    };
    let (a, b, c) = (
        part(5, 5, 21, 21, sector(0)),
        part(5, 5, 21, 21, sector(1)),
        part(5, 5, 21, 21, sector(2)),
    );
    let trim = |p: Part| {
        let bb = p.footprint.bbox().unwrap();
        let rect = PixelRect::new(
            p.rect.r0 + bb.r0,
            p.rect.c0 + bb.c0,
            p.rect.r0 + bb.r1,
            p.rect.c0 + bb.c1,
        );
        Part { rect, footprint: p.footprint.crop(bb).unwrap(), ..p }
    };
    let (a, b, c) = (trim(a), trim(b), trim(c));
    for (x, y) in [(&a, &b), (&b, &c), (&a, &c)] {
        assert!(fragments_merged(x, y, 1, 0.9).is_none());
    }
    let m = group_merged(&[&a, &b, &c], 1, 0.9).expect("the three merge");
    assert_eq!(
        m.footprint.count(),
        a.footprint.count() + b.footprint.count() + c.footprint.count()
    );
    // three crates in a row: their boxes meet only where they touch, not overlapping
    let crate_at = |c0: usize| part(0, c0, 8, 8, |_, _| true);
    assert!(group_merged(&[&crate_at(0), &crate_at(8), &crate_at(16)], 1, 0.9).is_none());
    // nor does a part that touches none of the others join them
    let apart = part(40, 40, 5, 5, |_, _| true);
    assert!(group_merged(&[&a, &b, &apart], 1, 0.9).is_none());
}

#[test]
fn an_inside_holds_the_smallest_object_and_is_closed() {
    // the square a hole holds: side 2 r - 1 texels (chessboard inradius r)
    assert!(!holds_an_object(0, 25) && !holds_an_object(2, 25));
    assert!(holds_an_object(3, 25) && !holds_an_object(3, 26));
    // a 16 x 16 part whose first-round mask is a ring three texels thick: its 10 x 10
    // inside is closed; opened on one side (a C), or only 3 x 3 wide, it is none
    let part = |r0: usize| Part {
        rect: PixelRect::new(r0, 0, r0 + 16, 16),
        footprint: Mask::from_fn(16, 16, |_, _| true),
        kmin: 0,
        kmax: 5,
    };
    let ring = |open: bool, inner: usize| {
        Mask::from_fn(40, 16, |r, c| {
            let (r, lo, hi) = (r % 20, 8 - inner / 2, 8 + inner.div_ceil(2));
            let hole = (lo..hi).contains(&r) && (lo..hi).contains(&c);
            let gap = open && (lo..hi).contains(&r) && c >= lo;
            r < 16 && !hole && !gap
        })
    };
    assert!(encloses_an_inside(&part(0), &ring(false, 10), 25));
    assert!(!encloses_an_inside(&part(0), &ring(true, 10), 25));
    assert!(!encloses_an_inside(&part(20), &ring(false, 3), 25));
    // the part's footprint must hold the hole: a footprint without it encloses nothing
    let bare =
        Part { footprint: ring(false, 10).crop(PixelRect::new(0, 0, 16, 16)).unwrap(), ..part(0) };
    assert!(!encloses_an_inside(&bare, &ring(false, 10), 25));
}

#[test]
fn two_hollow_objects_are_no_fragments_of_one() {
    // a 20 x 40 block cut along a ragged line (columns 19 and 21 by turns) into two parts
    // whose boxes interleave and whose union is the whole block: fragments of one object,
    // unless each encloses an inside (10 x 10 texels that the first round left empty)
    let mut v = floor_volume(60, 80, 20);
    fill(&mut v, (5, 25), (5, 45), (2, 8), 0.95);
    let grid = PlaneGrid { cols: 80, rows: 60, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let color = PlaneImage::zeros(60, 80, 3).unwrap();
    let opts = params();
    let cx = Ctx::new(&grid, &v, &color, &opts).unwrap();
    let cut = |r: usize| if r % 4 < 2 { 19 } else { 21 };
    let halves = || {
        vec![part(5, 5, 20, 21, |r, c| c < cut(r)), part(5, 24, 20, 21, |r, c| c + 19 >= cut(r))]
    };
    let inside = |r: usize, c: usize| {
        (10..20).contains(&r) && [10..20, 30..40].iter().any(|x| x.contains(&c))
    };
    let solid = Mask::from_fn(60, 80, |r, c| (5..25).contains(&r) && (5..45).contains(&c));
    let hollow = Mask::from_fn(60, 80, |r, c| solid.get(r, c) && !inside(r, c));
    let mut parts = halves();
    merge::merge_fragments(&cx, &solid, &mut parts);
    assert_eq!(parts.len(), 1, "{parts:?}");
    assert_eq!(parts[0].footprint.count(), 800);
    let mut parts = halves();
    merge::merge_fragments(&cx, &hollow, &mut parts);
    assert_eq!(parts.len(), 2);
}

#[test]
fn fragments_of_one_object_merge_but_neighbours_do_not() {
    // a 12 x 12 seat cut along a ragged line: the boxes interleave (the left piece
    // reaches column 7 in some rows, the right one starts at column 5)
    let cut = |r: usize| if r % 4 < 2 { 5 } else { 7 };
    let left = part(10, 10, 12, 8, |r, c| c < cut(r));
    let right = part(10, 15, 12, 7, |r, c| c + 5 >= cut(r));
    let m = fragments_merged(&left, &right, 1, 0.9).expect("fragments merge");
    assert_eq!(m.rect, PixelRect::new(10, 10, 22, 22));
    assert_eq!(m.footprint.count(), 144);
    assert_eq!((m.kmin, m.kmax), (0, 5));
    // a chair (6 x 6) at a round table (radius 8), in the corner of the table's box and
    // touching its rim: the boxes overlap, but the union is concave
    let inside = |r: usize, c: usize| {
        let (y, x) = (r as f32 - 7.5, c as f32 - 7.5);
        x * x + y * y <= 64.0
    };
    let table = part(0, 0, 16, 16, inside);
    let chair = part(12, 12, 6, 6, |r, c| !inside(r + 12, c + 12));
    assert!(fragments_merged(&table, &chair, 1, 0.9).is_none());
    // overlapping footprints are nesting, not fragments
    let under = part(4, 4, 6, 6, |_, _| true);
    assert!(fragments_merged(&table, &under, 1, 0.9).is_none());
    // a fragment reaching another height is another object
    let taller = Part { kmax: 9, ..right.clone() };
    assert!(fragments_merged(&left, &taller, 1, 0.9).is_none());
    // two crates side by side: their boxes touch but do not overlap
    let a = part(0, 0, 8, 8, |_, _| true);
    let b = part(0, 8, 8, 8, |_, _| true);
    assert!(fragments_merged(&a, &b, 1, 0.9).is_none());
    // a less convex object (the seat with two opposite corners cut off, 4 x 4 each) cut
    // along the same ragged line: its union is under the one-object bound, but more
    // convex than either fragment, which complete each other
    let notched = |r: usize, c: usize| !((r < 4 && c < 4) || (r >= 8 && c >= 8));
    let left = part(10, 10, 12, 8, |r, c| c < cut(r) && notched(r, c));
    let right = part(10, 15, 12, 7, |r, c| c + 5 >= cut(r) && notched(r, c + 5));
    let m = fragments_merged(&left, &right, 1, 0.9).expect("fragments merge");
    assert_eq!(m.footprint.count(), 144 - 32);
    let solidity = m.footprint.count() as f32 / crate::group::hull_area(&m.footprint);
    assert!(solidity < 0.9, "{solidity}");
}

#[test]
fn holes_fill() {
    let m = Mask::from_fn(5, 5, |r, c| r == 0 || r == 4 || c == 0 || c == 4);
    assert_eq!(fill_holes(&m).count(), 25);
    let open = Mask::from_fn(5, 5, |r, c| (r == 0 || r == 4 || c == 0) && c < 4);
    assert_eq!(fill_holes(&open).count(), open.count());
}

#[test]
fn robust_top_ignores_specks_of_haze() {
    let (rows, cols, nz) = (12, 12, 20);
    let mut data = vec![0f32; rows * cols * nz];
    // a 10 x 10 box over levels 2..=8
    for r in 1..11 {
        for c in 1..11 {
            for k in 2..=8 {
                data[(r * cols + c) * nz + k] = 0.9;
            }
        }
    }
    // a speck of haze over one column at level 15
    data[(5 * cols + 5) * nz + 15] = 0.9;
    let vol = OpacityVolume { rows, cols, nz, z0: 0.0, dz: 0.05, data };
    let rect = PixelRect::new(0, 0, rows, cols);
    let fp = Mask::from_fn(rows, cols, |r, c| (1..11).contains(&r) && (1..11).contains(&c));
    assert_eq!(robust_top_level(&vol, rect, &fp, 2, 15, 0.5), 8);
    // a tall part over a fifth of the columns (a chair's back) counts
    let mut vol2 = vol.clone();
    for r in 1..11 {
        for c in 1..3 {
            for k in 9..=14 {
                vol2.data[(r * cols + c) * nz + k] = 0.9;
            }
        }
    }
    assert_eq!(robust_top_level(&vol2, rect, &fp, 2, 15, 0.5), 14);
    // a tiny footprint keeps the given top
    let one = Mask::from_fn(rows, cols, |r, c| r == 5 && c == 5);
    assert_eq!(robust_top_level(&vol, rect, &one, 2, 15, 0.5), 15);
}

#[test]
fn thin_strips() {
    let strip = Mask::from_fn(20, 20, |_, c| (8..13).contains(&c));
    assert!(is_thin(&strip, 3));
    assert!(!is_thin(&strip, 2));
    // a ring is judged with its hole filled
    let ring = Mask::from_fn(12, 12, |r, c| r == 0 || c == 0 || r == 11 || c == 11);
    assert!(!is_thin(&ring, 3));
    assert!(is_thin(&Mask::from_fn(4, 4, |_, _| false), 1));
}

#[test]
fn floating_heads_do_not_stand_on_specks() {
    let (rows, cols, nz) = (6, 6, 40);
    let vol = |f: &dyn Fn(usize, usize, usize) -> bool| {
        let mut data = vec![0f32; rows * cols * nz];
        for r in 0..rows {
            for c in 0..cols {
                for k in 0..nz {
                    if f(r, c, k) {
                        data[(r * cols + c) * nz + k] = 0.9;
                    }
                }
            }
        }
        OpacityVolume { rows, cols, nz, z0: 0.0, dz: 0.05, data }
    };
    let rect = PixelRect::new(0, 0, rows, cols);
    let all = Mask::from_fn(rows, cols, |_, _| true);
    // a lamp head at levels 30..=33 over a speck of haze on the ground
    let head = vol(&|r, c, k| {
        (1..5).contains(&r) && (1..5).contains(&c) && (30..=33).contains(&k)
            || (r, c) == (2, 2) && k <= 3
    });
    assert!(!stands(&head, rect, &all, 0, 2, 0.5, 3));
    // a table top at levels 10..=11 over legs the field kept up to level 6
    let table = vol(&|r, c, k| {
        (10..=11).contains(&k) || [(0, 0), (0, 5), (5, 0), (5, 5)].contains(&(r, c)) && k <= 6
    });
    assert!(stands(&table, rect, &all, 0, 2, 0.5, 3));
    // a post from the ground up
    let post = vol(&|r, c, _| (r, c) == (3, 3));
    assert!(stands(&post, rect, &all, 0, 2, 0.5, 3));
    // nothing at all
    assert!(!stands(&vol(&|_, _, _| false), rect, &all, 0, 2, 0.5, 3));
}

/// The ground's tilt as detection measures it: on the floor's surface columns when a floor
/// is found.
fn tilt(v: &OpacityVolume) -> Option<(f32, f32)> {
    let surfaces = floor::surface_levels(v);
    let f = floor::floor_on_surfaces(v, &surfaces, &params());
    floor::ground_tilt(v, f.map(|f| (f, surfaces.as_slice())), &params())
}

#[test]
fn a_tilted_ground_is_refused_with_advice_and_a_level_one_is_measured() {
    // a ground slab rising one level every 8 texels (7.1 degrees) under boxes
    let (rows, cols, nz) = (40, 60, 30);
    let mut v = OpacityVolume::empty(rows, cols, nz, 0.05);
    for c in 0..cols {
        let k = c / 8;
        fill(&mut v, (0, rows), (c, c + 1), (k, k + 2), 0.95);
    }
    fill(&mut v, (5, 12), (5, 12), (3, 9), 0.9);
    let (deg, cov) = tilt(&v).unwrap();
    assert!((deg - 7.1).abs() < 1.0 && cov > 0.99, "{deg} {cov}");
    let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let color = PlaneImage::zeros(rows, cols, 3).unwrap();
    let e = detect(&grid, &v, &color, None, &params()).unwrap_err().to_string();
    assert!(e.contains(&format!("tilted by {deg:.1}")) && e.contains("--align-ground pca"), "{e}");
    // without the floor search the tilt is not judged
    let no_floor = DetectParams { stages: Stages { floor: false, ..Stages::ALL }, ..params() };
    let r = detect(&grid, &v, &color, None, &no_floor);
    assert!(r.as_ref().map_or_else(|e| !e.to_string().contains("tilted"), |_| true), "{r:?}");
    // a level floor measures no tilt; no floor at all measures none either
    let level = floor_volume(rows, cols, nz);
    assert!(tilt(&level).unwrap().0 < 0.01);
    assert!(
        floor::ground_tilt(&OpacityVolume::empty(rows, cols, nz, 0.05), None, &params()).is_none()
    );
}

#[test]
fn empty_enclosures_fill_and_enclosures_holding_something_do_not() {
    // a ring with nothing inside, a ring around an island, a U open to the outside
    let m = Mask::from_fn(20, 40, |r, c| {
        let ring = |r0: usize, c0: usize| {
            (r0..r0 + 8).contains(&r)
                && (c0..c0 + 8).contains(&c)
                && (r == r0 || r == r0 + 7 || c == c0 || c == c0 + 7)
        };
        let island = (5..7).contains(&r) && (15..17).contains(&c);
        let u = (2..10).contains(&r) && (26..34).contains(&c) && (c == 26 || c == 33 || r == 9);
        ring(2, 2) || ring(2, 12) || island || u
    });
    let f = shape::fill_empty_holes(&m);
    assert!(f.get(5, 5), "the empty ring is filled");
    assert_eq!(f.count() - m.count(), 36, "only the empty ring's inside is added");
    assert!(!f.get(4, 14), "the ring around an island keeps its hole");
    assert!(!f.get(5, 30), "an open U has no hole");
}

#[test]
fn a_roofless_shell_is_one_object_and_the_room_s_walls_around_it_are_walls() {
    // a room's walls (two texels thick all round) holding a box and the sides of a long
    // object whose top the field did not learn (a white van roof under a white sky): its
    // sides are thin and as long as the room's walls, but nothing stands inside them
    let (rows, cols) = (60, 80);
    let mut v = walled_room(rows, cols);
    fill(&mut v, (40, 50), (30, 40), (2, 10), 0.95); // the box
    fill(&mut v, (8, 26), (10, 60), (2, 16), 0.95); // the shell, 18 x 50 texels
    fill(&mut v, (10, 24), (12, 58), (2, 16), 0.0);
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    assert_found_exactly(&d, &[PixelRect::new(8, 10, 26, 60), PixelRect::new(40, 30, 50, 40)]);
    assert_a_wall_removed(&d);
}

#[test]
fn hollow_shells_in_contact_are_one_object_each() {
    // three long objects whose tops the field did not learn (walls three texels thick), the
    // middle one touching both others with a side, end to end; a box against the left
    // shell's side; and a flat table top, as wide, with narrow gaps in it (a faint top): the
    // shells are one object each, the box stays a box, the gapped top stays one object
    let (rows, cols) = (70, 110);
    let mut v = floor_volume(rows, cols, 30);
    let shells = three_shells_in_contact(5, 5);
    for s in shells {
        roofless_shell(&mut v, s);
    }
    fill(&mut v, (10, 20), (1, 5), (2, 8), 0.95); // a box against the first shell
    fill(&mut v, (52, 66), (10, 50), (2, 10), 0.95); // a table top
    for c in [18, 26, 34] {
        fill(&mut v, (56, 62), (c, c + 3), (2, 10), 0.0); // with gaps in it
    }
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    let others = [PixelRect::new(10, 1, 20, 5), PixelRect::new(52, 10, 66, 50)];
    assert_found_exactly(&d, &[&shells[..], &others].concat());
}

#[test]
fn a_hollow_shell_walled_in_by_its_neighbours_is_one_object() {
    // three shells stacked end to end (20 x 40 texels, walls three texels thick) with a
    // solid box against each side of the middle one: the middle shell's walls reach the
    // outside only through its neighbours, yet each shell is one object and each box a box
    let (rows, cols) = (70, 90);
    let mut v = floor_volume(rows, cols, 30);
    let shells = [
        PixelRect::new(5, 25, 25, 65),
        PixelRect::new(25, 25, 45, 65),
        PixelRect::new(45, 25, 65, 65),
    ];
    for s in shells {
        roofless_shell(&mut v, s);
    }
    let boxes = [PixelRect::new(25, 5, 45, 25), PixelRect::new(25, 65, 45, 85)];
    for b in boxes {
        fill(&mut v, (b.r0, b.r1), (b.c0, b.c1), (2, 16), 0.95);
    }
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    assert_found_exactly(&d, &[&shells[..], &boxes[..]].concat());
}

#[test]
fn what_a_hollow_shell_holds_is_its_own_and_the_room_keeps_what_stands_in_it() {
    // a room's walls (two texels thick all round) around three long shells in contact, end
    // to end, whose tops the field did not learn and whose insides hold sheets it left there
    // instead (a white van's roof painted onto the ground, the rest drawn as curtains), and a
    // box standing free in the room: the shells are one object each and not a wall, the
    // sheets no objects, the box a box, the room's walls walls
    let (rows, cols) = (74, 114);
    let mut v = walled_room(rows, cols);
    let shells = three_shells_in_contact(7, 7);
    for s in shells {
        roofless_shell(&mut v, s);
        // a sheet inside, as tall as the shell
        fill(&mut v, (s.r0 + 8, s.r0 + 10), (s.c0 + 8, s.c1 - 8), (2, 15), 0.95);
    }
    fill(&mut v, (55, 65), (80, 90), (2, 10), 0.95); // the box
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    assert_found_exactly(&d, &[&shells[..], &[PixelRect::new(55, 80, 65, 90)]].concat());
    assert_a_wall_removed(&d);
}

#[test]
fn a_wall_corner_closed_off_by_a_streak_is_still_a_wall() {
    // walls along two sides (an L, two texels thick) and a one-texel streak of haze across
    // the corner: the streak closes an empty triangle, which is no hollow object, for most
    // of the L stays thin with the triangle filled
    let (rows, cols) = (60, 80);
    let mut v = floor_volume(rows, cols, 30);
    fill(&mut v, (0, 2), (0, cols), (2, 20), 0.95);
    fill(&mut v, (0, rows), (0, 2), (2, 20), 0.95);
    for i in 2..14 {
        fill(&mut v, (i, i + 1), (15 - i, 16 - i), (2, 4), 0.95);
    }
    fill(&mut v, (40, 50), (30, 40), (2, 10), 0.95); // a box
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    let boxes = rects(&d);
    assert_eq!(boxes.len(), 1, "{boxes:?} removed {:?}", d.removed);
    assert!(within_a_texel(boxes[0], PixelRect::new(40, 30, 50, 40)), "{boxes:?}");
}

#[test]
fn a_wall_along_the_short_side_of_a_long_plane_is_a_wall() {
    // a plane 60 x 100 texels: the left wall (two texels thick, levels 2..20) runs along 40
    // of the 60 rows, a doorway leaving the rest open; it spans 0.67 of the side it runs
    // along, though only 0.4 of the plane's longer side. A bench as thin and as long (40
    // texels) along the long side runs along 0.4 of it, and is an object.
    let (rows, cols) = (60, 100);
    let mut v = floor_volume(rows, cols, 30);
    fill(&mut v, (0, 40), (0, 2), (2, 20), 0.95);
    fill(&mut v, (50, 52), (30, 70), (2, 8), 0.95); // the bench
    fill(&mut v, (20, 30), (40, 50), (2, 10), 0.95); // a box
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    assert_a_wall_removed(&d);
    assert_found_exactly(&d, &[PixelRect::new(50, 30, 52, 70), PixelRect::new(20, 40, 30, 50)]);
    assert!((filters::run_share(PixelRect::new(0, 0, 40, 2), rows, cols) - 0.667).abs() < 1e-3);
}

#[test]
fn a_thin_surface_is_opaque_at_its_peak_only() {
    use super::split::opaque;
    let tau = 0.4;
    // a solid voxel; a surface spread over two levels (0.35 each: 0.58 together) is one
    // voxel thick (the first peak level whose window holds it); the same surface spread over
    // four levels (0.15 each) is fog
    let col = [0.0, 0.95, 0.0, 0.0, 0.35, 0.35, 0.0, 0.0, 0.15, 0.15, 0.15, 0.15, 0.0];
    let occupied: Vec<usize> = (0..col.len()).filter(|&k| opaque(&col, k, tau, 2)).collect();
    assert_eq!(occupied, vec![1, 4]);
    // nothing solid grows: the blur tail next to a solid voxel is below its neighbour
    let col = [0.0, 0.3, 0.95, 0.3, 0.0];
    let occupied: Vec<usize> = (0..col.len()).filter(|&k| opaque(&col, k, tau, 3)).collect();
    assert_eq!(occupied, vec![2]);
    // a window of one level is the plain threshold
    assert!(!opaque(&[0.0, 0.35, 0.35, 0.0], 1, tau, 1));
}

#[test]
fn a_desk_whose_thin_top_joins_its_drawer_blocks_is_one_object() {
    // two drawer blocks (levels 2..10) under a desk top the field spread thin over levels
    // 8..10 (0.35 a level: below the voxel threshold, above it over the two levels)
    let (rows, cols) = (30, 50);
    let mut v = floor_volume(rows, cols, 16);
    fill(&mut v, (5, 17), (5, 13), (2, 10), 0.95);
    fill(&mut v, (5, 17), (32, 40), (2, 10), 0.95);
    fill(&mut v, (5, 17), (13, 32), (8, 10), 0.35);
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    assert!(
        d.voxel_threshold > 0.35 && d.voxel_threshold < 0.5,
        "the premise: one level of the top is below the threshold, two are above ({})",
        d.voxel_threshold
    );
    assert_eq!(rects(&d), vec![PixelRect::new(5, 5, 17, 40)], "{:?}", d.removed);
}

#[test]
fn a_monitor_along_a_desk_s_faded_back_edge_unpacks() {
    // a desk-like solid body (levels 2..=12) whose top fades along its back edge (rows 5..8:
    // the field's blurred fringe), and a monitor standing along that edge: the side of its
    // ring over the fringe is no free surface, the rest is, a majority but not 60%
    let (mut v, color) = desk_with_a_dark_monitor((8, 12), (20, 36));
    fill(&mut v, (5, 8), (10, 50), (10, 13), 0.1);
    let d = detect_small(&v, &color);
    let child = only_child(&d);
    assert!(within_a_texel(child.rect, PixelRect::new(8, 20, 12, 36)), "{:?}", child.rect);
}

#[test]
fn the_floor_is_the_surface_seen_from_above_whatever_lies_under_and_over_it() {
    // what a short run leaves: the floor's top at levels 6..=8, a partial opaque copy of it
    // at levels 1..=2 (40% of the plane), faint haze over it, and two boxes standing on it
    let (rows, cols, nz) = (40, 60, 30);
    let mut v = OpacityVolume::empty(rows, cols, nz, 0.05);
    fill(&mut v, (0, rows), (0, cols), (6, 9), 0.9);
    fill(&mut v, (0, 16), (0, cols), (1, 3), 0.6);
    fill(&mut v, (0, rows), (0, cols), (9, 13), 0.05);
    fill(&mut v, (5, 12), (5, 12), (9, 16), 0.9);
    fill(&mut v, (20, 30), (30, 44), (9, 14), 0.9);
    let f = floor_band(&v, &params()).unwrap();
    assert_eq!(f.hi, 8, "the top seen from above: {f:?}");
    assert_eq!(f.lo, 1, "the band reaches down to the opaque copy (the container's): {f:?}");
    let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let color = PlaneImage::zeros(rows, cols, 3).unwrap();
    let d = detect(&grid, &v, &color, None, &params()).unwrap();
    let mut rects: Vec<PixelRect> = d.detections.iter().map(|x| x.rect).collect();
    rects.sort_by_key(|r| r.r0);
    assert_eq!(rects.len(), 2, "{rects:?}");
    assert!(within_a_texel(rects[0], PixelRect::new(5, 5, 12, 12)), "{rects:?}");
    assert!(within_a_texel(rects[1], PixelRect::new(20, 30, 30, 44)), "{rects:?}");
    // a thick slab: its top, not its bottom
    let mut thick = OpacityVolume::empty(rows, cols, nz, 0.05);
    fill(&mut thick, (0, rows), (0, cols), (0, 7), 0.95);
    assert_eq!(floor_band(&thick, &params()).map(|f| (f.lo, f.hi)), Some((0, 6)));
}

#[test]
fn a_floor_with_nothing_on_it_is_said_to_be_empty() {
    let (rows, cols, nz) = (30, 40, 20);
    let mut v = OpacityVolume::empty(rows, cols, nz, 0.05);
    fill(&mut v, (0, rows), (0, cols), (0, 3), 0.95);
    let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let color = PlaneImage::zeros(rows, cols, 3).unwrap();
    let e = detect(&grid, &v, &color, None, &params()).unwrap_err().to_string();
    assert!(e.contains("nothing stands on the floor") && e.contains("no objects"), "{e}");
    let empty = OpacityVolume::empty(rows, cols, nz, 0.05);
    let e = detect(&grid, &empty, &color, None, &params()).unwrap_err().to_string();
    assert!(e.contains("nothing stands in the field"), "{e}");
}

#[test]
fn a_partial_floor_counts_what_stands_on_it() {
    // a rug-like floor over 40% of the plane (rows 0..24 of 60), 45% of it hidden from
    // above by boxes standing on it: 22% of the plane shows the floor's surface, but the
    // floor is there under the boxes
    let (rows, cols, nz) = (60, 80, 24);
    let mut v = OpacityVolume::empty(rows, cols, nz, 0.05);
    fill(&mut v, (0, 24), (0, cols), (0, 2), 0.95);
    for c0 in [4, 30, 56] {
        fill(&mut v, (3, 21), (c0, c0 + 16), (2, 10), 0.9);
    }
    let f = floor_band(&v, &params()).expect("the partial floor");
    assert_eq!(f.hi, 1, "{f:?}");
    assert!(f.coverage < params().floor_coverage, "the visible floor alone is too small: {f:?}");
    // boxes on an invisible ground, with a floor nowhere: their bases are opaque at the
    // lowest level over 19% of the plane, but nothing around them is a floor
    let mut bare = OpacityVolume::empty(rows, cols, nz, 0.05);
    for r0 in [2, 22, 42] {
        for c0 in [4, 30, 56] {
            fill(&mut bare, (r0, r0 + 10), (c0, c0 + 10), (0, 8), 0.9);
        }
    }
    assert_eq!(floor_band(&bare, &params()), None);
    // nor are a few low objects' tops on an invisible ground the floor of the boxes around them
    fill(&mut bare, (20, 38), (20, 28), (0, 1), 0.9);
    assert_eq!(floor_band(&bare, &params()), None);
    // nor the lower levels of a thick slab whose top is at level 6, where it shows thinner in
    // specks: the slab's own top is the floor
    let mut slab = OpacityVolume::empty(rows, cols, nz, 0.05);
    fill(&mut slab, (0, rows), (0, cols), (0, 7), 0.95);
    for r in (3..rows).step_by(6) {
        for c in (3..cols).step_by(5) {
            fill(&mut slab, (r, r + 1), (c, c + 1), (2, 7), 0.0);
        }
    }
    assert_eq!(floor_band(&slab, &params()).map(|f| f.hi), Some(6));
}

#[test]
fn tops_on_an_invisible_ground_are_no_floor_however_much_they_cover() {
    // 30 boxes on an invisible ground, two texels apart, their tops at level 7: 62% of the
    // plane sees a surface at or below level 7, but the tops are 30 pieces with empty
    // columns between them, none a floor
    let (rows, cols, nz) = (60, 80, 24);
    let mut v = OpacityVolume::empty(rows, cols, nz, 0.05);
    for r0 in (0..rows).step_by(12) {
        for c0 in (1..cols - 10).step_by(13) {
            fill(&mut v, (r0, r0 + 10), (c0, c0 + 10), (0, 8), 0.9);
        }
    }
    assert_eq!(floor_band(&v, &params()), None);
    // a floor divided into four rooms by walls: each room shows less than the coverage, but
    // the floor runs on through the walls' feet, one piece
    let mut rooms = OpacityVolume::empty(rows, cols, nz, 0.05);
    fill(&mut rooms, (0, rows), (0, cols), (0, 2), 0.95);
    fill(&mut rooms, (29, 31), (0, cols), (2, 16), 0.95);
    fill(&mut rooms, (0, rows), (39, 41), (2, 16), 0.95);
    let f = floor_band(&rooms, &params()).expect("the floor of the four rooms");
    assert_eq!(f.hi, 1, "{f:?}");
}

#[test]
fn a_hollow_slab_seen_through_its_thin_top_has_its_top_as_the_floor() {
    // a thick slab as a field leaves it: its bottom face at level 1 and its top at level 5,
    // nothing inside (never seen), and the top left out along a network of lines every nine
    // texels (21% of the plane sees the bottom face); three boxes on it. Counted from the
    // bottom, the bottom face and the top's patches hidden by it (each bounded by the
    // network, larger than itself) reach the coverage at level 1; the top is the surface
    // of 79% of the plane on its own
    let (rows, cols, nz) = (63, 81, 24);
    let mut v = OpacityVolume::empty(rows, cols, nz, 0.05);
    fill(&mut v, (0, rows), (0, cols), (1, 2), 0.95);
    fill(&mut v, (0, rows), (0, cols), (5, 6), 0.95);
    for r in (0..rows).step_by(9) {
        fill(&mut v, (r, r + 1), (0, cols), (5, 6), 0.0);
    }
    for c in (0..cols).step_by(9) {
        fill(&mut v, (0, rows), (c, c + 1), (5, 6), 0.0);
    }
    for c0 in [10, 38, 60] {
        fill(&mut v, (20, 32), (c0, c0 + 12), (6, 12), 0.9);
    }
    let f = floor_band(&v, &params()).expect("the slab");
    assert_eq!(f.hi, 5, "{f:?}");
    let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let color = PlaneImage::zeros(rows, cols, 3).unwrap();
    let d = detect(&grid, &v, &color, None, &params()).unwrap();
    assert_eq!(d.detections.len(), 3, "the boxes, not the slab: {:?}", d.detections);
}

#[test]
fn a_lamp_on_a_side_table_is_held_on_a_stem() {
    // areas per level: a table body to level 10, its top's blur, a stem, a shade
    let mut area = vec![0usize; 30];
    area[2..=10].fill(400);
    area[11] = 60;
    area[12..=16].fill(2);
    area[17..=20].fill(150);
    assert!(held_on_a_stem(&area, 10, 3, 25));
    // a chair's back rises from its seat without a stem
    let mut chair = area.clone();
    chair[12..=20].fill(70);
    assert!(!held_on_a_stem(&chair, 10, 3, 25));
    // a stem too short to tell from the top's blur
    let mut short = area.clone();
    short[14..=16].fill(150);
    assert!(!held_on_a_stem(&short, 10, 3, 25));
    // nothing held above the stem (haze)
    let mut bare = area.clone();
    bare[17..=20].fill(20);
    assert!(!held_on_a_stem(&bare, 10, 3, 25));
    // a shade with one faint level inside it is still one held body
    let mut dip = area.clone();
    dip[19] = 3;
    assert!(held_on_a_stem(&dip, 10, 3, 25));
    // a pine's tiers: flat discs with empty levels between them are one tree
    let mut pine = vec![0usize; 30];
    pine[2..=10].fill(900);
    pine[14] = 700;
    pine[17] = 500;
    pine[20] = 300;
    assert!(!held_on_a_stem(&pine, 10, 3, 25));

    // and in a volume: a side table (solid, 0.45 m) whose lamp shade covers 44% of it,
    // leaving a rim of one or two texels, on a one-texel stem
    let (rows, cols) = (30, 30);
    let mut v = floor_volume(rows, cols, 40);
    fill(&mut v, (10, 19), (10, 19), (2, 12), 0.95);
    fill(&mut v, (14, 15), (14, 15), (12, 20), 0.95);
    fill(&mut v, (11, 17), (11, 17), (20, 24), 0.95);
    // the shade in one colour, the rest in another
    let color = painted(rows, cols, (11..17, 11..17), [0.95, 0.9, 0.7], [0.6, 0.45, 0.3]);
    let d = detect_small(&v, &color);
    let lamp = only_child(&d);
    assert_eq!(lamp.rect, PixelRect::new(11, 11, 17, 17));
}

#[test]
fn a_canopy_on_a_trunk_is_one_body() {
    // a round tree as a field renders it: a trunk one texel wide (levels 2..16), a canopy
    // of leaf layers 14 x 14 texels on every other level (16..=28), and a crown 6 x 6 texels
    // over the top layer, across one empty level. The top layer is no table top with the
    // crown standing on it: the layers under it are its body; the trunk is no part of that
    let (rows, cols) = (30, 30);
    // the canopy and crown over what stands under them (rows and columns of levels 2..16)
    let tree = |under: (usize, usize)| {
        let mut v = floor_volume(rows, cols, 40);
        fill(&mut v, under, under, (2, 16), 0.95);
        for k in (16..=28).step_by(2) {
            fill(&mut v, (8, 22), (8, 22), (k, k + 1), 0.95);
        }
        fill(&mut v, (12, 18), (12, 18), (30, 34), 0.95);
        v
    };
    let color = painted(rows, cols, (12..18, 12..18), [0.3, 0.6, 0.3], [0.2, 0.45, 0.2]);
    let d = detect_small(&tree((14, 15)), &color);
    let found: Vec<_> = d.detections.iter().map(|d| (d.rect, d.parent)).collect();
    assert_eq!(found, vec![(PixelRect::new(8, 8, 22, 22), None)]);
    // the same canopy on a body as wide as itself (a thick column under the top layer):
    // still one body
    assert_eq!(detect_small(&tree((8, 22)), &color).detections.len(), 1);
    // and the body's levels are counted from the first that holds an object's area
    assert_eq!(unpack::body_from(&[3, 1, 1, 60, 0, 60], 1, 5, 4), 3);
    assert_eq!(unpack::body_from(&[3, 1, 1, 2, 0, 60], 1, 5, 4), 5);
}

/// A [`floor_volume`] of 60 x 80 texels and 24 levels with a thin table top (rows 10..40,
/// columns 10..60, level 8) on four legs.
fn thin_table() -> OpacityVolume {
    let mut v = floor_volume(60, 80, 24);
    fill(&mut v, (10, 40), (10, 60), (8, 9), 0.95);
    for (r, c) in [(10, 10), (10, 59), (39, 10), (39, 59)] {
        fill(&mut v, (r, r + 1), (c, c + 1), (2, 8), 0.95);
    }
    v
}

#[test]
fn an_object_whose_foot_blurs_over_the_table_stands_within_free_surface() {
    // a box on the table (rows 20..26, columns 30..36, top level 8) whose foot the field
    // blurs one texel sideways in the level just over the table's top (within the table's
    // blur, under the first level counted as raised), in the table's colour: its ring is
    // free surface, and the box an object standing on the table
    let (rows, cols) = (60, 80);
    let mut v = thin_table();
    fill(&mut v, (19, 27), (29, 37), (9, 10), 0.95);
    fill(&mut v, (20, 26), (30, 36), (9, 16), 0.95);
    let color = painted(rows, cols, (20..26, 30..36), [0.2, 0.2, 0.7], [0.9, 0.9, 0.85]);
    assert_child_within_a_texel(&v, &color, PixelRect::new(20, 30, 26, 36));
}

#[test]
fn a_shadow_on_the_table_is_not_part_of_what_casts_it() {
    // a box on the table (rows 20..26, columns 30..36) casting a soft shadow three texels
    // wide all round: the shadow differs from the table's colour, but nothing rises there
    let (rows, cols) = (60, 80);
    let mut v = thin_table();
    fill(&mut v, (20, 26), (30, 36), (9, 16), 0.95);
    let color = PlaneImage::from_fn(rows, cols, 3, |r, c, k| {
        let object = (20..26).contains(&r) && (30..36).contains(&c);
        let shadow = (17..29).contains(&r) && (27..39).contains(&c);
        if object {
            [0.2, 0.2, 0.7][k]
        } else if shadow {
            [0.5, 0.5, 0.47][k]
        } else {
            [0.9, 0.9, 0.85][k]
        }
    })
    .unwrap();
    let d = detect_small(&v, &color);
    let r = only_child(&d).rect;
    assert!(within_a_texel(r, PixelRect::new(20, 30, 26, 36)), "{r:?}");
    // the same band made of something lying flat on the table, one level over its top (a
    // laptop's keyboard around its screen): part of the object
    let mut v2 = thin_table();
    fill(&mut v2, (17, 29), (27, 39), (9, 10), 0.95);
    fill(&mut v2, (20, 26), (30, 36), (10, 16), 0.95);
    let d2 = detect_small(&v2, &color);
    let r2 = only_child(&d2).rect;
    assert!(within_a_texel(r2, PixelRect::new(17, 27, 29, 39)), "{r2:?}");
}

#[test]
fn colours_at_a_height_weigh_each_channel_by_its_axis_there() {
    // three channels over 4 levels: one the field uses at every height, one only low (a
    // table's legs), one only high (what stands on the table)
    let axis = [
        1.0, 2.0, 0.0, //
        1.0, 2.0, 0.0, //
        1.0, 0.0, 3.0, //
        1.0, 0.0, 3.0, //
    ];
    let rms = |v: [f32; 4]| (v.iter().map(|x| x * x).sum::<f32>() / 4.0).sqrt();
    let axis = normalised_axis(&axis, 3);
    let w = height_weights(&axis, 3, 2, 3);
    assert!((w[0] - 1.0).abs() < 1e-6, "{w:?}");
    assert_eq!(w[1], 0.0, "a channel of the legs says nothing up there");
    assert!((w[2] - 3.0 / rms([0.0, 0.0, 3.0, 3.0])).abs() < 1e-6, "{w:?}");
    // levels past the axis clamp to its top; a range ending below its start is its start
    assert_eq!(height_weights(&axis, 3, 3, 9), height_weights(&axis, 3, 3, 3));
    assert_eq!(height_weights(&axis, 3, 1, 0), height_weights(&axis, 3, 1, 1));
    // a channel that is zero everywhere weighs nothing; no axis rows: no weighting
    assert_eq!(height_weights(&normalised_axis(&[0.0, 1.0], 2), 2, 0, 0), vec![0.0, 1.0]);
    assert_eq!(height_weights(&normalised_axis(&[], 3), 3, 0, 0), vec![1.0; 3]);
}

#[test]
fn the_colour_axis_must_match_the_volume_and_the_plane() {
    let mut v = thin_table();
    fill(&mut v, (20, 26), (30, 36), (9, 16), 0.95);
    let color = painted(60, 80, (20..26, 30..36), [0.2, 0.2, 0.7], [0.9, 0.9, 0.85]);
    let grid = PlaneGrid { cols: 80, rows: 60, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let opts = params();
    let err = detect_with_color_axis(&grid, &v, &color, Some(&[1.0; 10]), None, &opts);
    assert!(matches!(err, Err(crate::MiningError::SizeMismatch { .. })), "{err:?}");
    // an axis that is the same at every height finds what the plane alone finds
    let flat = vec![1.0f32; 24 * 3];
    let d = detect_with_color_axis(&grid, &v, &color, Some(&flat), None, &opts).unwrap();
    assert_eq!(rects(&d), rects(&detect_small(&v, &color)));
    assert!(within_a_texel(only_child(&d).rect, PixelRect::new(20, 30, 26, 36)));
}

#[test]
fn what_the_colour_clusters_run_along_in_a_thin_strip_is_cut_off() {
    // a box on the table with a strip two texels wide of its colour running from it across
    // the table (the colour of a leg under the top, bled into the plane), rising a little
    let (rows, cols) = (60, 80);
    let mut v = thin_table();
    fill(&mut v, (20, 26), (30, 36), (9, 16), 0.95);
    fill(&mut v, (26, 34), (31, 33), (9, 10), 0.3);
    let object_or_strip = |r: usize, c: usize| {
        (20..26).contains(&r) && (30..36).contains(&c)
            || (26..34).contains(&r) && (31..33).contains(&c)
    };
    let color = painted_where(rows, cols, object_or_strip, [0.2, 0.2, 0.7], [0.9, 0.9, 0.85]);
    assert_child_within_a_texel(&v, &color, PixelRect::new(20, 30, 26, 36));
}

#[test]
fn a_bouquet_of_faint_leaves_on_a_desk_is_seeded_by_its_opacity_seen_from_above() {
    // a solid desk (levels 2..=12) with flowers on it: leaves of opacity 0.3 per level over
    // rows 20..28, columns 30..38, levels 13..=18 (no voxel of them occupied on its own,
    // opaque seen from above) round a stem one texel wide
    let (rows, cols) = (60, 80);
    let mut v = floor_volume(rows, cols, 24);
    fill(&mut v, (5, 45), (10, 60), (2, 13), 0.95);
    fill(&mut v, (20, 28), (30, 38), (13, 19), 0.3);
    fill(&mut v, (24, 25), (34, 35), (13, 17), 0.95);
    let color = painted(rows, cols, (20..28, 30..38), [0.3, 0.6, 0.2], [0.9, 0.9, 0.85]);
    assert_child_within_a_texel(&v, &color, PixelRect::new(20, 30, 28, 38));
}

#[test]
fn a_small_faint_flower_that_rises_on_a_solid_body_is_found() {
    // a solid desk (levels 2..=12) with a flower on it: a faint stem and leaves (opacity
    // 0.2 per level, not opaque seen from above) over rows 20..23, columns 30..33, levels
    // 13..=17, and a bloom (levels 18..=19) over its middle row of three texels: the bloom alone
    // is opaque, smaller than the smallest object (4 texels) with 6 opaque voxels, but it
    // stands well past the top's blur. A speck as small right over the top is haze
    // (`objects_on_a_solid_body_unpack_but_specks_do_not`).
    let (rows, cols) = (60, 80);
    let mut v = floor_volume(rows, cols, 24);
    fill(&mut v, (5, 45), (10, 60), (2, 13), 0.95);
    fill(&mut v, (20, 23), (30, 33), (13, 18), 0.2);
    fill(&mut v, (21, 22), (30, 33), (18, 20), 0.95);
    let color = painted(rows, cols, (20..23, 30..33), [0.8, 0.2, 0.3], [0.9, 0.9, 0.85]);
    assert_child_within_a_texel(&v, &color, PixelRect::new(20, 30, 23, 33));
}

#[test]
fn floating_neighbours_bridged_by_haze_stay_apart() {
    // two stool seats (levels 8..=11) whose legs a short run left too faint to see, joined
    // by a one-texel bridge of haze at their height: neither stands, so neither is a part
    // of the other; a lamp's shade over its standing base still joins the base
    let (rows, cols) = (40, 60);
    let mut v = floor_volume(rows, cols, 20);
    fill(&mut v, (5, 15), (5, 15), (8, 12), 0.95);
    fill(&mut v, (5, 15), (25, 35), (8, 12), 0.95);
    fill(&mut v, (9, 10), (15, 25), (8, 10), 0.95);
    let color = painted(rows, cols, (0..1, 0..1), [0.9, 0.9, 0.85], [0.3, 0.3, 0.6]);
    let d = detect_small(&v, &color);
    assert_eq!(
        rects(&d),
        vec![PixelRect::new(5, 5, 15, 15), PixelRect::new(5, 25, 15, 35)],
        "{:?}",
        d.removed
    );
    // a lamp: a standing base, and a head held out on a thin arm with nothing under it
    let mut lamp = floor_volume(rows, cols, 20);
    fill(&mut lamp, (25, 33), (5, 13), (2, 10), 0.95);
    fill(&mut lamp, (28, 29), (13, 17), (9, 14), 0.95);
    fill(&mut lamp, (25, 33), (17, 25), (12, 16), 0.95);
    let d = detect_small(&lamp, &color);
    assert_eq!(rects(&d), vec![PixelRect::new(25, 5, 33, 25)], "{:?}", d.removed);
}

#[test]
fn a_small_object_standing_alone_is_found_but_not_one_beside_another() {
    // with the smallest object at 25 texels and the smallest lone one at 16 (a share of
    // 0.64): a 4 x 5 box
    // (20 texels) far from everything is an object; the same box two texels from a large
    // one (within the field's blur across) is taken for a fragment of it
    let (rows, cols) = (60, 80);
    let mut v = floor_volume(rows, cols, 20);
    fill(&mut v, (10, 30), (10, 30), (2, 10), 0.95);
    fill(&mut v, (40, 44), (50, 55), (2, 8), 0.95);
    fill(&mut v, (12, 16), (31, 36), (2, 8), 0.95);
    let color = painted(rows, cols, (0..1, 0..1), [0.9, 0.9, 0.85], [0.3, 0.3, 0.6]);
    let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
    let p = DetectParams { min_area_texels: 25, min_lone_area_share: 0.64, ..params() };
    let d = detect(&grid, &v, &color, None, &p).unwrap();
    assert_eq!(
        rects(&d),
        vec![PixelRect::new(10, 10, 30, 30), PixelRect::new(40, 50, 44, 55)],
        "{:?}",
        d.removed
    );
    // without the lone rule the small box is a speck
    let plain = DetectParams { min_lone_area_share: 1.0, ..p };
    let d = detect(&grid, &v, &color, None, &plain).unwrap();
    assert_eq!(rects(&d), vec![PixelRect::new(10, 10, 30, 30)]);
}

/// A street lamp in a volume of [`floor_volume`] 30 levels high: a base (6 x 6 texels,
/// levels 2..4) at rows 18..24, columns 28..34, a post (one texel) up to level 18, an arm
/// one texel wide at levels 16..18 running from the post towards row 0 up to row `arm_r0`,
/// and a head (levels 14..18) over rows `head.0` and columns `head.1`. Post and arm are
/// thinner than the smallest object of the tests' parameters.
fn street_lamp(v: &mut OpacityVolume, arm_r0: usize, head: ((usize, usize), (usize, usize))) {
    fill(v, (18, 24), (28, 34), (2, 4), 0.95); // base
    fill(v, (20, 21), (30, 31), (2, 18), 0.95); // post
    fill(v, (arm_r0, 21), (30, 31), (16, 18), 0.95); // arm
    fill(v, head.0, head.1, (14, 18), 0.95);
}

#[test]
fn a_lamp_whose_arm_reaches_a_wall_stays_a_lamp() {
    // a wall along row 0 (two texels thick, levels 2..20) and a street lamp whose arm hangs
    // over the ground up to the wall: thin like the wall and touching it, but hanging, so
    // only the arm's end within the wall's half thickness goes with the wall
    let (rows, cols) = (40, 60);
    let mut v = floor_volume(rows, cols, 30);
    fill(&mut v, (0, 2), (0, cols), (2, 20), 0.95);
    street_lamp(&mut v, 2, ((5, 9), (27, 35)));
    let d = detect_small(&v, &PlaneImage::zeros(rows, cols, 3).unwrap());
    assert_a_wall_removed(&d);
    assert_found_exactly(&d, &[PixelRect::new(4, 27, 24, 35)]);
}

#[test]
fn a_lamp_s_base_of_another_colour_stays_with_its_head() {
    // a street lamp standing free, its base in one colour and its post, arm and head (larger
    // than the base) in another: the base stands, but what the colour split would leave (arm
    // and head) hangs over the ground, so the lamp stays one object
    let (rows, cols) = (40, 60);
    let mut v = floor_volume(rows, cols, 30);
    street_lamp(&mut v, 6, ((2, 8), (26, 36)));
    let color = painted(rows, cols, (18..24, 28..34), [0.9, 0.2, 0.1], [0.2, 0.3, 0.8]);
    let d = detect_small(&v, &color);
    assert_found_exactly(&d, &[PixelRect::new(2, 26, 24, 36)]);
}

#[test]
fn an_object_at_a_table_s_edge_unpacks_but_the_table_s_raised_edge_does_not() {
    // a box standing at the edge of a thin table top (its side on the top's outline): an
    // object on the table, touching the rim along its width
    let (rows, cols) = (60, 80);
    let mut v = thin_table();
    fill(&mut v, (10, 16), (30, 36), (9, 16), 0.95);
    let color = painted(rows, cols, (10..16, 30..36), [0.2, 0.2, 0.7], [0.9, 0.9, 0.85]);
    let d = detect_small(&v, &color);
    let r = only_child(&d).rect;
    assert!(within_a_texel(r, PixelRect::new(10, 30, 16, 36)), "{r:?}");
    // a back two texels thick along the top's long edge (a bench's): the table's own shape,
    // running along the rim, not standing on it
    let mut v2 = thin_table();
    fill(&mut v2, (10, 12), (15, 55), (9, 16), 0.95);
    let color2 = painted(rows, cols, (10..12, 15..55), [0.2, 0.2, 0.7], [0.9, 0.9, 0.85]);
    let d2 = detect_small(&v2, &color2);
    assert!(d2.detections.iter().all(|x| x.parent.is_none()), "{:?}", rects(&d2));
    assert_eq!(d2.detections.len(), 1, "{:?}", rects(&d2));
}

#[test]
fn an_object_flush_with_a_round_table_s_edge_unpacks() {
    // a round table top (radius 16 texels, one pedestal) and a box standing flush with its
    // edge where the outline curves: the box touches the rim along its side, a staircase of
    // more texels than the side is long
    let (rows, cols) = (60, 80);
    let (cr, cc, radius) = (30i64, 40i64, 16i64);
    let disc = |r: usize, c: usize| {
        let (dr, dc) = (r as i64 - cr, c as i64 - cc);
        dr * dr + dc * dc <= radius * radius
    };
    let object = |r: usize, c: usize| (24..30).contains(&r) && (25..31).contains(&c) && disc(r, c);
    let mut v = floor_volume(rows, cols, 24);
    fill(&mut v, (29, 32), (39, 42), (2, 8), 0.95);
    for r in 0..rows {
        for c in 0..cols {
            if disc(r, c) {
                fill(&mut v, (r, r + 1), (c, c + 1), (8, 9), 0.95);
            }
            if object(r, c) {
                fill(&mut v, (r, r + 1), (c, c + 1), (9, 16), 0.95);
            }
        }
    }
    let color = painted_where(rows, cols, object, [0.2, 0.2, 0.7], [0.9, 0.9, 0.85]);
    assert_child_within_a_texel(&v, &color, PixelRect::new(24, 25, 30, 31));
}

#[test]
fn an_object_whose_legs_the_field_left_out_stands_on_the_ground() {
    // two pedestal tables, one whose pedestal the field reconstructed only under its top:
    // both stand on the floor (the level above its top), as the layout places them
    let (rows, cols) = (40, 60);
    let mut v = floor_volume(rows, cols, 24);
    for (c0, foot) in [(5, 2), (35, 6)] {
        fill(&mut v, (10, 24), (c0, c0 + 14), (9, 10), 0.95);
        fill(&mut v, (16, 18), (c0 + 6, c0 + 8), (foot, 9), 0.95);
    }
    let color = PlaneImage::from_fn(rows, cols, 3, |_, _, k| [0.6, 0.4, 0.3][k]).unwrap();
    let d = detect_small(&v, &color);
    assert_eq!(d.detections.len(), 2, "{:?}", rects(&d));
    for x in &d.detections {
        assert!((x.base - v.height(2)).abs() < 1e-6, "{:?}: base {}", x.rect, x.base);
    }
}

#[test]
fn a_car_s_body_left_as_sheets_is_solid_under_its_cabin() {
    // a car's body (rows 10..30, columns 10..60): walls one texel thick, the inside left as
    // full sheets every third level, the bonnet's level on top (11), and a cabin of another
    // colour over most of it (56%): the body is solid, so the cabin is its own shape, no
    // object standing on it
    let (rows, cols) = (40, 70);
    let mut v = floor_volume(rows, cols, 30);
    fill(&mut v, (10, 30), (10, 60), (2, 12), 0.95);
    fill(&mut v, (11, 29), (11, 59), (2, 11), 0.0);
    for k in [3, 6, 9] {
        fill(&mut v, (10, 30), (10, 60), (k, k + 1), 0.95);
    }
    fill(&mut v, (13, 27), (15, 55), (12, 18), 0.95);
    let color = painted(rows, cols, (13..27, 15..55), [0.2, 0.2, 0.3], [0.2, 0.3, 0.8]);
    let d = detect_small(&v, &color);
    assert_eq!(rects(&d), vec![PixelRect::new(10, 10, 30, 60)], "{:?}", d.removed);
    // with the sheets gone the body is a slab on walls, and the cabin stands on it
    let mut open = v.clone();
    for k in [3, 6, 9] {
        fill(&mut open, (11, 29), (11, 59), (k, k + 1), 0.0);
    }
    let d2 = detect_small(&open, &color);
    assert!(d2.detections.iter().any(|x| x.parent.is_some()), "{:?}", rects(&d2));
}
