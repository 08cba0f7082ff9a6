//! The subcommands, one module per group (a command split over files is a folder: `train`
//! with its multi-scene `joint` part, `bench` with its `edit` bench); what several commands
//! share lives in `util` (progress bars, field loading, the dataset of a field, parsing) and
//! `backend` (`--backend`), never in another command.

mod backend;
mod bench;
mod compose;
mod demo;
mod edit;
mod eval;
mod mine;
mod planes;
mod refine;
mod render;
mod scene;
mod train;
mod util;

pub use bench::{BenchArgs, bench};
pub use compose::{ComposeArgs, compose};
pub use demo::{DemoArgs, DemoStep, demo, demo_plan};
pub use edit::{EditArgs, edit};
pub use eval::{EvalArgs, eval};
pub use mine::{LibraryArgs, MineArgs, library, mine};
pub use planes::{PlanesArgs, planes};
pub use refine::{RefineArgs, refine};
pub use render::{RenderArgs, render};
pub use scene::{InspectArgs, LayoutArgs, SynthArgs, inspect, layout, synth};
pub use train::{TrainArgs, train};
