//! Field files: one safetensors file holding every tensor under its documented name and shape
//! (see [`crate::model`] and ARCHITECTURE.md), the full [`FieldConfig`] as JSON in the
//! metadata, and optionally the occupancy grid. Training checkpoints add the optimiser state.

use crate::config::FieldConfig;
use crate::model::Field;
use crate::occupancy::Occupancy;
use assetfield_core::{CoreError, TensorFile};
use std::path::Path;

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
}

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

    /// Rebuild a field from a loaded file; every tensor must be present with its shape.
    pub fn from_tensor_file(
        file: &mut TensorFile,
    ) -> Result<(Field, Option<Occupancy>), FieldError> {
        let path =
            file.origin().map(|p| p.display().to_string()).unwrap_or_else(|| "<in memory>".into());
        let format = file.meta("format").map(str::to_string);
        if format.as_deref() != Some(FORMAT) {
            return Err(FieldError::NotAField { path, found: format });
        }
        let config: FieldConfig = file.meta_json("config")?;
        if config.res.iter().any(|r| *r < 2) {
            return Err(FieldError::Invalid {
                path,
                message: format!("resolution {:?} is too small", config.res),
            });
        }
        let mut field = Field::new(config, 0);
        for spec in field.params.specs.clone() {
            let data = file.take_f32(&spec.name, &spec.shape)?;
            field.params.data[spec.offset..spec.offset + spec.len].copy_from_slice(&data);
        }
        let occupancy = match file.shape_of("occupancy").map(<[usize]>::to_vec) {
            Some(shape) if shape.len() == 3 => {
                let cells = file.take_u8("occupancy", &shape)?;
                Some(Occupancy::from_cells(&field, [shape[2], shape[1], shape[0]], &cells))
            }
            Some(shape) => {
                return Err(FieldError::Invalid {
                    path,
                    message: format!(
                        "tensor \"occupancy\" has shape {shape:?}, expected [nz, ny, nx]"
                    ),
                });
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
