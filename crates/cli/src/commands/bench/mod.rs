//! `assetfield bench render|reconfigure`: how fast a composed scene renders and how an edit's
//! cost grows with the scene, on the GPU (wgpu compute shaders) or the CPU reference.
//!
//! Both commands build the same scene for either backend: the synthetic one of
//! `assetfield_gpu::bench_scene` (a floor and two furniture templates in a 30 x 30 m box) or,
//! with `--library`, a mined library's container and category templates, with random
//! layouts drawn from `--seed`.

mod edit;

use super::backend::{BackendArg, device};
use super::util::median;
use super::util::progress_bar;
use anyhow::{Context, Result, anyhow, bail};
use assetfield_core::Camera;
use assetfield_gpu::bench_scene::{BenchScene, SplitMix};
use assetfield_gpu::{GpuComposer, GpuContext, GpuError, Layout, fallback_note};
use assetfield_scene::world::ComposedPlanes;
use assetfield_scene::{AssetLibrary, Composer, InstanceOf};
use clap::{Args, Subcommand};
use indicatif::ProgressBar;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub what: BenchCommand,
}

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Render one composed scene of --instances instances: milliseconds per --res x --res
    /// frame and rays per second (median of --frames frames after a first, untimed one), then
    /// --batch random layouts x --views cameras rasterised and rendered in one go: layouts
    /// per second.
    Render(BenchRenderArgs),
    /// Re-compose scenes of each --instances count: --layouts random layouts (every instance
    /// moved, turned, one in four swapped between two templates), each rasterised and
    /// rendered at --res x --res (layouts per second); and the cost of moving one instance
    /// (dirty rectangles redrawn, occupancy refreshed) against redrawing every texel, to see
    /// how both grow with the instance count.
    Reconfigure(BenchReconfigureArgs),
    /// What the editor (`assetfield edit`) costs after a one-instance move on a library's
    /// layout padded to --instances instances: the composed planes brought up to date, then
    /// each --res view rendered (medians of --moves moves).
    Edit(edit::BenchEditArgs),
}

