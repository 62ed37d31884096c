//! Textures: values that vary over a surface with its texture coordinates `(u, v)`, to drive
//! reflectance or roughness. A bitmap (`image.rs`: PNG, TGA and JPEG decoded from sRGB unless
//! raw; EXR, PFM and Radiance HDR linear), a checkerboard, or a constant.
//!
//! Coordinates follow OBJ and pbrt: `v = 0` is the image's *bottom* row. A bitmap's texel
//! `(i, j)` (column, row from the top) is centred at `((i + ½)/W, 1 − (j + ½)/H)`; bilinear
//! filtering interpolates between the four nearest centres, and the wrap mode says what lies
//! beyond the edges.
use crate::geometry::{Vec2, Vec3A};

mod image;
pub use image::{ImageFormat, decode};

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
    pub texels: Texels,
    pub wrap: Wrap,
    pub filter: Filter,
}

/// A bitmap's texels: linear values, or (images of 8 bits per channel) each channel's 8-bit
/// code with the table that decodes it. Codes take 3 bytes a texel rather than 16, and give
/// the values the table would have stored, bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub enum Texels {
    Linear(Vec<Vec3A>),
    Coded { codes: Vec<[u8; 3]>, table: Box<[[f32; 256]; 3]> },
}

/// The value of an 8-bit texel `code` through its channels' `table`.
#[inline]
fn decode_code([r, g, b]: [u8; 3], table: &[[f32; 256]; 3]) -> Vec3A {
    Vec3A::new(table[0][r as usize], table[1][g as usize], table[2][b as usize])
}

