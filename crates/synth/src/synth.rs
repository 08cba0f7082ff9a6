//! `assetfield synth`: render a layout script into a NeRF-synthetic dataset with its
//! ground-truth layout.
//!
//! Output folder (written to a staging folder, renamed into place when complete):
//! `transforms_train.json`, `transforms_test.json`, `train/r_K.png`, `test/r_K.png`,
//! `gt_layout.json`, `layout.png` (bird's-eye view of the ground truth), `synth.json`
//! (settings, bounds, timings) and, with an edited layout, `edited/` holding the same test
//! cameras rendered with the edited layout plus its `gt_layout.json`. A script given as
//! text ([`synthesize_loaded`], e.g. a random scene) is also written as `scene.ron`.

use crate::SynthError;
use crate::assets::AssetSet;
use crate::capture::{CaptureConfig, Photo, capture_rig, develop, sky};
use crate::tracer::{Light, Scene};
use assetfield_core::fsx::{StagingDir, write_atomic};
use assetfield_core::{Aabb3, Camera, Intrinsics, Rect2, interrupt};
use assetfield_data::{FrameEntry, TransformsFile, write_transforms};
use assetfield_layout::{
    GtLayout, InvalidValue, LoadedScript, Location, ResolvedLayout, ViewSettings, resolve,
};
use glam::{Vec2, Vec3};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Settings of the camera rig and renderer, as the user may give them (unset = scene or
/// built-in default).
#[derive(Debug, Clone, Default)]
pub struct SynthOptions {
    pub views: Option<u32>,
    pub test_views: Option<u32>,
    pub resolution: Option<u32>,
    pub radius: Option<f32>,
    pub elevation_deg: Option<(f32, f32)>,
    pub fov_deg: Option<f32>,
    pub samples_per_side: Option<u32>,
    /// Also write the scene's meshes into `mesh/` ([`crate::export::export_obj`]), for
    /// rendering the same cameras with another renderer.
    pub mesh: bool,
    /// Photograph the scene as a hand-held capture ([`crate::capture`]) even when its script
    /// does not ask for one (`views: (capture: ...)`).
    pub capture: bool,
}

/// Validated settings, ready to run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SynthConfig {
    /// Total number of views (train + test). Paper default: 50.
    pub views: u32,
    /// Views held out for testing, evenly interleaved. Paper default: 10.
    pub test_views: u32,
    /// Square image size in pixels.
    pub resolution: u32,
    /// Camera distance from the scene centre; `None` fits the scene's bounding sphere.
    pub radius: Option<f32>,
    /// Elevation range of the cameras above the ground, degrees.
    pub elevation_deg: (f32, f32),
    /// Horizontal (= vertical) field of view, degrees.
    pub fov_deg: f32,
    /// Anti-aliasing: samples per pixel = this squared.
    pub samples_per_side: u32,
}

impl SynthConfig {
    pub const DEFAULT: SynthConfig = SynthConfig {
        views: 50,
        test_views: 10,
        resolution: 400,
        radius: None,
        elevation_deg: (15.0, 75.0),
        fov_deg: 40.0,
        samples_per_side: 2,
    };

    /// Command-line options over the scene's `views` settings over the defaults; checked.
    pub fn resolve(opts: &SynthOptions, scene: Option<&ViewSettings>) -> Result<Self, SynthError> {
        SynthConfig::resolve_at(opts, scene, None)
    }

