//! Named tensors in [safetensors](https://github.com/huggingface/safetensors) files, which
//! Python opens with `safetensors.numpy.load_file` (or torch). A small typed layer over the
//! `safetensors` crate: owned little-endian `f32` / `u8` / `i64` data, shape checks with
//! messages that name the file and the tensor, atomic saving and string metadata (with JSON
//! helpers for storing a configuration inside the file).
//!
//! The format: 8 bytes little-endian header length `n`, `n` bytes of JSON header mapping each
//! tensor name to `{"dtype", "shape", "data_offsets": [begin, end]}` (offsets into the data
//! section that follows) plus an optional `"__metadata__"` string-to-string map, then the raw
//! row-major (C order) little-endian tensor data.

use crate::CoreError;
use safetensors::{Dtype, SafeTensors, View};
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// Reserved header key of the metadata map; no tensor may be called this.
const METADATA_KEY: &str = "__metadata__";

/// The values of a tensor, row-major.
#[derive(Debug, Clone, PartialEq)]
pub enum TensorData {
    F32(Vec<f32>),
    U8(Vec<u8>),
    I64(Vec<i64>),
}

impl TensorData {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            TensorData::F32(v) => v.len(),
            TensorData::U8(v) => v.len(),
            TensorData::I64(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The safetensors name of the element type: `F32`, `U8` or `I64`.
    pub fn dtype_name(&self) -> &'static str {
        match self {
            TensorData::F32(_) => "F32",
            TensorData::U8(_) => "U8",
            TensorData::I64(_) => "I64",
        }
    }

    fn dtype(&self) -> Dtype {
        match self {
            TensorData::F32(_) => Dtype::F32,
            TensorData::U8(_) => Dtype::U8,
            TensorData::I64(_) => Dtype::I64,
        }
    }

    /// Little-endian bytes (borrowed for `u8` data).
    fn le_bytes(&self) -> Cow<'_, [u8]> {
        match self {
            TensorData::F32(v) => Cow::Owned(v.iter().flat_map(|x| x.to_le_bytes()).collect()),
            TensorData::U8(v) => Cow::Borrowed(v),
            TensorData::I64(v) => Cow::Owned(v.iter().flat_map(|x| x.to_le_bytes()).collect()),
        }
    }
}

/// A shaped array of values, row-major (last index fastest), as numpy's C order.
#[derive(Debug, Clone, PartialEq)]
pub struct Tensor {
    pub shape: Vec<usize>,
    pub data: TensorData,
}

impl Tensor {
    /// A tensor of `f32` values.
    ///
    /// # Panics
    /// If the number of values is not the product of the shape.
    pub fn f32(shape: impl Into<Vec<usize>>, data: Vec<f32>) -> Self {
        Self::checked(shape.into(), TensorData::F32(data))
    }

    /// A tensor of `u8` values (masks, labels, images).
    ///
    /// # Panics
    /// If the number of values is not the product of the shape.
    pub fn u8(shape: impl Into<Vec<usize>>, data: Vec<u8>) -> Self {
        Self::checked(shape.into(), TensorData::U8(data))
    }

    /// A tensor of `i64` values (indices, counters).
    ///
    /// # Panics
    /// If the number of values is not the product of the shape.
    pub fn i64(shape: impl Into<Vec<usize>>, data: Vec<i64>) -> Self {
        Self::checked(shape.into(), TensorData::I64(data))
    }

    fn checked(shape: Vec<usize>, data: TensorData) -> Self {
        let t = Tensor { shape, data };
        assert_eq!(
            t.numel(),
            t.data.len(),
            "tensor of shape {:?} needs {} values, got {}",
            t.shape,
            t.numel(),
            t.data.len()
        );
        t
    }

    /// Number of elements the shape asks for (1 for a scalar's empty shape).
    ///
    /// # Panics
    /// If the product overflows `usize` (never for a tensor read from a file: the reader
    /// refuses such shapes, see [`checked_numel`]).
    pub fn numel(&self) -> usize {
        checked_numel(&self.shape).expect("tensor shape product overflows usize")
    }
}

