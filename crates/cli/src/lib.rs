//! The `assetfield` command line: argument parsing (clap), progress bars, Ctrl-C handling
//! and error reporting around the library crates. `anyhow` is used here and only here.

mod commands;

use clap::{Parser, Subcommand};
use std::ffi::OsString;

pub use commands::{InspectArgs, LayoutArgs, SynthArgs};

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
}

#[derive(Debug, Subcommand)]
pub enum Command {
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
    /// Reads NeRF-synthetic (transforms_{train,val,test}.json) and nerfstudio / instant-ngp
    /// (transforms.json) folders. Images are checked for existence and size.
    Inspect(InspectArgs),
    /// Check a layout script without rendering: resolve it and list every instance with its
    /// id, key, category and world transform; optionally draw it from above.
    Layout(LayoutArgs),
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
    install_ctrlc();
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

fn install_ctrlc() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // A second Ctrl-C while a job winds down exits at once; outputs are staged, so
        // nothing half-written is left in place either way.
        let _ = ctrlc::set_handler(|| {
            if assetfield_core::interrupt::requested() {
                std::process::exit(130);
            }
            eprintln!("\ninterrupt: finishing the current step and discarding partial output (Ctrl-C again to quit now)");
            assetfield_core::interrupt::request();
        });
    });
}

/// Run a parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Synth(a) => commands::synth(a),
        Command::Inspect(a) => commands::inspect(a),
        Command::Layout(a) => commands::layout(a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }
}
