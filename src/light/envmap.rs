//! Environment light: radiance arriving from infinitely far away, from an equirectangular map
//! (or a constant), with importance sampling of its directions.
//!
//! Directions map to the unit square with `y` up: `u = φ/2π` with `φ = atan2(x, −z)` in
//! `[0, 2π)`, `v = θ/π` with `cos θ = y`; row 0 of the map is the zenith. Radiance is constant
//! over each texel (nearest lookup), so what the sampler can produce and what the map holds
//! are the same set of directions.
//!
//! Sampling is piecewise constant *over solid angle*: a texel is picked with probability ∝
//! its luminance × its exact solid angle `(2π/W)·(cos θ₀ − cos θ₁)`, then a direction
//! uniform over the texel's solid angle (φ uniform, cos θ uniform between the row's bounds).
//! The density of a direction is therefore `lum(texel) / Σ lum·Ω`, constant over each texel:
//! a constant environment is sampled uniformly over the sphere and its estimate `L/pdf` is
//! exactly `4π·L` for every sample (the usual "luminance × sin θ at the texel centre" leaves
//! the variation of sin θ within a texel row in the weights).
//!
//! With [`Lookup::Mitsuba`] (imported Mitsuba scenes), radiance is read as Mitsuba 3's
//! `envmap` reads it: bilinearly between texels placed at `φ = 2π(i + ½)/W` and, unlike the
//! bands above, `θ = πj/(H − 1)` (row 0 at the zenith, the last row at the nadir), in the
//! map's own frame turned into the world by a rotation. Sampling stays the piecewise-constant
//! density above (the map's luminance per band): `pdf` is that density, so weights stay exact
//! while radiance is interpolated.
use super::{Light, LightSample, Receiver};
use crate::film::Image;
use crate::geometry::warp::Discrete;
use crate::geometry::{Frame, Ray, Vec2, Vec3A, luminance, warp};
use std::f32::consts::{PI, TAU};

/// A sampled direction towards the environment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Unit direction (towards the environment).
    pub direction: Vec3A,
    /// Radiance arriving from it.
    pub radiance: Vec3A,
    /// Density per steradian.
    pub pdf: f32,
}

/// How radiance is read from the map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Lookup {
    /// Constant over each texel's band of the sphere (what sampling draws from).
    #[default]
    Nearest,
    /// Mitsuba 3's bilinear reading (module documentation).
    Mitsuba,
}

/// An equirectangular environment map (a constant environment is a 1×1 map).
#[derive(Clone, Debug)]
pub struct Environment {
    lookup: Lookup,
    /// World to the map's frame, when the map is turned (Mitsuba lookups only).
    to_local: Option<glam::Mat3A>,
    width: usize,
    height: usize,
    /// Linear RGB radiance, row-major, row 0 at the zenith.
    texels: Vec<Vec3A>,
    /// `cos θ` at each row boundary (`height + 1` values, from 1 down to −1).
    cos_bounds: Vec<f32>,
    /// Rows by their summed weight, then each row's texels by weight (`None` when the whole
    /// map is black: nothing to sample).
    rows: Option<Discrete>,
    cols: Vec<Option<Discrete>>,
    /// `Σ lum·Ω` over the map.
    total: f32,
}

impl Environment {
    /// A constant environment of radiance `radiance`.
    #[must_use]
    pub fn constant(radiance: Vec3A) -> Self {
        Self::from_texels(1, 1, vec![radiance]).expect("a 1×1 map is valid")
    }

    /// The map of an image (linear RGB radiance, top row at the zenith).
    pub fn from_image(image: &Image) -> crate::Result<Self> {
        let texels = image.pixels.iter().map(|p| Vec3A::from_array(*p)).collect();
        Self::from_texels(image.width as usize, image.height as usize, texels)
    }

