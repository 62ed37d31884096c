//! Images: float RGB with optional per-pixel sample variance, EXR (with render metadata) and
//! PNG output written atomically, the error metrics of ALGORITHM.md §6, and how a render's
//! samples are shared among its pixels ([`rates`]).
mod atomic;
mod exr_io;
mod metrics;
mod partial;
mod passes;
mod png_out;
pub mod rates;
mod sums;

pub use atomic::{
    Staged, check_destination, check_outputs, check_writable, commit, path_key, remove_pending_files, same_file, stage,
    write_atomically,
};
pub use exr_io::{read_exr, read_exr_from, read_exr_with, stage_exr, stage_exr_with, write_exr, write_exr_to};
pub use metrics::{
    Metrics, TRIM_FRACTION, error_map_png, mean_image, metrics, metrics_of_rows, reference_noise, split_by_brightness,
    trimmed,
};
pub use partial::{PartialHeader, parse_partial, read_partial, read_partial_header, stage_partial, stage_sums};
pub use passes::{PriorSamples, mean_and_variance, mean_variance};
pub use png_out::write_rgb8 as write_rgb8_png;
pub use png_out::{stage_png, to_srgb8, write_png};
pub use sums::{Partial, PixelSums};
pub(crate) use sums::{add_fixed, finish_counted, finish_pixel, to_fixed};

/// Most pixels an image may have, rendered or read: 2^26 (e.g. 8192 × 8192). A render peaks
/// at about 114 bytes per pixel (`path`) and 256 (`zvidpt`, training passes combined; 128-bit
/// exact sums), measured between 1024×768 and 2048×1536 (docs/cli.md, "Errors and limits"): 7.7
/// and 17 GB at the limit, within this machine's 24 GiB.
pub const MAX_PIXELS: u64 = 1 << 26;

/// A float RGB image, row-major from the top-left.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// Pixel values (mean radiance of the pixel's samples).
    pub pixels: Vec<[f32; 3]>,
    /// Unbiased sample variance of one sample, per pixel and channel, when known.
    pub variance: Option<Vec<[f32; 3]>>,
    /// Samples per pixel behind `pixels` (0 when unknown, e.g. read from a foreign EXR).
    pub spp: u32,
}

impl Image {
    /// Mean over pixels, per channel.
    #[must_use]
    pub fn mean(&self) -> [f64; 3] {
        let mut s = [0.0f64; 3];
        for p in &self.pixels {
            for c in 0..3 {
                s[c] += p[c] as f64;
            }
        }
        s.map(|x| x / self.pixels.len().max(1) as f64)
    }
}

/// Render facts written into an image's metadata.
#[derive(Clone, Debug, Default)]
pub struct Metadata {
    pub entries: Vec<(String, String)>,
}

impl Metadata {
    pub fn push(&mut self, key: &str, value: impl ToString) {
        self.entries.push((key.to_string(), value.to_string()));
    }

    #[must_use]
    pub fn get(&self, key: &str) -> Option<&str> {
        self.entries.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }
}
