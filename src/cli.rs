//! The command line: `zvidpt render`, `zvidpt diff`.
use crate::accel::{Accel, BackendKind, WithAccel, with_backend};
use crate::film::{self, Image, Metadata};
use crate::integrator::{
    Estimator, GuideSettings, Jensen, LearnedSettings, LearnedZvidpt, MAX_SUBPIXELS, PathTracer, Roulette, Zvidpt,
};
use crate::photon::{GridShape, GuidePhotons, MAX_GUIDE_CELLS};
use crate::render::{RenderSettings, RenderStats, render};
use crate::scene::{LightSampling, Scene};
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
}

#[derive(Debug, Args)]
pub struct ReferenceArgs {
    /// Scene file, or a folder holding `scene.toml`.
    #[arg(default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Samples per pixel.
    #[arg(long, default_value_t = 4096)]
    pub spp: u32,
    /// Output EXR (with a PNG beside it).
    #[arg(short, long, default_value = "reference.exr")]
    pub output: PathBuf,
    /// Random seed (kept apart from the seeds `converge` uses).
    #[arg(long, default_value_t = 1_000_003)]
    pub seed: u64,
    /// Render even if an up-to-date reference exists.
    #[arg(long)]
    pub force: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

#[derive(Debug, Args)]
pub struct ConvergeArgs {
    /// Scene file, or a folder holding `scene.toml`.
    #[arg(default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Integrators to compare, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "path,jensen,zvidpt-collision,zvidpt-terminal")]
    pub integrators: Vec<IntegratorKind>,
    /// Samples per pixel to measure at, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16,32,64,100")]
    pub spp: Vec<u32>,
    /// Independent runs (seeds) per integrator and spp.
    #[arg(long, default_value_t = 4)]
    pub runs: u32,
    /// Reference EXR (see `zvidpt reference`).
    #[arg(long)]
    pub reference: PathBuf,
    /// Output folder for runs.csv and converge.csv.
    #[arg(short, long, default_value = "converge")]
    pub output: PathBuf,
    /// First seed; run r uses seed + r.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Instead of the spp sweep: the seconds each integrator needs to reach this MSE (spp
    /// doubled from 1, then log–log interpolation), mean ± s.e. over the runs.
    #[arg(long)]
    pub time_to_mse: Option<f64>,
    /// Also render every integrator for this many seconds and write DIR/equal_time.png, the
    /// images side by side with the spp each reached and its MSE.
    #[arg(long)]
    pub equal_time: Option<f64>,
    /// Largest spp tried by --time-to-mse.
    #[arg(long, default_value_t = 65536)]
    pub max_spp: u32,
    #[command(flatten)]
    pub photon: PhotonArgs,
}

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// An EXR written by zvidpt (or any RGB EXR).
    pub image: PathBuf,
}

/// Light-transport algorithm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
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

/// On or off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Switch {
    On,
    Off,
}

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file, or a folder holding `scene.toml`.
    #[arg(default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Output EXR (linear float RGB, per-pixel variance, render metadata).
    #[arg(short, long, default_value = "render.exr")]
    pub output: PathBuf,
    /// Output PNG (sRGB). Default: the EXR's path with a .png extension.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Do not write a PNG.
    #[arg(long, conflicts_with = "png")]
    pub no_png: bool,
    /// PNG exposure in stops (pixel values are scaled by 2^EV before sRGB encoding).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Samples per pixel [default: 64, or unlimited when --time is given].
    #[arg(long)]
    pub spp: Option<u32>,
    /// Time budget in seconds: render whole passes until it is used up.
    #[arg(long, allow_negative_numbers = true)]
    pub time: Option<f64>,
    /// Light-transport algorithm (`zvidpt` by default: it beats the path tracer at equal time
    /// on every shipped scene; README, "Results").
    #[arg(long, value_enum, default_value_t = IntegratorKind::Zvidpt)]
    pub integrator: IntegratorKind,
    #[command(flatten)]
    pub photon: PhotonArgs,
    /// Random seed; the same seed, scene and flags give the same image bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Tile side in pixels (does not change the image).
    #[arg(long, default_value_t = 32)]
    pub tile_size: u32,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
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

