//! The composer's systems, tested the way bevy tests systems: set up a world, run the
//! schedule once, assert on the result. The key property: after any sequence of edits the
//! incrementally maintained planes equal a from-scratch rasterisation, while each edit
//! redraws only the texels it touched.

use assetfield_core::{Aabb3, GroundTransform};
use assetfield_field::{Field, FieldConfig, ModelKind};
use assetfield_scene::{Composer, Composition, FeaturePatch, SceneError, TexelRect};
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// A random S-AssetField on an 8 x 6 m box at 0.1 m texels (81 x 61), and a composer whose
/// canvas is that field's planes with the object region emptied.
fn setup() -> (Composer, Arc<FeaturePatch>, Vec<f32>, Vec<f32>) {
    let aabb = Aabb3::new(Vec3::new(-4.0, -3.0, 0.0), Vec3::new(4.0, 3.0, 1.5));
    let mut cfg = FieldConfig::new(ModelKind::Standard, aabb, 81);
    cfg.density_channels = 4;
    cfg.color_channels = 6;
    let field = Field::new(cfg, 5);
    let comp = Composition::new(field).unwrap();
    let grid = comp.grid;
    let (d_at, c_at) = (
        comp.field.params.spec("density.plane").unwrap().offset,
        comp.field.params.spec("color.plane").unwrap().offset,
    );
    let n = grid.rows * grid.cols;
    let dens = comp.field.params.data[d_at..][..n * 4].to_vec();
    let col = comp.field.params.data[c_at..][..n * 6].to_vec();
    // an object: a 1.2 x 0.8 m patch with a soft-edged rectangular footprint
    let rect = TexelRect { r0: 20, c0: 30, r1: 29, c1: 43 };
    let (patch, centre) = FeaturePatch::cut("chair", &grid, &dens, &col, rect, |r, c| {
        let inner = r > rect.r0 && r + 1 < rect.r1 && c > rect.c0 && c + 1 < rect.c1;
        if inner { 1.0 } else { 0.5 }
    })
    .unwrap();
    assert!((centre - Vec2::new(-0.4, -0.6)).length() < 1e-4, "{centre}");
    let mut composer = Composer::new(comp);
    let patch = Arc::new(patch);
    composer.set_template("chair", "chair", patch.clone()).unwrap();
    (composer, patch, dens, col)
}

fn planes(c: &Composer) -> Vec<f32> {
    let comp = c.composition();
    let d = comp.field.params.spec("density.plane").unwrap();
    let k = comp.field.params.spec("color.plane").unwrap();
    let mut v = comp.field.params.data[d.offset..][..d.len].to_vec();
    v.extend_from_slice(&comp.field.params.data[k.offset..][..k.len]);
    v
}

fn at(x: f32, y: f32, yaw: f32) -> GroundTransform {
    GroundTransform::new(Vec2::new(x, y), yaw, 1.0, 0.0)
}

#[test]
fn an_instance_put_back_where_it_was_cut_reproduces_the_planes() {
    let (mut c, _, dens, col) = setup();
    let before = planes(&c);
    c.spawn("chair[0]", "chair", at(-0.4, -0.6, 0.0)).unwrap();
    c.update();
    let after = planes(&c);
    let mut original = dens.clone();
    original.extend_from_slice(&col);
    let worst = after.iter().zip(&original).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "largest difference {worst}");
    assert_eq!(before, original, "the canvas starts as the field's planes");
    let s = c.stats();
    assert!(s.texels > 0 && s.texels < 40 * 40, "redrew {} texels for one instance", s.texels);
}

#[test]
fn incremental_edits_match_a_full_redraw_and_cost_follows_the_edited_area() {
    let (mut c, patch, _, _) = setup();
    let mut keys = Vec::new();
    for i in 0..6 {
        let e = c
            .spawn(&format!("chair[{i}]"), "chair", at(-3.0 + i as f32 * 1.1, 1.5, 30.0 * i as f32))
            .unwrap();
        keys.push(e);
    }
    c.update();
    let full = c.composition().grid.rows * c.composition().grid.cols;
    // one move: only the old and new footprints are redrawn
    c.set_placement(keys[2], at(0.5, -1.5, 90.0)).unwrap();
    c.update();
    let s = c.stats();
    assert!(s.texels > 0 && s.texels * 5 < full, "a move redrew {} of {full} texels", s.texels);
    // rotate, scale, delete, duplicate, warp
    c.set_placement(keys[0], GroundTransform::new(Vec2::new(-3.0, 1.5), 137.0, 1.3, 0.0)).unwrap();
    c.despawn(keys[4]);
    c.spawn("chair[6]", "chair", at(2.5, -2.0, -45.0)).unwrap();
    let warped = Arc::new(patch.with_density_of(&patch).unwrap());
    c.set_override(keys[1], Some(warped)).unwrap();
    c.update();
    // nothing changed: nothing redrawn
    c.update();
    assert_eq!(c.stats().texels, 0, "an idle frame redraws nothing");
    let incremental = planes(&c);
    c.rasterise_everything();
    let scratch = planes(&c);
    let worst = incremental.iter().zip(&scratch).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-6, "incremental planes differ from a full redraw by {worst}");
}

