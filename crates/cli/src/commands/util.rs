//! Helpers shared by the commands: progress bars, field loading with clear errors, the
//! dataset a field was trained on, parsing of small values, PNG output, medians of timings.

use anyhow::{Context, Result, bail};
use assetfield_data::ImageF32;
use assetfield_field::eval::{FieldInfo, LoadedField, load_field};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// A bar counting items (views), with elapsed time and ETA.
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner:.green} {msg} [{bar:40.cyan/blue}] {pos}/{len} {elapsed_precise} (eta {eta})",
        )
        .expect("valid progress template")
        .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// Load a field file (or training checkpoint), saying what was expected when it fails.
pub fn open_field(path: &Path) -> Result<LoadedField> {
    load_field(path).with_context(|| {
        format!(
            "cannot read field {} (expected a .safetensors field file written by `assetfield train`)",
            path.display()
        )
    })
}

/// A colour: `white`, `black`, `gray`/`grey`, or `R,G,B` with components in [0, 1].
pub fn parse_color(s: &str) -> Result<[f32; 3]> {
    match s.trim().to_ascii_lowercase().as_str() {
        "white" => return Ok([1.0; 3]),
        "black" => return Ok([0.0; 3]),
        "gray" | "grey" => return Ok([0.5; 3]),
        _ => {}
    }
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let err = || {
        anyhow::anyhow!(
            "invalid colour {s:?}: expected white, black, grey or R,G,B with components in [0, 1]"
        )
    };
    if parts.len() != 3 {
        return Err(err());
    }
    let mut c = [0.0f32; 3];
    for (v, p) in c.iter_mut().zip(&parts) {
        *v = p.parse().map_err(|_| err())?;
        if !(0.0..=1.0).contains(v) {
            return Err(err());
        }
    }
    Ok(c)
}

/// Six comma-separated numbers `xmin,ymin,zmin,xmax,ymax,zmax`, each min below its max.
pub fn parse_aabb(s: &str) -> Result<assetfield_core::Aabb3> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 6 {
        bail!(
            "invalid --aabb {s:?}: expected six comma-separated numbers xmin,ymin,zmin,xmax,ymax,zmax, got {}",
            parts.len()
        );
    }
    let mut v = [0.0f32; 6];
    for (x, p) in v.iter_mut().zip(&parts) {
        *x = p
            .parse::<f32>()
            .ok()
            .filter(|x| x.is_finite())
            .with_context(|| format!("invalid --aabb {s:?}: {p:?} is not a finite number"))?;
    }
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        if v[k] >= v[k + 3] {
            bail!(
                "invalid --aabb {s:?}: {axis}min ({}) must be below {axis}max ({})",
                v[k],
                v[k + 3]
            );
        }
    }
    Ok(assetfield_core::Aabb3::new(
        glam::Vec3::new(v[0], v[1], v[2]),
        glam::Vec3::new(v[3], v[4], v[5]),
    ))
}

/// Save an RGB float image (values in [0, 1], row-major) as PNG.
pub fn save_rgb(path: &Path, width: u32, height: u32, rgb: Vec<f32>) -> Result<()> {
    let img = ImageF32 { width, height, rgb, alpha: None }.to_rgb8();
    assetfield_core::fsx::save_png(path, &img.into())?;
    Ok(())
}

/// `[a, b, c]` with a few decimals.
pub fn fmt_vec(v: [f32; 3]) -> String {
    format!("[{:.3}, {:.3}, {:.3}]", v[0], v[1], v[2])
}

/// Seconds as `1h02m`, `3m05s` or `12.3s`.
pub fn fmt_duration(s: f64) -> String {
    if !s.is_finite() || s < 0.0 {
        return "?".into();
    }
    let t = s.round() as u64;
    if t >= 3600 {
        format!("{}h{:02}m", t / 3600, (t % 3600) / 60)
    } else if t >= 60 {
        format!("{}m{:02}s", t / 60, t % 60)
    } else {
        format!("{s:.1}s")
    }
}

/// Median (and minimum) of seconds.
pub(crate) fn median(t: &[f64]) -> (f64, f64) {
    let mut v = t.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => (f64::NAN, f64::NAN),
        n => (v[n / 2], v[0]),
    }
}

/// The progress bar of a training run (per mille of its budget, a message per update).
pub(crate) fn training_bar(total_iters: Option<u64>) -> ProgressBar {
    let pb = ProgressBar::new(1000);
    pb.set_style(
        ProgressStyle::with_template("{spinner:.green} [{bar:30.cyan/blue}] {percent:>3}% {msg}")
            .expect("valid progress template")
            .progress_chars("=> "),
    );
    pb.enable_steady_tick(Duration::from_millis(200));
    if let Some(n) = total_iters {
        pb.set_message(format!("starting ({n} iterations)"));
    }
    pb
}

/// The dataset a field command works on: `--data`, else the one stored in the field.
pub fn dataset_dir(given: Option<&Path>, info: &FieldInfo, field: &Path) -> Result<PathBuf> {
    match (given, &info.dataset) {
        (Some(d), stored) => {
            if let (Some(s), Ok(g)) = (stored, d.canonicalize())
                && &g != s
            {
                eprintln!(
                    "note: {} was trained on {}; evaluating on {}",
                    field.display(),
                    s.display(),
                    g.display()
                );
            }
            Ok(d.to_path_buf())
        }
        (None, Some(s)) => Ok(s.clone()),
        (None, None) => bail!(
            "{} does not say which dataset it was trained on; pass --data DATA_DIR",
            field.display()
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_and_boxes_parse_or_explain() {
        assert_eq!(parse_color("white").unwrap(), [1.0; 3]);
        assert_eq!(parse_color("0, 0.5,1").unwrap(), [0.0, 0.5, 1.0]);
        assert!(parse_color("2,0,0").is_err() && parse_color("red").is_err());
        let b = parse_aabb("-1,-2,0,1,2,3").unwrap();
        assert_eq!(b.min.to_array(), [-1.0, -2.0, 0.0]);
        assert!(parse_aabb("1,2,3").unwrap_err().to_string().contains("six"));
        assert!(parse_aabb("0,0,0,1,1,x").unwrap_err().to_string().contains("\"x\""));
        assert!(parse_aabb("0,0,2,1,1,1").unwrap_err().to_string().contains("zmin"));
        assert_eq!(fmt_duration(75.0), "1m15s");
        assert_eq!(fmt_duration(3.24), "3.2s");
    }
}
