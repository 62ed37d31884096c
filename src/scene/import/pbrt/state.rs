//! pbrt's graphics state: the current transform, named coordinate systems, attribute blocks
//! (`AttributeBegin`/`End`), `ReverseOrientation`, the current material and area light, and
//! the directives that change them.
use super::Parser;
use super::tokens::{Cursor, Token, describe};
use crate::error::Result;
use crate::scene::import::{At, syntax};
use glam::{DMat4, DVec3};

/// Deepest `AttributeBegin` nesting.
pub(super) const MAX_ATTRIBUTE_DEPTH: usize = 4096;

/// The area light in force (`AreaLightSource "diffuse"`): what the shapes that follow emit.
#[derive(Clone, Debug)]
pub(super) struct AreaLight {
    pub(super) radiance: [f32; 3],
    pub(super) two_sided: bool,
    /// Where it was declared (file, line).
    pub(super) origin: (std::path::PathBuf, u32),
}

/// pbrt's graphics state.
#[derive(Clone, Debug)]
pub(super) struct State {
    pub(super) ctm: DMat4,
    pub(super) reverse: bool,
    /// The current material's name among the description's materials.
    pub(super) material: String,
    pub(super) area_light: Option<AreaLight>,
    /// The media inside and outside the shapes that follow (`MediumInterface`), as the
    /// description's names (`None`: vacuum).
    pub(super) media: [Option<String>; 2],
}

/// pbrt's `LookAt`: camera space's +z towards the target, +y up, +x to `up × dir` (pbrt's
/// image right).
fn look_at(eye: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - eye).try_normalize()?;
    let right = up.try_normalize()?.cross(dir).try_normalize()?;
    let new_up = dir.cross(right);
    // World from camera; the CTM is camera from world.
    Some(DMat4::from_cols(right.extend(0.0), new_up.extend(0.0), dir.extend(0.0), eye.extend(1.0)).inverse())
}

impl Parser<'_> {
    pub(super) fn concat(&mut self, m: DMat4, at: &At) -> Result<()> {
        let ctm = self.state.ctm * m;
        if !ctm.is_finite() {
            return Err(syntax(at, "the transform is not finite"));
        }
        self.state.ctm = ctm;
        Ok(())
    }

    /// The graphics state: transforms, named coordinate systems, attribute blocks, motion.
    pub(super) fn state_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        match d {
            "Identity" => self.state.ctm = DMat4::IDENTITY,
            "Translate" => {
                let v = c.numbers(3, d)?;
                self.concat(DMat4::from_translation(DVec3::new(v[0], v[1], v[2])), at)?;
            }
            "Scale" => {
                let v = c.numbers(3, d)?;
                self.concat(DMat4::from_scale(DVec3::new(v[0], v[1], v[2])), at)?;
            }
            "Rotate" => {
                let v = c.numbers(4, d)?;
                let axis = DVec3::new(v[1], v[2], v[3])
                    .try_normalize()
                    .ok_or_else(|| syntax(at, "Rotate needs a non-zero axis"))?;
                self.concat(DMat4::from_axis_angle(axis, v[0].to_radians()), at)?;
            }
            "LookAt" => {
                let v = c.numbers(9, d)?;
                let m =
                    look_at(DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]), DVec3::new(v[6], v[7], v[8]))
                        .ok_or_else(|| syntax(at, "LookAt: the eye is on the target, or up is parallel to the view"))?;
                self.concat(m, at)?;
            }
            "Transform" | "ConcatTransform" => {
                let v = c.bracketed_numbers(16, d)?;
                // pbrt's 16 numbers are the matrix's columns.
                let m = DMat4::from_cols_array(&v.try_into().expect("16 numbers"));
                if d == "Transform" {
                    self.state.ctm = DMat4::IDENTITY;
                }
                self.concat(m, at)?;
            }
            "CoordinateSystem" => {
                let name = c.text(d)?;
                self.named_frames.insert(name, self.state.ctm);
            }
            "CoordSysTransform" => {
                let name = c.text(d)?;
                match self.named_frames.get(&name) {
                    Some(m) => self.state.ctm = *m,
                    None => self
                        .unsupported(at, format!("CoordSysTransform \"{name}\": no such coordinate system: ignored"))?,
                }
            }
            "ReverseOrientation" => self.state.reverse = !self.state.reverse,
            "AttributeBegin" | "TransformBegin" => {
                if self.stack.len() >= MAX_ATTRIBUTE_DEPTH {
                    return Err(syntax(at, format!("{d} nests deeper than {MAX_ATTRIBUTE_DEPTH}")));
                }
                self.stack.push((self.state.clone(), at.clone()));
            }
            "AttributeEnd" | "TransformEnd" => {
                let (saved, _) = self.stack.pop().ok_or_else(|| syntax(at, format!("{d} without a matching begin")))?;
                if d == "TransformEnd" {
                    self.state.ctm = saved.ctm;
                } else {
                    self.state = saved;
                }
            }
            "WorldBegin" => {
                if self.in_world {
                    return Err(syntax(at, "a second WorldBegin"));
                }
                self.in_world = true;
                self.named_frames.insert("camera".into(), self.state.ctm);
                self.state.ctm = DMat4::IDENTITY;
            }
            "WorldEnd" => {}
            "TransformTimes" => {
                let _ = c.numbers(2, d)?;
            }
            "ActiveTransform" => {
                let at2 = c.at();
                match c.next() {
                    Some(Token::Word(w)) if w == "All" => {}
                    Some(Token::Word(w)) if w == "StartTime" || w == "EndTime" => {
                        self.unsupported(
                            &at2,
                            "ActiveTransform: motion blur is not supported; every transform applies".into(),
                        )?;
                    }
                    other => {
                        return Err(syntax(
                            &at2,
                            format!(
                                "ActiveTransform: expected All, StartTime or EndTime, found {}",
                                describe(other.as_ref())
                            ),
                        ));
                    }
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}