#[test]
fn a_category_edit_redraws_every_instance_of_the_template() {
    let (mut c, patch, _, _) = setup();
    let a = c.spawn("a", "chair", at(-2.0, 1.0, 0.0)).unwrap();
    let b = c.spawn("b", "chair", at(2.0, -1.0, 45.0)).unwrap();
    c.update();
    // recolour the category: shift every colour feature
    let mut recoloured = (*patch).clone();
    recoloured.color.iter_mut().for_each(|v| *v += 0.5);
    c.set_template("chair", "chair", Arc::new(recoloured)).unwrap();
    c.update();
    let s = c.stats();
    assert_eq!(s.rects, 2, "both instances' rectangles are redrawn");
    let incremental = planes(&c);
    c.rasterise_everything();
    assert_eq!(incremental, planes(&c));
    let _ = (a, b);
}

#[test]
fn bad_edits_are_refused_with_the_instance_named() {
    let (mut c, _, _, _) = setup();
    let e = c.spawn("ok", "chair", at(0.0, 0.0, 0.0)).unwrap();
    let err = c.spawn("zero", "chair", GroundTransform::new(Vec2::ZERO, 0.0, 0.0, 0.0));
    assert!(matches!(err, Err(SceneError::BadTransform { ref key, .. }) if key == "zero"));
    let err = c.spawn("far", "chair", at(40.0, 0.0, 0.0)).unwrap_err().to_string();
    assert!(err.contains("far") && err.contains("outside the canvas"), "{err}");
    let err = c.spawn("x", "sofa", at(0.0, 0.0, 0.0)).unwrap_err().to_string();
    assert!(err.contains("unknown asset \"sofa\""), "{err}");
    assert!(c.set_placement(e, GroundTransform::new(Vec2::ZERO, 0.0, -1.0, 0.0)).is_err());
    // a patch with other channel counts (other axes / decoders) is refused
    let other = FeaturePatch::new(
        "alien",
        2,
        2,
        Vec2::splat(0.1),
        vec![0.0; 4 * 5],
        vec![0.0; 4 * 6],
        vec![1.0; 4],
    )
    .unwrap();
    let err = c.set_template("alien", "alien", Arc::new(other)).unwrap_err().to_string();
    assert!(err.contains("density channels"), "{err}");
}

#[test]
fn additive_density_keeps_the_canvas_under_objects_and_sums_overlaps() {
    let (mut c, patch, dens, col) = setup();
    c.world.resource_mut::<assetfield_scene::world::ComposedPlanes>().0.density_rule =
        assetfield_scene::DensityRule::Add;
    // two copies overlapping at the same spot: density = canvas + 2 x patch, colour = patch
    c.spawn("a", "chair", at(0.0, 0.0, 0.0)).unwrap();
    c.spawn("b", "chair", at(0.0, 0.0, 0.0)).unwrap();
    c.update();
    let comp = c.composition();
    let grid = comp.grid;
    let (r, col_idx) = (30usize, 40usize); // the texel at (0, 0): inside both copies
    assert!((grid.world(r, col_idx) - Vec2::ZERO).length() < 1e-4);
    let k = r * grid.cols + col_idx;
    let (pr, pc) = ((patch.rows - 1) / 2, (patch.cols - 1) / 2);
    let pk = pr * patch.cols + pc;
    assert_eq!(patch.weight[pk], 1.0);
    let d = comp.field.params.spec("density.plane").unwrap();
    let got = &comp.field.params.data[d.offset + k * 4..][..4];
    for i in 0..4 {
        let want = dens[k * 4 + i] + 2.0 * patch.density[pk * 4 + i];
        assert!((got[i] - want).abs() < 1e-5, "channel {i}: {} vs {want}", got[i]);
    }
    let cs = comp.field.params.spec("color.plane").unwrap();
    let got = &comp.field.params.data[cs.offset + k * 6..][..6];
    for i in 0..6 {
        assert!((got[i] - patch.color[pk * 6 + i]).abs() < 1e-5, "colour {i}");
    }
    // far from both, the canvas is untouched
    let far = 5 * grid.cols + 5;
    assert_eq!(&comp.field.params.data[d.offset + far * 4..][..4], &dens[far * 4..][..4]);
    let _ = col;
}

