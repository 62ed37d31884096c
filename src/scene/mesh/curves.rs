//! Curves (pbrt-v4's `curve` shape: hair and fur) as triangles: each cubic or quadratic
//! segment is cut into straight steps fine enough that the polyline stays within a tenth of
//! the curve's width of the curve, and each step is swept into a tube (`cylinder` and `flat`
//! curves) or a strip turned by the curve's normals (`ribbon`).
//!
//! A tube has the curve's silhouette from every side and smooth normals around it, as pbrt's
//! cylinder curve shades; pbrt's flat curve always faces the ray, which a mesh cannot, so it
//! becomes a tube too (the importer warns).
use glam::DVec3;

/// How the control points define the curve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Basis {
    /// Segments of `degree + 1` points, each sharing its last point with the next.
    Bezier,
    /// A uniform B-spline: every `degree + 1` consecutive points make a segment.
    Bspline,
}

/// The surface swept along the curve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sweep {
    /// A closed tube of the curve's width.
    Tube,
    /// A strip of the curve's width, facing the normals given at the segments' ends.
    Ribbon,
}

/// A curve, in world space.
#[derive(Clone, Debug)]
pub struct Curve<'a> {
    /// Control points.
    pub points: &'a [DVec3],
    /// How the control points define the curve.
    pub basis: Basis,
    /// 2 or 3.
    pub degree: usize,
    /// The surface swept along it.
    pub sweep: Sweep,
    /// Width at the curve's start and end (linear in between, over the segments).
    pub width: [f64; 2],
    /// Ribbons: one normal per segment end (segments + 1).
    pub normals: Option<&'a [DVec3]>,
}

/// Sides of a tube's cross-section.
const TUBE_SIDES: usize = 6;
/// Most steps a segment is cut into.
const MAX_STEPS: usize = 64;

/// Triangles of tessellated curves (positions, per-vertex normals, three indices each).
#[derive(Clone, Debug, Default)]
pub struct CurveMesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Vertex normals.
    pub normals: Vec<[f32; 3]>,
    /// Three vertex indices per triangle.
    pub indices: Vec<u32>,
}

