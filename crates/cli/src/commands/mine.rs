//! `assetfield mine`: detect, group and pose the objects of a trained field and write an
//! asset library with the mined layout; `assetfield library`: check and merge libraries.

use super::util::progress_bar;
use anyhow::{Context, Result, bail};
use assetfield_layout::GtLayout;
use assetfield_library::open_library;
use assetfield_mining::agglomerative::Linkage;
use assetfield_mining::detect::{DetectParams, Filters, Preset};
use assetfield_mining::group::GroupCut;
use assetfield_mining::merge::{MergeOptions, merge_libraries_with};
use assetfield_mining::pipeline::{GroupOn, MineOptions, Progress, YawOn, mine as run_mining};
use assetfield_mining::planes::PlaneChoice;
use assetfield_mining::regroup::RegroupOptions;
use clap::{Args, Subcommand, ValueEnum};
use indicatif::ProgressBar;
use std::path::PathBuf;

/// A ground plane to work on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PlaneArg {
    /// The density field (detection: per column, the opacity above the floor).
    Density,
    /// The colour plane (I-AssetField: the integrated RGB plane).
    Color,
    /// The semantic features of an I-AssetField trained with feature maps.
    Semantic,
}

impl PlaneArg {
    fn choice(self) -> PlaneChoice {
        match self {
            PlaneArg::Density => PlaneChoice::Density,
            PlaneArg::Color => PlaneChoice::Color,
            PlaneArg::Semantic => PlaneChoice::Semantic,
        }
    }
}

/// What the grouping's label histograms are built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GroupOnArg {
    /// The colour plane (I-AssetField: the integrated RGB plane).
    Color,
    /// The semantic features of an I-AssetField trained with feature maps.
    Semantic,
    /// The density plane.
    Density,
    /// The decoded colours of each object's own surface voxels.
    Voxels,
}

impl GroupOnArg {
    fn choice(self) -> GroupOn {
        match self {
            GroupOnArg::Voxels => GroupOn::Voxels,
            GroupOnArg::Color => GroupOn::Color,
            GroupOnArg::Semantic => GroupOn::Semantic,
            GroupOnArg::Density => GroupOn::Density,
        }
    }
}

/// `--yaw-on`: what template matching compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum YawOnArg {
    /// Voxels for categories with a member standing on another object, density otherwise.
    Auto,
    /// The density plane.
    Density,
    /// The colour plane.
    Color,
    /// The semantic plane (I-AssetField trained with feature maps).
    Semantic,
    /// Each object's own voxels, for every category.
    Voxels,
}

impl YawOnArg {
    fn choice(self) -> YawOn {
        match self {
            YawOnArg::Auto => YawOn::Auto,
            YawOnArg::Density => YawOn::Density,
            YawOnArg::Color => YawOn::Color,
            YawOnArg::Semantic => YawOn::Semantic,
            YawOnArg::Voxels => YawOn::Voxels,
        }
    }
}

