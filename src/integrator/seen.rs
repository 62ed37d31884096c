//! Light the camera sees, split over the pixel.
//!
//! Where a light smaller than a pixel is seen directly (or through mirrors and glass), a
//! pixel's error is how often its film points land on the light: the walk behind the first
//! hit cannot help, and the rest of the pixel may already be nearly noiseless. The *seen*
//! term, emission met along the camera's prefix of delta scatters (the first hit's own
//! emission, then emission behind each delta lobe while every scatter so far was delta), is
//! estimated apart in such pixels: the walk skips it, and `m × m` stratified film points of
//! the pixel trace the prefix again and average what they see. Every camera sample's
//! expected value is unchanged for any `m ≥ 1` (the walk's remaining terms and the strata's
//! mean are each unbiased for their share), so `m` may come from anything but the final
//! render's own samples: here from the training iterations' per-pixel variances of the two
//! parts and from the emitters' projections onto the film (a light too small for training to
//! have met is still found).
use super::{RenderContext, Scatter, Scratch, sample_bsdf};
use crate::accel::Accel;
use crate::geometry::{Ray, UVec2, Vec2, Vec3A};
use crate::sampler::{SampleStream, survival_probability};
use crate::scene::SurfaceInteraction;

/// Strata per axis where nothing is split.
pub const UNSPLIT: u8 = 1;

/// Each pixel's strata per axis (`m`; `m × m` film points per camera sample; 1: not split).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SeenPlan {
    width: u32,
    strata: Vec<u8>,
}

impl SeenPlan {
    /// Strata per axis of `pixel`.
    #[inline]
    #[must_use]
    pub fn strata(&self, pixel: UVec2) -> u8 {
        self.strata.get((pixel.y * self.width + pixel.x) as usize).copied().unwrap_or(UNSPLIT)
    }

    /// Pixels split, and the most strata per axis of any.
    #[must_use]
    pub fn split_pixels(&self) -> (usize, u8) {
        let split = self.strata.iter().filter(|&&m| m > UNSPLIT).count();
        (split, self.strata.iter().copied().max().unwrap_or(UNSPLIT))
    }
}

/// Per-pixel sums of the training samples' seen term and of the rest (each summed over the
/// three channels), from which [`plan`] reads their variances.
#[derive(Clone, Debug, Default)]
pub struct SeenStats {
    /// Samples per pixel summed.
    pub samples: u64,
    /// Σ seen, Σ seen², Σ rest, Σ rest², Σ rays of the delta prefix per pixel (row-major).
    pub sums: Vec<[f64; 5]>,
    /// Rays the summed samples traced.
    pub rays: u64,
}

impl SeenStats {
    /// Adds one pass of `spp` samples per pixel.
    pub fn add(&mut self, spp: u32, sums: &[[f64; 5]], rays: u64) {
        if self.sums.is_empty() {
            self.sums = vec![[0.0; 5]; sums.len()];
        }
        for (a, b) in self.sums.iter_mut().zip(sums) {
            for k in 0..5 {
                a[k] += b[k];
            }
        }
        self.samples += u64::from(spp);
        self.rays += rays;
    }
}

/// The emission along the camera's delta prefix through film point `film`, with the
/// throughput of its delta scatters (roulette by albedo after 3, as the walks). Paths of at
/// most `ctx.max_depth` segments.
#[inline]
pub fn seen_emission<A: Accel>(
    ctx: &RenderContext<A>,
    film: Vec2,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
) -> Vec3A {
    let mut ray = ctx.scene.camera.ray(film);
    let (mut weight, mut seen) = (Vec3A::ONE, Vec3A::ZERO);
    let mut segments = 1u32;
    loop {
        scratch.rays += 1;
        if segments > ctx.max_depth {
            return seen;
        }
        let Some(hit) = ctx.accel.intersect(&ray) else {
            return seen;
        };
        let si = ctx.scene.interaction(&ray, &hit);
        seen += weight * si.emitted();
        let Some(s) = delta_scatter(&si, segments, rng) else {
            return seen;
        };
        weight *= s.weight;
        ray = si.spawn_ray(s.dir);
        segments += 1;
    }
}

