//! `assetfield bench edit`: what the editor costs after a one-instance move: the composed
//! planes brought up to date (resolve the edited layout, redraw the dirty rectangles,
//! refresh the occupancy there), then the coarse preview and the full view rendered.

use crate::commands::backend::{BackendArg, device};
use crate::commands::util::median;
use anyhow::{Context, Result, bail};
use assetfield_editor::{EditSession, SessionOptions, ViewRequest};
use assetfield_gpu::bench_scene::SplitMix;
use clap::Args;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct BenchEditArgs {
    /// The asset library (its layout.ron is the scene; see --instances).
    pub library: PathBuf,
    /// Instances in the scene: the library's layout, with copies of its instances added at
    /// random places (drawn from --seed) until there are this many.
    #[arg(long, default_value_t = 30, value_name = "N")]
    pub instances: usize,
    /// Timed moves (the median of each step is reported).
    #[arg(long, default_value_t = 9, value_name = "N")]
    pub moves: usize,
    /// Image sides (square) rendered after every move: the preview, then the full view.
    #[arg(long, value_delimiter = ',', default_value = "128,256", value_name = "PX,PX")]
    pub res: Vec<u32>,
    /// Seed of the copies' places and of the moves.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Uniform in [0, 1) with 53 bits, from the project's seeded generator.
fn next(rng: &mut SplitMix) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

pub fn bench_edit(a: BenchEditArgs) -> Result<()> {
    if a.moves == 0 || a.res.is_empty() {
        bail!("--moves and --res need at least one value");
    }
    let scratch =
        std::env::temp_dir().join(format!("assetfield-bench-edit-{}.ron", std::process::id()));
    let gpu = device(a.backend)?.map(|ctx| (ctx, a.backend == BackendArg::Auto));
    let opts = SessionOptions { layout: Some(scratch.clone()), ..Default::default() };
    let _ = std::fs::remove_file(&scratch);
    let mut s = EditSession::open(&a.library, &opts, gpu)
        .with_context(|| format!("opening {}", a.library.display()))?;
    let mut rng = SplitMix::new(a.seed);
    // pad the scene with copies at random places inside the planes (a quarter-extent margin)
    let e = s.view().extent;
    let (w, h) = (e[2] - e[0], e[3] - e[1]);
    let keys: Vec<String> =
        s.layout().objects().filter(|i| i.supported_by.is_none()).map(|i| i.key.clone()).collect();
    if keys.is_empty() {
        bail!("the library's layout has no instance on the ground to copy or move");
    }
    let mut k = 0;
    while s.layout().objects().count() < a.instances {
        let (x, y) = (
            e[0] + w * (0.2 + 0.6 * next(&mut rng) as f32),
            e[1] + h * (0.2 + 0.6 * next(&mut rng) as f32),
        );
        s.apply(&format!("[Duplicate(target: {:?}, at: ({x}, {y}))]", keys[k % keys.len()]))?;
        k += 1;
    }
    let n = s.layout().objects().count();
    let movable: Vec<String> =
        s.layout().objects().filter(|i| i.supported_by.is_none()).map(|i| i.key.clone()).collect();
    let view = |side: u32| ViewRequest {
        width: side,
        height: side,
        azimuth_deg: -60.0,
        elevation_deg: 35.0,
        radius: None,
    };
    for &side in &a.res {
        s.render(&view(side))?; // warm up (occupancy, caches)
    }
    let mut update = Vec::new();
    let mut texels = Vec::new();
    let mut renders: Vec<Vec<f64>> = vec![Vec::new(); a.res.len()];
    let step = 0.03 * w.max(h);
    for m in 0..a.moves {
        let key = &movable[(next(&mut rng) * movable.len() as f64) as usize % movable.len()];
        // out and back, so that the scene stays where it was
        let sign = if m % 2 == 0 { 1.0 } else { -1.0 };
        let t0 = Instant::now();
        s.apply(&format!("[Move(target: {key:?}, by: ({}, 0.0))]", sign * step))?;
        update.push(t0.elapsed().as_secs_f64());
        texels.push(s.composer().stats().texels as f64);
        for (j, &side) in a.res.iter().enumerate() {
            let t0 = Instant::now();
            s.render(&view(side))?;
            renders[j].push(t0.elapsed().as_secs_f64());
        }
    }
    let _ = std::fs::remove_file(&scratch);
    let up = median(&update).0 * 1e3;
    let tx = median(&texels).0;
    let rs: Vec<f64> = renders.iter().map(|r| median(r).0 * 1e3).collect();
    let backend = s.backend();
    if a.json {
        let sides: Vec<_> =
            a.res.iter().zip(&rs).map(|(s, ms)| json!({"side": s, "ms": ms})).collect();
        println!(
            "{}",
            json!({"library": a.library.display().to_string(), "instances": n, "moves": a.moves,
            "backend": backend, "update_ms": up, "texels_redrawn": tx, "renders": sides})
        );
    } else {
        println!("{} ({n} instances, {} moves, {backend}):", a.library.display(), a.moves);
        println!("  planes updated after a one-instance move: {up:.1} ms ({tx:.0} texels redrawn)");
        for (side, ms) in a.res.iter().zip(&rs) {
            println!("  {side} x {side} render: {ms:.0} ms");
        }
    }
    Ok(())
}
