//! Every hand-written gradient against central finite differences, for every model kind and
//! decoder: the full chain from compositing through colour decoders, basis, guidance MLP,
//! planes and axes down to the density features.

use assetfield_core::{Aabb3, Ray};
use assetfield_field::march::{backward, forward};
use assetfield_field::{DecoderKind, Field, FieldConfig, MarchSettings, MarchWork, ModelKind};
use glam::Vec3;

fn tiny(kind: ModelKind, decoder: DecoderKind, semantic: usize) -> Field {
    let aabb = Aabb3::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 1.0));
    let mut cfg = FieldConfig::new(kind, aabb, 6);
    cfg.res = [6, 5, 4];
    cfg.density_channels = 3;
    cfg.color_channels = 4;
    cfg.basis_dim = 5;
    cfg.guide_hidden = 5;
    cfg.decoder = decoder;
    cfg.semantic_channels = semantic;
    cfg.density_shift = -1.0;
    cfg.distance_scale = 1.5;
    cfg.step_ratio = 1.7;
    // seed chosen so that no ReLU unit sits within the finite-difference step of its kink
    let mut f = Field::new(cfg, if semantic > 0 { 3 } else { 7 });
    // larger grid values than the default init so every term matters
    for v in f.params.data.iter_mut() {
        *v *= 4.0;
    }
    f
}

fn rays() -> Vec<Ray> {
    let o = Vec3::new(-2.0, -1.7, 1.6);
    [
        Vec3::new(0.5, 0.1, 0.0),
        Vec3::new(-0.3, 0.4, 0.2),
        Vec3::new(0.2, -0.5, 0.5),
        Vec3::new(0.9, 0.8, 0.1),
    ]
    .iter()
    .map(|t| Ray { origin: o, dir: (*t - o).normalize() })
    .collect()
}

const SETTINGS: MarchSettings = MarchSettings {
    weight_threshold: 0.0,
    stop_transmittance: 0.0,
    max_samples: 10_000,
    color_grad_weight: 0.0,
    density_grad_alpha: 0.0,
};

const SEM_TARGET: f32 = 0.3;

fn loss(field: &Field, w: &mut MarchWork) -> f64 {
    let bg = Vec3::new(1.0, 0.9, 0.8);
    let rs = rays();
    w.want_semantic = field.has_semantic();
    forward(field, None, &rs, Some(&[0.1, 0.5, 0.9, 0.3]), bg, &SETTINGS, w);
    let target = Vec3::new(0.2, 0.6, 0.4);
    let rgb: f64 = w.rgb.iter().map(|c| (*c - target).length_squared() as f64).sum();
    let sem: f64 = w.semantic.iter().map(|f| ((f - SEM_TARGET) as f64).powi(2)).sum();
    rgb + sem
}

fn check(kind: ModelKind, decoder: DecoderKind, semantic: usize) {
    let mut field = tiny(kind, decoder.clone(), semantic);
    let mut w = MarchWork::default();
    let bg = Vec3::new(1.0, 0.9, 0.8);
    let base = loss(&field, &mut w);
    assert!(w.samples > 10, "the rays must cross the field ({} samples)", w.samples);
    assert_eq!(w.semantic.len(), rays().len() * semantic, "semantic output per ray");
    let target = Vec3::new(0.2, 0.6, 0.4);
    let d_rgb: Vec<Vec3> = w.rgb.iter().map(|c| 2.0 * (*c - target)).collect();
    let d_sem: Vec<f32> = w.semantic.iter().map(|f| 2.0 * (f - SEM_TARGET)).collect();
    let mut grad = vec![0.0f32; field.params.len()];
    backward(&field, bg, &d_rgb, (semantic > 0).then_some(&d_sem[..]), &mut w, &mut grad);

    // f32 forward: steps of 4e-3 keep rounding noise (~1e-5) well under the tolerance floor
    let eps = 4e-3f32;
    let gmax = grad.iter().fold(0.0f32, |m, g| m.max(g.abs())) as f64;
    let mut worst = (0.0f64, String::new());
    let (mut dot, mut na, mut nn) = (0.0f64, 0.0f64, 0.0f64);
    let specs = field.params.specs.clone();
    for spec in &specs {
        for k in 0..spec.len {
            let i = spec.offset + k;
            let v = field.params.data[i];
            field.params.data[i] = v + eps;
            let lp = loss(&field, &mut w);
            field.params.data[i] = v - eps;
            let lm = loss(&field, &mut w);
            field.params.data[i] = v;
            let numeric = (lp - lm) / (2.0 * eps as f64);
            let analytic = grad[i] as f64;
            dot += numeric * analytic;
            na += analytic * analytic;
            nn += numeric * numeric;
            // relative error with a floor of 1e-3 of the largest gradient
            let err =
                (numeric - analytic).abs() / (numeric.abs().max(analytic.abs()) + 1e-2 * gmax);
            if err > worst.0 {
                worst = (
                    err,
                    format!("{}[{k}]: analytic {analytic:.6} numeric {numeric:.6}", spec.name),
                );
            }
        }
    }
    let cosine = dot / (na.sqrt() * nn.sqrt()).max(1e-30);
    let label = format!("{kind:?} {decoder:?} semantic {semantic}");
    assert!(na > 1e-8, "{label}: gradient is zero");
    assert!(cosine > 0.9999, "{label}: gradient direction off (cosine {cosine})");
    assert!(
        worst.0 < 0.05,
        "{label}: worst parameter {} (relative error {:.4}); loss {base}",
        worst.1,
        worst.0
    );
    eprintln!(
        "{label}: {} parameters, cosine {cosine:.7}, worst relative error {:.5}",
        field.params.len(),
        worst.0
    );
}

