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
use crate::sampler::{Domain, SampleStream, survival_probability};
use crate::scene::SurfaceInteraction;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

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
    /// Σ seen, Σ seen², Σ rest, Σ rest², Σ rays of the delta prefix, Σ seen·rest per pixel
    /// (row-major).
    pub sums: Vec<[f64; 6]>,
    /// Rays the summed samples traced.
    pub rays: u64,
}

impl SeenStats {
    /// Adds one pass of `spp` samples per pixel.
    pub fn add(&mut self, spp: u32, sums: &[[f64; 6]], rays: u64) {
        if self.sums.is_empty() {
            self.sums = vec![[0.0; 6]; sums.len()];
        }
        for (a, b) in self.sums.iter_mut().zip(sums) {
            for k in 0..6 {
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
    trace_seen(ctx, film, rng, scratch).0
}

/// Where a delta prefix that scattered at least once ended: its last ray and the distance
/// to the surface that ended it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PrefixEnd {
    pub ray: Ray,
    pub t: f32,
}

/// [`seen_emission`], and where the prefix ended when it scattered at least once and met a
/// surface without a delta lobe.
#[inline]
fn trace_seen<A: Accel>(
    ctx: &RenderContext<A>,
    film: Vec2,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
) -> (Vec3A, Option<PrefixEnd>) {
    let mut ray = ctx.scene.camera.ray(film);
    let (mut weight, mut seen) = (Vec3A::ONE, Vec3A::ZERO);
    let mut segments = 1u32;
    loop {
        scratch.rays += 1;
        if segments > ctx.max_depth {
            return (seen, None);
        }
        let Some(hit) = ctx.accel.intersect(&ray) else {
            return (seen, None);
        };
        let si = ctx.scene.interaction(&ray, &hit);
        seen += weight * si.emitted();
        let Some(s) = delta_scatter(&si, segments, rng) else {
            return (seen, (segments > 1).then_some(PrefixEnd { ray, t: hit.t }));
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
    let mut sum = Vec3A::ZERO;
    for_each_stratum(ctx, pixel, m, rng, scratch, |seen, _| sum += seen);
    let inv = 1.0 / m as f32;
    sum * (inv * inv)
}

/// The seen term through each of `m × m` stratified film points of `pixel` (jittered in each
/// stratum of the pixel filter's sample square, row by row), handed to `each` with where its
/// prefix ended.
#[inline]
fn for_each_stratum<A: Accel>(
    ctx: &RenderContext<A>,
    pixel: UVec2,
    m: u32,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
    mut each: impl FnMut(Vec3A, Option<PrefixEnd>),
) {
    let inv = 1.0 / m as f32;
    for j in 0..m {
        for i in 0..m {
            let u = rng.next_2d();
            let u = Vec2::new(((i as f32 + u.x) * inv).min(0.999_999_94), ((j as f32 + u.y) * inv).min(0.999_999_94));
            let film = ctx.scene.camera.film_point(pixel, u);
            let (seen, end) = if ctx.volumetric {
                super::volume::trace_seen_volume(ctx, film, rng, scratch)
            } else {
                trace_seen(ctx, film, rng, scratch)
            };
            each(seen, end);
        }
    }
}

/// Points per square pixel of a light's image that [`projected_variance`] looks through at
/// most: a sliver of 1/1,000 of a pixel still holds about 16.
pub const PROJECTION_DENSITY: f64 = 16_384.0;
/// Points [`projected_variance`] looks through over all lights (one ray or more each): where
/// the lights' images are larger, they are spread thinner.
pub const PROJECTION_POINTS: f64 = 262_144.0;
/// The largest share of a pixel's footprint the lights' projection judges: above it, the
/// training's own measure of the seen light stands.
pub const PROJECTED_SHARE: f64 = 0.25;
/// The golden ratio's fractional part: the second axis of the lattice of points.
const GOLDEN: f64 = 0.618_033_988_749_894_9;

/// The per-sample variance of the seen term (channels summed) that the lights' visible parts
/// add where they project: a pixel whose footprint sees lights of radiance `Lⱼ` over shares
/// `fⱼ` of it has `Σ fⱼLⱼ² − (Σ fⱼLⱼ)²`. Each emitting triangle facing the camera is covered by
/// points spread evenly over its image on the film (at most [`PROJECTION_DENSITY`] per square
/// pixel, [`PROJECTION_POINTS`] over all lights), each point's share counted where the camera
/// sees it (its transmittance through media and index-matched boundaries; zero behind a
/// surface). So a light larger than a pixel of which the camera sees only a sliver past an
/// occluder (a lamp's bulb past its shade) counts as the small light it looks like, and a
/// light fully seen over a pixel adds nothing there. The points are fixed by the geometry
/// alone (no random number), so a plan built from them keeps every sample unbiased. Pixels
/// whose footprint the lights cover by [`PROJECTED_SHARE`] or more read 0 (the training
/// meets those lights often enough to measure them).
#[must_use]
pub fn projected_variance<A: Accel>(ctx: &RenderContext<A>) -> Vec<f32> {
    let camera = &ctx.scene.camera;
    let (w, h) = (camera.width, camera.height);
    let [rx, ry] = camera.filter.shape.radius();
    let footprint = (4.0 * rx * ry).max(1e-6);
    // The emitting triangles facing the camera whose image meets the film: index, film
    // corners and image area (square pixels).
    let mut lights: Vec<(usize, [Vec2; 3], f32)> = Vec::new();
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
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        let meets = hi.x + rx >= 0.0 && lo.x - rx <= w as f32 && hi.y + ry >= 0.0 && lo.y - ry <= h as f32;
        if area.is_finite() && area > 0.0 && meets {
            lights.push((t, [a, b, c], area));
        }
    }
    // Per pixel: Σ f, Σ f·L and Σ f·L² (channel sums), f the share of its footprint.
    let mut moments = vec![(0.0f64, 0.0f64, 0.0f64); (w as usize) * (h as usize)];
    let total: f64 = lights.iter().map(|l| f64::from(l.2)).sum();
    let density = PROJECTION_DENSITY.min(PROJECTION_POINTS / total.max(1e-30));
    for (t, [a, b, c], area) in lights {
        let tri = ctx.scene.triangles[t];
        let emission = ctx.scene.material_of(t as u32).emission;
        let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        // At most `PROJECTION_POINTS` for one triangle, at least one.
        let n = (f64::from(area) * density).ceil().clamp(1.0, PROJECTION_POINTS) as u32;
        let share = f64::from(area) / f64::from(n) / f64::from(footprint);
        for i in 0..n {
            // A rank-1 lattice over the unit square, folded onto the triangle.
            let u = (f64::from(i) + 0.5) / f64::from(n);
            let v = (f64::from(i) * GOLDEN).fract();
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let (u, v) = (u as f32, v as f32);
            let film = a + (b - a) * u + (c - a) * v;
            // The light's point the camera's ray through `film` meets.
            let ray = camera.ray(film);
            let along = ray.dir.dot(ng);
            if along == 0.0 {
                continue;
            }
            let point = ray.origin + ray.dir * ((tri[0] - ray.origin).dot(ng) / along);
            let Some(tr) = transmittance_to(ctx, camera.eye, point) else {
                continue;
            };
            let radiance = f64::from((emission * tr).element_sum());
            if !(radiance.is_finite() && radiance > 0.0) {
                continue;
            }
            // Pixels whose footprint [x + ½ − r, x + ½ + r] holds the point.
            let x0 = (film.x - 0.5 - rx).ceil().max(0.0);
            let x1 = (film.x - 0.5 + rx).floor().min(w as f32 - 1.0);
            let y0 = (film.y - 0.5 - ry).ceil().max(0.0);
            let y1 = (film.y - 0.5 + ry).floor().min(h as f32 - 1.0);
            if !(x0 <= x1 && y0 <= y1) {
                continue;
            }
            for y in y0 as u32..=y1 as u32 {
                for x in x0 as u32..=x1 as u32 {
                    let m = &mut moments[(y * w + x) as usize];
                    m.0 += share;
                    m.1 += share * radiance;
                    m.2 += share * radiance * radiance;
                }
            }
        }
    }
    // Where lights cover a large share of the footprint the training meets them often and
    // measures their variance itself; the points' own discretisation (a few per cent of a
    // pixel) would read a fully covered pixel as a noisy one.
    moments
        .into_iter()
        .map(|(f, mean, square)| if f < PROJECTED_SHARE { (square - mean * mean).max(0.0) as f32 } else { 0.0 })
        .collect()
}

/// Film points [`probed_variance`] traces in one pixel at most.
pub const PROBE_POINTS_PER_PIXEL: u32 = 16_384;
/// Film points the probe's first look traces in one pixel at most.
pub const PROBE_FIRST_POINTS: u32 = 1024;
/// The share of the probe's rays its first look may take; the rest go to the pixels whose
/// prefixes passed near a light ([`NEAR_LIGHT`]).
pub const PROBE_FIRST_SHARE: f64 = 0.25;
/// A prefix whose last ray passes within this many of a light triangle's radii of its centre
/// (the nearest light to where the ray ended) passes near that light: its pixel may see the
/// light over a sliver too small for the first look to have met.
pub const NEAR_LIGHT: f32 = 8.0;
/// A pixel whose first look met light through this many film points has its measure: it is
/// not looked at twice.
pub const MEASURED_HITS: u32 = 16;
/// A light the probe met over a share of a pixel that the training's samples would meet
/// fewer times than this is a sliver there ([`SeenProbe::sliver`]): the training's estimate
/// of it is off by a quarter or more. (Less than once: on `tiny-lights` at 128 spp, 63 of
/// them training, a light a fortieth of a pixel was no sliver, and the training's rare hits
/// of it read image-wide |z| 10.7.)
pub const SLIVER_HITS: f64 = 16.0;
/// The share of the render's rays the seen light's probe may take: where many pixels see
/// glass or mirrors, each gets fewer film points.
pub const PROBE_SHARE: f64 = 0.05;

/// The emitting triangles' centres and radii, nearest first from any point: how close a
/// ray passes to a light.
pub(crate) struct LightCentres {
    tree: Option<ImmutableKdTree<f32, 3>>,
    centres: Vec<Vec3A>,
    radii: Vec<f32>,
}

impl LightCentres {
    /// The emitting triangles of `scene`.
    pub(crate) fn new(scene: &crate::scene::Scene) -> Self {
        let (mut centres, mut radii) = (Vec::new(), Vec::new());
        for tri in scene.lights.area.prims.iter().filter_map(|&t| scene.triangles.get(t as usize)) {
            let c = (tri[0] + tri[1] + tri[2]) / 3.0;
            let r = tri.iter().map(|v| v.distance(c)).fold(0.0f32, f32::max);
            if c.is_finite() && r.is_finite() && r > 0.0 {
                centres.push(c);
                radii.push(r);
            }
        }
        let points: Vec<[f32; 3]> = centres.iter().map(|c| c.to_array()).collect();
        let tree = if points.is_empty() { None } else { ImmutableKdTree::new_from_slice(&points).ok() };
        Self { tree, centres, radii }
    }

    /// How near `end`'s ray passes to the light triangle nearest to where it ended: its
    /// distance from the triangle's centre in the triangle's radii, infinite where there is
    /// none or it lies behind the ray.
    pub(crate) fn nearness(&self, end: &PrefixEnd) -> f32 {
        let Some(tree) = &self.tree else {
            return f32::INFINITY;
        };
        let x = end.ray.origin + end.ray.dir * end.t;
        if !x.is_finite() {
            return f32::INFINITY;
        }
        let near = tree.query(&x.to_array()).nearest_one::<SquaredEuclidean<f32>>().execute();
        let j = near.item as usize;
        let (Some(&c), Some(&r)) = (self.centres.get(j), self.radii.get(j)) else {
            return f32::INFINITY;
        };
        let v = c - end.ray.origin;
        let along = v.dot(end.ray.dir);
        if along <= 0.0 {
            return f32::INFINITY;
        }
        (v - end.ray.dir * along).length() / r
    }
}

/// The pixels next to one whose training samples' delta prefixes went past the camera's ray
/// (some first hit had a delta lobe: glass, a mirror): where a light may be seen through
/// delta scatters over a share of the pixel too small for the training to have measured.
/// A pixel's own samples do not mark it (its neighbours' do), so what the probe decides for
/// it is independent of its own training samples (see [`SeenProbe::sliver`]). `stats` as
/// [`plan`] reads them.
#[must_use]
pub fn delta_pixels(width: u32, stats: &SeenStats) -> Vec<bool> {
    let n = stats.samples.max(1) as f64;
    let own: Vec<bool> = stats.sums.iter().map(|s| s[4] / n > 1.0 + 1e-9).collect();
    let w = width.max(1) as usize;
    let h = own.len() / w;
    let mut out = vec![false; own.len()];
    for y in 0..h {
        for x in 0..w {
            if own[y * w + x] {
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        if (xx, yy) != (x, y) {
                            out[yy * w + xx] = true;
                        }
                    }
                }
            }
        }
    }
    out
}

/// The mean rays of a delta prefix (a film point's cost) over the pixels `probe` marks, as
/// training measured them; at least one.
#[must_use]
pub fn delta_prefix_rays(stats: &SeenStats, probe: &[bool]) -> f64 {
    let n = stats.samples.max(1) as f64;
    let (sum, count) =
        stats.sums.iter().zip(probe).filter(|&(_, &p)| p).fold((0.0, 0.0), |(s, c), (x, _)| (s + x[4] / n, c + 1.0));
    if count > 0.0 { (sum / count).max(1.0) } else { 1.0 }
}

/// The seen term's per-sample variance (channels summed) in the pixels `probe` marks,
/// measured from many stratified film points of each, their delta prefixes traced as
/// [`split_seen`] traces them; 0 elsewhere. A light seen through glass or in a mirror over a
/// small share of a pixel (a lamp's image in a glass egg: 1/1,300 of a pixel on Bitterli's
/// veach-bidir at an eighth of its film) is one the training's few samples rarely meet, so a
/// plan from the training alone leaves that pixel a lottery. The probe looks twice: first
/// every marked pixel through up to [`PROBE_FIRST_POINTS`] film points ([`PROBE_FIRST_SHARE`]
/// of `points`, at least 16 each), then the pixels where some prefix's last ray passed near
/// a light ([`NEAR_LIGHT`]) and few film points met one ([`MEASURED_HITS`]), nearest first,
/// each through up to [`PROBE_POINTS_PER_PIXEL`] in all, while the rays of the rest of
/// `points` last: a sliver met by 1 film point in 1,300, which an even share of the film
/// points (about 2,200 a pixel there) misses in about one render in six, is met about 12
/// times.
/// The film points are the probe's own streams, apart from the render's samples, so a plan
/// built from them keeps every sample unbiased.
#[must_use]
pub fn probed_variance<A: Accel>(
    ctx: &RenderContext<A>,
    seed: u64,
    probe: &[bool],
    points: u64,
    training_spp: u64,
) -> SeenProbe {
    let width = ctx.scene.camera.width;
    let count = probe.iter().filter(|&&p| p).count() as u64;
    if count == 0 {
        return SeenProbe { variance: vec![0.0; probe.len()], ..SeenProbe::default() };
    }
    let lights = LightCentres::new(ctx.scene);
    // One look at pixel `i` through `side × side` film points of stream `look`.
    let look = |i: usize, side: u32, look: u64, scratch: &mut Scratch| {
        let before = scratch.rays;
        let pixel = UVec2::new(i as u32 % width, i as u32 / width);
        let mut rng = SampleStream::in_domain(Domain::SeenProbe, seed, i as u64, look);
        let mut l = Look { points: u64::from(side * side), first: u64::from(side * side), ..Look::default() };
        for_each_stratum(ctx, pixel, side, &mut rng, scratch, |seen, end| {
            let s = f64::from(seen.element_sum());
            if s.is_finite() && s > 0.0 {
                l.sum += s;
                l.square += s * s;
                l.hits += 1;
            }
            // Only the first look chooses where to look again.
            if let Some(end) = end.filter(|_| look == 0) {
                l.near = l.near.min(lights.nearness(&end));
            }
        });
        l.rays = scratch.rays - before;
        l
    };
    // Film points per pixel: a square number.
    let side_of = |per: u64| ((per as f64).sqrt() as u32).max(1);
    let first = (PROBE_FIRST_SHARE * points as f64) as u64 / count;
    let side = side_of(first.clamp(16, u64::from(PROBE_FIRST_POINTS)));
    let mut looks: Vec<Look> = probe
        .par_iter()
        .enumerate()
        .with_min_len(64)
        .map_init(Scratch::default, |scratch, (i, &on)| if on { look(i, side, 0, scratch) } else { Look::default() })
        .collect();
    // The second look: the pixels where a prefix passed near a light and few film points met
    // one, nearest first, each through as many film points as the rest of the rays allow
    // (a film point costing its pixel's prefix as the first look traced it).
    let (first_points, first_rays) = looks.iter().fold((0u64, 0u64), |(p, r), l| (p + l.points, r + l.rays));
    let mut rest = points as f64 * first_rays as f64 / first_points.max(1) as f64 - first_rays as f64;
    let mut near: Vec<usize> =
        (0..looks.len()).filter(|&i| looks[i].near <= NEAR_LIGHT && looks[i].hits < MEASURED_HITS).collect();
    near.sort_by(|&a, &b| looks[a].near.total_cmp(&looks[b].near).then(a.cmp(&b)));
    let cap = u64::from(PROBE_POINTS_PER_PIXEL).saturating_sub(u64::from(side * side));
    let mut second: Vec<(usize, u32)> = Vec::new();
    for i in near {
        let cost = looks[i].rays.max(1) as f64 / looks[i].points.max(1) as f64;
        let per = (rest / cost).min(cap as f64);
        if per.is_nan() || per < 16.0 {
            break;
        }
        let side = side_of(per as u64);
        rest -= f64::from(side * side) * cost;
        second.push((i, side));
    }
    let more: Vec<(usize, Look)> = second
        .par_iter()
        .with_min_len(1)
        .map_init(Scratch::default, |scratch, &(i, side)| (i, look(i, side, 1, scratch)))
        .collect();
    for (i, m) in more {
        let l = &mut looks[i];
        (l.sum, l.square, l.points, l.rays) =
            (l.sum + m.sum, l.square + m.square, l.points + m.points, l.rays + m.rays);
    }
    let variance = looks
        .iter()
        .map(|l| {
            if l.points > 0 {
                let k = l.points as f64;
                let mean = l.sum / k;
                (l.square / k - mean * mean).max(0.0) as f32
            } else {
                0.0
            }
        })
        .collect();
    // Where the probe met light over a share of the pixel that the training's samples would
    // meet fewer than `SLIVER_HITS` times, as its first look measured the share: a sliver.
    let sliver = looks
        .iter()
        .map(|l| l.sum > 0.0 && f64::from(l.hits) * (training_spp as f64) < SLIVER_HITS * l.first as f64)
        .collect();
    SeenProbe { variance, rays: looks.iter().map(|l| l.rays).sum(), refined: second.len(), sliver }
}

/// What one look of the probe saw in a pixel.
#[derive(Clone, Copy, Debug)]
struct Look {
    /// Σ s and Σ s² of the seen term (channels summed) over its film points.
    sum: f64,
    square: f64,
    /// Film points, those of the first look, and those of the first look that met light.
    points: u64,
    first: u64,
    hits: u32,
    /// The nearest any prefix's last ray passed to a light ([`LightCentres::nearness`]).
    near: f32,
    rays: u64,
}

impl Default for Look {
    fn default() -> Self {
        Self { sum: 0.0, square: 0.0, points: 0, first: 0, hits: 0, near: f32::INFINITY, rays: 0 }
    }
}

/// What the seen light's probe measured: each pixel's variance, and the rays it traced.
#[derive(Clone, Debug, Default)]
pub struct SeenProbe {
    /// The seen term's per-sample variance each pixel's film points read (0 where not probed).
    pub variance: Vec<f32>,
    /// Rays the probe traced.
    pub rays: u64,
    /// Pixels looked at twice (a prefix passed near a light).
    pub refined: usize,
    /// Per pixel, whether the probe met light there over a share of the pixel (as its first
    /// look measured it) that the training's samples would meet fewer than [`SLIVER_HITS`]
    /// times: a sliver.
    sliver: Vec<bool>,
}

impl SeenProbe {
    /// The variances a plan splits by: the larger of `bounds` and the probe's. (A pixel the
    /// probe looked at and saw nothing in keeps its own measure, not its neighbours': the
    /// second look finds the slivers next to a light, and taking the neighbours' largest split
    /// 1,194 pixels of Bitterli's coffee, where 671 pays: MSE 0.94× path's against 1.08×.)
    #[must_use]
    pub fn planned(&self, bounds: &[f32]) -> Vec<f32> {
        let mut out = bounds.to_vec();
        self.raise(&mut out);
        out
    }

