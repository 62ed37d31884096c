//! zvidpt — Zero Variance Importance Sampling Driven Potential Tracing.
//!
//! A CPU renderer whose ray-tracing backend is chosen at run time and whose integrators are
//! generic over that backend. See `docs/cli.md` for the command line and `docs/scene-format.md` for the scene format.
// The only unsafe code lives in `accel::embree` (feature `embree`); everywhere else it is
// forbidden. `forbid` cannot be relaxed by a child module, hence `deny` when Embree is built.
#![cfg_attr(not(feature = "embree"), forbid(unsafe_code))]
#![cfg_attr(feature = "embree", deny(unsafe_code))]
#![deny(unsafe_op_in_unsafe_fn)]

pub mod accel;
pub mod batch;
pub mod cli;
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
