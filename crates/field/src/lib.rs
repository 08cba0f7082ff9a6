//! Ground feature plane radiance fields (paper Sec. 3.1, 3.3): S-AssetField, I-AssetField and
//! the TensoRF-VM baseline, built from the same blocks (plane-axis components, a colour basis,
//! MLP or spherical-harmonics decoders), with hand-written fused forward and backward ray
//! kernels, training and CPU rendering.

pub mod adam;
pub mod appearance;
pub mod background;
pub mod config;
pub mod interp;
pub mod io;
pub mod joint;
pub mod march;
pub mod mlp;
pub mod model;
pub mod occupancy;
pub mod params;
pub mod touched;
pub mod train;

pub use background::BackgroundMap;
pub use config::{DecoderKind, FieldConfig, ModelKind};
pub use io::FieldError;
pub use joint::{JointTrainer, joint_configs, share_config};
pub use march::{MarchSettings, MarchWork};
pub use model::Field;
pub use occupancy::Occupancy;
pub use train::{
    Clock, GridRule, StepStats, TrainConfig, Trainer, process_cpu_seconds, render_semantic_view,
    render_view, render_view_map, render_view_unless,
};
pub mod eval;
pub mod pictures;
