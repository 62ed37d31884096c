//! Reading a bitmap from an image file: PNG (8 or 16 bits, streamed), TGA and JPEG (the `image`
//! crate), sRGB-decoded unless raw; OpenEXR, PFM and Radiance HDR, linear. Sizes are bounded
//! from the header before any allocation.
use super::{Bitmap, Filter, Texels, Wrap, srgb_to_linear};
use crate::geometry::Vec3A;
use std::path::Path;

/// Largest image file read (a 16k × 16k float RGB image is 3 GiB; PNG and EXR stream instead).
const MAX_IMAGE_FILE_BYTES: u64 = 4 << 30;

/// The image formats a bitmap is read from, by file extension (case ignored).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// PNG, 8 or 16 bits: sRGB unless raw.
    Png,
    /// OpenEXR: linear.
    Exr,
    /// Portable float map (`PF` colour, `Pf` grey): linear.
    Pfm,
    /// Radiance RGBE (`.hdr`, `.pic`): linear.
    Hdr,
    /// Truevision TGA, 8 bits: sRGB unless raw.
    Tga,
    /// JPEG: sRGB unless raw.
    Jpeg,
}

impl ImageFormat {
    /// The format a file's extension names.
    #[must_use]
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        Some(match ext.as_deref()? {
            "png" => Self::Png,
            "exr" => Self::Exr,
            "pfm" => Self::Pfm,
            "hdr" | "pic" | "rgbe" => Self::Hdr,
            "tga" | "targa" => Self::Tga,
            "jpg" | "jpeg" => Self::Jpeg,
            _ => return None,
        })
    }

    /// Whether the file stores linear values (float formats); the others hold display values
    /// that are decoded from sRGB unless the texture is raw, as pbrt-v4 and Mitsuba 3 do.
    #[must_use]
    pub fn is_linear(self) -> bool {
        matches!(self, Self::Exr | Self::Pfm | Self::Hdr)
    }
}

impl Bitmap {
    /// Reads an image by its extension: PNG (8 or 16 bits), TGA and JPEG, decoded from sRGB
    /// unless `raw` (data such as roughness); EXR, PFM and Radiance HDR, linear. Grey images
    /// give grey texels; alpha is ignored. Sizes are checked before pixels are allocated.
    pub fn load(path: &Path, wrap: Wrap, filter: Filter, raw: bool) -> crate::Result<Self> {
        let err = |message: String| crate::Error::Image { path: path.to_path_buf(), message };
        let Some(format) = ImageFormat::from_path(path) else {
            return Err(err(
                "textures are read from .png, .tga, .jpg (sRGB unless raw), .exr, .pfm or .hdr (linear) files".into(),
            ));
        };
        let (width, height, texels) = match format {
            ImageFormat::Png => return load_png(path, wrap, filter, raw),
            ImageFormat::Exr => {
                let (image, _) = crate::film::read_exr(path)?;
                let texels = image.pixels.iter().map(|p| Vec3A::from_array(*p)).collect();
                (image.width as usize, image.height as usize, Texels::Linear(texels))
            }
            _ => {
                let bytes = crate::io::read_bounded(path, MAX_IMAGE_FILE_BYTES, "image file")?;
                decode_texels(&bytes, format, raw).map_err(err)?
            }
        };
        Self::with_texels(width, height, texels, wrap, filter).ok_or_else(|| err("the image has no pixels".into()))
    }
}

/// Decodes an image held in memory (any format but PNG and EXR, which are read from their
/// files): its width, height and linear texels, row-major from the top row.
pub fn decode(bytes: &[u8], format: ImageFormat, raw: bool) -> Result<(usize, usize, Vec<Vec3A>), String> {
    decode_texels(bytes, format, raw).map(|(w, h, t)| (w, h, t.into_linear()))
}

fn decode_texels(bytes: &[u8], format: ImageFormat, raw: bool) -> Result<(usize, usize, Texels), String> {
    match format {
        ImageFormat::Pfm => decode_pfm(bytes).map(|(w, h, t)| (w, h, Texels::Linear(t))),
        ImageFormat::Hdr | ImageFormat::Tga | ImageFormat::Jpeg => decode_with_image(bytes, format, raw),
        ImageFormat::Png | ImageFormat::Exr => Err(format!("{format:?} images are read from files")),
    }
}