/// Estimator options: light sampling (every integrator), then the photon map and guides of
/// the guided integrators (jensen, zvidpt-*).
#[derive(Clone, Debug, Args)]
pub struct PhotonArgs {
    /// How next event estimation picks a point on an emitter: a uniform point on its area
    /// (ALGORITHM.md §3) or a uniform direction in its solid angle (bounded weights beside a
    /// light; the estimate is the same, the noise lower).
    #[arg(long, value_enum, default_value_t = LightSampling::SolidAngle)]
    pub light_sampling: LightSampling,
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
    /// (1 + 1/ε_L)·ρ. ALGORITHM.md §2 suggests 0.1; 1 measured best (see README).
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
            train_spp: None,
            guide_mix: 0.75,
            learn_mix: Switch::On,
            guide_carry: 0.25,
            window: 5.0,
            max_split: 8,
            roulette_cv: Switch::On,
            learned_guide: Switch::Off,
        }
    }

    /// The learned integrator's settings (`zvidpt`, or `jensen --learned-guide on`).
    fn learned(&self, roulette: Roulette) -> LearnedSettings {
        LearnedSettings {
            photons: self.photons,
            knn: self.knn,
            split_samples: self.split_samples,
            guide_mix: self.guide_mix,
            learn_mix: self.learn_mix == Switch::On,
            guide_carry: self.guide_carry,
            roulette,
            window: self.window,
            max_split: self.max_split,
            control_variate: self.roulette_cv == Switch::On && roulette != Roulette::Albedo,
            train_spp: self.train_spp,
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
        if !(self.guide_mix >= 0.0 && self.guide_mix < 1.0) {
            return Err(Error::InvalidOption(
                "--guide-mix must lie in [0, 1) (cosine sampling keeps every direction)".into(),
            ));
        }
        if !(self.guide_carry.is_finite() && (0.0..=1.0).contains(&self.guide_carry)) {
            return Err(Error::InvalidOption("--guide-carry must lie in [0, 1]".into()));
        }
        if !(self.window.is_finite() && self.window >= 1.0) {
            return Err(Error::InvalidOption("--window must be a number of at least 1".into()));
        }
        if !(1..=64).contains(&self.max_split) {
            return Err(Error::InvalidOption("--max-split must lie in 1..=64".into()));
        }
        Ok(())
    }

    /// Metadata describing the options that shaped `integrator`'s image.
    fn describe(&self, integrator: IntegratorKind, meta: &mut Metadata) {
        meta.push("light_sampling", flag_name(self.light_sampling));
        if integrator == IntegratorKind::Path {
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
        if integrator == IntegratorKind::Zvidpt || self.learned_guide == Switch::On {
            meta.push("roulette", flag_name(self.roulette));
            meta.push("split_samples", self.split_samples);
            meta.push("guide_mix", self.guide_mix);
            meta.push("learn_mix", flag_name(self.learn_mix));
            meta.push("guide_carry", self.guide_carry);
            meta.push("window", self.window);
            meta.push("max_split", self.max_split);
            meta.push("roulette_cv", flag_name(self.roulette_cv));
        }
    }
}

#[derive(Debug, Args)]
pub struct DiffArgs {
    /// The image to measure.
    pub image: PathBuf,
    /// The reference image.
    pub reference: PathBuf,
    /// Write a false-colour PNG of per-pixel relative squared error.
    #[arg(long)]
    pub error_map: Option<PathBuf>,
    /// Also print the error of N horizontal bands of rows (top first), each with its share of
    /// the whole image's squared error.
    #[arg(long, value_name = "N")]
    pub bands: Option<u32>,
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

/// Renders with whichever backend the user chose: the one dynamic choice, at the top.
struct RenderJob<'a> {
    scene: &'a Scene,
    integrator: IntegratorKind,
    photon: &'a PhotonArgs,
    settings: &'a RenderSettings,
}

impl WithAccel for RenderJob<'_> {
    type Output = Result<(Image, RenderStats, &'static str)>;
    fn run<A: Accel>(self, accel: &A) -> Self::Output {
        let a = self.photon;
        let guide = a.settings();
        let zvidpt = |estimator| Zvidpt {
            pixel_grid: a.pixel_grid,
            q_max: a.q_max,
            q_kappa: a.q_kappa,
            ..Zvidpt::new(estimator, guide.clone())
        };
        let (scene, s) = (self.scene, self.settings);
        let (image, stats) = match self.integrator {
            IntegratorKind::Path => render(scene, accel, &mut PathTracer::default(), s)?,
            IntegratorKind::Jensen if a.learned_guide == Switch::On => {
                render(scene, accel, &mut LearnedZvidpt::new(a.learned(Roulette::Albedo)), s)?
            }
            IntegratorKind::Jensen => render(scene, accel, &mut Jensen::new(guide.clone()), s)?,
            IntegratorKind::Zvidpt => render(scene, accel, &mut LearnedZvidpt::new(a.learned(a.roulette)), s)?,
            IntegratorKind::ZvidptTerminal => render(scene, accel, &mut zvidpt(Estimator::Terminal), s)?,
            IntegratorKind::ZvidptCollision => render(scene, accel, &mut zvidpt(Estimator::Collision), s)?,
        };
        Ok((image, stats, accel.name()))
    }
}

/// Renders `scene` with `integrator` on `backend`: the one place below the command line
/// where the backend and the integrator are chosen. Returns the backend's name too.
pub fn render_scene(
    scene: &Scene,
    integrator: IntegratorKind,
    photon: &PhotonArgs,
    backend: BackendKind,
    settings: &RenderSettings,
) -> Result<(Image, RenderStats, &'static str)> {
    with_backend(backend, scene, RenderJob { scene, integrator, photon, settings })?
}

/// Checks a command's options alone (no file is touched): what `run` checks first.
pub fn validate(cli: &Cli) -> Result<()> {
    match &cli.command {
        Command::Render(a) => check_render_options(a),
        Command::Converge(a) => check_converge_options(a),
        Command::Reference(a) => check_reference_options(a),
        Command::Diff(_) | Command::Info(_) => Ok(()),
    }
}

fn check_render_options(args: &RenderArgs) -> Result<()> {
    if args.spp == Some(0) {
        return Err(Error::InvalidOption("--spp must be at least 1".into()));
    }
    if !args.exposure.is_finite() {
        return Err(Error::InvalidOption("--exposure must be finite".into()));
    }
    if let Some(t) = args.time
        && !(t.is_finite() && t > 0.0)
    {
        return Err(Error::InvalidOption(format!("--time must be a positive number of seconds, got {t}")));
    }
    if args.machine.threads == Some(0) {
        return Err(Error::InvalidOption("--threads must be at least 1".into()));
    }
    args.photon.check()
}

fn check_reference_options(args: &ReferenceArgs) -> Result<()> {
    if args.spp == 0 {
        return Err(Error::InvalidOption("--spp must be at least 1".into()));
    }
    Ok(())
}

fn check_converge_options(args: &ConvergeArgs) -> Result<()> {
    if args.runs == 0 || args.spp.is_empty() || args.spp.contains(&0) || args.integrators.is_empty() {
        return Err(Error::InvalidOption(
            "--runs, --spp and --integrators need at least one positive value each".into(),
        ));
    }
    if args.max_spp == 0 {
        return Err(Error::InvalidOption("--max-spp must be at least 1".into()));
    }
    if args.seed.checked_add(u64::from(args.runs) - 1).is_none() {
        return Err(Error::InvalidOption(format!(
            "--seed {} with --runs {}: run r uses seed + r, which would pass the largest seed",
            args.seed, args.runs
        )));
    }
    args.photon.check()?;
    Ok(())
}

/// Renders as the command line says; returns what it measured.
pub fn run_render(args: &RenderArgs) -> Result<RenderStats> {
    check_render_options(args)?;
    let png = (!args.no_png).then(|| args.png.clone().unwrap_or_else(|| args.output.with_extension("png")));
    // Fail before rendering if an output cannot be written or would replace what it must not.
    if let Some(p) = &png {
        if args.png.is_none() && film::same_file(p, &args.output) {
            return Err(Error::InvalidOption(format!(
                "-o {} names the EXR, and the PNG beside it would be the same file: use -o NAME.exr, --png PATH or --no-png",
                args.output.display()
            )));
        }
        if args.png.is_none() {
            check_derived_png(p)?;
        }
    }
    args.machine.backend.check_available()?;
    let mut scene = Scene::load(locate_scene(&args.scene))?;
    if let Some((w, h)) = args.machine.resolution {
        scene.set_resolution(w, h)?;
    }
    let mut outputs = vec![("EXR", args.output.as_path())];
    if let Some(p) = &png {
        outputs.push(("PNG", p.as_path()));
    }
    let inputs: Vec<(&str, &Path)> = scene.sources.iter().map(|s| ("scene's file", s.as_path())).collect();
    film::check_outputs(&outputs, &inputs)?;
    // Warnings only once every option is known to be valid, so a failed run prints one line.
    for w in &scene.warnings {
        warn!("warning: {w}");
    }
    let settings = RenderSettings {
        spp: args.spp.or(if args.time.is_some() { None } else { Some(64) }),
        time_limit: args.time,
        seed: args.seed,
        threads: args.machine.threads,
        tile_size: args.tile_size,
        progress: !args.quiet,
        light_sampling: args.photon.light_sampling,
    };
    let integrator = args.integrator;
    let (image, stats, backend) = render_scene(&scene, integrator, &args.photon, args.machine.backend, &settings)?;

    let mut meta = Metadata::default();
    meta.push("scene", scene.path.display());
    meta.push("integrator", flag_name(integrator));
    meta.push("backend", backend);
    meta.push("seed", args.seed);
    meta.push("seconds", format!("{:.3}", stats.seconds));
    meta.push("prepass_seconds", format!("{:.3}", stats.prepass_seconds));
    if let Some(p) = &stats.prepass {
        meta.push("prepass", p);
    }
    args.photon.describe(integrator, &mut meta);
    meta.push("scene_hash", format!("{:016x}", scene.content_hash()));
    meta.push("threads", stats.threads);
    if stats.prior_spp > 0 {
        // The image averages these pre-pass (training) samples with the `spp` final ones.
        meta.push("final_spp", stats.spp);
        meta.push("training_spp_in_image", stats.prior_spp);
    }
    meta.push("rays", stats.rays);
    meta.push("version", crate::VERSION);
    // Both images or neither.
    let mut staged = vec![film::stage_exr(&args.output, &image, &meta)?];
    if let Some(p) = &png {
        staged.push(film::stage_png(p, &image, args.exposure)?);
    }
    film::commit(staged)?;
    if stats.non_finite > 0 {
        warn!("warning: {} samples were NaN or infinite and were dropped", stats.non_finite);
    }
    // The images are written: a closed or full standard output no longer fails the command.
    let summary = || -> Result<()> {
        if let Some(p) = &stats.prepass {
            out!("pre-pass: {p}");
        }
        out!(
            "{} {}x{}, {} spp{}, {:.2} s{}, {:.2} M samples/s, {:.2} M rays/s ({}, {}, {} threads) -> {}{}",
            scene.name,
            image.width,
            image.height,
            stats.spp,
            if stats.prior_spp > 0 {
                format!(" (+{} training spp in the image)", stats.prior_spp)
            } else {
                String::new()
            },
            stats.seconds,
            if stats.prepass.is_some() { format!(" (pre-pass {:.2} s)", stats.prepass_seconds) } else { String::new() },
            stats.samples_per_second() / 1e6,
            stats.rays_per_second() / 1e6,
            meta.get("integrator").unwrap_or("?"),
            backend,
            stats.threads,
            args.output.display(),
            png.as_ref().map_or(String::new(), |p| format!(", {}", p.display())),
        );
        Ok(())
    };
    if let Err(e) = summary()
        && !e.is_broken_pipe()
    {
        warn!("warning: the images are written, but the summary could not be printed: {e}");
    }
    Ok(stats)
}

/// The PNG written beside the EXR by default (a path the user did not type) may replace only
/// an earlier PNG, never another kind of file.
fn check_derived_png(path: &Path) -> Result<()> {
    use std::io::Read as _;
    if !path.is_file() {
        return Ok(());
    }
    let mut magic = [0u8; 8];
    let is_png =
        std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)).is_ok() && magic == *b"\x89PNG\r\n\x1a\n";
    if is_png {
        Ok(())
    } else {
        Err(Error::Output {
            path: path.to_path_buf(),
            message: "exists and is not a PNG image; not replacing it (name the PNG with --png, or --no-png)".into(),
        })
    }
}

