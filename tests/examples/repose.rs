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
//!
//! A render run through COLMAP (issue 33: the same scene with COLMAP's poses and with exact
//! ones): its ground truth moved to where the field trained on the COLMAP project puts it.
//! The similarity from the render's frame to COLMAP's is fitted to the camera centres (the
//! render's `transforms_{train,test}.json` against the model's images named `SPLIT_r_K.png`,
//! Horn's closed form); its residual says how far COLMAP's centres are from the render's.
//!
//! ```sh
//! cargo run --release -p assetfield-tests --example repose -- gt-colmap RENDER COLMAP F.safetensors GT_OUT
//! ```

use assetfield_data::colmap::ColmapModel;

use assetfield_tests::{Similarity, moved_gt, render_poses, repose_as_nerfstudio};
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
        ["gt-colmap", render, colmap, field, out] => {
            let render = Path::new(render);
            let gt = assetfield_layout::GtLayout::read(&render.join("gt_layout.json"))
                .expect("the render's gt_layout.json");
            let (s, rms, spread, n) = fit_to_colmap(render, Path::new(colmap));
            println!(
                "{n} cameras: scale {:.5}, centres within {:.3}% of their spread (rms {rms:.5} of {spread:.3} COLMAP units)",
                s.scale,
                100.0 * rms / spread
            );
            let up = s.rotation * Vec3::Z;
            println!("the render's up in COLMAP's frame: [{:.4}, {:.4}, {:.4}]", up.x, up.y, up.z);
            let loaded =
                assetfield_field::eval::load_field(Path::new(field)).expect("a trained field");
            let align = loaded.info.ground_transform.expect("a field trained with --align-ground");
            let moved = moved_gt(&gt, &s, &align);
            std::fs::write(out, serde_json::to_string(&moved).expect("serialisable"))
                .expect("writable");
            println!("wrote {out}");
        }
        _ => {
            eprintln!(
                "usage: repose pose DATA OUT SCALE TILT TURN | repose gt GT FIELD SCALE TILT TURN OUT | repose gt-colmap RENDER COLMAP FIELD GT_OUT"
            );
            std::process::exit(2);
        }
    }
}

/// The similarity from `render`'s frame to the COLMAP model's under `colmap`, fitted to the
/// camera centres of the images both hold; with the rms residual of the fitted centres, the
/// rms spread of COLMAP's centres about their mean (COLMAP units) and the number of cameras.
fn fit_to_colmap(render: &Path, colmap: &Path) -> (Similarity, f64, f64, usize) {
    use glam::DVec3;
    let exact = render_poses(render);
    let dir = assetfield_data::colmap::find_model(colmap).expect("a COLMAP model");
    let model = ColmapModel::read(&dir).expect("a readable COLMAP model");
    let pairs: Vec<(DVec3, DVec3)> = model
        .images
        .iter()
        .filter_map(|im| exact.get(&im.name).map(|m| (m.w_axis.truncate().as_dvec3(), im.centre())))
        .collect();
    assert!(pairs.len() >= 3, "at least three cameras in both ({} found)", pairs.len());
    let n = pairs.len() as f64;
    let (mx, my) = pairs.iter().fold((DVec3::ZERO, DVec3::ZERO), |a, p| (a.0 + p.0, a.1 + p.1));
    let (mx, my) = (mx / n, my / n);
    // Horn: the rotation is the unit quaternion maximising q^T N q, N built from the
    // cross-covariance of the centred points
    let mut c = [[0.0f64; 3]; 3];
    for (x, y) in &pairs {
        let (a, b) = (*x - mx, *y - my);
        let (a, b) = (a.to_array(), b.to_array());
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] += a[i] * b[j];
            }
        }
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = c;
    let nm = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    // the largest eigenvalue's vector by power iteration on N shifted to be positive
    let shift: f64 = nm.iter().flatten().map(|v| v.abs()).sum();
    let mut q = [1.0f64, 0.0, 0.0, 0.0];
    for _ in 0..2000 {
        let mut next = [0.0f64; 4];
        for (i, row) in nm.iter().enumerate() {
            next[i] = row.iter().zip(&q).map(|(m, v)| m * v).sum::<f64>() + shift * q[i];
        }
        let len = next.iter().map(|v| v * v).sum::<f64>().sqrt();
        q = next.map(|v| v / len);
    }
    let rot = glam::DQuat::from_xyzw(q[1], q[2], q[3], q[0]).normalize();
    let rm = glam::DMat3::from_quat(rot);
    let (num, den) = pairs.iter().fold((0.0, 0.0), |a, (x, y)| {
        let (xa, yb) = (rm * (*x - mx), *y - my);
        (a.0 + xa.dot(yb), a.1 + xa.length_squared())
    });
    let scale = num / den;
    let offset = my - scale * (rm * mx);
    let rms = (pairs
        .iter()
        .map(|(x, y)| (scale * (rm * *x) + offset - *y).length_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    let spread = (pairs.iter().map(|(_, y)| (*y - my).length_squared()).sum::<f64>() / n).sqrt();
    let s = Similarity { scale: scale as f32, rotation: rm.as_mat3(), offset: offset.as_vec3() };
    (s, rms, spread, pairs.len())
}