    /// Pixels where the probe met light over a sliver ([`Self::sliver`]).
    #[must_use]
    pub fn slivers(&self) -> usize {
        self.sliver.iter().filter(|&&s| s).count()
    }

    /// The pixels where the probe met light over a sliver of the pixel, the training's passes
    /// to be left out of them ([`crate::film::PriorSamples::exclude`]): the final passes
    /// split the seen light there over many film points, while the training's few unsplit
    /// samples read a miss in most renders and a hit hundreds of times the pixel in a rare
    /// one. Decided by the probe's own streams in pixels its neighbours' samples marked
    /// ([`delta_pixels`]), so independent of the pixel's own training samples.
    #[must_use]
    pub fn sliver(&self) -> &[bool] {
        &self.sliver
    }

    /// Raises `bounds` to the probe's variances: what a split pixel's seen term is measured as.
    pub fn raise(&self, bounds: &mut [f32]) {
        for (b, &q) in bounds.iter_mut().zip(&self.variance) {
            *b = b.max(q);
        }
    }
}

/// The seen light's probe after training: the pixels next to one whose training samples
/// passed a delta scatter ([`delta_pixels`]), probed with [`PROBE_SHARE`] of
/// `render_rays`, the rays the render will trace, each film point costing the delta prefix's
/// rays as training measured them ([`probed_variance`]); none where `render_rays` is 0.
#[must_use]
pub fn probe_seen<A: Accel>(
    ctx: &RenderContext<A>,
    seed: u64,
    width: u32,
    stats: &SeenStats,
    render_rays: f64,
) -> SeenProbe {
    if render_rays.is_nan() || render_rays <= 0.0 {
        return SeenProbe::default();
    }
    let probed = delta_pixels(width, stats);
    let points = PROBE_SHARE * render_rays / delta_prefix_rays(stats, &probed);
    let points = if points.is_finite() { points.max(0.0) as u64 } else { 0 };
    probed_variance(ctx, seed, &probed, points, stats.samples)
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

/// A pixel's seen term and rest (channels summed) as the training's samples measured them:
/// their variances per sample, the seen one raised to `bound` (a measure of the seen light
/// the samples may have missed), their covariance, and the rays of a film point.
#[derive(Clone, Copy, Debug)]
struct Parts {
    seen: f64,
    rest: f64,
    covariance: f64,
    point: f64,
}

impl Parts {
    fn of(s: &[f64; 6], n: f64, bound: f64) -> Self {
        let (seen, rest) = (s[0] / n, s[2] / n);
        Self {
            seen: (s[1] / n - seen * seen).max(0.0).max(bound),
            rest: (s[3] / n - rest * rest).max(0.0),
            covariance: s[5] / n - seen * rest,
            point: (s[4] / n).max(1.0),
        }
    }

    /// The per-sample variance unsplit: the seen term and the rest of one film point, which
    /// go together (a film point that sees the light through glass sees nothing else there).
    fn unsplit(&self) -> f64 {
        (self.seen + self.rest + 2.0 * self.covariance).max(0.0)
    }

    /// Split over `k` film points: the rest from the camera's sample, the seen term from `k`
    /// others of its own.
    fn split(&self, k: f64) -> f64 {
        self.rest + self.seen / k
    }
}

/// Each pixel's strata, chosen for the image's efficiency: a split pixel's seen variance
/// falls by its `k = m²` film points while every one of them costs `c` rays, the rays of the
/// pixel's delta prefix as training measured them (one where the light is seen directly,
/// several through glass), and every pixel of the image waits for those rays. The product
/// (mean variance `V̄`) × (mean rays per sample `C̄`) is least at `k = √(V_seen / V̄ · C̄ / c)`,
/// with `V̄` and `C̄` those of the split image (a fixed point, reached in a few rounds), at
/// most `max_strata` per axis; a pixel is split only where that lowers the product: where
/// the variance it saves, over `V̄`, exceeds its rays, over `C̄`. The variance saved is the
/// unsplit pixel's `V_seen + V_rest + 2 Cov` less the split one's `V_seen / k + V_rest`: where
/// a film point sees either the light through glass or something else (Bitterli's coffee
/// pot, lit panels behind it), the two parts go against each other, the unsplit pixel is
/// the quieter one, and the split, which separates them, only adds noise. `V_seen` is the
/// larger of the training's measurement and the lights' projection ([`projected_variance`]).
/// All split pixels together add at most half the walk's rays per pass (strata lowered
/// evenly until they fit).
///
/// Judging each pixel by its own rest instead, with a film point at one ray, Bitterli's
/// coffee at an eighth of its size splits 374 pixels seen through the glass 8 × 8 (several
/// rays a film point there) and renders half the path tracer's samples per second: MSE
/// 1.5× path's at equal time.
#[must_use]
pub fn plan(width: u32, stats: &SeenStats, projected: &[f32], cost: f64, max_strata: u8) -> SeenPlan {
    let n = stats.samples.max(1) as f64;
    let pixels = stats.sums.len().max(1) as f64;
    let cost = cost.max(1.0);
    let parts: Vec<Parts> = stats
        .sums
        .iter()
        .enumerate()
        .map(|(i, s)| Parts::of(s, n, f64::from(projected.get(i).copied().unwrap_or(0.0))))
        .collect();
    let top = f64::from(max_strata.max(1));
    let mut strata = vec![UNSPLIT; parts.len()];
    for _ in 0..4 {
        let (mut v, mut c) = (0.0, cost);
        for (&m, p) in strata.iter().zip(&parts) {
            if m > UNSPLIT {
                let k = f64::from(m) * f64::from(m);
                v += p.split(k);
                c += k * p.point / pixels;
            } else {
                v += p.unsplit();
            }
        }
        let v = (v / pixels).max(1e-30);
        for (m, p) in strata.iter_mut().zip(&parts) {
            let r = (p.seen / v * c / p.point).sqrt().sqrt().round();
            let r = if r.is_finite() { r.clamp(1.0, top) } else { 1.0 };
            let k = r * r;
            let pays = (p.unsplit() - p.split(k)) / v > k * p.point / c;
            *m = if r > 1.0 && pays { r as u8 } else { UNSPLIT };
        }
    }
    let budget = 0.5 * cost * pixels;
    let extra = |strata: &[u8]| {
        strata
            .iter()
            .zip(&parts)
            .filter(|&(&m, _)| m > 1)
            .map(|(&m, p)| f64::from(m) * f64::from(m) * p.point)
            .sum::<f64>()
    };
    while extra(&strata) > budget {
        for m in &mut strata {
            *m = m.saturating_sub(1).max(UNSPLIT);
        }
    }
    SeenPlan { width, strata }
}

/// A pixel's per-sample `variance` and `rays`, measured by training samples that did not split
/// the seen light, as they will be where `plan` splits it into `m²` film points: the pixel's
/// unsplit variance of its parts becomes their split one (see [`plan`]; the seen term the
/// larger of the training's and the lights' projection, as [`plan`] weighs it; `projected`
/// may be empty), and each film point adds the rays of the pixel's delta prefix.
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
    let p = Parts::of(s, n, f64::from(projected.get(pixel).copied().unwrap_or(0.0)));
    let k = f64::from(m) * f64::from(m);
    // Channel-summed parts: their ratio scales the channel-averaged variance.
    let (before, after) = (p.unsplit(), p.split(k));
    let share = if before > 0.0 { after / before } else { 1.0 };
    (variance * share, rays + k * p.point)
}

/// [`plan`] from the lights' projections onto the film alone (no pass measured yet): where a
/// light smaller than a pixel projects, split from the start. Samples drawn under it stay
/// unbiased, since the plan looks at no sample.
#[must_use]
pub fn plan_from_projection(width: u32, projected: &[f32], max_strata: u8) -> SeenPlan {
    let none = SeenStats { samples: 1, sums: vec![[0.0; 6]; projected.len()], rays: 0 };
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
        let s = [12.0, 72.0, 8.0, 20.0, 8.0, 24.0];
        let st = SeenStats { samples: 4, sums: vec![s, s], rays: 0 };
        let plan = SeenPlan { width: 2, strata: vec![3, UNSPLIT] };
        let (v, r) = after_split(&plan, &st, &[], 0, 5.0, 4.0);
        assert!((v - 5.0 * (1.0 + 9.0 / 9.0) / 10.0).abs() < 1e-12, "{v}");
        assert!((r - (4.0 + 9.0 * 2.0)).abs() < 1e-12, "{r}");
        assert_eq!(after_split(&plan, &st, &[], 1, 5.0, 4.0), (5.0, 4.0));
        // The lights' projection counts where it is the larger.
        let (v, _) = after_split(&plan, &st, &[90.0, 0.0], 0, 5.0, 4.0);
        assert!((v - 5.0 * (1.0 + 90.0 / 9.0) / 91.0).abs() < 1e-12, "{v}");
        // Seen 0, 0, 6, 6 against rest 3, 3, 0, 0 (variance 2.25, covariance −4.5): unsplit
        // 9 + 2.25 − 9, split 2.25 + 9 / 9: the split pixel is the noisier.
        let s = [12.0, 72.0, 6.0, 18.0, 8.0, 0.0];
        let st = SeenStats { samples: 4, sums: vec![s, s], rays: 0 };
        let (v, _) = after_split(&plan, &st, &[], 0, 5.0, 4.0);
        assert!((v - 5.0 * 3.25 / 2.25).abs() < 1e-12, "{v}");
    }

