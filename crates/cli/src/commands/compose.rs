//! `assetfield compose`: a layout script composed from an asset library and rendered.

use super::backend::{BackendArg, ViewRenderer};
use super::util::{progress_bar, save_rgb};
use anyhow::{Context, Result, bail};
use assetfield_core::Camera;
use assetfield_core::fsx::{StagingDir, write_atomic};
use assetfield_core::metrics::error_image;
use assetfield_core::{Orbit, fitting_radius};
use assetfield_data::{Dataset, Frame, LoadOptions, Split};
use assetfield_field::eval::evaluate_with;
use assetfield_field::pictures::{color_plane_name, density_picture, pca_picture};
use assetfield_layout::{ResolvedLayout, resolve};
use assetfield_scene::{AssetLibrary, Canvas, Composer, ScriptAssets};
use clap::Args;
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, Args)]
pub struct ComposeArgs {
    /// The layout script (the language `synth` reads). Its assets are library assets:
    /// `library: Library(path, entry, size)` definitions, or the library's category names
    /// (drawn with the category's template) and entry names (drawn with that entry's own
    /// patch). A mined `layout.ron` composes as it is; edits (`edits: [...]`, or a script with
    /// `base: "layout.ron"`) move, turn, delete, duplicate and swap instances.
    pub script: PathBuf,
    /// Apply the `edits` of this script too, after the layout's own (its `base` and other
    /// fields are ignored): an edit list written against the ground-truth scene applies to a
    /// layout mined with `mine --gt --gt-names`, whose instances carry the same keys.
    /// Repeatable.
    #[arg(long, value_name = "EDITS.ron")]
    pub edits: Vec<PathBuf>,
    /// The asset library (written by `assetfield mine` or `assetfield library merge`): its
    /// shared axes and decoders render the scene, its container is the default canvas.
    #[arg(long, short)]
    pub library: PathBuf,
    /// Output folder: the renders (r_K.png for --views, orbit_NNN.png for --orbit),
    /// compose.json, layout.png and, with --planes, the composed planes. Written atomically.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Render these cameras: a dataset folder (its --split views) or a transforms JSON file
    /// (e.g. DATA/transforms_test.json, or DATA/edited from `synth --edited`).
    #[arg(long, value_name = "DIR|JSON", conflicts_with = "orbit")]
    pub views: Option<PathBuf>,
    /// Which split --views renders when it names a folder: test, val, train or all.
    #[arg(long, default_value = "test")]
    pub split: Split,
    /// Compare the renders with the images of --views: PSNR and SSIM per view and mean in
    /// metrics.json (keys psnr, ssim, views) and error/r_K.png, as `eval` computes them.
    #[arg(long, requires = "views")]
    pub metrics: bool,
    /// Turntable of N views around the layout's extent (the default: 8 views).
    #[arg(long, value_name = "N")]
    pub orbit: Option<usize>,
    /// Turntable elevation above the ground, degrees.
    #[arg(long, default_value_t = 35.0, value_name = "DEG")]
    pub elevation: f32,
    /// Turntable image size (square), pixels.
    #[arg(long, default_value_t = 400, value_name = "PX")]
    pub res: u32,
    /// Turntable horizontal field of view, degrees.
    #[arg(long, default_value_t = 40.0, value_name = "DEG")]
    pub fov: f32,
    /// What to compose onto: a container of the library by name (a trained scene with its
    /// objects removed), or `empty` (nothing but the placed assets, over the layout's
    /// extent) [default: the library's first container, else empty].
    #[arg(long, value_name = "NAME|empty")]
    pub canvas: Option<String>,
    /// Texels around each entry's mask that its patch covers [default: the ring `mine`
    /// filled in the container of the entry's scene, as the library's index records]
    #[arg(long, value_name = "TEXELS")]
    pub halo: Option<usize>,
    /// Where to render: gpu (wgpu; an error without an adapter), cpu (the reference
    /// renderer), or auto: the GPU when a wgpu adapter exists, else the CPU with one line
    /// saying so (also when the GPU fails mid-run).
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    pub backend: BackendArg,
    /// Also write the composed planes: planes/density.png and planes/color_pca.png.
    #[arg(long)]
    pub planes: bool,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub force: bool,
}

