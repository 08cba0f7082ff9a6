//! Ctrl-C during synthesis leaves no output and no staging folder behind. (Own test binary:
//! the interrupt flag is process-wide.)

use assetfield_synth::{SynthOptions, synthesize};
use std::path::Path;

#[test]
fn an_interrupted_run_leaves_nothing_behind() {
    let root =
        std::env::temp_dir().join(format!("assetfield-synth-interrupt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let out = root.join("data");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/plaza.ron");
    let opts = SynthOptions {
        views: Some(6),
        test_views: Some(2),
        resolution: Some(24),
        samples_per_side: Some(1),
        ..Default::default()
    };
    // interrupt after the second view
    let err = synthesize(&scene, &opts, &out, false, None, &mut |done, _| {
        if done == 2 {
            assetfield_core::interrupt::request();
        }
    })
    .unwrap_err();
    assetfield_core::interrupt::reset();
    assert!(err.to_string().contains("interrupted"), "{err}");
    assert!(!out.exists());
    assert_eq!(std::fs::read_dir(&root).unwrap().count(), 0, "staging folder removed");
    std::fs::remove_dir_all(&root).unwrap();
}