/// The camera's delta prefix continued at `si`, its `segments`-th hit: a delta lobe of its
/// BSDF, with roulette by albedo after 3 bounces (as the walks) folded into the weight;
/// `None` where the prefix ends (no delta lobe there, roulette, or a non-delta lobe drawn).
#[inline]
pub(crate) fn delta_scatter(si: &SurfaceInteraction, segments: u32, rng: &mut SampleStream) -> Option<Scatter> {
    if !si.material.bsdf.has_delta_lobe() {
        return None;
    }
    let depth = segments - 1;
    let q = if depth >= 3 { survival_probability(si.material.albedo()) } else { 1.0 };
    let q = if depth >= 32 { q.min(0.8) } else { q };
    if q <= 0.0 || rng.next_f32() >= q {
        return None;
    }
    let frame = si.bsdf_frame();
    let s = sample_bsdf(si, &frame, frame.to_local(si.wo), rng).filter(|s| s.delta)?;
    Some(Scatter { weight: s.weight / q, ..s })
}

/// The seen term of `pixel` from `m × m` stratified film points (jittered in each stratum of
/// the pixel filter's sample square), averaged.
#[inline]
pub fn split_seen<A: Accel>(
    ctx: &RenderContext<A>,
    pixel: UVec2,
    m: u8,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
) -> Vec3A {
    let m = u32::from(m.max(1));
    let inv = 1.0 / m as f32;
    let mut sum = Vec3A::ZERO;
    for j in 0..m {
        for i in 0..m {
            let u = rng.next_2d();
            let u = Vec2::new(((i as f32 + u.x) * inv).min(0.999_999_94), ((j as f32 + u.y) * inv).min(0.999_999_94));
            let film = ctx.scene.camera.film_point(pixel, u);
            sum += if ctx.volumetric {
                super::volume::seen_emission_volume(ctx, film, rng, scratch)
            } else {
                seen_emission(ctx, film, rng, scratch)
            };
        }
    }
    sum * (inv * inv)
}

/// The per-sample variance of the seen term (channels summed) that lights smaller than a
/// pixel's footprint add where they project, lit side towards the camera and their centre
/// unoccluded: a light covering a share `f` of the footprint with radiance `L` gives
/// `L²·f·(1 − f)`. Lights of a footprint or more are left to the training's measurement.
#[must_use]
pub fn projected_variance<A: Accel>(ctx: &RenderContext<A>) -> Vec<f32> {
    let camera = &ctx.scene.camera;
    let (w, h) = (camera.width, camera.height);
    let [rx, ry] = camera.filter.shape.radius();
    let footprint = (4.0 * rx * ry).max(1e-6);
    // Per pixel: the share of its footprint lights cover, and their brightest radiance.
    let mut cover = vec![(0.0f32, 0.0f32); (w as usize) * (h as usize)];
    for (t, tri) in ctx.scene.triangles.iter().enumerate() {
        let material = ctx.scene.material_of(t as u32);
        if material.emission == Vec3A::ZERO {
            continue;
        }
        let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
        let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        if !material.two_sided_emission && ng.dot(camera.eye - centre) <= 0.0 {
            continue;
        }
        let (Some(a), Some(b), Some(c)) = (camera.project(tri[0]), camera.project(tri[1]), camera.project(tri[2]))
        else {
            continue;
        };
        let area = 0.5 * ((b - a).perp_dot(c - a)).abs();
        if area.is_nan() || area >= footprint {
            continue;
        }
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        // Pixels whose footprint [x + ½ − r, x + ½ + r] meets the light's box.
        let x0 = (lo.x - 0.5 - rx).ceil().max(0.0);
        let x1 = (hi.x - 0.5 + rx).floor().min(w as f32 - 1.0);
        let y0 = (lo.y - 0.5 - ry).ceil().max(0.0);
        let y1 = (hi.y - 0.5 + ry).floor().min(h as f32 - 1.0);
        if x0 > x1 || y0 > y1 {
            continue;
        }
        let Some(tr) = transmittance_to(ctx, camera.eye, centre) else {
            continue;
        };
        let radiance = (material.emission * tr).element_sum();
        for y in y0 as u32..=y1 as u32 {
            for x in x0 as u32..=x1 as u32 {
                let c = &mut cover[(y * w + x) as usize];
                c.0 += area / footprint;
                c.1 = c.1.max(radiance);
            }
        }
    }
    cover
        .into_iter()
        .map(|(f, l)| {
            let f = f.min(1.0);
            l * l * f * (1.0 - f)
        })
        .collect()
}

