//! The asset library format of assetfield (paper Sec. 3.4): feature patches of templates and instances,
//! an emptied container, and the tensors shared by every patch.
//!
//! A library is a folder:
//!
//! * `index.ron`: [`LibraryIndex`] (format `assetfield-library/1`): sources, model kind,
//!   texel size, categories (name, template entry, members), entries (name, category, kind,
//!   tensor names, patch size, world extents, base height, source box, yaw relative to the
//!   template, residual, support), the containers, and the shared-tensor file with a content
//!   hash of it.
//! * `patches.safetensors`: per entry `ENTRY.density` `[h, w, Nd]`, `ENTRY.color`
//!   `[h, w, Nc]` (f32) and `ENTRY.mask` `[h, w]` (u8, 1 = the object's own texels); per
//!   container `NAME.density`, `NAME.color` (the whole planes with the objects filled with
//!   the surrounding background) and `NAME.mask` (1 = texels that were filled).
//! * `shared.safetensors`: every non-plane tensor of the field (vertical axes, colour basis,
//!   guidance MLPs, decoders), with the field configuration (JSON) in the metadata key
//!   `config`.
//!
//! [`open_library`] checks the index against the tensors (a shape that differs names the
//! tensor, the expected and the actual shape) and the shared file against its hash;
//! [`merge()`] builds a cross-scene library from libraries whose shared tensors are
//! identical and refuses, naming the first tensor that differs, otherwise.
//!
//! Mining writes libraries ([`write_library_files`]); the composer, the editor, template
//! refinement and `train --share` read them, always through [`open_library`].

mod check;
mod error;
mod files;
mod index;
mod merge;

pub use check::validate;

/// Halo (texels) around an entry's mask that its patch covers when composed, for libraries
/// that do not record theirs ([`Container::halo`]): the ring that `assetfield mine` filled
/// in the container along with the entry's mask before the halo followed the field's blur.
pub const DEFAULT_HALO: usize = 2;
pub use error::{LibraryError, Result};
pub use files::{
    Library, field_with_shared, open_library, shared_tensors, write_library_files,
    write_sample_library,
};
pub use index::{
    Category, Container, Entry, EntryKind, FORMAT, INDEX_FILE, LibraryIndex, PATCHES_FILE,
    SHARED_FILE, SHARED_FORMAT, SharedRef, content_hash, index_from_ron, index_to_ron,
};
pub use merge::{Merged, merge, merge_libraries, shared_difference};
