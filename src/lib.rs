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
// The only unsafe code lives in `accel::embree` (feature `embree`); everywhere else it is
// forbidden. `forbid` cannot be relaxed by a child module, hence `deny` when Embree is built.
#![cfg_attr(not(feature = "embree"), forbid(unsafe_code))]
#![cfg_attr(feature = "embree", deny(unsafe_code))]
#![deny(unsafe_op_in_unsafe_fn)]

pub mod accel;
pub mod batch;
pub mod cli;
pub mod color;
pub mod converge;
pub mod error;
pub mod film;
pub mod fuzzing;
pub mod geometry;
pub mod integrator;
pub mod io;
pub mod learned_guide;
pub mod light;
pub mod material;
pub mod medium;
pub mod photon;
pub mod plot;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod stats;
pub mod texture;

pub use error::{Error, Result};

/// The crate version, written into every image's metadata.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