/// A portable float map: a header `PF` (RGB) or `Pf` (grey), width, height and a scale whose
/// sign gives the byte order (negative: little-endian), then 32-bit floats, rows from the
/// *bottom* of the image.
fn decode_pfm(bytes: &[u8]) -> Result<(usize, usize, Vec<Vec3A>), String> {
    // The header: three whitespace-separated tokens after the magic, ended by one whitespace byte.
    let mut at = 0;
    let mut token = || -> Result<&str, String> {
        while at < bytes.len() && bytes[at].is_ascii_whitespace() {
            at += 1;
        }
        let start = at;
        while at < bytes.len() && !bytes[at].is_ascii_whitespace() && at - start < 64 {
            at += 1;
        }
        if start == at || at >= bytes.len() {
            return Err("not a PFM file: its header ends early".into());
        }
        std::str::from_utf8(&bytes[start..at]).map_err(|_| "not a PFM file: its header is not text".to_string())
    };
    let channels = match token()? {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err("not a PFM file (it starts with neither PF nor Pf)".into()),
    };
    let number = |t: &str, what: &str| t.parse::<usize>().map_err(|_| format!("not a PFM file: its {what} is {t:?}"));
    let width = number(token()?, "width")?;
    let height = number(token()?, "height")?;
    let scale: f32 = token()?.parse().map_err(|_| "not a PFM file: its scale is not a number".to_string())?;
    if !scale.is_finite() || scale == 0.0 {
        return Err(format!("not a PFM file: its scale is {scale}"));
    }
    at += 1; // the single whitespace byte after the scale
    let pixels = width.checked_mul(height).filter(|&n| n > 0 && n as u64 <= crate::film::MAX_PIXELS);
    let Some(pixels) = pixels else {
        return Err(format!(
            "claims {width}x{height} pixels; this reader takes 1 to {} pixels",
            crate::film::MAX_PIXELS
        ));
    };
    let data = &bytes[at.min(bytes.len())..];
    let need = pixels * channels * 4;
    if data.len() < need {
        return Err(format!("claims {width}x{height} pixels, but holds {} of their {need} bytes", data.len()));
    }
    let little = scale < 0.0;
    let value = |k: usize| {
        let b = [data[4 * k], data[4 * k + 1], data[4 * k + 2], data[4 * k + 3]];
        let v = if little { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) };
        if v.is_finite() { v } else { 0.0 }
    };
    let mut texels = Vec::with_capacity(pixels);
    for row in (0..height).rev() {
        for i in 0..width {
            let k = (row * width + i) * channels;
            texels.push(if channels == 1 {
                Vec3A::splat(value(k))
            } else {
                Vec3A::new(value(k), value(k + 1), value(k + 2))
            });
        }
    }
    Ok((width, height, texels))
}