fn run_diff(args: &DiffArgs) -> Result<()> {
    let (image, _) = film::read_exr(&args.image)?;
    let (reference, _) = film::read_exr(&args.reference)?;
    if let Some(p) = &args.error_map {
        film::check_outputs(&[("error map", p)], &[("image", &args.image), ("reference", &args.reference)])?;
    }
    let m = film::metrics(&image, &reference)?;
    if let Some(p) = &args.error_map {
        film::error_map_png(p, &image, &reference)?;
    }
    out!("MSE {:.6e}  relMSE {:.6e}", m.mse, m.rel_mse);
    for (what, img, path) in [("image", &image, &args.image), ("reference", &reference, &args.reference)] {
        let bad = non_finite_values(img);
        if bad > 0 {
            warn!("note: the {what} {} has {bad} NaN or infinite pixel values: the errors are NaN", path.display());
        }
    }
    if let Some(n) = args.bands {
        if n == 0 || n > image.height {
            return Err(Error::InvalidOption(format!("--bands must lie in 1..={} (the image's rows)", image.height)));
        }
        for k in 0..n {
            let rows = k * image.height / n..(k + 1) * image.height / n;
            let b = film::metrics_of_rows(&image, &reference, rows.clone())?;
            let share =
                b.mse * f64::from(rows.end - rows.start) / (m.mse * f64::from(image.height)).max(f64::MIN_POSITIVE);
            out!(
                "rows {:>4}..{:<4} MSE {:.4e}  relMSE {:.4e}  share {:5.1}%",
                rows.start,
                rows.end,
                b.mse,
                b.rel_mse,
                100.0 * share
            );
        }
    }
    Ok(())
}