/// The cameras to render, named after their files.
fn cameras(a: &ComposeArgs, lib: &AssetLibrary, layout: &ResolvedLayout) -> Result<Views> {
    match &a.views {
        Some(v) => {
            let (dir, split) = if v.is_file() {
                let stem = v.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
                let split = match stem.strip_prefix("transforms_") {
                    Some("train") => Split::Train,
                    Some("val") => Split::Val,
                    Some("test") => Split::Test,
                    _ => Split::All,
                };
                (v.parent().unwrap_or(Path::new(".")).to_path_buf(), split)
            } else {
                (v.clone(), a.split)
            };
            let opts = LoadOptions { background: lib.background.to_array(), ..Default::default() };
            if a.metrics {
                let mut data = Dataset::load(&dir, split, &opts)
                    .with_context(|| format!("loading the {split} views of {}", dir.display()))?;
                if let Some(g) = &lib.info.ground_transform {
                    g.apply_to_dataset(&mut data);
                }
                Ok(Views::Frames(data.frames))
            } else {
                let mut cams = Dataset::load_cameras_only(&dir, split, &opts)
                    .with_context(|| format!("reading the cameras of {}", dir.display()))?;
                if let Some(g) = &lib.info.ground_transform {
                    g.apply_to_cameras(&mut cams);
                }
                Ok(Views::Cameras(
                    cams.views.iter().map(|v| (format!("r_{}.png", v.index), v.camera)).collect(),
                ))
            }
        }
        None => {
            let e = layout.extent;
            let z = lib.config.aabb();
            let aabb = assetfield_core::Aabb3::new(
                e.min.extend(z.min.z.max(0.0)),
                e.max.extend(z.max.z.max(0.5)),
            );
            let mut orbit = Orbit::around(&aabb, a.orbit.unwrap_or(8), a.res);
            orbit.elevation_deg = a.elevation;
            orbit.fov_deg = a.fov;
            orbit.radius = fitting_radius(&aabb, a.fov);
            Ok(Views::Cameras(
                orbit
                    .cameras()
                    .into_iter()
                    .enumerate()
                    .map(|(k, c)| (format!("orbit_{k:03}.png"), c))
                    .collect(),
            ))
        }
    }
}

enum Views {
    Cameras(Vec<(String, Camera)>),
    Frames(Vec<Frame>),
}

/// The canvas the user asked for.
fn canvas(a: &ComposeArgs, lib: &AssetLibrary, layout: &ResolvedLayout) -> Canvas {
    match a.canvas.as_deref() {
        Some("empty") => Canvas::Empty { extent: lib.empty_extent(layout) },
        Some(name) => Canvas::Container(name.to_string()),
        None => lib.canvas_for(layout),
    }
}

