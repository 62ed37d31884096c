//! Small statistics helpers shared by the Monte Carlo tests and the comparison tools.

/// Standard normal quantile (Acklam's rational approximation, |error| < 1.2e-9).
// The coefficients are quoted at the precision they were published with.
#[allow(clippy::excessive_precision)]
#[must_use]
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383577518672690e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] =
        [-5.447609879822406e1, 1.615858368580409e2, -1.556989798598866e2, 6.680131188771972e1, -1.328068155288572e1];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [7.784695709041462e-3, 3.224671290700398e-1, 2.445134137142996, 3.754408661907416];
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// The value a χ² statistic with `dof` degrees of freedom exceeds with probability `alpha`
/// (Wilson–Hilferty approximation, accurate to a few percent for dof ≥ 3).
#[must_use]
pub fn chi_square_critical(dof: usize, alpha: f64) -> f64 {
    let k = dof as f64;
    let z = normal_quantile(1.0 - alpha);
    let h = 2.0 / (9.0 * k);
    k * (1.0 - h + z * h.sqrt()).powi(3)
}

/// The two-sided z bound that `n` independent standard normals all stay under with
/// probability `1 − alpha` (Šidák correction): a family-wise bound for per-pixel/block tests.
#[must_use]
pub fn family_z_bound(n: usize, alpha: f64) -> f64 {
    let per = 1.0 - (1.0 - alpha).powf(1.0 / n.max(1) as f64);
    normal_quantile(1.0 - per / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_quantiles() {
        assert!((normal_quantile(0.975) - 1.959964).abs() < 1e-5);
        assert!((normal_quantile(0.5)).abs() < 1e-9);
        assert!((normal_quantile(1e-4) + 3.719016).abs() < 1e-4);
        // χ²(10) upper 1% point is 23.209.
        assert!((chi_square_critical(10, 0.01) - 23.209).abs() < 0.3);
        assert!(family_z_bound(1, 0.05) - 1.96 < 1e-3);
        assert!(family_z_bound(1000, 0.01) > 4.0);
    }
}