/// Pixel values (per channel) that are NaN or infinite.
fn non_finite_values(image: &Image) -> usize {
    image.pixels.iter().flatten().filter(|x| !x.is_finite()).count()
}

fn run_info(args: &InfoArgs) -> Result<()> {
    let (image, meta) = film::read_exr(&args.image)?;
    let m = image.mean();
    out_part!(
        "{}: {}x{}, mean RGB ({:.5}, {:.5}, {:.5})",
        args.image.display(),
        image.width,
        image.height,
        m[0],
        m[1],
        m[2]
    );
    // Standard error of the image mean from the per-pixel sample variances.
    match (&image.variance, image.spp) {
        (Some(v), spp) if spp > 1 => {
            let n = v.len() as f64;
            let se = [0, 1, 2].map(|c| (v.iter().map(|p| p[c] as f64).sum::<f64>() / spp as f64).sqrt() / n);
            let mean_var = [0, 1, 2].map(|c| v.iter().map(|p| p[c] as f64).sum::<f64>() / n);
            out!(" ± ({:.5}, {:.5}, {:.5}) (1 s.e.)", se[0], se[1], se[2]);
            out!("  mean per-sample variance ({:.4e}, {:.4e}, {:.4e})", mean_var[0], mean_var[1], mean_var[2]);
        }
        _ => out!(),
    }
    let bad = non_finite_values(&image);
    if bad > 0 {
        out!("  note: {bad} pixel values are NaN or infinite (so is the mean)");
    }
    // Attribute text comes from the file: control characters are shown escaped.
    let printable = |s: &str| -> String {
        s.chars().map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() }).collect()
    };
    for (k, v) in &meta.entries {
        out!("  {} = {}", printable(k), printable(v));
    }
    Ok(())
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

