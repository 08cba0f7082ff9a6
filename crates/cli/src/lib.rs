//! The `assetfield` command line: argument parsing (clap), progress bars, Ctrl-C handling
//! and error reporting around the library crates. `anyhow` is used here and only here.

/// `eprintln!` for the whole command line, without its panic: a message to a closed standard
/// error (`assetfield edit LIB 2>&1 | head -1` once `head` has its line) is dropped and the
/// job goes on. The standard macro panics there, and a panic in the signal handler's thread
/// left the process deaf to Ctrl-C and SIGTERM. Defined before the modules, it shadows the
/// standard macro in all of them.
macro_rules! eprintln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

mod commands;

use clap::{Parser, Subcommand};
use std::ffi::OsString;

pub use commands::{
    BenchArgs, ComposeArgs, DemoArgs, DemoStep, EditArgs, EvalArgs, InspectArgs, LayoutArgs,
    LibraryArgs, MineArgs, PlanesArgs, RefineArgs, RenderArgs, SynthArgs, TrainArgs, demo_plan,
};

/// AssetField: editable neural scenes on ground feature planes.
///
/// Multi-view photos of a man-made scene (rooms, halls, streets) become a radiance field
/// factorised into bird's-eye-view ground feature planes; objects are mined from the planes
/// into an asset library and recomposed into new layouts. Scene layouts are written as RON
/// scripts (see scenes/ and ARCHITECTURE.md); world Z is up and the ground is the XY plane.
#[derive(Debug, Parser)]
#[command(
    name = "assetfield",
    version,
    about,
    long_about,
    propagate_version = true,
    max_term_width = 100
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Raise (or lower) a limit for this run: what a layout script may ask for (instances,
    /// scatter-tries, region-points, include-depth, file-loads, script-bytes; the environment
    /// variables ASSETFIELD_MAX_* set the same, this flag wins) or how large a field may be
    /// (plane-res: samples per plane side, default 4096; parameters: values of all its
    /// tensors, default 2^31). E.g. --limit instances=5000000; repeat for several.
    #[arg(long = "limit", value_name = "NAME=N", global = true, value_parser = parse_limit)]
    pub limits: Vec<LimitSetting>,
}

/// One `--limit NAME=N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitSetting {
    /// A limit of the layout language.
    Script(assetfield_layout::Limit, u64),
    /// Samples per plane side (and along the vertical axis) of a field.
    PlaneRes(u64),
    /// Values of all a field's tensors together.
    Parameters(u64),
}

impl LimitSetting {
    /// Put the setting in force for the rest of this process.
    fn install(self) {
        use assetfield_field::config::set_size_limits_for_process;
        match self {
            LimitSetting::Script(limit, v) => assetfield_layout::Limits::set_for_process(limit, v),
            LimitSetting::PlaneRes(v) => set_size_limits_for_process(Some(v), None),
            LimitSetting::Parameters(v) => set_size_limits_for_process(None, Some(v)),
        }
    }
}

