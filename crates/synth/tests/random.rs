//! Random scenes: determinism, the drawn properties, and the validation seeds synthesising.
//!
//! Synthesis needs the Sweet Home 3D catalogs: without them those tests print
//! `SKIPPED: sweethome3d-furniture not installed (...)` (and fail under
//! `ASSETFIELD_STRICT_TESTS=1`); drawing scripts needs nothing.

use assetfield_layout::{ResolvedLayout, load_str, resolve};
use assetfield_synth::random::{CATEGORIES, RANDOM_RESOLUTION, UNITS_PER_METRE, random_scene};
use assetfield_synth::sh3f::{DIR_ENV, catalog_dir, catalogs_installed};
use assetfield_synth::{AssetSet, LoadedScene, SynthOptions, synthesize_loaded};
use glam::Vec2;
use std::path::{Path, PathBuf};

#[derive(Debug)]
struct Seeds {
    validation: Vec<u64>,
    dev: Vec<u64>,
}

/// `scenes/validation_seeds.txt`: lines `NAME: SEED SEED ...`, `#` comments.
fn seeds() -> Seeds {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/validation_seeds.txt");
    let text = std::fs::read_to_string(p).unwrap();
    let list = |name: &str| -> Vec<u64> {
        let lines: Vec<&str> = text
            .lines()
            .map(|l| l.split('#').next().unwrap().trim())
            .filter(|l| l.starts_with(&format!("{name}:")))
            .collect();
        assert_eq!(lines.len(), 1, "one `{name}:` line");
        lines[0][name.len() + 1..].split_whitespace().map(|s| s.parse().unwrap()).collect()
    };
    Seeds { validation: list("validation"), dev: list("dev") }
}

fn catalogs_or_skip(test: &str) -> bool {
    let dir = catalog_dir();
    if catalogs_installed(&dir) {
        return true;
    }
    let why = format!(
        "{} lacks the catalogs; apt-get install sweethome3d-furniture, or set {DIR_ENV}",
        dir.display()
    );
    if std::env::var("ASSETFIELD_STRICT_TESTS").as_deref() == Ok("1") {
        panic!("{test}: sweethome3d-furniture not installed ({why}) and ASSETFIELD_STRICT_TESTS=1");
    }
    eprintln!("SKIPPED: sweethome3d-furniture not installed ({why}); {test} did not run");
    false
}

#[test]
fn the_seed_files_lists_are_fixed() {
    let s = seeds();
    // a validation seed only ever leaves for dev (once it has been debugged), replaced by a
    // seed never drawn before: 1003 and 1008 left, 1013 and 1014 came
    assert_eq!(
        s.validation,
        vec![1001, 1002, 1004, 1005, 1006, 1007, 1009, 1010, 1011, 1012, 1013, 1014]
    );
    // the dev list may grow (seeds 6, 10, 11 and 12 joined it later, 1003 and 1008 from
    // validation)
    assert_eq!(s.dev, vec![1, 2, 3, 4, 6, 10, 11, 12, 1003, 1008]);
    assert!(s.dev.iter().all(|d| !s.validation.contains(d)));
    assert!(s.validation.len() >= 12);
}

#[test]
fn a_seed_gives_the_same_script_byte_for_byte() {
    for seed in [1, 1001, 77] {
        let a = random_scene(seed).unwrap();
        let b = random_scene(seed).unwrap();
        assert_eq!(a.text, b.text);
        // the text is an ordinary script that reads back to the same value
        let back = assetfield_layout::source::parse_script(Path::new("r.ron"), &a.text).unwrap();
        assert_eq!(back, a.script);
    }
    assert_ne!(random_scene(1).unwrap().text, random_scene(2).unwrap().text);
}

/// Whether two footprints (as world quads) overlap: separating axis test.
fn quads_overlap(a: &[Vec2; 4], b: &[Vec2; 4]) -> bool {
    for quad in [a, b] {
        for k in 0..4 {
            let e = quad[(k + 1) % 4] - quad[k];
            let n = Vec2::new(-e.y, e.x);
            let pa = a.iter().map(|p| n.dot(*p));
            let pb = b.iter().map(|p| n.dot(*p));
            let (amin, amax) = pa.fold((f32::MAX, f32::MIN), |(l, h), v| (l.min(v), h.max(v)));
            let (bmin, bmax) = pb.fold((f32::MAX, f32::MIN), |(l, h), v| (l.min(v), h.max(v)));
            // touching is allowed (pairs in contact): demand a real overlap
            let tol = 1e-4 * n.length();
            if amax <= bmin + tol || bmax <= amin + tol {
                return false;
            }
        }
    }
    true
}