    /// [`SynthConfig::resolve`], with the place of the scene's `views` in its script: a
    /// setting of the script that does not fit (its `test` views against `--views`, say) is
    /// reported there, naming the script's field; one of the command line names the flag.
    pub fn resolve_at(
        opts: &SynthOptions,
        scene: Option<&ViewSettings>,
        views_at: Option<&Location>,
    ) -> Result<Self, SynthError> {
        let d = SynthConfig::DEFAULT;
        let s = scene.cloned().unwrap_or(ViewSettings {
            count: None,
            test: None,
            resolution: None,
            radius: None,
            elevation_deg: None,
            fov_deg: None,
            capture: None,
        });
        let capture = opts.capture || s.capture.is_some();
        let fov_default = if capture { crate::capture::FOV_DEG } else { d.fov_deg };
        let origin = |flag: bool, script: bool| match (flag, script) {
            (true, _) => Origin::Flag,
            (false, true) => Origin::Script,
            _ => Origin::Default,
        };
        let origins = [
            (Setting::Views, origin(opts.views.is_some(), s.count.is_some())),
            (Setting::TestViews, origin(opts.test_views.is_some(), s.test.is_some())),
            (Setting::Resolution, origin(opts.resolution.is_some(), s.resolution.is_some())),
            (Setting::Radius, origin(opts.radius.is_some(), s.radius.is_some())),
            (Setting::Elevation, origin(opts.elevation_deg.is_some(), s.elevation_deg.is_some())),
            (Setting::Fov, origin(opts.fov_deg.is_some(), s.fov_deg.is_some())),
            (Setting::Aa, Origin::Flag),
        ];
        let origin_of = |k: Setting| origins.iter().find(|(s, _)| *s == k).map(|(_, o)| *o);
        // a capture walks: more photos, every 8th held out
        let views =
            opts.views.or(s.count).unwrap_or(if capture { crate::capture::VIEWS } else { d.views });
        let test_default =
            if capture { (views / crate::capture::HOLDOUT_EVERY).max(1) } else { d.test_views };
        let cfg = SynthConfig {
            views,
            test_views: opts.test_views.or(s.test).unwrap_or(test_default),
            resolution: opts.resolution.or(s.resolution).unwrap_or(d.resolution),
            radius: opts.radius.or(s.radius),
            elevation_deg: opts.elevation_deg.or(s.elevation_deg).unwrap_or(d.elevation_deg),
            fov_deg: opts.fov_deg.or(s.fov_deg).unwrap_or(fov_default),
            samples_per_side: opts.samples_per_side.unwrap_or(d.samples_per_side),
        };
        let Some(p) = cfg.problem() else { return Ok(cfg) };
        let (views, test) = (origin_of(Setting::Views), origin_of(Setting::TestViews));
        // the script is to blame when the failing setting came from it; for the test views
        // against the views, the one of the two that the script gave
        let blame = match p.setting {
            Setting::TestViews if test == Some(Origin::Script) => Some(Setting::TestViews),
            Setting::TestViews if views == Some(Origin::Script) => Some(Setting::Views),
            k if origin_of(k) == Some(Origin::Script) => Some(k),
            _ => None,
        };
        match (blame, views_at) {
            (Some(k), Some(at)) => Err(script_problem(&cfg, &p, k, views, test, at)),
            _ => Err(SynthError::Config(p.flag_message())),
        }
    }

    pub fn validate(&self) -> Result<(), SynthError> {
        match self.problem() {
            Some(p) => Err(SynthError::Config(p.flag_message())),
            None => Ok(()),
        }
    }

    /// The first setting out of its range, if any.
    fn problem(&self) -> Option<Problem> {
        let views = &ViewSettings::COUNT;
        let bad =
            |setting, expected: String, value: String| Some(Problem { setting, expected, value });
        if !views.contains(&self.views) {
            let expected = format!("between {} and {}", views.start(), views.end());
            return bad(Setting::Views, expected, self.views.to_string());
        }
        if self.test_views == 0 || self.test_views >= self.views {
            let expected = format!("between 1 and views - 1 ({})", self.views - 1);
            return bad(Setting::TestViews, expected, self.test_views.to_string());
        }
        let px = &ViewSettings::RESOLUTION_PX;
        if !px.contains(&self.resolution) {
            let expected = format!("between {} and {} pixels", px.start(), px.end());
            return bad(Setting::Resolution, expected, self.resolution.to_string());
        }
        let (lo, hi) = self.elevation_deg;
        let elev = &ViewSettings::ELEVATION_DEG;
        if !elev.contains(&lo) || !elev.contains(&hi) || lo > hi {
            let expected = format!("a range with {} <= min <= max <= {}", elev.start(), elev.end());
            return bad(Setting::Elevation, expected, format!("{lo}..{hi}"));
        }
        let fov = &ViewSettings::FOV_DEG;
        if !fov.contains(&self.fov_deg) {
            let expected = format!("{}..{} degrees", fov.start(), fov.end());
            return bad(Setting::Fov, expected, self.fov_deg.to_string());
        }
        if let Some(r) = self.radius
            && !(r.is_finite() && r > 0.0)
        {
            return bad(Setting::Radius, "positive".into(), r.to_string());
        }
        if !(1..=8).contains(&self.samples_per_side) {
            let expected = "1..8 samples per side".into();
            return bad(Setting::Aa, expected, self.samples_per_side.to_string());
        }
        None
    }