/// `NAME=N` of `--limit`.
fn parse_limit(s: &str) -> Result<LimitSetting, String> {
    use assetfield_layout::Limit;
    let names = || {
        let mut v: Vec<&str> = Limit::ALL.iter().map(|l| l.flag_name()).collect();
        v.extend(["plane-res", "parameters"]);
        v.join(", ")
    };
    let (name, value) =
        s.split_once('=').ok_or_else(|| format!("expected NAME=N (NAME one of {})", names()))?;
    let n: u64 =
        value.trim().parse().map_err(|_| format!("{value:?} is not a whole number >= 0"))?;
    match name.trim() {
        "plane-res" => Ok(LimitSetting::PlaneRes(n)),
        "parameters" => Ok(LimitSetting::Parameters(n)),
        other => Limit::from_flag_name(other)
            .map(|l| LimitSetting::Script(l, n))
            .ok_or_else(|| format!("unknown limit {name:?} (one of {})", names())),
    }
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// The whole pipeline on the built-in default scene (scenes/conference_room.ron), from
    /// the repository root: synthesise the dataset and an edited version, train an
    /// S-AssetField (--iters, 6000 by default), evaluate, draw the planes, mine the asset
    /// library, compose the edit from it and compare with the ground truth, and render a
    /// turntable of the composed scene. Everything lands in --out (runs/demo).
    Demo(DemoArgs),
    /// Render a layout script into a multi-view NeRF-synthetic dataset with its ground truth.
    ///
    /// Writes transforms_train.json / transforms_test.json with RGBA PNGs under train/ and
    /// test/ (50 views on the upper half-sphere, 40 train / 10 test by default, as in the
    /// paper), gt_layout.json (every object's category, position, yaw, scale, box and support),
    /// layout.png (a bird's-eye view of the ground truth) and synth.json (settings, timings).
    /// With --edited, a second layout is rendered from the same test cameras into DIR/edited/.
    Synth(SynthArgs),
    /// Describe a dataset: views, resolution, focal length, camera bounds, plus a picture of
    /// the camera positions seen from above.
    ///
    /// Reads NeRF-synthetic (transforms_{train,val,test}.json), nerfstudio / instant-ngp
    /// (transforms.json) and COLMAP folders (a sparse model in sparse/0/ or nerfstudio's
    /// colmap/sparse/0/, binary or text, photos in images/). Images are checked for existence
    /// and size.
    Inspect(InspectArgs),
    /// Check a layout script without rendering: resolve it and list every instance with its
    /// id, key, category and world transform; optionally draw it from above.
    ///
    /// Every command that reads a script holds it to limits: instances per script
    /// (ASSETFIELD_MAX_INSTANCES, default 1000000), scatter tries (ASSETFIELD_MAX_SCATTER_TRIES),
    /// points of a scatter region (ASSETFIELD_MAX_REGION_POINTS), base/include nesting
    /// (ASSETFIELD_MAX_INCLUDE_DEPTH) and file loads (ASSETFIELD_MAX_FILE_LOADS), and bytes per
    /// file (ASSETFIELD_MAX_SCRIPT_BYTES); set the variable, or pass --limit NAME=N, to raise one.
    Layout(LayoutArgs),
    /// Train a radiance field on ground feature planes from a dataset.
    ///
    /// S-AssetField (--model s), I-AssetField (i) or the TensoRF-VM baseline (vm), Z up, planes
    /// on the ground (XY). Shows a progress bar (iteration, loss, batch PSNR, rays/s, plane
    /// resolution, time left); saves a checkpoint next to the output every few minutes, on
    /// Ctrl-C (exit 130; continue with --resume) and at the end. Writes the field file
    /// (safetensors: tensors, model config and metadata: training history, dataset, box,
    /// background, ground alignment) only when training is complete.
    Train(TrainArgs),
    /// Render held-out views with a trained field and measure PSNR and SSIM.
    ///
    /// Writes DIR/metrics.json (mean psnr and ssim, per-view values, seconds per view, model,
    /// resolution), DIR/render/r_K.png and DIR/error/r_K.png (absolute error, dark = exact,
    /// yellow >= 0.25). SSIM as TensoRF / mip-NeRF: 11x11 Gaussian window, sigma 1.5.
    /// Photos whose exposure varies are also scored as NeRF-W scores them: an affine colour
    /// map (12 numbers) fitted by least squares on each view's left half, PSNR and SSIM on
    /// its right half (psnr_fitted, ssim_fitted).
    Eval(EvalArgs),
    /// Render a trained field from a dataset's cameras or on a turntable into PNGs.
    Render(RenderArgs),
    /// Draw a field's ground feature planes and training curve (the paper's Fig. 3).
    ///
    /// density.png (max opacity over each vertical column), density_pca.png and color_pca.png
    /// (PCA false colour of the ground planes; for VM the XY planes, for I-AssetField the
    /// integrated colour plane), curve.png (PSNR against seconds) and planes.json. Seen from
    /// above: +x right, +y up.
    Planes(PlanesArgs),
    /// Mine a trained field's ground planes into an asset library and a layout (paper Sec.
    /// 3.2-3.4).
    ///
    /// Detection: the floor slab is found from the density volume and removed, walls are
    /// dropped as thin long structures, per texel the opacity above the floor is split with
    /// K-means (--k), specks are dropped and Suzuki-Abe contours give regions; touching
    /// objects are separated (thin bridges, 3D connectivity, colour boundaries), and a
    /// second round inside every object treats its top surface as
    /// background to find objects standing on it. Grouping: K-means labels of the colour
    /// plane (--labels), label histograms, Jensen-Shannon divergence plus a size term and
    /// the divergence of the objects' vertical profiles, average-linkage clustering cut where
    /// groups are at least the minimum separation apart (or --auto-cut, --categories,
    /// --distance). Identical objects pushed together are cut apart when the same object
    /// stands alone elsewhere (--no-copies). Templates: the member of each category that
    /// fits its copies best (--template to choose); every instance's yaw and position come
    /// from rotating the template patch onto it. Writes LIB_DIR/index.ron,
    /// patches.safetensors, shared.safetensors, layout.ron, boxes.png, categories.png,
    /// mining.json and, with --gt, metrics.json. Every detection threshold is in plane
    /// texels or volume levels, never in world units, so captures in any unit mine alike;
    /// --preset paper runs only the paper's steps. Set ASSETFIELD_LOG=assetfield_mining=debug
    /// to see each decision of the detector on stderr.
    Mine(MineArgs),
    /// Check asset libraries or merge them into a cross-scene library (`library check LIB`,
    /// `library merge LIB_A LIB_B ... --out LIB_C`).
    Library(LibraryArgs),
    /// Compose a layout script from an asset library and render it (paper Sec. 3.4).
    ///
    /// The library's shared axes and decoders become the scene's field, its container (a
    /// trained scene with the objects removed; `--canvas empty` for nothing) the canvas.
    /// Every instance of the script is an entity of an ECS world (bevy_ecs) whose systems
    /// rasterise the instances' feature patches onto the ground planes (density summed,
    /// colour weighted by density); the composed planes are volume-rendered from --views
    /// cameras or a turntable. Object edits (Move, Rotate, Scale, Remove, Duplicate),
    /// category edits (ReplaceAsset, RemoveCategory) and scenes from library assets are all
    /// written in the script. Errors name the script line. Writes the renders, compose.json,
    /// layout.png and, with --metrics, metrics.json against the --views images.
    Compose(ComposeArgs),
    /// Refine a library's templates against its scene's training views (paper Sec. 3.4).
    ///
    /// Every instance is drawn with its category's template patch, posed as mining found
    /// it; only the template patches are optimised (Adam on the exact gradient of the
    /// rendered colour, through the composition) so that the composed scene reproduces the
    /// training views. Axes, decoders, poses and the container stay fixed. Writes a new
    /// library whose layout.ron draws every instance with its template (what `compose` reads
    /// like any other), and refine.json with the test-view PSNR of the mined layout (own
    /// patches) and of the templates-only layout before and after. The dataset must be the
    /// library's scene: views that do not look into its box are refused.
    Refine(RefineArgs),
    /// Edit a library's layout in the browser: a local web server and its page.
    ///
    /// The page shows the bird's-eye view (the composed ground plane with every instance's
    /// footprint: click to select, drag to move, Q/E or the handle to turn, Shift for 15
    /// degree steps, Delete, Ctrl-D to duplicate, +/- to scale), a 3D view rendered from an
    /// orbit camera after every edit (a coarse preview first), the library's assets and
    /// categories (insert, replace a category's template, remove a category), undo / redo,
    /// the edit log as RON (the language `compose --edits` reads) and Save. The first line
    /// on stdout is the page's URL with its token; the same token guards the HTTP API
    /// (GET /api/layout, POST /api/edits, /api/undo, /api/redo, GET /api/render,
    /// /api/bev, POST /api/save) for scripts. Binds 127.0.0.1 unless --host says otherwise.
    Edit(EditArgs),
    /// Measure composed-scene rendering and re-composition on the GPU or the CPU
    /// (`bench render`, `bench reconfigure`).
    ///
    /// `bench render`: milliseconds per --res x --res frame of a scene of --instances
    /// instances, rays per second, and layouts per second for a --batch of random layouts
    /// rendered from --views cameras in one go. `bench reconfigure`: for each --instances
    /// count, --layouts random layouts (moves, turns, template swaps) rasterised and rendered
    /// (layouts per second), and one instance moved (dirty rectangles) against every texel
    /// redrawn. The scene is synthetic (a floor and two furniture templates in a 30 x 30 m
    /// box; see `assetfield_gpu::bench_scene`) or, with --library, a mined library's
    /// container and templates. --backend auto (the default) uses the GPU when a wgpu adapter
    /// exists, else the CPU after one line on stderr; --json prints one JSON object.
    Bench(BenchArgs),
}

