//! The command line: one file per subcommand; the arguments they share, parsing, and the
//! dispatch live here.
use crate::accel::BackendKind;
use crate::film::{self, Image, Metadata};
pub use crate::integrator::IntegratorKind;
use crate::integrator::{
    Allocation, Estimator, GuideSettings, IntegratorSettings, LearnedSettings, MAX_SUBPIXELS, Mis, Roulette,
};
use crate::light::LightSampling;
use crate::photon::{GridShape, GuidePhotons, MAX_GUIDE_CELLS};
use crate::render::{RenderSettings, RenderStats, render_scene, render_scene_with_aovs};
use crate::scene::Scene;
use crate::{Error, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::{Path, PathBuf};

/// `println!` that returns an error instead of panicking when standard output is closed
/// (`zvidpt diff … | head -1`); `main` exits quietly on a broken pipe.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*).map_err(|e| Error::io("standard output", e))?
    }};
}

/// `print!` without the newline, as [`out!`].
macro_rules! out_part {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout().lock(), $($arg)*).map_err(|e| Error::io("standard output", e))?
    }};
}

/// `eprintln!` for warnings and progress lines, which are dropped if standard error is closed.
macro_rules! warn {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($arg)*);
    }};
}

mod batch;
mod converge;
mod denoise;
mod diff;
pub mod help_doc;
mod info;
mod merge;
mod reference;
mod render;
mod shell;

pub use batch::BatchArgs;
use batch::{check_batch_options, run_batch};
pub use converge::ConvergeArgs;
use converge::{check_converge_options, run_converge};
pub use denoise::DenoiseArgs;
use denoise::run_denoise;
pub use diff::DiffArgs;
use diff::run_diff;
pub use info::InfoArgs;
use info::run_info;
pub use merge::MergeArgs;
use merge::run_merge;
pub use reference::ReferenceArgs;
use reference::{check_reference_options, run_reference};
use render::check_render_options;
pub use render::{RenderArgs, run_render};
pub use shell::{CompletionsArgs, ManArgs, man_pages};
use shell::{run_completions, run_man};

/// The command-line spelling of a value (`zvidpt-terminal`, `solid-angle`), as written into
/// metadata and tables.
fn flag_name(value: impl ValueEnum) -> String {
    value.to_possible_value().map_or("?".into(), |v| v.get_name().to_string())
}
#[derive(Debug, Parser)]
#[command(
    name = "zvidpt",
    version,
    about = "Zero Variance Importance Sampling Driven Potential Tracing: a CPU renderer"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a scene to an EXR (linear float, with render metadata) and a PNG (sRGB).
    Render(RenderArgs),
    /// Compare an image with a reference: prints MSE and relMSE.
    Diff(DiffArgs),
    /// Print an EXR's size, render metadata and per-channel mean.
    Info(InfoArgs),
    /// Render a high-spp path-traced reference (with per-pixel variance); skipped when the
    /// output already holds a reference of the same scene (content hash) and spp.
    Reference(ReferenceArgs),
    /// Measure MSE and relMSE against a reference for several integrators and sample counts,
    /// averaged over independent seeds; writes CSVs into a folder.
    Converge(ConvergeArgs),
    /// Render a job file of scenes × integrators × budgets one job after another: jobs whose
    /// output already holds the same render are skipped (rerun to resume), a failed job is
    /// recorded and the rest go on; writes summary.csv and summary.json.
    Batch(BatchArgs),
    /// Merge partial renders of sample ranges (`render --samples A..B`) into one image,
    /// bit-identical to a single render of all the samples.
    Merge(MergeArgs),
    /// Denoise an image with Intel Open Image Denoise (guided by its albedo and normal
    /// layers) into a new file; the noisy estimate is left as it is.
    Denoise(DenoiseArgs),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    Completions(CompletionsArgs),
    /// Print or install the manual pages (zvidpt.1 and one per subcommand).
    Man(ManArgs),
}

/// On or off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Switch {
    On,
    Off,
}