fn quad(i: &assetfield_layout::ResolvedInstance) -> [Vec2; 4] {
    let (a, b) = (i.footprint.min, i.footprint.max);
    [a, Vec2::new(b.x, a.y), b, Vec2::new(a.x, b.y)].map(|p| i.transform.transform_point2(p))
}

fn check_properties(seed: u64, layout: &ResolvedLayout, units: f32) -> usize {
    let cats = layout.categories();
    assert!((CATEGORIES.0..=CATEGORIES.1).contains(&cats.len()), "seed {seed}: {cats:?}");
    assert!((UNITS_PER_METRE.0..UNITS_PER_METRE.1).contains(&units), "seed {seed}: {units}");
    let ground: Vec<_> = layout.objects().filter(|i| i.supported_by.is_none()).collect();
    for (k, a) in ground.iter().enumerate() {
        for b in &ground[k + 1..] {
            assert!(
                !quads_overlap(&quad(a), &quad(b)),
                "seed {seed}: {} overlaps {}",
                a.key,
                b.key
            );
        }
    }
    for c in &cats {
        let n = layout.objects().filter(|i| &i.category == c).count();
        assert!(n >= 1, "seed {seed}: {c}");
    }
    layout.objects().filter(|i| i.supported_by.is_some()).count()
}

#[test]
fn drawn_properties_hold_for_many_seeds() {
    // resolved with the draw's own sizes (no catalog needed): categories, units, no overlaps
    let s = seeds();
    let mut on_tables = 0;
    let mut pairs = 0;
    for seed in s.validation.iter().chain(&s.dev).copied().chain(2000..2030) {
        let r = random_scene(seed).unwrap();
        assert_eq!(r.script.units_per_metre, Some(r.units_per_metre));
        assert_eq!(r.script.views.as_ref().and_then(|v| v.resolution), Some(RANDOM_RESOLUTION));
        let loaded = load_str(Path::new("r.ron"), &r.text).unwrap();
        let layout = resolve(&loaded, &r.catalog().unwrap()).unwrap();
        check_properties(seed, &layout, r.units_per_metre);
        on_tables += usize::from(r.text.contains("on: \""));
        pairs += usize::from(r.text.contains("_pair"));
    }
    assert!(on_tables >= 5, "only {on_tables} scenes have objects on tables");
    assert!(pairs >= 5, "only {pairs} scenes have touching pairs");
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("assetfield-random-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn every_validation_and_dev_seed_synthesises() {
    if !catalogs_or_skip("random scene synthesis") {
        return;
    }
    let s = seeds();
    let opts = SynthOptions {
        views: Some(3),
        test_views: Some(1),
        resolution: Some(12),
        samples_per_side: Some(1),
        ..Default::default()
    };
    let mut with_table_objects = 0;
    let root = scratch("suite");
    for seed in s.validation.iter().chain(&s.dev).copied() {
        let r = random_scene(seed).unwrap();
        let path = PathBuf::from(format!("random_{seed}.ron"));
        let loaded = load_str(&path, &r.text).unwrap();
        let assets = AssetSet::from_script(&loaded).unwrap();
        let layout = resolve(&loaded, &assets).unwrap();
        with_table_objects += usize::from(check_properties(seed, &layout, r.units_per_metre) > 0);
        let out = root.join(seed.to_string());
        let mut progress = |_: usize, _: usize| {};
        let source = LoadedScene { script: &loaded, path: &path, text: Some(&r.text) };
        let report = synthesize_loaded(source, &opts, &out, false, None, &mut progress).unwrap();
        assert_eq!(report.units_per_metre, r.units_per_metre);
        assert_eq!(report.categories.len(), layout.categories().len());
        // the dataset holds the script, and the ground truth records units and sources
        assert_eq!(std::fs::read_to_string(out.join("scene.ron")).unwrap(), r.text);
        let gt: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("gt_layout.json")).unwrap())
                .unwrap();
        assert_eq!(gt["units_per_metre"].as_f64().unwrap() as f32, r.units_per_metre);
        for inst in gt["instances"].as_array().unwrap() {
            let catalog_model = inst["asset"].as_str().unwrap().starts_with(['k', 'b'])
                && inst["asset"].as_str().unwrap().as_bytes().get(2) == Some(&b'_');
            if catalog_model {
                let src = &inst["source"];
                assert!(src["license"].as_str().unwrap().contains("Creative Commons"), "{inst}");
                assert!(!src["creator"].as_str().unwrap().is_empty(), "{inst}");
            }
        }
    }
    assert!(with_table_objects >= 3, "only {with_table_objects} scenes with objects on tables");
    let _ = std::fs::remove_dir_all(&root);
}