/// Number of elements of `shape` (1 for the empty shape of a scalar), or `None` when the
/// product overflows `usize`. Use it for every size computed from a file's header.
pub fn checked_numel(shape: &[usize]) -> Option<usize> {
    shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d))
}

/// The first value that is NaN or infinite, with its index.
pub fn first_non_finite(values: &[f32]) -> Option<(usize, f32)> {
    values.iter().copied().enumerate().find(|(_, v)| !v.is_finite())
}

/// Bytes per element of a dtype assetfield reads.
fn dtype_size(dtype: Dtype) -> Option<usize> {
    match dtype {
        Dtype::F32 => Some(4),
        Dtype::U8 => Some(1),
        Dtype::I64 => Some(8),
        _ => None,
    }
}

/// The contents of one safetensors file: tensors by name and string metadata, both sorted
/// by key. Remembers the path it was loaded from for error messages.
#[derive(Debug, Clone, Default)]
pub struct TensorFile {
    pub tensors: BTreeMap<String, Tensor>,
    pub metadata: BTreeMap<String, String>,
    origin: Option<PathBuf>,
}

/// A tensor ready for the `safetensors` serialiser.
struct Encoded<'a> {
    dtype: Dtype,
    shape: &'a [usize],
    bytes: Cow<'a, [u8]>,
}

impl View for Encoded<'_> {
    fn dtype(&self) -> Dtype {
        self.dtype
    }
    fn shape(&self) -> &[usize] {
        self.shape
    }
    fn data(&self) -> Cow<'_, [u8]> {
        Cow::Borrowed(&self.bytes)
    }
    fn data_len(&self) -> usize {
        self.bytes.len()
    }
}

/// The name errors use for the file: its path, or `<in memory>`.
fn label(origin: Option<&Path>) -> PathBuf {
    origin.map_or_else(|| PathBuf::from("<in memory>"), Path::to_path_buf)
}

impl TensorFile {
    pub fn new() -> Self {
        Self::default()
    }

    /// The file this was loaded from, if any.
    pub fn origin(&self) -> Option<&Path> {
        self.origin.as_deref()
    }

    fn path(&self) -> PathBuf {
        label(self.origin())
    }

    /// Add or replace a tensor; returns the one it replaces.
    pub fn insert(&mut self, name: impl Into<String>, tensor: Tensor) -> Option<Tensor> {
        self.tensors.insert(name.into(), tensor)
    }

    /// Add or replace an `f32` tensor.
    ///
    /// # Panics
    /// If the number of values is not the product of the shape.
    pub fn insert_f32(&mut self, name: impl Into<String>, shape: &[usize], data: Vec<f32>) {
        self.insert(name, Tensor::f32(shape, data));
    }

    /// Add or replace a `u8` tensor.
    ///
    /// # Panics
    /// If the number of values is not the product of the shape.
    pub fn insert_u8(&mut self, name: impl Into<String>, shape: &[usize], data: Vec<u8>) {
        self.insert(name, Tensor::u8(shape, data));
    }

    /// Add or replace an `i64` tensor.
    ///
    /// # Panics
    /// If the number of values is not the product of the shape.
    pub fn insert_i64(&mut self, name: impl Into<String>, shape: &[usize], data: Vec<i64>) {
        self.insert(name, Tensor::i64(shape, data));
    }

