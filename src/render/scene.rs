//! Rendering a scene from its description of the integrator: builds the backend the user
//! chose over the scene's triangles and the integrator, then renders.
use super::aov::{Aovs, first_hit_aovs};
use super::{RenderSettings, RenderStats, render};
use crate::Result;
use crate::accel::{Accel, BackendKind, WithAccel, with_backend_timed};
use crate::film::Image;
use crate::integrator::{GuidedVolume, IntegratorSettings, Jensen, LearnedZvidpt, PathTracer, Zvidpt};
use crate::scene::Scene;

/// Renders with whichever backend the user chose: the one dynamic choice, at the top.
struct RenderJob<'a> {
    scene: &'a Scene,
    integrator: &'a IntegratorSettings,
    settings: &'a RenderSettings,
    /// Trace first-hit AOVs after the render, with the same backend.
    aovs: bool,
}

impl WithAccel for RenderJob<'_> {
    type Output = Result<(Image, RenderStats, &'static str, Option<Aovs>)>;
    fn run<A: Accel>(self, accel: &A) -> Self::Output {
        let (scene, s) = (self.scene, self.settings);
        let (image, stats) = match self.integrator {
            // The learned surface walk does not model media: such scenes take volumetric
            // paths guided at medium points.
            IntegratorSettings::Learned(learned) if scene.volumetric() => {
                render(scene, accel, &mut GuidedVolume::new(learned.clone()), s)?
            }
            IntegratorSettings::Path { mis } => {
                render(scene, accel, &mut PathTracer { mis: *mis, ..PathTracer::default() }, s)?
            }
            IntegratorSettings::Jensen(guide) => render(scene, accel, &mut Jensen::new(guide.clone()), s)?,
            IntegratorSettings::Paper { estimator, guide, pixel_grid, q_max, q_kappa } => {
                let mut zvidpt = Zvidpt {
                    pixel_grid: *pixel_grid,
                    q_max: *q_max,
                    q_kappa: *q_kappa,
                    ..Zvidpt::new(*estimator, guide.clone())
                };
                render(scene, accel, &mut zvidpt, s)?
            }
            IntegratorSettings::Learned(learned) => render(scene, accel, &mut LearnedZvidpt::new(learned.clone()), s)?,
        };
        let aovs = self.aovs.then(|| first_hit_aovs(scene, accel, s.seed));
        Ok((image, stats, accel.name(), aovs))
    }
}

/// Renders `scene` with `integrator` on `backend`: the one place where the backend and the
/// integrator are chosen. Returns the backend's name too.
pub fn render_scene(
    scene: &Scene,
    integrator: &IntegratorSettings,
    backend: BackendKind,
    settings: &RenderSettings,
) -> Result<(Image, RenderStats, &'static str)> {
    render_scene_with_aovs(scene, integrator, backend, settings, false).map(|(i, s, b, _)| (i, s, b))
}

/// [`render_scene`], and the first-hit AOVs when `aovs`.
pub fn render_scene_with_aovs(
    scene: &Scene,
    integrator: &IntegratorSettings,
    backend: BackendKind,
    settings: &RenderSettings,
    aovs: bool,
) -> Result<(Image, RenderStats, &'static str, Option<Aovs>)> {
    if scene.volumetric() && matches!(integrator, IntegratorSettings::Jensen(_) | IntegratorSettings::Paper { .. }) {
        return Err(crate::Error::InvalidOption(format!(
            "{}: this integrator does not track participating media; `path` and `zvidpt` render them",
            scene.name
        )));
    }
    let (out, built) = with_backend_timed(backend, &scene.triangles, RenderJob { scene, integrator, settings, aovs })?;
    out.map(|(image, stats, name, aovs)| (image, RenderStats { build_seconds: built, ..stats }, name, aovs))
}
