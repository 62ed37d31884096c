use super::{Image, Metadata, Staged, commit, stage};
use crate::{Error, Result};
use exr::prelude::*;
use std::path::Path;

/// Channel names: RGB, and the per-pixel sample variance as a `variance` layer when present.
const RGB: [&str; 3] = ["R", "G", "B"];
const VARIANCE: [&str; 3] = ["variance.R", "variance.G", "variance.B"];
/// Most channels an EXR read here may have (ours have 6; AOV files a few dozen).
const MAX_CHANNELS: u64 = 64;

/// Writes linear float RGB (and variance, if any), with `meta` as string header attributes
/// named `zvidpt.<key>`.
pub fn write_exr(path: &Path, image: &Image, meta: &Metadata) -> Result<()> {
    commit(vec![stage_exr(path, image, meta)?])
}

/// [`write_exr`] to a temporary file, for [`super::commit`] with other outputs.
pub fn stage_exr(path: &Path, image: &Image, meta: &Metadata) -> Result<Staged> {
    stage_exr_with(path, image, meta, Vec::new())
}

/// [`stage_exr`] with extra channels (name, one value per pixel): AOV layers such as
/// `albedo.R` or `Z`.
pub fn stage_exr_with(path: &Path, image: &Image, meta: &Metadata, extra: Vec<(String, Vec<f32>)>) -> Result<Staged> {
    stage(path, |w| encode(w, path, image, meta, extra))
}

/// [`write_exr`] into `w` (any seekable writer; `path` names it in errors), without staging.
pub fn write_exr_to(w: impl std::io::Write + std::io::Seek, path: &Path, image: &Image, meta: &Metadata) -> Result<()> {
    encode(w, path, image, meta, Vec::new())
}

/// The one EXR encoder: `extra` channels, RGB, the variance layer when present, and `meta`
/// as `zvidpt.<key>` text attributes.
fn encode(
    w: impl std::io::Write + std::io::Seek,
    path: &Path,
    image: &Image,
    meta: &Metadata,
    extra: Vec<(String, Vec<f32>)>,
) -> Result<()> {
    let size = (image.width as usize, image.height as usize);
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for (name, values) in extra {
        if values.len() != image.pixels.len() {
            return Err(Error::Image {
                path: path.to_path_buf(),
                message: format!("channel {name} has the wrong size"),
            });
        }
        channels.push(AnyChannel::new(name.as_str(), FlatSamples::F32(values)));
    }
    for c in 0..3 {
        channels.push(AnyChannel::new(RGB[c], FlatSamples::F32(image.pixels.iter().map(|p| p[c]).collect())));
        if let Some(v) = &image.variance {
            channels.push(AnyChannel::new(VARIANCE[c], FlatSamples::F32(v.iter().map(|p| p[c]).collect())));
        }
    }
    let mut attributes = LayerAttributes::named("");
    attributes.layer_name = None;
    for (k, v) in &meta.entries {
        attributes.other.insert(utf8_text(&format!("zvidpt.{k}")), AttributeValue::Text(utf8_text(v)));
    }
    attributes.other.insert(utf8_text("zvidpt.spp"), AttributeValue::Text(utf8_text(&image.spp.to_string())));
    let layer = Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, AnyChannels::sort(channels.into()));
    exr::image::Image::from_layer(layer)
        .write()
        .to_buffered(w)
        .map_err(|e| Error::Image { path: path.to_path_buf(), message: e.to_string() })
}

/// An EXR text attribute holding `s` as UTF-8 bytes (OpenEXR's text is a byte string; the
/// `exr` crate's `Text::from` takes Latin-1 alone and panics on anything else, such as a path
/// in Japanese).
fn utf8_text(s: &str) -> Text {
    Text::from_slice_unchecked(s.as_bytes())
}

/// An EXR text attribute as a string: UTF-8 where it is (ours always), Latin-1 otherwise.
fn text_string(t: &Text) -> String {
    String::from_utf8(t.bytes().to_vec()).unwrap_or_else(|_| t.bytes().iter().map(|&b| char::from(b)).collect())
}

/// Reads an EXR's R, G, B (and variance layer, if present) and its `zvidpt.*` metadata.
pub fn read_exr(path: &Path) -> Result<(Image, Metadata)> {
    let file = crate::io::open_regular(path, "EXR image")?;
    read_exr_from(std::io::BufReader::new(file), path)
}

