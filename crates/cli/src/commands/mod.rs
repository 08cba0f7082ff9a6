//! The subcommands, one module per group; shared helpers in `util`.

mod bench;
mod bench_edit;
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
mod train_joint;
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