    /// The probe looks at the neighbours of the pixels whose samples traced more than the
    /// camera's ray, whatever light they met; a film point's cost is the mean prefix there.
    #[test]
    fn probes_reach_the_neighbours() {
        // Four samples: one ray each, except pixels (4, 3) and (0, 0), which traced more.
        // A pixel is marked by its neighbours' samples, never its own: (0, 0)'s neighbours
        // are, (0, 0) is not; (4, 3)'s neighbours are, (4, 3) is not.
        let mut sums = vec![[0.0, 0.0, 0.0, 0.0, 4.0, 0.0]; 20];
        sums[19][4] = 10.0;
        sums[0][4] = 6.0;
        // Light met along the prefix does not matter.
        sums[13] = [2.0, 4.0, 0.0, 0.0, 4.0, 0.0];
        let st = SeenStats { samples: 4, sums, rays: 0 };
        let d = delta_pixels(5, &st);
        let marked: Vec<usize> = (0..20).filter(|&i| d[i]).collect();
        assert_eq!(marked, vec![1, 5, 6, 13, 14, 18]);
        // The marked pixels' own samples traced one ray each.
        assert!((delta_prefix_rays(&st, &d) - 1.0).abs() < 1e-12);
        assert_eq!(delta_prefix_rays(&st, &[false; 20]), 1.0);
    }