    /// Tensor names, sorted.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.tensors.keys().map(String::as_str)
    }

    /// Shape of a tensor, if present.
    pub fn shape_of(&self, name: &str) -> Option<&[usize]> {
        self.tensors.get(name).map(|t| t.shape.as_slice())
    }

    /// The tensor called `name`, or an error listing the tensors present.
    pub fn get(&self, name: &str) -> Result<&Tensor, CoreError> {
        self.tensors.get(name).ok_or_else(|| self.missing(name))
    }

    fn missing(&self, name: &str) -> CoreError {
        const SHOWN: usize = 20;
        let shown: Vec<&str> = self.names().take(SHOWN).collect();
        let more = self.tensors.len().saturating_sub(SHOWN);
        let mut present = if shown.is_empty() { "none".to_string() } else { shown.join(", ") };
        if more > 0 {
            present.push_str(&format!(", and {more} more"));
        }
        CoreError::TensorMissing { path: self.path(), name: name.to_string(), present }
    }

    /// Check `name` exists with `expected_shape` and element type `dtype`.
    fn checked(
        &self,
        name: &str,
        expected_shape: &[usize],
        dtype: &str,
    ) -> Result<&Tensor, CoreError> {
        let t = self.get(name)?;
        if t.shape != expected_shape {
            return Err(CoreError::TensorShape {
                path: self.path(),
                name: name.to_string(),
                actual: t.shape.as_slice().into(),
                expected: expected_shape.into(),
            });
        }
        if t.data.dtype_name() != dtype {
            return Err(CoreError::TensorDtype {
                path: self.path(),
                name: name.to_string(),
                actual: t.data.dtype_name().to_string(),
                expected: dtype.to_string(),
            });
        }
        Ok(t)
    }

    /// The values of `f32` tensor `name`, which must have shape `expected_shape`.
    pub fn get_f32(&self, name: &str, expected_shape: &[usize]) -> Result<&[f32], CoreError> {
        match &self.checked(name, expected_shape, "F32")?.data {
            TensorData::F32(v) => Ok(v),
            _ => unreachable!("dtype checked"),
        }
    }

    /// The values of `u8` tensor `name`, which must have shape `expected_shape`.
    pub fn get_u8(&self, name: &str, expected_shape: &[usize]) -> Result<&[u8], CoreError> {
        match &self.checked(name, expected_shape, "U8")?.data {
            TensorData::U8(v) => Ok(v),
            _ => unreachable!("dtype checked"),
        }
    }

    /// The values of `i64` tensor `name`, which must have shape `expected_shape`.
    pub fn get_i64(&self, name: &str, expected_shape: &[usize]) -> Result<&[i64], CoreError> {
        match &self.checked(name, expected_shape, "I64")?.data {
            TensorData::I64(v) => Ok(v),
            _ => unreachable!("dtype checked"),
        }
    }

    /// Remove `f32` tensor `name` (shape `expected_shape`) and return its values without
    /// copying. On error the file is left unchanged.
    pub fn take_f32(
        &mut self,
        name: &str,
        expected_shape: &[usize],
    ) -> Result<Vec<f32>, CoreError> {
        self.checked(name, expected_shape, "F32")?;
        match self.tensors.remove(name).map(|t| t.data) {
            Some(TensorData::F32(v)) => Ok(v),
            _ => unreachable!("checked"),
        }
    }

    /// Remove `u8` tensor `name` (shape `expected_shape`) and return its values.
    pub fn take_u8(&mut self, name: &str, expected_shape: &[usize]) -> Result<Vec<u8>, CoreError> {
        self.checked(name, expected_shape, "U8")?;
        match self.tensors.remove(name).map(|t| t.data) {
            Some(TensorData::U8(v)) => Ok(v),
            _ => unreachable!("checked"),
        }
    }

    /// Remove `i64` tensor `name` (shape `expected_shape`) and return its values.
    pub fn take_i64(
        &mut self,
        name: &str,
        expected_shape: &[usize],
    ) -> Result<Vec<i64>, CoreError> {
        self.checked(name, expected_shape, "I64")?;
        match self.tensors.remove(name).map(|t| t.data) {
            Some(TensorData::I64(v)) => Ok(v),
            _ => unreachable!("checked"),
        }
    }

    /// Check that `f32` tensor `name` holds only finite values (tensors of other element
    /// types always pass); the error names the tensor and the index of the first bad value.
    pub fn check_finite(&self, name: &str) -> Result<(), CoreError> {
        match &self.get(name)?.data {
            TensorData::F32(v) => match first_non_finite(v) {
                Some((index, value)) => Err(CoreError::TensorNonFinite {
                    path: self.path(),
                    name: name.to_string(),
                    index,
                    value,
                }),
                None => Ok(()),
            },
            TensorData::U8(_) | TensorData::I64(_) => Ok(()),
        }
    }

    /// [`TensorFile::check_finite`] for every tensor, in name order.
    pub fn check_all_finite(&self) -> Result<(), CoreError> {
        self.names().try_for_each(|name| self.check_finite(name))
    }

    /// Set a metadata entry.
    pub fn set_meta(&mut self, key: impl Into<String>, value: impl Into<String>) {
        self.metadata.insert(key.into(), value.into());
    }

    /// A metadata entry.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata.get(key).map(String::as_str)
    }

    /// Store `value` as JSON in metadata entry `key` (a configuration, say).
    pub fn set_meta_json<T: Serialize + ?Sized>(
        &mut self,
        key: &str,
        value: &T,
    ) -> Result<(), CoreError> {
        let json = serde_json::to_string(value).map_err(|e| CoreError::TensorMeta {
            path: self.path(),
            key: key.to_string(),
            message: format!("cannot encode as JSON: {e}"),
        })?;
        self.set_meta(key, json);
        Ok(())
    }

    /// Read metadata entry `key` as JSON; an error when it is missing or does not parse as `T`.
    pub fn meta_json<T: DeserializeOwned>(&self, key: &str) -> Result<T, CoreError> {
        let err = |message: String| CoreError::TensorMeta {
            path: self.path(),
            key: key.to_string(),
            message,
        };
        let text = self.meta(key).ok_or_else(|| {
            let keys: Vec<&str> = self.metadata.keys().map(String::as_str).collect();
            err(format!(
                "missing (present: {})",
                if keys.is_empty() { "none".to_string() } else { keys.join(", ") }
            ))
        })?;
        serde_json::from_str(text)
            .map_err(|e| err(format!("invalid JSON for the expected type: {e}")))
    }

    /// The file's bytes in safetensors format.
    pub fn to_bytes(&self) -> Result<Vec<u8>, CoreError> {
        let format_err = |message: String| CoreError::TensorFormat { path: self.path(), message };
        let mut views = Vec::with_capacity(self.tensors.len());
        for (name, t) in &self.tensors {
            if name == METADATA_KEY {
                return Err(format_err(format!("a tensor cannot be called \"{METADATA_KEY}\"")));
            }
            if t.numel() != t.data.len() {
                return Err(format_err(format!(
                    "tensor \"{name}\" of shape {:?} needs {} values, has {}",
                    t.shape,
                    t.numel(),
                    t.data.len()
                )));
            }
            views.push((
                name.as_str(),
                Encoded { dtype: t.data.dtype(), shape: &t.shape, bytes: t.data.le_bytes() },
            ));
        }
        let meta: Option<HashMap<String, String>> = (!self.metadata.is_empty())
            .then(|| self.metadata.iter().map(|(k, v)| (k.clone(), v.clone())).collect());
        safetensors::serialize(views, meta)
            .map_err(|e| format_err(format!("cannot encode safetensors: {e}")))
    }

    /// Parse safetensors bytes; `origin` names the file in error messages.
    pub fn from_bytes(bytes: &[u8], origin: &Path) -> Result<Self, CoreError> {
        let format_err =
            |message: String| CoreError::TensorFormat { path: origin.to_path_buf(), message };
        let parsed = SafeTensors::deserialize(bytes)
            .map_err(|e| format_err(format!("not a valid safetensors file: {e}")))?;
        let (_, header) = SafeTensors::read_metadata(bytes)
            .map_err(|e| format_err(format!("not a valid safetensors file: {e}")))?;
        // Sizes from the header are checked here, before any value is copied, rather than
        // trusted to the parser: the element count of every shape (overflow-checked) times
        // the element size must be exactly the bytes the tensor spans in this file, so no
        // allocation below is larger than the file itself.
        for (name, view) in parsed.iter() {
            let Some(size) = dtype_size(view.dtype()) else {
                return Err(format_err(format!(
                    "tensor \"{name}\" has dtype {}, which assetfield does not read (F32, U8, I64)",
                    view.dtype()
                )));
            };
            let bytes = checked_numel(view.shape()).and_then(|n| n.checked_mul(size));
            if bytes != Some(view.data().len()) {
                return Err(format_err(format!(
                    "tensor \"{name}\" declares shape {:?} of {} ({}), but its data in the file is {} bytes",
                    view.shape(),
                    view.dtype(),
                    bytes.map_or_else(
                        || "more values than can be counted".into(),
                        |b| format!("{b} bytes")
                    ),
                    view.data().len()
                )));
            }
        }
        let mut tensors = BTreeMap::new();
        for (name, view) in parsed.iter() {
            let raw = view.data();
            let data = match view.dtype() {
                Dtype::F32 => TensorData::F32(
                    raw.chunks_exact(4)
                        .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
                        .collect(),
                ),
                Dtype::U8 => TensorData::U8(raw.to_vec()),
                Dtype::I64 => TensorData::I64(
                    raw.chunks_exact(8)
                        .map(|b| i64::from_le_bytes(b.try_into().expect("8 bytes")))
                        .collect(),
                ),
                other => {
                    return Err(format_err(format!(
                        "tensor \"{name}\" has dtype {other}, which assetfield does not read (F32, U8, I64)"
                    )));
                }
            };
            tensors.insert(name.to_string(), Tensor { shape: view.shape().to_vec(), data });
        }
        let metadata = header
            .metadata()
            .as_ref()
            .map(|m| m.iter().map(|(k, v)| (k.clone(), v.clone())).collect())
            .unwrap_or_default();
        Ok(TensorFile { tensors, metadata, origin: Some(origin.to_path_buf()) })
    }

    /// Write the file atomically (it appears complete or not at all).
    pub fn save(&self, path: &Path) -> Result<(), CoreError> {
        let bytes = self.to_bytes().map_err(|e| match e {
            CoreError::TensorFormat { message, .. } => {
                CoreError::TensorFormat { path: path.to_path_buf(), message }
            }
            other => other,
        })?;
        crate::fsx::write_atomic(path, &bytes)
    }

    /// Read a file written by [`TensorFile::save`], Python's `safetensors` or torch (tensors
    /// of type F32, U8 or I64).
    pub fn load(path: &Path) -> Result<Self, CoreError> {
        // a regular file that fits memory: `/dev/zero` or a FIFO named as a field is refused
        let bytes = crate::fsx::read_regular_file(path)?;
        Self::from_bytes(&bytes, path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir()
            .join(format!("assetfield-core-tensors-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Config {
        resolution: u32,
        channels: Vec<usize>,
        name: String,
    }

    fn sample() -> TensorFile {
        let mut f = TensorFile::new();
        f.insert_f32("density.plane", &[2, 3, 4], (0..24).map(|i| i as f32 * 0.5 - 3.0).collect());
        f.insert_f32("scalar", &[], vec![std::f32::consts::PI]);
        f.insert_u8("mask", &[5], vec![0, 1, 2, 254, 255]);
        f.insert_i64("ids", &[2, 2], vec![-1, 0, 1 << 40, i64::MIN]);
        f.insert_f32("empty", &[0, 3], vec![]);
        f.set_meta("format", "assetfield-test");
        f.set_meta_json(
            "config",
            &Config { resolution: 300, channels: vec![16, 24], name: "b\"q".into() },
        )
        .unwrap();
        f
    }

    #[test]
    fn round_trip() {
        let dir = scratch("roundtrip");
        let path = dir.join("sub/fields.safetensors");
        let f = sample();
        f.save(&path).unwrap();
        let mut g = TensorFile::load(&path).unwrap();
        assert_eq!(g.origin(), Some(path.as_path()));
        assert_eq!(g.tensors, f.tensors);
        assert_eq!(g.metadata, f.metadata);
        assert_eq!(g.meta("format"), Some("assetfield-test"));
        let cfg: Config = g.meta_json("config").unwrap();
        assert_eq!(cfg.channels, vec![16, 24]);
        assert_eq!(g.shape_of("density.plane"), Some(&[2usize, 3, 4][..]));
        assert_eq!(g.get_f32("scalar", &[]).unwrap(), &[std::f32::consts::PI]);
        assert_eq!(g.get_u8("mask", &[5]).unwrap()[3], 254);
        assert_eq!(g.get_i64("ids", &[2, 2]).unwrap()[3], i64::MIN);
        let plane = g.take_f32("density.plane", &[2, 3, 4]).unwrap();
        assert_eq!(plane[23], 8.5);
        assert!(g.shape_of("density.plane").is_none());
        // nothing but the file itself in the folder (atomic write leaves no temporaries)
        assert_eq!(std::fs::read_dir(dir.join("sub")).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn shape_dtype_and_missing_messages() {
        let mut f = sample();
        f.origin = Some(PathBuf::from("run/fields.safetensors"));
        f.insert_f32("feat", &[300, 300, 16], vec![0.0; 300 * 300 * 16]);
        let e = f.get_f32("feat", &[300, 300, 24]).unwrap_err().to_string();
        assert_eq!(
            e,
            "run/fields.safetensors: tensor \"feat\" has shape [300, 300, 16], expected [300, 300, 24]"
        );
        let e = f.get_f32("x", &[1]).unwrap_err().to_string();
        assert_eq!(
            e,
            "run/fields.safetensors: missing tensor \"x\" (present: density.plane, empty, feat, ids, mask, scalar)"
        );
        let e = f.get_f32("mask", &[5]).unwrap_err().to_string();
        assert!(e.contains("\"mask\" has dtype U8, expected F32"), "{e}");
        // a failed take leaves the tensor in place
        assert!(f.take_f32("feat", &[1]).is_err());
        assert!(f.shape_of("feat").is_some());
        let e = f.meta_json::<Config>("nope").unwrap_err().to_string();
        assert!(e.contains("metadata \"nope\"") && e.contains("config, format"), "{e}");
        let e = f.meta_json::<Vec<u32>>("config").unwrap_err().to_string();
        assert!(e.contains("invalid JSON"), "{e}");
        let empty = TensorFile::new();
        assert_eq!(
            empty.get("a").unwrap_err().to_string(),
            "<in memory>: missing tensor \"a\" (present: none)"
        );
    }

    #[test]
    fn bad_tensors_are_refused_when_saving() {
        let mut f = TensorFile::new();
        f.tensors
            .insert("bad".into(), Tensor { shape: vec![2, 2], data: TensorData::F32(vec![1.0]) });
        let e = f.save(Path::new("/nonexistent/x.safetensors")).unwrap_err().to_string();
        assert!(e.starts_with("/nonexistent/x.safetensors: tensor \"bad\""), "{e}");
        let mut g = TensorFile::new();
        g.insert_u8(METADATA_KEY, &[1], vec![1]);
        assert!(g.to_bytes().is_err());
    }

    #[test]
    fn garbage_and_truncated_files_give_errors() {
        let bytes = sample().to_bytes().unwrap();
        let origin = Path::new("broken.safetensors");
        for cut in [0, 3, 8, 20, bytes.len() / 2, bytes.len() - 1] {
            let e = TensorFile::from_bytes(&bytes[..cut], origin).unwrap_err().to_string();
            assert!(e.starts_with("broken.safetensors: "), "{e}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(TensorFile::from_bytes(&longer, origin).is_err());
        let mut garbage = vec![0xffu8; 64];
        assert!(TensorFile::from_bytes(&garbage, origin).is_err());
        garbage[..8].copy_from_slice(&16u64.to_le_bytes());
        garbage[8..24].copy_from_slice(b"{not json at all");
        assert!(TensorFile::from_bytes(&garbage[..24], origin).is_err());
        // a valid file with a dtype we do not read
        let header = br#"{"h":{"dtype":"F16","shape":[2],"data_offsets":[0,4]}}"#;
        let mut f16 = (header.len() as u64).to_le_bytes().to_vec();
        f16.extend_from_slice(header);
        f16.extend_from_slice(&[0, 60, 0, 64]);
        let e = TensorFile::from_bytes(&f16, origin).unwrap_err().to_string();
        assert!(e.contains("\"h\" has dtype F16"), "{e}");
        let dir = scratch("missing");
        assert!(TensorFile::load(&dir.join("absent.safetensors")).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A file of one tensor whose header says `dtype` and `shape` over `data`.
    fn raw_file(dtype: &str, shape: &str, data: &[u8]) -> Vec<u8> {
        let header = format!(
            r#"{{"t":{{"dtype":"{dtype}","shape":{shape},"data_offsets":[0,{}]}}}}"#,
            data.len()
        );
        let mut out = (header.len() as u64).to_le_bytes().to_vec();
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(data);
        out
    }

    #[test]
    fn huge_declared_shapes_are_refused_before_allocating() {
        let origin = Path::new("huge.safetensors");
        // 2^40 x 2^40 values over 4 bytes, a product that overflows, and one that fits usize
        // but not the file: all refused (no allocation, no panic), naming file and tensor
        for shape in [
            "[1099511627776,1099511627776]",
            "[4294967296,4294967296,4294967296]",
            "[18446744073709551615,2]",
            "[1000000000]",
            "[2,0,3]",
        ] {
            let bytes = raw_file("F32", shape, &[0, 0, 128, 63]);
            let e = TensorFile::from_bytes(&bytes, origin).unwrap_err().to_string();
            assert!(e.starts_with("huge.safetensors: "), "{shape}: {e}");
        }
        // the same header with the data it declares is fine
        let ok = TensorFile::from_bytes(&raw_file("F32", "[1]", &[0, 0, 128, 63]), origin).unwrap();
        assert_eq!(ok.get_f32("t", &[1]).unwrap(), &[1.0]);
        assert_eq!(checked_numel(&[usize::MAX, 2]), None);
        assert_eq!(checked_numel(&[0, usize::MAX]), Some(0));
        assert_eq!(checked_numel(&[]), Some(1));
    }

    #[test]
    fn non_finite_values_are_found_with_their_index() {
        let mut f = sample();
        f.origin = Some(PathBuf::from("run/fields.safetensors"));
        assert!(f.check_all_finite().is_ok());
        let mut v: Vec<f32> = (0..24).map(|i| i as f32).collect();
        v[17] = f32::NAN;
        v[20] = f32::INFINITY;
        f.insert_f32("density.plane", &[2, 3, 4], v);
        let e = f.check_all_finite().unwrap_err();
        assert!(
            matches!(&e, CoreError::TensorNonFinite { name, index: 17, .. } if name == "density.plane"),
            "{e}"
        );
        assert_eq!(
            e.to_string(),
            "run/fields.safetensors: tensor \"density.plane\" has a non-finite value (NaN) at index 17"
        );
        assert!(f.check_finite("mask").is_ok());
        assert!(f.check_finite("absent").is_err());
        assert_eq!(first_non_finite(&[0.0, f32::NEG_INFINITY]), Some((1, f32::NEG_INFINITY)));
        assert_eq!(first_non_finite(&[]), None);
    }

    /// Decode a safetensors file without the `safetensors` crate, documenting the format:
    /// returns metadata and, per tensor, (dtype, shape, raw bytes).
    #[allow(clippy::type_complexity)]
    fn independent_read(
        bytes: &[u8],
    ) -> (BTreeMap<String, String>, BTreeMap<String, (String, Vec<usize>, Vec<u8>)>) {
        let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
        let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + n]).unwrap();
        let data = &bytes[8 + n..];
        assert_eq!(
            (8 + n) % 8,
            0,
            "data section starts 8-byte aligned (header padded with spaces)"
        );
        let mut meta = BTreeMap::new();
        let mut tensors = BTreeMap::new();
        let mut spans = Vec::new();
        for (name, entry) in header.as_object().expect("header is a JSON object") {
            if name == "__metadata__" {
                for (k, v) in entry.as_object().unwrap() {
                    meta.insert(
                        k.clone(),
                        v.as_str().expect("metadata values are strings").to_string(),
                    );
                }
                continue;
            }
            let dtype = entry["dtype"].as_str().unwrap().to_string();
            let shape: Vec<usize> = entry["shape"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| d.as_u64().unwrap() as usize)
                .collect();
            let offs = entry["data_offsets"].as_array().unwrap();
            let (b, e) = (offs[0].as_u64().unwrap() as usize, offs[1].as_u64().unwrap() as usize);
            let size = match dtype.as_str() {
                "F32" => 4,
                "U8" => 1,
                "I64" => 8,
                other => panic!("unexpected dtype {other}"),
            };
            assert_eq!(
                e - b,
                shape.iter().product::<usize>() * size,
                "{name}: byte span matches shape"
            );
            spans.push((b, e));
            tensors.insert(name.clone(), (dtype, shape, data[b..e].to_vec()));
        }
        // the tensors tile the data section exactly
        spans.sort();
        let mut at = 0;
        for (b, e) in spans {
            assert_eq!(b, at);
            at = e;
        }
        assert_eq!(at, data.len());
        (meta, tensors)
    }

    #[test]
    fn file_opens_outside_this_crate() {
        let dir = scratch("python");
        let path = dir.join("fields.safetensors");
        let f = sample();
        f.save(&path).unwrap();

        let bytes = std::fs::read(&path).unwrap();
        let (meta, tensors) = independent_read(&bytes);
        assert_eq!(meta, f.metadata);
        let (dtype, shape, raw) = &tensors["density.plane"];
        assert_eq!((dtype.as_str(), shape.as_slice()), ("F32", &[2usize, 3, 4][..]));
        let values: Vec<f32> =
            raw.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
        assert_eq!(values, (0..24).map(|i| i as f32 * 0.5 - 3.0).collect::<Vec<_>>());
        let (dtype, shape, raw) = &tensors["ids"];
        assert_eq!((dtype.as_str(), shape.as_slice()), ("I64", &[2usize, 2][..]));
        assert_eq!(i64::from_le_bytes(raw[16..24].try_into().unwrap()), 1 << 40);
        assert_eq!(tensors["mask"].2, vec![0, 1, 2, 254, 255]);
        assert_eq!(tensors.len(), 5);

        let python = std::process::Command::new("python3")
            .args(["-c", "import numpy, safetensors"])
            .output()
            .is_ok_and(|o| o.status.success());
        if python {
            let script = r#"
import sys, json
import numpy as np
from safetensors import safe_open
from safetensors.numpy import load_file
t = load_file(sys.argv[1])
a = t["density.plane"]
assert a.shape == (2, 3, 4) and a.dtype == np.float32, (a.shape, a.dtype)
assert np.array_equal(a.ravel(), np.arange(24, dtype=np.float32) * 0.5 - 3.0)
assert t["mask"].dtype == np.uint8 and list(t["mask"]) == [0, 1, 2, 254, 255]
assert t["ids"].dtype == np.int64 and t["ids"][1, 0] == 1 << 40
with safe_open(sys.argv[1], framework="numpy") as f:
    assert json.loads(f.metadata()["config"])["resolution"] == 300
print("OK")
"#;
            let out = std::process::Command::new("python3")
                .args(["-c", script])
                .arg(&path)
                .output()
                .unwrap();
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(
                out.status.success() && stdout.trim() == "OK",
                "python check failed: {stdout}\n{}",
                String::from_utf8_lossy(&out.stderr)
            );
            eprintln!(
                "safetensors file checked by the independent reader and by Python (safetensors.numpy)"
            );
        } else {
            eprintln!(
                "safetensors file checked by the independent reader only (python3 with numpy and safetensors not available)"
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