impl CurveMesh {
    /// Appends `curve`'s triangles; refuses (before allocating) to grow past `max_triangles`.
    pub fn add(&mut self, curve: &Curve, max_triangles: usize) -> Result<(), String> {
        let segments = bezier_segments(curve)?;
        if let Some(n) = curve.normals {
            if curve.sweep == Sweep::Ribbon && n.len() != segments.len() + 1 {
                return Err(format!(
                    "a ribbon curve of {} segments needs {} normals, got {}",
                    segments.len(),
                    segments.len() + 1,
                    n.len()
                ));
            }
        } else if curve.sweep == Sweep::Ribbon {
            return Err("a ribbon curve needs \"normal N\"".into());
        }
        let [w0, w1] = curve.width;
        if !(w0.is_finite() && w1.is_finite() && w0 >= 0.0 && w1 >= 0.0 && w0.max(w1) > 0.0) {
            return Err(format!("curve widths must be finite, non-negative and not both 0, got {w0} and {w1}"));
        }
        let count = segments.len();
        // Steps per segment: a Bézier polyline of n steps is within d(d−1)/8 · max|Δ²b| / n²
        // of the curve; a tenth of the width is close enough to be invisible.
        let steps: Vec<usize> = segments
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let eps = 0.1 * lerp(w0, w1, i as f64 / count as f64).max(lerp(w0, w1, (i + 1) as f64 / count as f64));
                let d = curve.degree as f64;
                let second =
                    (0..curve.degree - 1).map(|k| (b[k] - 2.0 * b[k + 1] + b[k + 2]).length()).fold(0.0, f64::max);
                let n = (d * (d - 1.0) / 8.0 * second / eps).sqrt().ceil();
                if n.is_finite() { (n as usize).clamp(1, MAX_STEPS) } else { MAX_STEPS }
            })
            .collect();
        let rings = steps.iter().sum::<usize>() + 1;
        let per_step = if curve.sweep == Sweep::Tube { 2 * TUBE_SIDES } else { 2 };
        let new_triangles = (rings - 1) * per_step;
        if self.indices.len() / 3 + new_triangles > max_triangles {
            return Err(format!("the curves need more than {max_triangles} triangles"));
        }
        // The curve's points, tangents, widths and (ribbons) normals at every ring.
        let mut frames = Vec::with_capacity(rings);
        for (i, (b, &n)) in segments.iter().zip(&steps).enumerate() {
            let first = if i == 0 { 0 } else { 1 };
            for s in first..=n {
                let t = s as f64 / n as f64;
                let (p, dp) = eval(b, curve.degree, t);
                let along = (i as f64 + t) / count as f64;
                let normal = curve.normals.map(|ns| ns[i].lerp(ns[i + 1], t));
                frames.push((p, dp, lerp(w0, w1, along), normal));
            }
        }
        let base = self.positions.len() as u32;
        match curve.sweep {
            Sweep::Tube => {
                // A frame carried along the curve by parallel transport (no twist).
                let mut side = None::<DVec3>;
                let mut last_tangent = DVec3::ZERO;
                for &(p, dp, w, _) in &frames {
                    let tangent =
                        dp.try_normalize().unwrap_or(if last_tangent == DVec3::ZERO { DVec3::Z } else { last_tangent });
                    let s = match side {
                        None => tangent.any_orthonormal_vector(),
                        Some(s) => (s - tangent * s.dot(tangent))
                            .try_normalize()
                            .unwrap_or_else(|| tangent.any_orthonormal_vector()),
                    };
                    side = Some(s);
                    last_tangent = tangent;
                    let up = tangent.cross(s);
                    for k in 0..TUBE_SIDES {
                        let a = std::f64::consts::TAU * k as f64 / TUBE_SIDES as f64;
                        let radial = s * a.cos() + up * a.sin();
                        self.positions.push((p + radial * (0.5 * w)).as_vec3().to_array());
                        self.normals.push(radial.as_vec3().to_array());
                    }
                }
                for r in 0..frames.len() as u32 - 1 {
                    for k in 0..TUBE_SIDES as u32 {
                        let k1 = (k + 1) % TUBE_SIDES as u32;
                        let (a, b) = (base + r * TUBE_SIDES as u32 + k, base + r * TUBE_SIDES as u32 + k1);
                        let (c, d) = (a + TUBE_SIDES as u32, b + TUBE_SIDES as u32);
                        // Counter-clockwise seen from outside (the radial normal's side).
                        self.indices.extend([a, b, d, a, d, c]);
                    }
                }
            }
            Sweep::Ribbon => {
                for &(p, dp, w, n) in &frames {
                    let n = n.unwrap_or(DVec3::Z);
                    let across = dp.cross(n).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
                    let facing = across.cross(dp).try_normalize().unwrap_or(n);
                    for sign in [-0.5, 0.5] {
                        self.positions.push((p + across * (sign * w)).as_vec3().to_array());
                        self.normals.push(facing.as_vec3().to_array());
                    }
                }
                for r in 0..frames.len() as u32 - 1 {
                    let (a, b, c, d) = (base + 2 * r, base + 2 * r + 1, base + 2 * r + 2, base + 2 * r + 3);
                    self.indices.extend([a, b, d, a, d, c]);
                }
            }
        }
        Ok(())
    }
}

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// The curve's segments as Bézier control points (`degree + 1` each, the rest unused).
fn bezier_segments(curve: &Curve) -> Result<Vec<[DVec3; 4]>, String> {
    let (p, d) = (curve.points, curve.degree);
    if !(d == 2 || d == 3) {
        return Err(format!("curve degree {d}: pbrt-v4's curves are of degree 2 or 3"));
    }
    if p.iter().any(|q| !q.is_finite()) {
        return Err("curve control points must be finite".into());
    }
    let mut out = Vec::new();
    match curve.basis {
        Basis::Bezier => {
            if p.len() < d + 1 || (p.len() - 1) % d != 0 {
                return Err(format!("a Bézier curve of degree {d} needs {d}·n + 1 control points, got {}", p.len()));
            }
            for s in (0..p.len() - 1).step_by(d) {
                let mut b = [DVec3::ZERO; 4];
                b[..=d].copy_from_slice(&p[s..=s + d]);
                out.push(b);
            }
        }
        Basis::Bspline => {
            if p.len() < d + 1 {
                return Err(format!(
                    "a B-spline curve of degree {d} needs at least {} control points, got {}",
                    d + 1,
                    p.len()
                ));
            }
            for s in 0..p.len() - d {
                let q = &p[s..=s + d];
                out.push(if d == 3 {
                    [
                        (q[0] + 4.0 * q[1] + q[2]) / 6.0,
                        (2.0 * q[1] + q[2]) / 3.0,
                        (q[1] + 2.0 * q[2]) / 3.0,
                        (q[1] + 4.0 * q[2] + q[3]) / 6.0,
                    ]
                } else {
                    [(q[0] + q[1]) / 2.0, q[1], (q[1] + q[2]) / 2.0, DVec3::ZERO]
                });
            }
        }
    }
    Ok(out)
}

