//! Deterministic random streams. A stream is keyed by `(seed, pixel, sample index)` and yields
//! one value per *dimension* by hashing the key with a dimension counter, so a pixel's samples
//! never depend on which thread rendered it, in which tile, or in which order.
use glam::{Vec2, Vec3A};

/// A counter-based random stream: value `d` of the stream is `hash(key, d)`.
#[derive(Clone, Debug)]
pub struct SampleStream {
    key: u64,
    dim: u64,
    /// Camera streams: this sample's point in the pixel footprint (see [`Self::pixel_2d`]).
    pixel_point: Vec2,
}

/// Streams of different purposes (camera samples, photon paths, per-pixel set-up) are kept
/// apart by a domain tag mixed into the key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u64)]
pub enum Domain {
    Camera = 0,
    PixelSetup = 1,
    Photon = 2,
    /// First-hit AOV rays.
    Aov = 3,
    /// A learning integrator's probe of its walks (through pixel centres): independent of
    /// the render's own camera samples.
    Probe = 4,
    /// The seen light's probe of pixels that see through delta scatters: independent of the
    /// render's own camera samples.
    SeenProbe = 5,
}

/// A 64-bit finaliser with full avalanche (Pelle Evensen's rrmxmx).
#[inline(always)]
fn mix64(mut v: u64) -> u64 {
    v ^= v.rotate_right(49) ^ v.rotate_right(24);
    v = v.wrapping_mul(0x9FB2_1C65_1E98_DF25);
    v ^= v >> 28;
    v = v.wrapping_mul(0x9FB2_1C65_1E98_DF25);
    v ^ (v >> 28)
}

impl SampleStream {
    /// The stream of camera sample `sample` of pixel `pixel` (a linear pixel index).
    #[inline]
    #[must_use]
    pub fn new(seed: u64, pixel: u32, sample: u32) -> Self {
        let mut stream = Self::in_domain(Domain::Camera, seed, pixel as u64, sample as u64);
        let scramble = mix64(seed ^ mix64(0x005E_ED0F_50B0_u64 ^ pixel as u64));
        stream.pixel_point = sobol_02(sample, scramble);
        stream
    }

    /// Where this sample falls inside its pixel, as a point of `[0,1)²`: point number `sample`
    /// of a (0,2)-sequence (the first two Sobol dimensions), Owen-scrambled per pixel and seed.
    /// Every point is uniform on its own, so each sample stays an unbiased estimate; together a
    /// pixel's first 4^k samples fill every one of 4^k congruent cells of any elementary
    /// grid, which is what removes most of the noise of pixels that an edge crosses (the
    /// light's silhouette on `cornell-paper`). The per-pixel variance written with the image
    /// is the samples' variance, which then overstates the mean's error (tests stay
    /// conservative).
    #[inline]
    #[must_use]
    pub fn pixel_2d(&self) -> Vec2 {
        self.pixel_point
    }

    /// A stream for any purpose, keyed by a domain and two indices.
    #[inline]
    #[must_use]
    pub fn in_domain(domain: Domain, seed: u64, a: u64, b: u64) -> Self {
        let k = mix64(seed ^ mix64((domain as u64) << 56 ^ mix64(a.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ b)));
        Self { key: k, dim: 0, pixel_point: Vec2::splat(0.5) }
    }

