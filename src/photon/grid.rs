//! The `GL` guide grid (ALGORITHM.md §2): a piecewise-constant density over the cosine-warped
//! hemisphere `(u, v) ∈ [0,1)²`, `sinθ = √u`, `φ = 2πv`; rows split `u`, columns split `v`.
//! Sampling cell `c` with probability `Pc` and `(u, v)` uniformly inside it gives the
//! solid-angle density `pdf(ω) = Pc · |GL| · cosθ / π`.
use crate::geometry::{Vec2, Vec3A, warp};

/// Largest number of cells a grid may have (keeps per-vertex grids on the stack).
pub const MAX_GUIDE_CELLS: usize = 1024;

/// Rows × columns of a grid (`--guide-grid 4x16`, `--pixel-grid 2x4`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridShape {
    pub rows: u32,
    pub cols: u32,
}

impl GridShape {
    #[must_use]
    pub const fn cells(self) -> usize {
        (self.rows * self.cols) as usize
    }

    /// Parses `RxC`; both at least 1 and at most `max_cells` cells in all.
    pub fn parse(s: &str, max_cells: usize) -> Result<Self, String> {
        let (r, c) = s.split_once(['x', 'X']).ok_or_else(|| format!("`{s}`: expected ROWSxCOLS, e.g. 4x16"))?;
        let rows: u32 = r.trim().parse().map_err(|_| format!("`{s}`: bad row count"))?;
        let cols: u32 = c.trim().parse().map_err(|_| format!("`{s}`: bad column count"))?;
        if rows == 0 || cols == 0 || (rows as usize * cols as usize) > max_cells {
            return Err(format!("`{s}`: needs 1 to {max_cells} cells"));
        }
        Ok(Self { rows, cols })
    }

    /// The cell holding local direction `w` (`w.z > 0`).
    #[inline]
    #[must_use]
    pub fn cell_of(self, w: Vec3A) -> usize {
        let uv = warp::cosine_hemisphere_inverse(w);
        let r = ((uv.x * self.rows as f32) as u32).min(self.rows - 1);
        let c = ((uv.y * self.cols as f32) as u32).min(self.cols - 1);
        (r * self.cols + c) as usize
    }
}

/// Turns cell weights into a sampling CDF in place: floors every cell with
/// `floor · mean(weights)` (so every direction keeps a positive density) and falls back to
/// uniform (cosine sampling) when all weights are zero. Returns `false` for the uniform case.
pub fn weights_to_cdf(w: &mut [f32], floor: f32) -> bool {
    let n = w.len() as f32;
    let total: f32 = w.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        for (i, x) in w.iter_mut().enumerate() {
            *x = (i + 1) as f32 / n;
        }
        return false;
    }
    let add = floor * total / n;
    let norm = 1.0 / (total + add * n);
    let mut acc = 0.0;
    for x in w.iter_mut() {
        acc += (*x + add) * norm;
        *x = acc;
    }
    *w.last_mut().unwrap() = 1.0;
    true
}

/// Inverts a CDF over cells (as [`weights_to_cdf`] builds): the cell `u` falls in, its
/// probability, and `u` rescaled to `[0, 1)` inside the cell (so one uniform number can pick
/// the cell and then place a point in it). Zero-width cells are never picked.
#[inline]
#[must_use]
pub fn pick_cell(cdf: &[f32], u: f32) -> (usize, f32, f32) {
    let c = cdf.partition_point(|&x| x <= u).min(cdf.len() - 1);
    let below = if c > 0 { cdf[c - 1] } else { 0.0 };
    let p = cdf[c] - below;
    (c, p, ((u - below) / p).clamp(0.0, 1.0 - f32::EPSILON))
}

/// Samples a direction from a grid given as a CDF over its cells. Returns the local direction
/// (z = normal) and `Pc · |GL|`, so that `f·cosθ / pdf = f · π / (Pc·|GL|)`.
#[inline]
#[must_use]
pub fn sample_cdf(shape: GridShape, cdf: &[f32], u_cell: f32, u: Vec2) -> (Vec3A, f32) {
    let (c, pc, _) = pick_cell(cdf, u_cell);
    let (row, col) = (c as u32 / shape.cols, c as u32 % shape.cols);
    let uv = Vec2::new((row as f32 + u.x) / shape.rows as f32, (col as f32 + u.y) / shape.cols as f32);
    (warp::cosine_hemisphere(uv), pc * shape.cells() as f32)
}

