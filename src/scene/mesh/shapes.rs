//! Shapes a scene names instead of a mesh file (`[[shape]]`): rectangle, disk, cube and
//! sphere, in Mitsuba 3's canonical frames, placed by a transform. They become triangles like
//! every mesh; the rectangle and cube exactly, the disk and sphere as fine tessellations whose
//! error is stated below.
//!
//! Canonical shapes (as Mitsuba 3's): the rectangle is `[−1, 1]²` in the plane `z = 0` with
//! its normal (and emitting side) along `+z`; the disk the unit disk there; the cube
//! `[−1, 1]³` with outward normals; the sphere has its own centre and radius.
use crate::geometry::Vec3A;
use std::f32::consts::TAU;

/// Default number of segments of a disk's rim: the polygon's area is within 3e-5 of the
/// disk's (`1 − sin(2π/n)/(2π/n) ≈ (2π/n)²/6 = 2.5e-5`).
pub const DISK_SEGMENTS: u32 = 512;
/// Default subdivisions of the icosahedron a sphere starts from: 81,920 triangles, whose
/// vertices lie on the sphere and whose faces sag at most 2e-4 of the radius inside it (its
/// silhouette moves by less than a tenth of a pixel for a sphere 500 pixels across).
pub const SPHERE_SUBDIVISIONS: u32 = 6;
/// Most subdivisions accepted (20·4^8 = 1.3 M triangles per sphere).
pub const MAX_SPHERE_SUBDIVISIONS: u32 = 8;

/// `[−1, 1]²` at `z = 0`, normal `+z` (counter-clockwise seen from `+z`).
#[must_use]
pub fn rectangle() -> Vec<[Vec3A; 3]> {
    let (a, b, c, d) = (
        Vec3A::new(-1.0, -1.0, 0.0),
        Vec3A::new(1.0, -1.0, 0.0),
        Vec3A::new(1.0, 1.0, 0.0),
        Vec3A::new(-1.0, 1.0, 0.0),
    );
    vec![[a, b, c], [a, c, d]]
}

/// The unit disk at `z = 0`, normal `+z`, as a fan of `segments` triangles.
#[must_use]
pub fn disk(segments: u32) -> Vec<[Vec3A; 3]> {
    let rim = |k: u32| {
        let phi = TAU * k as f32 / segments as f32;
        Vec3A::new(phi.cos(), phi.sin(), 0.0)
    };
    (0..segments).map(|k| [Vec3A::ZERO, rim(k), rim(k + 1)]).collect()
}

/// `[−1, 1]³` with outward normals.
#[must_use]
pub fn cube() -> Vec<[Vec3A; 3]> {
    let mut out = Vec::with_capacity(12);
    // Each face: its normal axis and sign; the rectangle rotated onto it.
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let corner = |a: f32, b: f32| {
                let mut p = Vec3A::ZERO;
                p[axis] = sign;
                p[u] = a;
                p[v] = b;
                p
            };
            let q = [corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)];
            // (u, v, axis) is right-handed, so this winding faces +axis; flip for −axis.
            if sign > 0.0 {
                out.push([q[0], q[1], q[2]]);
                out.push([q[0], q[2], q[3]]);
            } else {
                out.push([q[0], q[2], q[1]]);
                out.push([q[0], q[3], q[2]]);
            }
        }
    }
    out
}