impl Texels {
    /// How many texels.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Self::Linear(t) => t.len(),
            Self::Coded { codes, .. } => codes.len(),
        }
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Texel `k`, row-major.
    #[inline]
    #[must_use]
    pub fn get(&self, k: usize) -> Vec3A {
        match self {
            Self::Linear(t) => t[k],
            Self::Coded { codes, table } => decode_code(codes[k], table),
        }
    }

    /// Every texel's value, row-major.
    pub fn values(&self) -> impl Iterator<Item = Vec3A> + '_ {
        self.values_in(0..self.len())
    }

    /// The values of texels `range` (a chunk for digests computed in parallel).
    pub fn values_in(&self, range: std::ops::Range<usize>) -> impl Iterator<Item = Vec3A> + '_ {
        range.map(|k| self.get(k))
    }

    /// Replaces each value `v` by `f(v)`; `f` must act on each channel alone (a scale, an
    /// inversion), so that coded texels change their tables, not their codes.
    pub fn map_channels(&mut self, f: impl Fn(Vec3A) -> Vec3A) {
        match self {
            Self::Linear(t) => t.iter_mut().for_each(|v| *v = f(*v)),
            Self::Coded { table, .. } => {
                for k in 0..256 {
                    let v = f(Vec3A::new(table[0][k], table[1][k], table[2][k]));
                    (table[0][k], table[1][k], table[2][k]) = (v.x, v.y, v.z);
                }
            }
        }
    }

    /// Whether every value is finite and non-negative (for coded texels, every table entry).
    #[must_use]
    pub fn all_finite_non_negative(&self) -> bool {
        let ok = |x: f32| x.is_finite() && x >= 0.0;
        match self {
            Self::Linear(t) => t.iter().all(|v| v.is_finite() && v.min_element() >= 0.0),
            Self::Coded { table, .. } => table.iter().flatten().all(|&x| ok(x)),
        }
    }

    /// The values, row-major.
    #[must_use]
    pub fn into_linear(self) -> Vec<Vec3A> {
        match self {
            Self::Linear(t) => t,
            coded @ Self::Coded { .. } => coded.values().collect(),
        }
    }

    fn swap_rows(&mut self, a: usize, b: usize, width: usize) {
        fn swap<T>(v: &mut [T], a: usize, b: usize, w: usize) {
            let (lo, hi) = (a.min(b), a.max(b));
            let (top, bottom) = v.split_at_mut(hi * w);
            top[lo * w..(lo + 1) * w].swap_with_slice(&mut bottom[..w]);
        }
        match self {
            Self::Linear(t) => swap(t, a, b, width),
            Self::Coded { codes, .. } => swap(codes, a, b, width),
        }
    }
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
                let sum: glam::DVec3 = b.texels.values().map(|t| glam::Vec3::from(t).as_dvec3()).sum();
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
        Self::with_texels(width, height, Texels::Linear(texels), wrap, filter)
    }

    /// A `width × height` bitmap of texels stored either way; `None` unless the texel count
    /// matches and is non-zero.
    #[must_use]
    pub fn with_texels(width: usize, height: usize, texels: Texels, wrap: Wrap, filter: Filter) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width * height).then_some(Self {
            width,
            height,
            texels,
            wrap,
            filter,
        })
    }

    /// The image upside down: a bitmap read with `v = 0` at its *top* row (Mitsuba's
    /// convention) is ours of the flipped image.
    pub fn flip_rows(&mut self) {
        for j in 0..self.height / 2 {
            self.texels.swap_rows(j, self.height - 1 - j, self.width);
        }
    }

    /// Width, height and the texels' values, row-major from the top row.
    #[must_use]
    pub fn into_texels(self) -> (usize, usize, Vec<Vec3A>) {
        (self.width, self.height, self.texels.into_linear())
    }

    /// The index of texel `(i, j)` (column, row from the top) after wrapping each index.
    #[inline]
    fn index(&self, i: i64, j: i64) -> usize {
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
        wrap(j, self.height) * self.width + wrap(i, self.width)
    }

    /// The value at texture coordinates `uv`.
    #[must_use]
    pub fn eval(&self, uv: Vec2) -> Vec3A {
        // One match on the storage per lookup, not one per texel read.
        match &self.texels {
            Texels::Linear(t) => self.filtered(uv, |k| t[k]),
            Texels::Coded { codes, table } => self.filtered(uv, |k| decode_code(codes[k], table)),
        }
    }

    #[inline]
    fn filtered(&self, uv: Vec2, texel: impl Fn(usize) -> Vec3A) -> Vec3A {
        if !uv.is_finite() {
            return Vec3A::ZERO;
        }
        let at = |i: i64, j: i64| texel(self.index(i, j));
        // Continuous texel coordinates: x across, y down from the top row.
        let x = f64::from(uv.x) * self.width as f64;
        let y = (1.0 - f64::from(uv.y)) * self.height as f64;
        match self.filter {
            Filter::Nearest => at(x.floor() as i64, y.floor() as i64),
            Filter::Bilinear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
                let (i, j) = (x0 as i64, y0 as i64);
                let top = at(i, j) * (1.0 - fx) + at(i + 1, j) * fx;
                let bottom = at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx;
                top * (1.0 - fy) + bottom * fy
            }
        }
    }
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
                let d = (b.eval(centre(i, j, &b)) - b.texels.get(j * 3 + i)).abs().max_element();
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

    /// Coded texels read, average, flip and scale exactly as the values they decode to.
    #[test]
    fn coded_texels_are_their_values() {
        let (w, h) = (5, 4);
        let codes: Vec<[u8; 3]> =
            (0..w * h).map(|k| [(k * 13) as u8, (k * 7 + 100) as u8, (255 - k * 11) as u8]).collect();
        let table: [f32; 256] = std::array::from_fn(|v| srgb_to_linear(v as f32 / 255.0));
        let decoded = codes.iter().map(|c| Vec3A::from_array(c.map(|v| table[v as usize]))).collect();
        let (coded, linear) = (Texels::Coded { codes, table: Box::new([table; 3]) }, Texels::Linear(decoded));
        for wrap in [Wrap::Repeat, Wrap::Clamp, Wrap::Mirror] {
            for filter in [Filter::Bilinear, Filter::Nearest] {
                let mut a = Bitmap::with_texels(w, h, coded.clone(), wrap, filter).unwrap();
                let mut b = Bitmap::with_texels(w, h, linear.clone(), wrap, filter).unwrap();
                let scale = |v: Vec3A| (Vec3A::ONE - Vec3A::new(0.5, 2.0, 0.25) * v).max(Vec3A::ZERO);
                a.texels.map_channels(scale);
                b.texels.map_channels(scale);
                a.flip_rows();
                b.flip_rows();
                assert!(matches!(a.texels, Texels::Coded { .. }), "coded texels stay coded");
                for k in 0..200 {
                    let uv = Vec2::new(k as f32 * 0.0173 - 0.4, k as f32 * 0.0311 - 1.2);
                    assert_eq!(a.eval(uv).to_array().map(f32::to_bits), b.eval(uv).to_array().map(f32::to_bits));
                }
                let (ta, tb) = (Texture::Bitmap(a.clone()), Texture::Bitmap(b.clone()));
                assert_eq!(ta.mean().to_array().map(f32::to_bits), tb.mean().to_array().map(f32::to_bits));
                assert_eq!(a.into_texels(), b.into_texels());
            }
        }
    }
}