fn run_reference(args: &ReferenceArgs) -> Result<()> {
    check_reference_options(args)?;
    args.machine.backend.check_available()?;
    let scene = load_at(&args.scene, args.machine.resolution)?;
    let hash = format!("{:016x}", scene.content_hash());
    let up_to_date = !args.force
        && args.output.is_file()
        && film::read_exr(&args.output).is_ok_and(|(image, meta)| {
            meta.get("scene_hash") == Some(hash.as_str())
                && image.spp == args.spp
                && meta.get("integrator") == Some("path")
                && image.variance.is_some()
        });
    if up_to_date {
        out!("{}: up to date ({} spp, scene {hash}); --force renders it again", args.output.display(), args.spp);
        return Ok(());
    }
    let png = args.output.with_extension("png");
    if film::same_file(&png, &args.output) {
        return Err(Error::InvalidOption(format!(
            "-o {} names the EXR, and the PNG beside it would be the same file: use -o NAME.exr",
            args.output.display()
        )));
    }
    check_derived_png(&png)?;
    let inputs: Vec<(&str, &Path)> = scene.sources.iter().map(|s| ("scene's file", s.as_path())).collect();
    film::check_outputs(&[("EXR", &args.output), ("PNG", &png)], &inputs)?;
    let settings = RenderSettings {
        spp: Some(args.spp),
        time_limit: None,
        seed: args.seed,
        threads: args.machine.threads,
        tile_size: 32,
        progress: !args.quiet,
        light_sampling: LightSampling::default(),
    };
    let photon = PhotonArgs::default_for_path();
    let (image, stats, backend) = render_scene(&scene, IntegratorKind::Path, &photon, args.machine.backend, &settings)?;
    let mut meta = Metadata::default();
    meta.push("scene", scene.path.display());
    meta.push("scene_hash", &hash);
    meta.push("integrator", "path");
    photon.describe(IntegratorKind::Path, &mut meta);
    meta.push("backend", backend);
    meta.push("seed", args.seed);
    meta.push("seconds", format!("{:.3}", stats.seconds));
    meta.push("threads", stats.threads);
    meta.push("version", crate::VERSION);
    film::commit(vec![film::stage_exr(&args.output, &image, &meta)?, film::stage_png(&png, &image, 0.0)?])?;
    out!(
        "{}: reference {}x{}, {} spp, {:.1} s ({}, {} threads)",
        args.output.display(),
        image.width,
        image.height,
        stats.spp,
        stats.seconds,
        backend,
        stats.threads
    );
    Ok(())
}