/// Where and how big: shared by `render`, `reference` and `converge`.
#[derive(Clone, Debug, Args)]
pub struct MachineArgs {
    /// Override the scene's resolution, as WIDTHxHEIGHT (the view is kept; `converge` needs
    /// the reference's).
    #[arg(long, value_parser = parse_resolution)]
    pub resolution: Option<(u32, u32)>,
    /// Ray-tracing backend (auto: Embree when compiled in, otherwise bvh).
    #[arg(long, value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// Worker threads [default: one per core].
    #[arg(long)]
    pub threads: Option<usize>,
}

/// How the scene file is read, and what of it the command line overrides.
#[derive(Clone, Debug, Default, Args)]
pub struct SceneArgs {
    /// Mitsuba scenes: the value of `$NAME` (over the scene's `<default>`), as Mitsuba's -D.
    #[arg(short = 'D', long = "define", value_parser = parse_define, value_name = "NAME=VALUE")]
    pub defines: Vec<(String, String)>,
    /// Imported scenes: anything outside the supported subset is an error, not a warning.
    #[arg(long)]
    pub strict: bool,
    /// The longest path counted, in segments (1: emitters seen directly; 2: direct light)
    /// [default: the scene's (Mitsuba's `max_depth`), else unbounded]. path, jensen and zvidpt
    /// (the paper's zvidpt-terminal and zvidpt-collision count paths of every length).
    #[arg(long, value_name = "N")]
    pub max_depth: Option<u32>,
}

impl SceneArgs {
    #[must_use]
    pub fn import_options(&self) -> crate::scene::import::ImportOptions {
        crate::scene::import::ImportOptions { defines: self.defines.clone(), strict: self.strict }
    }
}

fn parse_define(s: &str) -> std::result::Result<(String, String), String> {
    let (name, value) = s.split_once('=').ok_or_else(|| format!("\"{s}\" is not NAME=VALUE"))?;
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(format!("\"{name}\" is not a name (letters, digits, _)"));
    }
    Ok((name.to_string(), value.to_string()))
}

