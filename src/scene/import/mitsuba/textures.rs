//! Textures: `bitmap` and `checkerboard` (with `to_uv`) as the description's textures.
use super::*;

impl Translator<'_, '_> {
    /// A texture: its name in the description.
    pub(super) fn texture(&mut self, t: &Obj) -> Result<String> {
        let name = self.fresh("texture");
        let description = match t.plugin.as_str() {
            "bitmap" => {
                self.check_params(t, &["filename", "filter_type", "wrap_mode", "raw", "to_uv"])?;
                let file = self.text(t, "filename")?.ok_or_else(|| syntax(&t.at, "a bitmap needs `filename`"))?;
                let path = resolve(&self.reader.includes.files[0], &t.at.file, &file);
                let filter = match self.text(t, "filter_type")?.as_deref() {
                    None | Some("bilinear") => FilterDescription::Bilinear,
                    Some("nearest") => FilterDescription::Nearest,
                    Some(other) => return Err(syntax(&t.at, format!("unknown filter_type \"{other}\""))),
                };
                let wrap = match self.text(t, "wrap_mode")?.as_deref() {
                    None | Some("repeat") => WrapDescription::Repeat,
                    Some("mirror") => WrapDescription::Mirror,
                    Some("clamp") => WrapDescription::Clamp,
                    Some(other) => return Err(syntax(&t.at, format!("unknown wrap_mode \"{other}\""))),
                };
                let to_uv = self.transform(t, "to_uv")?;
                TextureDescription {
                    kind: TextureKind::Bitmap,
                    file: Some(path.to_string_lossy().into_owned()),
                    wrap: Some(wrap),
                    filter: Some(filter),
                    raw: Some(self.boolean(t, "raw", false)?),
                    color0: None,
                    color1: None,
                    scale: None,
                    v_from_top: Some(true),
                    uv_transform: (to_uv != DMat4::IDENTITY).then(|| uv_rows(to_uv)),
                    factor: None,
                    invert: None,
                }
            }
            "checkerboard" => {
                self.check_params(t, &["color0", "color1", "to_uv"])?;
                let c0 = self.constant_colour(t, "color0", [0.4; 3])?;
                let c1 = self.constant_colour(t, "color1", [0.2; 3])?;
                let m = self.transform(t, "to_uv")?;
                // One period of Mitsuba's checkerboard spans [0, 1]: two squares each way,
                // after `to_uv` (a positive scale is folded into the squares' count).
                let (sx, sy) = (m.x_axis.x, m.y_axis.y);
                let pure_scale = m.x_axis.y == 0.0 && m.y_axis.x == 0.0 && m.w_axis.x == 0.0 && m.w_axis.y == 0.0;
                let (scale, map) = if pure_scale && sx > 0.0 && sy > 0.0 {
                    ([(2.0 * sx) as f32, (2.0 * sy) as f32], None)
                } else {
                    ([2.0, 2.0], Some(uv_rows(m)))
                };
                TextureDescription { uv_transform: map, ..TextureDescription::checkerboard(c0, c1, scale) }
            }
            other => {
                self.unsupported(&t.at, format!("<texture type=\"{other}\"> is not supported: grey 0.5 used"))?;
                TextureDescription::constant([0.5; 3])
            }
        };
        self.out.origins.insert(format!("texture {name}"), (t.at.file.to_path_buf(), t.at.line));
        self.out.textures.insert(name.clone(), description);
        Ok(name)
    }

    /// The texture `name` as Mitsuba 3 reads it for a single value (`eval_1`): a bitmap by its
    /// luminance, as we read any scalar texture, but a checkerboard with its colours swapped
    /// (Mitsuba's `eval_1` puts `color1` where `eval` puts `color0`; checked with Mitsuba 3.9.1
    /// at the four quadrants).
    pub(super) fn scalar_texture(&mut self, name: String) -> String {
        match self.out.textures.get(&name) {
            Some(t) if t.kind == TextureKind::Checkerboard => {
                let swapped = TextureDescription { color0: t.color1, color1: t.color0, ..t.clone() };
                let key = format!("{name}/scalar");
                self.out.textures.insert(key.clone(), swapped);
                key
            }
            _ => name,
        }
    }
}

/// A `to_uv` transform (read as 3D, applied to `(u, v, 0)`) as the rows of its 2D affine map.
fn uv_rows(m: DMat4) -> [[f32; 3]; 2] {
    let r = |k: usize| [m.col(0)[k] as f32, m.col(1)[k] as f32, m.col(3)[k] as f32];
    [r(0), r(1)]
}