    /// The next uniform value in `[0, 1)`.
    #[inline(always)]
    pub fn next_f32(&mut self) -> f32 {
        let h = mix64(self.key.wrapping_add(self.dim.wrapping_mul(0x9E37_79B9_7F4A_7C15)));
        self.dim += 1;
        (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.next_f32();
        Vec2::new(x, self.next_f32())
    }
}

/// Point `i` of the Owen-scrambled (0,2)-sequence keyed by `scramble`: van der Corput in x,
/// Sobol's second dimension in y, each nested-uniform-scrambled with its own seed.
#[inline]
fn sobol_02(i: u32, scramble: u64) -> Vec2 {
    // Sobol's second dimension: generator matrix = Pascal's triangle mod 2, as direction numbers.
    let mut y = 0u32;
    let mut v = 1u32 << 31;
    let mut bits = i;
    while bits != 0 {
        if bits & 1 != 0 {
            y ^= v;
        }
        bits >>= 1;
        v ^= v >> 1;
    }
    let x = owen_scramble(i.reverse_bits(), scramble as u32);
    let y = owen_scramble(y, (scramble >> 32) as u32);
    let to_unit = |b: u32| (b >> 8) as f32 * (1.0 / (1u32 << 24) as f32);
    Vec2::new(to_unit(x), to_unit(y))
}

/// A nested uniform (Owen) scramble of the binary fraction `bits` (most significant bit first)
/// keyed by `seed`: each bit is flipped by a pseudo-random function of the bits above it. In
/// reversed bit order that is a map in which bit k depends only on bits 0..=k, which additions,
/// multiplications by odd numbers and `x ^= x·even` all are (Laine and Karras's construction;
/// the constants are ours).
#[inline]
fn owen_scramble(bits: u32, seed: u32) -> u32 {
    let mut x = bits.reverse_bits();
    x = x.wrapping_add(seed.wrapping_mul(0x9E37_79B9));
    x ^= x.wrapping_mul(0x6C50_B47C);
    x = x.wrapping_mul(seed | 1);
    x ^= x.wrapping_mul(0xB82F_1E52);
    x = x.wrapping_add(seed.rotate_left(16));
    x ^= x.wrapping_mul(0xC7AF_E638);
    x ^= x.wrapping_mul(0x8D22_F6E6);
    x.reverse_bits()
}

/// Survival probability for Russian roulette: the albedo's largest channel, capped so that a
/// white (ρ = 1) closed scene still terminates. Any cap keeps the estimator unbiased.
#[inline]
#[must_use]
pub fn survival_probability(albedo: Vec3A) -> f32 {
    albedo.max_element().min(0.95)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scrambled (0,2)-sequence keeps its stratification: for several pixels and seeds,
    /// the first 64 points put exactly one point in each cell of every elementary grid of 64
    /// cells (64×1, 32×2, …, 1×64), and the first 16 in each of 16.
    #[test]
    fn pixel_points_are_stratified() {
        for (seed, pixel) in [(0u64, 0u32), (1, 7), (42, 123_456), (7, u32::MAX)] {
            for count in [16u32, 64] {
                let points: Vec<Vec2> = (0..count).map(|i| SampleStream::new(seed, pixel, i).pixel_2d()).collect();
                let k = count.trailing_zeros();
                for a in 0..=k {
                    let (nx, ny) = (1u32 << a, 1u32 << (k - a));
                    let mut cells = vec![0u32; (nx * ny) as usize];
                    for p in &points {
                        let (cx, cy) = ((p.x * nx as f32) as u32, (p.y * ny as f32) as u32);
                        cells[(cy.min(ny - 1) * nx + cx.min(nx - 1)) as usize] += 1;
                    }
                    assert!(cells.iter().all(|&c| c == 1), "seed {seed} pixel {pixel}: {nx}x{ny} cells {cells:?}");
                }
            }
        }
    }

    /// Each point is uniform on its own (over pixels, at a fixed sample index): chi-square over
    /// 8×8 cells at 1e-4, and different pixels get different points.
    #[test]
    fn pixel_points_are_uniform_across_pixels() {
        for sample in [0u32, 1, 5, 1000] {
            let n = 64_000u32;
            let mut cells = [0f64; 64];
            for pixel in 0..n {
                let p = SampleStream::new(3, pixel, sample).pixel_2d();
                assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                cells[((p.y * 8.0) as usize) * 8 + (p.x * 8.0) as usize] += 1.0;
            }
            let e = f64::from(n) / 64.0;
            let chi2: f64 = cells.iter().map(|c| (c - e).powi(2) / e).sum();
            let bound = crate::stats::chi_square_critical(63, 1e-4);
            assert!(chi2 < bound, "sample {sample}: chi-square {chi2} ≥ {bound}");
        }
    }

    #[test]
    fn deterministic_and_distinct() {
        let a: Vec<f32> = (0..8)
            .map({
                let mut s = SampleStream::new(1, 2, 3);
                move |_| s.next_f32()
            })
            .collect();
        let b: Vec<f32> = (0..8)
            .map({
                let mut s = SampleStream::new(1, 2, 3);
                move |_| s.next_f32()
            })
            .collect();
        let c: Vec<f32> = (0..8)
            .map({
                let mut s = SampleStream::new(1, 2, 4);
                move |_| s.next_f32()
            })
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.iter().all(|x| (0.0..1.0).contains(x)));
    }

    /// Mean and variance of many values match U(0,1) (z-bound 5 on each).
    #[test]
    fn uniform_moments() {
        let n = 1_000_000;
        let (mut s1, mut s2) = (0.0f64, 0.0f64);
        for i in 0..n {
            let mut s = SampleStream::new(9, i, 0);
            let x = s.next_f32() as f64;
            let y = s.next_f32() as f64;
            s1 += x;
            s2 += x * y;
        }
        let mean = s1 / n as f64;
        let z_mean = (mean - 0.5) / (1.0 / 12f64).sqrt() * (n as f64).sqrt();
        assert!(z_mean.abs() < 5.0, "mean {mean}");
        // E[xy] = 1/4 for independent dimensions; Var(xy) = 1/9 − 1/16.
        let exy = s2 / n as f64;
        let z_xy = (exy - 0.25) / (1.0 / 9.0 - 1.0 / 16.0f64).sqrt() * (n as f64).sqrt();
        assert!(z_xy.abs() < 5.0, "E[xy] {exy}");
    }
}
