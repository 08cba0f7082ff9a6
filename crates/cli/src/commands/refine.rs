//! `assetfield refine`: refine a library's templates against its scene's training views
//! (paper Sec. 3.4), writing a new library whose `layout.ron` draws every instance with its
//! category's template.

use super::util::fmt_duration;
use super::util::training_bar;
use anyhow::{Context, Result, anyhow, bail};
use assetfield_core::fsx::{StagingDir, write_atomic};
use assetfield_core::{Camera, interrupt};
use assetfield_data::{Dataset, Frame, LoadOptions, Split};
use assetfield_library::{open_library, write_library_files};
use assetfield_mining::layout_out::{layout_script, script_text_checked};
use assetfield_scene::refine::{
    RefineOptions, TemplateRefiner, cameras_looking_at, compose_draws, own_poses,
};
use assetfield_scene::{AssetLibrary, Composition};
use clap::Args;
use glam::Vec3;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Fewest of the training views whose central ray must pass through the library's box: a
/// dataset of the library's own scene looks into it from every view.
const MIN_VIEWS_LOOKING_IN: f32 = 0.5;

#[derive(Debug, Args)]
pub struct RefineArgs {
    /// The asset library (written by `assetfield mine`) whose templates to refine.
    pub lib: PathBuf,
    /// The dataset of the scene the library was mined from (the training views refine
    /// against; its test views, when present, measure the result).
    #[arg(long)]
    pub data: PathBuf,
    /// The refined library folder to write.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Time budget in minutes (with --iters too, whichever ends first).
    #[arg(long)]
    pub minutes: Option<f64>,
    /// Iterations [default: 2000 unless --minutes is given].
    #[arg(long)]
    pub iters: Option<u64>,
    /// Rays per iteration.
    #[arg(long, default_value_t = 4096)]
    pub batch: usize,
    /// Adam's learning rate for the template features at the start (decays to a tenth).
    #[arg(long, default_value_t = 0.005)]
    pub lr: f32,
    /// Downscale the images by this integer factor before refining.
    #[arg(long, default_value_t = 1)]
    pub downscale: u32,
    /// Random seed of the ray batches.
    #[arg(long, default_value_t = 20230)]
    pub seed: u64,
    /// Save a checkpoint (OUT.ckpt.safetensors, next to the output folder) this often, in
    /// wall-clock minutes (0: only on Ctrl-C); it is removed once the library is written.
    #[arg(long, default_value_t = 5.0)]
    pub checkpoint_every_minutes: f64,
    /// Continue the run saved in OUT.ckpt.safetensors (--iters / --minutes, when given,
    /// replace its limits).
    #[arg(long)]
    pub resume: bool,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub force: bool,
}

