//! Field files: one safetensors file holding every tensor under its documented name and shape
//! (see [`crate::model`] and ARCHITECTURE.md), the full [`FieldConfig`] as JSON in the
//! metadata, and optionally the occupancy grid. Training checkpoints add the optimiser state.

use crate::config::FieldConfig;
use crate::model::Field;
use crate::occupancy::Occupancy;
use assetfield_core::{CoreError, TensorFile};
use std::path::{Path, PathBuf};

/// Format tag stored in the metadata.
pub const FORMAT: &str = "assetfield-field/1";

#[derive(Debug, thiserror::Error)]
pub enum FieldError {
    #[error(transparent)]
    Core(#[from] CoreError),
    #[error(
        "{path}: not an assetfield field file (metadata \"format\" is {found:?}, expected {FORMAT:?})"
    )]
    NotAField { path: String, found: Option<String> },
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
    /// A value of the field's configuration (metadata `config`) is out of bounds (see the
    /// constants of [`crate::config`]).
    #[error("{}: config \"{key}\" is {actual}, expected {expected}", path.display())]
    Config { path: PathBuf, key: String, expected: String, actual: String },
    /// A tensor's shape is not the one the field's configuration implies.
    #[error(
        "{}: tensor \"{tensor}\" has shape {actual:?}, expected {expected:?} (the shape its config implies)",
        path.display()
    )]
    Shape { path: PathBuf, tensor: String, expected: Vec<usize>, actual: Vec<usize> },
    /// A parameter tensor holds NaN or an infinity; `index` is the first such value
    /// (row-major).
    #[error(
        "{}: tensor \"{tensor}\" has a non-finite value ({value}) at index {index}",
        path.display()
    )]
    NonFinite { path: PathBuf, tensor: String, index: usize, value: f32 },
    /// A parameter is finite but beyond [`MAX_PARAMETER_MAGNITUDE`]: decoding it would
    /// overflow to infinities and NaN.
    #[error(
        "{}: tensor \"{tensor}\" has a value of {value} at index {index}, beyond the {MAX_PARAMETER_MAGNITUDE:e} a field's parameters stay within",
        path.display()
    )]
    ParameterRange { path: PathBuf, tensor: String, index: usize, value: f32 },
    /// An image metric came out NaN or infinite, which `metrics.json` cannot hold.
    #[error(
        "view {index} ({file_path}, image {}): {metric} is {value}, not a finite number: {why}",
        image.display()
    )]
    NonFiniteMetric {
        index: usize,
        file_path: String,
        image: PathBuf,
        metric: &'static str,
        value: f32,
        why: &'static str,
    },
}

impl FieldError {
    /// [`CoreError::TensorNonFinite`] as [`FieldError::NonFinite`]; other errors as they are.
    pub(crate) fn from_core(e: CoreError) -> Self {
        match e {
            CoreError::TensorNonFinite { path, name, index, value } => {
                FieldError::NonFinite { path, tensor: name, index, value }
            }
            other => FieldError::Core(other),
        }
    }
}

/// Largest magnitude a field parameter may have. Trained fields stay far below it (the
/// shipped `living_room_s128` field's largest is 5.2); at 1e6, a feature times a weight summed
/// over 256 channels and three layers stays below f32's 3.4e38, so no input that passes makes
/// the renderer produce an infinity or NaN (found by the fuzz harness: values of 3e38 did).
pub const MAX_PARAMETER_MAGNITUDE: f32 = 1.0e6;

impl Field {
    /// Every tensor plus config metadata, ready to save.
    pub fn to_tensor_file(&self, occupancy: Option<&Occupancy>) -> Result<TensorFile, FieldError> {
        let mut f = TensorFile::new();
        for s in &self.params.specs {
            f.insert_f32(&s.name, &s.shape, self.params.data[s.offset..s.offset + s.len].to_vec());
        }
        if let Some(o) = occupancy {
            let [nx, ny, nz] = o.res;
            f.insert_u8("occupancy", &[nz, ny, nx], o.cells_u8());
        }
        f.set_meta("format", FORMAT);
        f.set_meta("model", self.config.kind.name());
        f.set_meta_json("config", &self.config)?;
        Ok(f)
    }

    /// Save to a safetensors file (atomically).
    pub fn save(&self, path: &Path, occupancy: Option<&Occupancy>) -> Result<(), FieldError> {
        self.to_tensor_file(occupancy)?.save(path)?;
        Ok(())
    }

    /// Rebuild a field from a loaded file. Everything is checked before the field is
    /// allocated: the configuration against its bounds ([`FieldConfig::validate`]), then
    /// every tensor it implies (present, of the implied shape, `f32`, finite values), then
    /// the occupancy grid; so the field is never larger than the file.
    pub fn from_tensor_file(
        file: &mut TensorFile,
    ) -> Result<(Field, Option<Occupancy>), FieldError> {
        let origin = file.origin().map_or_else(|| PathBuf::from("<in memory>"), Path::to_path_buf);
        let path = origin.display().to_string();
        let format = file.meta("format").map(str::to_string);
        if format.as_deref() != Some(FORMAT) {
            return Err(FieldError::NotAField { path, found: format });
        }
        let config: FieldConfig = file.meta_json("config")?;
        config.validate(&origin)?;
        let shapes = config.tensor_shapes();
        for (name, expected) in &shapes {
            let actual = file.get(name)?.shape.clone();
            if &actual != expected {
                return Err(FieldError::Shape {
                    path: origin.clone(),
                    tensor: name.clone(),
                    expected: expected.clone(),
                    actual,
                });
            }
            file.check_finite(name).map_err(FieldError::from_core)?;
            let values = file.get_f32(name, expected)?;
            if let Some(index) = values.iter().position(|v| v.abs() > MAX_PARAMETER_MAGNITUDE) {
                return Err(FieldError::ParameterRange {
                    path: origin.clone(),
                    tensor: name.clone(),
                    index,
                    value: values[index],
                });
            }
        }
        // the trainer's grid has half the field's resolution: the plane bound covers it
        let most = crate::config::max_plane_res();
        let occupancy_res = match file.shape_of("occupancy") {
            Some(&[nz, ny, nx]) if [nx, ny, nz].iter().all(|n| (1..=most).contains(n)) => {
                Some([nx, ny, nz])
            }
            Some(shape) => {
                return Err(FieldError::Invalid {
                    path,
                    message: format!(
                        "tensor \"occupancy\" has shape {shape:?}, expected [nz, ny, nx] with 1 to {most} cells per axis"
                    ),
                });
            }
            None => None,
        };
        let mut field = Field::new(config, 0);
        for spec in field.params.specs.clone() {
            let data = file.take_f32(&spec.name, &spec.shape)?;
            field.params.data[spec.offset..spec.offset + spec.len].copy_from_slice(&data);
        }
        let occupancy = match occupancy_res {
            Some([nx, ny, nz]) => {
                let cells = file.take_u8("occupancy", &[nz, ny, nx])?;
                Some(Occupancy::from_cells(&field, [nx, ny, nz], &cells))
            }
            None => None,
        };
        Ok((field, occupancy))
    }

    /// Load a field saved by [`Field::save`] (or a training checkpoint).
    pub fn load(path: &Path) -> Result<(Field, Option<Occupancy>), FieldError> {
        let mut file = TensorFile::load(path)?;
        Field::from_tensor_file(&mut file)
    }
}