fn run_converge(args: &ConvergeArgs) -> Result<()> {
    check_converge_options(args)?;
    args.machine.backend.check_available()?;
    // The output folder is checked before any render, not after the last.
    if args.output.exists() && !args.output.is_dir() {
        return Err(Error::Output {
            path: args.output.clone(),
            message: "is not a folder (converge writes its tables and plots into the folder -o names)".into(),
        });
    }
    std::fs::create_dir_all(&args.output).map_err(|e| Error::io(&args.output, e))?;
    film::check_writable(&args.output.join("runs.csv"))?;
    let scene = load_at(&args.scene, args.machine.resolution)?;
    let (reference, ref_meta) = film::read_exr(&args.reference)?;
    if (reference.width, reference.height) != (scene.camera.width, scene.camera.height) {
        return Err(Error::InvalidOption(format!(
            "the reference is {}x{} but the scene renders at {}x{} (use --resolution)",
            reference.width, reference.height, scene.camera.width, scene.camera.height
        )));
    }
    let hash = format!("{:016x}", scene.content_hash());
    if ref_meta.get("scene_hash").is_some_and(|h| h != hash) {
        return Err(Error::InvalidOption(format!("{} was rendered from a different scene", args.reference.display())));
    }
    if let Some(seconds) = args.equal_time {
        equal_time_image(args, &scene, &reference, seconds)?;
    }
    if let Some(target) = args.time_to_mse {
        return run_time_to_mse(args, &scene, &reference, target);
    }
    let mut runs = Vec::new();
    for &integrator in &args.integrators {
        let name = flag_name(integrator);
        for &spp in &args.spp {
            for r in 0..args.runs {
                let seed = args.seed + u64::from(r);
                let (stats, metrics) = measure(args, &scene, &reference, integrator, spp, seed)?;
                warn!(
                    "{name} {spp} spp seed {seed}: MSE {:.4e} relMSE {:.4e} in {:.2} s",
                    metrics.mse, metrics.rel_mse, stats.seconds
                );
                runs.push(crate::converge::Run {
                    integrator: name.clone(),
                    spp,
                    seed,
                    seconds: stats.seconds,
                    prepass_seconds: stats.prepass_seconds,
                    metrics,
                });
            }
        }
    }
    let summary = crate::converge::summarise(&runs);
    crate::converge::write_csv(&args.output, &runs, &summary)?;
    crate::converge::plot(&args.output, &scene.name, &summary)?;
    out!(
        "{:<18} {:>5} {:>12} {:>10} {:>12} {:>9} {:>9}",
        "integrator",
        "spp",
        "MSE",
        "± s.e.",
        "relMSE",
        "seconds",
        "pre-pass"
    );
    for s in &summary {
        out!(
            "{:<18} {:>5} {:>12.4e} {:>10.2e} {:>12.4e} {:>9.3} {:>9.3}",
            s.integrator,
            s.spp,
            s.mse.0,
            s.mse.1,
            s.rel_mse.0,
            s.seconds.0,
            s.prepass_seconds
        );
    }
    out!("-> {} (runs.csv, converge.csv, mse_vs_spp.png/svg, mse_vs_seconds.png/svg)", args.output.display());
    Ok(())
}