#[derive(Debug, Args)]
pub struct MineArgs {
    /// The field file written by `assetfield train` (S- or I-AssetField; TensoRF-VM fields
    /// have no ground plane representation and are refused).
    pub field: PathBuf,
    /// The library folder to write: index.ron, patches.safetensors, shared.safetensors,
    /// layout.ron, boxes.png, categories.png, mining.json (and metrics.json with --gt).
    /// Written atomically: it appears only when complete.
    #[arg(long, short, value_name = "LIB_DIR")]
    pub out: PathBuf,
    /// Ground-truth layout (gt_layout.json written by `assetfield synth`): writes
    /// metrics.json (precision, recall, f1 at BEV IoU >= --iou, ari, yaw_median_deg,
    /// yaw_max_deg, position_median, per category and per instance) and prints a summary.
    #[arg(long, value_name = "GT_LAYOUT")]
    pub gt: Option<PathBuf>,
    /// Start from a preset: default (every stage of the detector) or paper (only the
    /// paper's steps: K-means on the density feature plane with the largest cluster as
    /// background, contours, and a second K-means inside each box with its dominant
    /// surface as background; grouping on the colour plane, yaw on the density plane). The
    /// flags below change the preset's values.
    #[arg(long, value_enum, default_value = "default")]
    pub preset: PresetArg,
    /// Which plane the first K-means runs on: density (per texel, the opacity of the
    /// densest few levels of the column above the floor; the paper preset: the density
    /// plane's features), color or semantic (K-means on the plane features, the largest
    /// cluster is background).
    #[arg(long, value_enum)]
    pub detect_on: Option<PlaneArg>,
    /// Clusters of the first K-means (2 as in the paper; more keeps fainter objects, the
    /// lowest cluster is always background).
    #[arg(long, default_value_t = 2)]
    pub k: usize,
    /// Smallest object footprint in plane texels (smaller specks are dropped; at the
    /// default 300-texel plane, 25 texels is 0.02 m^2 in an 8 m room). An object standing
    /// alone may be smaller, down to 0.64 of it (`min_lone_area_share` in a
    /// --detect-params file). Texels, not world units: captures come in any unit.
    #[arg(long, value_name = "TEXELS")]
    pub min_area: Option<usize>,
    /// Do not look for a floor slab (measure the evidence over the whole column).
    #[arg(long)]
    pub no_floor: bool,
    /// Half the thickness of the thickest wall of a room shell, in plane texels: thin,
    /// long structures up to twice this are dropped as walls (0 keeps them).
    #[arg(long, value_name = "TEXELS")]
    pub wall_half_thickness: Option<f32>,
    /// Switch off one of the detector's filters (repeatable; `mining.json` names the
    /// filter that removed each region): walls (thin, long structures), duplicates (an
    /// object found both on the ground and standing on its host).
    #[arg(long, value_name = "FILTER", value_parser = clap::builder::PossibleValuesParser::new(assetfield_mining::detect::Filters::NAMES))]
    pub no_filter: Vec<String>,
    /// Skip the second round inside every object (objects standing on tables are then not
    /// separated from them).
    #[arg(long)]
    pub no_unpack: bool,
    /// Do not separate objects that touch in the bird's-eye view (thin bridges, 3D
    /// connectivity, colours and heights).
    #[arg(long)]
    pub no_split: bool,
    /// Keep every object's box where its evidence passes the threshold: do not grow an
    /// object by the faint fringe that reaches past its edge's blur (a plant's thin leaves
    /// around its dense crown). Off with --preset paper.
    #[arg(long)]
    pub no_fringe: bool,
    /// Read every detection value from FILE (JSON: the `detect` object of a `mining.json`'s
    /// `options`, edited), instead of the preset's; the flags above and below still apply on
    /// top. For sensitivity studies: which value decides what on a scene.
    #[arg(long, value_name = "FILE")]
    pub detect_params: Option<PathBuf>,
    /// Do not cut a detection that is, in shape and colour, two or three copies of another
    /// detection into that many objects (identical objects pushed together leave no seam in
    /// the field; their repetition elsewhere in the scene tells them apart). Off with
    /// --preset paper.
    #[arg(long)]
    pub no_copies: bool,
    /// Do not join two categories whose members pair up one to one, each touching its
    /// partner in the same placement, into one object per pair (a two-tone object that the
    /// colour split cut in two, every copy the same way). Off with --preset paper.
    #[arg(long)]
    pub no_halves: bool,
    /// Number of labels the grouping features are discretised into (K-means over the
    /// objects' texels or voxels, weighted by opacity).
    #[arg(long, default_value_t = assetfield_mining::group::GroupOptions::default().labels)]
    pub labels: usize,
    /// Number of categories [default: automatic, see --auto-cut].
    #[arg(long, conflicts_with = "distance")]
    pub categories: Option<usize>,
    /// How the number of categories is chosen when neither --categories nor --distance is
    /// given: separation (every group of objects at least the minimum separation, 0.25,
    /// apart is a category), silhouette (among those cuts, the one of highest mean
    /// silhouette: each object's distance to its own category against the nearest other one)
    /// or largest-ratio (where the next merge height is largest relative to the previous
    /// one). Either way, groups closer than the minimum separation are one category.
    /// [default: separation; silhouette with --preset paper, as its tables were measured]
    #[arg(long, value_enum)]
    pub auto_cut: Option<AutoCutArg>,
    /// Cut the dendrogram at this distance (JSD in bits plus the shape term) instead.
    #[arg(long, value_name = "T")]
    pub distance: Option<f64>,
    /// Weight of the shape term of the grouping distance (footprint area, height and
    /// elongation log ratios beyond a tolerance; separates objects of the same colours but
    /// different sizes or outlines). 0 = label histograms only, as in the paper.
    #[arg(long, default_value_t = 1.0)]
    pub shape_weight: f64,
    /// Weight of the vertical-profile term of the grouping distance: the Jensen-Shannon
    /// divergence of how two objects' occupied voxels spread over the levels above their
    /// bases (a round table and a plant of one size and colour differ there). 0 = off.
    /// [default: 1; 0 with --preset paper]
    #[arg(long)]
    pub profile_weight: Option<f64>,
    /// Linkage of the agglomerative clustering: average, single or complete.
    #[arg(long, value_enum, default_value = "average")]
    pub linkage: LinkageArg,
    /// What is discretised for grouping. voxels (default): the colours the field decodes on
    /// each object's own surface voxels from its base to its top, so that copies look alike
    /// whatever they stand on (a floor slab or beside it, a pallet or the floor). Or a
    /// plane's features over each object's own texels, each describing its whole column,
    /// the floor under the object included: color (the paper's choice, and --preset
    /// paper's), semantic or density.
    #[arg(long, value_enum)]
    pub group_on: Option<GroupOnArg>,
    /// What is matched to find each instance's yaw. auto (default): the density plane's
    /// patches, whose shape (a car's cabin nearer its back) tells front from back where
    /// colours may not (on the suite's 3-minute fields the worst yaw errors drop from up to
    /// 180 to at most 16 degrees); but for categories with a member standing on another
    /// object, the objects' own voxels (the opacity of each level above the base), since
    /// a laptop's plane column also holds the table's legs and crossbars, which do not turn
    /// with it. density, color, semantic: that plane for every category; voxels: the own
    /// voxels for every category. [default: auto; density with --preset paper]
    #[arg(long, value_enum)]
    pub yaw_on: Option<YawOnArg>,
    /// Use detection INDEX (the number in boxes.png) as the template of CATEGORY (catK or
    /// K) instead of the member that fits its copies best. Repeatable.
    #[arg(long, value_name = "CATEGORY=INDEX")]
    pub template: Vec<String>,
    /// Margin around each object's box in its patches, in texels [default: the detection's
    /// vertical blur, 3 levels: a patch holds the blurred edge of its object].
    #[arg(long)]
    pub margin: Option<usize>,
    /// BEV IoU a detection needs to match a ground-truth box (with --gt).
    #[arg(long, default_value_t = 0.5)]
    pub iou: f32,
    /// Name the instances of layout.ron after the ground-truth keys they match (with
    /// --gt; e.g. `tables[2]`), so that an edit script written against the ground-truth
    /// scene applies unchanged to the mined layout (`base: "LIB/layout.ron"`).
    #[arg(long, requires = "gt")]
    pub gt_names: bool,
    /// In layout.ron, an instance whose template-matching residual (on the plane a layout
    /// places: density, for poses found on voxels) exceeds this many times the median of
    /// the residuals measured on the same plane keeps its own patch (its own asset, same
    /// category) instead of its category's template; with fewer than three residuals on a
    /// plane there is no median, and those instances keep their own patches. The default 0
    /// gives every instance its own patch: the layout reproduces the scene exactly and edits
    /// of it stay faithful. 2 uses the template where it fits (a compact layout; rotated
    /// templates lose some detail on thin parts), `inf` templates only (the paper's
    /// reconfiguration).
    #[arg(long, default_value_t = assetfield_mining::layout_out::OWN_PATCH_RESIDUAL, value_name = "R")]
    pub own_patch_residual: f32,
    /// Seed of the K-means runs.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Replace the library folder if it exists.
    #[arg(long)]
    pub force: bool,
}

