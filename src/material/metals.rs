//! Named conductors: the complex index of refraction `eta + i·k` per RGB channel for the
//! metals Mitsuba names in its `conductor` plugins (`material = "Au"`, …). The values are the
//! RGB reduction of the measured spectra both Mitsuba and pbrt ship (Palik's handbook data,
//! via the PBRT/Mitsuba `.spd` files), as published in the tables of the Tungsten and
//! yocto-gl renderers, rounded to six digits.
//!
//! `none` is Mitsuba's default: a perfect mirror (`eta` 0, `k` 1 reflects everything).
use crate::geometry::Vec3A;

/// Name, `eta`, `k` (six decimals as published, beyond what f32 keeps of some).
#[allow(clippy::excessive_precision)]
const TABLE: &[(&str, [f32; 3], [f32; 3])] = &[
    ("none", [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
    ("a-C", [2.944100, 2.227150, 1.968167], [0.887433, 0.799322, 0.815286]),
    ("Ag", [0.155265, 0.116723, 0.138381], [4.828343, 3.122246, 2.146950]),
    ("Al", [1.657460, 0.880369, 0.521229], [9.223869, 6.269523, 4.837001]),
    ("Au", [0.143119, 0.374957, 1.442479], [3.983160, 2.385721, 1.603215]),
    ("Be", [4.185059, 3.185060, 2.784091], [3.835440, 3.010126, 2.869009]),
    ("Cr", [4.369683, 2.916702, 1.654701], [5.206434, 4.231365, 3.754947]),
    ("Cu", [0.200438, 0.924033, 1.102212], [3.912949, 2.452848, 2.142188]),
    ("Cu2O", [3.549283, 2.952062, 2.736920], [0.113218, 0.194666, 0.600168]),
    ("CuO", [3.245382, 2.449629, 2.197411], [0.520274, 0.570737, 0.717225]),
    ("Hg", [2.398931, 1.440025, 0.909551], [6.327627, 4.371941, 3.421790]),
    ("Ir", [3.086410, 2.082194, 1.617887], [5.592151, 4.067176, 3.267261]),
    ("K", [0.064049, 0.046410, 0.038184], [2.104216, 1.348936, 0.913211]),
    ("Li", [0.265787, 0.195610, 0.220920], [3.540174, 2.311131, 1.668593]),
    ("Mo", [4.483701, 3.525458, 2.776077], [4.111131, 3.420872, 3.150603]),
    ("Na", [0.060267, 0.056141, 0.061991], [3.179291, 2.112480, 1.579094]),
    ("Nb", [3.420135, 2.790192, 2.395586], [3.441382, 2.737644, 2.579913]),
    ("Ni", [2.367275, 1.663358, 1.467055], [4.498833, 3.050164, 2.345427]),
    ("Rh", [2.585795, 1.860187, 1.554428], [6.782293, 4.702950, 3.976089]),
    ("Ta", [2.062585, 2.393092, 2.628068], [2.408047, 1.741371, 1.947038]),
    ("TiC", [3.700467, 2.837436, 2.582303], [3.265691, 2.351559, 2.172786]),
    ("TiN", [1.648469, 1.150448, 1.379780], [3.368460, 1.943489, 1.102012]),
    ("V", [4.277513, 3.513154, 2.761126], [3.491184, 2.889358, 3.111697]),
    ("VC", [3.657567, 2.752730, 2.532681], [3.068352, 2.198669, 1.963182]),
    ("VN", [2.865601, 2.119182, 1.940077], [3.032326, 2.056108, 1.616293]),
    ("W", [4.370703, 3.300297, 2.998267], [3.500678, 2.604865, 2.273193]),
];

/// `(eta, k)` of the named conductor, if known (names as Mitsuba spells them).
#[must_use]
pub fn lookup(name: &str) -> Option<(Vec3A, Vec3A)> {
    TABLE.iter().find(|e| e.0 == name).map(|e| (Vec3A::from_array(e.1), Vec3A::from_array(e.2)))
}

/// Every name [`lookup`] knows, for error messages.
#[must_use]
pub fn names() -> Vec<&'static str> {
    TABLE.iter().map(|e| e.0).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::fresnel;

    /// Normal-incidence reflectance `((η−1)² + k²)/((η+1)² + k²)` of the table's metals is what
    /// they look like: gold reflects red far more than blue, silver and aluminium are bright
    /// and nearly neutral, and `none` reflects everything.
    #[test]
    fn presets_have_the_colours_of_their_metals() {
        let r = |name: &str| {
            let (eta, k) = lookup(name).unwrap();
            fresnel::conductor(1.0, eta, k)
        };
        let au = r("Au");
        assert!(au.x > 0.9 && au.z < 0.5, "gold {au}");
        let cu = r("Cu");
        assert!(cu.x > cu.y && cu.y > cu.z - 0.05, "copper {cu}");
        for name in ["Ag", "Al"] {
            let c = r(name);
            assert!(c.min_element() > 0.85 && c.max_element() - c.min_element() < 0.1, "{name} {c}");
        }
        assert!((r("none") - Vec3A::ONE).abs().max_element() < 1e-6);
        assert!(lookup("Unobtainium").is_none());
    }
}
