use std::path::PathBuf;

/// Errors of ground-truth synthesis.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    #[error(transparent)]
    Layout(#[from] assetfield_layout::LayoutError),
    #[error(transparent)]
    Core(#[from] assetfield_core::CoreError),
    #[error(transparent)]
    Data(#[from] assetfield_data::DataError),
    #[error("{location}: asset \"{asset}\": cannot load OBJ {}: {message}", path.display())]
    Obj { location: assetfield_layout::Location, asset: String, path: PathBuf, message: String },
    /// A catalog model that cannot be used (catalog not allowed or missing, unknown id,
    /// broken mesh).
    #[error("{location}: asset \"{asset}\": {source}")]
    Catalog {
        location: assetfield_layout::Location,
        asset: String,
        #[source]
        source: Box<crate::sh3f::CatalogError>,
    },
    #[error("{location}: asset \"{asset}\" has no geometry (give `parts` or `obj`)")]
    EmptyAsset { location: assetfield_layout::Location, asset: String },
    #[error(
        "{location}: asset \"{asset}\" is a neural asset from the library {library}; the ray tracer cannot draw it (render the script with `assetfield compose`)"
    )]
    LibraryAsset { location: assetfield_layout::Location, asset: String, library: String },
    #[error("invalid synthesis settings: {0}")]
    Config(String),
    /// A layout with nothing for the ray tracer to draw: no instance, or containers only.
    #[error(
        "{location}: nothing to render: the resolved layout has {}; add objects to `layout`",
        what_is_there(*instances)
    )]
    EmptyScene { location: assetfield_layout::Location, instances: usize },
}

/// What an empty layout holds, in words.
fn what_is_there(instances: usize) -> String {
    match instances {
        0 => "no instances".into(),
        n => format!("containers only ({n} instances, no object)"),
    }
}