/// Estimator options: light sampling (every integrator), then the photon map and guides of
/// the guided integrators (jensen, zvidpt-*).
#[derive(Clone, Debug, Args)]
pub struct PhotonArgs {
    /// How next event estimation picks a point on an emitter: a uniform point on its area
    /// (ALGORITHM.md §3) or a uniform direction in its solid angle (bounded weights beside a
    /// light; the estimate is the same, the noise lower).
    #[arg(long, value_enum, default_value_t = LightSampling::SolidAngle)]
    pub light_sampling: LightSampling,
    /// path and the learned integrators (zvidpt, jensen --learned-guide on): where light found
    /// by the sampled directions is weighed against NEE by multiple importance sampling: at
    /// surfaces that are not Lambertian (where NEE alone is nearly ideal it only adds noise),
    /// everywhere, or nowhere.
    #[arg(long, value_enum, default_value_t = Mis::Glossy)]
    pub mis: Mis,
    /// Photons stored by the photon pass (jensen, zvidpt-*; the paper used 6891).
    #[arg(long, default_value_t = 6891)]
    pub photons: usize,
    /// Photons per radiance estimate and guide grid (the paper's N).
    #[arg(long, default_value_t = 50)]
    pub knn: usize,
    /// Direction guide grid GL as ROWSxCOLS over the cosine-warped hemisphere (rows split θ).
    #[arg(long, default_value = "4x16", value_parser = parse_guide_grid)]
    pub guide_grid: GridShape,
    /// ZVIDPT's subpixel grid Gp as ROWSxCOLS (at most 32 subpixels).
    #[arg(long, default_value = "2x4", value_parser = parse_pixel_grid)]
    pub pixel_grid: GridShape,
    /// Photons that shape ZVIDPT's guide grid: indirect (bounced at least once) or all (the
    /// paper's choice). Jensen always uses all.
    #[arg(long, value_enum, default_value_t = GuidePhotons::Indirect)]
    pub guide: GuidePhotons,
    /// ε_L: every guide-grid cell is floored at this fraction of the mean cell, i.e. the grid
    /// is mixed with cosine sampling in proportion ε_L : 1 and direction weights stay below
    /// (1 + 1/ε_L)·ρ. ALGORITHM.md §2 suggests 0.1; 1 measured best (docs/integrators.md).
    #[arg(long, default_value_t = 1.0)]
    pub guide_floor: f32,
    /// ZVIDPT's largest termination probability q (ALGORITHM.md §2: 0.95); must be below 1,
    /// or the indirect term would be dropped.
    #[arg(long, default_value_t = 0.95)]
    pub q_max: f32,
    /// κ in ZVIDPT's termination probability q = L̃1/(L̃1 + κ·L̃ind); 1 is ALGORITHM.md's
    /// q = L̃1/L̃r, larger values continue walks more often where direct light dominates.
    #[arg(long, default_value_t = 1.0)]
    pub q_kappa: f32,
    /// Precompute guide records after the photon pass (on) or query the photon map at every
    /// walk vertex (off, the paper's way; slower).
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub guide_cache: Switch,
    /// zvidpt: how walks continue: a weight window on the expected indirect contribution
    /// (splits too), the paper's q = L̃1/L̃r, or the path tracer's albedo rule.
    #[arg(long, value_enum, default_value_t = Roulette::Window)]
    pub roulette: Roulette,
    /// zvidpt: samples a learned-guide cell must receive in a training iteration to be split
    /// (× √2 per iteration; PPG's c).
    #[arg(long, default_value_t = 4000)]
    pub split_samples: u64,
    /// zvidpt: a cell whose directions' relative second moment (with its best mixture) exceeds
    /// this splits at a proportionally lower count, down to a quarter of --split-samples (0:
    /// every cell at --split-samples).
    #[arg(long, default_value_t = 2.0)]
    pub split_moment: f32,
    /// zvidpt: training samples per pixel in all (iterations of 1, 2, 4, …) [default: half
    /// of --spp; with --time, iterations while the next would end within 35% of the budget].
    #[arg(long)]
    pub train_spp: Option<u32>,
    /// zvidpt: fraction of directions drawn from the learned guide (the rest: cosine); with
    /// --learn-mix on, each guide cell starts from it and then picks its own.
    #[arg(long, default_value_t = 0.75)]
    pub guide_mix: f32,
    /// zvidpt: each guide cell learns its fraction (by the second moment of the directions'
    /// weights under each candidate; the default), or all keep --guide-mix.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub learn_mix: Switch,
    /// zvidpt: weight per deposit of earlier training iterations' directional data when a
    /// guide tree is rebuilt (0: each iteration's own deposits only, as PPG; 1: all alike;
    /// compounds per iteration).
    #[arg(long, default_value_t = 0.25)]
    pub guide_carry: f32,
    /// zvidpt: fraction of directions aimed at a uniform point of the box each guide cell
    /// learned its light comes from (where it learned one; 0: off).
    #[arg(long, default_value_t = 0.3)]
    pub box_mix: f32,
    /// zvidpt: caustic photons traced before training (photons that reach a Lambertian
    /// surface straight from glass or a mirror): around where they left the specular surface
    /// lie source boxes that the cells they reached aim at (0: none).
    #[arg(long, default_value_t = 10_000)]
    pub caustic_photons: usize,
    /// zvidpt: cells that caustic photons reached aim, instead of at the whole caustic box,
    /// at cones toward where the caustic photons that landed near each shading point left
    /// the specular surface.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub caustic_lobes: Switch,
    /// zvidpt: weight-window width s (no roulette or split while the expected contribution
    /// ratio lies in [2/(1+s), 2s/(1+s)]).
    #[arg(long, default_value_t = 5.0)]
    pub window: f32,
    /// zvidpt: most branches a vertex splits into.
    #[arg(long, default_value_t = 8)]
    pub max_split: u32,
    /// zvidpt: a walk that roulette stops returns the learned L̃ind (continuations correct
    /// it: unbiased, and no roulette noise where L̃ is exact) instead of 0.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub roulette_cv: Switch,
    /// zvidpt and jensen --learned-guide on: measure the path tracer during training (an
    /// 8-spp probe) and let it render the rest where the learned walk's variance times cost
    /// per sample is higher (on), or always keep the learned walk (off). With `on`, zvidpt's
    /// walk is also probed without splitting, and splits only where that measured no better.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub fallback: Switch,
    /// zvidpt: lowest survival probability of the weight window (bounds the weight a
    /// surviving walk gains where the learned radiance is too low).
    #[arg(long, default_value_t = 0.2)]
    pub min_survival: f32,
    /// zvidpt and jensen --learned-guide on: least share of cosine sampling at a diffuse
    /// vertex, whatever its guide cell learned (a defensive mixture; 0: as learned).
    #[arg(long, default_value_t = 0.0)]
    pub defensive: f32,
    /// zvidpt and jensen --learned-guide on: most strata per axis over which a pixel's seen
    /// light (emission at the first hit, and behind mirrors and smooth glass from there) is
    /// split, where a light smaller than the pixel makes it the pixel's noise: up to N×N
    /// extra camera rays per sample, chosen per pixel from the training (1: off).
    #[arg(long, default_value_t = 8)]
    pub seen_strata: u8,
    /// zvidpt and jensen --learned-guide on: before splitting the seen light, trace the
    /// pixels that see glass or mirrors through many film points each (at most 5% of the
    /// render's rays), so a light's image there too small for the training to meet is split.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub seen_probe: Switch,
    /// zvidpt and jensen --learned-guide on: share the render's samples among the pixels in
    /// proportion to the per-sample standard deviation the training measured around each
    /// (from its neighbours, never its own samples: unbiased), floored at 0.4 of the
    /// mean; or give every pixel the same count. --spp is then the mean count.
    #[arg(long, value_enum, default_value_t = Allocation::Error)]
    pub allocation: Allocation,
    /// jensen: guide with the learned importance function (PPG-style guided path tracing)
    /// instead of the photon grid.
    #[arg(long, value_enum, default_value_t = Switch::Off)]
    pub learned_guide: Switch,
}

