//! Partial renders (`zvidpt render --samples A..B`): a sample range's exact per-pixel sums,
//! the pre-pass samples in the image, and the render's metadata, for `zvidpt merge`.
//!
//! Layout (little-endian): the magic `ZVIDPT-PARTIAL3\n`; the metadata as a `u32` byte count
//! and `key=value` lines; `width`, `height`, `first`, `spp`, `total_spp` as `u32`; per pixel
//! the sums of R, G, B and of their squares (`i128`, fixed point 2^-40) as zigzag LEB128
//! varints (about 40 bytes a pixel instead of 96: a checkpoint's time is its disk write); a
//! byte saying whether pre-pass samples follow, and if so their encoding; last, the CRC-32 of
//! every byte before it, so that a damaged file (a flipped bit, a cut) is refused, never
//! merged or resumed.
use super::{MAX_PIXELS, Metadata};
use super::{Partial, PixelSums, PriorSamples};
use crate::{Error, Result};
use std::io::Write;
use std::path::Path;

const MAGIC: &[u8; 16] = b"ZVIDPT-PARTIAL3\n";
/// The layout before the checksum: refused with a line saying so.
const MAGIC_WITHOUT_CHECKSUM: &[u8; 16] = b"ZVIDPT-PARTIAL2\n";

/// A writer that keeps the CRC-32 of everything written through it.
struct Checksummed<'w, W: Write> {
    inner: &'w mut W,
    crc: crc32fast::Hasher,
}

impl<W: Write> Write for Checksummed<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.crc.update(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}
/// Longest varint of an `i128` (128 bits in 7-bit groups).
const MAX_VARINT: usize = 19;

/// Appends `v` as a zigzag LEB128 varint to `out` at `at`; returns the new end.
fn put_varint(out: &mut [u8], mut at: usize, v: i128) -> usize {
    let mut z = ((v << 1) ^ (v >> 127)) as u128;
    loop {
        let byte = (z & 0x7f) as u8;
        z >>= 7;
        if z == 0 {
            out[at] = byte;
            return at + 1;
        }
        out[at] = byte | 0x80;
        at += 1;
    }
}

/// Reads a zigzag LEB128 varint (`None` when truncated or longer than an `i128`).
fn get_varint(b: &mut &[u8]) -> Option<i128> {
    let mut z: u128 = 0;
    let mut shift = 0;
    loop {
        let (&byte, rest) = b.split_first()?;
        *b = rest;
        // The 19th byte holds the last 2 bits and ends the number.
        if shift == 126 && byte > 3 {
            return None;
        }
        z |= u128::from(byte & 0x7f) << shift;
        if byte & 0x80 == 0 {
            return Some(((z >> 1) as i128) ^ -((z & 1) as i128));
        }
        shift += 7;
    }
}
/// Marks the per-pixel sample counts at the end of a partial render.
const COUNTS_TAG: u8 = 0xC0;
/// Largest metadata block read.
const MAX_META_BYTES: usize = 1 << 20;

fn bad(path: &Path, what: &str) -> Error {
    Error::Image { path: path.to_path_buf(), message: format!("not a zvidpt partial render ({what})") }
}

/// Stages `part` with `meta` at `path` (commit with [`super::commit`]).
pub fn stage_partial(path: &Path, part: &Partial, meta: &Metadata) -> Result<super::Staged> {
    let s = &part.sums;
    let header = [s.width, s.height, part.first, s.spp, part.total_spp];
    let counts = (!s.counts.is_empty()).then_some(s.counts.as_slice());
    stage_sums(path, meta, header, |j| (s.sum[j], s.sum_sq[j]), part.prior.as_ref(), counts)
}