/// What reaches the camera at `eye` from point `to` (the light's own surface excluded): zero
/// behind a surface (`None`), else the transmittance of the media crossed (1 in vacuum), the
/// boundaries of media crossed without a bounce.
fn transmittance_to<A: Accel>(ctx: &RenderContext<A>, eye: Vec3A, to: Vec3A) -> Option<Vec3A> {
    let scene = ctx.scene;
    let (mut origin, mut medium, mut tr) = (eye, scene.camera_medium, Vec3A::ONE);
    for _ in 0..64 {
        let span = to - origin;
        let distance = span.length();
        if distance <= 0.0 {
            return Some(tr);
        }
        let ray = Ray::new(origin, span / distance);
        let along = |m: Option<u16>, d: f32| m.map_or(Vec3A::ONE, |i| scene.media[usize::from(i)].transmittance(d));
        let Some(hit) = ctx.accel.intersect(&ray).filter(|h| h.t < distance * (1.0 - 1e-4)) else {
            return Some(tr * along(medium, distance));
        };
        let si = scene.interaction(&ray, &hit);
        if !si.material.bsdf.is_interface() {
            return None;
        }
        tr *= along(medium, hit.t);
        medium = scene.medium_interface(si.prim).after(si.ng, ray.dir, medium);
        origin = si.spawn_ray(ray.dir).origin;
    }
    None
}

/// Each pixel's strata, chosen for the image's efficiency: a split pixel's seen variance
/// falls by its `k = m²` film points while every one of them costs `c` rays, the rays of the
/// pixel's delta prefix as training measured them (one where the light is seen directly,
/// several through glass), and every pixel of the image waits for those rays. The product
/// (mean variance `V̄`) × (mean rays per sample `C̄`) is least at `k = √(V_seen / V̄ · C̄ / c)`,
/// with `V̄` and `C̄` those of the split image (a fixed point, reached in a few rounds), at
/// most `max_strata` per axis. `V_seen` is the larger of the training's measurement and the
/// lights' projection ([`projected_variance`]). All split pixels together add at most half the
/// walk's rays per pass (strata lowered evenly until they fit).
///
/// Judging each pixel by its own rest instead, with a film point at one ray, Bitterli's
/// coffee at an eighth of its size splits 374 pixels seen through the glass 8 × 8 (several
/// rays a film point there) and renders half the path tracer's samples per second: MSE
/// 1.5× path's at equal time. With this rule it splits them 3 × 3 and is level with path.
#[must_use]
pub fn plan(width: u32, stats: &SeenStats, projected: &[f32], cost: f64, max_strata: u8) -> SeenPlan {
    let n = stats.samples.max(1) as f64;
    let variance = |sum: f64, sq: f64| (sq / n - (sum / n) * (sum / n)).max(0.0);
    let pixels = stats.sums.len().max(1) as f64;
    let cost = cost.max(1.0);
    // Per pixel: the seen term's variance, the rest's, and the rays of a film point.
    let parts: Vec<(f64, f64, f64)> = stats
        .sums
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let seen = variance(s[0], s[1]).max(f64::from(projected.get(i).copied().unwrap_or(0.0)));
            (seen, variance(s[2], s[3]), (s[4] / n).max(1.0))
        })
        .collect();
    let top = f64::from(max_strata.max(1));
    let mut strata = vec![UNSPLIT; parts.len()];
    for _ in 0..4 {
        let (mut v, mut c) = (0.0, cost);
        for (&m, &(seen, rest, point)) in strata.iter().zip(&parts) {
            let k = f64::from(m) * f64::from(m);
            v += rest + seen / k;
            if m > UNSPLIT {
                c += k * point / pixels;
            }
        }
        let v = (v / pixels).max(1e-30);
        for (m, &(seen, _, point)) in strata.iter_mut().zip(&parts) {
            let k = (seen / v * c / point).sqrt();
            let r = k.sqrt().round();
            *m = if r.is_finite() { r.clamp(1.0, top) as u8 } else { UNSPLIT };
        }
    }
    let budget = 0.5 * cost * pixels;
    let extra = |strata: &[u8]| {
        strata.iter().zip(&parts).filter(|&(&m, _)| m > 1).map(|(&m, p)| f64::from(m) * f64::from(m) * p.2).sum::<f64>()
    };
    while extra(&strata) > budget {
        for m in &mut strata {
            *m = m.saturating_sub(1).max(UNSPLIT);
        }
    }
    SeenPlan { width, strata }
}

