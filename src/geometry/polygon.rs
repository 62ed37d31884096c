//! Triangulating a mesh polygon: a convex one as a fan, a concave one by ear clipping in its
//! plane (a fan would cover area outside a concave polygon).
use super::{Vec2, Vec3A};

/// Appends to `out` triangles (indices into `points`, in the polygon's winding) covering the
/// polygon `points`. Returns false if the polygon is not simple (no ear could be clipped:
/// self-intersecting or degenerate); its remainder is then fanned.
pub fn triangulate(points: &[Vec3A], out: &mut Vec<[usize; 3]>) -> bool {
    let n = points.len();
    if n < 3 {
        return true;
    }
    if n == 3 {
        out.push([0, 1, 2]);
        return true;
    }
    // Newell's normal; project onto the plane of its two smaller axes, oriented so that the
    // polygon turns counter-clockwise.
    let mut normal = Vec3A::ZERO;
    for i in 0..n {
        let (a, b) = (points[i], points[(i + 1) % n]);
        normal += Vec3A::new((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    let abs = normal.abs();
    let (u, v, sign) = if abs.x >= abs.y && abs.x >= abs.z {
        (1, 2, normal.x)
    } else if abs.y >= abs.z {
        (2, 0, normal.y)
    } else {
        (0, 1, normal.z)
    };
    let flat: Vec<Vec2> =
        points.iter().map(|p| if sign >= 0.0 { Vec2::new(p[u], p[v]) } else { Vec2::new(p[v], p[u]) }).collect();
    let cross = |a: Vec2, b: Vec2, c: Vec2| (b - a).perp_dot(c - a);
    let convex = (0..n).all(|i| cross(flat[i], flat[(i + 1) % n], flat[(i + 2) % n]) >= 0.0);
    if convex {
        out.extend((1..n - 1).map(|i| [0, i, i + 1]));
        return true;
    }
    let mut ring: Vec<usize> = (0..n).collect();
    while ring.len() > 3 {
        let m = ring.len();
        let ear = (0..m).find(|&k| {
            let (a, b, c) = (ring[(k + m - 1) % m], ring[k], ring[(k + 1) % m]);
            let (pa, pb, pc) = (flat[a], flat[b], flat[c]);
            if cross(pa, pb, pc) <= 0.0 {
                return false;
            }
            // No other vertex inside or on the triangle.
            ring.iter().all(|&j| {
                j == a
                    || j == b
                    || j == c
                    || !(cross(pa, pb, flat[j]) >= 0.0
                        && cross(pb, pc, flat[j]) >= 0.0
                        && cross(pc, pa, flat[j]) >= 0.0)
            })
        });
        let Some(k) = ear else {
            out.extend((1..ring.len() - 1).map(|i| [ring[0], ring[i], ring[i + 1]]));
            return false;
        };
        out.push([ring[(k + m - 1) % m], ring[k], ring[(k + 1) % m]]);
        ring.remove(k);
    }
    out.push([ring[0], ring[1], ring[2]]);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(points: &[Vec3A], tris: &[[usize; 3]]) -> f32 {
        tris.iter().map(|t| 0.5 * (points[t[1]] - points[t[0]]).cross(points[t[2]] - points[t[0]]).length()).sum()
    }

    #[test]
    fn a_concave_polygon_keeps_its_shape() {
        // An L in the xz plane (area 3), listed clockwise seen from +y; the fan from vertex 0
        // would cover the missing square too.
        let l = [(0.0, 0.0), (0.0, 2.0), (1.0, 2.0), (1.0, 1.0), (2.0, 1.0), (2.0, 0.0)];
        let points: Vec<Vec3A> = l.iter().map(|&(x, z)| Vec3A::new(x, 5.0, z)).collect();
        let mut tris = Vec::new();
        assert!(triangulate(&points, &mut tris));
        assert_eq!(tris.len(), 4);
        assert!((area(&points, &tris) - 3.0).abs() < 1e-5, "area {}", area(&points, &tris));
        // Every triangle keeps the polygon's winding: normals all the same way, as the
        // convex corner (0, 1, 2)'s.
        let normal_y = |t: [usize; 3]| (points[t[1]] - points[t[0]]).cross(points[t[2]] - points[t[0]]).y;
        let winding = normal_y([0, 1, 2]).signum();
        for t in &tris {
            assert_eq!(normal_y(*t).signum(), winding, "{t:?}");
        }
        // Centre of the missing square is not covered.
        let inside = |p: Vec3A| {
            tris.iter().any(|t| {
                let [a, b, c] = t.map(|i| Vec2::new(points[i].x, points[i].z));
                let q = Vec2::new(p.x, p.z);
                let s = [(b - a).perp_dot(q - a), (c - b).perp_dot(q - b), (a - c).perp_dot(q - c)];
                s.iter().all(|&x| x > 0.0) || s.iter().all(|&x| x < 0.0)
            })
        };
        assert!(!inside(Vec3A::new(1.5, 5.0, 1.5)));
        assert!(inside(Vec3A::new(0.5, 5.0, 1.5)));
    }

    #[test]
    fn convex_polygons_are_fanned_and_bow_ties_reported() {
        let quad = [Vec3A::ZERO, Vec3A::X, Vec3A::new(1.0, 1.0, 0.0), Vec3A::Y];
        let mut tris = Vec::new();
        assert!(triangulate(&quad, &mut tris));
        assert_eq!(tris, vec![[0, 1, 2], [0, 2, 3]]);
        // A bow tie is not simple: still two triangles out, no panic.
        let bow = [Vec3A::ZERO, Vec3A::new(1.0, 1.0, 0.0), Vec3A::X, Vec3A::Y];
        tris.clear();
        triangulate(&bow, &mut tris);
        assert_eq!(tris.len(), 2);
    }
}