/// `OUT` -> `OUT.ckpt.safetensors` beside it.
fn checkpoint_path(out: &Path) -> PathBuf {
    let name =
        out.file_name().map_or_else(|| "refined".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{name}.ckpt.safetensors"))
}

/// `refine.json`.
#[derive(Debug, Serialize)]
struct Report {
    iterations: u64,
    seconds: f64,
    templates: usize,
    instances: usize,
    /// Mean test-view PSNR: every instance with its own patch (the mined layout), and with
    /// its category's template before and after refinement; `null` without test views.
    test_psnr_own_patches: Option<f32>,
    test_psnr_templates_before: Option<f32>,
    test_psnr_templates_after: Option<f32>,
    test_views: usize,
    /// (iteration, batch PSNR) of the templates-only composition during refinement.
    history: Vec<(u64, f32)>,
    options: RefineOptions,
}

fn mean_psnr(comp: &Composition, views: &[Frame], bg: Vec3) -> Option<f32> {
    if views.is_empty() {
        return None;
    }
    let total: f32 = views
        .iter()
        .map(|f| assetfield_core::metrics::psnr(&comp.render(&f.camera, bg), &f.image.rgb))
        .sum();
    Some(total / views.len() as f32)
}

/// `assetfield refine`: check the options, open the library and load its scene's views,
/// measure the layouts before, refine the templates, write the library and report.
pub fn refine(a: RefineArgs) -> Result<()> {
    let ckpt = check_refine_args(&a)?;
    let lib = AssetLibrary::open(&a.lib)?;
    if lib.index.containers.is_empty() {
        bail!(
            "{} has no container: refine needs the emptied scene its templates were mined from",
            a.lib.display()
        );
    }
    let bg = lib.background;
    let (train, test) = load_views(&a, &lib)?;

    // before: the mined layout (own patches) and the templates-only layout
    let patches = lib.patches(None)?;
    let own = own_poses(&lib.index)
        .into_iter()
        .map(|(name, t)| {
            let p = patches.get(&name).ok_or_else(|| anyhow!("no patch for entry {name:?}"))?;
            Ok((p, t))
        })
        .collect::<Result<Vec<_>>>()?;
    let psnr_own = mean_psnr(&compose_draws(&lib, &own)?, &test, bg);
    let options = RefineOptions {
        iters: a.iters.unwrap_or(if a.minutes.is_some() { u64::MAX } else { 2000 }),
        seconds: a.minutes.map(|m| m * 60.0),
        batch: a.batch,
        lr: a.lr,
        seed: a.seed,
        ..RefineOptions::default()
    };
    let views = train.frames.iter().map(|f| (f.camera, f.image.rgb.clone())).collect();
    let mut r = TemplateRefiner::new(&lib, &patches, views, bg, options.clone())?;
    // the refiner composes the templates-only layout itself (its taps are the rasteriser's)
    let psnr_before = mean_psnr(&r.comp, &test, bg);
    if a.resume {
        let f = assetfield_core::TensorFile::load(&ckpt)
            .with_context(|| format!("reading checkpoint {}", ckpt.display()))?;
        r.resume(&f, &ckpt, a.iters, options.seconds)?;
        eprintln!("resuming at iteration {} from {}", r.iter, ckpt.display());
    }
    eprintln!(
        "refining {} templates of {} instances against {} training views{}",
        lib.index.categories.len(),
        lib.index.entries.len(),
        train.len(),
        match (psnr_own, psnr_before) {
            (Some(o), Some(t)) =>
                format!(" (test PSNR: own patches {o:.2} dB, templates {t:.2} dB)"),
            _ => String::new(),
        }
    );
    let (seconds, last) = refine_loop(&mut r, &a, &ckpt, options.iters)?;
    r.comp.refresh_occupancy(None);
    let psnr_after = mean_psnr(&r.comp, &test, bg);
    let report = Report {
        iterations: r.iter,
        seconds,
        templates: lib.index.categories.len(),
        instances: 0,
        test_psnr_own_patches: psnr_own,
        test_psnr_templates_before: psnr_before,
        test_psnr_templates_after: psnr_after,
        test_views: test.len(),
        history: r.history.clone(),
        options,
    };
    let (out, report) = write_refined(&a, &r, report)?;
    if ckpt.exists() {
        std::fs::remove_file(&ckpt).with_context(|| format!("removing {}", ckpt.display()))?;
    }
    println!(
        "refined {} templates for {} iterations in {} (final batch PSNR {last:.2} dB)",
        report.templates,
        r.iter,
        fmt_duration(seconds)
    );
    if let (Some(o), Some(b), Some(f)) = (psnr_own, psnr_before, psnr_after) {
        println!(
            "test PSNR over {} views: own patches {o:.2} dB; templates only {b:.2} -> {f:.2} dB",
            test.len()
        );
    }
    println!(
        "wrote {} (index.ron, patches.safetensors, shared.safetensors, layout.ron: templates only, refine.json)",
        out.display()
    );
    Ok(())
}

/// The numeric options, `--out`, `--resume` and `--force`: the checkpoint's path.
fn check_refine_args(a: &RefineArgs) -> Result<PathBuf> {
    if let Some(m) = a.minutes
        && !(m.is_finite() && m > 0.0)
    {
        bail!("--minutes {m} must be a positive number");
    }
    if a.iters == Some(0) || a.batch == 0 || a.downscale == 0 {
        bail!("--iters, --batch and --downscale must be at least 1");
    }
    if !(a.lr.is_finite() && a.lr > 0.0) {
        bail!("--lr must be a positive number");
    }
    if a.out.exists() && !a.force {
        bail!("{} already exists (pass --force to replace it)", a.out.display());
    }
    if !(a.checkpoint_every_minutes.is_finite() && a.checkpoint_every_minutes >= 0.0) {
        bail!("--checkpoint-every-minutes must be 0 or more");
    }
    let ckpt = checkpoint_path(&a.out);
    if a.resume && !ckpt.is_file() {
        bail!(
            "--resume: no checkpoint at {}; run without --resume to start afresh",
            ckpt.display()
        );
    }
    if !a.resume && ckpt.exists() && !a.force {
        bail!(
            "a checkpoint of an earlier run exists at {}: continue it with --resume, or pass --force to start afresh",
            ckpt.display()
        );
    }
    Ok(ckpt)
}

/// The training views (which must look into the library's box) and the test views (none,
/// with a note, where the dataset has none), levelled like the library's field.
fn load_views(a: &RefineArgs, lib: &AssetLibrary) -> Result<(Dataset, Vec<Frame>)> {
    let opts = LoadOptions {
        background: lib.background.to_array(),
        downscale: a.downscale,
        ..LoadOptions::default()
    };
    let load = |split: Split| -> Result<Dataset> {
        let mut d = Dataset::load(&a.data, split, &opts)
            .with_context(|| format!("loading the {split:?} views of {}", a.data.display()))?;
        if let Some(g) = &lib.info.ground_transform {
            g.apply_to_dataset(&mut d);
        }
        Ok(d)
    };
    let train = load(Split::Train)?;
    let cams: Vec<Camera> = train.frames.iter().map(|f| f.camera).collect();
    let looking = cameras_looking_at(lib, &cams);
    if looking < MIN_VIEWS_LOOKING_IN {
        let c = &lib.index.containers[0];
        bail!(
            "{} does not look like the scene of {}: only {:.0}% of its {} training views look into the library's box [{:.2}, {:.2}] .. [{:.2}, {:.2}]; refine needs the views of the scene the library was mined from",
            a.data.display(),
            a.lib.display(),
            looking * 100.0,
            cams.len(),
            c.world[0],
            c.world[1],
            c.world[2],
            c.world[3]
        );
    }
    if let Some(d) = &lib.info.dataset
        && d.canonicalize().ok() != a.data.canonicalize().ok()
    {
        eprintln!(
            "note: the library was mined from a field trained on {}; refining against {}",
            d.display(),
            a.data.display()
        );
    }
    let test = match load(Split::Test) {
        Ok(d) => d.frames,
        Err(e) => {
            eprintln!("note: no test views to measure with ({e:#})");
            Vec::new()
        }
    };
    Ok((train, test))
}

/// Refine until the budget is spent, with the progress bar and periodic checkpoints;
/// Ctrl-C saves a checkpoint and ends with an error that says how to resume. The session's
/// seconds and the last batch PSNR.
fn refine_loop(
    r: &mut TemplateRefiner,
    a: &RefineArgs,
    ckpt: &Path,
    iters: u64,
) -> Result<(f64, f32)> {
    let save = |r: &TemplateRefiner| -> Result<()> {
        r.checkpoint()?.save(ckpt).with_context(|| format!("saving checkpoint {}", ckpt.display()))
    };
    let every = std::time::Duration::from_secs_f64(a.checkpoint_every_minutes * 60.0);
    let mut last_save = Instant::now();
    let pb = training_bar((iters != u64::MAX).then_some(iters));
    let t0 = Instant::now();
    let mut last = f32::NAN;
    while !r.finished() {
        if interrupt::requested() {
            pb.finish_and_clear();
            save(r)?;
            return Err(anyhow!(
                "interrupted at iteration {}: checkpoint saved to {}; no library was written. Continue with: assetfield refine {} --data {} --out {} --resume",
                r.iter,
                ckpt.display(),
                a.lib.display(),
                a.data.display(),
                a.out.display()
            ));
        }
        last = r.step();
        if !every.is_zero() && last_save.elapsed() >= every {
            save(r)?;
            last_save = Instant::now();
        }
        pb.set_position((r.progress() * 1000.0) as u64);
        pb.set_message(format!(
            "it {} | psnr {last:.2} | {}",
            r.iter,
            fmt_duration(t0.elapsed().as_secs_f64())
        ));
    }
    pb.finish_and_clear();
    Ok((t0.elapsed().as_secs_f64(), last))
}

/// The library with the refined template features, a templates-only layout and
/// `refine.json` (the report, completed with the layout's instances), written to `--out`.
fn write_refined(a: &RefineArgs, r: &TemplateRefiner, report: Report) -> Result<(PathBuf, Report)> {
    let mut stored = open_library(&a.lib)?;
    for (name, dd, dc) in r.deltas() {
        let e = stored.index.entry(&name).cloned().ok_or_else(|| anyhow!("no entry {name:?}"))?;
        let (h, w) = e.patch_size;
        let (nd, nc) = stored.index.channels;
        for (tensor, delta, ch) in [(&e.density, dd, nd), (&e.color, dc, nc)] {
            let v: Vec<f32> = stored
                .patches
                .get_f32(tensor, &[h, w, ch])?
                .iter()
                .zip(&delta)
                .map(|(a, b)| a + b)
                .collect();
            stored.patches.insert_f32(tensor.clone(), &[h, w, ch], v);
        }
    }
    let c = &stored.index.containers[0];
    let name =
        a.out.file_name().map_or_else(|| "refined".into(), |s| s.to_string_lossy().into_owned());
    let names = instance_names(&a.lib, &stored.index);
    let script = layout_script(&stored.index, &name, c.world, ".", &names, f32::INFINITY)?;
    let staging = StagingDir::new(&a.out, a.force)?;
    let (text, instances) = script_text_checked(&script, &staging.path().join("layout.ron"))?;
    write_library_files(staging.path(), &stored.index, &stored.patches, &stored.shared)?;
    write_atomic(&staging.path().join("layout.ron"), text.as_bytes())?;
    let report = Report { templates: stored.index.categories.len(), instances, ..report };
    write_atomic(
        &staging.path().join("refine.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    Ok((staging.commit()?, report))
}

/// The instance keys of the library's own `layout.ron` by entry (what `mine --gt-names`
/// named them, so that edit scripts written for the scene still find them): an instance
/// stands for the entry whose pivot (own patch) or template position it is placed at.
/// Empty when the layout is missing or does not resolve.
fn instance_names(
    lib: &Path,
    index: &assetfield_library::LibraryIndex,
) -> BTreeMap<String, String> {
    let Ok(loaded) = assetfield_layout::load(&lib.join("layout.ron")) else {
        return BTreeMap::new();
    };
    let catalog = assetfield_layout::PartsCatalog::from_script(&loaded);
    let Ok(resolved) = assetfield_layout::resolve(&loaded, &catalog) else {
        return BTreeMap::new();
    };
    // the layout writes three decimals
    let close = |p: glam::Vec2, q: glam::Vec2| (p - q).length() < 2e-3;
    let mut names = BTreeMap::new();
    for inst in &resolved.instances {
        let p = inst.transform.position;
        if let Some(e) = index.entries.iter().find(|e| {
            !names.contains_key(&e.name)
                && (close(e.pivot_world(), p)
                    || close(glam::Vec2::new(e.position.0, e.position.1), p))
        }) {
            names.insert(e.name.clone(), inst.key.clone());
        }
    }
    names
}
