//! Distant (directional) lights: parallel light from one direction, as the sun is modelled
//! (pbrt's `distant`, Mitsuba's `directional`). `irradiance` is the power per unit area on a
//! surface facing the light. Like point lights they are delta lights: next event estimation
//! reaches them with one deterministic connection, and no path hits them by chance.
use super::{Light, LightSample, Receiver};
use crate::geometry::{Frame, Ray, Vec2, Vec3A, luminance, warp};
use std::f32::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistantLight {
    /// Unit direction the light travels in.
    pub direction: Vec3A,
    /// Irradiance on a surface facing the light, linear RGB.
    pub irradiance: Vec3A,
}

impl DistantLight {
    /// `None` unless `direction` is non-zero and finite and `irradiance` finite and
    /// non-negative.
    pub fn new(direction: Vec3A, irradiance: Vec3A) -> crate::Result<Self> {
        let direction = direction.try_normalize().ok_or_else(|| {
            crate::Error::InvalidOption(format!("a distant light needs a non-zero, finite direction, got {direction}"))
        })?;
        if !(irradiance.is_finite() && irradiance.min_element() >= 0.0) {
            return Err(crate::Error::InvalidOption(format!(
                "a distant light's irradiance must be finite and non-negative, got {irradiance}"
            )));
        }
        Ok(Self { direction, irradiance })
    }

    /// The power crossing a disc of radius `r` facing the light (what the scene's bounding
    /// sphere receives).
    #[must_use]
    pub fn power_through(&self, r: f32) -> Vec3A {
        self.irradiance * (PI * r * r)
    }

    /// A photon: a uniform point `u` of the disc of radius `radius` facing the light, on the
    /// light's side of the sphere around `centre`, travelling along the light; its flux is
    /// `E · π r²`.
    #[must_use]
    pub fn emit(&self, centre: Vec3A, radius: f32, u: Vec2) -> (Vec3A, Vec3A, Vec3A) {
        let frame = Frame::from_normal(self.direction);
        let disc = warp::uniform_disk(u) * radius;
        let origin = centre - self.direction * radius + frame.s * disc.x + frame.t * disc.y;
        (origin, self.direction, self.power_through(radius))
    }
}

impl Light for DistantLight {
    /// As a light at infinity: `p` is the direction towards it.
    fn sample_from(&self, _: &Receiver, _: f32, _: Vec2, pick: f32) -> Option<LightSample> {
        Some(LightSample {
            prim: u32::MAX,
            delta: true,
            infinite: true,
            p: -self.direction,
            p_err: Vec3A::ZERO,
            ng: self.direction,
            emission: self.irradiance,
            inv_pdf: 1.0 / pick,
        })
    }

    fn pdf_from(&self, _: &Receiver, _: u32, _: Vec3A) -> f32 {
        0.0
    }

    fn luminous_power(&self, radius: f32) -> f32 {
        let p = self.power_through(radius);
        luminance(p).max(1e-6 * p.max_element())
    }

    fn emit_photon(&self, _: f32, u_point: Vec2, _: Vec2, bounds: (Vec3A, f32), pick: f32) -> Option<(Ray, Vec3A)> {
        let (origin, dir, flux) = self.emit(bounds.0, bounds.1, u_point);
        Some((Ray::new(origin, dir), flux / pick))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn photons_leave_a_disc_facing_the_light() {
        let l = DistantLight::new(Vec3A::new(0.0, -2.0, 0.0), Vec3A::splat(3.0)).unwrap();
        assert_eq!(l.direction, -Vec3A::Y);
        for k in 0..50 {
            let u = Vec2::new((k as f32 * 0.37).fract(), (k as f32 * 0.61).fract());
            let (o, d, flux) = l.emit(Vec3A::new(1.0, 1.0, 1.0), 2.0, u);
            assert_eq!(d, -Vec3A::Y);
            assert!((o.y - 3.0).abs() < 1e-5, "{o}");
            assert!(((o - Vec3A::new(1.0, 3.0, 1.0)).length()) <= 2.0 + 1e-5);
            assert!((flux - Vec3A::splat(3.0 * PI * 4.0)).abs().max_element() < 1e-4);
        }
        assert!(DistantLight::new(Vec3A::ZERO, Vec3A::ONE).is_err());
        assert!(DistantLight::new(Vec3A::X, Vec3A::splat(-1.0)).is_err());
    }
}
