//! Point and spot lights: all light leaves one point, so next event estimation reaches them
//! with a single deterministic connection (a delta position: no density, and no path can hit
//! them by chance). Intensity `I` is power per steradian, as in Mitsuba 3 and pbrt.
//!
//! A spot light's profile follows Mitsuba 3's `spot`: full intensity within `beam_width` of
//! its axis, falling linearly *in angle* to zero at `cutoff_angle` (defaults 20° and ¾ of the
//! cutoff), so scenes imported from Mitsuba match.
use super::{Light, LightSample, Receiver};
use crate::geometry::{Frame, Ray, Vec2, Vec3A, luminance};
use std::f32::consts::{PI, TAU};

/// The cone of a spot light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spot {
    /// Local frame, `z` along the axis.
    frame: Frame,
    cutoff: f32,
    beam: f32,
    cos_cutoff: f32,
    cos_beam: f32,
}

/// A point light, or with a cone a spot light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    pub position: Vec3A,
    /// Radiant intensity (on the axis, for a spot light), linear RGB.
    pub intensity: Vec3A,
    pub spot: Option<Spot>,
}

/// What reaches a point from the light, as next event estimation uses it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointSample {
    /// Unit direction from the receiving point to the light.
    pub direction: Vec3A,
    pub distance: f32,
    /// `I·falloff / d²`: times the receiver's `f·|cos θ|`, the contribution (unoccluded).
    pub irradiance: Vec3A,
}

/// A photon leaving the light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emission {
    pub origin: Vec3A,
    pub direction: Vec3A,
    /// Flux the photon carries (`I·falloff / pdf` of its direction).
    pub weight: Vec3A,
}

impl PointLight {
    /// A light shining equally in every direction.
    pub fn point(position: Vec3A, intensity: Vec3A) -> crate::Result<Self> {
        check(position, intensity)?;
        Ok(Self { position, intensity, spot: None })
    }

    /// A spot light at `position` pointing along `axis`, black beyond `cutoff_deg` from it and
    /// at full intensity within `beam_deg` (default ¾ of the cutoff).
    pub fn spot(
        position: Vec3A,
        axis: Vec3A,
        intensity: Vec3A,
        cutoff_deg: f32,
        beam_deg: Option<f32>,
    ) -> crate::Result<Self> {
        check(position, intensity)?;
        let axis = axis.try_normalize().ok_or_else(|| invalid("a spot light's direction must be a non-zero vector"))?;
        let beam_deg = beam_deg.unwrap_or(0.75 * cutoff_deg);
        if !(cutoff_deg > 0.0 && cutoff_deg <= 180.0) {
            return Err(invalid(&format!("a spot light's cutoff angle must lie in (0°, 180°], got {cutoff_deg}")));
        }
        if !(beam_deg > 0.0 && beam_deg <= cutoff_deg) {
            return Err(invalid(&format!(
                "a spot light's beam width must lie in (0°, cutoff angle {cutoff_deg}°], got {beam_deg}"
            )));
        }
        let (cutoff, beam) = (cutoff_deg.to_radians(), beam_deg.to_radians());
        let spot =
            Spot { frame: Frame::from_normal(axis), cutoff, beam, cos_cutoff: cutoff.cos(), cos_beam: beam.cos() };
        Ok(Self { position, intensity, spot: Some(spot) })
    }

    /// The profile in unit direction `d` leaving the light: 1 for a point light; for a spot
    /// light 1 within the beam, `(cutoff − θ)/(cutoff − beam)` up to the cutoff, 0 beyond.
    #[inline]
    #[must_use]
    pub fn falloff(&self, d: Vec3A) -> f32 {
        let Some(s) = &self.spot else {
            return 1.0;
        };
        let cos_theta = s.frame.to_local(d).z;
        if cos_theta <= s.cos_cutoff {
            0.0
        } else if cos_theta >= s.cos_beam || s.cutoff <= s.beam {
            1.0
        } else {
            ((s.cutoff - cos_theta.clamp(-1.0, 1.0).acos()) / (s.cutoff - s.beam)).clamp(0.0, 1.0)
        }
    }