/// TGA, JPEG and Radiance HDR through the `image` crate, with its limits set from ours so
/// that a crafted header is an error before anything is allocated.
fn decode_with_image(bytes: &[u8], format: ImageFormat, raw: bool) -> Result<(usize, usize, Texels), String> {
    let kind = match format {
        ImageFormat::Hdr => image::ImageFormat::Hdr,
        ImageFormat::Tga => image::ImageFormat::Tga,
        _ => image::ImageFormat::Jpeg,
    };
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(crate::film::MAX_PIXELS as u32);
    limits.max_image_height = Some(crate::film::MAX_PIXELS as u32);
    limits.max_alloc = Some(crate::film::MAX_PIXELS * 16);
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), kind);
    reader.limits(limits.clone());
    let (w, h) = reader.into_dimensions().map_err(|e| format!("not a readable {format:?} image: {e}"))?;
    if u64::from(w) * u64::from(h) > crate::film::MAX_PIXELS {
        return Err(format!("claims {w}x{h} pixels; this reader takes at most {} pixels", crate::film::MAX_PIXELS));
    }
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), kind);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| format!("not a readable {format:?} image: {e}"))?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let texels = if format.is_linear() {
        Texels::Linear(img.into_rgb32f().pixels().map(|p| Vec3A::new(p[0], p[1], p[2]).max(Vec3A::ZERO)).collect())
    } else {
        // 8- or 16-bit display values, each channel through one table (or the curve).
        let decode = |c: f32| if raw { c } else { srgb_to_linear(c) };
        match img {
            image::DynamicImage::ImageLuma16(_)
            | image::DynamicImage::ImageLumaA16(_)
            | image::DynamicImage::ImageRgb16(_)
            | image::DynamicImage::ImageRgba16(_) => Texels::Linear(
                img.into_rgb16()
                    .pixels()
                    .map(|p| Vec3A::from_array(p.0.map(|c| decode(f32::from(c) / 65535.0))))
                    .collect(),
            ),
            _ => Texels::Coded { codes: img.into_rgb8().pixels().map(|p| p.0).collect(), table: code_table(raw) },
        }
    };
    if texels.len() != w * h {
        return Err(format!("decoded {} texels for {w}x{h}", texels.len()));
    }
    Ok((w, h, texels))
}

/// The table that decodes an 8-bit code of each channel: `code / 255`, from sRGB unless raw.
fn code_table(raw: bool) -> Box<[[f32; 256]; 3]> {
    let value = |v: usize| if raw { v as f32 / 255.0 } else { srgb_to_linear(v as f32 / 255.0) };
    let row: [f32; 256] = std::array::from_fn(value);
    Box::new([row; 3])
}

/// Most bytes a PNG may decode to (a 16k × 16k RGBA image at 16 bits is 2 GiB).
const PNG_LIMIT: usize = 2 << 30;

