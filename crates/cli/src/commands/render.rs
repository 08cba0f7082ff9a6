//! `assetfield render`: pictures of a trained field from a dataset's cameras or a turntable.

use super::util::{dataset_dir, open_field, progress_bar, save_rgb};
use anyhow::{Context, Result, bail};
use assetfield_core::Camera;
use assetfield_core::fsx::StagingDir;
use assetfield_core::{Orbit, fitting_radius};
use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_field::render_view;
use clap::Args;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The field file written by `assetfield train`.
    pub field: PathBuf,
    /// Output folder of PNGs (RGB on the field's background). Written atomically.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Render the cameras of this dataset (its --split views, named r_K.png after their
    /// frame index) instead of a turntable. `--data stored` uses the dataset the field was
    /// trained on.
    #[arg(long, conflicts_with_all = ["orbit", "elevation", "radius", "fov", "res"])]
    pub data: Option<PathBuf>,
    /// Which split's cameras --data renders: test, val, train or all.
    #[arg(long, default_value = "test", requires = "data")]
    pub split: Split,
    /// Image downscale factor for --data cameras [default: the training one].
    #[arg(long, requires = "data")]
    pub downscale: Option<u32>,
    /// Turntable of N views (orbit_000.png, ...) around the centre of the field's box, evenly
    /// spaced in azimuth starting on +X. The default when --data is not given (8 views).
    #[arg(long, value_name = "N")]
    pub orbit: Option<usize>,
    /// Turntable camera elevation above the ground plane, degrees.
    #[arg(long, default_value_t = 30.0, value_name = "DEG")]
    pub elevation: f32,
    /// Turntable radius [default: the distance at which the box's bounding sphere fills the
    /// view, plus 5%].
    #[arg(long, value_name = "R")]
    pub radius: Option<f32>,
    /// Turntable image size (square), pixels.
    #[arg(long, default_value_t = 400, value_name = "PX")]
    pub res: u32,
    /// Turntable horizontal field of view, degrees.
    #[arg(long, default_value_t = 40.0, value_name = "DEG")]
    pub fov: f32,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub force: bool,
}

pub fn render(a: RenderArgs) -> Result<()> {
    if a.res == 0 || a.orbit == Some(0) {
        bail!("--res and --orbit must be at least 1");
    }
    if !(a.fov > 0.0 && a.fov < 180.0) {
        bail!("--fov {} must be between 0 and 180 degrees", a.fov);
    }
    if let Some(r) = a.radius
        && !(r.is_finite() && r > 0.0)
    {
        bail!("--radius {r} must be positive");
    }
    if a.out.exists() && !a.force {
        bail!("{} already exists (pass --force to replace it)", a.out.display());
    }
    let loaded = open_field(&a.field)?;
    let info = &loaded.info;
    let cameras: Vec<(String, Camera)> = match &a.data {
        Some(d) => {
            let given = (d.as_os_str() != "stored").then_some(d.as_path());
            let dir = dataset_dir(given, info, &a.field)?;
            let opts = LoadOptions {
                background: info.background.unwrap_or([1.0; 3]),
                downscale: a.downscale.or(info.downscale).unwrap_or(1),
                ..LoadOptions::default()
            };
            let mut cams = Dataset::load_cameras_only(&dir, a.split, &opts)
                .with_context(|| format!("reading the cameras of {}", dir.display()))?;
            if let Some(g) = &info.ground_transform {
                g.apply_to_cameras(&mut cams);
            }
            cams.views.iter().map(|v| (format!("r_{}.png", v.index), v.camera)).collect()
        }
        None => {
            let aabb = loaded.field.config.aabb();
            let mut orbit = Orbit::around(&aabb, a.orbit.unwrap_or(8), a.res);
            orbit.elevation_deg = a.elevation;
            orbit.fov_deg = a.fov;
            orbit.radius = a.radius.unwrap_or_else(|| fitting_radius(&aabb, a.fov));
            orbit
                .cameras()
                .into_iter()
                .enumerate()
                .map(|(k, c)| (format!("orbit_{k:03}.png"), c))
                .collect()
        }
    };
    let staging = StagingDir::new(&a.out, a.force)?;
    let bg = info.background_or_white();
    let pb = progress_bar(cameras.len() as u64, "rendering");
    let t0 = std::time::Instant::now();
    for (name, cam) in &cameras {
        assetfield_core::interrupt::check()?;
        let rgb = match &loaded.background_map {
            Some(_) => loaded.render(cam),
            None => render_view(&loaded.field, loaded.occupancy.as_ref(), cam, bg),
        };
        save_rgb(&staging.path().join(name), cam.intrinsics.width, cam.intrinsics.height, rgb)?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    let out = staging.commit()?;
    let (w, h) = cameras.first().map_or((0, 0), |(_, c)| (c.intrinsics.width, c.intrinsics.height));
    println!("rendered {} views ({w}x{h}) in {:.1} s", cameras.len(), t0.elapsed().as_secs_f64());
    println!("wrote {}", out.display());
    Ok(())
}