    /// The light as seen from `x`; `None` at the light itself or where it sends nothing.
    #[inline]
    #[must_use]
    pub fn arrival(&self, x: Vec3A) -> Option<PointSample> {
        let to = self.position - x;
        let d2 = to.length_squared();
        let distance = d2.sqrt();
        let direction = to / distance;
        let falloff = self.falloff(-direction);
        (d2 > 0.0 && d2.is_finite() && falloff > 0.0).then(|| PointSample {
            direction,
            distance,
            irradiance: self.intensity * (falloff / d2),
        })
    }

    /// A photon: a direction uniform over the sphere (point) or over the cone (spot), weighted
    /// by its flux, so that the weights average to [`Self::power`].
    #[must_use]
    pub fn emit(&self, u: Vec2) -> Emission {
        let cos_max = self.spot.map_or(-1.0, |s| s.cos_cutoff);
        // Uniform in the cone cos θ ∈ [cos_max, 1]: density 1 / (2π(1 − cos_max)).
        let cos_theta = 1.0 - u.x * (1.0 - cos_max);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = TAU * u.y;
        let local = Vec3A::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta);
        let direction = match &self.spot {
            Some(s) => s.frame.to_world(local),
            None => local,
        };
        let inv_pdf = TAU * (1.0 - cos_max);
        Emission { origin: self.position, direction, weight: self.intensity * (self.falloff(direction) * inv_pdf) }
    }

    /// Total emitted power: `4π·I` for a point light; for a spot light
    /// `2π·I·(1 − (sin c − sin b)/(c − b))` (cutoff `c`, beam `b`; `1 − cos c` when they meet).
    #[must_use]
    pub fn power(&self) -> Vec3A {
        let solid = match &self.spot {
            None => 4.0 * PI,
            Some(s) if s.cutoff - s.beam < 1e-6 => TAU * (1.0 - s.cos_cutoff),
            Some(s) => TAU * (1.0 - (s.cutoff.sin() - s.beam.sin()) / (s.cutoff - s.beam)),
        };
        self.intensity * solid
    }
}

impl Light for PointLight {
    /// The one connection to the light (`p` its position), weighed by `1/pick`.
    fn sample_from(&self, at: &Receiver, _: f32, _: Vec2, pick: f32) -> Option<LightSample> {
        let l = self.arrival(at.x)?;
        Some(LightSample {
            prim: u32::MAX,
            delta: true,
            infinite: false,
            p: self.position,
            p_err: Vec3A::ZERO,
            ng: -l.direction,
            emission: l.irradiance,
            inv_pdf: 1.0 / pick,
        })
    }

    fn pdf_from(&self, _: &Receiver, _: u32, _: Vec3A) -> f32 {
        0.0
    }

    fn luminous_power(&self, _radius: f32) -> f32 {
        luminance(self.power()).max(1e-6 * self.power().max_element())
    }

    fn emit_photon(&self, _: f32, _: Vec2, u_dir: Vec2, _: (Vec3A, f32), pick: f32) -> Option<(Ray, Vec3A)> {
        let e = self.emit(u_dir);
        Some((Ray::new(e.origin, e.direction), e.weight / pick))
    }
}

fn invalid(message: &str) -> crate::Error {
    crate::Error::InvalidOption(message.to_string())
}

