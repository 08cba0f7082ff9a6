//! `GpuViews`: one field version uploaded at a time, and the one rule for when a device
//! failure hands the views to the CPU.

mod common;

use assetfield_core::Aabb3;
use assetfield_field::{DecoderKind, Field, FieldConfig, ModelKind};
use assetfield_gpu::{FieldRenderer, GpuContext, GpuError, GpuView, GpuViews};
use common::{cameras, context_or_skip, occupancy, structured_field};
use glam::Vec3;

fn mlp() -> DecoderKind {
    DecoderKind::Mlp { hidden: vec![64], view_freqs: 2 }
}

/// A field the shader cannot take (a hidden layer wider than it holds): a failure the CPU
/// renderer can take over.
fn too_wide() -> Field {
    let mut cfg =
        FieldConfig::new(ModelKind::Standard, Aabb3::new(common::AABB_MIN, common::AABB_MAX), 16);
    cfg.decoder = DecoderKind::Mlp { hidden: vec![256], view_freqs: 2 };
    Field::new(cfg, 1)
}

fn rendered(v: GpuView<Vec<f32>>) -> Vec<f32> {
    match v {
        GpuView::Done(rgb) => rgb,
        GpuView::FellBack { note } => panic!("fell back: {note}"),
    }
}

#[test]
fn views_follow_the_field_version_and_fall_back_only_where_allowed() {
    let Some(shared) = context_or_skip("views_follow_the_field_version") else { return };
    let cam = &cameras(24)[0];
    let bg = Vec3::ONE;
    let a = structured_field(ModelKind::Standard, mlp());
    let mut b = a.clone();
    b.params.data.iter_mut().for_each(|p| *p *= 0.5);
    let direct = |f: &Field| {
        FieldRenderer::new(shared, f, Some(&occupancy(f))).unwrap().render(cam, bg).unwrap()
    };
    let mut views = GpuViews::new(GpuContext::new().unwrap(), false);
    // version 0 is uploaded once and renders as a renderer of its own does
    let (occ_a, occ_b) = (occupancy(&a), occupancy(&b));
    let first = rendered(views.render(&a, Some(&occ_a), 0, cam, bg).unwrap());
    assert_eq!(first, direct(&a));
    // the same version is not uploaded again: another field under version 0 renders as a
    assert_eq!(rendered(views.render(&b, Some(&occ_b), 0, cam, bg).unwrap()), first);
    // a new version is
    let second = rendered(views.render(&b, Some(&occ_b), 1, cam, bg).unwrap());
    assert_eq!(second, direct(&b));
    assert_ne!(second, first);
    // a failure the CPU could take over is an error where falling back is not allowed ...
    let wide = too_wide();
    let err = views.render(&wide, None, 2, cam, bg).unwrap_err();
    assert!(matches!(err, GpuError::Unsupported(_)), "{err}");
    // ... and hands over, with a note, where it is
    let mut auto = GpuViews::new(GpuContext::new().unwrap(), true);
    match auto.prepare(&wide, None, 0).unwrap() {
        GpuView::FellBack { note } => assert!(note.contains("GPU"), "{note}"),
        GpuView::Done(()) => panic!("a field too wide for the shader uploaded"),
    }
    // bad input is never the device's failure: no fallback for it
    assert!(!GpuError::Input("x".into()).cpu_can_do_it());
}
