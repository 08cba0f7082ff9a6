//! Dataset commands: `synth`, `inspect`, `layout`.

use super::util::progress_bar;
use anyhow::{Context, Result};
use assetfield_data::{Dataset, DatasetSummary, LoadOptions, Split};
use assetfield_synth::random::Style;
use assetfield_synth::{LoadedScene, SynthOptions, synthesize, synthesize_loaded};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// The layout script to render (e.g. scenes/conference_room.ron); or give --random.
    #[arg(required_unless_present = "random")]
    pub scene: Option<PathBuf>,
    /// Render a random scene drawn from SEED instead of a script (the same seed gives the
    /// same scene on every machine). The draw: scene units per metre in 0.5..2 (every
    /// length scaled, recorded as `units_per_metre`); 3-12 object categories from curated
    /// Sweet Home 3D furniture (package sweethome3d-furniture) and the primitive assets of
    /// scenes/assets, 2-5 instances each at varied yaw; some as touching pairs, small
    /// objects on some tables, ground objects never overlapping; a room sized to them; a
    /// floor (none, thin, thick, partial, or tiled: checker, planks, carpet or asphalt
    /// noise) and walls on 0-3 sides; 256 x 256 views unless --res. The script is written
    /// into the dataset as scene.ron (rendering it again gives the same dataset). Validation
    /// and dev seeds: scenes/validation_seeds.txt.
    #[arg(long, value_name = "SEED", conflicts_with = "scene")]
    pub random: Option<u64>,
    /// With --random: also write the drawn script to FILE (RON).
    #[arg(long, value_name = "FILE")]
    pub write_script: Option<PathBuf>,
    /// Output folder [default: runs/SCENE_NAME]. Written atomically: it appears only when
    /// complete.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Total number of views (train + test) [default: the scene's `views.count`, else 50;
    /// 200 for a capture, which walks].
    #[arg(long)]
    pub views: Option<u32>,
    /// Number of test views, evenly interleaved [default: the scene's `views.test`, else 10;
    /// every 8th for a capture].
    #[arg(long)]
    pub test_views: Option<u32>,
    /// Square image resolution in pixels [default: 400].
    #[arg(long = "res")]
    pub resolution: Option<u32>,
    /// Camera distance from the scene centre [default: fit the whole scene in view].
    #[arg(long)]
    pub radius: Option<f32>,
    /// Lowest camera elevation above the ground, degrees [default: 15].
    #[arg(long)]
    pub elev_min: Option<f32>,
    /// Highest camera elevation above the ground, degrees [default: 75].
    #[arg(long)]
    pub elev_max: Option<f32>,
    /// Horizontal field of view, degrees [default: 40].
    #[arg(long)]
    pub fov: Option<f32>,
    /// Anti-aliasing: N x N samples per pixel [default: 2].
    #[arg(long)]
    pub aa: Option<u32>,
    /// Also render this edited layout from the same test cameras into OUT/edited/.
    #[arg(long)]
    pub edited: Option<PathBuf>,
    /// Also write the scene as meshes into OUT/mesh/ (scene.obj in world coordinates, Z
    /// up; scene.mtl; textures/), so that another renderer can render the same cameras:
    /// scripts/blender_render.py renders the dataset again with Blender's Cycles.
    #[arg(long)]
    pub mesh: bool,
    /// Photograph the scene as a hand-held capture: cameras along a walking path at eye
    /// height (1.6 m) inside the scene's extent (0.5 m from its edges), looking into the
    /// room and down at it, each photo with its own exposure (0.25 stops) and white balance
    /// (4%), sensor noise (1% of full scale), opaque over a sky; 60 degrees field of view
    /// unless --fov. With --random, the drawn room is one to photograph from inside: walls
    /// all round at full height with striped wallpaper and framed pictures, a tiled floor, a
    /// walking margin of 1 m around the furniture. A script asks for the same with
    /// `views: (capture: ())`; synth.json records every photo's gain.
    #[arg(long)]
    pub capture: bool,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub force: bool,
    /// Print the run report as JSON on stdout instead of the text summary.
    #[arg(long)]
    pub json: bool,
}

fn stem(p: &Path) -> String {
    p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into())
}