/// `--preset`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PresetArg {
    /// Every stage of the detector.
    Default,
    /// Only the paper's steps (the baseline).
    Paper,
}

/// Agglomerative linkage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LinkageArg {
    Average,
    Single,
    Complete,
}

/// `--auto-cut`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AutoCutArg {
    /// Every group of objects at least the minimum separation (0.25) apart.
    Separation,
    /// The cut of highest mean silhouette.
    Silhouette,
    /// The largest ratio between consecutive merge heights.
    LargestRatio,
}

#[derive(Debug, Args)]
pub struct LibraryArgs {
    #[command(subcommand)]
    pub command: LibraryCommand,
}

#[derive(Debug, Subcommand)]
pub enum LibraryCommand {
    /// Check a library: index against tensors, shared tensors against their hash; list its
    /// categories.
    Check {
        /// The library folder.
        lib: PathBuf,
    },
    /// Merge libraries mined from fields that share their vertical axes, basis and
    /// decoders (scenes trained together: `train DATA_A DATA_B ...`, or fitted with `train
    /// --share`) into one cross-scene library (names get the source folder as a prefix:
    /// FOLDER/obj003). Libraries whose shared tensors differ are refused, naming the tensor
    /// and the files.
    Merge {
        /// Two or more library folders.
        #[arg(required = true, num_args = 2..)]
        libs: Vec<PathBuf>,
        /// The merged library folder.
        #[arg(long, short)]
        out: PathBuf,
        /// Unite categories across scenes: every entry is described as `mine` describes
        /// objects (colour-plane label histograms, shape, vertical profile) and categories of
        /// different scenes closer than mine's separation cut (average linkage) become one,
        /// so that one category spans scenes; a scene's own categories are never split or
        /// joined with each other. Templates are chosen and members posed anew. Without it
        /// every scene keeps its own categories.
        #[arg(long)]
        regroup: bool,
        /// One ground truth (gt_layout.json) per library, in the same order: OUT/metrics.json
        /// gets cross_scene_ari (ARI of the matched entries of all scenes together against
        /// their ground-truth categories) and every scene's precision, recall, F1 and ARI.
        #[arg(long, num_args = 1..)]
        gt: Vec<PathBuf>,
        /// BEV IoU an entry needs to match a ground-truth box (with --gt).
        #[arg(long, default_value_t = 0.5)]
        iou: f32,
        /// Replace the output folder if it exists.
        #[arg(long)]
        force: bool,
    },
}

