//! `assetfield eval`: render held-out views with a trained field and measure PSNR / SSIM.

use super::util::{dataset_dir, open_field, progress_bar, save_rgb};
use anyhow::{Context, Result, bail};
use assetfield_core::fsx::{StagingDir, write_atomic};
use assetfield_core::metrics::error_image;
use assetfield_core::plot::{pca_colors, rgb_image};
use assetfield_data::{Dataset, Frame, LoadOptions, Split};
use assetfield_field::render_semantic_view;
use clap::Args;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// The field file written by `assetfield train`.
    pub field: PathBuf,
    /// The dataset to evaluate on [default: the dataset the field was trained on, as
    /// stored in the field file]. Its poses get the field's ground alignment, if any.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Output folder: metrics.json, render/r_K.png, error/r_K.png (K = the frame's index in
    /// its transforms file). Written atomically: it appears only when complete.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Evaluate only the first N selected views.
    #[arg(long, value_name = "N")]
    pub views: Option<usize>,
    /// Take every K-th view of the split (0, K, 2K, ...).
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub every: usize,
    /// Which split to evaluate on: test, val, train or all.
    #[arg(long, default_value = "test")]
    pub split: Split,
    /// Image downscale factor [default: the one the field was trained with].
    #[arg(long)]
    pub downscale: Option<u32>,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub force: bool,
}

pub fn eval(a: EvalArgs) -> Result<()> {
    if a.every == 0 {
        bail!("--every must be at least 1");
    }
    if a.views == Some(0) {
        bail!("--views must be at least 1");
    }
    if a.out.exists() && !a.force {
        bail!("{} already exists (pass --force to replace it)", a.out.display());
    }
    let loaded = open_field(&a.field)?;
    let info = &loaded.info;
    let data_dir = dataset_dir(a.data.as_deref(), info, &a.field)?;
    let background = info.background.unwrap_or([1.0; 3]);
    let opts = LoadOptions {
        background,
        downscale: a.downscale.or(info.downscale).unwrap_or(1),
        max_frames: a.views.map(|n| (n - 1) * a.every + 1),
        ..LoadOptions::default()
    };
    let mut data = Dataset::load(&data_dir, a.split, &opts)
        .with_context(|| format!("loading the {} views of {}", a.split, data_dir.display()))?;
    if let Some(g) = &info.ground_transform {
        g.apply_to_dataset(&mut data);
    }
    let frames: Vec<&Frame> = data.frames.iter().step_by(a.every).collect();
    let (w, h) = data.resolution();
    let staging = StagingDir::new(&a.out, a.force)?;
    let root = staging.path().to_path_buf();
    let pb = progress_bar(frames.len() as u64, "rendering views");
    let result = assetfield_field::eval::evaluate_with(
        loaded.field.config.kind.name(),
        &frames,
        |f| Ok::<_, anyhow::Error>(loaded.render(&f.camera)),
        |frame, rgb, m| -> Result<()> {
            let name = format!("r_{}.png", frame.index);
            save_rgb(&root.join("render").join(&name), w, h, rgb.to_vec())?;
            let err = error_image(rgb, &frame.image.rgb, w as usize, h as usize);
            assetfield_core::fsx::save_png(&root.join("error").join(&name), &err.into())?;
            // I-AssetField with a semantic field: its features, PCA-coloured
            if let Some(sem) =
                render_semantic_view(&loaded.field, loaded.occupancy.as_ref(), &frame.camera)
            {
                let colors =
                    pca_colors(&sem, (w * h) as usize, loaded.field.config.semantic_channels);
                let img = rgb_image(&colors, w, h);
                assetfield_core::fsx::save_png(&root.join("semantic").join(&name), &img.into())?;
            }
            pb.set_message(format!("view {} psnr {:.2}", frame.index, m.psnr));
            pb.inc(1);
            Ok(())
        },
    );
    pb.finish_and_clear();
    let report = result?;
    let json = serde_json::to_string_pretty(&report)?;
    write_atomic(&root.join("metrics.json"), json.as_bytes())?;
    let out = staging.commit()?;
    println!(
        "{} views of {} ({}x{}): PSNR {:.2} dB, SSIM {:.4}, {:.2} s/view; right halves after a colour map fitted on the left halves (photos that vary): PSNR {:.2} dB, SSIM {:.4}",
        report.views.len(),
        data_dir.display(),
        w,
        h,
        report.psnr,
        report.ssim,
        report.seconds_per_view,
        report.psnr_fitted,
        report.ssim_fitted
    );
    println!("wrote {}", out.join("metrics.json").display());
    Ok(())
}
