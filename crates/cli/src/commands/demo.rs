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

/// One step of the demo: what it does and the `assetfield` arguments that do it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DemoStep {
    pub title: &'static str,
    pub args: Vec<String>,
}

/// The demo's commands, in order: synth -> train -> eval -> planes -> mine -> compose (edit)
/// -> compose (turntable). The README's tour lists the same commands (a test compares them).
pub fn demo_plan(a: &DemoArgs) -> Vec<DemoStep> {
    let o = |p: &str| -> String { a.out.join(p).display().to_string() };
    let s = |p: &Path| p.display().to_string();
    let (data, field, lib) = (o("data"), o("field.safetensors"), o("library"));
    let layout = o("library/layout.ron");
    let step = |title, args: &[&str]| DemoStep {
        title,
        args: args.iter().map(|a| a.to_string()).collect(),
    };
    let (iters, minutes) = (a.iters.to_string(), a.minutes.map(|m| m.to_string()));
    let mut train = vec!["train", &data, "--out", &field, "--iters", &iters];
    if let Some(m) = &minutes {
        train.extend(["--minutes", m, "--clock", "cpu"]);
    }
    train.extend(["--force", "--discard-checkpoint"]);
    vec![
        step(
            "render the scene and its edit (ground truth)",
            &["synth", &s(&a.scene), "--out", &data, "--edited", &s(&a.edit), "--force"],
        ),
        step("train an S-AssetField", &train),
        step(
            "evaluate on the test views",
            &["eval", &field, "--data", &data, "--out", &o("eval"), "--force"],
        ),
        step("draw the ground planes", &["planes", &field, "--out", &o("planes"), "--force"]),
        step(
            "mine the planes into an asset library",
            &[
                "mine",
                &field,
                "--out",
                &lib,
                "--gt",
                &o("data/gt_layout.json"),
                "--gt-names",
                "--force",
            ],
        ),
        step(
            "compose the edit from the library, compare with the ground truth",
            &[
                "compose",
                &layout,
                "--library",
                &lib,
                "--edits",
                &s(&a.edit),
                "--views",
                &o("data/edited"),
                "--metrics",
                "--planes",
                "--out",
                &o("edit"),
                "--force",
            ],
        ),
        step(
            "a turntable of the composed scene",
            &[
                "compose",
                &layout,
                "--library",
                &lib,
                "--orbit",
                "12",
                "--out",
                &o("orbit"),
                "--force",
            ],
        ),
    ]
}

fn run_step(n: usize, total: usize, step: &DemoStep) -> Result<()> {
    let title = format!("{n}/{total} {}", step.title);
    println!("\n== {title}: assetfield {}", step.args.join(" "));
    let mut argv = vec!["assetfield"];
    argv.extend(step.args.iter().map(String::as_str));
    let cli = crate::Cli::try_parse_from_args(&argv)?;
    crate::run(cli).with_context(|| format!("demo step: {title}"))
}

/// Check the arguments and the output folder, then run [`demo_plan`] step by step.
pub fn demo(a: DemoArgs) -> Result<()> {
    check(&a)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let plan = demo_plan(&a);
    for (i, step) in plan.iter().enumerate() {
        let ran = run_step(i + 1, plan.len(), step);
        // the edit names objects by their ground-truth keys: when mining missed one (a field
        // trained too briefly), say what to do about it
        let ran = match (ran, step.args.iter().any(|x| x == "--edits")) {
            (Err(e), true) => Err(match mined_f1(&a.out) {
                Some(f) if f < 0.95 => e.context(format!(
                    "mining found too few objects (detection F1 {f:.2}, see {}/boxes.png) for \
                     the edit to name them: train longer (--iters {} or more)",
                    a.out.join("library").display(),
                    (a.iters * 2).max(DEMO_ITERS)
                )),
                _ => e,
            }),
            (r, _) => r,
        };
        ran?;
    }
    println!(
        "\ndemo done: {} (eval/metrics.json, library/boxes.png, edit/metrics.json, orbit/*.png)",
        a.out.display()
    );
    Ok(())
}

/// The detection F1 that mining recorded in the library's `metrics.json`, if any.
fn mined_f1(out: &Path) -> Option<f64> {
    let text = std::fs::read_to_string(out.join("library/metrics.json")).ok()?;
    serde_json::from_str::<serde_json::Value>(&text).ok()?["f1"].as_f64()
}

fn check(a: &DemoArgs) -> Result<()> {
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
    Ok(())
}