struct Bar(ProgressBar);

impl Progress for Bar {
    fn step(&self, index: usize, _total: usize, what: &str) {
        self.0.set_position(index as u64);
        self.0.set_message(what.to_string());
    }
}

fn parse_template(s: &str) -> Result<(String, usize)> {
    let (c, i) = s.split_once('=').with_context(|| {
        format!("invalid --template {s:?}: expected CATEGORY=INDEX, e.g. cat1=7")
    })?;
    let i: usize = i
        .trim()
        .parse()
        .with_context(|| format!("invalid --template {s:?}: {i:?} is not a detection number"))?;
    Ok((c.trim().to_string(), i))
}

pub fn mine(a: MineArgs) -> Result<()> {
    if a.k < 2 {
        bail!("--k must be at least 2 (one background and one object cluster)");
    }
    if a.labels == 0 {
        bail!("--labels must be at least 1");
    }
    if a.categories == Some(0) {
        bail!("--categories must be at least 1");
    }
    if a.own_patch_residual.is_nan() || a.own_patch_residual < 0.0 {
        bail!("--own-patch-residual must be 0 or more (inf for templates only)");
    }
    if !(a.iou > 0.0 && a.iou <= 1.0) {
        bail!("--iou must be in (0, 1], got {}", a.iou);
    }
    if a.out.exists() && !a.force {
        bail!("{} already exists (pass --force to replace it)", a.out.display());
    }
    let preset = match a.preset {
        PresetArg::Default => Preset::Default,
        PresetArg::Paper => Preset::Paper,
    };
    let detect = match &a.detect_params {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read --detect-params {}", path.display()))?;
            serde_json::from_str::<DetectParams>(&text).with_context(|| {
                format!("--detect-params {}: not the JSON of the detection values", path.display())
            })?
        }
        None => DetectParams::preset(preset),
    };
    let mut o = MineOptions { detect, ..MineOptions::preset(preset) };
    if a.no_copies {
        o.group.split_copies = false;
    }
    if a.no_halves {
        o.group.join_halves = false;
    }
    if let Some(on) = a.detect_on {
        o.detect.on = on.choice();
    }
    o.detect.k = a.k;
    if let Some(m) = a.min_area {
        o.detect.min_area_texels = m;
    }
    if let Some(w) = a.wall_half_thickness {
        if !(w.is_finite() && w >= 0.0) {
            bail!("--wall-half-thickness must be 0 or more texels, got {w}");
        }
        o.detect.wall_half_thickness_texels = w;
    }
    if a.no_floor {
        o.detect.stages.floor = false;
    }
    if a.no_unpack {
        o.detect.stages.unpack = false;
    }
    if a.no_fringe {
        o.detect.stages.fringe = false;
    }
    if a.no_split {
        let s = &mut o.detect.stages;
        (s.split_bridges, s.split_3d, s.split_colour) = (false, false, false);
    }
    for f in &a.no_filter {
        if !o.detect.filters.set(f, false) {
            bail!("--no-filter {f}: unknown filter (one of {})", Filters::NAMES.join(", "));
        }
    }
    o.group.labels = a.labels;
    o.group.shape_weight = a.shape_weight;
    if let Some(w) = a.profile_weight {
        if !(w.is_finite() && w >= 0.0) {
            bail!("--profile-weight must be 0 or more, got {w}");
        }
        o.group.profile_weight = w;
    }
    o.group.linkage = match a.linkage {
        LinkageArg::Average => Linkage::Average,
        LinkageArg::Single => Linkage::Single,
        LinkageArg::Complete => Linkage::Complete,
    };
    o.group.cut = match (a.categories, a.distance) {
        (Some(n), _) => GroupCut::Categories(n),
        (None, Some(t)) => GroupCut::Distance(t),
        (None, None) => match a.auto_cut {
            None => o.group.cut,
            Some(AutoCutArg::Separation) => GroupCut::Separation,
            Some(AutoCutArg::Silhouette) => GroupCut::Silhouette,
            Some(AutoCutArg::LargestRatio) => GroupCut::LargestRatio,
        },
    };
    if let Some(g) = a.group_on {
        o.group_on = g.choice();
    }
    if let Some(y) = a.yaw_on {
        o.yaw_on = y.choice();
    }
    o.pose.margin = a.margin.unwrap_or(o.detect.blur_levels);
    o.templates = a.template.iter().map(|t| parse_template(t)).collect::<Result<_>>()?;
    o.gt = a.gt.clone();
    o.iou = a.iou;
    o.gt_names = a.gt_names;
    o.own_patch_residual = a.own_patch_residual;
    o.force = a.force;
    if let Some(seed) = a.seed {
        o.detect.seed = seed;
        o.group.seed = seed;
    }
    let pb = progress_bar(7, "mining");
    let report = run_mining(&a.field, &a.out, &o, &Bar(pb.clone()));
    pb.finish_and_clear();
    let r = report.with_context(|| format!("mining {} failed", a.field.display()))?;
    let copies = match r.copies_cut {
        0 => String::new(),
        1 => format!(", {} identical objects in contact cut apart", r.copies_pieces),
        n => format!(
            ", {} identical objects in contact cut apart from {n} detections",
            r.copies_pieces
        ),
    };
    let halves = match r.halves_joined {
        0 => String::new(),
        n => format!(", {n} joined from two halves"),
    };
    let fringes = match r.fringes_taken {
        0 => String::new(),
        n => format!(", {n} grown by a faint fringe"),
    };
    println!(
        "mined {} objects ({} standing on others{copies}{halves}{fringes}) in {} categories from {} ({}-assetfield) in {:.1}s",
        r.detections,
        r.supported,
        r.categories,
        a.field.display(),
        r.model,
        r.seconds
    );
    if let Some(note) = &r.content_note {
        println!("note: {note}");
    }
    match r.floor {
        Some(z) => println!("floor slab up to z = {z:.3}; evidence threshold {:.3}", r.threshold),
        None => println!("no floor slab; evidence threshold {:.3}", r.threshold),
    }
    for x in &r.removed {
        println!("background: {x}");
    }
    println!("grouping: {}", r.cut);
    println!(
        "wrote {}: index.ron, patches.safetensors, shared.safetensors, layout.ron ({} instances), boxes.png, categories.png, mining.json{}",
        r.out.display(),
        r.layout_instances,
        if r.metrics.is_some() { ", metrics.json" } else { "" }
    );
    if let Some(m) = &r.metrics {
        println!("{}", m.summary());
    }
    Ok(())
}

