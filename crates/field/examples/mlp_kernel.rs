//! The dense layers' kernels alone: multiply-adds per second of the forward and backward
//! passes at the decoders' layer widths, over one batch of 1024 rows, keeping each pass's
//! fastest of 200 runs (the machine's noise only ever slows a run down).
//!
//! `cargo run --release -p assetfield-field --example mlp_kernel`
use assetfield_field::mlp::{DenseDims, dense_backward, dense_forward};
use std::io::Write;
use std::time::Instant;

/// Rows in one batch: the trainer's chunks decode about this many samples at once.
const BATCH: usize = 1024;
/// Timed runs per pass; the fastest is kept.
const RUNS: usize = 200;

fn main() {
    let mut stdout = std::io::stdout().lock();
    for &(inn, out) in &[(48usize, 27usize), (27, 64), (64, 64), (64, 3)] {
        let w: Vec<f32> = (0..inn * out).map(|i| (i % 7) as f32 * 0.01).collect();
        let x: Vec<f32> = (0..BATCH * inn).map(|i| (i % 11) as f32 * 0.01).collect();
        let dy: Vec<f32> = (0..BATCH * out).map(|i| (i % 5) as f32 * 0.01).collect();
        let mut y = vec![0.0; BATCH * out];
        let (mut dx, mut dw) = (vec![0.0; BATCH * inn], vec![0.0; inn * out]);
        let dims = DenseDims { batch: BATCH, inn, out };
        let (mut forward, mut backward) = (f64::MAX, f64::MAX);
        for _ in 0..RUNS {
            let t = Instant::now();
            dense_forward(&w, None, &x, &mut y, dims);
            forward = forward.min(t.elapsed().as_secs_f64());
            let t = Instant::now();
            dense_backward(&w, &x, &dy, Some(&mut dx), &mut dw, None, dims);
            backward = backward.min(t.elapsed().as_secs_f64());
        }
        let macs = (BATCH * inn * out) as f64;
        // the sum keeps the compiler from dropping the work; a closed pipe ends the listing
        let line = format!(
            "{inn}->{out}: forward {:.2} GMAC/s, backward {:.2} GMAC/s (checksum {})",
            macs / forward / 1e9,
            2.0 * macs / backward / 1e9,
            y[5] + dx[3] + dw[1]
        );
        if writeln!(stdout, "{line}").is_err() {
            return;
        }
    }
}