/// Stages a partial render whose pixel `j` (row-major) has the sums `pixel(j)`, without a
/// copy of the image's sums (a checkpoint taken mid-render). `header` is `[width, height,
/// first, spp, total_spp]`; `counts`, each pixel's own sample count where they differ
/// (adaptive sampling).
pub fn stage_sums(
    path: &Path,
    meta: &Metadata,
    header: [u32; 5],
    pixel: impl Fn(usize) -> ([i128; 3], [i128; 3]),
    prior: Option<&PriorSamples>,
    counts: Option<&[u32]>,
) -> Result<super::Staged> {
    let mut text = String::new();
    for (k, v) in &meta.entries {
        // Keys and values are ours; a newline or '=' in a key would break the layout.
        text.push_str(&k.replace(['\n', '='], "_"));
        text.push('=');
        text.push_str(&v.replace('\n', " "));
        text.push('\n');
    }
    let pixels = header[0] as usize * header[1] as usize;
    super::stage(path, |out| {
        let io = |e| Error::io(path, e);
        let mut w = Checksummed { inner: out, crc: crc32fast::Hasher::new() };
        w.write_all(MAGIC).map_err(io)?;
        w.write_all(&(text.len() as u32).to_le_bytes()).map_err(io)?;
        w.write_all(text.as_bytes()).map_err(io)?;
        for v in header {
            w.write_all(&v.to_le_bytes()).map_err(io)?;
        }
        let mut row = [0u8; 6 * MAX_VARINT];
        for j in 0..pixels {
            let (sum, sq) = pixel(j);
            let end = sum.iter().chain(&sq).fold(0, |at, &v| put_varint(&mut row, at, v));
            w.write_all(&row[..end]).map_err(io)?;
        }
        let mut tail = Vec::new();
        match prior {
            Some(p) => {
                tail.push(1);
                p.encode(&mut tail);
            }
            None => tail.push(0),
        }
        // Per-pixel counts, if any, follow (files without them end here), under a tag that no
        // section of the pre-pass samples starts with.
        if let Some(counts) = counts {
            tail.push(COUNTS_TAG);
            for &c in counts {
                tail.extend_from_slice(&c.to_le_bytes());
            }
        }
        w.write_all(&tail).map_err(io)?;
        let crc = w.crc.finalize();
        out.write_all(&crc.to_le_bytes()).map_err(io)
    })
}

/// Reads a partial render written by [`stage_partial`].
pub fn read_partial(path: &Path) -> Result<(Partial, Metadata)> {
    // Header, sums and pre-pass samples of the largest image, with room to spare.
    let limit = 1024 + MAX_META_BYTES as u64 + MAX_PIXELS * (6 * MAX_VARINT as u64 + 48 + 1);
    let bytes = crate::io::read_bounded(path, limit, "partial render")?;
    parse_partial(&bytes, path)
}

/// What a partial render's header says: its size and sample range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartialHeader {
    pub width: u32,
    pub height: u32,
    pub first: u32,
    pub spp: u32,
    pub total_spp: u32,
}

/// Reads only the header and metadata of a partial render (for progress reports: the sums
/// of a large image are not read).
pub fn read_partial_header(path: &Path) -> Result<(PartialHeader, Metadata)> {
    use std::io::Read as _;
    let file = crate::io::open_regular(path, "partial render")?;
    let mut head = Vec::new();
    file.take(16 + 4 + MAX_META_BYTES as u64 + 20).read_to_end(&mut head).map_err(|e| Error::io(path, e))?;
    let (header, meta, _) = parse_header(&head, path)?;
    Ok((header, meta))
}

/// The header of a partial render and the bytes after it.
fn parse_header<'a>(bytes: &'a [u8], path: &Path) -> Result<(PartialHeader, Metadata, &'a [u8])> {
    let mut b = bytes;
    let Some((magic, rest)) = b.split_first_chunk::<16>() else { return Err(bad(path, "too short")) };
    if magic == MAGIC_WITHOUT_CHECKSUM {
        return Err(bad(path, "written by an older zvidpt, without a checksum: render it again"));
    }
    if magic != MAGIC {
        return Err(bad(path, "wrong magic"));
    }
    b = rest;
    let u32_at = |b: &mut &[u8]| -> Result<u32> {
        let (head, rest) = b.split_first_chunk::<4>().ok_or_else(|| bad(path, "truncated"))?;
        *b = rest;
        Ok(u32::from_le_bytes(*head))
    };
    let meta_len = u32_at(&mut b)? as usize;
    if meta_len > MAX_META_BYTES || meta_len > b.len() {
        return Err(bad(path, "metadata length"));
    }
    let text = std::str::from_utf8(&b[..meta_len]).map_err(|_| bad(path, "metadata is not UTF-8"))?;
    let mut meta = Metadata::default();
    for line in text.lines() {
        let (k, v) = line.split_once('=').ok_or_else(|| bad(path, "metadata line"))?;
        meta.push(k, v);
    }
    b = &b[meta_len..];
    let [width, height, first, spp, total_spp] =
        [u32_at(&mut b)?, u32_at(&mut b)?, u32_at(&mut b)?, u32_at(&mut b)?, u32_at(&mut b)?];
    let pixels = u64::from(width) * u64::from(height);
    if width == 0 || height == 0 || pixels > MAX_PIXELS {
        return Err(bad(path, "image size"));
    }
    if spp == 0 || first.checked_add(spp).is_none_or(|end| end > total_spp) {
        return Err(bad(path, "sample range"));
    }
    Ok((PartialHeader { width, height, first, spp, total_spp }, meta, b))
}