pub fn library(a: LibraryArgs) -> Result<()> {
    match a.command {
        LibraryCommand::Check { lib } => {
            // the loader `compose` uses (AssetLibrary::open runs exactly this check)
            let l = open_library(&lib)
                .with_context(|| format!("{} is not a valid asset library", lib.display()))?;
            let ix = &l.index;
            println!(
                "{}: {} ({}-assetfield), {} entries in {} categories, {} container(s), texel {:.4} x {:.4}, shared {}",
                lib.display(),
                ix.format,
                ix.model,
                ix.entries.len(),
                ix.categories.len(),
                ix.containers.len(),
                ix.texel_size.0,
                ix.texel_size.1,
                ix.shared.hash
            );
            for c in &ix.categories {
                println!("  {}: template {}, {} member(s)", c.name, c.template, c.members.len());
            }
            println!(
                "ok: the index, every patch and the shared tensors pass the check `compose` opens libraries with"
            );
            Ok(())
        }
        LibraryCommand::Merge { libs, out, regroup, gt, iou, force } => {
            if out.exists() && !force {
                bail!("{} already exists (pass --force to replace it)", out.display());
            }
            if !gt.is_empty() && gt.len() != libs.len() {
                bail!(
                    "--gt takes one ground truth per library, in the same order: {} libraries, {} ground truths",
                    libs.len(),
                    gt.len()
                );
            }
            if !(iou.is_finite() && iou > 0.0 && iou <= 1.0) {
                bail!("--iou must lie in (0, 1]");
            }
            let gts = gt
                .iter()
                .map(|p| {
                    GtLayout::read(p)
                        .with_context(|| format!("reading ground truth {}", p.display()))
                })
                .collect::<Result<Vec<_>>>()?;
            let opts = MergeOptions {
                regroup: regroup
                    .then(|| RegroupOptions::from_mining(&MineOptions::preset(Preset::Default))),
                gt: gts,
                iou_threshold: iou,
            };
            let r = merge_libraries_with(&libs, &out, force, &opts)
                .context("merging libraries failed")?;
            println!(
                "wrote {}: {} entries, {} categories{}, {} containers from {} libraries",
                r.out.display(),
                r.entries,
                r.categories,
                if regroup { " (grouped across scenes)" } else { "" },
                r.containers,
                libs.len()
            );
            if let Some(m) = &r.metrics {
                for s in &m.per_scene {
                    println!(
                        "  {}: {} entries, {}/{} matched, F1 {:.3}, ARI {:.3}",
                        s.library, s.entries, s.matched, s.ground_truth, s.f1, s.ari
                    );
                }
                println!(
                    "cross-scene ARI {:.3} over {} matched entries; {} of {} categories span scenes; {} of {} ground-truth categories found in several scenes are one category",
                    m.cross_scene_ari,
                    m.matched,
                    m.categories_spanning_scenes,
                    m.categories,
                    m.shared_gt_categories_united,
                    m.shared_gt_categories
                );
                println!("wrote {}", r.out.join("metrics.json").display());
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn templates_parse() {
        assert_eq!(parse_template("cat1=7").unwrap(), ("cat1".to_string(), 7));
        assert_eq!(parse_template(" 2 = 3 ").unwrap(), ("2".to_string(), 3));
        assert!(parse_template("cat1").is_err());
        assert!(parse_template("cat1=x").unwrap_err().to_string().contains("detection number"));
    }
}
