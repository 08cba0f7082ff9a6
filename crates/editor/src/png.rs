//! PNG encoding of renders and pictures, in memory.

use assetfield_data::ImageF32;

use crate::error::{EditorError, Result};

fn encode(img: image::DynamicImage) -> Result<Vec<u8>> {
    let mut buf = std::io::Cursor::new(Vec::new());
    img.write_to(&mut buf, image::ImageFormat::Png).map_err(|e| EditorError::Io {
        context: "encoding a PNG".into(),
        source: assetfield_core::CoreError::Image { path: "(in memory)".into(), source: e },
    })?;
    Ok(buf.into_inner())
}

/// A render (`3 * width * height` linear values in `[0, 1]`, row-major) as PNG bytes,
/// quantised as every image the command line writes is ([`ImageF32::to_rgb8`]).
pub fn encode_rgb_f32(width: u32, height: u32, rgb: Vec<f32>) -> Result<Vec<u8>> {
    encode(ImageF32 { width, height, rgb, alpha: None }.to_rgb8().into())
}

/// 8-bit RGB pixels (row-major) as PNG bytes.
pub fn encode_rgb8(width: u32, height: u32, pixels: &[[u8; 3]]) -> Result<Vec<u8>> {
    let raw: Vec<u8> = pixels.iter().flatten().copied().collect();
    let img = image::RgbImage::from_raw(width, height, raw).ok_or_else(|| {
        EditorError::BadRequest(format!("{} pixels do not make {width} x {height}", pixels.len()))
    })?;
    encode(img.into())
}
