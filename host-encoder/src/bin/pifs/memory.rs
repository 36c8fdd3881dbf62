//! How much memory an encode may use, and how much it needs.
//!
//! The analysis keeps, at every quadtree node it analyses (none inside a settled node: easy
//! content needs much less), the candidates on the node's rate/distortion hull, and the fits
//! of a band of about a megapixel until its coarse pass: its memory grows with the pixels.
//! Measured peaks
//! (`/usr/bin/time -f %M pifs encode IN.png --gray -o x.pifs --bpp 0.25`, the default
//! settings): 500² of noise 52 MB, tilings of 512² Kodak crops of 1024² 115 MB and 1536²
//! 259 MB, mosaics of Kodak images of 3072x2048 540 MB and 6000x4000 2.04 GB (in bands):
//! about 100 bytes per pixel beside a fixed part of about 10 MB, and 170 for noise; with
//! `--min-leaf-log2 1` 105 MB and 258 MB for the first two (235 to 380 bytes), with 3 38 MB
//! and 55 MB (43 to 113). Format 18 (no weights to fit or keep) brought 500² of noise to 47 MB
//! (150 bytes per pixel beside the fixed part) and RGB noise to 55 MB (`/usr/bin/time -f %M`,
//! same commands). Since the nodes past an analysis's first band (about a megapixel) make
//! their candidates' indices again instead of holding them, the mosaics peak at 281 MB and
//! 818 MB (about 34 bytes a pixel). Noise past the first band (`/usr/bin/time -f %M pifs
//! encode IN.png [--gray] -o x.pifs --bpp 0.25 --max-memory 20G`, uniform noise made with
//! numpy): grayscale 1024² 137 MB, 2048² 266 MB, 3072x2048 356 MB, so 41 and 43 bytes per
//! pixel past the first; RGB 1024² 171 MB, 2048² 428 MB, 82 bytes per pixel past it.
//! [`encode_bytes`] rounds these up: 250 bytes a pixel with 4 px leaves in the first band (up
//! to 2^20 pixels and a row of 128 px nodes), 64 past it, and the pixels beside the analysis.
//!
//! A colour encode analyses the luma plane and keeps, at every node, what its chroma costs
//! (the hull of its chroma options): RGB noise of 500² peaked at 56 MB against 52 MB in
//! grayscale (`/usr/bin/time -f %M pifs encode IN.png -o x.pifs --bpp 0.25`), about 16 bytes
//! per pixel more; [`image_bytes_per_pixel`] prices it.
//!
//! An image whose analysis does not fit is analysed in parts (`host_encoder::analyse_in_parts`):
//! bands of a stripe, one at a time, beside the image held whole and the stream's
//! reconstruction ([`parts_within`] chooses the largest parts that fit).
//!
//! The test `encode_is_bounded_by_its_memory_budget` (host-encoder/tests/robustness_table/
//! host.rs) checks the estimate against measured peaks of a grayscale and a colour encode, and
//! an encode in parts against the budget it was given, so that a change in the analysis shows
//! here.
//!
//! What may be used is the smallest of: the memory the system has available
//! (`MemAvailable`), what the process's cgroup may still charge (`memory.max` less
//! `memory.current`), and what the process's address-space and data limits (`ulimit -v`,
//! `ulimit -d`, `prlimit`) leave. Linux only; elsewhere nothing is known and only
//! `--max-pixels` bounds an encode.

/// Bytes of the analysis per pixel of its first band, by the smallest leaf (log2): the nodes
/// there hold their candidates' indices.
fn first_band_bytes_per_pixel(min_leaf_log2: u8) -> u64 {
    match min_leaf_log2 {
        0 | 1 => 600,
        2 => 250,
        _ => 200,
    }
}

/// Bytes of the analysis per pixel past its first band, where the nodes make their
/// candidates' indices again instead of holding them: noise, the worst content, takes 41 to
/// 43 (module documentation); 2 px leaves are priced as in the first band (not measured).
fn later_bytes_per_pixel(min_leaf_log2: u8) -> u64 {
    match min_leaf_log2 {
        0 | 1 => first_band_bytes_per_pixel(min_leaf_log2),
        _ => 64,
    }
}