#[test]
fn under_the_additive_rule_a_core_displaces_the_canvas_and_the_ring_adds_to_it() {
    // the chair's inner texels are its core: there its features are the whole column
    let (mut c, patch, dens, _) = setup();
    let core: Vec<f32> = patch.weight.iter().map(|&w| if w == 1.0 { 1.0 } else { 0.0 }).collect();
    let cored = Arc::new((*patch).clone().with_core(core).unwrap());
    c.set_template("cored", "chair", cored.clone()).unwrap();
    c.world.resource_mut::<assetfield_scene::world::ComposedPlanes>().0.density_rule =
        assetfield_scene::DensityRule::Add;
    // moved by whole texels to (1.0, 0.5), where the canvas holds other features
    c.spawn("a", "cored", at(1.0, 0.5, 0.0)).unwrap();
    c.update();
    let comp = c.composition();
    let grid = comp.grid;
    let d = comp.field.params.spec("density.plane").unwrap();
    let texel = |x: f32, y: f32| {
        let k = (0..grid.rows * grid.cols)
            .find(|&k| (grid.world(k / grid.cols, k % grid.cols) - Vec2::new(x, y)).length() < 1e-4)
            .unwrap();
        (k, &comp.field.params.data[d.offset + k * 4..][..4])
    };
    // the patch centre: a core texel, exactly the patch's features whatever the canvas
    let pk = (patch.rows - 1) / 2 * patch.cols + (patch.cols - 1) / 2;
    let (k, got) = texel(1.0, 0.5);
    assert!((0..4).any(|i| (dens[k * 4 + i]).abs() > 1e-3), "the canvas is not empty there");
    for i in 0..4 {
        assert!((got[i] - cored.density[pk * 4 + i]).abs() < 1e-5, "core channel {i}");
    }
    // a corner of the patch: ring (weight 0.5, no core), canvas plus half the features
    let corner = Vec2::new(1.0, 0.5) - cored.half_extent();
    let (k, got) = texel(corner.x, corner.y);
    assert_eq!((cored.weight[0], cored.core[0]), (0.5, 0.0));
    for i in 0..4 {
        let want = dens[k * 4 + i] + 0.5 * cored.density[i];
        assert!((got[i] - want).abs() < 1e-5, "ring channel {i}: {} vs {want}", got[i]);
    }
}

#[test]
fn a_container_entity_is_the_canvas_and_swapping_it_redraws_everything() {
    let (mut c, _, dens, col) = setup();
    c.spawn("chair[0]", "chair", at(1.0, 1.0, 45.0)).unwrap();
    c.update();
    let with_field_canvas = planes(&c);
    // an empty room: zero features everywhere but under the chair
    let n = dens.len() / 4;
    c.set_container("empty room", vec![0.0; n * 4], vec![0.0; n * 6]).unwrap();
    c.update();
    let s = c.stats();
    let grid = c.composition().grid;
    assert_eq!(s.texels, grid.rows * grid.cols, "a new container redraws every texel");
    let empty = planes(&c);
    assert_ne!(empty, with_field_canvas);
    let far = 2 * grid.cols + 2;
    assert!(empty[far * 4..far * 4 + 4].iter().all(|v| *v == 0.0), "the canvas is the container");
    // swapping back to the original planes restores the first picture
    c.set_container("field", dens.clone(), col.clone()).unwrap();
    c.update();
    let back = planes(&c);
    let worst =
        back.iter().zip(&with_field_canvas).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-6, "{worst}");
    // an idle frame redraws nothing; removing the container empties the canvas
    c.update();
    assert_eq!(c.stats().texels, 0);
    c.remove_container();
    c.update();
    assert_eq!(planes(&c), empty, "no container: empty space under the chair");
    // a container of the wrong size is refused, naming it
    let e = c.set_container("attic", vec![0.0; 3], vec![0.0; 3]).unwrap_err();
    assert!(e.to_string().contains("attic"), "{e}");
}

#[test]
fn an_asset_is_placed_and_turned_about_its_pivot() {
    // the chair's patch with its pivot 0.4 m to its -x side (as a street lamp's pole)
    let (mut c, patch, dens, col) = setup();
    let pivoted = Arc::new((*patch).clone().with_origin(Vec2::new(0.4, 0.0)));
    c.set_template("lamp", "lamp", pivoted).unwrap();
    // placed at its pivot, it restores the planes it was cut from
    let e = c.spawn("lamp[0]", "lamp", at(-0.8, -0.6, 0.0)).unwrap();
    c.update();
    let mut original = dens.clone();
    original.extend_from_slice(&col);
    let worst = planes(&c).iter().zip(&original).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    assert!(worst < 1e-5, "largest difference {worst}");
    // a quarter turn about the pivot swings the patch centre to 0.4 m along +y of it: the
    // same planes as the centred patch drawn there, and as a redraw from scratch
    c.set_placement(e, at(1.0, 0.5, 90.0)).unwrap();
    c.update();
    let turned = planes(&c);
    let (mut reference, _, _, _) = setup();
    reference.spawn("chair[0]", "chair", at(1.0, 0.9, 90.0)).unwrap();
    reference.update();
    let worst =
        turned.iter().zip(planes(&reference)).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    assert!(worst < 1e-5, "turned about the pivot: largest difference {worst}");
    c.rasterise_everything();
    let worst = turned.iter().zip(planes(&c)).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    assert!(worst < 1e-6, "incremental vs full redraw: {worst}");
}