    fn intrinsics(&self) -> Intrinsics {
        Intrinsics::from_fov_x(self.resolution, self.resolution, self.fov_deg.to_radians())
    }
}

/// A setting of the camera rig (for messages naming where it came from).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Setting {
    Views,
    TestViews,
    Resolution,
    Radius,
    Elevation,
    Fov,
    Aa,
}

impl Setting {
    /// The command-line flag that sets it.
    fn flag(self) -> &'static str {
        match self {
            Setting::Views => "--views",
            Setting::TestViews => "--test-views",
            Setting::Resolution => "--res",
            Setting::Radius => "--radius",
            Setting::Elevation => "--elev-min/--elev-max",
            Setting::Fov => "--fov",
            Setting::Aa => "--aa",
        }
    }

    /// Its field in a script's `views: (...)`.
    fn field(self) -> &'static str {
        match self {
            Setting::Views => "count",
            Setting::TestViews => "test",
            Setting::Resolution => "resolution",
            Setting::Radius => "radius",
            Setting::Elevation => "elevation_deg",
            Setting::Fov => "fov_deg",
            Setting::Aa => "aa",
        }
    }
}

/// Where a setting's value came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Origin {
    Flag,
    Script,
    Default,
}

impl Origin {
    fn describe(self, s: Setting) -> String {
        match self {
            Origin::Flag => format!("from {}", s.flag()),
            Origin::Script => format!("from `views: ({}: ...)`", s.field()),
            Origin::Default => "by default".into(),
        }
    }
}

/// A setting out of its range: what it must be and what it is.
#[derive(Debug)]
struct Problem {
    setting: Setting,
    expected: String,
    value: String,
}

impl Problem {
    fn flag_message(&self) -> String {
        format!("{} must be {}, got {}", self.setting.flag(), self.expected, self.value)
    }
}

/// The error for a `views` setting of the script (`blame`) that does not fit the rest.
fn script_problem(
    cfg: &SynthConfig,
    p: &Problem,
    blame: Setting,
    views: Option<Origin>,
    test: Option<Origin>,
    at: &Location,
) -> SynthError {
    let describe = |o: Option<Origin>, s| o.map(|o| o.describe(s)).unwrap_or_default();
    let (value, expected) = match (p.setting, blame) {
        (Setting::TestViews, Setting::TestViews) => (
            cfg.test_views.to_string(),
            format!(
                "between 1 and {} (one less than the {} views {})",
                cfg.views.saturating_sub(1),
                cfg.views,
                describe(views, Setting::Views)
            ),
        ),
        (Setting::TestViews, _) => (
            cfg.views.to_string(),
            format!(
                "more than the {} test views {}",
                cfg.test_views,
                describe(test, Setting::TestViews)
            ),
        ),
        _ => (p.value.clone(), p.expected.clone()),
    };
    SynthError::Layout(assetfield_layout::LayoutError::Invalid(Box::new(InvalidValue {
        location: at.clone(),
        item: "views".into(),
        field: blame.field().into(),
        value,
        expected,
    })))
}

/// One camera of the rig.
#[derive(Debug, Clone, Copy)]
pub struct RigView {
    pub camera: Camera,
    pub test: bool,
}

