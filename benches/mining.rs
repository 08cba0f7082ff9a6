//! Mining's hot spot: the yaw search of one instance against its template (`estimate_yaw`:
//! a coarse scan of every angle, then refinement of angle and offset), on density patches
//! of the shape mining poses (16 channels, an object of 36 x 20 texels turned by 37 degrees
//! with a margin round it). Poses and the choice of each category's template (every pair
//! of members fitted) spend most of a `mine` run here.
//!
//! `cargo bench -p assetfield-benches --bench mining`.

use assetfield_mining::PlaneImage;
use assetfield_mining::rotate::rotate;
use assetfield_mining::yaw::{YawOptions, estimate_yaw};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

/// Channels of a density patch (S-AssetField's density plane).
const CHANNELS: usize = 16;

/// A smooth, asymmetric object of `rows x cols` texels with `CHANNELS` channels (an L of
/// blobs whose channels weigh its arms differently), zero round it.
fn template(rows: usize, cols: usize) -> PlaneImage {
    let (cy, cx) = (rows as f32 * 0.5, cols as f32 * 0.5);
    PlaneImage::from_fn(rows + 8, cols + 8, CHANNELS, |r, c, k| {
        let (y, x) = (r as f32 - 4.0 - cy, c as f32 - 4.0 - cx);
        let arm = (-(y + cy * 0.6).powi(2) / 8.0).exp() * f32::from(u8::from(x.abs() < cx));
        let leg = (-(x + cx * 0.7).powi(2) / 8.0).exp() * f32::from(u8::from(y.abs() < cy));
        let w = (k + 1) as f32 / CHANNELS as f32;
        w * arm + (1.0 - w) * leg
    })
    .expect("a patch")
}

fn yaw_search(c: &mut Criterion) {
    let t = template(20, 36);
    let inst = rotate(&t, 37.0, (0.5, -0.5), t.rows + 8, t.cols + 8).expect("turned");
    let opts = YawOptions::default();
    c.bench_function("estimate_yaw 16 ch, 36 x 20 object", |b| {
        b.iter(|| estimate_yaw(black_box(&t), black_box(&inst), &opts).expect("a fit"))
    });
}

criterion_group!(benches, yaw_search);
criterion_main!(benches);
