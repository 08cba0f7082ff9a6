//! Template refinement's building blocks: the templates-only composition it writes through
//! its taps is the rasteriser's, and its mapping of plane gradients onto template texels is
//! the exact transpose of that composition (checked against finite differences of a linear
//! functional).

use assetfield_library::write_sample_library;
use assetfield_scene::AssetLibrary;
use assetfield_scene::refine::{RefineOptions, TemplateRefiner, compose_draws, template_poses};
use glam::Vec3;

fn library(name: &str) -> AssetLibrary {
    let dir = std::env::temp_dir().join(format!("assetfield-refine-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    write_sample_library(&dir, 0.25).unwrap();
    AssetLibrary::open(&dir).unwrap()
}

fn refiner(lib: &AssetLibrary) -> TemplateRefiner {
    // one view whose pixels do not matter here
    let cam = assetfield_core::Orbit::around(&lib.config.aabb(), 1, 8).cameras()[0];
    TemplateRefiner::new(
        lib,
        &lib.patches(None).unwrap(),
        vec![(cam, vec![0.5; 8 * 8 * 3])],
        Vec3::ONE,
        RefineOptions::default(),
    )
    .unwrap()
}

fn planes(lib: &AssetLibrary, r: &TemplateRefiner) -> Vec<f32> {
    let f = &r.comp.field;
    let mut out = f.params.tensor("density.plane").unwrap().to_vec();
    out.extend_from_slice(f.params.tensor("color.plane").unwrap());
    let _ = lib;
    out
}

#[test]
fn the_taps_compose_what_the_rasteriser_composes() {
    let lib = library("compose");
    let mut r = refiner(&lib);
    // give the templates distinct, non-constant features
    for (k, p) in r.params_mut().iter_mut().enumerate() {
        *p = ((k * 37 % 11) as f32 - 5.0) * 0.3;
    }
    r.compose();
    let patches = r.refined_patches();
    let draws: Vec<_> =
        template_poses(&lib.index).into_iter().map(|(c, t)| (&patches[c].1, t)).collect();
    let reference = compose_draws(&lib, &draws).unwrap();
    let want: Vec<f32> = {
        let f = &reference.field;
        let mut v = f.params.tensor("density.plane").unwrap().to_vec();
        v.extend_from_slice(f.params.tensor("color.plane").unwrap());
        v
    };
    let got = planes(&lib, &r);
    assert_eq!(got.len(), want.len());
    let worst = got.iter().zip(&want).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "taps and rasteriser differ by {worst}");
}

#[test]
fn plane_gradients_map_onto_templates_by_the_exact_transpose() {
    let lib = library("transpose");
    let mut r = refiner(&lib);
    for (k, p) in r.params_mut().iter_mut().enumerate() {
        *p = ((k * 13 % 7) as f32 - 3.0) * 0.2;
    }
    r.compose();
    // a linear functional of the composed field's parameters: <g, params>
    let n = r.comp.field.params.len();
    let g: Vec<f32> = (0..n).map(|k| ((k * 29 % 17) as f32 - 8.0) / 8.0).collect();
    let f = |r: &TemplateRefiner| -> f64 {
        r.comp.field.params.data.iter().zip(&g).map(|(a, b)| f64::from(a * b)).sum()
    };
    let analytic = r.to_templates(&[&g]);
    let base = f(&r);
    let eps = 1e-2;
    let mut checked = 0;
    for i in 0..r.params().len() {
        r.params_mut()[i] += eps;
        r.compose();
        let numeric = (f(&r) - base) / f64::from(eps);
        r.params_mut()[i] -= eps;
        let a = f64::from(analytic[i]);
        assert!((numeric - a).abs() < 2e-3 * (1.0 + a.abs()), "param {i}: {numeric} vs {a}");
        checked += usize::from(a != 0.0);
    }
    r.compose();
    assert!(checked > 10, "the functional reached {checked} template features");
}

#[test]
fn a_checkpoint_restores_the_run_and_refuses_other_templates() {
    let lib = library("ckpt");
    let mut r = refiner(&lib);
    for _ in 0..3 {
        r.step();
    }
    let f = r.checkpoint().unwrap();
    let mut again = refiner(&lib);
    again.resume(&f, std::path::Path::new("c.safetensors"), Some(10), None).unwrap();
    assert_eq!((again.iter, again.params()), (3, r.params()));
    assert_eq!(planes(&lib, &again), planes(&lib, &r));
    assert_eq!(again.options.iters, 10);
    // a checkpoint of other templates (other sizes) is refused, naming the file
    let mut other = f.clone();
    let n = r.params().len() + 1;
    other.insert_f32("params", &[n], vec![0.0; n]);
    let e = refiner(&lib).resume(&other, std::path::Path::new("c.safetensors"), None, None);
    assert!(e.unwrap_err().to_string().contains("c.safetensors"));
}