#[derive(Debug, Args)]
pub struct BenchSceneArgs {
    /// gpu (wgpu; an error without an adapter), cpu (the reference renderer), or auto: the
    /// GPU when a wgpu adapter exists, else the CPU with one line on stderr saying so (also
    /// when the GPU fails: loops cut short, buffers too large, a lost device).
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
    /// Compose from a mined asset library (written by `assetfield mine`): its first
    /// container as the canvas and its categories' templates, instead of the synthetic
    /// scene.
    #[arg(long, value_name = "LIB_DIR")]
    pub library: Option<PathBuf>,
    /// Seed of the random layouts (and of the synthetic scene's field).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Args)]
pub struct BenchRenderArgs {
    #[command(flatten)]
    pub scene: BenchSceneArgs,
    /// Image size (square), pixels.
    #[arg(long, default_value_t = 800, value_name = "PX")]
    pub res: u32,
    /// Instances in the scene.
    #[arg(long, default_value_t = 50, value_name = "N")]
    pub instances: usize,
    /// Timed frames (the same camera and layout).
    #[arg(long, default_value_t = 3, value_name = "N")]
    pub frames: usize,
    /// Random layouts rendered as one batch (0: no batch).
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub batch: usize,
    /// Cameras per layout in the batch (around the scene).
    #[arg(long, default_value_t = 2, value_name = "N")]
    pub views: usize,
}

#[derive(Debug, Args)]
pub struct BenchReconfigureArgs {
    #[command(flatten)]
    pub scene: BenchSceneArgs,
    /// Random layouts per instance count.
    #[arg(long, default_value_t = 32, value_name = "N")]
    pub layouts: usize,
    /// Instance counts, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "10,100,1000", value_name = "N,N,..")]
    pub instances: Vec<usize>,
    /// Image size (square) of each layout's render, pixels.
    #[arg(long, default_value_t = 64, value_name = "PX")]
    pub res: u32,
    /// Timed single-instance moves per instance count (the median is reported).
    #[arg(long, default_value_t = 5, value_name = "N")]
    pub moves: usize,
}

pub fn bench(a: BenchArgs) -> Result<()> {
    match a.what {
        BenchCommand::Render(r) => bench_render(r),
        BenchCommand::Reconfigure(r) => bench_reconfigure(r),
        BenchCommand::Edit(e) => edit::bench_edit(e),
    }
}

/// The scene, from the library or synthetic.
fn load_scene(a: &BenchSceneArgs) -> Result<BenchScene> {
    match &a.library {
        None => BenchScene::synthetic(a.seed).context("building the synthetic scene"),
        Some(dir) => library_scene(dir),
    }
}

fn library_scene(dir: &Path) -> Result<BenchScene> {
    let lib = AssetLibrary::open(dir)
        .with_context(|| format!("opening the asset library {}", dir.display()))?;
    let canvas = lib.default_canvas();
    let composition = lib.composition(&canvas)?;
    let mut templates = Vec::new();
    let mut names = Vec::new();
    for c in &lib.index.categories {
        templates.push(lib.patch(&c.template, None)?);
        names.push(c.name.clone());
    }
    if templates.is_empty() {
        bail!("the library {} has no categories to place", dir.display());
    }
    let grid = composition.grid;
    let description = format!(
        "library {}: canvas {canvas:?} ({} x {} texels, {} + {} channels), {} template(s): {}",
        dir.display(),
        grid.cols,
        grid.rows,
        composition.nd,
        composition.nc,
        templates.len(),
        names.join(", ")
    );
    Ok(BenchScene::new(composition, templates, lib.background, description))
}

fn secs(t0: Instant) -> f64 {
    t0.elapsed().as_secs_f64()
}

fn ms(s: f64) -> f64 {
    (s * 1e4).round() / 10.0
}

/// Run `gpu` on the device when there is one. When it fails with an error of the device
/// (not of the input), `auto` says so in one line and runs `cpu`; `gpu` makes it an error,
/// named a lost device when the device was lost. The backend that ran, and its results.
fn run_backend<T>(
    choice: BackendArg,
    ctx: Option<&GpuContext>,
    gpu: impl FnOnce(&GpuContext) -> Result<T>,
    cpu: impl FnOnce() -> Result<T>,
) -> Result<(&'static str, T)> {
    let Some(ctx) = ctx else { return Ok(("cpu", cpu()?)) };
    match gpu(ctx) {
        Ok(t) => Ok(("gpu", t)),
        Err(e) => {
            let g = ctx.explain(e.downcast::<GpuError>()?);
            if choice == BackendArg::Auto && g.cpu_can_do_it() {
                eprintln!("assetfield: {}", fallback_note(&g));
                Ok(("cpu", cpu()?))
            } else {
                Err(anyhow!(g)).context(format!("rendering on {}", ctx.describe()))
            }
        }
    }
}

/// A CPU composer (ECS) over the scene with templates `t0, t1, ..`, `layout`'s instances
/// `i0, i1, ..` spawned and one frame run.
fn cpu_composer(scene: &BenchScene, layout: &Layout) -> Result<Composer> {
    let mut c = Composer::new(scene.composition.clone());
    for (k, t) in scene.templates.iter().enumerate() {
        c.set_template(&format!("t{k}"), &t.name, Arc::new(t.clone()))?;
    }
    for (k, i) in layout.iter().enumerate() {
        c.spawn(&format!("i{k}"), &format!("t{}", i.patch), i.transform)?;
    }
    c.update();
    Ok(c)
}

/// Make the CPU composer's instances match `layout` (same length as the one it was built
/// with): placements and templates, only where they differ from `current`; then one frame.
macro_rules! cpu_apply {
    ($c:expr, $ents:expr, $tpls:expr, $current:expr, $layout:expr) => {{
        for (k, (old, new)) in $current.iter().zip($layout.iter()).enumerate() {
            if old.transform != new.transform {
                $c.set_placement($ents[k], new.transform)?;
            }
            if old.patch != new.patch {
                $c.world.entity_mut($ents[k]).insert(InstanceOf($tpls[new.patch]));
            }
        }
        $c.update();
    }};
}

/// Entities of the CPU composer's instances and templates, in layout and template order.
macro_rules! cpu_entities {
    ($c:expr, $n:expr, $t:expr) => {{
        let ents: Vec<_> = (0..$n)
            .map(|k| $c.find(&format!("i{k}")).ok_or_else(|| anyhow!("instance i{k} missing")))
            .collect::<Result<_>>()?;
        let tpls: Vec<_> = (0..$t)
            .map(|k| $c.template(&format!("t{k}")).ok_or_else(|| anyhow!("template t{k} missing")))
            .collect::<Result<_>>()?;
        (ents, tpls)
    }};
}

// ----- bench render -----

#[derive(Debug, Default)]
struct RenderTimes {
    setup: f64,
    first: f64,
    frames: Vec<f64>,
    /// seconds for the whole batch
    batch: Option<f64>,
}

fn bench_render(a: BenchRenderArgs) -> Result<()> {
    if a.res == 0 || a.frames == 0 || a.views == 0 {
        bail!("--res, --frames and --views must be at least 1");
    }
    let scene = load_scene(&a.scene)?;
    let ctx = device(a.scene.backend)?;
    let mut rng = SplitMix::new(a.scene.seed);
    let layout = scene.random_layout(a.instances, &mut rng);
    let batch: Vec<Layout> =
        (0..a.batch).map(|_| scene.random_layout(a.instances, &mut rng)).collect();
    let cams = scene.cameras(a.views, a.res);
    let pb = progress_bar((1 + a.frames + a.batch) as u64, "bench render");
    let (backend, t) = run_backend(
        a.scene.backend,
        ctx.as_ref(),
        |ctx| render_gpu(ctx, &scene, &layout, &batch, &cams, a.frames, &pb),
        || render_cpu(&scene, &layout, &batch, &cams, a.frames, &pb),
    )?;
    pb.finish_and_clear();
    let adapter = (backend == "gpu").then(|| ctx.as_ref().map(GpuContext::describe)).flatten();
    let (med, min) = median(&t.frames);
    let rays = f64::from(a.res) * f64::from(a.res);
    let batch_json = t.batch.map(|s| {
        let layouts = a.batch as f64;
        json!({
            "layouts": a.batch,
            "views": a.views,
            "seconds": s,
            "layouts_per_s": layouts / s,
            "ms_per_layout": ms(s / layouts),
            "rays_per_s": rays * layouts * a.views as f64 / s,
        })
    });
    let out = json!({
        "command": "bench render",
        "backend": backend,
        "adapter": adapter,
        "scene": scene.description,
        "res": a.res,
        "instances": a.instances,
        "frames": a.frames,
        "setup_ms": ms(t.setup),
        "first_frame_ms": ms(t.first),
        "ms_per_frame": ms(med),
        "min_ms_per_frame": ms(min),
        "rays_per_s": rays / med,
        "batch": batch_json,
    });
    if report_head(a.scene.json, &out, "render", adapter.as_deref(), &scene.description)? {
        return Ok(());
    }
    println!("{} instances, {} x {} pixels", a.instances, a.res, a.res);
    let row = |what: &str, v: String| println!("  {what:<34} {v}");
    row("setup (upload, first rasterisation)", format!("{:.1} ms", ms(t.setup)));
    row("first frame (compiles, builds grid)", format!("{:.1} ms", ms(t.first)));
    row(
        &format!("per frame (median of {})", a.frames),
        format!("{:.1} ms (min {:.1})", ms(med), ms(min)),
    );
    row("rays per second", format!("{:.3} M", rays / med / 1e6));
    if let Some(b) = &batch_json {
        row(
            &format!("batch: {} layouts x {} views", a.batch, a.views),
            format!(
                "{:.2} s = {:.3} layouts/s ({:.1} ms per layout, {:.3} M rays/s)",
                b["seconds"].as_f64().unwrap_or(f64::NAN),
                b["layouts_per_s"].as_f64().unwrap_or(f64::NAN),
                b["ms_per_layout"].as_f64().unwrap_or(f64::NAN),
                b["rays_per_s"].as_f64().unwrap_or(f64::NAN) / 1e6
            ),
        );
    }
    Ok(())
}

fn render_gpu(
    ctx: &GpuContext,
    scene: &BenchScene,
    layout: &Layout,
    batch: &[Layout],
    cams: &[Camera],
    frames: usize,
    pb: &ProgressBar,
) -> Result<RenderTimes> {
    let bg = scene.background;
    let mut t = RenderTimes::default();
    let t0 = Instant::now();
    let mut gpu = GpuComposer::new(ctx, &scene.composition, &scene.templates)?;
    gpu.rasterise(layout, None)?;
    t.setup = secs(t0);
    let cam = &cams[..1];
    let t0 = Instant::now();
    gpu.render(cam, bg)?;
    t.first = secs(t0);
    pb.inc(1);
    for _ in 0..frames {
        assetfield_core::interrupt::check()?;
        let t0 = Instant::now();
        gpu.render(cam, bg)?;
        t.frames.push(secs(t0));
        pb.inc(1);
    }
    if !batch.is_empty() {
        assetfield_core::interrupt::check()?;
        let t0 = Instant::now();
        gpu.render_layouts(batch, cams, bg)?;
        t.batch = Some(secs(t0));
        pb.inc(batch.len() as u64);
    }
    Ok(t)
}

fn render_cpu(
    scene: &BenchScene,
    layout: &Layout,
    batch: &[Layout],
    cams: &[Camera],
    frames: usize,
    pb: &ProgressBar,
) -> Result<RenderTimes> {
    let bg = scene.background;
    let mut t = RenderTimes::default();
    let t0 = Instant::now();
    let mut c = cpu_composer(scene, layout)?;
    t.setup = secs(t0);
    let (ents, tpls) = cpu_entities!(c, layout.len(), scene.templates.len());
    let t0 = Instant::now();
    c.render(&cams[0], bg);
    t.first = secs(t0);
    pb.inc(1);
    for _ in 0..frames {
        assetfield_core::interrupt::check()?;
        let t0 = Instant::now();
        c.render(&cams[0], bg);
        t.frames.push(secs(t0));
        pb.inc(1);
    }
    if !batch.is_empty() {
        let t0 = Instant::now();
        let mut current = layout.clone();
        for l in batch {
            assetfield_core::interrupt::check()?;
            cpu_apply!(c, ents, tpls, current, l);
            current.clone_from(l);
            for cam in cams {
                c.render(cam, bg);
            }
            pb.inc(1);
        }
        t.batch = Some(secs(t0));
    }
    Ok(t)
}

// ----- bench reconfigure -----

/// One instance count's figures (seconds).
#[derive(Debug, Default, Clone)]
struct ReconfigureRow {
    instances: usize,
    layouts_s: f64,
    move_one_s: f64,
    move_one_texels: usize,
    /// every texel redrawn, no occupancy grid
    full_s: f64,
    /// every texel redrawn and the whole occupancy grid rebuilt
    full_grid_s: f64,
    full_texels: usize,
}

fn bench_reconfigure(a: BenchReconfigureArgs) -> Result<()> {
    if a.res == 0 || a.layouts == 0 || a.moves == 0 {
        bail!("--res, --layouts and --moves must be at least 1");
    }
    if a.instances.is_empty() || a.instances.contains(&0) {
        bail!("--instances needs counts of at least 1, e.g. 10,100,1000");
    }
    let scene = load_scene(&a.scene)?;
    let ctx = device(a.scene.backend)?;
    let cams = scene.cameras(1, a.res);
    // per count: the first layout, the random layouts, single moves
    let jobs: Vec<(Layout, Vec<Layout>, Vec<Layout>)> = a
        .instances
        .iter()
        .map(|&n| {
            let mut rng = SplitMix::new(a.scene.seed ^ (n as u64).wrapping_mul(0x9E37));
            let first = scene.random_layout(n, &mut rng);
            let mut layouts = Vec::with_capacity(a.layouts);
            let mut l = first.clone();
            for _ in 0..a.layouts {
                l = scene.edit(&l, &mut rng);
                layouts.push(l.clone());
            }
            // instance 0 moved back and forth between two places
            let moved = scene.edit(&first[..1], &mut rng)[0];
            let moves = (0..a.moves)
                .map(|k| {
                    let mut m = first.clone();
                    if k % 2 == 0 {
                        m[0] = moved;
                    }
                    m
                })
                .collect();
            (first, layouts, moves)
        })
        .collect();
    let steps: usize = a.instances.len() * (a.layouts + a.moves + 3);
    let pb = progress_bar(steps as u64, "bench reconfigure");
    let (backend, rows) = run_backend(
        a.scene.backend,
        ctx.as_ref(),
        |ctx| reconfigure_gpu(ctx, &scene, &jobs, &cams, &pb),
        || reconfigure_cpu(&scene, &jobs, &cams, &pb),
    )?;
    pb.finish_and_clear();
    let adapter = (backend == "gpu").then(|| ctx.as_ref().map(GpuContext::describe)).flatten();
    let json_rows: Vec<Value> = rows
        .iter()
        .map(|r| {
            json!({
                "instances": r.instances,
                "layouts_per_s": a.layouts as f64 / r.layouts_s,
                "ms_per_layout": ms(r.layouts_s / a.layouts as f64),
                "move_one_ms": ms(r.move_one_s),
                "move_one_texels": r.move_one_texels,
                "full_raster_ms": ms(r.full_s),
                "full_with_grid_ms": ms(r.full_grid_s),
                "full_raster_texels": r.full_texels,
            })
        })
        .collect();
    let out = json!({
        "command": "bench reconfigure",
        "backend": backend,
        "adapter": adapter,
        "scene": scene.description,
        "res": a.res,
        "layouts": a.layouts,
        "moves": a.moves,
        "rows": json_rows,
    });
    if report_head(a.scene.json, &out, "reconfigure", adapter.as_deref(), &scene.description)? {
        return Ok(());
    }
    let (mover, full) = if backend == "gpu" {
        ("GpuComposer::rasterise_rects", "GpuComposer::rasterise(.., None)")
    } else {
        ("Composer::set_placement + update", "Composer::rasterise_everything")
    };
    println!(
        "{} random layouts per count (moves, turns, template swaps), each rasterised and \
         rendered at {} x {} pixels",
        a.layouts, a.res, a.res
    );
    println!(
        "move one: one instance moved, its old and new footprints redrawn and their occupancy \
         columns refreshed ({mover}, median of {}); full: every texel redrawn ({full}, median of \
         3), without and with the whole occupancy grid rebuilt",
        a.moves
    );
    println!(
        "{:>9} {:>10} {:>10} {:>14} {:>8} {:>10} {:>15} {:>8} {:>15}",
        "instances",
        "layouts/s",
        "ms/layout",
        "move one (ms)",
        "texels",
        "full (ms)",
        "full+grid (ms)",
        "texels",
        "full+grid/move"
    );
    for r in &rows {
        println!(
            "{:>9} {:>10.2} {:>10.1} {:>14.2} {:>8} {:>10.1} {:>15.1} {:>8} {:>15.1}",
            r.instances,
            a.layouts as f64 / r.layouts_s,
            ms(r.layouts_s / a.layouts as f64),
            ms(r.move_one_s),
            r.move_one_texels,
            ms(r.full_s),
            ms(r.full_grid_s),
            r.full_texels,
            r.full_grid_s / r.move_one_s
        );
    }
    Ok(())
}

type Jobs = [(Layout, Vec<Layout>, Vec<Layout>)];

fn reconfigure_gpu(
    ctx: &GpuContext,
    scene: &BenchScene,
    jobs: &Jobs,
    cams: &[Camera],
    pb: &ProgressBar,
) -> Result<Vec<ReconfigureRow>> {
    let bg = scene.background;
    let mut gpu = GpuComposer::new(ctx, &scene.composition, &scene.templates)?;
    let mut rows = Vec::new();
    for (first, layouts, moves) in jobs {
        assetfield_core::interrupt::check()?;
        let mut row = ReconfigureRow { instances: first.len(), ..Default::default() };
        // warm: pipelines compiled, the first layout drawn
        gpu.rasterise(first, None)?;
        gpu.render(cams, bg)?;
        pb.inc(1);
        for grid in [false, true] {
            gpu.set_occupancy(grid)?;
            let mut full = Vec::new();
            for _ in 0..3 {
                let t0 = Instant::now();
                row.full_texels = gpu.rasterise(first, None)?.texels;
                full.push(secs(t0));
            }
            pb.inc(1);
            *(if grid { &mut row.full_grid_s } else { &mut row.full_s }) = median(&full).0;
        }
        let mut current = first.clone();
        let mut times = Vec::new();
        for m in moves {
            let rects = scene.dirty_rects(&current, m);
            let t0 = Instant::now();
            row.move_one_texels = gpu.rasterise_rects(m, &rects)?.texels;
            times.push(secs(t0));
            current.clone_from(m);
            pb.inc(1);
        }
        row.move_one_s = median(&times).0;
        // in batches: each layout rasterised (with its occupancy grid) and rendered
        let t0 = Instant::now();
        for batch in layouts.chunks(8) {
            assetfield_core::interrupt::check()?;
            gpu.render_layouts(batch, cams, bg)?;
            pb.inc(batch.len() as u64);
        }
        row.layouts_s = secs(t0);
        rows.push(row);
    }
    Ok(rows)
}

fn reconfigure_cpu(
    scene: &BenchScene,
    jobs: &Jobs,
    cams: &[Camera],
    pb: &ProgressBar,
) -> Result<Vec<ReconfigureRow>> {
    let bg = scene.background;
    let mut rows = Vec::new();
    for (first, layouts, moves) in jobs {
        assetfield_core::interrupt::check()?;
        let mut row = ReconfigureRow { instances: first.len(), ..Default::default() };
        let mut c = cpu_composer(scene, first)?;
        let (ents, tpls) = cpu_entities!(c, first.len(), scene.templates.len());
        // the first render builds the occupancy grid, which later frames keep in step
        c.render(&cams[0], bg);
        pb.inc(1);
        for grid in [false, true] {
            let mut full = Vec::new();
            for _ in 0..3 {
                let t0 = Instant::now();
                row.full_texels = c.rasterise_everything();
                if grid {
                    c.world.resource_mut::<ComposedPlanes>().0.refresh_occupancy(None);
                }
                full.push(secs(t0));
            }
            pb.inc(1);
            *(if grid { &mut row.full_grid_s } else { &mut row.full_s }) = median(&full).0;
        }
        let mut current = first.clone();
        let mut times = Vec::new();
        for m in moves {
            let t0 = Instant::now();
            cpu_apply!(c, ents, tpls, current, m);
            times.push(secs(t0));
            row.move_one_texels = c.stats().texels;
            current.clone_from(m);
            pb.inc(1);
        }
        row.move_one_s = median(&times).0;
        let t0 = Instant::now();
        for l in layouts {
            assetfield_core::interrupt::check()?;
            cpu_apply!(c, ents, tpls, current, l);
            current.clone_from(l);
            for cam in cams {
                c.render(cam, bg);
            }
            pb.inc(1);
        }
        row.layouts_s = secs(t0);
        rows.push(row);
    }
    Ok(rows)
}

/// The start of a bench's report: the whole of it as JSON when `json` is asked (true: the
/// report is done), else its title line (the backend that ran) and the scene.
fn report_head(
    json: bool,
    out: &Value,
    name: &str,
    adapter: Option<&str>,
    scene: &str,
) -> Result<bool> {
    if json {
        println!("{}", serde_json::to_string_pretty(out)?);
        return Ok(true);
    }
    println!("bench {name}: {}", adapter.map_or("cpu".to_string(), |d| format!("gpu, {d}")));
    println!("scene: {scene}");
    Ok(false)
}