/// A pixel's per-sample `variance` and `rays`, measured by training samples that did not split
/// the seen light, as they will be where `plan` splits it into `m²` film points: the seen
/// term's share of the variance (the larger of the training's and the lights' projection,
/// as [`plan`] weighs it; `projected` may be empty) falls by `m²`, and each film point adds
/// the rays of the pixel's delta prefix.
#[must_use]
pub fn after_split(
    plan: &SeenPlan,
    stats: &SeenStats,
    projected: &[f32],
    pixel: usize,
    variance: f64,
    rays: f64,
) -> (f64, f64) {
    let m = plan.strata.get(pixel).copied().unwrap_or(UNSPLIT);
    let Some(s) = stats.sums.get(pixel).filter(|_| m > UNSPLIT) else {
        return (variance, rays);
    };
    let n = stats.samples.max(1) as f64;
    let var = |sum: f64, sq: f64| (sq / n - (sum / n) * (sum / n)).max(0.0);
    let seen = var(s[0], s[1]).max(f64::from(projected.get(pixel).copied().unwrap_or(0.0)));
    let rest = var(s[2], s[3]);
    let k = f64::from(m) * f64::from(m);
    // Channel-summed parts: their ratio scales the channel-averaged variance.
    let share = if seen + rest > 0.0 { (rest + seen / k) / (seen + rest) } else { 1.0 };
    (variance * share, rays + k * (s[4] / n).max(1.0))
}