impl ConvergeArgs {
    /// The render settings of one convergence render: a sample count or a time budget.
    fn settings(&self, spp: Option<u32>, time_limit: Option<f64>, seed: u64) -> RenderSettings {
        RenderSettings {
            spp,
            time_limit,
            seed,
            threads: self.machine.threads,
            tile_size: 32,
            progress: false,
            light_sampling: self.photon.light_sampling,
        }
    }
}

/// One convergence point: `integrator` at `spp` with `seed`, and its error against `reference`.
fn measure(
    args: &ConvergeArgs,
    scene: &Scene,
    reference: &Image,
    integrator: IntegratorKind,
    spp: u32,
    seed: u64,
) -> Result<(RenderStats, crate::film::Metrics)> {
    let settings = args.settings(Some(spp), None, seed);
    let (image, stats, _) = render_scene(scene, integrator, &args.photon, args.machine.backend, &settings)?;
    let metrics = film::metrics(&image, reference)?;
    Ok((stats, metrics))
}

fn run_time_to_mse(args: &ConvergeArgs, scene: &Scene, reference: &Image, target: f64) -> Result<()> {
    if !(target.is_finite() && target > 0.0) {
        return Err(Error::InvalidOption("--time-to-mse must be a positive MSE".into()));
    }
    let mut rows = Vec::new();
    out!(
        "{:<18} {:>10} {:>10} {:>9}  (target MSE {target:.4e}, {} runs)",
        "integrator",
        "seconds",
        "± s.e.",
        "spp",
        args.runs
    );
    for &integrator in &args.integrators {
        let name = flag_name(integrator);
        let mut seconds = Vec::new();
        let mut spps = Vec::new();
        for r in 0..args.runs {
            let seed = args.seed + u64::from(r);
            let t = crate::converge::time_to_mse(
                |spp| {
                    let (stats, m) = measure(args, scene, reference, integrator, spp, seed)?;
                    warn!("{name} seed {seed} {spp} spp: MSE {:.4e} in {:.2} s", m.mse, stats.seconds);
                    Ok((stats.seconds, m.mse))
                },
                target,
                args.max_spp,
            )?;
            if !t.reached {
                warn!("warning: {name} seed {seed} did not reach the target within {} spp", args.max_spp);
            }
            seconds.push(t.seconds);
            spps.push(t.spp as f64);
            rows.push((name.clone(), seed, t));
        }
        let (m, se) = crate::converge::mean_and_se(&seconds);
        out!("{:<18} {:>10.3} {:>10.3} {:>9.0}", name, m, se, crate::converge::mean_and_se(&spps).0);
    }
    std::fs::create_dir_all(&args.output).map_err(|e| Error::io(&args.output, e))?;
    let path = args.output.join("time_to_mse.csv");
    film::write_atomically(&path, |w| {
        use std::io::Write;
        let io = |e| Error::io(&path, e);
        writeln!(w, "integrator,seed,target_mse,seconds,spp,reached").map_err(io)?;
        for (name, seed, t) in &rows {
            writeln!(w, "{name},{seed},{target:e},{:.4},{},{}", t.seconds, t.spp, t.reached).map_err(io)?;
        }
        Ok(())
    })?;
    out!("-> {}", path.display());
    Ok(())
}

fn equal_time_image(args: &ConvergeArgs, scene: &Scene, reference: &Image, seconds: f64) -> Result<()> {
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(Error::InvalidOption("--equal-time must be a positive number of seconds".into()));
    }
    let mut shots = Vec::new();
    for &integrator in &args.integrators {
        let name = flag_name(integrator);
        let settings = args.settings(None, Some(seconds), args.seed);
        let (image, stats, _) = render_scene(scene, integrator, &args.photon, args.machine.backend, &settings)?;
        let m = film::metrics(&image, reference)?;
        out!("equal time {seconds} s: {name} {} spp, MSE {:.4e}, relMSE {:.4e}", stats.spp, m.mse, m.rel_mse);
        shots.push((format!("{name}\n{} spp, MSE {:.2e}", stats.spp, m.mse), image));
    }
    std::fs::create_dir_all(&args.output).map_err(|e| Error::io(&args.output, e))?;
    let path = args.output.join("equal_time.png");
    let refs: Vec<(String, &Image)> = shots.iter().map(|(c, i)| (c.clone(), i)).collect();
    crate::plot::side_by_side(&path, &refs)?;
    out!("-> {}", path.display());
    Ok(())
}
