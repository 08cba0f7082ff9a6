//! The library format: index round trips, the check's errors, merging.

use assetfield_core::fsx::write_atomic;
use assetfield_library::{
    INDEX_FILE, LibraryError, index_from_ron, index_to_ron, merge_libraries, open_library,
    write_sample_library,
};
use glam::Vec2;
use std::path::{Path, PathBuf};

fn write_tiny(dir: &Path, bias: f32) {
    write_sample_library(dir, bias).unwrap();
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("assetfield-library-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn index_round_trips_and_validates() {
    let root = scratch("lib-rt");
    let a = root.join("a");
    write_tiny(&a, 0.25);
    let lib = open_library(&a).unwrap();
    assert_eq!(lib.index.entries.len(), 2);
    let text = std::fs::read_to_string(a.join(INDEX_FILE)).unwrap();
    assert!(text.contains("assetfield-library/1") && text.contains("Template"), "{text}");
    let again = index_from_ron(&a.join(INDEX_FILE), &index_to_ron(&lib.index).unwrap()).unwrap();
    assert_eq!(again, lib.index);
    // an index written before entries had pivots reads as pivots at the box centres, and
    // a pivot round-trips
    assert!(!text.contains("pivot"), "{text}");
    let e = &lib.index.entries[0];
    assert_eq!((e.pivot, e.pivot_offset()), (None, Vec2::ZERO));
    let mut index = lib.index.clone();
    index.entries[0].pivot = Some((0.05, 0.1));
    let text = index_to_ron(&index).unwrap();
    let again = index_from_ron(&a.join(INDEX_FILE), &text).unwrap();
    assert_eq!(again.entries[0].pivot, Some((0.05, 0.1)));
    let offset = again.entries[0].pivot_offset() - Vec2::new(0.05 - 0.15, 0.1 - 0.1);
    assert!(offset.length() < 1e-6, "{offset}");
    // a container written before it recorded its halo read as the old default halo; a
    // recorded halo round-trips
    let container = lib.index.containers[0].clone();
    assert_eq!(container.halo, assetfield_library::DEFAULT_HALO);
    let mut index = lib.index.clone();
    index.containers[0] = container.with_halo(6);
    let text = index_to_ron(&index).unwrap();
    assert!(text.contains("halo: 6"), "{text}");
    let again = index_from_ron(&a.join(INDEX_FILE), &text).unwrap();
    assert_eq!(again.containers[0].halo, 6);
    let old = text.replace("halo: 6,", "").replace("halo: 6", "");
    assert!(!old.contains("halo"), "{old}");
    let again = index_from_ron(&a.join(INDEX_FILE), &old).unwrap();
    assert_eq!(again.containers[0].halo, assetfield_library::DEFAULT_HALO);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn index_tensor_mismatch_names_expected_and_actual() {
    let root = scratch("lib-mismatch");
    let a = root.join("a");
    write_tiny(&a, 0.25);
    let mut index = open_library(&a).unwrap().index;
    index.entries[1].patch_size = (3, 3);
    write_atomic(&a.join(INDEX_FILE), index_to_ron(&index).unwrap().as_bytes()).unwrap();
    let e = open_library(&a).unwrap_err();
    let msg = e.to_string();
    assert!(
        matches!(&e, LibraryError::ShapeMismatch { tensor, expected, actual, .. }
            if tensor == "obj001.density" && expected == &vec![3, 3, 2] && actual == &vec![2, 3, 2]),
        "{msg}"
    );
    assert!(
        msg.contains("obj001.density") && msg.contains("[3, 3, 2]") && msg.contains("[2, 3, 2]"),
        "{msg}"
    );
    // a missing tensor, an unknown member and a changed shared file are reported too
    index.entries[1].patch_size = (2, 3);
    index.entries[1].mask = "nope.mask".into();
    write_atomic(&a.join(INDEX_FILE), index_to_ron(&index).unwrap().as_bytes()).unwrap();
    assert!(open_library(&a).unwrap_err().to_string().contains("nope.mask"));
    index.entries[1].mask = "obj001.mask".into();
    index.shared.hash = "fnv1a64:0000000000000000".into();
    write_atomic(&a.join(INDEX_FILE), index_to_ron(&index).unwrap().as_bytes()).unwrap();
    assert!(open_library(&a).unwrap_err().to_string().contains("content hash"));
    std::fs::write(a.join(INDEX_FILE), "Library(format: \"x\")").unwrap();
    assert!(open_library(&a).is_err());
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn merge_accepts_equal_shared_tensors_and_refuses_others() {
    let root = scratch("lib-merge");
    let (a, b, c) = (root.join("a"), root.join("b"), root.join("c"));
    write_tiny(&a, 0.25);
    write_tiny(&b, 0.25);
    write_tiny(&c, 0.75);
    let out = root.join("ab");
    let written = merge_libraries(&[a.clone(), b.clone()], &out, false).unwrap();
    let m = open_library(&written).unwrap();
    let counts = (m.index.entries.len(), m.index.categories.len(), m.index.containers.len());
    assert_eq!(counts, (4, 2, 2));
    assert!(m.index.entry("a/obj000").is_some() && m.index.entry("b/obj001").is_some());
    assert_eq!(m.index.categories[1].template, "b/obj000");
    assert_eq!(m.index.sources.len(), 2);
    // the output exists: refused without force
    assert!(matches!(
        merge_libraries(&[a.clone(), b.clone()], &out, false),
        Err(LibraryError::OutputExists(_))
    ));
    let e = merge_libraries(&[a.clone(), c.clone()], &root.join("ac"), false).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("decoder.0.bias") && msg.contains("differs"), "{msg}");
    assert!(!root.join("ac").exists(), "nothing may be written on refusal");
    std::fs::remove_dir_all(&root).unwrap();
}