/// A sphere: an icosahedron subdivided `subdivisions` times, every vertex projected onto the
/// sphere, faces outward.
#[must_use]
pub fn sphere(center: Vec3A, radius: f32, subdivisions: u32) -> Vec<[Vec3A; 3]> {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let v: Vec<Vec3A> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3A::new(x, y, z).normalize())
    .collect();
    let faces = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut tris: Vec<[Vec3A; 3]> = faces.iter().map(|f| [v[f[0]], v[f[1]], v[f[2]]]).collect();
    for _ in 0..subdivisions {
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let (ab, bc, ca) = ((a + b).normalize(), (b + c).normalize(), (c + a).normalize());
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        tris = next;
    }
    tris.into_iter().map(|t| t.map(|p| center + p * radius)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(tris: &[[Vec3A; 3]]) -> f64 {
        tris.iter().map(|t| f64::from((t[1] - t[0]).cross(t[2] - t[0]).length()) * 0.5).sum()
    }

    /// Every face's normal points away from `inside`.
    fn outward(tris: &[[Vec3A; 3]], inside: Vec3A) -> bool {
        tris.iter().all(|t| {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            n.dot((t[0] + t[1] + t[2]) / 3.0 - inside) > 0.0
        })
    }

    const SCENE: &str = r#"
[camera]
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov_y = 40.0
width = 32
height = 24

[materials.white]
diffuse = [0.8, 0.8, 0.8]

[materials.light]
emission = [5.0, 5.0, 5.0]

# A ceiling light: the rectangle turned to face down, 0.5 × 0.4, at y = 0.9.
[[shape]]
type = "rectangle"
material = "light"
scale = [0.25, 0.2, 1.0]
rotate = { axis = [1.0, 0.0, 0.0], angle = 90.0 }
translate = [0.0, 0.9, 0.0]

# A mirrored cube (negative determinant): still outward.
[[shape]]
type = "cube"
material = "white"
matrix = [[-0.3, 0.0, 0.0, 0.5], [0.0, 0.3, 0.0, -0.7], [0.0, 0.0, 0.3, 0.0], [0.0, 0.0, 0.0, 1.0]]

[[shape]]
type = "sphere"
material = "white"
center = [-0.5, -0.6, 0.0]
radius = 0.4
subdivisions = 3

[[shape]]
type = "disk"
material = "white"
segments = 64
"#;

    #[test]
    fn shapes_in_a_scene_file() {
        let scene = crate::scene::Scene::parse(SCENE, std::path::Path::new("shapes/scene.toml")).unwrap();
        assert_eq!(scene.triangles.len(), 2 + 12 + 20 * 64 + 64);
        let light: Vec<_> = scene.triangles.iter().take(2).collect();
        for t in &light {
            let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
            assert!((n - Vec3A::NEG_Y).length() < 1e-6, "light normal {n}");
            assert!(t.iter().all(|p| (p.y - 0.9).abs() < 1e-6 && p.x.abs() <= 0.25 + 1e-6 && p.z.abs() <= 0.2 + 1e-6));
        }
        let cube: Vec<[Vec3A; 3]> = scene.triangles[2..14].to_vec();
        assert!(outward(&cube, Vec3A::new(0.5, -0.7, 0.0)));
        assert!((area(&cube) - 24.0 * 0.09).abs() < 1e-5);
        let sphere: Vec<[Vec3A; 3]> = scene.triangles[14..14 + 1280].to_vec();
        assert!(outward(&sphere, Vec3A::new(-0.5, -0.6, 0.0)));
    }

    #[test]
    fn bad_shapes_are_refused_by_name() {
        let with = |extra: &str| {
            let text = format!("{}\n{extra}", SCENE.split("# A ceiling").next().unwrap());
            crate::scene::Scene::parse(&text, std::path::Path::new("shapes/scene.toml")).unwrap_err().to_string()
        };
        let cases = [
            ("[[shape]]\ntype = \"cube\"\nmaterial = \"gold\"", "unknown material `gold`"),
            ("[[shape]]\ntype = \"cube\"\nmaterial = \"white\"\nradius = 2.0", "are for spheres"),
            ("[[shape]]\ntype = \"cube\"\nmaterial = \"white\"\nscale = [1.0, 0.0, 1.0]", "determinant is zero"),
            ("[[shape]]\ntype = \"sphere\"\nmaterial = \"white\"\nradius = -1.0", "positive radius"),
            ("[[shape]]\ntype = \"sphere\"\nmaterial = \"white\"\nsubdivisions = 12", "at most 8"),
            ("[[shape]]\ntype = \"disk\"\nmaterial = \"white\"\nsegments = 2", "segments"),
            ("[[shape]]\ntype = \"torus\"\nmaterial = \"white\"", "torus"),
            (
                "[[shape]]\ntype = \"cube\"\nmaterial = \"white\"\ntranslate = [1.0, 0.0, 0.0]\nmatrix = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]",
                "not both",
            ),
        ];
        for (extra, want) in cases {
            let e = with(extra);
            assert!(e.contains(want) && e.contains("scene.toml"), "{extra}: {e}");
        }
    }

    #[test]
    fn rectangle_and_cube_are_exact() {
        let r = rectangle();
        assert_eq!(area(&r), 4.0);
        assert!(r.iter().all(|t| (t[1] - t[0]).cross(t[2] - t[0]).normalize() == Vec3A::Z));
        let c = cube();
        assert_eq!(c.len(), 12);
        assert_eq!(area(&c), 24.0);
        assert!(outward(&c, Vec3A::ZERO));
    }

    #[test]
    fn disk_and_sphere_are_close() {
        let d = disk(DISK_SEGMENTS);
        let rel = (area(&d) / std::f64::consts::PI - 1.0).abs();
        assert!(rel < 3e-5, "disk area off by {rel}");
        assert!(d.iter().all(|t| (t[1] - t[0]).cross(t[2] - t[0]).z > 0.0));
        let (c, r) = (Vec3A::new(1.0, 2.0, 3.0), 0.5);
        let s = sphere(c, r, SPHERE_SUBDIVISIONS);
        assert_eq!(s.len(), 20 * 4usize.pow(SPHERE_SUBDIVISIONS));
        assert!(outward(&s, c));
        assert!(s.iter().flatten().all(|p| ((*p - c).length() / r - 1.0).abs() < 1e-5));
        // Largest sag: a face's centroid below the surface, relative to the radius.
        let sag = s.iter().map(|t| 1.0 - ((t[0] + t[1] + t[2]) / 3.0 - c).length() / r).fold(0.0f32, f32::max);
        assert!(sag < 2e-4, "sag {sag}");
        let rel = (area(&s) / (4.0 * std::f64::consts::PI * f64::from(r * r)) - 1.0).abs();
        assert!(rel < 1e-3, "sphere area off by {rel}");
    }
}