/// Density (solid angle) with which [`sample_cdf`] picks local direction `w`: `Pc·|GL|·cosθ/π`
/// for the cell holding `w`, 0 below the horizon.
#[inline]
#[must_use]
pub fn grid_pdf(shape: GridShape, cdf: &[f32], w: Vec3A) -> f32 {
    if w.z <= 0.0 {
        return 0.0;
    }
    let c = shape.cell_of(w);
    let pc = cdf[c] - if c > 0 { cdf[c - 1] } else { 0.0 };
    pc * shape.cells() as f32 * w.z * std::f32::consts::FRAC_1_PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;
    use crate::stats::chi_square_critical;
    use std::f64::consts::PI;

    fn test_cdf(shape: GridShape) -> Vec<f32> {
        // A lumpy, partly empty weight pattern.
        let mut w: Vec<f32> =
            (0..shape.cells()).map(|i| if i % 5 == 0 { 0.0 } else { ((i * 37) % 11) as f32 }).collect();
        assert!(weights_to_cdf(&mut w, 0.1));
        w
    }

    fn cell_prob(cdf: &[f32], c: usize) -> f64 {
        (cdf[c] - if c > 0 { cdf[c - 1] } else { 0.0 }) as f64
    }

    /// The solid-angle pdf `Pc·|GL|·cosθ/π` integrates to one over the hemisphere
    /// (midpoint rule in (cosθ, φ), cell looked up per quadrature point).
    #[test]
    fn pdf_integrates_to_one() {
        let shape = GridShape { rows: 4, cols: 16 };
        let cdf = test_cdf(shape);
        let (n_mu, n_phi) = (800, 800);
        let mut sum = 0.0;
        for i in 0..n_mu {
            let mu = (i as f64 + 0.5) / n_mu as f64;
            let s = (1.0 - mu * mu).sqrt();
            for j in 0..n_phi {
                let phi = (j as f64 + 0.5) / n_phi as f64 * 2.0 * PI;
                let w = Vec3A::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, mu as f32);
                let pc = cell_prob(&cdf, shape.cell_of(w));
                sum += pc * shape.cells() as f64 * mu / PI * (1.0 / n_mu as f64) * (2.0 * PI / n_phi as f64);
            }
        }
        assert!((sum - 1.0).abs() < 2e-3, "integral {sum}");
    }

    /// Sampled directions land in each cell with probability Pc (χ² over cells), and the
    /// returned factor is Pc·|GL| for the cell they land in.
    #[test]
    fn samples_follow_the_grid() {
        let shape = GridShape { rows: 4, cols: 16 };
        let cdf = test_cdf(shape);
        let n = 400_000;
        let mut hist = vec![0f64; shape.cells()];
        let mut rng = SampleStream::new(21, 0, 0);
        for _ in 0..n {
            let (w, factor) = sample_cdf(shape, &cdf, rng.next_f32(), rng.next_2d());
            let c = shape.cell_of(w);
            assert!((factor as f64 - cell_prob(&cdf, c) * shape.cells() as f64).abs() < 1e-4);
            hist[c] += 1.0;
        }
        let chi2: f64 = (0..shape.cells())
            .map(|c| (hist[c] - n as f64 * cell_prob(&cdf, c)).powi(2) / (n as f64 * cell_prob(&cdf, c)))
            .sum();
        let crit = chi_square_critical(shape.cells() - 1, 1e-4);
        assert!(chi2 < crit, "chi2 {chi2} >= {crit}");
    }

    #[test]
    fn empty_grid_is_uniform_and_floor_keeps_cells_positive() {
        let mut w = vec![0.0f32; 8];
        assert!(!weights_to_cdf(&mut w, 0.1));
        assert!((w[3] - 0.5).abs() < 1e-6);
        let mut w = vec![0.0, 0.0, 8.0, 0.0];
        assert!(weights_to_cdf(&mut w, 0.1));
        assert!(cell_prob(&w, 0) > 0.0 && (cell_prob(&w, 2) - 8.2 / 8.8).abs() < 1e-6);
        assert!(
            GridShape::parse("4x16", 1024).is_ok()
                && GridShape::parse("0x4", 1024).is_err()
                && GridShape::parse("64x64", 1024).is_err()
        );
    }
}
