//! The scene suite in `scenes/`: what the suite must contain, and every scene synthesised
//! (at a small resolution) with a ground-truth layout that agrees with its script.

use assetfield_core::ground::yaw_difference;
use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_layout::script::Part;
use assetfield_layout::{GtLayout, ResolvedLayout};
use assetfield_synth::{SynthOptions, load_scene, synthesize};
use assetfield_tests::{convex_overlap, footprint_polygon, scene_files, scratch};
use std::collections::BTreeMap;

fn resolved() -> Vec<(String, assetfield_layout::LoadedScript, ResolvedLayout)> {
    scene_files()
        .iter()
        .map(|p| {
            let (script, _, layout) =
                load_scene(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (p.file_stem().unwrap().to_string_lossy().into_owned(), script, layout)
        })
        .collect()
}

/// A part with its colour removed, and its colour, for comparing assets.
fn shape_and_colour(p: &Part) -> (String, (u32, u32, u32)) {
    let mut q = p.clone();
    let c = match &mut q {
        Part::Box { color, .. }
        | Part::Cylinder { color, .. }
        | Part::Cone { color, .. }
        | Part::Sphere { color, .. } => std::mem::replace(color, (0.0, 0.0, 0.0)),
    };
    (format!("{q:?}"), ((c.0 * 1000.0) as u32, (c.1 * 1000.0) as u32, (c.2 * 1000.0) as u32))
}

#[test]
fn the_suite_has_what_the_paper_setup_needs() {
    let scenes = resolved();
    assert!(scenes.len() >= 10, "at least 10 scenes, found {}", scenes.len());
    let (mut with_background, mut with_support) = (0, 0);
    let (mut colour_pair, mut shape_pair) = (None, None);
    for (name, script, layout) in &scenes {
        let cats = layout.categories();
        assert!((3..=12).contains(&cats.len()), "{name}: {} categories {cats:?}", cats.len());
        // repeated instances at varied yaw: some category has 2+ instances at yaws that differ
        // under the asset's own symmetry
        let mut by_cat: BTreeMap<&str, Vec<(f32, f32)>> = BTreeMap::new();
        for i in layout.objects() {
            by_cat.entry(&i.category).or_default().push((i.transform.yaw_deg, i.yaw_symmetry_deg));
        }
        let varied = by_cat
            .values()
            .any(|v| v.len() >= 2 && v.iter().any(|(y, s)| yaw_difference(*y, v[0].0, *s) > 5.0));
        assert!(varied, "{name}: no repeated category at varied yaw");
        assert!(by_cat.values().any(|v| v.len() >= 3), "{name}: no category repeated 3+ times");
        with_background += usize::from(layout.containers().count() > 0);
        with_support += usize::from(layout.objects().any(|i| i.supported_by.is_some()));
        // pairs of assets used together in one scene that differ only in colour / only in shape
        let used: Vec<&String> = layout
            .objects()
            .map(|i| &i.asset)
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        for (ai, a) in used.iter().enumerate() {
            for b in &used[ai + 1..] {
                let (pa, pb) = (&script.assets[*a].def.parts, &script.assets[*b].def.parts);
                if pa.is_empty() || pb.is_empty() {
                    continue;
                }
                let (sa, ca): (Vec<_>, Vec<_>) = pa.iter().map(shape_and_colour).unzip();
                let (sb, cb): (Vec<_>, Vec<_>) = pb.iter().map(shape_and_colour).unzip();
                if sa == sb && ca != cb {
                    colour_pair = Some(format!("{name}: {a} / {b}"));
                }
                let (mut ka, mut kb) = (ca.clone(), cb.clone());
                ka.sort();
                ka.dedup();
                kb.sort();
                kb.dedup();
                if ka == kb && sa != sb {
                    shape_pair = Some(format!("{name}: {a} / {b}"));
                }
            }
        }
    }
    assert!(with_background >= 2, "scenes on a visible floor or in a room: {with_background}");
    assert!(with_support >= 2, "scenes with objects standing on tables: {with_support}");
    assert!(colour_pair.is_some(), "no scene has two categories that differ only in colour");
    assert!(shape_pair.is_some(), "no scene has two categories that differ only in shape");
    eprintln!(
        "colour-only pair: {}; shape-only pair: {}",
        colour_pair.unwrap(),
        shape_pair.unwrap()
    );
}

#[test]
fn objects_on_the_ground_do_not_overlap() {
    for (name, _, layout) in resolved() {
        let ground: Vec<_> = layout.objects().filter(|i| i.supported_by.is_none()).collect();
        for (k, a) in ground.iter().enumerate() {
            for b in &ground[k + 1..] {
                let (pa, pb) = (footprint_polygon(a, 0.01), footprint_polygon(b, 0.01));
                assert!(!convex_overlap(&pa, &pb), "{name}: {} and {} overlap", a.key, b.key);
            }
        }
    }
}

#[test]
fn every_scene_synthesises_and_its_ground_truth_matches_the_script() {
    let root = scratch("suite");
    let opts = SynthOptions {
        views: Some(4),
        test_views: Some(1),
        resolution: Some(32),
        samples_per_side: Some(1),
        ..Default::default()
    };
    for path in scene_files() {
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let out = root.join(&name);
        let report = synthesize(&path, &opts, &out, false, None, &mut |_, _| {})
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let (_, _, layout) = load_scene(&path).unwrap();
        let gt = GtLayout::read(&out.join("gt_layout.json")).unwrap();
        let objects: Vec<_> = layout.objects().collect();
        assert_eq!(gt.instances.len(), objects.len(), "{name}");
        assert_eq!(report.instances, objects.len());
        for (g, o) in gt.instances.iter().zip(&objects) {
            assert_eq!((g.id, &g.category, &g.key), (o.id, &o.category, &o.key), "{name}");
            let t = o.transform;
            assert_eq!(g.position, [t.position.x, t.position.y, t.base], "{name} {}", o.key);
            assert_eq!((g.yaw_deg, g.scale), (t.yaw_deg, t.scale));
            let [x0, y0, x1, y1] = g.bev_aabb;
            assert!(
                x0 < x1
                    && y0 < y1
                    && x0 <= g.position[0]
                    && g.position[0] <= x1
                    && y0 <= g.position[1]
                    && g.position[1] <= y1
            );
            if let Some(s) = g.supported_by {
                let sup = gt.instances.iter().find(|i| i.id == s).expect("supporter is an object");
                assert!(
                    (g.position[2] - sup.top).abs() < 1e-4,
                    "{name}: {} floats above its support",
                    g.key
                );
            }
        }
        // the dataset reads back, and every view shows something
        let ds = Dataset::load(&out, Split::All, &LoadOptions::default()).unwrap();
        assert_eq!(ds.frames.len(), 4, "{name}");
        for f in &ds.frames {
            let alpha = f.image.alpha.as_ref().expect("synthetic views carry alpha");
            let covered = alpha.iter().filter(|a| **a > 0.5).count();
            assert!(covered > 20, "{name}: view {} is nearly empty", f.file_path);
        }
    }
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn the_layout_language_example_resolves() {
    let page = assetfield_tests::repo().join("docs/layout-language.md");
    let page = std::fs::read_to_string(page).unwrap();
    let block = page
        .split("```ron\n")
        .nth(1)
        .expect("docs/layout-language.md has a ```ron block")
        .split("```")
        .next()
        .unwrap();
    // resolved as if it were a file of the suite, so its includes are found
    let path = assetfield_tests::repo().join("scenes/readme_example.ron");
    let loaded = assetfield_layout::load_str(&path, block).unwrap_or_else(|e| panic!("{e}"));
    let assets = assetfield_synth::AssetSet::from_script(&loaded).unwrap();
    let layout = assetfield_layout::resolve(&loaded, &assets).unwrap_or_else(|e| panic!("{e}"));
    let lamp = layout.instances.iter().find(|i| i.asset == "lamp").unwrap();
    let table = layout.by_key("tables[4]").unwrap();
    assert_eq!(lamp.supported_by, Some(table.id));
    assert!(
        (lamp.transform.position - table.transform.position).length() < 1e-5,
        "the lamp moved with its table"
    );
    assert!(layout.by_key("tables[8]/chairs[2]").is_none());
    assert!(layout.objects().any(|i| i.key == "tables[1]+copy1"));
    assert!(layout.objects().all(|i| i.category != "plant"));
}
