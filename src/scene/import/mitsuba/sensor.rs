//! The sensor (perspective camera), its film and reconstruction filter, the sampler, and the
//! integrator's depth, as the camera and render defaults.
use super::*;

impl Translator<'_, '_> {
    pub(super) fn integrator(&mut self, i: &Obj) -> Result<()> {
        if !matches!(i.plugin.as_str(), "path" | "volpath" | "volpathmis" | "direct" | "prb" | "ptracer") {
            self.unsupported(
                &i.at,
                format!(
                    "<integrator type=\"{}\">: its max_depth alone is read; the integrator is --integrator's",
                    i.plugin
                ),
            )?;
        }
        let depth = match i.plugin.as_str() {
            "direct" => 2,
            _ => self.integer(i, "max_depth", -1)?,
        };
        if depth >= 0 {
            let render = self.out.render.get_or_insert_with(RenderDescription::default);
            render.max_depth = Some(u32::try_from(depth).unwrap_or(u32::MAX));
        }
        Ok(())
    }

    pub(super) fn sensor(&mut self, s: &Obj) -> Result<()> {
        if !matches!(s.plugin.as_str(), "perspective" | "thinlens") {
            return Err(syntax(&s.at, format!("<sensor type=\"{}\"> is not supported (only perspective)", s.plugin)));
        }
        if s.plugin == "thinlens" {
            self.unsupported(&s.at, "a thinlens sensor renders as a pinhole (no depth of field)".into())?;
        }
        self.check_params(
            s,
            &[
                "fov",
                "fov_axis",
                "to_world",
                "near_clip",
                "far_clip",
                "focal_length",
                "aperture_radius",
                "focus_distance",
            ],
        )?;
        let to_world = self.transform(s, "to_world")?;
        let (mut width, mut height, mut crop) = (768i64, 576i64, None);
        let mut filter = MITSUBA_FILTER;
        let mut medium = None;
        for child in &s.children {
            if let Some(m) = self.child_medium(child)? {
                medium = m;
                continue;
            }
            let Child::Obj(o) = child else { continue };
            match o.tag.as_str() {
                "film" => {
                    if o.plugin != "hdrfilm" {
                        self.unsupported(&o.at, format!("<film type=\"{}\">: read as hdrfilm", o.plugin))?;
                    }
                    self.check_params(
                        o,
                        &[
                            "width",
                            "height",
                            "crop_offset_x",
                            "crop_offset_y",
                            "crop_width",
                            "crop_height",
                            "pixel_format",
                            "component_format",
                            "file_format",
                            "rfilter",
                            "banner",
                        ],
                    )?;
                    width = self.integer(o, "width", 768)?;
                    height = self.integer(o, "height", 576)?;
                    if ["crop_offset_x", "crop_offset_y", "crop_width", "crop_height"]
                        .iter()
                        .any(|k| o.param(k).is_some())
                    {
                        let x = self.integer(o, "crop_offset_x", 0)?;
                        let y = self.integer(o, "crop_offset_y", 0)?;
                        let w = self.integer(o, "crop_width", width - x)?;
                        let h = self.integer(o, "crop_height", height - y)?;
                        let window: Vec<u32> =
                            [x, y, w, h].iter().map(|&v| u32::try_from(v).unwrap_or(u32::MAX)).collect();
                        crop = Some([window[0], window[1], window[2], window[3]]);
                    }
                    for c in &o.children {
                        if let Child::Obj(f) = c
                            && f.tag == "rfilter"
                        {
                            filter = self.rfilter(f)?;
                        }
                    }
                }
                "sampler" => {
                    self.check_params(o, &["sample_count", "seed", "jitter"])?;
                    let n = self.integer(o, "sample_count", 4)?;
                    let Some(n) = u32::try_from(n).ok().filter(|&n| n >= 1) else {
                        return Err(syntax(&o.at, format!("sample_count must lie in 1..={}, got {n}", u32::MAX)));
                    };
                    let render = self.out.render.get_or_insert_with(RenderDescription::default);
                    render.spp = Some(n);
                }
                other => self.unsupported(&o.at, format!("a <{other}> inside the sensor is not supported: ignored"))?,
            }
        }
        let (fov, axis) = match (s.param("fov"), s.param("focal_length")) {
            (Some(_), Some((_, _, at))) => return Err(syntax(at, "give `fov` or `focal_length`, not both")),
            (Some(_), None) => (self.float(s, "fov", 45.0)?, self.text(s, "fov_axis")?.unwrap_or_else(|| "x".into())),
            (None, focal) => {
                let text = match focal {
                    Some((_, Value::Text(t), _)) => t.clone(),
                    Some((_, _, at)) => return Err(syntax(at, "`focal_length` must be a <string> such as \"50mm\"")),
                    None => "50mm".into(),
                };
                let mm: f64 = text
                    .trim()
                    .trim_end_matches("mm")
                    .parse()
                    .ok()
                    .filter(|f: &f64| f.is_finite() && *f > 0.0)
                    .ok_or_else(|| syntax(&s.at, format!("focal_length \"{text}\" is not a length in mm")))?;
                // A 36×24 mm film: the diagonal's field of view.
                ((36f64.hypot(24.0) / (2.0 * mm)).atan().to_degrees() * 2.0, "diagonal".into())
            }
        };
        if width < 1 || height < 1 || width > i64::from(u32::MAX) || height > i64::from(u32::MAX) {
            return Err(syntax(&s.at, format!("the film must be at least 1×1, got {width}×{height}")));
        }
        self.camera(to_world, fov, &axis, width as u32, height as u32, &s.at)?;
        self.out.camera.crop = crop;
        self.out.camera.filter = Some(filter);
        self.out.camera.medium = medium;
        Ok(())
    }

