//! Image files in and out: any format the `image` crate reads, converted to 8-bit luma.

use crate::encoder::Plane;
use std::path::Path;

/// Loads an image file as 8-bit luma, by the rule of [`to_luma`].
pub fn load_luma(path: &Path) -> Result<Plane, String> {
    if path.is_dir() {
        return Err(format!("{} is a directory, not an image", path.display()));
    }
    let reader = image::ImageReader::open(path)
        .map_err(|e| format!("cannot open {}: {e}", path.display()))?
        .with_guessed_format()
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if reader.format().is_none() {
        let mut magic = [0u8; 4];
        let is_pifs = std::fs::File::open(path)
            .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
            .is_ok()
            && magic == decoder_core::internal::format::MAGIC;
        return Err(if is_pifs {
            format!(
                "{} is already a PIFS stream (use 'pifs decode' to turn it into an image)",
                path.display()
            )
        } else {
            format!("{}: not a supported image format", path.display())
        });
    }
    let img = reader
        .decode()
        .map_err(|e| format!("cannot decode {}: {e}", path.display()))?;
    Ok(to_luma(&img))
}

/// Converts a decoded image to 8-bit luma:
/// - colour by the BT.601 weights, `Y = 0.299 R + 0.587 G + 0.114 B` (grey stays grey);
/// - any bit depth (16-bit, float) from its full range to 0..=255, rounded;
/// - palette images through their palette;
/// - transparency composited over white, `Y' = a Y + (1 - a)` with `a` the alpha in 0..=1, as
///   an image viewer shows it on a white page (a fully transparent pixel becomes white,
///   whatever colour it carries).
pub fn to_luma(img: &image::DynamicImage) -> Plane {
    let rgba = img.to_rgba32f();
    let (w, h) = rgba.dimensions();
    let data = rgba
        .pixels()
        .map(|p| {
            let y = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
            let a = p[3].clamp(0.0, 1.0);
            let y = a * y + (1.0 - a);
            (y * 255.0).round().clamp(0.0, 255.0) as u8
        })
        .collect();
    Plane::new(w, h, data)
}

/// Encodes a grayscale image as PNG or PGM (chosen by the extension of `path`) into memory.
pub fn encode_gray(path: &Path, width: u32, height: u32, pixels: &[u8]) -> Result<Vec<u8>, String> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let format = match ext.as_str() {
        "png" => image::ImageFormat::Png,
        "pgm" | "pnm" => image::ImageFormat::Pnm,
        other => {
            return Err(format!(
                "unsupported output format '.{other}' (use .png or .pgm)"
            ))
        }
    };
    let img = image::GrayImage::from_raw(width, height, pixels.to_vec())
        .ok_or("pixel buffer size mismatch")?;
    let mut out = std::io::Cursor::new(Vec::new());
    if format == image::ImageFormat::Pnm {
        let enc = image::codecs::pnm::PnmEncoder::new(&mut out).with_subtype(
            image::codecs::pnm::PnmSubtype::Graymap(image::codecs::pnm::SampleEncoding::Binary),
        );
        img.write_with_encoder(enc).map_err(|e| e.to_string())?;
    } else {
        img.write_to(&mut out, format).map_err(|e| e.to_string())?;
    }
    Ok(out.into_inner())
}

/// Writes `bytes` to `path` atomically: into a temporary file in the same directory, then
/// renamed over `path`, so an interrupted or failed write never leaves a partial file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    use std::io::Write;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    // The temporary file's random name stays out of the message: the user named `path`.
    let mut tmp = tempfile::Builder::new()
        .prefix(".pifs-tmp-")
        .tempfile_in(&dir)
        .map_err(|e| {
            let text = e.to_string();
            let cause = text.split(" at path ").next().unwrap_or(&text);
            format!("cannot write {}: {cause}", path.display())
        })?;
    tmp.write_all(bytes)
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    tmp.as_file()
        .sync_all()
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    tmp.persist(path)
        .map_err(|e| format!("cannot write {}: {}", path.display(), e.error))?;
    Ok(())
}