/// Cameras on the upper half-sphere around `bounds`, looking at its centre: a Fibonacci
/// lattice over the spherical band between the elevation limits (even coverage by area), test
/// views evenly interleaved.
pub fn camera_rig(bounds: &Aabb3, cfg: &SynthConfig) -> Vec<RigView> {
    let target = bounds.center();
    let half_fov = 0.5 * cfg.fov_deg.to_radians();
    let sphere = 0.5 * bounds.extent().length();
    let radius = cfg.radius.unwrap_or(sphere / half_fov.sin() * 1.02);
    let (z0, z1) = (cfg.elevation_deg.0.to_radians().sin(), cfg.elevation_deg.1.to_radians().sin());
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let n = cfg.views;
    let test = test_indices(cfg);
    (0..n)
        .map(|k| {
            let z = z0 + (z1 - z0) * (k as f32 + 0.5) / n as f32;
            let r_xy = (1.0 - z * z).max(0.0).sqrt();
            let az = k as f32 * golden;
            let dir = Vec3::new(r_xy * az.cos(), r_xy * az.sin(), z);
            let camera = Camera::look_at(cfg.intrinsics(), target + dir * radius, target, Vec3::Z);
            RigView { camera, test: test.contains(&k) }
        })
        .collect()
}

/// The indices of the held-out views among `cfg.views`: `cfg.test_views` of them, evenly
/// interleaved.
pub fn test_indices(cfg: &SynthConfig) -> Vec<u32> {
    let n = cfg.views;
    (0..cfg.test_views)
        .map(|t| (((t as f32 + 0.5) * n as f32) / cfg.test_views as f32) as u32)
        .collect()
}

/// A capture's settings and how each of its photos was developed (train views, then test
/// views, in file order).
#[derive(Debug, Clone, Serialize)]
pub struct CaptureReport {
    pub settings: CaptureConfig,
    /// The room the cameras walked in (the script's extent), scene units.
    pub room: [[f32; 2]; 2],
    pub train_gains: Vec<[f32; 3]>,
    pub test_gains: Vec<[f32; 3]>,
}

/// What a synthesis run produced.
#[derive(Debug, Clone, Serialize)]
pub struct SynthReport {
    pub scene: String,
    pub source: PathBuf,
    pub out_dir: PathBuf,
    pub config: SynthConfig,
    pub train_views: usize,
    pub test_views: usize,
    pub edited_views: usize,
    pub instances: usize,
    pub categories: Vec<String>,
    /// Scene units per metre (the script's `units_per_metre`, 1 when it gives none).
    pub units_per_metre: f32,
    pub scene_aabb: [[f32; 3]; 2],
    pub camera_radius: f32,
    pub seconds: f64,
    pub rays_per_second: f64,
    /// Triangles written to `mesh/scene.obj` (with `--mesh`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh_triangles: Option<usize>,
    /// With `--capture`: the capture's settings and every photo's gain.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub capture: Option<CaptureReport>,
}

/// Progress of a run: views rendered so far and in all.
pub type Progress<'a> = &'a mut dyn FnMut(usize, usize);

/// Load and resolve a script with its geometry.
pub fn load_scene(path: &Path) -> Result<(LoadedScript, AssetSet, ResolvedLayout), SynthError> {
    let script = assetfield_layout::load(path)?;
    let assets = AssetSet::from_script(&script)?;
    let layout = resolve(&script, &assets)?;
    Ok((script, assets, layout))
}

/// An empty layout (or one of containers only) has nothing to render: an error at the
/// script's `layout`.
fn refuse_empty(script: &LoadedScript, layout: &ResolvedLayout) -> Result<(), SynthError> {
    if layout.objects().next().is_some() {
        return Ok(());
    }
    let location = match script.files.first() {
        Some(main) => main.find_ident("layout", 0),
        None => Location { file: script.path.clone(), line: 1, col: 1 },
    };
    Err(SynthError::EmptyScene { location, instances: layout.instances.len() })
}

fn rel_name(split: &str, k: usize) -> String {
    format!("./{split}/r_{k}")
}