impl Cli {
    /// Parse a command line (first = program name); a usage error becomes an error.
    pub fn try_parse_from_args(args: &[&str]) -> anyhow::Result<Cli> {
        Cli::try_parse_from(args).map_err(|e| anyhow::anyhow!("{e}"))
    }
}

/// Run the CLI on the given arguments (first = program name); returns the exit code:
/// 0 success, 1 failure, 2 bad usage, 130 interrupted by Ctrl-C.
pub fn main_with_args(args: impl IntoIterator<Item = impl Into<OsString> + Clone>) -> i32 {
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    for setting in &cli.limits {
        setting.install();
    }
    install_ctrlc();
    install_broken_pipe_exit();
    install_logging();
    match run(cli) {
        Ok(()) => 0,
        Err(e) => {
            let interrupted = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<assetfield_core::CoreError>(),
                    Some(assetfield_core::CoreError::Interrupted)
                )
            }) || assetfield_core::interrupt::requested();
            eprintln!("error: {e}");
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            if interrupted { 130 } else { 1 }
        }
    }
}

/// Diagnostics of the library crates (`tracing`) go to stderr when the environment variable
/// `ASSETFIELD_LOG` asks for them, in `tracing_subscriber`'s filter syntax: e.g.
/// `ASSETFIELD_LOG=assetfield_mining=debug assetfield mine ...` prints the detector's
/// decisions. Unset: nothing is printed.
fn install_logging() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let Some(spec) = std::env::var_os("ASSETFIELD_LOG") else { return };
        let filter = match tracing_subscriber::EnvFilter::try_new(spec.to_string_lossy()) {
            Ok(f) => f,
            Err(e) => {
                eprintln!("warning: ASSETFIELD_LOG is not a valid filter ({e}); no diagnostics");
                return;
            }
        };
        let _ = tracing_subscriber::fmt()
            .with_env_filter(filter)
            .with_writer(std::io::stderr)
            .with_target(false)
            .try_init();
    });
}

