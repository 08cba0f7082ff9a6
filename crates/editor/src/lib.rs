//! The assetfield scene editor (`assetfield edit`).
//!
//! - [`session`]: an [`EditSession`] over one asset library: the layout being edited (the
//!   file it started from plus batches of edits in the layout language), undo and redo,
//!   renders from an orbit camera, the bird's-eye view and an atomic Save. Every change goes
//!   through the ECS composer, which redraws only what an edit touched.
//! - [`server`]: the local web server (axum): the page, compiled into the binary (no build
//!   step, no CDN), and the token-guarded HTTP API the page, tests and scripts use.
//! - [`bev`]: the bird's-eye picture and how its pixels map to the world.

pub mod bev;
pub mod error;
pub mod png;
pub mod server;
pub mod session;

pub use bev::BevMapping;
pub use error::EditorError;
pub use server::{AppState, MAX_BODY_BYTES, random_token, router, run, serve};
pub use session::{EditSession, LayoutView, SessionOptions, ViewRequest};