impl PhotonArgs {
    /// The defaults (the path tracer ignores them).
    fn default_for_path() -> Self {
        let g = GuideSettings::default();
        Self {
            light_sampling: LightSampling::default(),
            mis: Mis::default(),
            photons: g.photons,
            knn: g.knn,
            guide_grid: g.grid,
            pixel_grid: GridShape { rows: 2, cols: 4 },
            guide: g.which,
            guide_floor: g.floor,
            guide_cache: Switch::On,
            q_max: 0.95,
            q_kappa: 1.0,
            roulette: Roulette::Window,
            split_samples: 4000,
            split_moment: 2.0,
            train_spp: None,
            guide_mix: 0.75,
            learn_mix: Switch::On,
            guide_carry: 0.25,
            box_mix: 0.3,
            caustic_photons: 10_000,
            caustic_lobes: Switch::On,
            window: 5.0,
            max_split: 8,
            roulette_cv: Switch::On,
            fallback: Switch::On,
            min_survival: 0.2,
            defensive: 0.0,
            seen_strata: 8,
            seen_probe: Switch::On,
            allocation: Allocation::Error,
            learned_guide: Switch::Off,
        }
    }

    /// The learned integrator's settings (`zvidpt`, or `jensen --learned-guide on`).
    fn learned(&self, roulette: Roulette) -> LearnedSettings {
        LearnedSettings {
            photons: self.photons,
            knn: self.knn,
            split_samples: self.split_samples,
            split_moment: self.split_moment,
            guide_mix: self.guide_mix,
            learn_mix: self.learn_mix == Switch::On,
            guide_carry: self.guide_carry,
            box_mix: self.box_mix,
            caustic_photons: self.caustic_photons,
            caustic_lobes: self.caustic_lobes == Switch::On,
            roulette,
            window: self.window,
            max_split: self.max_split,
            control_variate: self.roulette_cv == Switch::On && roulette != Roulette::Albedo,
            fallback: self.fallback == Switch::On,
            min_survival: self.min_survival,
            defensive: self.defensive,
            seen_strata: self.seen_strata,
            seen_probe: self.seen_probe == Switch::On,
            allocation: self.allocation,
            train_spp: self.train_spp,
            mis: self.mis,
        }
    }

