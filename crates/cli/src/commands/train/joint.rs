//! `assetfield train DATA_A DATA_B ... --out DIR`: several scenes trained together, one field
//! per scene sharing its vertical axes, basis and decoders (see
//! [`assetfield_field::joint`]); checkpoints per scene, resume, Ctrl-C as a single run.

use super::{
    AlignArg, DecoderArg, TrainArgs, checkpoint_path, save_checkpoint, scene_bounds, shared_hash,
    time_left, train_config, write_field,
};
use crate::commands::util::{fmt_duration, fmt_vec, parse_color, training_bar};
use anyhow::{Context, Result, anyhow, bail};
use assetfield_core::{Aabb3, TensorFile, interrupt};
use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_field::eval::{FieldInfo, keys};
use assetfield_field::{DecoderKind, FieldConfig, JointTrainer, ModelKind, joint_configs};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// One scene of the run: where its data and files are.
struct Scene {
    name: String,
    data: PathBuf,
    field: PathBuf,
    ckpt: PathBuf,
    info: FieldInfo,
}

/// Scene names from the dataset folders' names (refusing two alike: their files would
/// collide).
fn scene_names(data: &[PathBuf]) -> Result<Vec<String>> {
    let mut names: Vec<String> = Vec::new();
    for d in data {
        let canonical = d.canonicalize().unwrap_or_else(|_| d.clone());
        let name = canonical
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.is_empty())
            .ok_or_else(|| anyhow!("{}: a dataset folder needs a name", d.display()))?;
        if let Some(k) = names.iter().position(|n| *n == name) {
            bail!(
                "{} and {} are both named {name:?}: each scene's field is OUT/<folder name>.safetensors, so the folders need different names",
                data[k].display(),
                d.display()
            );
        }
        names.push(name);
    }
    Ok(names)
}

