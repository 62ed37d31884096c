//! Textures: values that vary over a surface with its texture coordinates `(u, v)`, to drive
//! reflectance or roughness. A bitmap (PNG decoded from sRGB, EXR linear), a checkerboard, or
//! a constant.
//!
//! Coordinates follow OBJ and pbrt: `v = 0` is the image's *bottom* row. A bitmap's texel
//! `(i, j)` (column, row from the top) is centred at `((i + ½)/W, 1 − (j + ½)/H)`; bilinear
//! filtering interpolates between the four nearest centres, and the wrap mode says what lies
//! beyond the edges.
use crate::geometry::{Vec2, Vec3A};
use std::path::Path;

/// What a bitmap holds beyond `[0, 1]²`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// The image tiles the plane.
    #[default]
    Repeat,
    /// Every tile is the mirror image of its neighbours.
    Mirror,
    /// The edge texels extend for ever.
    Clamp,
}

/// How a bitmap is read between texel centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    #[default]
    Bilinear,
    Nearest,
}

/// A grid of linear RGB values.
#[derive(Clone, Debug, PartialEq)]
pub struct Bitmap {
    pub width: usize,
    pub height: usize,
    /// Row-major, row 0 at the top.
    pub texels: Vec<Vec3A>,
    pub wrap: Wrap,
    pub filter: Filter,
}

/// A texture, dispatched statically (no trait object per lookup).
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    Constant(Vec3A),
    Bitmap(Bitmap),
    /// Squares of `a` and `b` alternating `scale.x` times across `u ∈ [0, 1)` and `scale.y`
    /// times across `v`, `a` at the origin.
    Checkerboard {
        a: Vec3A,
        b: Vec3A,
        scale: Vec2,
    },
}

impl Texture {
    /// The value at texture coordinates `uv`.
    #[inline]
    #[must_use]
    pub fn eval(&self, uv: Vec2) -> Vec3A {
        match self {
            Self::Constant(c) => *c,
            Self::Bitmap(b) => b.eval(uv),
            Self::Checkerboard { a, b, scale } => {
                let p = uv * *scale;
                if (p.x.floor() + p.y.floor()).rem_euclid(2.0) < 0.5 { *a } else { *b }
            }
        }
    }
}

impl Texture {
    /// The mean value over the texture's square `[0, 1)²` (for sampling decisions, such as a
    /// plastic's share of mirror samples: Mitsuba 3 uses the same).
    #[must_use]
    pub fn mean(&self) -> Vec3A {
        match self {
            Self::Constant(c) => *c,
            Self::Checkerboard { a, b, .. } => (*a + *b) * 0.5,
            Self::Bitmap(b) => {
                let sum: glam::DVec3 = b.texels.iter().map(|t| glam::Vec3::from(*t).as_dvec3()).sum();
                (sum / b.texels.len() as f64).as_vec3().into()
            }
        }
    }
}

/// sRGB's transfer function, decoded: an encoded value in `[0, 1]` to linear.
#[inline]
#[must_use]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