pub fn compose(a: ComposeArgs) -> Result<()> {
    if a.res == 0 || a.orbit == Some(0) {
        bail!("--res and --orbit must be at least 1");
    }
    if !(a.fov > 0.0 && a.fov < 180.0) {
        bail!("--fov {} must be between 0 and 180 degrees", a.fov);
    }
    if a.out.exists() && !a.force {
        bail!("{} already exists (pass --force to replace it)", a.out.display());
    }
    let t0 = Instant::now();
    let lib = AssetLibrary::open(&a.library)
        .with_context(|| format!("opening the asset library {}", a.library.display()))?;
    let mut script = assetfield_layout::load(&a.script)?;
    for e in &a.edits {
        assetfield_layout::append_edits(&mut script, e)?;
    }
    let assets = ScriptAssets::resolve(&script, &lib, a.halo)?;
    let layout = resolve(&script, &assets)?;
    let canvas = canvas(&a, &lib, &layout);
    let composition = lib.composition(&canvas)?;
    let mut composer = Composer::new(composition);
    assets.install(&mut composer)?;
    composer.apply_layout(&layout)?;
    let t_build = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    composer.update();
    let raster = composer.stats();
    composer.ensure_occupancy();
    let t_frame = t1.elapsed().as_secs_f64();
    let bg = lib.background;

    let views = cameras(&a, &lib, &layout)?;
    let staging = StagingDir::new(&a.out, a.force)?;
    let root = staging.path().to_path_buf();
    let t2 = Instant::now();
    let comp = composer.composition();
    let mut renderer = ViewRenderer::new(a.backend, comp)?;
    let mut render = |cam: &Camera| renderer.render(comp, cam, bg);
    let model_name = comp.field.config.kind.name();
    let (n_views, summary) = render_views(&a, &views, &root, model_name, &mut render)?;
    let t_render = t2.elapsed().as_secs_f64();
    if a.planes {
        let field = &comp.field;
        let dir = root.join("planes");
        density_picture(field).upscaled(2).save_png(&dir.join("density.png"))?;
        if let Some(p) = pca_picture(field, color_plane_name(field)) {
            p.upscaled(2).save_png(&dir.join("color_pca.png"))?;
        }
    }
    assetfield_layout::layout_picture(&layout, &root.join("layout.png"))?;
    let canvas_desc = match &canvas {
        Canvas::Container(n) => format!("container {n}"),
        Canvas::Empty { extent } => format!(
            "empty [{:.2}, {:.2}] x [{:.2}, {:.2}]",
            extent.min.x, extent.max.x, extent.min.y, extent.max.y
        ),
    };
    let grid = comp.grid;
    let report = serde_json::json!({
        "script": a.script.display().to_string(),
        "library": a.library.display().to_string(),
        "canvas": canvas_desc,
        "planes": [grid.rows, grid.cols],
        "instances": layout.objects().count(),
        "assets": composer.asset_names(),
        "texels_rasterised": raster.texels,
        "views": n_views,
        "seconds": {"load": t_build, "rasterise": t_frame, "render": t_render},
        "backend": renderer.backend(),
        "device": renderer.device(),
        "background": Vec3::to_array(&bg),
    });
    write_atomic(&root.join("compose.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    let out = staging.commit()?;
    println!(
        "composed {} instances of {} assets on {} ({} x {} texels, {:.2} s to rasterise), rendered {} views in {:.1} s on the {}{}",
        layout.objects().count(),
        assets.assets.len(),
        canvas_desc,
        grid.rows,
        grid.cols,
        t_frame,
        n_views,
        t_render,
        renderer.backend().to_uppercase(),
        summary
    );
    println!("wrote {}", out.display());
    Ok(())
}

/// Render every view into `root` (`r_K.png` and `error/r_K.png` with `metrics.json` for the
/// views of a dataset, the cameras' own names otherwise); the number of views and, against
/// a dataset, the summary of the scores.
fn render_views(
    a: &ComposeArgs,
    views: &Views,
    root: &Path,
    model_name: &str,
    render: &mut dyn FnMut(&Camera) -> Result<Vec<f32>>,
) -> Result<(usize, String)> {
    let mut summary = String::new();
    let n_views;
    match views {
        Views::Cameras(cams) => {
            n_views = cams.len();
            let pb = progress_bar(cams.len() as u64, "rendering");
            for (name, cam) in cams {
                assetfield_core::interrupt::check()?;
                let rgb = render(cam)?;
                save_rgb(&root.join(name), cam.intrinsics.width, cam.intrinsics.height, rgb)?;
                pb.inc(1);
            }
            pb.finish_and_clear();
        }
        Views::Frames(frames) => {
            n_views = frames.len();
            let refs: Vec<&Frame> = frames.iter().collect();
            let pb = progress_bar(refs.len() as u64, "rendering and comparing");
            let report = evaluate_with(
                model_name,
                &refs,
                |f| render(&f.camera),
                |f, rgb, m| {
                    let (w, h) = (f.camera.intrinsics.width, f.camera.intrinsics.height);
                    let name = format!("r_{}.png", f.index);
                    save_rgb(&root.join(&name), w, h, rgb.to_vec())?;
                    let err = error_image(rgb, &f.image.rgb, w as usize, h as usize);
                    assetfield_core::fsx::save_png(&root.join("error").join(&name), &err.into())?;
                    pb.set_message(format!("view {} psnr {:.2}", f.index, m.psnr));
                    pb.inc(1);
                    anyhow::Ok(())
                },
            )?;
            pb.finish_and_clear();
            write_atomic(
                &root.join("metrics.json"),
                serde_json::to_string_pretty(&report)?.as_bytes(),
            )?;
            summary = format!(
                "; against {}: PSNR {:.2} dB, SSIM {:.4}",
                a.views.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
                report.psnr,
                report.ssim
            );
        }
    }
    Ok((n_views, summary))
}