fn check(position: Vec3A, intensity: Vec3A) -> crate::Result<()> {
    if !position.is_finite() {
        return Err(invalid(&format!("a light's position must be finite, got {position}")));
    }
    if !(intensity.is_finite() && intensity.min_element() >= 0.0) {
        return Err(invalid(&format!("a light's intensity must be finite and non-negative, got {intensity}")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{Domain, SampleStream};

    fn spot() -> PointLight {
        PointLight::spot(Vec3A::new(0.0, 2.0, 0.0), Vec3A::NEG_Y, Vec3A::new(3.0, 2.0, 1.0), 30.0, Some(20.0)).unwrap()
    }

    #[test]
    fn spot_profile_follows_mitsuba() {
        let s = spot();
        let at = |deg: f32| {
            let t = deg.to_radians();
            s.falloff(Vec3A::new(t.sin(), -t.cos(), 0.0))
        };
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(19.9), 1.0);
        assert!((at(25.0) - 0.5).abs() < 1e-4, "{}", at(25.0));
        assert_eq!(at(30.1), 0.0);
        assert_eq!(at(120.0), 0.0);
        // Defaults: beam ¾ of the cutoff.
        let d = PointLight::spot(Vec3A::ZERO, Vec3A::Z, Vec3A::ONE, 20.0, None).unwrap();
        assert_eq!(d.spot.unwrap().beam, 15f32.to_radians());
        assert_eq!(PointLight::point(Vec3A::ZERO, Vec3A::ONE).unwrap().falloff(Vec3A::X), 1.0);
    }

    /// Next event estimation: `I·falloff/d²` along the right direction, nothing outside the cone.
    #[test]
    fn what_a_point_receives() {
        let s = spot();
        let got = s.arrival(Vec3A::ZERO).unwrap();
        assert_eq!(got.direction, Vec3A::Y);
        assert_eq!(got.distance, 2.0);
        assert_eq!(got.irradiance, Vec3A::new(3.0, 2.0, 1.0) / 4.0);
        assert!(s.arrival(Vec3A::new(5.0, 0.0, 0.0)).is_none());
        assert!(s.arrival(s.position).is_none());
    }

    /// The photons' weights average to the closed-form power (10⁵ photons; the spot's weights
    /// vary only in the transition ring, so the relative standard error is below 0.3%;
    /// tolerance 1%), and the closed form matches a direct integration of the profile.
    #[test]
    fn photons_carry_the_power() {
        let mut rng = SampleStream::in_domain(Domain::Photon, 21, 0, 0);
        for light in [PointLight::point(Vec3A::ONE, Vec3A::new(1.0, 2.0, 3.0)).unwrap(), spot()] {
            let n = 100_000;
            let mut sum = Vec3A::ZERO;
            for _ in 0..n {
                let e = light.emit(rng.next_2d());
                assert!((e.direction.length() - 1.0).abs() < 1e-5 && e.origin == light.position);
                sum += e.weight;
            }
            let mean = sum / n as f32;
            let power = light.power();
            assert!(((mean - power) / power).abs().max_element() < 0.01, "{mean} vs {power}");
            // ∫ I·falloff dω by a fine midpoint rule in θ (the profile is symmetric in φ).
            let m = 200_000;
            let integral: f64 = (0..m)
                .map(|i| {
                    let t = PI * (i as f32 + 0.5) / m as f32;
                    let axis = light.spot.map_or(Vec3A::Z, |s| s.frame.to_world(Vec3A::Z));
                    let d = Frame::from_normal(axis).to_world(Vec3A::new(t.sin(), 0.0, t.cos()));
                    f64::from(light.falloff(d)) * f64::from(t.sin())
                })
                .sum::<f64>()
                * std::f64::consts::TAU
                * std::f64::consts::PI
                / f64::from(m);
            let want = f64::from(power.x / light.intensity.x);
            assert!((integral / want - 1.0).abs() < 1e-3, "∫falloff dω = {integral}, closed form {want}");
        }
    }

    #[test]
    fn bad_lights_are_refused() {
        let p = Vec3A::ZERO;
        assert!(PointLight::point(p, Vec3A::new(-1.0, 0.0, 0.0)).is_err());
        assert!(PointLight::point(Vec3A::splat(f32::INFINITY), Vec3A::ONE).is_err());
        assert!(PointLight::spot(p, Vec3A::ZERO, Vec3A::ONE, 20.0, None).is_err());
        assert!(PointLight::spot(p, Vec3A::Z, Vec3A::ONE, 0.0, None).is_err());
        assert!(PointLight::spot(p, Vec3A::Z, Vec3A::ONE, 200.0, None).is_err());
        assert!(PointLight::spot(p, Vec3A::Z, Vec3A::ONE, 20.0, Some(25.0)).is_err());
        assert!(PointLight::spot(p, Vec3A::Z, Vec3A::ONE, 20.0, Some(f32::NAN)).is_err());
        // A hard-edged spot (beam = cutoff): power 2πI(1 − cos c).
        let hard = PointLight::spot(p, Vec3A::Z, Vec3A::ONE, 40.0, Some(40.0)).unwrap();
        assert!((hard.power().x - TAU * (1.0 - 40f32.to_radians().cos())).abs() < 1e-5);
    }
}