impl Bitmap {
    /// A `width × height` bitmap; `None` unless the texel count matches and is non-zero.
    #[must_use]
    pub fn new(width: usize, height: usize, texels: Vec<Vec3A>, wrap: Wrap, filter: Filter) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width * height).then_some(Self {
            width,
            height,
            texels,
            wrap,
            filter,
        })
    }

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

    /// The image upside down: a bitmap read with `v = 0` at its *top* row (Mitsuba's
    /// convention) is ours of the flipped image.
    pub fn flip_rows(&mut self) {
        let w = self.width;
        for j in 0..self.height / 2 {
            let (top, bottom) = self.texels.split_at_mut((self.height - 1 - j) * w);
            top[j * w..(j + 1) * w].swap_with_slice(&mut bottom[..w]);
        }
    }

    /// Width, height and the texels, row-major from the top row.
    #[must_use]
    pub fn into_texels(self) -> (usize, usize, Vec<Vec3A>) {
        (self.width, self.height, self.texels)
    }

    /// Texel `(i, j)` (column, row from the top) after wrapping each index.
    #[inline]
    fn texel(&self, i: i64, j: i64) -> Vec3A {
        let wrap = |k: i64, n: usize| -> usize {
            let n = n as i64;
            let k = match self.wrap {
                Wrap::Repeat => k.rem_euclid(n),
                Wrap::Clamp => k.clamp(0, n - 1),
                Wrap::Mirror => {
                    let m = k.rem_euclid(2 * n);
                    if m < n { m } else { 2 * n - 1 - m }
                }
            };
            k as usize
        };
        self.texels[wrap(j, self.height) * self.width + wrap(i, self.width)]
    }

    /// The value at texture coordinates `uv`.
    #[must_use]
    pub fn eval(&self, uv: Vec2) -> Vec3A {
        if !uv.is_finite() {
            return Vec3A::ZERO;
        }
        // Continuous texel coordinates: x across, y down from the top row.
        let x = f64::from(uv.x) * self.width as f64;
        let y = (1.0 - f64::from(uv.y)) * self.height as f64;
        match self.filter {
            Filter::Nearest => self.texel(x.floor() as i64, y.floor() as i64),
            Filter::Bilinear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
                let (i, j) = (x0 as i64, y0 as i64);
                let top = self.texel(i, j) * (1.0 - fx) + self.texel(i + 1, j) * fx;
                let bottom = self.texel(i, j + 1) * (1.0 - fx) + self.texel(i + 1, j + 1) * fx;
                top * (1.0 - fy) + bottom * fy
            }
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

    fn grid() -> Bitmap {
        // 3 × 2: top row 0, 1, 2; bottom row 10, 11, 12 (grey).
        let texels = [0.0, 1.0, 2.0, 10.0, 11.0, 12.0].map(Vec3A::splat).to_vec();
        Bitmap::new(3, 2, texels, Wrap::Repeat, Filter::Bilinear).unwrap()
    }

    fn centre(i: usize, j: usize, b: &Bitmap) -> Vec2 {
        Vec2::new((i as f32 + 0.5) / b.width as f32, 1.0 - (j as f32 + 0.5) / b.height as f32)
    }

    #[test]
    fn bilinear_hits_texel_centres_and_interpolates_between() {
        let b = grid();
        for j in 0..2 {
            for i in 0..3 {
                let d = (b.eval(centre(i, j, &b)) - b.texels[j * 3 + i]).abs().max_element();
                assert!(d < 1e-5, "texel {i},{j}: off by {d}");
            }
        }
        // Halfway between the top row's first two centres, and the middle of four.
        let mid = (centre(0, 0, &b) + centre(1, 0, &b)) * 0.5;
        assert!((b.eval(mid).x - 0.5).abs() < 1e-5);
        let four = (centre(0, 0, &b) + centre(1, 1, &b)) * 0.5;
        assert!((b.eval(four).x - 5.5).abs() < 1e-4, "{}", b.eval(four));
        // v = 0 is the bottom row.
        let nearest = Bitmap { filter: Filter::Nearest, ..grid() };
        assert_eq!(nearest.eval(Vec2::new(0.1, 0.1)).x, 10.0);
        assert_eq!(nearest.eval(Vec2::new(0.1, 0.9)).x, 0.0);
    }

    #[test]
    fn wrap_modes() {
        let repeat = grid();
        for uv in [Vec2::new(0.13, 0.4), Vec2::new(0.9, 0.95), Vec2::new(0.02, 0.01)] {
            assert!((repeat.eval(uv) - repeat.eval(uv + Vec2::new(1.0, -2.0))).abs().max_element() < 1e-4);
        }
        // Repeat: left of the first column's centre blends in the last column.
        let left = Vec2::new(0.0, centre(0, 0, &repeat).y);
        assert!((repeat.eval(left).x - 1.0).abs() < 1e-5, "{}", repeat.eval(left));
        let clamp = Bitmap { wrap: Wrap::Clamp, ..grid() };
        assert_eq!(clamp.eval(Vec2::new(-5.0, 5.0)).x, 0.0);
        assert_eq!(clamp.eval(Vec2::new(7.0, -3.0)).x, 12.0);
        let mirror = Bitmap { wrap: Wrap::Mirror, ..grid() };
        for uv in [Vec2::new(0.2, 0.3), Vec2::new(0.7, 0.8)] {
            let flipped = Vec2::new(-uv.x, uv.y);
            assert!((mirror.eval(uv) - mirror.eval(flipped)).abs().max_element() < 1e-4, "{uv}");
            let shifted = Vec2::new(2.0 - uv.x, uv.y);
            assert!((mirror.eval(uv) - mirror.eval(shifted)).abs().max_element() < 1e-4, "{uv}");
        }
        assert_eq!(repeat.eval(Vec2::new(f32::NAN, 0.5)), Vec3A::ZERO);
    }

    #[test]
    fn checkerboard_alternates() {
        let t = Texture::Checkerboard { a: Vec3A::ONE, b: Vec3A::ZERO, scale: Vec2::new(4.0, 2.0) };
        assert_eq!(t.eval(Vec2::new(0.1, 0.1)), Vec3A::ONE);
        assert_eq!(t.eval(Vec2::new(0.3, 0.1)), Vec3A::ZERO);
        assert_eq!(t.eval(Vec2::new(0.3, 0.6)), Vec3A::ONE);
        assert_eq!(t.eval(Vec2::new(-0.1, 0.1)), Vec3A::ZERO);
        assert_eq!(Texture::Constant(Vec3A::X).eval(Vec2::ZERO), Vec3A::X);
    }

    #[test]
    fn srgb_decoding() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // 128/255 decodes to 0.2158605 (the sRGB standard's curve).
        assert!((srgb_to_linear(128.0 / 255.0) - 0.215_860_5).abs() < 1e-6);
        assert!((srgb_to_linear(0.04) - 0.04 / 12.92).abs() < 1e-9);
    }

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