fn transforms_for(cameras: &[(String, Camera)], fov: f32) -> TransformsFile {
    TransformsFile {
        camera_angle_x: Some(fov),
        frames: cameras
            .iter()
            .map(|(path, c)| FrameEntry {
                file_path: path.clone(),
                transform_matrix: c.c2w_matrix().transpose().to_cols_array_2d(),
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    }
}

/// Render the dataset of a scene script into `out` (see the module docs for the layout).
/// `edited` renders a second layout from the same test cameras into `out/edited`.
pub fn synthesize(
    scene: &Path,
    opts: &SynthOptions,
    out: &Path,
    overwrite: bool,
    edited: Option<&Path>,
    progress: Progress<'_>,
) -> Result<SynthReport, SynthError> {
    let script = assetfield_layout::load(scene)?;
    let loaded = LoadedScene { script: &script, path: scene, text: None };
    synthesize_loaded(loaded, opts, out, overwrite, edited, progress)
}

/// A scene script already loaded: the script, the path that names it in the report, and
/// its text when the dataset is to hold it as `scene.ron` (so that a generated scene can be
/// read and rendered again).
#[derive(Debug, Clone, Copy)]
pub struct LoadedScene<'a> {
    pub script: &'a LoadedScript,
    pub path: &'a Path,
    pub text: Option<&'a str>,
}

/// [`synthesize`] for a script already loaded ([`LoadedScene`]).
pub fn synthesize_loaded(
    loaded: LoadedScene<'_>,
    opts: &SynthOptions,
    out: &Path,
    overwrite: bool,
    edited: Option<&Path>,
    progress: Progress<'_>,
) -> Result<SynthReport, SynthError> {
    let LoadedScene { script, path: scene, text: script_text } = loaded;
    let start = Instant::now();
    let assets = AssetSet::from_script(script)?;
    let layout = resolve(script, &assets)?;
    refuse_empty(script, &layout)?;
    let cfg = SynthConfig::resolve_at(opts, script.views.as_ref(), script.views_at.as_ref())?;
    let light = Light::from_script(script.lighting.as_ref());
    let world = Scene::new(&layout, &assets, light);
    let edited_scene = match edited {
        Some(p) => {
            let (escript, eassets, elayout) = load_scene(p)?;
            refuse_empty(&escript, &elayout)?;
            let light = Light::from_script(escript.lighting.as_ref().or(script.lighting.as_ref()));
            let gt = GtLayout::from_resolved(&elayout)
                .to_json_with(escript.units_per_metre.or(script.units_per_metre), &eassets.sources);
            Some((Scene::new(&elayout, &eassets, light), elayout, gt))
        }
        None => None,
    };

    let bounds = world.bounds();
    let capture = (opts.capture || script.views.as_ref().is_some_and(|v| v.capture.is_some()))
        .then(|| {
            let settings = script.views.as_ref().and_then(|v| v.capture).unwrap_or_default();
            CaptureConfig::resolve(&settings, script.units_per_metre.unwrap_or(1.0))
        });
    let room = script
        .extent
        .map(|((x0, y0), (x1, y1))| Rect2::new(Vec2::new(x0, y0), Vec2::new(x1, y1)))
        .unwrap_or_else(|| bounds.bev());
    let (rig, photos): (Vec<RigView>, Vec<Option<Photo>>) = match &capture {
        Some(cap) => capture_rig(room, cfg.intrinsics(), cfg.views, &test_indices(&cfg), cap)?
            .into_iter()
            .map(|(v, p)| (v, Some(p)))
            .unzip(),
        None => camera_rig(&bounds, &cfg).into_iter().map(|v| (v, None)).unzip(),
    };
    // one view as the camera saw it: over the sky and developed for a capture, else with
    // a transparent background
    let shoot = |scene: &Scene, k: usize, camera: &Camera| match (&capture, photos[k]) {
        (Some(cap), Some(photo)) => {
            let light = scene.light.direction;
            let pixels = scene.render_over(camera, cfg.samples_per_side, &|d| sky(d, light));
            let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
            image::DynamicImage::ImageRgb8(develop(&pixels, w, h, &photo, cap, k as u64))
        }
        _ => image::DynamicImage::ImageRgba8(scene.render(camera, cfg.samples_per_side)),
    };
    let staging = StagingDir::new(out, overwrite)?;
    let dir = staging.path().to_path_buf();
    for sub in ["train", "test"] {
        std::fs::create_dir_all(dir.join(sub))
            .map_err(|e| assetfield_core::CoreError::io(dir.join(sub), e))?;
    }
    let n_edit = if edited_scene.is_some() { cfg.test_views as usize } else { 0 };
    let total = rig.len() + n_edit;
    let (mut train, mut test) = (Vec::new(), Vec::new());
    // the rig index of every view, train then test (the edited views reuse the test ones')
    let (mut train_k, mut test_k) = (Vec::new(), Vec::new());
    for (k, view) in rig.iter().enumerate() {
        interrupt::check()?;
        let (split, list, ks) = if view.test {
            ("test", &mut test, &mut test_k)
        } else {
            ("train", &mut train, &mut train_k)
        };
        let name = rel_name(split, list.len());
        assetfield_core::fsx::save_png(
            &dir.join(format!("{name}.png")),
            &shoot(&world, k, &view.camera),
        )?;
        list.push((name, view.camera));
        ks.push(k);
        progress(k + 1, total);
    }
    let fov = cfg.fov_deg.to_radians();
    write_transforms(&dir.join("transforms_train.json"), &transforms_for(&train, fov))?;
    write_transforms(&dir.join("transforms_test.json"), &transforms_for(&test, fov))?;
    let gt = GtLayout::from_resolved(&layout).to_json_with(script.units_per_metre, &assets.sources);
    write_atomic(&dir.join("gt_layout.json"), gt.as_bytes())?;
    assetfield_layout::layout_picture(&layout, &dir.join("layout.png"))?;
    if let Some(text) = script_text {
        write_atomic(&dir.join("scene.ron"), text.as_bytes())?;
    }
    let mesh = if opts.mesh {
        Some(crate::export::export_obj(&layout, &assets, &dir.join("mesh"))?)
    } else {
        None
    };

    if let Some((escene, elayout, egt)) = &edited_scene {
        let edir = dir.join("edited");
        std::fs::create_dir_all(edir.join("test"))
            .map_err(|e| assetfield_core::CoreError::io(&edir, e))?;
        for (k, ((name, cam), &rig_k)) in test.iter().zip(&test_k).enumerate() {
            interrupt::check()?;
            assetfield_core::fsx::save_png(
                &edir.join(format!("{name}.png")),
                &shoot(escene, rig_k, cam),
            )?;
            progress(rig.len() + k + 1, total);
        }
        write_transforms(&edir.join("transforms_test.json"), &transforms_for(&test, fov))?;
        write_atomic(&edir.join("gt_layout.json"), egt.as_bytes())?;
        assetfield_layout::layout_picture(elayout, &edir.join("layout.png"))?;
    }

    let seconds = start.elapsed().as_secs_f64();
    let rays =
        (total as f64) * (cfg.resolution as f64).powi(2) * (cfg.samples_per_side as f64).powi(2);
    let report = SynthReport {
        scene: layout.name.clone(),
        source: std::fs::canonicalize(scene).unwrap_or_else(|_| scene.to_path_buf()),
        out_dir: out.to_path_buf(),
        config: cfg.clone(),
        train_views: train.len(),
        test_views: test.len(),
        edited_views: n_edit,
        instances: layout.objects().count(),
        categories: layout.categories(),
        units_per_metre: script.units_per_metre.unwrap_or(1.0),
        scene_aabb: [bounds.min.to_array(), bounds.max.to_array()],
        camera_radius: rig
            .first()
            .map(|v| (v.camera.position() - bounds.center()).length())
            .unwrap_or(0.0),
        seconds,
        rays_per_second: rays / seconds.max(1e-9),
        mesh_triangles: mesh.map(|m| m.triangles),
        capture: capture.map(|settings| {
            let gains =
                |ks: &[usize]| ks.iter().filter_map(|&k| photos[k]).map(|p| p.gain).collect();
            CaptureReport {
                settings,
                room: [room.min.to_array(), room.max.to_array()],
                train_gains: gains(&train_k),
                test_gains: gains(&test_k),
            }
        }),
    };
    let json = serde_json::to_string_pretty(&report).expect("report serialises");
    write_atomic(&dir.join("synth.json"), json.as_bytes())?;
    staging.commit()?;
    Ok(report)
}