/// Pixels of the analysis's first band at most, for an image `width` pixels wide: the
/// encoder's bands hold 2^20 pixels or more, in whole rows of its largest nodes (128 px).
fn first_band_pixels(width: u64) -> u64 {
    width.saturating_mul(128).saturating_add(1 << 20)
}

/// Bytes the analysis of a `width`-wide image of `pixels` pixels needs, with the pixels
/// beside it ([`image_bytes_per_pixel`]).
fn analysis_bytes(pixels: u64, width: u64, channels: u8, min_leaf_log2: u8) -> u64 {
    let first = pixels.min(first_band_pixels(width));
    let later = pixels - first;
    let image = image_bytes_per_pixel(channels);
    first
        .saturating_mul(first_band_bytes_per_pixel(min_leaf_log2) + image)
        .saturating_add(later.saturating_mul(later_bytes_per_pixel(min_leaf_log2) + image))
}

/// Memory besides the pixels' (the program, its threads, the encoder's tables): measured
/// peaks of 8 MB for 16² noise and 34 MB for 128² (the projection tables of 128 px leaves),
/// 43–44 MB for 500² (`/usr/bin/time -f %M pifs encode IN.png -o x.pifs`, format 19).
const FIXED_BYTES: u64 = 48 << 20;

/// Bytes per pixel of the pixels an encode holds beside the analysis, by the channels of the
/// stream: grayscale, the 8-bit plane three times (the image, the analysis's copy and the luma
/// its trial encode drew); colour, the RGB pixels twice (3 bytes each), the analysis's luma
/// plane and its trial's, the chroma planes (a quarter each), and the RGB reconstruction and
/// its check decode the writer adds (3 bytes each, where grayscale's are 1 and within its
/// analysis figure).
fn image_bytes_per_pixel(channels: u8) -> u64 {
    if channels == 3 {
        // 3 + 3 + 1 + 1 + 0.5 + 2 * (3 - 1), rounded up, and the nodes' chroma costs (24).
        13 + 24
    } else {
        3
    }
}

/// The size of an image an encode is asked for, as its header gives it before decoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageSize {
    /// Width in pixels.
    pub width: u64,
    /// Height in pixels.
    pub height: u64,
    /// Bytes of the decoded image in its own colour type.
    pub decoded_bytes: u64,
}

/// Bytes an encode of an image of `size` into a stream of `channels` channels (1 or 3) needs
/// at its peak: the decoded image in its own colour type (twice while a rotation is applied)
/// with the 8-bit plane and RGB (which a colour type gets even for a grayscale stream), then
/// the analysis and the pixels beside it ([`analysis_bytes`]; a quality target that analyses
/// again frees the first analysis before).
pub fn encode_bytes(size: ImageSize, channels: u8, min_leaf_log2: u8) -> u64 {
    let pixels = size.width.saturating_mul(size.height);
    let decoding = size
        .decoded_bytes
        .saturating_mul(2)
        .saturating_add(pixels.saturating_mul(4));
    let analysing = analysis_bytes(pixels, size.width, channels, min_leaf_log2);
    decoding.max(analysing).saturating_add(FIXED_BYTES)
}

/// The largest part an encode in parts of about `part_pixels` pixels analyses at once, of an
/// image of `size` coded in stripes of `stripe` pixels (0: the whole width): its width and
/// pixels. Parts are whole bands of 128 pixels of a stripe, `part_pixels` or one band, and the
/// last part of a stripe takes a short rest with it (`host_encoder::analyse_in_parts`).
fn largest_part(size: ImageSize, stripe: u64, part_pixels: u64) -> (u64, u64) {
    let width = match stripe {
        0 => size.width,
        s => s.min(size.width),
    };
    let bands = (part_pixels / (width.max(1) * 128)).max(1);
    let rows = (128 * bands + 64 * bands + 128).min(size.height);
    (width, width.saturating_mul(rows))
}

