//! Deterministic random streams. A stream is keyed by `(seed, pixel, sample index)` and yields
//! one value per *dimension* by hashing the key with a dimension counter, so a pixel's samples
//! never depend on which thread rendered it, in which tile, or in which order.
use glam::Vec2;

/// A counter-based random stream: value `d` of the stream is `hash(key, d)`.
#[derive(Clone, Debug)]
pub struct SampleStream {
    key: u64,
    dim: u64,
}

/// Streams of different purposes (camera samples, photon paths, per-pixel set-up) are kept
/// apart by a domain tag mixed into the key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u64)]
pub enum Domain {
    Camera = 0,
    PixelSetup = 1,
    Photon = 2,
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
        Self::in_domain(Domain::Camera, seed, pixel as u64, sample as u64)
    }

    /// A stream for any purpose, keyed by a domain and two indices.
    #[inline]
    #[must_use]
    pub fn in_domain(domain: Domain, seed: u64, a: u64, b: u64) -> Self {
        let k = mix64(seed ^ mix64((domain as u64) << 56 ^ mix64(a.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ b)));
        Self { key: k, dim: 0 }
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

#[cfg(test)]
mod tests {
    use super::*;

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
