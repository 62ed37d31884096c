//! zvidpt — Zero Variance Importance Sampling Driven Potential Tracing.
//!
//! A CPU renderer whose ray-tracing backend is chosen at run time and whose integrators are
//! generic over that backend. See `docs/cli.md` for the command line and `docs/scene-format.md` for the scene format.
//!
//! Rendering a scene from Rust: load it (TOML, Mitsuba 3 XML or pbrt-v4), build a backend over
//! its triangles, and render with an integrator.
//!
//! ```
//! use zvidpt::accel::BvhAccel;
//! use zvidpt::integrator::path::PathTracer;
//! use zvidpt::render::{RenderSettings, render};
//! use zvidpt::scene::Scene;
//!
//! let mut scene = Scene::load("scenes/cornell-paper/scene.toml")?;
//! scene.set_resolution(32, 24)?;
//! let accel = BvhAccel::build(&scene.triangles);
//! let settings = RenderSettings { spp: Some(4), seed: 1, ..RenderSettings::default() };
//! let (image, stats) = render(&scene, &accel, &mut PathTracer::default(), &settings)?;
//! let [r, g, b] = image.mean();
//! assert!(r > 0.0 && g > 0.0 && b > 0.0, "the lit box is not black");
//! assert_eq!(stats.spp, 4);
//! # Ok::<(), zvidpt::Error>(())
//! ```
// The only unsafe code lives in the two FFI modules, `accel::embree` (feature `embree`) and
// `denoise`'s Open Image Denoise loader, which allow it; every other module forbids it
// (`forbid` cannot be relaxed below, hence `deny` at the root).
#![deny(unsafe_code)]
#![deny(unsafe_op_in_unsafe_fn)]

pub mod accel;
#[forbid(unsafe_code)]
pub mod batch;
#[forbid(unsafe_code)]
pub mod cli;
#[forbid(unsafe_code)]
pub mod color;
#[forbid(unsafe_code)]
pub mod converge;
pub mod denoise;
#[forbid(unsafe_code)]
pub mod error;
#[forbid(unsafe_code)]
pub mod film;
#[forbid(unsafe_code)]
pub mod fuzzing;
#[forbid(unsafe_code)]
pub mod geometry;
#[forbid(unsafe_code)]
pub mod integrator;
#[forbid(unsafe_code)]
pub mod io;
#[forbid(unsafe_code)]
pub mod learned_guide;
#[forbid(unsafe_code)]
pub mod light;
#[forbid(unsafe_code)]
pub mod material;
#[forbid(unsafe_code)]
pub mod medium;
#[forbid(unsafe_code)]
pub mod photon;
#[forbid(unsafe_code)]
pub mod plot;
#[forbid(unsafe_code)]
pub mod render;
#[forbid(unsafe_code)]
pub mod sampler;
#[forbid(unsafe_code)]
pub mod scene;
#[forbid(unsafe_code)]
pub mod stats;
#[forbid(unsafe_code)]
pub mod texture;

pub use error::{Error, Result};

/// The crate version, written into every image's metadata.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
