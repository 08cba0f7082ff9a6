//! Per-view feature maps (e.g. DINO features exported from Python) that I-AssetField learns as
//! its semantic field: one file per training image, `.npy` or `.safetensors`, shape
//! `(H, W, C)` (or `(H, W)` for one channel), at any resolution (sampled bilinearly at each
//! pixel centre).

use crate::DataError;
use assetfield_core::TensorFile;
use std::path::{Path, PathBuf};

/// A feature map: `height x width` texels of `channels` values, row-major, channels fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureMap {
    pub width: u32,
    pub height: u32,
    pub channels: usize,
    pub data: Vec<f32>,
}

/// File extensions searched for a view's feature map, in order.
pub const FEATURE_EXTENSIONS: [&str; 2] = ["npy", "safetensors"];

fn bad(path: &Path, reason: impl Into<String>) -> DataError {
    DataError::Features { path: path.to_path_buf(), reason: reason.into() }
}

impl FeatureMap {
    /// Read a `.npy` (little-endian float16/32/64, C order) or `.safetensors` (F32; the
    /// tensor named `features`, or the only tensor) file.
    pub fn load(path: &Path) -> Result<FeatureMap, DataError> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        let (shape, data) = match ext.as_str() {
            "npy" => {
                let bytes = std::fs::read(path)
                    .map_err(|e| DataError::Io { path: path.to_path_buf(), source: e })?;
                parse_npy(&bytes).map_err(|r| bad(path, r))?
            }
            "safetensors" => {
                let mut f = TensorFile::load(path)?;
                let names: Vec<String> = f.names().map(str::to_owned).collect();
                let name = if names.iter().any(|n| n == "features") {
                    "features".to_string()
                } else if names.len() == 1 {
                    names[0].clone()
                } else {
                    return Err(bad(
                        path,
                        format!(
                            "expected a tensor named \"features\" or exactly one tensor, found {}",
                            names.join(", ")
                        ),
                    ));
                };
                let shape = f.shape_of(&name).unwrap_or(&[]).to_vec();
                let data = f.take_f32(&name, &shape)?;
                (shape, data)
            }
            _ => return Err(bad(path, "feature maps must be .npy or .safetensors files")),
        };
        let (h, w, c) = match shape.as_slice() {
            [h, w] => (*h, *w, 1),
            [h, w, c] => (*h, *w, *c),
            s => {
                return Err(bad(path, format!("expected shape (H, W, C) or (H, W), found {s:?}")));
            }
        };
        if h == 0 || w == 0 || c == 0 {
            return Err(bad(path, format!("empty feature map of shape {shape:?}")));
        }
        let side = crate::validate::MAX_IMAGE_SIDE as usize;
        if h > side || w > side {
            return Err(bad(
                path,
                format!("feature map of shape {shape:?}: at most {side} pixels per side"),
            ));
        }
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            return Err(bad(path, format!("value {i} is not finite ({})", data[i])));
        }
        Ok(FeatureMap { width: w as u32, height: h as u32, channels: c, data })
    }

    /// Bilinear sample at the centre of pixel `(i, j)` of an image `image_w x image_h`
    /// (the map may have another resolution; edges are clamped), into `out` (`channels`).
    pub fn sample_pixel(&self, i: u32, j: u32, image_w: u32, image_h: u32, out: &mut [f32]) {
        let x = (i as f32 + 0.5) * self.width as f32 / image_w as f32 - 0.5;
        let y = (j as f32 + 0.5) * self.height as f32 / image_h as f32 - 0.5;
        let (w, h, c) = (self.width as usize, self.height as usize, self.channels);
        let x = x.clamp(0.0, (w - 1) as f32);
        let y = y.clamp(0.0, (h - 1) as f32);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let at = |xx: usize, yy: usize| &self.data[(yy * w + xx) * c..][..c];
        let (a, b, cc, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
        for k in 0..c {
            out[k] = (1.0 - fy) * ((1.0 - fx) * a[k] + fx * b[k])
                + fy * ((1.0 - fx) * cc[k] + fx * d[k]);
        }
    }

    /// Write as `.npy` (float32, shape `(H, W, C)`), atomically.
    pub fn save_npy(&self, path: &Path) -> Result<(), DataError> {
        let shape = [self.height as usize, self.width as usize, self.channels];
        assetfield_core::fsx::write_atomic(path, &npy_bytes(&shape, &self.data))?;
        Ok(())
    }
}

/// The file holding the feature map of the image `image_path` in `dir`: the image's file
/// stem with one of [`FEATURE_EXTENSIONS`].
pub fn find_feature_file(dir: &Path, image_path: &Path) -> Result<PathBuf, Vec<PathBuf>> {
    let stem = image_path.file_stem().map(|s| s.to_os_string()).unwrap_or_default();
    let tried: Vec<PathBuf> = FEATURE_EXTENSIONS
        .iter()
        .map(|e| {
            let mut name = stem.clone();
            name.push(".");
            name.push(e);
            dir.join(name)
        })
        .collect();
    tried.iter().find(|p| p.is_file()).cloned().ok_or(tried)
}