/// [`plan`] from the lights' projections onto the film alone (no pass measured yet): where a
/// light smaller than a pixel projects, split from the start. Samples drawn under it stay
/// unbiased, since the plan looks at no sample.
#[must_use]
pub fn plan_from_projection(width: u32, projected: &[f32], max_strata: u8) -> SeenPlan {
    let none = SeenStats { samples: 1, sums: vec![[0.0; 5]; projected.len()], rays: 0 };
    plan(width, &none, projected, 1.0, max_strata)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A split pixel's variance keeps its rest and a `1/m²` share of its seen term, and its
    /// samples cost `m²` more film points; an unsplit pixel's are left as measured.
    #[test]
    fn a_split_lowers_the_seen_variance_and_adds_its_rays() {
        // Two pixels of 4 samples: seen 0, 0, 6, 6 (variance 9), rest 1, 3, 1, 3 (variance 1),
        // two delta-prefix rays a sample.
        let s = [12.0, 72.0, 8.0, 20.0, 8.0];
        let st = SeenStats { samples: 4, sums: vec![s, s], rays: 0 };
        let plan = SeenPlan { width: 2, strata: vec![3, UNSPLIT] };
        let (v, r) = after_split(&plan, &st, &[], 0, 5.0, 4.0);
        assert!((v - 5.0 * (1.0 + 9.0 / 9.0) / 10.0).abs() < 1e-12, "{v}");
        assert!((r - (4.0 + 9.0 * 2.0)).abs() < 1e-12, "{r}");
        assert_eq!(after_split(&plan, &st, &[], 1, 5.0, 4.0), (5.0, 4.0));
        // The lights' projection counts where it is the larger.
        let (v, _) = after_split(&plan, &st, &[90.0, 0.0], 0, 5.0, 4.0);
        assert!((v - 5.0 * (1.0 + 90.0 / 9.0) / 91.0).abs() < 1e-12, "{v}");
    }

    fn stats(sums: Vec<[f64; 5]>, samples: u64) -> SeenStats {
        SeenStats { samples, sums, rays: 0 }
    }

    /// A pixel whose variance is all in its seen term splits up to the cap; one without a seen
    /// term does not; a projected light counts where training met none; a long delta prefix
    /// asks for fewer film points; a seen term small beside the image's noise elsewhere is
    /// not split however quiet its pixel's rest; the budget holds, counted in rays.
    #[test]
    fn plan_splits_where_the_seen_term_dominates() {
        // Four samples: seen 0 or 10 (variance 25); rest 1 ± 0.1 (variance 0.01), rest of
        // variance 1 and of variance 100; one ray a film point.
        let (seen, quiet, rest1, rest100) = ([20.0, 200.0], [4.0, 4.04], [4.0, 8.0], [4.0, 404.0]);
        let pixel = |s: [f64; 2], r: [f64; 2]| [s[0], s[1], r[0], r[1], 4.0];
        let at = |p: &SeenPlan| p.strata(UVec2::new(0, 0));
        // Pixel 0 seen, the 199 others quiet (a budget of 0.5 × 8 × 200 = 800 extra rays).
        let mut sums = vec![pixel([0.0; 2], quiet); 200];
        sums[0] = pixel(seen, quiet);
        let p = plan(200, &stats(sums.clone(), 4), &[], 8.0, 8);
        assert_eq!(at(&p), 8);
        assert_eq!(p.strata(UVec2::new(1, 0)), 1);
        assert_eq!(p.split_pixels(), (1, 8));
        let p = plan(200, &stats(sums.clone(), 4), &[0.0, 25.0], 8.0, 8);
        assert_eq!(p.strata(UVec2::new(1, 0)), 8);
        // Every pixel's rest of variance 1: k = √(25 / V̄ · C̄ / c) ≈ 14 film points (4 × 4)
        // where a film point costs one ray, 5 (2 × 2) where it costs 8.
        let mut noisy = vec![pixel([0.0; 2], rest1); 200];
        noisy[0] = pixel(seen, rest1);
        assert_eq!(at(&plan(200, &stats(noisy.clone(), 4), &[], 8.0, 8)), 4);
        noisy[0][4] = 8.0 * 4.0;
        assert_eq!(at(&plan(200, &stats(noisy, 4), &[], 8.0, 8)), 2);
        // The image's noise is elsewhere (variance 100): pixel 0's quiet rest does not matter.
        let mut elsewhere = vec![pixel([0.0; 2], rest100); 200];
        elsewhere[0] = pixel(seen, quiet);
        assert_eq!(at(&plan(200, &stats(elsewhere, 4), &[], 8.0, 8)), 1);
        // On two pixels a split of more than 2 × 2 would pass the budget of 8 rays: lowered.
        assert_eq!(at(&plan(2, &stats(sums[..2].to_vec(), 4), &[], 8.0, 8)), 2);
        // A thousand pixels all asking for 8×8 cannot have them: half the walk's rays in all,
        // a film point costing its prefix's rays.
        for rays in [1.0, 6.0] {
            let many = vec![[20.0, 200.0, 4.0, 4.04, 4.0 * rays]; 1000];
            let p = plan(1000, &stats(many, 4), &[], 8.0, 8);
            let (split, most) = p.split_pixels();
            let extra = split as f64 * f64::from(most) * f64::from(most) * rays;
            assert!(extra <= 4000.0, "{split} pixels at {most}, {rays} rays a film point");
        }
        assert_eq!(plan(2, &stats(vec![[0.0; 5]; 2], 4), &[], 8.0, 8).split_pixels(), (0, 1));
    }
}