    /// The integrator `kind` with these settings.
    #[must_use]
    pub fn integrator(&self, kind: IntegratorKind) -> IntegratorSettings {
        let guide = self.settings();
        let paper = |estimator| IntegratorSettings::Paper {
            estimator,
            guide: guide.clone(),
            pixel_grid: self.pixel_grid,
            q_max: self.q_max,
            q_kappa: self.q_kappa,
        };
        match kind {
            IntegratorKind::Path => IntegratorSettings::Path { mis: self.mis },
            IntegratorKind::Jensen if self.learned_guide == Switch::On => {
                IntegratorSettings::Learned(self.learned(Roulette::Albedo))
            }
            IntegratorKind::Jensen => IntegratorSettings::Jensen(guide),
            IntegratorKind::Zvidpt => IntegratorSettings::Learned(self.learned(self.roulette)),
            IntegratorKind::ZvidptTerminal => paper(Estimator::Terminal),
            IntegratorKind::ZvidptCollision => paper(Estimator::Collision),
        }
    }

    fn settings(&self) -> GuideSettings {
        GuideSettings {
            photons: self.photons,
            knn: self.knn,
            grid: self.guide_grid,
            which: self.guide,
            cache: self.guide_cache == Switch::On,
            floor: self.guide_floor,
            ..GuideSettings::default()
        }
    }

    fn check(&self) -> Result<()> {
        if !(1..=crate::photon::MAX_PHOTONS).contains(&self.photons) {
            return Err(Error::InvalidOption(format!(
                "--photons must lie in 1..={} (about 100 bytes each)",
                crate::photon::MAX_PHOTONS
            )));
        }
        if self.knn == 0 || self.knn > self.photons {
            return Err(Error::InvalidOption(format!(
                "--knn must lie in 1..={} (the photon count, --photons)",
                self.photons
            )));
        }
        if !(self.guide_floor.is_finite() && self.guide_floor > 0.0) {
            return Err(Error::InvalidOption("--guide-floor must be a positive number".into()));
        }
        if !(self.q_kappa.is_finite() && self.q_kappa > 0.0) {
            return Err(Error::InvalidOption("--q-kappa must be a positive number".into()));
        }
        if !(self.q_max >= 0.05 && self.q_max < 1.0) {
            return Err(Error::InvalidOption("--q-max must lie in [0.05, 1)".into()));
        }
        if !(16..=1 << 40).contains(&self.split_samples) {
            return Err(Error::InvalidOption("--split-samples must lie in 16..=2^40".into()));
        }
        if !(self.split_moment == 0.0 || (self.split_moment >= 1.0 && self.split_moment.is_finite())) {
            return Err(Error::InvalidOption("--split-moment must be 0 (off) or a number of at least 1".into()));
        }
        if !(self.guide_mix >= 0.0 && self.guide_mix < 1.0) {
            return Err(Error::InvalidOption(
                "--guide-mix must lie in [0, 1) (cosine sampling keeps every direction)".into(),
            ));
        }
        if !(self.guide_carry.is_finite() && (0.0..=1.0).contains(&self.guide_carry)) {
            return Err(Error::InvalidOption("--guide-carry must lie in [0, 1]".into()));
        }
        if !(self.box_mix >= 0.0 && self.box_mix < 1.0) {
            return Err(Error::InvalidOption("--box-mix must lie in [0, 1)".into()));
        }
        if self.caustic_photons > crate::photon::MAX_PHOTONS {
            return Err(Error::InvalidOption(format!(
                "--caustic-photons must lie in 0..={}",
                crate::photon::MAX_PHOTONS
            )));
        }
        if !(self.window.is_finite() && self.window >= 1.0) {
            return Err(Error::InvalidOption("--window must be a number of at least 1".into()));
        }
        if !(1..=64).contains(&self.max_split) {
            return Err(Error::InvalidOption("--max-split must lie in 1..=64".into()));
        }
        if !(self.min_survival > 0.0 && self.min_survival <= 1.0) {
            return Err(Error::InvalidOption("--min-survival must lie in (0, 1]".into()));
        }
        if !(self.defensive.is_finite() && (0.0..=1.0).contains(&self.defensive)) {
            return Err(Error::InvalidOption("--defensive must lie in [0, 1]".into()));
        }
        if !(1..=16).contains(&self.seen_strata) {
            return Err(Error::InvalidOption("--seen-strata must lie in 1..=16".into()));
        }
        Ok(())
    }