    /// A film's reconstruction filter: `box`, `gaussian` (`stddev`), `tent` (`radius`);
    /// others fall back to Mitsuba's default Gaussian.
    fn rfilter(&mut self, f: &Obj) -> Result<PixelFilterDescription> {
        Ok(match f.plugin.as_str() {
            "box" => {
                self.check_params(f, &[])?;
                PixelFilterDescription { kind: PixelFilterKind::Box, stddev: None, radius: None }
            }
            "gaussian" => {
                self.check_params(f, &["stddev"])?;
                let stddev = self.float(f, "stddev", 0.5)? as f32;
                PixelFilterDescription { kind: PixelFilterKind::Gaussian, stddev: Some(stddev), radius: None }
            }
            "tent" => {
                self.check_params(f, &["radius"])?;
                let r = self.float(f, "radius", 1.0)? as f32;
                PixelFilterDescription { kind: PixelFilterKind::Tent, stddev: None, radius: Some([r; 2]) }
            }
            other => {
                self.unsupported(&f.at, format!("<rfilter type=\"{other}\">: the default gaussian used"))?;
                MITSUBA_FILTER
            }
        })
    }

    /// The camera of a Mitsuba sensor: its `to_world` (+z forward, +y up, +x to the image's
    /// left) and field of view `fov` degrees along `axis`.
    pub(super) fn camera(
        &mut self,
        to_world: DMat4,
        fov: f64,
        axis: &str,
        width: u32,
        height: u32,
        at: &At,
    ) -> Result<()> {
        let (w, h) = (f64::from(width), f64::from(height));
        let half = (fov.to_radians() / 2.0).tan();
        let tan_y = match axis {
            "x" => half * h / w,
            "y" => half,
            "diagonal" => half * h / w.hypot(h),
            "smaller" => {
                if w < h {
                    half * h / w
                } else {
                    half
                }
            }
            "larger" => {
                if w > h {
                    half * h / w
                } else {
                    half
                }
            }
            other => return Err(syntax(at, format!("unknown fov_axis \"{other}\""))),
        };
        let fov_y = (2.0 * tan_y.atan()).to_degrees();
        let eye = to_world.transform_point3(DVec3::ZERO);
        let forward = to_world.transform_vector3(DVec3::Z).normalize_or_zero();
        let up = to_world.transform_vector3(DVec3::Y).normalize_or_zero();
        let left = to_world.transform_vector3(DVec3::X);
        // Our camera's right is forward × up; Mitsuba's image right is −x. They disagree
        // when `to_world` mirrors.
        let mirror = forward.cross(up).dot(left) > 0.0;
        self.out.camera = CameraDescription {
            eye: eye.as_vec3().to_array(),
            look_at: (eye + forward).as_vec3().to_array(),
            up: up.as_vec3().to_array(),
            fov_y: fov_y as f32,
            width,
            height,
            crop: None,
            mirror,
            filter: None,
            medium: None,
        };
        Ok(())
    }
}