/// Bytes an encode in parts of about `part_pixels` pixels (`host_encoder::analyse_in_parts`)
/// of an image of `size` into a stream of `channels` channels, in stripes of `stripe` pixels,
/// needs at its peak: the decoding as [`encode_bytes`] prices it, then the image held whole
/// (luma, or RGB and its luma while the contrast is measured) with the stream's
/// reconstruction, beside the analysis of its largest part.
fn encode_in_parts_bytes(
    size: ImageSize,
    channels: u8,
    min_leaf_log2: u8,
    (stripe, part_pixels): (u64, u64),
) -> u64 {
    let pixels = size.width.saturating_mul(size.height);
    let decoding = size
        .decoded_bytes
        .saturating_mul(2)
        .saturating_add(pixels.saturating_mul(4));
    let whole = pixels.saturating_mul(if channels == 3 { 7 } else { 2 });
    let (width, part) = largest_part(size, stripe, part_pixels);
    let analysing = whole.saturating_add(analysis_bytes(part, width, channels, min_leaf_log2));
    decoding.max(analysing).saturating_add(FIXED_BYTES)
}

/// The largest parts (pixels, about) an encode in parts of an image of `size` into `channels`
/// channels, in stripes of `stripe` pixels, fits in `budget` bytes with (up to
/// [`host_encoder::PART_PIXELS`]; larger parts cost fewer analyses at their edges), and what
/// it then needs; or what the smallest parts need when even they do not fit.
pub fn parts_within(
    size: ImageSize,
    channels: u8,
    min_leaf_log2: u8,
    stripe: u64,
    budget: u64,
) -> Result<(u64, u64), u64> {
    let mut part_pixels = host_encoder::PART_PIXELS;
    loop {
        let need = encode_in_parts_bytes(size, channels, min_leaf_log2, (stripe, part_pixels));
        if need <= budget {
            return Ok((part_pixels, need));
        }
        if part_pixels <= 1 << 14 {
            return Err(need);
        }
        part_pixels /= 2;
    }
}

/// Bytes per pixel of the analysis of an image of `size` into `channels` channels, with the
/// pixels beside it: its mean over the image (for messages).
pub fn per_pixel(size: ImageSize, channels: u8, min_leaf_log2: u8) -> u64 {
    let pixels = size.width.saturating_mul(size.height).max(1);
    analysis_bytes(pixels, size.width, channels, min_leaf_log2).div_ceil(pixels)
}

/// The memory this process may still use, as far as the system says (Linux), bytes.
pub fn available() -> Option<u64> {
    let candidates = [
        meminfo_available(),
        cgroup_available(),
        rlimit_available("Max address space", "VmSize:"),
        rlimit_available("Max data size", "VmData:"),
    ];
    candidates.into_iter().flatten().min()
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path).ok()
}

/// A `Name:   1234 kB` line of a /proc file, in bytes.
fn kb_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kb: u64 = line[name.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kb * 1024)
}

fn meminfo_available() -> Option<u64> {
    kb_field(&read("/proc/meminfo")?, "MemAvailable:")
}

/// `memory.max - memory.current` of this process's cgroup (v2), when it has a limit.
fn cgroup_available() -> Option<u64> {
    let cgroup = read("/proc/self/cgroup")?;
    let path = cgroup.lines().find_map(|l| l.strip_prefix("0::"))?;
    let dir = format!("/sys/fs/cgroup{}", path.trim_end());
    let max: u64 = read(&format!("{dir}/memory.max"))?.trim().parse().ok()?;
    let current: u64 = read(&format!("{dir}/memory.current"))?
        .trim()
        .parse()
        .ok()?;
    Some(max.saturating_sub(current))
}

/// A soft resource limit of /proc/self/limits (`unlimited`: none) less what the process already
/// uses of it (the /proc/self/status field `used`).
fn rlimit_available(limit: &str, used: &str) -> Option<u64> {
    let limits = read("/proc/self/limits")?;
    let line = limits.lines().find(|l| l.starts_with(limit))?;
    let soft = line[limit.len()..].split_whitespace().next()?;
    let soft: u64 = soft.parse().ok()?;
    let in_use = kb_field(&read("/proc/self/status")?, used).unwrap_or(0);
    Some(soft.saturating_sub(in_use))
}

