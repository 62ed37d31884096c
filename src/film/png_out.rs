use super::{Image, Staged, stage, write_atomically};
use crate::{Error, Result};
use std::path::Path;

/// Linear to sRGB transfer.
#[inline]
fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 }
}

/// 8-bit sRGB bytes of `image` scaled by `2^exposure` (clamped, no tone curve).
#[must_use]
pub fn to_srgb8(image: &Image, exposure: f32) -> Vec<u8> {
    let scale = exposure.exp2();
    image
        .pixels
        .iter()
        .flat_map(|p| p.map(|c| (srgb_encode((c * scale).clamp(0.0, 1.0)) * 255.0 + 0.5) as u8))
        .collect()
}

/// Writes an 8-bit sRGB PNG of `image` scaled by `2^exposure` (clamped, no tone curve).
pub fn write_png(path: &Path, image: &Image, exposure: f32) -> Result<()> {
    write_rgb8(path, image.width, image.height, &to_srgb8(image, exposure))
}

/// [`write_png`] to a temporary file, for [`super::commit`] with other outputs.
pub fn stage_png(path: &Path, image: &Image, exposure: f32) -> Result<Staged> {
    let bytes = to_srgb8(image, exposure);
    let (width, height) = (image.width, image.height);
    let err = |e: png::EncodingError| Error::Image { path: path.to_path_buf(), message: e.to_string() };
    stage(path, |w| encode_rgb8(w, width, height, &bytes).map_err(err))
}

fn encode_rgb8(w: &mut impl std::io::Write, width: u32, height: u32, bytes: &[u8]) -> Result<(), png::EncodingError> {
    let mut enc = png::Encoder::new(w, width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    let mut writer = enc.write_header()?;
    writer.write_image_data(bytes)?;
    writer.finish()
}

/// Writes 8-bit RGB bytes as a PNG, atomically.
pub fn write_rgb8(path: &Path, width: u32, height: u32, bytes: &[u8]) -> Result<()> {
    let err = |e: png::EncodingError| Error::Image { path: path.to_path_buf(), message: e.to_string() };
    write_atomically(path, |w| encode_rgb8(w, width, height, bytes).map_err(err))
}