    /// A ray's nearness to a light: its distance from the nearest light triangle's centre in
    /// that triangle's radii, infinite behind the ray.
    #[test]
    fn nearness_counts_in_the_lights_radii() {
        let c = LightCentres {
            tree: ImmutableKdTree::new_from_slice(&[[0.0f32, 0.0, 0.0], [10.0, 0.0, 0.0]]).ok(),
            centres: vec![Vec3A::ZERO, Vec3A::new(10.0, 0.0, 0.0)],
            radii: vec![0.5, 2.0],
        };
        let end = |o: [f32; 3], d: [f32; 3], t: f32| PrefixEnd {
            ray: Ray::new(Vec3A::from(o), Vec3A::from(d).normalize()),
            t,
        };
        // Past the first light 1 off its centre: 2 radii.
        assert!((c.nearness(&end([-5.0, 1.0, 0.0], [1.0, 0.0, 0.0], 6.0)) - 2.0).abs() < 1e-5);
        // Ending by the second light, 1 off its centre: half its radius.
        assert!((c.nearness(&end([0.0, 1.0, 0.0], [1.0, 0.0, 0.0], 9.5)) - 0.5).abs() < 1e-5);
        // The nearest light lies behind the ray.
        assert!(c.nearness(&end([1.0, 0.0, 0.0], [1.0, 0.0, 0.0], -0.5)).is_infinite());
        let none = LightCentres { tree: None, centres: Vec::new(), radii: Vec::new() };
        assert!(none.nearness(&end([0.0; 3], [1.0, 0.0, 0.0], 1.0)).is_infinite());
    }

