//! The full-size check of issue 16, section 2: a synthesised capture posed in another frame
//! and unit, and its ground truth moved to where a levelled field puts it.
//!
//! ```sh
//! # the photos of DATA as a nerfstudio capture whose cameras are moved by a similarity
//! cargo run --release -p assetfield-tests --example repose -- pose DATA OUT SCALE TILT_DEG TURN_DEG
//! assetfield train OUT --out F.safetensors --align-ground pca ...
//! # DATA's ground truth moved by the same similarity and by F's recorded ground alignment
//! cargo run --release -p assetfield-tests --example repose -- gt DATA/gt_layout.json F.safetensors SCALE TILT_DEG TURN_DEG GT_OUT
//! assetfield mine F.safetensors --gt GT_OUT ...
//! ```
//!
//! The similarity is `p -> SCALE * Rx(TILT) * Rz(TURN) * p + (1.3, -0.7, 2.1) * SCALE`.

use assetfield_tests::{Similarity, moved_gt, repose_as_nerfstudio};
use glam::{Mat3, Vec3};
use std::path::Path;

fn similarity(scale: &str, tilt: &str, turn: &str) -> Similarity {
    let num = |s: &str| s.parse::<f32>().unwrap_or_else(|_| panic!("not a number: {s}"));
    let scale = num(scale);
    Similarity {
        scale,
        rotation: Mat3::from_rotation_x(num(tilt).to_radians())
            * Mat3::from_rotation_z(num(turn).to_radians()),
        offset: Vec3::new(1.3, -0.7, 2.1) * scale,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["pose", data, out, scale, tilt, turn] => {
            repose_as_nerfstudio(Path::new(data), Path::new(out), &similarity(scale, tilt, turn));
            println!("wrote {out}/transforms.json");
        }
        ["gt", gt, field, scale, tilt, turn, out] => {
            let gt = assetfield_layout::GtLayout::read(Path::new(gt)).expect("a ground truth");
            let loaded =
                assetfield_field::eval::load_field(Path::new(field)).expect("a trained field");
            let align = loaded.info.ground_transform.expect("a field trained with --align-ground");
            let moved = moved_gt(&gt, &similarity(scale, tilt, turn), &align);
            std::fs::write(out, serde_json::to_string(&moved).expect("serialisable"))
                .expect("writable");
            println!("wrote {out}");
        }
        _ => {
            eprintln!(
                "usage: repose pose DATA OUT SCALE TILT TURN | repose gt GT FIELD SCALE TILT TURN OUT"
            );
            std::process::exit(2);
        }
    }
}