    /// Metadata describing the options that shaped `integrator`'s image.
    fn describe(&self, integrator: IntegratorKind, meta: &mut Metadata) {
        meta.push("light_sampling", flag_name(self.light_sampling));
        if integrator == IntegratorKind::Path {
            meta.push("mis", flag_name(self.mis));
            return;
        }
        meta.push("photons", self.photons);
        meta.push("knn", self.knn);
        meta.push("guide_grid", format!("{}x{}", self.guide_grid.rows, self.guide_grid.cols));
        meta.push("guide_cache", flag_name(self.guide_cache));
        meta.push("guide_floor", self.guide_floor);
        if matches!(integrator, IntegratorKind::ZvidptTerminal | IntegratorKind::ZvidptCollision) {
            meta.push("pixel_grid", format!("{}x{}", self.pixel_grid.rows, self.pixel_grid.cols));
            meta.push("q_max", self.q_max);
            meta.push("q_kappa", self.q_kappa);
            meta.push("guide", flag_name(self.guide));
        }
        if integrator == IntegratorKind::Jensen {
            meta.push("learned_guide", flag_name(self.learned_guide));
        }
        if integrator == IntegratorKind::Zvidpt || self.learned_guide == Switch::On {
            meta.push("train_spp", self.train_spp.map_or("-".into(), |n| n.to_string()));
            meta.push("roulette", flag_name(self.roulette));
            meta.push("split_samples", self.split_samples);
            meta.push("split_moment", self.split_moment);
            meta.push("guide_mix", self.guide_mix);
            meta.push("learn_mix", flag_name(self.learn_mix));
            meta.push("guide_carry", self.guide_carry);
            meta.push("box_mix", self.box_mix);
            meta.push("caustic_photons", self.caustic_photons);
            meta.push("caustic_lobes", flag_name(self.caustic_lobes));
            meta.push("window", self.window);
            meta.push("max_split", self.max_split);
            meta.push("roulette_cv", flag_name(self.roulette_cv));
            meta.push("mis", flag_name(self.mis));
            meta.push("fallback", flag_name(self.fallback));
            meta.push("min_survival", self.min_survival);
            meta.push("defensive", self.defensive);
            meta.push("seen_strata", self.seen_strata);
            meta.push("seen_probe", flag_name(self.seen_probe));
            meta.push("allocation", flag_name(self.allocation));
        }
    }
}

fn parse_guide_grid(s: &str) -> std::result::Result<GridShape, String> {
    GridShape::parse(s, MAX_GUIDE_CELLS)
}

fn parse_pixel_grid(s: &str) -> std::result::Result<GridShape, String> {
    GridShape::parse(s, MAX_SUBPIXELS)
}

fn parse_resolution(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WIDTHxHEIGHT, e.g. 256x192")?;
    let w = w.trim().parse().map_err(|_| format!("bad width `{w}`"))?;
    let h = h.trim().parse().map_err(|_| format!("bad height `{h}`"))?;
    Ok((w, h))
}

/// Runs a parsed command line. Warnings go to stderr; results to stdout.
/// Parses a command line (the program name first). Negative numbers are values, so
/// `--seed -1` is reported as an invalid seed, not as an unknown flag `-1`.
pub fn parse_from<I, T>(args: I) -> std::result::Result<Cli, clap::Error>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    use clap::{CommandFactory, FromArgMatches};
    let mut command = Cli::command().mut_subcommands(|s| s.allow_negative_numbers(true));
    let matches = command.try_get_matches_from_mut(args)?;
    Cli::from_arg_matches(&matches).map_err(|e| e.format(&mut command))
}

pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => run_render(&args).map(|_| ()),
        Command::Diff(args) => run_diff(&args),
        Command::Info(args) => run_info(&args),
        Command::Reference(args) => run_reference(&args),
        Command::Converge(args) => run_converge(&args),
        Command::Batch(args) => run_batch(&args),
        Command::Merge(args) => run_merge(&args),
        Command::Denoise(args) => run_denoise(&args),
        Command::Completions(args) => run_completions(&args),
        Command::Man(args) => run_man(&args),
    }
}

/// The scene argument's default.
const DEFAULT_SCENE: &str = "scenes/cornell-paper";

/// The default scene also works from outside the source tree (said on standard error); any
/// other path means what it says.
fn locate_scene(path: &Path) -> PathBuf {
    if path == Path::new(DEFAULT_SCENE) && !path.exists() {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
        if shipped.exists() {
            warn!("note: no {DEFAULT_SCENE} here; using the shipped one, {}", shipped.display());
            return shipped;
        }
    }
    path.to_path_buf()
}

/// Checks a command's options alone (no file is touched): what `run` checks first.
pub fn validate(cli: &Cli) -> Result<()> {
    match &cli.command {
        Command::Render(a) => check_render_options(a),
        Command::Converge(a) => check_converge_options(a),
        Command::Reference(a) => check_reference_options(a),
        Command::Batch(a) => check_batch_options(a),
        Command::Diff(_)
        | Command::Info(_)
        | Command::Merge(_)
        | Command::Denoise(_)
        | Command::Completions(_)
        | Command::Man(_) => Ok(()),
    }
}

/// The sRGB PNG written beside a command's EXR: shared by `render`, `merge` and `denoise`.
#[derive(Clone, Debug, Args)]
pub struct PngArgs {
    /// Output PNG (sRGB). Default: the EXR's path with a .png extension.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Do not write a PNG.
    #[arg(long, conflicts_with = "png")]
    pub no_png: bool,
    /// PNG exposure in stops (pixel values are scaled by 2^EV before sRGB encoding).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
}

impl PngArgs {
    /// Where the PNG beside the EXR `output` goes: `--png` if given, none with `--no-png` or
    /// `skip`, else the EXR's path with a .png extension — checked: that derived path must not
    /// be the EXR itself and may replace only an earlier PNG.
    fn destination(&self, output: &Path, skip: bool) -> Result<Option<PathBuf>> {
        if self.no_png || skip {
            return Ok(None);
        }
        if let Some(p) = &self.png {
            return Ok(Some(p.clone()));
        }
        let derived = output.with_extension("png");
        if film::same_file(&derived, output) {
            return Err(Error::InvalidOption(format!(
                "-o {} names the EXR, and the PNG beside it would be the same file: use -o NAME.exr, --png PATH or --no-png",
                output.display()
            )));
        }
        check_derived_png(&derived)?;
        Ok(Some(derived))
    }
}

/// The PNG written beside the EXR by default (a path the user did not type) may replace only
/// an earlier PNG, never another kind of file.
fn check_derived_png(path: &Path) -> Result<()> {
    use std::io::Read as _;
    if !path.is_file() {
        return Ok(());
    }
    let mut magic = [0u8; 8];
    let is_png = crate::io::open_regular(path, "PNG").is_ok_and(|mut f| f.read_exact(&mut magic).is_ok())
        && magic == *b"\x89PNG\r\n\x1a\n";
    if is_png {
        Ok(())
    } else {
        Err(Error::Output {
            path: path.to_path_buf(),
            message: "exists and is not a PNG image; not replacing it (name the PNG with --png, or --no-png)".into(),
        })
    }
}

/// Pixel values (per channel) that are NaN or infinite.
fn non_finite_values(image: &Image) -> usize {
    image.pixels.iter().flatten().filter(|x| !x.is_finite()).count()
}

fn load_at(scene: &Path, resolution: Option<(u32, u32)>) -> Result<Scene> {
    let mut scene = Scene::load(locate_scene(scene))?;
    if let Some((w, h)) = resolution {
        scene.set_resolution(w, h)?;
    }
    for w in &scene.warnings {
        warn!("warning: {w}");
    }
    Ok(scene)
}