/// A channel's values at full resolution, row-major, if the file has it.
pub type Channel = Option<Vec<f32>>;

/// [`read_exr`], also returning the channels named in `extra` (e.g. `albedo.R`) where the
/// file has them at full resolution.
pub fn read_exr_with(path: &Path, extra: &[&str]) -> Result<(Image, Metadata, Vec<Channel>)> {
    let file = crate::io::open_regular(path, "EXR image")?;
    read_exr_channels(std::io::BufReader::new(file), path, extra)
}

/// [`read_exr`] from any seekable reader (`path` names it in errors).
pub fn read_exr_from(reader: impl std::io::Read + std::io::Seek, path: &Path) -> Result<(Image, Metadata)> {
    read_exr_channels(reader, path, &[]).map(|(image, meta, _)| (image, meta))
}

fn read_exr_channels(
    mut reader: impl std::io::Read + std::io::Seek,
    path: &Path,
    extra: &[&str],
) -> Result<(Image, Metadata, Vec<Channel>)> {
    let err = |message: String| Error::Image { path: path.to_path_buf(), message };
    // The headers first: a file may claim any size, and the pixels are allocated from it.
    let headers = exr::meta::MetaData::read_from_buffered(&mut reader, false).map_err(|e| err(e.to_string()))?;
    for h in &headers.headers {
        let (w, hgt) = (h.layer_size.width() as u64, h.layer_size.height() as u64);
        let channels = h.channels.list.len() as u64;
        if w.saturating_mul(hgt) > super::MAX_PIXELS || channels > MAX_CHANNELS {
            return Err(err(format!(
                "claims {w}x{hgt} pixels in {channels} channels; this reader takes at most {} pixels and {MAX_CHANNELS} channels",
                super::MAX_PIXELS
            )));
        }
    }
    reader.seek(std::io::SeekFrom::Start(0)).map_err(|e| Error::io(path, e))?;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(reader)
        .map_err(|e| err(e.to_string()))?;
    let layer = &img.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let find = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .map(|c| c.sample_data.values_as_f32().collect::<Vec<f32>>())
            // A subsampled channel has fewer samples than pixels: not one of ours.
            .filter(|v| v.len() == w * h)
    };
    let planes: Vec<Vec<f32>> = RGB
        .iter()
        .map(|n| find(n).ok_or_else(|| err(format!("no full-resolution `{n}` channel"))))
        .collect::<Result<_>>()?;
    let pixels = (0..w * h).map(|i| [planes[0][i], planes[1][i], planes[2][i]]).collect();
    let variance = VARIANCE
        .iter()
        .map(|n| find(n))
        .collect::<Option<Vec<_>>>()
        .map(|v| (0..w * h).map(|i| [v[0][i], v[1][i], v[2][i]]).collect());
    let mut meta = Metadata::default();
    for (k, v) in &layer.attributes.other {
        if let (Some(key), AttributeValue::Text(t)) = (text_string(k).strip_prefix("zvidpt."), v) {
            meta.push(key, text_string(t));
        }
    }
    let spp = meta.get("spp").and_then(|s| s.parse().ok()).unwrap_or(0);
    let extra = extra.iter().map(|n| find(n)).collect();
    Ok((Image { width: w as u32, height: h as u32, pixels, variance, spp }, meta, extra))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Metadata text outside Latin-1 (a scene folder named in Japanese, a euro sign, an
    /// emoji) is written and read back as it was, not a panic after the render.
    #[test]
    fn metadata_round_trips_any_utf8() {
        let dir = std::env::temp_dir().join(format!("zvidpt-exr-utf8-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("日本€.exr");
        let image = Image { width: 2, height: 1, pixels: vec![[0.5; 3]; 2], variance: None, spp: 1 };
        let mut meta = Metadata::default();
        let values = [("scene", "/tmp/日本/scène€"), ("label", "🎥 latin-1: é"), ("empty", "")];
        for (k, v) in values {
            meta.push(k, v);
        }
        write_exr(&path, &image, &meta).unwrap();
        let (_, read) = read_exr(&path).unwrap();
        for (k, v) in values {
            assert_eq!(read.get(k), Some(v), "{:?}", read.entries);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