pub fn synth(a: SynthArgs) -> Result<()> {
    if a.write_script.is_some() && a.random.is_none() {
        anyhow::bail!("--write-script writes a drawn scene: it needs --random SEED");
    }
    let random = match a.random {
        Some(seed) => {
            let style = if a.capture { Style::Capture } else { Style::Orbit };
            let r = assetfield_synth::random::random_scene_styled(seed, style)
                .with_context(|| format!("drawing random scene {seed}"))?;
            if let Some(f) = &a.write_script {
                assetfield_core::fsx::write_atomic(f, r.text.as_bytes())
                    .with_context(|| format!("writing {}", f.display()))?;
            }
            Some(r)
        }
        None => None,
    };
    let scene = match (&random, &a.scene) {
        (Some(r), _) => PathBuf::from(format!(
            "{}.ron",
            r.script.name.clone().unwrap_or_else(|| format!("random_{}", r.seed))
        )),
        (None, Some(s)) => s.clone(),
        (None, None) => anyhow::bail!("give a scene script or --random SEED"),
    };
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("runs").join(stem(&scene)));
    let elevation = match (a.elev_min, a.elev_max) {
        (None, None) => None,
        (lo, hi) => Some((lo.unwrap_or(15.0), hi.unwrap_or(75.0))),
    };
    let opts = SynthOptions {
        views: a.views,
        test_views: a.test_views,
        resolution: a.resolution,
        radius: a.radius,
        elevation_deg: elevation,
        fov_deg: a.fov,
        capture: a.capture,
        samples_per_side: a.aa,
        mesh: a.mesh,
    };
    let pb = progress_bar(0, "rendering views");
    let mut progress = |done: usize, total: usize| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    };
    let result = match &random {
        Some(r) => assetfield_layout::load_str(&scene, &r.text)
            .map_err(assetfield_synth::SynthError::from)
            .and_then(|loaded| {
                let source = LoadedScene { script: &loaded, path: &scene, text: Some(&r.text) };
                synthesize_loaded(source, &opts, &out, a.force, a.edited.as_deref(), &mut progress)
            }),
        None => synthesize(&scene, &opts, &out, a.force, a.edited.as_deref(), &mut progress),
    };
    pb.finish_and_clear();
    let report = result.with_context(|| format!("synthesising {}", scene.display()))?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}: {} objects in {} categories ({})",
        report.scene,
        report.instances,
        report.categories.len(),
        report.categories.join(", ")
    );
    println!(
        "rendered {} train + {} test views{} at {}x{} ({}x{} samples/pixel) in {:.1} s ({:.2} M rays/s)",
        report.train_views,
        report.test_views,
        if report.edited_views > 0 {
            format!(" + {} edited", report.edited_views)
        } else {
            String::new()
        },
        report.config.resolution,
        report.config.resolution,
        report.config.samples_per_side,
        report.config.samples_per_side,
        report.seconds,
        report.rays_per_second / 1e6
    );
    if let Some(r) = &random {
        println!(
            "random scene {}: floor {}, {:.3} units per metre; script: {}",
            r.seed,
            r.floor,
            r.units_per_metre,
            out.join("scene.ron").display()
        );
    }
    if let Some(t) = report.mesh_triangles {
        println!("meshes: {} triangles in {}", t, out.join("mesh/scene.obj").display());
    }
    println!("wrote {}", out.display());
    Ok(())
}