/// The point and derivative of a Bézier segment at `t`.
fn eval(b: &[DVec3; 4], degree: usize, t: f64) -> (DVec3, DVec3) {
    let s = 1.0 - t;
    if degree == 3 {
        let p = b[0] * (s * s * s) + b[1] * (3.0 * s * s * t) + b[2] * (3.0 * s * t * t) + b[3] * (t * t * t);
        let dp = (b[1] - b[0]) * (3.0 * s * s) + (b[2] - b[1]) * (6.0 * s * t) + (b[3] - b[2]) * (3.0 * t * t);
        (p, dp)
    } else {
        let p = b[0] * (s * s) + b[1] * (2.0 * s * t) + b[2] * (t * t);
        let dp = (b[1] - b[0]) * (2.0 * s) + (b[2] - b[1]) * (2.0 * t);
        (p, dp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(sweep: Sweep, basis: Basis) -> CurveMesh {
        let points: Vec<DVec3> = (0..4).map(|i| DVec3::new(0.0, 0.0, f64::from(i))).collect();
        let normals = [DVec3::X, DVec3::X];
        let normals: &[DVec3] = if basis == Basis::Bezier { &normals } else { &[DVec3::X; 2] };
        let mut m = CurveMesh::default();
        let curve = Curve { points: &points, basis, degree: 3, sweep, width: [0.2, 0.2], normals: Some(normals) };
        m.add(&curve, 1 << 20).unwrap();
        m
    }

    #[test]
    fn a_straight_tube_has_the_curve_s_radius_and_outward_normals() {
        let m = straight(Sweep::Tube, Basis::Bezier);
        // One step (a straight segment is its own polyline): two rings of six.
        assert_eq!(m.positions.len(), 2 * TUBE_SIDES);
        assert_eq!(m.indices.len(), 3 * 2 * TUBE_SIDES);
        for (p, n) in m.positions.iter().zip(&m.normals) {
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            assert!((r - 0.1).abs() < 1e-6, "radius {r}");
            assert!((n[0] * p[0] + n[1] * p[1]) / r > 0.999, "normal {n:?} at {p:?}");
        }
        // Every triangle's winding agrees with its vertices' normals (outside is outside).
        for t in m.indices.chunks(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| glam::Vec3::from_array(m.positions[i as usize]));
            let face = (b - a).cross(c - a);
            let n = glam::Vec3::from_array(m.normals[t[0] as usize]);
            assert!(face.dot(n) > 0.0, "triangle {t:?} faces inwards");
        }
    }

    #[test]
    fn a_ribbon_faces_its_normals() {
        let m = straight(Sweep::Ribbon, Basis::Bezier);
        assert_eq!(m.positions.len(), 4);
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!((p[1].abs() - 0.1).abs() < 1e-6 && p[0].abs() < 1e-9, "{p:?}");
            assert!((n[0].abs() - 1.0).abs() < 1e-6, "{n:?}");
        }
    }

    #[test]
    fn bends_are_cut_finely_and_follow_the_curve() {
        // A quarter circle-ish cubic of radius 1, width 0.01: many steps, every ring centre
        // on the curve within a tenth of the width.
        let points = [
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.55, 0.0),
            DVec3::new(0.55, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let curve = Curve {
            points: &points,
            basis: Basis::Bezier,
            degree: 3,
            sweep: Sweep::Tube,
            width: [0.01, 0.01],
            normals: None,
        };
        let mut m = CurveMesh::default();
        m.add(&curve, 1 << 20).unwrap();
        let rings = m.positions.len() / TUBE_SIDES;
        assert!(rings > 10, "{rings} rings");
        for r in 0..rings {
            let centre = m.positions[r * TUBE_SIDES..(r + 1) * TUBE_SIDES]
                .iter()
                .fold(glam::Vec3::ZERO, |a, p| a + glam::Vec3::from_array(*p))
                / TUBE_SIDES as f32;
            let radius = centre.truncate().length();
            assert!((radius - 1.0).abs() < 0.03, "ring {r} at radius {radius}");
        }
        // Midpoints between consecutive ring centres stay within 0.1 × width of the curve.
        let (p, _) = eval(&points, 3, 0.5);
        assert!((p.truncate().length() - 1.0).abs() < 0.01);
    }

    #[test]
    fn b_splines_become_bezier_segments_and_mistakes_are_errors() {
        let points: Vec<DVec3> = (0..6).map(|i| DVec3::new(f64::from(i), 0.0, 0.0)).collect();
        let c = |basis, degree, n: usize| Curve {
            points: &points[..n],
            basis,
            degree,
            sweep: Sweep::Tube,
            width: [1.0, 0.5],
            normals: None,
        };
        assert_eq!(bezier_segments(&c(Basis::Bspline, 3, 6)).unwrap().len(), 3);
        assert_eq!(bezier_segments(&c(Basis::Bspline, 2, 6)).unwrap().len(), 4);
        assert_eq!(bezier_segments(&c(Basis::Bezier, 3, 4)).unwrap().len(), 1);
        // A uniform cubic B-spline of collinear, evenly spaced points starts at (p0+4p1+p2)/6.
        assert_eq!(bezier_segments(&c(Basis::Bspline, 3, 6)).unwrap()[0][0], DVec3::new(1.0, 0.0, 0.0));
        assert!(bezier_segments(&c(Basis::Bezier, 3, 5)).is_err());
        assert!(bezier_segments(&c(Basis::Bezier, 4, 5)).is_err());
        assert!(bezier_segments(&c(Basis::Bspline, 3, 3)).is_err());
        let mut m = CurveMesh::default();
        assert!(m.add(&c(Basis::Bspline, 3, 6), 2).unwrap_err().contains("triangles"));
        let ribbon = Curve { sweep: Sweep::Ribbon, ..c(Basis::Bezier, 3, 4) };
        assert!(m.add(&ribbon, 1 << 20).unwrap_err().contains("normal"));
        let thin = Curve { width: [0.0, 0.0], ..c(Basis::Bezier, 3, 4) };
        assert!(m.add(&thin, 1 << 20).is_err());
        assert!(m.positions.is_empty(), "a refused curve adds nothing");
    }
}
