//! `assetfield planes`: pictures of a field's ground feature planes and its training curve
//! (the paper's Fig. 3).

use super::util::open_field;
use anyhow::{Result, bail};
use assetfield_core::fsx::{StagingDir, write_atomic};
use assetfield_field::ModelKind;
use assetfield_field::pictures::{
    color_plane_name, density_picture, density_plane_name, pca_picture, training_curve,
};
use clap::Args;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct PlanesArgs {
    /// The field file written by `assetfield train` (a checkpoint works too).
    pub field: PathBuf,
    /// Output folder. Written atomically: it appears only when complete.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Enlarge plane pictures by this integer factor (nearest neighbour, texels stay
    /// visible) [default: the smallest factor that makes the longer side at least 512 px].
    #[arg(long)]
    pub scale: Option<u32>,
    /// Replace the output folder if it exists.
    #[arg(long)]
    pub force: bool,
}

pub fn planes(a: PlanesArgs) -> Result<()> {
    if a.scale == Some(0) {
        bail!("--scale must be at least 1");
    }
    if a.out.exists() && !a.force {
        bail!("{} already exists (pass --force to replace it)", a.out.display());
    }
    let loaded = open_field(&a.field)?;
    let field = &loaded.field;
    let [nx, ny, _] = field.config.res;
    let scale = a.scale.unwrap_or_else(|| 512u32.div_ceil(nx.max(ny) as u32).max(1));
    let staging = StagingDir::new(&a.out, a.force)?;
    let dir = staging.path();
    let mut written = Vec::new();

    density_picture(field).upscaled(scale).save_png(&dir.join("density.png"))?;
    written.push("density.png: per texel, max over the vertical column of one step's opacity 1 - exp(-sigma * step) (dark = empty, yellow = opaque)".to_string());
    let (dname, cname) = (density_plane_name(field), color_plane_name(field));
    for (file, name) in [("density_pca.png", dname), ("color_pca.png", cname)] {
        match pca_picture(field, name) {
            Some(p) => {
                p.upscaled(scale).save_png(&dir.join(file))?;
                written.push(format!("{file}: PCA colouring (3 principal components) of {name}"));
            }
            None => bail!("{}: the field has no tensor {name}", a.field.display()),
        }
    }
    let curve = match &loaded.info.history {
        Some(h) if !h.is_empty() => {
            let title = format!(
                "{} training: psnr against time",
                match field.config.kind {
                    ModelKind::Standard => "s-assetfield",
                    ModelKind::Integrated => "i-assetfield",
                    ModelKind::Vm => "tensorf-vm",
                }
            );
            training_curve(h, loaded.info.val_history.as_ref(), &title)
                .save_png(&dir.join("curve.png"))?;
            written
                .push("curve.png: batch PSNR (and test PSNR if recorded) against seconds".into());
            true
        }
        _ => false,
    };
    let summary = serde_json::json!({
        "field": a.field,
        "model": field.config.kind.name(),
        "plane_resolution": [nx, ny],
        "aabb": field.config.aabb,
        "scale": scale,
        "orientation": "seen from above: +x right, +y up (plane row 0 = ymin is the bottom row)",
        "files": written,
    });
    write_atomic(&dir.join("planes.json"), serde_json::to_string_pretty(&summary)?.as_bytes())?;
    let out = staging.commit()?;
    for w in &written {
        println!("{w}");
    }
    if !curve {
        println!(
            "no curve.png: {} holds no training history (\"history\" metadata)",
            a.field.display()
        );
    }
    println!("wrote {} ({nx}x{ny} texels, x{scale})", out.display());
    Ok(())
}