/// Parses a size: a number of bytes with an optional suffix K, M, G or T (powers of 1024;
/// `KB`, `KiB` and lower case are the same), such as `500M` or `1.5G`.
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("'{text}' is not a size (such as 800M or 2G)"))?;
    let unit = unit.trim().to_ascii_lowercase();
    let unit = unit.trim_end_matches("ib").trim_end_matches('b');
    let scale: u64 = match unit {
        "" => 1,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => return Err(format!("'{text}' is not a size (such as 800M or 2G)")),
    };
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("'{text}' is not a size (such as 800M or 2G)"));
    }
    Ok(bytes as u64)
}

/// A size for people, in the units `--max-memory` takes: "930 MiB", "58.3 GiB".
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    let (kib, mib, gib, tib) = (
        1024.0,
        1024.0 * 1024.0,
        1024.0f64.powi(3),
        1024.0f64.powi(4),
    );
    if b >= tib {
        format!("{:.1} TiB", b / tib)
    } else if b >= 10.0 * gib {
        format!("{:.0} GiB", b / gib)
    } else if b >= gib {
        format!("{:.1} GiB", b / gib)
    } else if b >= mib {
        format!("{:.0} MiB", b / mib)
    } else if b >= kib {
        format!("{:.0} KiB", b / kib)
    } else {
        format!("{bytes} bytes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_print() {
        assert_eq!(parse_size("1000").unwrap(), 1000);
        assert_eq!(parse_size("500M").unwrap(), 500 << 20);
        assert_eq!(parse_size("1.5G").unwrap(), 3 << 29);
        assert_eq!(parse_size("2GiB").unwrap(), 2 << 30);
        assert_eq!(parse_size("64kb").unwrap(), 64 << 10);
        assert!(parse_size("lots").is_err());
        assert!(parse_size("0").is_err());
        assert!(parse_size("5X").is_err());
        assert_eq!(human(930 << 20), "930 MiB");
        assert_eq!(human(3 << 29), "1.5 GiB");
        assert_eq!(human(58 << 30), "58 GiB");
        assert_eq!(human(12), "12 bytes");
    }

    fn size(width: u64, height: u64) -> ImageSize {
        ImageSize {
            width,
            height,
            decoded_bytes: width.saturating_mul(height).saturating_mul(3),
        }
    }

    #[test]
    fn the_estimate_grows_with_the_pixels_and_the_settings() {
        let small = encode_bytes(size(1000, 1000), 1, 2);
        // One band: 250 bytes a pixel for the analysis, 3 for the pixels, the fixed part beside.
        assert_eq!(small, 253_000_000 + FIXED_BYTES);
        assert!(encode_bytes(size(1000, 1000), 1, 1) > small);
        assert!(encode_bytes(size(1000, 1000), 1, 3) < small);
        // Colour: the RGB pixels and the nodes' chroma costs beside the luma analysis.
        let colour = encode_bytes(size(1000, 1000), 3, 2);
        assert_eq!(colour - small, 34_000_000);
        assert_eq!(
            per_pixel(size(1000, 1000), 3, 2) - per_pixel(size(1000, 1000), 1, 2),
            34
        );
        assert_eq!(encode_bytes(size(u64::MAX, 2), 3, 2), u64::MAX);
        // Past the first band (2^20 pixels and a row of 128 px nodes), 64 + 3 bytes a pixel.
        let first = (1 << 20) + 128 * 6000;
        let photo = encode_bytes(size(6000, 4000), 1, 2);
        assert_eq!(photo, first * 253 + (24_000_000 - first) * 67 + FIXED_BYTES);
        assert!(
            photo < 2_000_000_000,
            "a 24-megapixel photo in {photo} bytes"
        );
        assert_eq!(
            per_pixel(size(6000, 4000), 1, 2),
            (photo - FIXED_BYTES).div_ceil(24_000_000)
        );
        // 2 px leaves are priced as in the first band throughout.
        assert_eq!(
            encode_bytes(size(6000, 4000), 1, 1),
            24_000_000 * 603 + FIXED_BYTES
        );
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn linux_says_what_is_available() {
        let a = available().expect("/proc tells");
        assert!(a > 0);
    }
}