fn load_png(path: &Path, wrap: Wrap, filter: Filter, raw: bool) -> crate::Result<Bitmap> {
    let err = |message: String| crate::Error::Image { path: path.to_path_buf(), message };
    let file = crate::io::open_regular(path, "texture")?;
    let mut decoder = png::Decoder::new_with_limits(std::io::BufReader::new(file), png::Limits { bytes: PNG_LIMIT });
    // Palettes and bit depths below 8 to 8-bit channels; transparency to an alpha channel.
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(|e| err(format!("not a readable PNG: {e}")))?;
    // From the header, before anything the size of the image is allocated.
    let (w, h) = (reader.info().width, reader.info().height);
    if u64::from(w) * u64::from(h) > crate::film::MAX_PIXELS {
        return Err(err(format!(
            "claims {w}x{h} pixels; this reader takes at most {} pixels",
            crate::film::MAX_PIXELS
        )));
    }
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
    let eight_bits = match info.bit_depth {
        png::BitDepth::Eight => true,
        png::BitDepth::Sixteen => false,
        d => return Err(err(format!("unsupported bit depth {d:?}"))),
    };
    let (w, h) = (info.width as usize, info.height as usize);
    let decode = |c: f32| if raw { c } else { srgb_to_linear(c) };
    if eight_bits {
        let mut codes = Vec::with_capacity(w * h);
        for r in 0..h {
            let row = &buf[r * info.line_size..r * info.line_size + w * channels];
            codes.extend(row.chunks_exact(channels).map(|p| if channels < 3 { [p[0]; 3] } else { [p[0], p[1], p[2]] }));
        }
        drop(buf);
        let texels = Texels::Coded { codes, table: code_table(raw) };
        return Bitmap::with_texels(w, h, texels, wrap, filter).ok_or_else(|| err("the image has no pixels".into()));
    }
    // 16 bits a channel, big-endian: decoded to linear floats.
    let value = |row: &[u8], k: usize| decode(f32::from(u16::from_be_bytes([row[2 * k], row[2 * k + 1]])) / 65535.0);
    let mut texels = Vec::with_capacity(w * h);
    for r in 0..h {
        let row = &buf[r * info.line_size..r * info.line_size + w * channels * 2];
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
        assert!(matches!(b.texels, Texels::Coded { .. }), "8-bit images are stored coded");
        assert!((b.texels.get(0) - Vec3A::new(1.0, 0.0, srgb_to_linear(128.0 / 255.0))).abs().max_element() < 1e-6);
        assert!((b.texels.get(1) - Vec3A::new(0.0, srgb_to_linear(64.0 / 255.0), 1.0)).abs().max_element() < 1e-6);
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
        assert!((g.texels.get(0) - Vec3A::splat(srgb_to_linear(32768.0 / 65535.0))).abs().max_element() < 1e-6);
        assert_eq!(g.texels.get(1), Vec3A::ONE);
        // Not a PNG, missing, unknown extension: errors that name the file.
        let junk = dir.join("junk.png");
        std::fs::write(&junk, b"not a png at all").unwrap();
        for p in [junk, dir.join("missing.png"), dir.join("texture.bmp")] {
            let e = Bitmap::load(&p, Wrap::Repeat, Filter::Bilinear, false).unwrap_err().to_string();
            assert!(e.contains(p.file_name().unwrap().to_str().unwrap()), "{e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn pfm(magic: &str, w: usize, h: usize, scale: f32, values: &[f32]) -> Vec<u8> {
        let mut b = format!("{magic}\n{w} {h}\n{scale}\n").into_bytes();
        for v in values {
            b.extend(if scale < 0.0 { v.to_le_bytes() } else { v.to_be_bytes() });
        }
        b
    }

    #[test]
    fn pfm_rows_run_from_the_bottom_in_either_byte_order() {
        // 2 × 2 colour, stored bottom row first: bottom (1, 2), top (3, 4) in the red channel.
        let values: Vec<f32> = [1.0f32, 2.0, 3.0, 4.0].iter().flat_map(|&r| [r, 0.5, -0.0]).collect();
        for scale in [-1.0, 1.0] {
            let (w, h, t) = decode(&pfm("PF", 2, 2, scale, &values), ImageFormat::Pfm, false).unwrap();
            assert_eq!((w, h), (2, 2));
            assert_eq!(t.iter().map(|v| v.x).collect::<Vec<_>>(), [3.0, 4.0, 1.0, 2.0], "scale {scale}");
            assert_eq!(t[0].y, 0.5);
        }
        // Grey, linear whatever `raw` says.
        let (_, _, t) = decode(&pfm("Pf", 1, 1, -1.0, &[0.25]), ImageFormat::Pfm, false).unwrap();
        assert_eq!(t, [Vec3A::splat(0.25)]);
        // A non-finite texel is black, not a poisoned light.
        let (_, _, t) = decode(&pfm("Pf", 1, 1, -1.0, &[f32::NAN]), ImageFormat::Pfm, false).unwrap();
        assert_eq!(t, [Vec3A::ZERO]);
    }

    #[test]
    fn bad_pfm_headers_are_errors_before_allocation() {
        for (bytes, needle) in [
            (pfm("PF", 100_000, 100_000, -1.0, &[1.0; 3]), "pixels"),
            (pfm("PF", 2, 2, -1.0, &[1.0; 3]), "bytes"),
            (pfm("P6", 1, 1, -1.0, &[1.0; 3]), "PF"),
            (pfm("PF", 1, 1, 0.0, &[1.0; 3]), "scale"),
            (b"PF\n-1 1\n-1\n".to_vec(), "width"),
            (b"PF\n1".to_vec(), "early"),
            (Vec::new(), "early"),
        ] {
            let e = decode(&bytes, ImageFormat::Pfm, false).unwrap_err();
            assert!(e.contains(needle), "{e}");
        }
    }

    /// An uncompressed 24-bit TGA of `w × h` BGR texels given top row first, stored with its
    /// origin at the bottom left (the format's default) or the top left.
    fn tga(w: u16, h: u16, top_rows_first: &[[u8; 3]], origin_top: bool) -> Vec<u8> {
        let mut b = vec![0u8, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        b.extend(w.to_le_bytes());
        b.extend(h.to_le_bytes());
        b.extend([24, if origin_top { 0x20 } else { 0 }]);
        let rows: Vec<&[[u8; 3]]> = top_rows_first.chunks(w as usize).collect();
        let order: Vec<&&[[u8; 3]]> = if origin_top { rows.iter().collect() } else { rows.iter().rev().collect() };
        for row in order {
            for [r, g, bl] in row.iter() {
                b.extend([*bl, *g, *r]);
            }
        }
        b
    }

    #[test]
    fn tga_is_read_upright_and_decoded_from_srgb_unless_raw() {
        let texels = [[255, 0, 0], [0, 128, 0], [0, 0, 64], [10, 20, 30]];
        for origin_top in [false, true] {
            let bytes = tga(2, 2, &texels, origin_top);
            let (w, h, t) = decode(&bytes, ImageFormat::Tga, false).unwrap();
            assert_eq!((w, h), (2, 2));
            assert_eq!(t[0], Vec3A::new(1.0, 0.0, 0.0), "origin at the top: {origin_top}");
            assert!((t[1].y - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
            assert!((t[2].z - srgb_to_linear(64.0 / 255.0)).abs() < 1e-6);
            let (_, _, raw) = decode(&bytes, ImageFormat::Tga, true).unwrap();
            assert!((raw[3] - Vec3A::new(10.0, 20.0, 30.0) / 255.0).abs().max_element() < 1e-6);
        }
        // A header claiming 65535 × 65535 texels of a few bytes: an error, not an abort.
        let mut huge = tga(1, 1, &[[1, 2, 3]], false);
        huge[12..16].copy_from_slice(&[0xff; 4]);
        assert!(decode(&huge, ImageFormat::Tga, false).is_err());
        assert!(decode(b"not a tga", ImageFormat::Tga, false).is_err());
    }

    #[test]
    fn radiance_hdr_is_linear() {
        // Flat (not run-length) RGBE: mantissas 128, 64, 32 with exponent 129 are 1, 0.5, 0.25.
        let mut b = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n".to_vec();
        b.extend([128, 64, 32, 129, 128, 128, 128, 128]);
        let (w, h, t) = decode(&b, ImageFormat::Hdr, false).unwrap();
        assert_eq!((w, h), (2, 1));
        assert!((t[0] - Vec3A::new(1.0, 0.5, 0.25)).abs().max_element() < 1e-6, "{}", t[0]);
        assert!((t[1] - Vec3A::splat(0.5)).abs().max_element() < 1e-6, "{}", t[1]);
        assert!(decode(b"#?RADIANCE\n\n-Y 99999 +X 99999\n", ImageFormat::Hdr, false).is_err());
    }

    #[test]
    fn jpeg_is_decoded_from_srgb() {
        let mut bytes = Vec::new();
        let grey = image::RgbImage::from_pixel(16, 8, image::Rgb([128, 128, 128]));
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 100).encode_image(&grey).unwrap();
        let (w, h, t) = decode(&bytes, ImageFormat::Jpeg, false).unwrap();
        assert_eq!((w, h), (16, 8));
        // Within a code value of 128 after JPEG's rounding.
        assert!(t.iter().all(|v| (v.x - srgb_to_linear(128.0 / 255.0)).abs() < 0.004), "{}", t[0]);
        assert!(decode(&bytes[..40], ImageFormat::Jpeg, false).is_err());
    }

    #[test]
    fn formats_by_extension() {
        assert_eq!(ImageFormat::from_path(Path::new("a/b.TGA")), Some(ImageFormat::Tga));
        assert_eq!(ImageFormat::from_path(Path::new("x.jpeg")), Some(ImageFormat::Jpeg));
        assert_eq!(ImageFormat::from_path(Path::new("sky.pfm")), Some(ImageFormat::Pfm));
        assert_eq!(ImageFormat::from_path(Path::new("sky.hdr")), Some(ImageFormat::Hdr));
        assert_eq!(ImageFormat::from_path(Path::new("t.bmp")), None);
        assert!(ImageFormat::Pfm.is_linear() && !ImageFormat::Tga.is_linear());
    }
}