/// A partial render from its bytes (`path` names it in errors).
pub fn parse_partial(bytes: &[u8], path: &Path) -> Result<(Partial, Metadata)> {
    // The checksum first: a damaged file is refused whatever else it says.
    if bytes.get(..16).is_some_and(|m| m == MAGIC) {
        let Some((body, crc)) = bytes.split_last_chunk::<4>() else { return Err(bad(path, "truncated")) };
        if crc32fast::hash(body) != u32::from_le_bytes(*crc) {
            return Err(bad(path, "checksum mismatch: the file is damaged"));
        }
    }
    let bytes = &bytes[..bytes.len().saturating_sub(4)];
    let (PartialHeader { width, height, first, spp, total_spp }, meta, mut b) = parse_header(bytes, path)?;
    let pixels = u64::from(width) * u64::from(height);
    let pixels = pixels as usize;
    // Every pixel takes at least 6 bytes: a shorter file is cut off (and reserves no memory).
    if (b.len() as u64) < pixels as u64 * 6 + 1 {
        return Err(bad(path, "truncated"));
    }
    let mut sum = Vec::with_capacity(pixels);
    let mut sum_sq = Vec::with_capacity(pixels);
    for _ in 0..pixels {
        let mut v = [0i128; 6];
        for x in &mut v {
            *x = get_varint(&mut b).ok_or_else(|| bad(path, "truncated or malformed sums"))?;
        }
        sum.push([v[0], v[1], v[2]]);
        sum_sq.push([v[3], v[4], v[5]]);
    }
    let Some(&flag) = b.first() else { return Err(bad(path, "truncated")) };
    let prior = match flag {
        0 => None,
        1 => {
            let mut rest = &b[1..];
            let p = PriorSamples::decode(&mut rest, pixels).ok_or_else(|| bad(path, "pre-pass samples"))?;
            b = rest;
            Some(p)
        }
        _ => return Err(bad(path, "pre-pass flag")),
    };
    if prior.is_none() {
        b = &b[1..];
    }
    let mut counts = Vec::new();
    if let Some((&COUNTS_TAG, rest)) = b.split_first() {
        if rest.len() != pixels * 4 {
            return Err(bad(path, "per-pixel counts"));
        }
        counts = rest.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        // Adaptive sampling's counts are at most spp; sample rates' at most MAX_PIXEL_RATE × it.
        let most = (f64::from(spp) * f64::from(crate::film::rates::MAX_PIXEL_RATE)).ceil() as u64;
        if counts.iter().any(|&c| u64::from(c) > most) {
            return Err(bad(path, "per-pixel counts"));
        }
        b = &[];
    }
    if !b.is_empty() {
        return Err(bad(path, "trailing bytes"));
    }
    let sums = PixelSums { width, height, spp, sum, sum_sq, counts };
    Ok((Partial { first, total_spp, sums, prior }, meta))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(first: u32, spp: u32) -> Partial {
        let sums = PixelSums {
            width: 3,
            height: 2,
            spp,
            sum: (0..6).map(|i| [i, -i, i128::MAX / 3]).collect(),
            sum_sq: (0..6).map(|i| [i * i, 7, 1 << 100]).collect(),
            counts: Vec::new(),
        };
        Partial { first, total_spp: 10, sums, prior: None }
    }

    #[test]
    fn varints_round_trip_at_the_extremes() {
        let mut buf = [0u8; MAX_VARINT];
        for v in [0, 1, -1, 63, 64, -64, -65, i128::from(i64::MAX), 1 << 100, i128::MAX, i128::MIN, i128::MIN + 1] {
            let end = put_varint(&mut buf, 0, v);
            let mut b = &buf[..end];
            assert_eq!(get_varint(&mut b), Some(v), "{v}");
            assert!(b.is_empty());
        }
        assert_eq!(put_varint(&mut buf, 0, i128::MIN), MAX_VARINT);
        // Too long, or a 19th byte with more than 2 bits: refused.
        assert_eq!(get_varint(&mut &[0xffu8; 20][..]), None);
        let mut over = [0xffu8; MAX_VARINT];
        over[MAX_VARINT - 1] = 4;
        assert_eq!(get_varint(&mut &over[..]), None);
    }

    #[test]
    fn round_trip_and_malformed_input() {
        let dir = std::env::temp_dir().join(format!("zvidpt-partial-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.part");
        let mut meta = Metadata::default();
        meta.push("scene", "x=y\nz");
        let p = part(2, 5);
        super::super::commit(vec![stage_partial(&path, &p, &meta).unwrap()]).unwrap();
        let (back, m) = read_partial(&path).unwrap();
        assert_eq!(back, p);
        assert_eq!(m.get("scene"), Some("x=y z"));
        // Every truncation and a flipped magic fail with a message, never a panic.
        let bytes = std::fs::read(&path).unwrap();
        for n in 0..bytes.len() {
            assert!(parse_partial(&bytes[..n], &path).is_err(), "{n} bytes");
        }
        let mut flipped = bytes.clone();
        flipped[3] ^= 1;
        assert!(parse_partial(&flipped, &path).unwrap_err().to_string().contains("not a zvidpt partial"));
        // A flipped bit anywhere is refused (the checksum), never merged or resumed.
        for i in 16..bytes.len() {
            let mut damaged = bytes.clone();
            damaged[i] ^= 0x10;
            let e = parse_partial(&damaged, &path).unwrap_err().to_string();
            assert!(e.contains("checksum"), "byte {i}: {e}");
        }
        let mut older = bytes.clone();
        older[..16].copy_from_slice(MAGIC_WITHOUT_CHECKSUM);
        assert!(parse_partial(&older, &path).unwrap_err().to_string().contains("older zvidpt"));
        let mut longer = bytes;
        longer.push(0);
        assert!(parse_partial(&longer, &path).is_err());
    }

    /// Per-pixel sample counts (sample rates) come back as written; a count above
    /// `MAX_PIXEL_RATE` times the file's samples per pixel, or counts cut short, are refused;
    /// `merge` adds them up (a part without counts: its samples per pixel in every pixel).
    #[test]
    fn per_pixel_counts_round_trip() {
        let dir = std::env::temp_dir().join(format!("zvidpt-partial-counts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.part");
        let mut p = part(0, 5);
        p.sums.counts = vec![5, 2, 3, 5, 0, 4];
        super::super::commit(vec![stage_partial(&path, &p, &Metadata::default()).unwrap()]).unwrap();
        assert_eq!(read_partial(&path).unwrap().0, p);
        let mut q = part(5, 5);
        q.sums.counts = vec![9, 0, 1, 5, 2, 48];
        assert_eq!(Partial::merge(vec![q.clone(), p.clone()]).unwrap().sums.counts, vec![14, 2, 4, 10, 2, 52]);
        assert_eq!(Partial::merge(vec![part(5, 5), p.clone()]).unwrap().sums.counts, vec![10, 7, 8, 10, 5, 9]);
        for (counts, what) in [(vec![5, 2, 3, 5, 0, 81], "above 16 spp"), (vec![5, 2, 3], "short")] {
            let mut bad = p.clone();
            bad.sums.counts = counts;
            let s = &bad.sums;
            let header = [s.width, s.height, bad.first, s.spp, bad.total_spp];
            let staged =
                stage_sums(&path, &Metadata::default(), header, |j| (s.sum[j], s.sum_sq[j]), None, Some(&s.counts));
            super::super::commit(vec![staged.unwrap()]).unwrap();
            assert!(read_partial(&path).is_err(), "counts {what} were read");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