#[derive(Debug, Args)]
pub struct InspectArgs {
    /// The dataset folder (holding transforms_*.json or transforms.json).
    pub dir: PathBuf,
    /// Where to write the picture of the cameras seen from above
    /// [default: runs/inspect/FOLDER_NAME/cameras.png].
    #[arg(long)]
    pub picture: Option<PathBuf>,
    /// Also decode every image (slower; checks every file fully, not just its header).
    #[arg(long)]
    pub decode: bool,
    /// Print the summary as JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn inspect(a: InspectArgs) -> Result<()> {
    let opts = LoadOptions::default();
    let cams = Dataset::load_cameras_only(&a.dir, Split::All, &opts)
        .with_context(|| format!("reading dataset {}", a.dir.display()))?;
    if a.decode {
        let ds = Dataset::load(&a.dir, Split::All, &opts)
            .with_context(|| format!("decoding images of {}", a.dir.display()))?;
        eprintln!("decoded {} images", ds.len());
    }
    let summary = DatasetSummary::of(&cams);
    let name = a
        .dir
        .canonicalize()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_else(|| "dataset".into());
    let picture = a
        .picture
        .clone()
        .unwrap_or_else(|| PathBuf::from("runs/inspect").join(&name).join("cameras.png"));
    assetfield_data::camera_map(&cams.cameras(), &picture, &name)
        .context("drawing the camera map")?;
    if a.json {
        println!("{}", summary.to_json_pretty());
    } else {
        println!("{summary}");
        if !cams.points.is_empty() {
            println!("sparse points    {}", cams.points.len());
            match assetfield_data::GroundAlignment::fit_floor(&cams.points, &cams.cameras()) {
                Ok(g) => println!(
                    "floor            holds {:.0}% of the points, {:.1} degrees from the cameras' mean up (train --align-ground floor, the default for a capture, levels on it)",
                    100.0 * g.floor_share.unwrap_or(0.0),
                    g.up_cosine.clamp(0.0, 1.0).acos().to_degrees()
                ),
                Err(e) => println!("floor            not found: {e}"),
            }
        }
        println!("camera map: {}", picture.display());
    }
    Ok(())
}

#[derive(Debug, Args)]
pub struct LayoutArgs {
    /// The layout script to check.
    pub scene: PathBuf,
    /// Draw the resolved layout from above into this PNG.
    #[arg(long)]
    pub picture: Option<PathBuf>,
    /// Print the ground-truth layout JSON (the gt_layout.json schema) instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// A script whose assets are neural (library entries, as `mine` and `assetfield edit`
/// write them) resolved against the library its first library asset names: the footprints
/// are the library's.
fn load_neural_scene(
    path: &Path,
) -> Result<(assetfield_layout::LoadedScript, assetfield_layout::ResolvedLayout)> {
    let script = assetfield_layout::load(path)?;
    let dir = script
        .assets
        .values()
        .find_map(|e| e.def.library.as_ref().map(|l| e.base_dir(&script).join(&l.path)))
        .context("no library asset")?;
    let lib = assetfield_scene::AssetLibrary::open(&dir)
        .with_context(|| format!("opening the asset library {}", dir.display()))?;
    let assets = assetfield_scene::ScriptAssets::resolve(&script, &lib, None)?;
    let layout = assetfield_layout::resolve(&script, &assets)?;
    Ok((script, layout))
}

pub fn layout(a: LayoutArgs) -> Result<()> {
    let (script, sources, layout) = match assetfield_synth::load_scene(&a.scene) {
        Ok((script, assets, layout)) => (script, assets.sources, layout),
        Err(assetfield_synth::SynthError::LibraryAsset { .. }) => {
            let (script, layout) = load_neural_scene(&a.scene)
                .with_context(|| format!("resolving {}", a.scene.display()))?;
            (script, Default::default(), layout)
        }
        Err(e) => {
            return Err(anyhow::Error::new(e))
                .with_context(|| format!("resolving {}", a.scene.display()));
        }
    };
    if let Some(p) = &a.picture {
        assetfield_layout::layout_picture(&layout, p)?;
    }
    if a.json {
        let gt = assetfield_layout::GtLayout::from_resolved(&layout);
        println!("{}", gt.to_json_with(script.units_per_metre, &sources));
        return Ok(());
    }
    println!(
        "{}: {} instances ({} objects, {} containers)",
        layout.name,
        layout.instances.len(),
        layout.objects().count(),
        layout.containers().count()
    );
    if layout.objects().next().is_none() {
        println!("note: no objects: `assetfield synth` refuses this layout (nothing to render)");
    }
    println!(
        "{:>4}  {:<28} {:<14} {:>8} {:>8} {:>6} {:>7} {:>6}  on",
        "id", "key", "category", "x", "y", "z", "yaw", "scale"
    );
    for i in &layout.instances {
        let t = i.transform;
        println!(
            "{:>4}  {:<28} {:<14} {:>8.3} {:>8.3} {:>6.3} {:>7.1} {:>6.2}  {}",
            i.id,
            i.key,
            if i.container { format!("({})", i.category) } else { i.category.clone() },
            t.position.x,
            t.position.y,
            t.base,
            t.yaw_deg,
            t.scale,
            i.supported_by.map(|s| format!("#{s}")).unwrap_or_default()
        );
    }
    Ok(())
}