/// A float32 `.npy` file (version 1.0) of `shape` holding `data` in C order.
pub fn npy_bytes(shape: &[usize], data: &[f32]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_txt =
        if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // magic (6) + version (2) + header length (2) + header + newline, padded to 64 bytes
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat(total.next_multiple_of(64) - total));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len() * 4);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Parse a `.npy` file: `(shape, values as f32)`.
fn parse_npy(bytes: &[u8]) -> Result<(Vec<usize>, Vec<f32>), String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy file (no \\x93NUMPY magic)".into());
    }
    let (major, rest) = (bytes[6], &bytes[8..]);
    let (hlen, rest) = match major {
        1 => (u16::from_le_bytes([rest[0], rest[1]]) as usize, &rest[2..]),
        2 | 3 => {
            if rest.len() < 4 {
                return Err("truncated header".into());
            }
            (u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]) as usize, &rest[4..])
        }
        v => return Err(format!("unsupported .npy version {v}")),
    };
    if rest.len() < hlen {
        return Err("truncated header".into());
    }
    let header = std::str::from_utf8(&rest[..hlen]).map_err(|_| "header is not text")?;
    let body = &rest[hlen..];
    let value_of = |key: &str| -> Result<&str, String> {
        let k = format!("'{key}'");
        let at = header.find(&k).ok_or(format!("header has no {k}"))? + k.len();
        let after = header[at..].trim_start().strip_prefix(':').ok_or("malformed header")?;
        Ok(after.trim_start())
    };
    let descr = value_of("descr")?;
    let descr = descr.get(1..).and_then(|d| d.split('\'').next()).ok_or("malformed descr")?;
    if value_of("fortran_order")?.starts_with("True") {
        return Err("Fortran-order arrays are not supported; save with np.ascontiguousarray".into());
    }
    let shape_txt = value_of("shape")?;
    let close = shape_txt.find(')').ok_or("malformed shape")?;
    let shape = shape_txt[1..close]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>().map_err(|_| format!("bad dimension {s:?}")))
        .collect::<Result<Vec<_>, _>>()?;
    let size = match descr {
        "<f4" | "=f4" => 4,
        "<f2" | "=f2" => 2,
        "<f8" | "=f8" => 8,
        d => return Err(format!("dtype {d} is not supported (little-endian float16/32/64 are)")),
    };
    // the header's shape is checked against the data before anything is allocated from it
    let bytes = assetfield_core::checked_numel(&shape).and_then(|n| n.checked_mul(size));
    let Some(bytes) = bytes.filter(|b| *b <= body.len()) else {
        return Err(format!(
            "data holds {} bytes, shape {shape:?} of {descr} needs {}",
            body.len(),
            bytes.map_or_else(|| "more than can be counted".to_string(), |b| b.to_string())
        ));
    };
    let n = bytes / size;
    let data = body[..n * size]
        .chunks_exact(size)
        .map(|b| match size {
            4 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            2 => f16_to_f32(u16::from_le_bytes([b[0], b[1]])),
            _ => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32,
        })
        .collect();
    Ok((shape, data))
}

/// IEEE half to single precision.
fn f16_to_f32(h: u16) -> f32 {
    let sign = ((h >> 15) as u32) << 31;
    let exp = ((h >> 10) & 0x1f) as u32;
    let frac = (h & 0x3ff) as u32;
    let bits = match (exp, frac) {
        (0, 0) => sign,
        (0, f) => {
            // subnormal: value = f * 2^-24
            return if sign != 0 { -(f as f32) } else { f as f32 } * (2.0f32).powi(-24);
        }
        (31, 0) => sign | 0x7f80_0000,
        (31, f) => sign | 0x7f80_0000 | (f << 13),
        (e, f) => sign | ((e + 112) << 23) | (f << 13),
    };
    f32::from_bits(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn npy_headers_with_huge_shapes_are_refused() {
        for shape in [vec![4_294_967_296, 4_294_967_296, 2], vec![usize::MAX, 3], vec![1000, 1000]]
        {
            let mut bytes = npy_bytes(&shape, &[]);
            bytes.extend_from_slice(&[0; 16]);
            let e = parse_npy(&bytes).unwrap_err();
            assert!(e.contains("data holds 16 bytes"), "{shape:?}: {e}");
        }
    }

    #[test]
    fn npy_round_trip_and_f16() {
        let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.5 - 3.0).collect();
        let bytes = npy_bytes(&[2, 3, 4], &data);
        assert_eq!((bytes.len() - data.len() * 4) % 64, 0, "header padded to 64 bytes");
        let (shape, back) = parse_npy(&bytes).unwrap();
        assert_eq!(shape, vec![2, 3, 4]);
        assert_eq!(back, data);
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x3555), 0.333_251_95);
        assert_eq!(f16_to_f32(0x0001), 2.0f32.powi(-24));
    }

    #[test]
    fn npy_errors_say_what_is_wrong() {
        assert!(parse_npy(b"hello world").unwrap_err().contains("magic"));
        let mut bytes = npy_bytes(&[2, 2], &[1.0, 2.0, 3.0, 4.0]);
        bytes.truncate(bytes.len() - 4);
        assert!(parse_npy(&bytes).unwrap_err().contains("needs 16"));
        let mut b = npy_bytes(&[1], &[1.0]);
        let at = b.windows(3).position(|w| w == b"<f4").unwrap();
        b[at] = b'>';
        assert!(parse_npy(&b).unwrap_err().contains(">f4"));
    }

    #[test]
    fn sampling_maps_pixel_centres_across_resolutions() {
        // 2x2 map, one channel: values 0 1 / 2 3; a 4x4 image samples it bilinearly
        let m = FeatureMap { width: 2, height: 2, channels: 1, data: vec![0.0, 1.0, 2.0, 3.0] };
        let mut v = [0.0f32];
        m.sample_pixel(0, 0, 4, 4, &mut v);
        assert_eq!(v[0], 0.0, "clamped corner");
        m.sample_pixel(3, 3, 4, 4, &mut v);
        assert_eq!(v[0], 3.0);
        m.sample_pixel(1, 0, 4, 4, &mut v);
        assert!((v[0] - 0.25).abs() < 1e-6, "{}", v[0]);
        m.sample_pixel(1, 1, 2, 2, &mut v);
        assert_eq!(v[0], 3.0, "same resolution reads texels exactly");
    }
}
