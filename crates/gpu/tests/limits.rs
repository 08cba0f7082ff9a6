//! Fields the renderer cannot take give clear errors, never panics.

mod common;

use assetfield_core::Aabb3;
use assetfield_field::{DecoderKind, Field, FieldConfig, ModelKind};
use assetfield_gpu::{FieldRenderer, GpuError, plan_upload};
use common::{context_or_skip, occupancy, structured_field};

fn mlp() -> DecoderKind {
    DecoderKind::Mlp { hidden: vec![64], view_freqs: 2 }
}

#[test]
fn a_field_larger_than_a_storage_buffer_is_refused() {
    let field = structured_field(ModelKind::Standard, mlp());
    let bytes = field.params.len() as u64 * 4;
    // a device whose storage buffers hold a little less than the field
    let limits = wgpu::Limits { max_storage_buffer_binding_size: bytes - 4, ..Default::default() };
    let err = plan_upload(&field, None, &limits).unwrap_err();
    match &err {
        GpuError::BufferTooLarge { what, bytes: b, limit } => {
            assert_eq!(*what, "the field's parameters");
            assert_eq!((*b, *limit), (bytes, bytes - 4));
        }
        e => panic!("expected BufferTooLarge, got {e:?}"),
    }
    let msg = err.to_string();
    eprintln!("{msg}");
    assert!(msg.contains(&bytes.to_string()) && msg.contains("max_storage_buffer_binding_size"));
    // max_buffer_size counts too
    let limits = wgpu::Limits { max_buffer_size: 1024, ..Default::default() };
    assert!(matches!(
        plan_upload(&field, None, &limits),
        Err(GpuError::BufferTooLarge { limit: 1024, .. })
    ));
    // exactly at the limit is fine
    let limits = wgpu::Limits { max_storage_buffer_binding_size: bytes, ..Default::default() };
    let plan = plan_upload(&field, Some(&occupancy(&field)), &limits).unwrap();
    assert_eq!(plan.params_bytes, bytes);
    assert!(plan.pass_rays >= 64);
}

#[test]
fn layers_wider_than_the_shader_are_refused() {
    let aabb = Aabb3::new(common::AABB_MIN, common::AABB_MAX);
    let limits = wgpu::Limits::default();
    let mut cfg = FieldConfig::new(ModelKind::Standard, aabb, 16);
    cfg.decoder = DecoderKind::Mlp { hidden: vec![256], view_freqs: 2 };
    let err = plan_upload(&Field::new(cfg, 1), None, &limits).unwrap_err();
    assert!(matches!(err, GpuError::Unsupported(_)), "{err}");
    eprintln!("{err}");
    let mut cfg = FieldConfig::new(ModelKind::Integrated, aabb, 16);
    cfg.density_channels = 200;
    let err = plan_upload(&Field::new(cfg, 1), None, &limits).unwrap_err();
    assert!(matches!(err, GpuError::Unsupported(_)), "{err}");
    let mut cfg = FieldConfig::new(ModelKind::Standard, aabb, 16);
    cfg.decoder = DecoderKind::Mlp { hidden: vec![16; 4], view_freqs: 2 };
    let err = plan_upload(&Field::new(cfg, 1), None, &limits).unwrap_err();
    assert!(matches!(err, GpuError::Unsupported(_)), "{err}");
}

/// On a real device: the field fits, and the device's own limit is what is checked.
#[test]
fn the_device_limits_are_used() {
    let Some(ctx) = context_or_skip("the_device_limits_are_used") else { return };
    let field = structured_field(ModelKind::Integrated, mlp());
    let limits = ctx.limits();
    eprintln!(
        "device: max_storage_buffer_binding_size {} max_buffer_size {}",
        limits.max_storage_buffer_binding_size, limits.max_buffer_size
    );
    let r = FieldRenderer::new(ctx, &field, None).unwrap();
    assert_eq!(r.plan().params_bytes, field.params.len() as u64 * 4);
}