#[test]
fn standard_with_mlp_decoder() {
    check(ModelKind::Standard, DecoderKind::Mlp { hidden: vec![6, 5], view_freqs: 2 }, 0);
}

#[test]
fn standard_with_sh_decoder() {
    check(ModelKind::Standard, DecoderKind::Sh { degree: 2 }, 0);
}

#[test]
fn integrated_with_guidance_and_mlp_decoder() {
    check(ModelKind::Integrated, DecoderKind::Mlp { hidden: vec![6], view_freqs: 1 }, 0);
}

#[test]
fn integrated_with_sh_decoder() {
    check(ModelKind::Integrated, DecoderKind::Sh { degree: 1 }, 0);
}

#[test]
fn vm_baseline_with_mlp_decoder() {
    check(ModelKind::Vm, DecoderKind::Mlp { hidden: vec![6], view_freqs: 2 }, 0);
}

#[test]
fn vm_baseline_with_sh_decoder() {
    check(ModelKind::Vm, DecoderKind::Sh { degree: 0 }, 0);
}

#[test]
fn integrated_with_semantic_head() {
    check(ModelKind::Integrated, DecoderKind::Mlp { hidden: vec![6], view_freqs: 1 }, 3);
}

#[test]
fn integrated_with_semantic_head_and_sh_decoder() {
    check(ModelKind::Integrated, DecoderKind::Sh { degree: 1 }, 2);
}

/// A stochastic gradient estimator (the settings `with` gives for a threshold `tau`, `tau`
/// above every sample's weight or opacity, so each sample's share is a coin toss) is
/// unbiased: averaged over many draws (jitters that differ in their last bits, so the
/// samples stay put while the draw changes) it gives the exact gradient (`tau` 0); a single
/// draw differs from it, and the colours (the forward pass) are untouched.
fn draws_average_to_the_exact_gradient(with: impl Fn(f32) -> MarchSettings, tau: f32) {
    let field = tiny(ModelKind::Standard, DecoderKind::Mlp { hidden: vec![8], view_freqs: 1 }, 0);
    let bg = Vec3::new(1.0, 0.9, 0.8);
    let target = Vec3::new(0.2, 0.6, 0.4);
    let rs = rays();
    let gradient = |tau: f32, jitter: &[f32]| {
        let mut w = MarchWork::default();
        forward(&field, None, &rs, Some(jitter), bg, &with(tau), &mut w);
        let d_rgb: Vec<Vec3> = w.rgb.iter().map(|c| 2.0 * (*c - target)).collect();
        let mut g32 = vec![0.0f32; field.params.len()];
        backward(&field, bg, &d_rgb, None, &mut w, &mut g32);
        (g32.iter().map(|g| f64::from(*g)).collect::<Vec<_>>(), w.rgb.clone())
    };
    let base = [0.1f32, 0.5, 0.9, 0.3];
    let (exact, rgb) = gradient(0.0, &base);
    let draws = 4000;
    let mut mean = vec![0.0f64; exact.len()];
    let mut skipped_all = 0;
    for m in 0..draws {
        let jitter: Vec<f32> =
            base.iter().map(|j| f32::from_bits(j.to_bits() ^ (m as u32 & 0xff))).collect();
        let (g, c) = gradient(tau, &jitter);
        for (a, b) in rgb.iter().zip(&c) {
            assert!((*a - *b).length() < 1e-5, "colours stay exact");
        }
        skipped_all += usize::from(g.iter().zip(&exact).all(|(a, b)| a == b));
        for (s, v) in mean.iter_mut().zip(&g) {
            *s += v / f64::from(draws);
        }
    }
    assert_eq!(skipped_all, 0, "draws differ from the exact gradient");
    let norm = exact.iter().map(|g| g * g).sum::<f64>().sqrt();
    let err = mean.iter().zip(&exact).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
    assert!(err < 0.05 * norm, "mean of draws off by {err} (norm {norm})");
}

/// Stochastic colour gradients (`MarchSettings::color_grad_weight`) are unbiased; a single
/// draw skips most faint samples' decoder gradient.
#[test]
fn stochastic_colour_gradients_average_to_the_exact_gradient() {
    draws_average_to_the_exact_gradient(
        |tau| MarchSettings { color_grad_weight: tau, ..SETTINGS },
        2.0,
    );
}

/// Stochastic density gradients (`MarchSettings::density_grad_alpha`) are unbiased; a single
/// draw skips most samples' density-grid gradient.
#[test]
fn stochastic_density_gradients_average_to_the_exact_gradient() {
    draws_average_to_the_exact_gradient(
        |tau| MarchSettings { density_grad_alpha: tau, ..SETTINGS },
        1.0,
    );
}