    fn stats(sums: Vec<[f64; 6]>, samples: u64) -> SeenStats {
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
        // Uncorrelated: Σ seen·rest = 4 · mean seen · mean rest.
        let pixel = |s: [f64; 2], r: [f64; 2]| [s[0], s[1], r[0], r[1], 4.0, s[0] * r[0] / 4.0];
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
            let many = vec![[20.0, 200.0, 4.0, 4.04, 4.0 * rays, 20.0]; 1000];
            let p = plan(1000, &stats(many, 4), &[], 8.0, 8);
            let (split, most) = p.split_pixels();
            let extra = split as f64 * f64::from(most) * f64::from(most) * rays;
            assert!(extra <= 4000.0, "{split} pixels at {most}, {rays} rays a film point");
        }
        assert_eq!(plan(2, &stats(vec![[0.0; 6]; 2], 4), &[], 8.0, 8).split_pixels(), (0, 1));
        // Pixel 0 sees the light (10) or a lit wall (10) behind glass, never both: its seen
        // term and rest go against each other (covariance −25) and its unsplit samples are
        // all 10. Not split.
        let mut against = vec![pixel([0.0; 2], quiet); 200];
        against[0] = [20.0, 200.0, 20.0, 200.0, 4.0, 0.0];
        assert_eq!(at(&plan(200, &stats(against, 4), &[], 8.0, 8)), 1);
    }
}
