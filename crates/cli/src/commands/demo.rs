//! `assetfield demo`: the whole pipeline on the built-in default scene, one command.

use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder: data/ (the synthesised dataset and its edited test views),
    /// field.safetensors, eval/, planes/, library/, edit/ (the edit composed and compared with
    /// the ground truth) and orbit/ (a turntable of the composed scene).
    #[arg(long, short, default_value = "runs/demo")]
    pub out: PathBuf,
    /// The scene (a layout script of the suite) and its edit script.
    #[arg(long, default_value = "scenes/conference_room.ron")]
    pub scene: PathBuf,
    #[arg(long, default_value = "scenes/edits/conference_room.ron")]
    pub edit: PathBuf,
    /// Training budget in iterations of 4096 rays: the same field on every machine, however
    /// fast or busy (with the default seed, bit for bit).
    #[arg(long, default_value_t = DEMO_ITERS)]
    pub iters: u64,
    /// Also stop after this many minutes (CPU time divided by the worker threads), whichever
    /// comes first; the field then depends on the machine.
    #[arg(long)]
    pub minutes: Option<f64>,
    /// Replace the output folder's contents if it exists.
    #[arg(long)]
    pub force: bool,
}

/// The demo's training budget: iterations of 4096 rays (about 5 minutes on 2 cores).
pub const DEMO_ITERS: u64 = 6000;

fn step(title: &str, args: &[&str]) -> Result<()> {
    println!("\n== {title}: assetfield {}", args.join(" "));
    let mut argv = vec!["assetfield"];
    argv.extend_from_slice(args);
    let cli = crate::Cli::try_parse_from_args(&argv)?;
    crate::run(cli).with_context(|| format!("demo step: {title}"))
}

/// Run the pipeline: synth -> train -> eval -> planes -> mine -> compose (edit) -> compose
/// (turntable).
pub fn demo(a: DemoArgs) -> Result<()> {
    for p in [&a.scene, &a.edit] {
        if !p.is_file() {
            bail!(
                "{} not found: run the demo from the repository root, or pass --scene/--edit",
                p.display()
            );
        }
    }
    if let Some(m) = a.minutes
        && !(m.is_finite() && m > 0.0)
    {
        bail!("--minutes must be positive");
    }
    if a.iters == 0 {
        bail!("--iters must be at least 1");
    }
    if a.out.exists() && !a.force {
        bail!("{} already exists (pass --force to replace it)", a.out.display());
    }
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let o = |p: &str| -> String { a.out.join(p).display().to_string() };
    let s = |p: &Path| p.display().to_string();
    let iters = a.iters.to_string();
    let minutes = a.minutes.map(|m| m.to_string());
    let mut budget = vec!["--iters", iters.as_str()];
    if let Some(m) = &minutes {
        budget.extend(["--minutes", m.as_str(), "--clock", "cpu"]);
    }
    let (data, field, lib) = (o("data"), o("field.safetensors"), o("library"));
    let edited = o("data/edited");
    let gt = o("data/gt_layout.json");
    let layout = o("library/layout.ron");
    step(
        "1/7 render the scene and its edit (ground truth)",
        &["synth", &s(&a.scene), "--out", &data, "--edited", &s(&a.edit), "--force"],
    )?;
    let mut train = vec!["train", data.as_str(), "--out", field.as_str()];
    train.extend(&budget);
    train.extend(["--force", "--discard-checkpoint"]);
    step("2/7 train an S-AssetField", &train)?;
    step(
        "3/7 evaluate on the test views",
        &["eval", &field, "--data", &data, "--out", &o("eval"), "--force"],
    )?;
    step("4/7 draw the ground planes", &["planes", &field, "--out", &o("planes"), "--force"])?;
    step(
        "5/7 mine the planes into an asset library",
        &["mine", &field, "--out", &lib, "--gt", &gt, "--gt-names", "--force"],
    )?;
    // the edit names objects by their ground-truth keys: when mining missed one (a field
    // trained too briefly), say what to do about it
    let mined = std::fs::read_to_string(o("library/metrics.json")).ok();
    let f1 = mined
        .as_deref()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(t).ok())
        .and_then(|v| v["f1"].as_f64());
    step(
        "6/7 compose the edit from the library, compare with the ground truth",
        &[
            "compose",
            &layout,
            "--library",
            &lib,
            "--edits",
            &s(&a.edit),
            "--views",
            &edited,
            "--metrics",
            "--planes",
            "--out",
            &o("edit"),
            "--force",
        ],
    )
    .map_err(|e| match f1 {
        Some(f) if f < 0.95 => e.context(format!(
            "mining found too few objects (detection F1 {f:.2}, see {lib}/boxes.png) for the \
             edit to name them: train longer (--iters {} or more)",
            (a.iters * 2).max(DEMO_ITERS)
        )),
        _ => e,
    })?;
    step(
        "7/7 a turntable of the composed scene",
        &["compose", &layout, "--library", &lib, "--orbit", "12", "--out", &o("orbit"), "--force"],
    )?;
    println!(
        "\ndemo done: {} (eval/metrics.json, library/boxes.png, edit/metrics.json, orbit/*.png)",
        a.out.display()
    );
    Ok(())
}