/// Ctrl-C (SIGINT), SIGTERM (`kill`, a container stopping, a batch system's time limit) and
/// SIGHUP (the terminal closing) all ask the running job to stop cleanly: `train` saves a
/// checkpoint, other jobs discard their staged output.
fn install_ctrlc() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // A second signal while a job winds down exits at once; outputs are staged, so
        // nothing half-written is left in place either way.
        // The request comes first and the note cannot panic: whatever happens to standard
        // error, the job hears the signal.
        let _ = ctrlc::set_handler(|| {
            if assetfield_core::interrupt::requested() {
                std::process::exit(130);
            }
            assetfield_core::interrupt::request();
            eprintln!("\ninterrupt: finishing the current step and discarding partial output (Ctrl-C again to quit now)");
        });
    });
}

/// A reader that stops early (`assetfield layout X | head -1`) closes the pipe; Rust ignores
/// SIGPIPE, so the next `println!` panics. That is no failure of ours: the reader has what it
/// wanted, so the process ends quietly with status 0, as it would have if the output had fit.
/// Every other panic keeps the default report.
fn install_broken_pipe_exit() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let message = info
                .payload()
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| info.payload().downcast_ref::<&str>().copied())
                .unwrap_or("");
            if is_broken_stdout(message) {
                // an interrupted job still says so in its status
                std::process::exit(if assetfield_core::interrupt::requested() { 130 } else { 0 });
            }
            default(info);
        }));
    });
}

/// Whether a panic message is the standard library's report of a closed standard output.
fn is_broken_stdout(message: &str) -> bool {
    message.starts_with("failed printing to stdout") && message.contains("Broken pipe")
}

/// Run a parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Demo(a) => commands::demo(a),
        Command::Synth(a) => commands::synth(a),
        Command::Inspect(a) => commands::inspect(a),
        Command::Layout(a) => commands::layout(a),
        Command::Train(a) => commands::train(a),
        Command::Eval(a) => commands::eval(a),
        Command::Render(a) => commands::render(a),
        Command::Compose(a) => commands::compose(a),
        Command::Refine(a) => commands::refine(a),
        Command::Edit(a) => commands::edit(a),
        Command::Bench(a) => commands::bench(a),
        Command::Planes(a) => commands::planes(a),
        Command::Mine(a) => commands::mine(a),
        Command::Library(a) => commands::library(a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn only_a_closed_stdout_counts_as_a_broken_pipe() {
        assert!(is_broken_stdout("failed printing to stdout: Broken pipe (os error 32)"));
        assert!(!is_broken_stdout("failed printing to stdout: No space left on device"));
        assert!(!is_broken_stdout("index out of bounds: Broken pipe"));
    }

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }
}