    /// A `width × height` map; every value must be finite and non-negative.
    pub fn from_texels(width: usize, height: usize, texels: Vec<Vec3A>) -> crate::Result<Self> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(crate::Error::InvalidOption(format!(
                "an environment map needs width × height texels ({width}×{height}, got {})",
                texels.len()
            )));
        }
        if let Some(t) = texels.iter().find(|t| !(t.is_finite() && t.min_element() >= 0.0)) {
            return Err(crate::Error::InvalidOption(format!(
                "environment radiance must be finite and non-negative, got {t}"
            )));
        }
        let cos_bounds: Vec<f32> =
            (0..=height).map(|i| if i == height { -1.0 } else { (PI * i as f32 / height as f32).cos() }).collect();
        let mut row_weights = Vec::with_capacity(height);
        let mut cols = Vec::with_capacity(height);
        for i in 0..height {
            let omega = TAU / width as f32 * (cos_bounds[i] - cos_bounds[i + 1]);
            let w: Vec<f32> =
                texels[i * width..(i + 1) * width].iter().map(|t| luminance(*t).max(0.0) * omega).collect();
            row_weights.push(w.iter().map(|&x| f64::from(x)).sum::<f64>() as f32);
            cols.push(Discrete::new(&w));
        }
        let total = row_weights.iter().map(|&x| f64::from(x)).sum::<f64>() as f32;
        let rows = Discrete::new(&row_weights).filter(|_| total > 0.0 && total.is_finite());
        Ok(Self { lookup: Lookup::Nearest, to_local: None, width, height, texels, cos_bounds, rows, cols, total })
    }

    /// The same map read as Mitsuba 3 reads it, turned into the world by `rotation` (a map
    /// of fewer than 2 rows stays nearest).
    #[must_use]
    pub fn mitsuba(self, rotation: Option<glam::Mat3A>) -> Self {
        let lookup = if self.height >= 2 { Lookup::Mitsuba } else { Lookup::Nearest };
        Self { lookup, to_local: rotation.map(|r| r.transpose()), ..self }
    }

    /// A world direction in the map's frame.
    #[inline]
    fn local(&self, d: Vec3A) -> Vec3A {
        match &self.to_local {
            Some(m) => *m * d,
            None => d,
        }
    }

    /// Mitsuba 3's bilinear reading of a direction in the map's frame.
    fn bilinear(&self, d: Vec3A) -> Vec3A {
        let (w, h) = (self.width, self.height);
        let u = d.x.atan2(-d.z) / TAU - 0.5 / w as f32;
        let u = u - u.floor();
        let v = d.y.clamp(-1.0, 1.0).acos() / PI;
        let (x, y) = (u * w as f32, v * (h - 1) as f32);
        let (x0, y0) = ((x as usize).min(w - 1), (y as usize).min(h - 2));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let x1 = (x0 + 1) % w;
        let t = |row: usize, col: usize| self.texels[row * w + col];
        let top = t(y0, x0) * (1.0 - fx) + t(y0, x1) * fx;
        let bottom = t(y0 + 1, x0) * (1.0 - fx) + t(y0 + 1, x1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The texel (row, column) a unit direction falls in.
    #[inline]
    fn texel_of(&self, d: Vec3A) -> (usize, usize) {
        let mut phi = d.x.atan2(-d.z);
        if phi < 0.0 {
            phi += TAU;
        }
        let col = ((phi / TAU * self.width as f32) as usize).min(self.width - 1);
        // The row whose cos θ bounds hold d.y (rows run from the zenith down).
        let y = d.y.clamp(-1.0, 1.0);
        let row = self.cos_bounds[1..].partition_point(|&c| c > y).min(self.height - 1);
        (row, col)
    }

    /// Radiance arriving from unit direction `d`.
    #[inline]
    #[must_use]
    pub fn eval(&self, d: Vec3A) -> Vec3A {
        match self.lookup {
            Lookup::Nearest => {
                let (row, col) = self.texel_of(d);
                self.texels[row * self.width + col]
            }
            Lookup::Mitsuba => self.bilinear(self.local(d)),
        }
    }

    /// The density per steradian with which [`Self::sample`] returns unit direction `d`.
    #[inline]
    #[must_use]
    pub fn pdf(&self, d: Vec3A) -> f32 {
        if self.rows.is_none() {
            return 0.0;
        }
        let (row, col) = self.texel_of(self.local(d));
        luminance(self.texels[row * self.width + col]).max(0.0) / self.total
    }

    /// A direction towards the environment (`None` for a black one).
    #[must_use]
    pub fn sample(&self, u: Vec2) -> Option<EnvSample> {
        let rows = self.rows.as_ref()?;
        let (row, _, ux) = rows.sample_reusing(u.x);
        let (col, _, uy) = self.cols[row].as_ref()?.sample_reusing(u.y);
        let phi = TAU * (col as f32 + ux) / self.width as f32;
        let (c0, c1) = (self.cos_bounds[row], self.cos_bounds[row + 1]);
        let cos_theta = (c0 - uy * (c0 - c1)).clamp(c1.min(c0), c0.max(c1));
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let local = Vec3A::new(sin_theta * phi.sin(), cos_theta, -sin_theta * phi.cos());
        let texel = self.texels[row * self.width + col];
        let pdf = luminance(texel) / self.total;
        let (direction, radiance) = match self.lookup {
            Lookup::Nearest => (local, texel),
            Lookup::Mitsuba => {
                let world = self.to_local.map_or(local, |m| m.transpose() * local);
                (world, self.bilinear(local))
            }
        };
        (pdf > 0.0 && pdf.is_finite()).then_some(EnvSample { direction, radiance, pdf })
    }

    /// `∫ lum(L) dω` over the sphere (what sampling is proportional to).
    #[must_use]
    pub fn luminous_integral(&self) -> f32 {
        self.total
    }
}

impl Light for Environment {
    /// A direction by the map's sampling: `p` is the direction towards it.
    fn sample_from(&self, _: &Receiver, _: f32, u_point: Vec2, pick: f32) -> Option<LightSample> {
        let s = self.sample(u_point)?;
        Some(LightSample {
            prim: u32::MAX,
            delta: false,
            infinite: true,
            p: s.direction,
            p_err: Vec3A::ZERO,
            ng: -s.direction,
            emission: s.radiance,
            inv_pdf: 1.0 / (pick * s.pdf),
        })
    }

    /// The density of direction `d`.
    fn pdf_from(&self, _: &Receiver, _: u32, d: Vec3A) -> f32 {
        self.pdf(d)
    }

    /// `π r² ∫ lum(L) dω`: what a disc of the bounding sphere sees (pbrt's measure).
    fn luminous_power(&self, radius: f32) -> f32 {
        PI * radius * radius * self.luminous_integral()
    }

    /// A direction by the map's sampling (`u_dir`), entering through a uniform point
    /// (`u_point`) of the disc of the bounding sphere facing it.
    fn emit_photon(&self, _: f32, u_point: Vec2, u_dir: Vec2, bounds: (Vec3A, f32), pick: f32) -> Option<(Ray, Vec3A)> {
        let s = self.sample(u_dir)?;
        let (centre, radius) = bounds;
        let disc = warp::uniform_disk(u_point) * radius;
        let frame = Frame::from_normal(s.direction);
        let origin = centre + s.direction * radius + frame.s * disc.x + frame.t * disc.y;
        let flux = s.radiance * (PI * radius * radius / (s.pdf * pick));
        Some((Ray::new(origin, -s.direction), flux))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{Domain, SampleStream};

    fn uniform_sphere(u: Vec2) -> Vec3A {
        let (z, phi) = (1.0 - 2.0 * u.x, TAU * u.y);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3A::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// A small map with a bright spot, black texels and colour.
    fn test_map() -> Environment {
        let (w, h) = (8, 6);
        let texels = (0..w * h)
            .map(|k| {
                let (i, j) = (k / w, k % w);
                if (i, j) == (1, 5) {
                    Vec3A::new(40.0, 30.0, 10.0)
                } else if j == 2 || i == 5 {
                    Vec3A::ZERO
                } else {
                    Vec3A::new(0.2 + 0.1 * j as f32, 0.5, 0.1 * i as f32)
                }
            })
            .collect();
        Environment::from_texels(w, h, texels).unwrap()
    }

    /// Directions follow `pdf`: a chi-square test over 12×16 bins equal in solid angle (bands
    /// of cos θ × φ), expected counts from `pdf` integrated on a 48×64 grid per bin. 191
    /// degrees of freedom at most: the 1e-4 quantile is about 264.
    #[test]
    fn samples_follow_the_pdf() {
        check_samples_follow_the_pdf(&test_map());
        // Read as Mitsuba does and turned: the density is still `pdf`, in the world.
        let turn = glam::Mat3A::from_axis_angle(glam::Vec3::new(0.3, 1.0, 0.2).normalize(), 0.7);
        let env = test_map().mitsuba(Some(turn));
        check_samples_follow_the_pdf(&env);
        let mut rng = SampleStream::in_domain(Domain::Photon, 14, 0, 0);
        for _ in 0..1000 {
            let s = env.sample(rng.next_2d()).unwrap();
            assert!(
                (s.radiance - env.eval(s.direction)).abs().max_element() <= 1e-3 * s.radiance.max_element().max(1e-3)
            );
        }
    }

    /// Mitsuba's reading: texels at `φ = 2π(i + ½)/W`, `θ = πj/(H − 1)`, bilinear between
    /// them, wrapping in φ; turned by the rotation.
    #[test]
    fn mitsuba_lookup_is_bilinear_from_pole_to_pole() {
        let (w, h) = (4, 3);
        let texels: Vec<Vec3A> = (0..w * h).map(|k| Vec3A::new(k as f32, (k * k) as f32, 1.0)).collect();
        let env = Environment::from_texels(w, h, texels.clone()).unwrap().mitsuba(None);
        let dir = |theta: f32, phi: f32| Vec3A::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos());
        let t = |row: usize, col: usize| texels[row * w + col];
        let close = |a: Vec3A, b: Vec3A| (a - b).abs().max_element() < 1e-3 * b.max_element().max(1.0);
        // Row 1 sits at the equator (θ = π/2), rows 0 and 2 at the poles.
        assert!(close(env.eval(dir(PI / 2.0, TAU * 1.5 / 4.0)), t(1, 1)));
        assert!(close(env.eval(dir(PI / 4.0, TAU * 1.5 / 4.0)), (t(0, 1) + t(1, 1)) * 0.5));
        assert!(close(env.eval(dir(PI / 2.0, TAU * 2.0 / 4.0)), (t(1, 1) + t(1, 2)) * 0.5));
        // Between the last column and the first.
        assert!(close(env.eval(dir(PI / 2.0, TAU * 0.0001)), (t(1, 3) + t(1, 0)) * 0.5));
        // Turned a quarter about +y: the map's φ = π/2 direction (+x) is the world's −z.
        let turn = glam::Mat3A::from_axis_angle(glam::Vec3::Y, PI / 2.0);
        let turned = Environment::from_texels(w, h, texels.clone()).unwrap().mitsuba(Some(turn));
        assert!(close(turned.eval(turn * dir(PI / 2.0, TAU * 1.5 / 4.0)), t(1, 1)));
        // A one-row map stays nearest.
        assert_eq!(Environment::constant(Vec3A::ONE).mitsuba(None).eval(Vec3A::Y), Vec3A::ONE);
    }

    fn check_samples_follow_the_pdf(env: &Environment) {
        let mut rng = SampleStream::in_domain(Domain::Photon, 11, 0, 0);
        let (nb_c, nb_p, n) = (12usize, 16usize, 400_000usize);
        let bin = |d: Vec3A| {
            let mut phi = d.x.atan2(-d.z);
            if phi < 0.0 {
                phi += TAU;
            }
            let c = (((1.0 - d.y) * 0.5 * nb_c as f32) as usize).min(nb_c - 1);
            let p = ((phi / TAU * nb_p as f32) as usize).min(nb_p - 1);
            c * nb_p + p
        };
        let mut observed = vec![0f64; nb_c * nb_p];
        // A direction rounded onto a texel's far edge can land in its neighbour (`pdf` of the
        // direction then differs from the sample's): allowed once in 10⁴ samples.
        let mut mismatched = 0;
        for _ in 0..n {
            let s = env.sample(rng.next_2d()).unwrap();
            assert!((s.direction.length() - 1.0).abs() < 1e-5);
            mismatched += usize::from((s.pdf - env.pdf(s.direction)).abs() > 1e-4 * s.pdf);
            observed[bin(s.direction)] += 1.0;
        }
        assert!(mismatched < n / 10_000, "{mismatched} samples' density differs from pdf()");
        let mut expected = vec![0f64; nb_c * nb_p];
        let (mc, mp) = (nb_c * 48, nb_p * 64);
        let d_omega = 4.0 * std::f64::consts::PI / (mc * mp) as f64;
        for a in 0..mc {
            let y = 1.0 - 2.0 * (a as f32 + 0.5) / mc as f32;
            let r = (1.0 - y * y).max(0.0).sqrt();
            for b in 0..mp {
                let phi = TAU * (b as f32 + 0.5) / mp as f32;
                let d = Vec3A::new(r * phi.sin(), y, -r * phi.cos());
                expected[(a / 48) * nb_p + b / 64] += f64::from(env.pdf(d)) * d_omega * n as f64;
            }
        }
        let chi2: f64 =
            observed.iter().zip(&expected).filter(|(_, e)| **e > 5.0).map(|(o, e)| (o - e) * (o - e) / e).sum();
        let sparse: f64 = observed.iter().zip(&expected).filter(|(_, e)| **e <= 5.0).map(|(o, _)| *o).sum();
        assert!(sparse < 1e-3 * n as f64, "{sparse} samples in bins expecting almost none");
        assert!(chi2 < 264.0, "chi2 {chi2}");
    }

    /// The density integrates to 1 over the sphere (uniform directions, 10⁶ samples; the
    /// relative standard error is about 0.3%, tolerance 1.5%), is zero on black texels, and
    /// follows luminance.
    #[test]
    fn pdf_is_normalised_and_zero_where_black() {
        let env = test_map();
        let mut rng = SampleStream::in_domain(Domain::Photon, 12, 0, 0);
        let n = 1_000_000;
        let integral: f64 =
            (0..n).map(|_| f64::from(env.pdf(uniform_sphere(rng.next_2d())))).sum::<f64>() * 4.0 * std::f64::consts::PI
                / f64::from(n);
        assert!((integral - 1.0).abs() < 0.015, "∫pdf = {integral}");
        // Column 2 is black: φ in [2/8, 3/8) of the turn.
        let phi = TAU * 2.5 / 8.0;
        let d = Vec3A::new(0.6 * phi.sin(), 0.8, -0.6 * phi.cos());
        assert_eq!((env.eval(d), env.pdf(d)), (Vec3A::ZERO, 0.0));
        // The bright texel (row 1: θ in [30°, 60°]; column 5) against a dim one beside it.
        let at = |col: f32| {
            let (t, p) = (PI / 4.0, TAU * (col + 0.5) / 8.0);
            Vec3A::new(t.sin() * p.sin(), t.cos(), -t.sin() * p.cos())
        };
        assert_eq!(env.eval(at(5.0)), Vec3A::new(40.0, 30.0, 10.0));
        let ratio = env.pdf(at(5.0)) / env.pdf(at(4.0));
        let want = luminance(Vec3A::new(40.0, 30.0, 10.0)) / luminance(Vec3A::new(0.6, 0.5, 0.1));
        assert!((ratio / want - 1.0).abs() < 1e-4, "{ratio} vs {want}");
    }

    /// A constant environment is sampled uniformly over the sphere: every sample's estimate
    /// of `∫L dω`, `L/pdf`, is exactly 4π·L (to rounding).
    #[test]
    fn a_constant_environment_gives_its_radiance_exactly() {
        let l = Vec3A::new(0.7, 1.3, 2.0);
        let env = Environment::constant(l);
        let mut rng = SampleStream::in_domain(Domain::Photon, 13, 0, 0);
        let want = 4.0 * PI * l;
        for _ in 0..10_000 {
            let s = env.sample(rng.next_2d()).unwrap();
            assert_eq!(s.radiance, l);
            assert!(((s.radiance / s.pdf) - want).abs().max_element() < 1e-5 * want.max_element(), "{s:?}");
        }
        assert_eq!(env.eval(Vec3A::Y), l);
        assert_eq!(env.eval(-Vec3A::Y), l);
    }

    #[test]
    fn black_maps_sample_nothing_and_bad_maps_are_refused() {
        let env = Environment::constant(Vec3A::ZERO);
        assert!(env.sample(Vec2::new(0.3, 0.6)).is_none());
        assert_eq!(env.pdf(Vec3A::Y), 0.0);
        assert!(Environment::from_texels(2, 2, vec![Vec3A::ONE; 3]).is_err());
        assert!(Environment::from_texels(1, 1, vec![Vec3A::new(-1.0, 0.0, 0.0)]).is_err());
        assert!(Environment::from_texels(1, 1, vec![Vec3A::splat(f32::NAN)]).is_err());
    }
}
