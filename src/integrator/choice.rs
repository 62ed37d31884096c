//! Which integrator renders, and with what settings: what the library needs to build one
//! ([`crate::render::render_scene`] builds it, the command line fills it from its flags).
use super::{Estimator, GuideSettings, LearnedSettings, Mis};
use crate::photon::GridShape;

/// Light-transport algorithm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum IntegratorKind {
    /// Path tracing with next event estimation (the paper's baseline).
    Path,
    /// Jensen 1995: path tracing with directions guided by the photon map.
    Jensen,
    /// ZVIDPT, terminal estimator (zero variance with exact photon estimates).
    ZvidptTerminal,
    /// ZVIDPT, collision estimator.
    ZvidptCollision,
    /// ZVIDPT with a learned importance function: guided directions, NEE at every vertex,
    /// channel-aware zero-variance roulette and splitting of the indirect part.
    Zvidpt,
}

/// An integrator and its settings, ready to be built for a render.
#[derive(Clone, Debug)]
pub enum IntegratorSettings {
    /// `path`.
    Path {
        /// Which lights NEE weighs against BSDF sampling.
        mis: Mis,
    },
    /// `jensen` with the photon grid.
    Jensen(GuideSettings),
    /// The paper's ZVIDPT (`zvidpt-terminal`, `zvidpt-collision`).
    Paper {
        /// Terminal or collision.
        estimator: Estimator,
        /// The photon guide's settings.
        guide: GuideSettings,
        /// The pixel grid `Gp`.
        pixel_grid: GridShape,
        /// Largest termination probability.
        q_max: f32,
        /// `κ` of the termination probability.
        q_kappa: f32,
    },
    /// The learned walk: `zvidpt`, or `jensen --learned-guide on` (albedo roulette).
    Learned(LearnedSettings),
}
