//! Reading a bitmap from an image file.
use super::{Bitmap, Filter, Wrap, srgb_to_linear};
use crate::geometry::Vec3A;
use std::path::Path;

impl Bitmap {
    /// Reads a PNG (8 or 16 bits, grey or colour, any alpha ignored; decoded from sRGB unless
    /// `raw`, Mitsuba's flag for data such as roughness) or an EXR (linear), by extension.
    pub fn load(path: &Path, wrap: Wrap, filter: Filter, raw: bool) -> crate::Result<Self> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => load_png(path, wrap, filter, raw),
            Some("exr") => {
                let (image, _) = crate::film::read_exr(path)?;
                let texels = image.pixels.iter().map(|p| Vec3A::from_array(*p)).collect();
                Self::new(image.width as usize, image.height as usize, texels, wrap, filter).ok_or_else(|| {
                    crate::Error::Image { path: path.to_path_buf(), message: "the image has no pixels".into() }
                })
            }
            _ => Err(crate::Error::Image {
                path: path.to_path_buf(),
                message: "textures are read from .png (sRGB) or .exr (linear) files".into(),
            }),
        }
    }
}

/// Most bytes a PNG may decode to (a 16k × 16k RGBA image at 16 bits is 2 GiB).
const PNG_LIMIT: usize = 2 << 30;

fn load_png(path: &Path, wrap: Wrap, filter: Filter, raw: bool) -> crate::Result<Bitmap> {
    let err = |message: String| crate::Error::Image { path: path.to_path_buf(), message };
    let file = std::fs::File::open(path).map_err(|e| crate::Error::io(path, e))?;
    let mut decoder = png::Decoder::new_with_limits(std::io::BufReader::new(file), png::Limits { bytes: PNG_LIMIT });
    // Palettes and bit depths below 8 to 8-bit channels; transparency to an alpha channel.
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(|e| err(format!("not a readable PNG: {e}")))?;
    let size = reader.output_buffer_size().ok_or_else(|| err("the image is too large".into()))?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(|e| err(format!("not a readable PNG: {e}")))?;
    let channels = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err(err("an indexed PNG was not expanded".into())),
    };
    let bytes_per = match info.bit_depth {
        png::BitDepth::Eight => 1,
        png::BitDepth::Sixteen => 2,
        d => return Err(err(format!("unsupported bit depth {d:?}"))),
    };
    let (w, h) = (info.width as usize, info.height as usize);
    let decode = |c: f32| if raw { c } else { srgb_to_linear(c) };
    let lut: Vec<f32> = (0..256).map(|v| decode(v as f32 / 255.0)).collect();
    let value = |row: &[u8], k: usize| -> f32 {
        if bytes_per == 1 {
            lut[row[k] as usize]
        } else {
            decode(f32::from(u16::from_be_bytes([row[2 * k], row[2 * k + 1]])) / 65535.0)
        }
    };
    let mut texels = Vec::with_capacity(w * h);
    for r in 0..h {
        let row = &buf[r * info.line_size..r * info.line_size + w * channels * bytes_per];
        for i in 0..w {
            let k = i * channels;
            texels.push(if channels < 3 {
                Vec3A::splat(value(row, k))
            } else {
                Vec3A::new(value(row, k), value(row, k + 1), value(row, k + 2))
            });
        }
    }
    Bitmap::new(w, h, texels, wrap, filter).ok_or_else(|| err("the image has no pixels".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_png(path: &Path, w: u32, h: u32, color: png::ColorType, depth: png::BitDepth, data: &[u8]) {
        let file = std::fs::File::create(path).unwrap();
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        enc.write_header().unwrap().write_image_data(data).unwrap();
    }

    #[test]
    fn pngs_decode_from_srgb_and_bad_files_are_errors() {
        let dir = std::env::temp_dir().join(format!("zvidpt-texture-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rgb = dir.join("rgb.png");
        write_png(&rgb, 2, 1, png::ColorType::Rgb, png::BitDepth::Eight, &[255, 0, 128, 0, 64, 255]);
        let b = Bitmap::load(&rgb, Wrap::Clamp, Filter::Nearest, false).unwrap();
        assert_eq!((b.width, b.height), (2, 1));
        assert!((b.texels[0] - Vec3A::new(1.0, 0.0, srgb_to_linear(128.0 / 255.0))).abs().max_element() < 1e-6);
        assert!((b.texels[1] - Vec3A::new(0.0, srgb_to_linear(64.0 / 255.0), 1.0)).abs().max_element() < 1e-6);
        let grey16 = dir.join("grey16.png");
        write_png(
            &grey16,
            1,
            2,
            png::ColorType::GrayscaleAlpha,
            png::BitDepth::Sixteen,
            &[0x80, 0x00, 0xff, 0xff, 0xff, 0xff, 0x00, 0x00],
        );
        let g = Bitmap::load(&grey16, Wrap::Clamp, Filter::Nearest, false).unwrap();
        assert!((g.texels[0] - Vec3A::splat(srgb_to_linear(32768.0 / 65535.0))).abs().max_element() < 1e-6);
        assert_eq!(g.texels[1], Vec3A::ONE);
        // Not a PNG, missing, unknown extension: errors that name the file.
        let junk = dir.join("junk.png");
        std::fs::write(&junk, b"not a png at all").unwrap();
        for p in [junk, dir.join("missing.png"), dir.join("texture.bmp")] {
            let e = Bitmap::load(&p, Wrap::Repeat, Filter::Bilinear, false).unwrap_err().to_string();
            assert!(e.contains(p.file_name().unwrap().to_str().unwrap()), "{e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