/// Several scenes trained together: check the options, load every scene, start or resume
/// the joint run, train, write one field per scene and report.
pub fn train_joint(a: TrainArgs, res: usize) -> Result<()> {
    let kind = check_joint_options(&a)?;
    let mut scenes = joint_scenes(&a)?;
    let background = parse_color(&a.background).context("--background")?;
    let loaded = scenes
        .iter_mut()
        .map(|s| load_scene(s, &a, kind, background))
        .collect::<Result<Vec<_>>>()?;
    if let Some(k) = loaded.iter().position(|l| l.channels != loaded[0].channels) {
        bail!(
            "{} has {}-channel feature maps and {} has {}: the scenes share one semantic decoder, so they need feature maps of one kind (or none)",
            scenes[0].data.display(),
            loaded[0].channels,
            scenes[k].data.display(),
            loaded[k].channels
        );
    }
    let mut joint = if a.resume {
        resume_joint(&a, &scenes, &loaded)?
    } else {
        start_joint(&a, &mut scenes, &loaded, kind, res, background)?
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let session = joint_loop(&mut joint, &scenes, &a)?;

    // checkpoints first, then the fields (a kill at any moment leaves one or the other)
    save_checkpoints(&joint, &scenes)?;
    for (t, s) in joint.scenes.iter().zip(&scenes) {
        write_field(t, s.info.clone(), &s.field)?;
    }
    if a.discard_checkpoint {
        for s in &scenes {
            if s.ckpt.exists() {
                std::fs::remove_file(&s.ckpt)
                    .with_context(|| format!("removing {}", s.ckpt.display()))?;
            }
        }
    }
    report_joint(&joint, &scenes, &session, &a, kind)
}

/// The options that apply to one dataset only, `--model vm` and an `--out` that is a file
/// are refused; the model to train.
fn check_joint_options(a: &TrainArgs) -> Result<ModelKind> {
    for (given, flag) in [
        (a.aabb.is_some(), "--aabb"),
        (a.align_ground == AlignArg::Pca, "--align-ground pca"),
        (a.align_ground == AlignArg::Floor, "--align-ground floor"),
        (a.appearance == super::Switch::On, "--appearance on"),
        (a.background_map == super::Switch::On, "--background-map on"),
        (a.features.is_some(), "--features"),
        (a.val_every.is_some(), "--val-every"),
    ] {
        if given {
            bail!(
                "{flag} applies to one dataset; with several, each scene's box comes from its own data (and DATA/features is used where present): train without {flag}"
            );
        }
    }
    let kind = a.model.map_or(ModelKind::Standard, |m| m.kind());
    if kind == ModelKind::Vm {
        bail!(
            "--model vm: a TensoRF-VM field has no ground planes to keep per scene and nothing to share; train several scenes together with --model s or i"
        );
    }
    if a.out.is_file() {
        bail!(
            "--out {} is a file; with several datasets --out is the folder that receives one field per scene",
            a.out.display()
        );
    }
    Ok(kind)
}

/// The run's scenes and their files, checked against `--resume` and `--force`.
fn joint_scenes(a: &TrainArgs) -> Result<Vec<Scene>> {
    let names = scene_names(&a.data)?;
    let scenes: Vec<Scene> = names
        .iter()
        .zip(&a.data)
        .map(|(n, d)| {
            let field = a.out.join(format!("{n}.safetensors"));
            Scene {
                name: n.clone(),
                data: d.clone(),
                ckpt: checkpoint_path(&field),
                field,
                info: FieldInfo::default(),
            }
        })
        .collect();
    for s in &scenes {
        if a.resume {
            if !s.ckpt.is_file() {
                bail!(
                    "--resume: no checkpoint at {} for {}; run without --resume to start afresh",
                    s.ckpt.display(),
                    s.data.display()
                );
            }
        } else if !a.force {
            for p in [&s.field, &s.ckpt] {
                if p.exists() {
                    bail!(
                        "{} already exists (pass --force to replace the run, or --resume to continue it)",
                        p.display()
                    );
                }
            }
        }
    }
    Ok(scenes)
}

/// One scene's training views, box and feature maps.
struct Loaded {
    data: Dataset,
    aabb: Aabb3,
    /// Where the box came from.
    source: String,
    /// Semantic feature channels (0: none).
    channels: usize,
}

/// Load scene `s` (and, when resuming, what its checkpoint keeps, into `s.info`).
fn load_scene(
    s: &mut Scene,
    a: &TrainArgs,
    kind: ModelKind,
    background: [f32; 3],
) -> Result<Loaded> {
    let stored = if a.resume {
        let f = TensorFile::load(&s.ckpt)
            .with_context(|| format!("reading checkpoint {}", s.ckpt.display()))?;
        if f.meta(keys::TRAIN_STATE).is_none() {
            bail!("{} is not a training checkpoint (no training state in it)", s.ckpt.display());
        }
        Some(FieldInfo::read(&f)?)
    } else {
        None
    };
    let bg = stored.as_ref().and_then(|i| i.background).unwrap_or(background);
    let downscale = stored.as_ref().and_then(|i| i.downscale).unwrap_or(a.downscale);
    let opts = LoadOptions { background: bg, downscale, ..LoadOptions::default() };
    let cams = Dataset::load_cameras_only(&s.data, Split::All, &opts)
        .with_context(|| format!("reading dataset {}", s.data.display()))?;
    if !cams.points.is_empty() {
        bail!(
            "{} is a capture with sparse points (COLMAP), which is levelled on its floor before training; joint training takes Z-up datasets only: train it alone",
            s.data.display()
        );
    }
    let t0 = Instant::now();
    let mut data = Dataset::load(&s.data, Split::Train, &opts)
        .with_context(|| format!("loading the training views of {}", s.data.display()))?;
    let features = s.data.join("features");
    let channels = if kind == ModelKind::Integrated && features.is_dir() {
        data.load_features(&features)
            .with_context(|| format!("loading feature maps from {}", features.display()))?
    } else {
        0
    };
    let (w, h) = data.resolution();
    eprintln!(
        "{}: {} training views ({w}x{h}) in {:.1} s{}",
        s.name,
        data.len(),
        t0.elapsed().as_secs_f64(),
        if channels > 0 { format!(", {channels}-channel feature maps") } else { String::new() }
    );
    let (aabb, source) = scene_bounds(cams.scene_box, data.format, &cams.cameras(), &[], None)?;
    s.info = match stored {
        Some(i) => FieldInfo { history: None, val_history: None, ..i },
        None => FieldInfo {
            dataset: Some(data.root.clone()),
            ground_transform: None,
            background: Some(bg),
            downscale: Some(downscale),
            ..FieldInfo::default()
        },
    };
    Ok(Loaded { data, aabb, source, channels })
}

/// The joint run continued from every scene's checkpoint.
fn resume_joint(a: &TrainArgs, scenes: &[Scene], loaded: &[Loaded]) -> Result<JointTrainer> {
    let seconds = a.minutes.map(|m| m * 60.0);
    let data: Vec<&Dataset> = loaded.iter().map(|l| &l.data).collect();
    let ckpts: Vec<&Path> = scenes.iter().map(|s| s.ckpt.as_path()).collect();
    let j =
        JointTrainer::resume(&data, &ckpts, a.iters, seconds).context("resuming the joint run")?;
    eprintln!(
        "resuming {} scenes at iteration {} ({} trained)",
        scenes.len(),
        j.iter(),
        fmt_duration(j.elapsed())
    );
    Ok(j)
}

/// A new joint run: one configuration per scene on the joint grid, recorded in the scenes'
/// `info`.
fn start_joint(
    a: &TrainArgs,
    scenes: &mut [Scene],
    loaded: &[Loaded],
    kind: ModelKind,
    res: usize,
    background: [f32; 3],
) -> Result<JointTrainer> {
    let boxes: Vec<Aabb3> = loaded.iter().map(|l| l.aabb).collect();
    let mut template = FieldConfig::new(kind, boxes[0], res);
    if a.decoder == Some(DecoderArg::Sh) {
        template.decoder = DecoderKind::Sh { degree: 2 };
    }
    template.semantic_channels = loaded[0].channels;
    let configs = joint_configs(&template, &boxes, res)?;
    for ((s, c), l) in scenes.iter_mut().zip(&configs).zip(loaded) {
        c.validate(&s.field)
            .with_context(|| format!("the field of {} cannot be trained", s.name))?;
        eprintln!(
            "{}: box {} .. {} ({}, grown to the joint grid), plane {} x {}",
            s.name,
            fmt_vec(c.aabb[0]),
            fmt_vec(c.aabb[1]),
            l.source,
            c.res[0],
            c.res[1]
        );
        s.info.aabb = Some(c.aabb);
        s.info.aabb_source = Some(format!("{}; joint grid of {} scenes", l.source, configs.len()));
    }
    let v = configs[0].voxel_size();
    eprintln!(
        "shared: texel {:.4}, vertical axis {} samples over z {:.3} .. {:.3}, distance scale {:.3}",
        v.x,
        configs[0].res[2],
        configs[0].aabb[0][2],
        configs[0].aabb[1][2],
        configs[0].distance_scale
    );
    let tc = train_config(a, kind, res, background);
    let pairs: Vec<(&Dataset, FieldConfig)> = loaded.iter().map(|l| &l.data).zip(configs).collect();
    Ok(JointTrainer::new(&pairs, &tc)?)
}

/// Every scene's checkpoint, with its record.
fn save_checkpoints(j: &JointTrainer, scenes: &[Scene]) -> Result<()> {
    for (t, s) in j.scenes.iter().zip(scenes) {
        save_checkpoint(t, &s.info, &s.ckpt)?;
    }
    Ok(())
}

/// What one session of the joint run did.
struct JointSession {
    /// Iterations trained in this session.
    done: u64,
    seconds: f64,
    /// Every scene's last batch PSNR.
    last_psnr: Vec<f32>,
    /// Rays per iteration over all scenes.
    rays: f64,
}

/// Train until the budget is spent, with the progress bar and periodic checkpoints; Ctrl-C
/// saves the checkpoints and ends with an error that says how to resume.
fn joint_loop(joint: &mut JointTrainer, scenes: &[Scene], a: &TrainArgs) -> Result<JointSession> {
    let limit_iters =
        (joint.scenes[0].config.iters != u64::MAX).then_some(joint.scenes[0].config.iters);
    if joint.finished() {
        eprintln!(
            "the checkpoints have already reached their limit ({} iterations); pass a larger --iters or --minutes to train longer",
            joint.iter()
        );
    }
    let pb = training_bar(limit_iters);
    let start_iter = joint.iter();
    let session = Instant::now();
    let mut last_ckpt = Instant::now();
    let every = Duration::from_secs_f64(a.checkpoint_every_minutes * 60.0);
    let mut step_time = 0.0f64;
    let mut last_psnr: Vec<f32> =
        joint.scenes.iter().map(|t| t.history.last().map_or(f32::NAN, |h| h.2)).collect();
    let rays = (joint.scenes[0].config.batch * scenes.len()) as f64;
    while !joint.finished() {
        if interrupt::requested() {
            pb.finish_and_clear();
            save_checkpoints(joint, scenes)?;
            let data: Vec<String> = a.data.iter().map(|d| d.display().to_string()).collect();
            return Err(anyhow!(
                "interrupted at iteration {}: checkpoints saved in {}; no field file was written. Continue with: assetfield train {} --out {} --resume",
                joint.iter(),
                a.out.display(),
                data.join(" "),
                a.out.display()
            ));
        }
        let stats = joint.step();
        last_psnr = stats.iter().map(|s| s.psnr).collect();
        let k = if step_time == 0.0 { 1.0 } else { 0.05 };
        step_time += k * (stats[0].seconds - step_time);
        if !every.is_zero() && last_ckpt.elapsed() >= every {
            save_checkpoints(joint, scenes)?;
            last_ckpt = Instant::now();
        }
        let it = joint.iter();
        let left =
            time_left(limit_iters, it, step_time, joint.scenes[0].config.seconds, joint.elapsed());
        let psnrs: Vec<String> = last_psnr.iter().map(|p| format!("{p:.2}")).collect();
        pb.set_position((joint.progress() * 1000.0) as u64);
        pb.set_message(format!(
            "it {it}{} | psnr {} | {:.2} M rays/s | plane {} | left {}",
            limit_iters.map(|n| format!("/{n}")).unwrap_or_default(),
            psnrs.join(" / "),
            rays / step_time.max(1e-9) / 1e6,
            joint.scenes[0].field.config.res[0].max(joint.scenes[0].field.config.res[1]),
            fmt_duration(left)
        ));
    }
    pb.finish_and_clear();
    Ok(JointSession {
        done: joint.iter() - start_iter,
        seconds: session.elapsed().as_secs_f64(),
        last_psnr,
        rays,
    })
}

/// The closing lines: the run, every scene's field, the shared tensors' hash.
fn report_joint(
    joint: &JointTrainer,
    scenes: &[Scene],
    session: &JointSession,
    a: &TrainArgs,
    kind: ModelKind,
) -> Result<()> {
    let (done, session_s) = (session.done, session.seconds);
    println!(
        "trained {} scenes together ({}) for {} iterations in {} ({} this session{})",
        scenes.len(),
        kind.name(),
        joint.iter(),
        fmt_duration(joint.elapsed()),
        fmt_duration(session_s),
        if done > 0 && session_s > 0.0 {
            format!(", {:.2} M rays/s", done as f64 * session.rays / session_s / 1e6)
        } else {
            String::new()
        }
    );
    let hash = shared_hash(&joint.scenes[0].field)?;
    for ((t, s), p) in joint.scenes.iter().zip(scenes).zip(&session.last_psnr) {
        let c = &t.field.config;
        println!(
            "{}: final batch PSNR {p:.2} dB, plane {}x{}, vertical axis {}: wrote {}",
            s.name,
            c.res[0],
            c.res[1],
            c.res[2],
            s.field.display()
        );
        debug_assert_eq!(shared_hash(&t.field)?, hash);
    }
    println!("shared tensors {hash} (the same in every field)");
    if !a.discard_checkpoint {
        println!("checkpoints in {} (extend the run with --resume --iters N)", a.out.display());
    }
    Ok(())
}
