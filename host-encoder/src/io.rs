//! Files in and out: any image format the `image` crate reads, converted to 8-bit luma; decoded
//! images written as PNG or PNM; any output written atomically.
//!
//! Every function here fails with a [`FileError`], which names the user's path and keeps the
//! underlying cause as its [`source`](std::error::Error::source).

use crate::encoder::Plane;
use std::fmt;
use std::path::{Path, PathBuf};

/// Why reading or writing a file failed.
#[derive(Debug)]
#[non_exhaustive]
pub enum FileError {
    /// The input path is a directory.
    IsDirectory {
        /// The path given.
        path: PathBuf,
        /// What was expected there ("an image", "a .pifs stream").
        expected: &'static str,
    },
    /// The image file could not be opened.
    Open {
        /// The path given.
        path: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
    /// The file could not be read.
    Read {
        /// The path given.
        path: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
    /// The file is a PIFS stream where an image was expected.
    AlreadyPifs {
        /// The path given.
        path: PathBuf,
    },
    /// The file is in no image format this tool reads.
    Format {
        /// The path given.
        path: PathBuf,
    },
    /// The image is damaged or uses a feature the decoder lacks.
    Decode {
        /// The path given.
        path: PathBuf,
        /// The image decoder's reason.
        source: image::ImageError,
    },
    /// The output's name asks for a format that decoded images cannot be written in.
    UnsupportedOutput {
        /// The path given.
        path: PathBuf,
        /// Its extension, if it has one.
        extension: Option<String>,
    },
    /// A pixel buffer does not hold `width * height` samples.
    BufferSize {
        /// Width, pixels.
        width: u32,
        /// Height, pixels.
        height: u32,
        /// Samples in the buffer.
        len: usize,
    },
    /// The image encoder failed to encode the pixels.
    Encode {
        /// The path the image was meant for.
        path: PathBuf,
        /// The image encoder's reason.
        source: image::ImageError,
    },
    /// The output could not be written.
    Write {
        /// The path given.
        path: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FileError::IsDirectory { path, expected } => {
                write!(f, "{} is a directory, not {expected}", path.display())
            }
            FileError::Open { path, source } => {
                write!(f, "cannot open {}: {source}", path.display())
            }
            FileError::Read { path, source } => {
                write!(f, "cannot read {}: {source}", path.display())
            }
            FileError::AlreadyPifs { path } => write!(
                f,
                "{} is already a PIFS stream (use 'pifs decode' to turn it into an image)",
                path.display()
            ),
            FileError::Format { path } => {
                write!(f, "{}: not a supported image format", path.display())
            }
            FileError::Decode { path, source } => {
                write!(f, "cannot decode {}: {source}", path.display())
            }
            FileError::UnsupportedOutput { path, extension } => {
                let list = OutputFormat::list();
                match extension {
                    Some(ext) => write!(
                        f,
                        "unsupported output format '.{ext}' for {} (use {list})",
                        path.display()
                    ),
                    None => write!(
                        f,
                        "{} has no extension to choose the output format by (use {list})",
                        path.display()
                    ),
                }
            }
            FileError::BufferSize { width, height, len } => write!(
                f,
                "pixel buffer size mismatch: {len} samples for a {width}x{height} image"
            ),
            FileError::Encode { path, source } => {
                write!(f, "cannot encode {}: {source}", path.display())
            }
            FileError::Write { path, source } => {
                write!(f, "cannot write {}: {source}", path.display())
            }
        }
    }
}

impl std::error::Error for FileError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            FileError::Open { source, .. }
            | FileError::Read { source, .. }
            | FileError::Write { source, .. } => Some(source),
            FileError::Decode { source, .. } | FileError::Encode { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// Loads an image file as 8-bit luma, by the rule of [`to_luma`].
pub fn load_luma(path: &Path) -> Result<Plane, FileError> {
    if path.is_dir() {
        return Err(FileError::IsDirectory {
            path: path.to_path_buf(),
            expected: "an image",
        });
    }
    let bytes = std::fs::read(path).map_err(|source| FileError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    decode_luma(&bytes, path)
}

/// Decodes an image file's contents `bytes` as 8-bit luma, by the rule of [`to_luma`]. `path`
/// names the file in errors, and its extension is the format's first guess (the contents
/// decide when they are recognised).
pub fn decode_luma(bytes: &[u8], path: &Path) -> Result<Plane, FileError> {
    Ok(to_luma(&decode_dynamic(bytes, path)?))
}

/// Decodes an image file's contents (see [`decode_luma`]) as the `image` crate gives it.
fn decode_dynamic(bytes: &[u8], path: &Path) -> Result<image::DynamicImage, FileError> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes));
    if let Ok(format) = image::ImageFormat::from_path(path) {
        reader.set_format(format);
    }
    let reader = reader
        .with_guessed_format()
        .map_err(|source| FileError::Read {
            path: path.to_path_buf(),
            source,
        })?;
    if reader.format().is_none() {
        let is_pifs = bytes.starts_with(&decoder_core::internal::format::MAGIC);
        return Err(if is_pifs {
            FileError::AlreadyPifs {
                path: path.to_path_buf(),
            }
        } else {
            FileError::Format {
                path: path.to_path_buf(),
            }
        });
    }
    reader.decode().map_err(|source| FileError::Decode {
        path: path.to_path_buf(),
        source,
    })
}

/// An image as the encoder takes it: grayscale, or colour.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Loaded {
    /// 8-bit luma ([`to_luma`]).
    Gray(Plane),
    /// 8-bit RGB ([`to_rgb`]).
    Rgb {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// Row-major RGB, 3 bytes a pixel.
        data: Vec<u8>,
    },
}

/// Loads an image file: colour ([`Loaded::Rgb`], by the rule of [`to_rgb`]) when it has colour
/// (a colour type with some pixel whose channels differ), else luma ([`to_luma`]).
pub fn load_image(path: &Path) -> Result<Loaded, FileError> {
    if path.is_dir() {
        return Err(FileError::IsDirectory {
            path: path.to_path_buf(),
            expected: "an image",
        });
    }
    let bytes = std::fs::read(path).map_err(|source| FileError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    let img = decode_dynamic(&bytes, path)?;
    if img.color().has_color() {
        let (width, height, data) = to_rgb(&img);
        if data.chunks_exact(3).any(|p| p[0] != p[1] || p[1] != p[2]) {
            return Ok(Loaded::Rgb {
                width,
                height,
                data,
            });
        }
    }
    Ok(Loaded::Gray(to_luma(&img)))
}

/// Converts a decoded image to 8-bit RGB (width, height, row-major RGB): any bit depth from its
/// full range, rounded; palettes through their palette; transparency composited over white,
/// channel by channel (as [`to_luma`] does for luma).
pub fn to_rgb(img: &image::DynamicImage) -> (u32, u32, Vec<u8>) {
    let rgba = img.to_rgba32f();
    let (w, h) = rgba.dimensions();
    let mut data = Vec::with_capacity(3 * w as usize * h as usize);
    for p in rgba.pixels() {
        let a = p[3].clamp(0.0, 1.0);
        for c in 0..3 {
            let v = a * p[c] + (1.0 - a);
            data.push((v * 255.0).round().clamp(0.0, 255.0) as u8);
        }
    }
    (w, h, data)
}

/// Reads a whole `.pifs` stream into memory (a directory is refused by name).
pub fn read_stream(path: &Path) -> Result<Vec<u8>, FileError> {
    if path.is_dir() {
        return Err(FileError::IsDirectory {
            path: path.to_path_buf(),
            expected: "a .pifs stream",
        });
    }
    std::fs::read(path).map_err(|source| FileError::Read {
        path: path.to_path_buf(),
        source,
    })
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

/// The formats decoded images are written in, chosen by the output's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    /// PNG, 8-bit grayscale (`.png`).
    Png,
    /// Binary PGM, 8-bit (`.pgm`, `.pnm`).
    Pgm,
    /// Binary PPM, 8-bit RGB with the grey in every channel (`.ppm`), for tools that read
    /// colour only.
    Ppm,
}

impl OutputFormat {
    /// Every extension accepted, with its format, in the order the help lists them.
    pub const EXTENSIONS: [(&'static str, OutputFormat); 4] = [
        ("png", OutputFormat::Png),
        ("pgm", OutputFormat::Pgm),
        ("pnm", OutputFormat::Pgm),
        ("ppm", OutputFormat::Ppm),
    ];

    /// The format `path`'s extension names (case-insensitive), or
    /// [`FileError::UnsupportedOutput`].
    pub fn from_path(path: &Path) -> Result<OutputFormat, FileError> {
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .filter(|e| !e.is_empty());
        let found = extension.as_deref().and_then(|ext| {
            Self::EXTENSIONS
                .iter()
                .find(|(name, _)| *name == ext)
                .map(|&(_, format)| format)
        });
        found.ok_or_else(|| FileError::UnsupportedOutput {
            path: path.to_path_buf(),
            extension,
        })
    }

    /// The accepted extensions as a phrase: ".png, .pgm, .pnm or .ppm".
    pub fn list() -> String {
        let names: Vec<String> = Self::EXTENSIONS
            .iter()
            .map(|(e, _)| format!(".{e}"))
            .collect();
        match names.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => names.concat(),
        }
    }
}

/// Whether `path`'s extension names an image format (`.png`, `.jpg`, `.tiff`, …: any the
/// `image` crate knows, enabled or not), where a PIFS stream does not belong.
pub fn has_image_extension(path: &Path) -> bool {
    image::ImageFormat::from_path(path).is_ok()
}

/// Encodes an RGB image (`3 * width * height` bytes) in the format `path`'s extension names
/// into memory: PNG and PPM in colour; PGM (which holds gray only) as the image's luma.
pub fn encode_rgb(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[u8],
) -> Result<Vec<u8>, FileError> {
    use image::codecs::pnm::{PnmEncoder, PnmSubtype, SampleEncoding};
    let format = OutputFormat::from_path(path)?;
    let img =
        image::RgbImage::from_raw(width, height, pixels.to_vec()).ok_or(FileError::BufferSize {
            width,
            height,
            len: pixels.len(),
        })?;
    let mut out = std::io::Cursor::new(Vec::new());
    let written = match format {
        OutputFormat::Png => img.write_to(&mut out, image::ImageFormat::Png),
        OutputFormat::Ppm => img.write_with_encoder(
            PnmEncoder::new(&mut out).with_subtype(PnmSubtype::Pixmap(SampleEncoding::Binary)),
        ),
        OutputFormat::Pgm => {
            let luma: Vec<u8> = pixels
                .chunks_exact(3)
                .map(|p| decoder_core::internal::colour::rgb_to_luma(p[0], p[1], p[2]))
                .collect();
            return format.encode(path, width, height, &luma);
        }
    };
    written.map_err(|source| FileError::Encode {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(out.into_inner())
}

/// Encodes a grayscale image in the format `path`'s extension names ([`OutputFormat`]) into
/// memory.
pub fn encode_gray(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[u8],
) -> Result<Vec<u8>, FileError> {
    OutputFormat::from_path(path)?.encode(path, width, height, pixels)
}

impl OutputFormat {
    /// Encodes a grayscale image (`width * height` samples, row-major) in this format into
    /// memory; `path` is where it is going, for the errors.
    pub fn encode(
        self,
        path: &Path,
        width: u32,
        height: u32,
        pixels: &[u8],
    ) -> Result<Vec<u8>, FileError> {
        use image::codecs::pnm::{PnmEncoder, PnmSubtype, SampleEncoding};
        let img = image::GrayImage::from_raw(width, height, pixels.to_vec()).ok_or(
            FileError::BufferSize {
                width,
                height,
                len: pixels.len(),
            },
        )?;
        let mut out = std::io::Cursor::new(Vec::new());
        let written = match self {
            OutputFormat::Png => img.write_to(&mut out, image::ImageFormat::Png),
            OutputFormat::Pgm => img.write_with_encoder(
                PnmEncoder::new(&mut out).with_subtype(PnmSubtype::Graymap(SampleEncoding::Binary)),
            ),
            OutputFormat::Ppm => image::DynamicImage::ImageLuma8(img)
                .into_rgb8()
                .write_with_encoder(
                    PnmEncoder::new(&mut out)
                        .with_subtype(PnmSubtype::Pixmap(SampleEncoding::Binary)),
                ),
        };
        written.map_err(|source| FileError::Encode {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(out.into_inner())
    }
}

/// Writes `bytes` to `path` atomically: into a temporary file in the same directory, then
/// renamed over `path`, so an interrupted or failed write never leaves a partial file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    use std::io::Write;
    let failed = |source: std::io::Error| FileError::Write {
        path: path.to_path_buf(),
        source,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".pifs-tmp-")
        .tempfile_in(&dir)
        .map_err(|e| failed(without_temporary_path(e)))?;
    tmp.write_all(bytes).map_err(failed)?;
    tmp.as_file().sync_all().map_err(failed)?;
    tmp.persist(path).map_err(|e| failed(e.error))?;
    Ok(())
}

/// The system error under `tempfile`'s wrapper, whose message names the temporary file's random
/// path: the user named another path, and the message is about that one.
fn without_temporary_path(e: std::io::Error) -> std::io::Error {
    let inner = e
        .get_ref()
        .and_then(|wrapper| wrapper.source())
        .and_then(|cause| cause.downcast_ref::<std::io::Error>())
        .and_then(std::io::Error::raw_os_error);
    match inner.or_else(|| e.raw_os_error()) {
        Some(code) => std::io::Error::from_raw_os_error(code),
        None => {
            let text = e.to_string();
            let cause = text.split(" at path ").next().unwrap_or(&text).to_string();
            std::io::Error::new(e.kind(), cause)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::error::Error;

    #[test]
    fn output_format_follows_the_extension() {
        let f = |p: &str| OutputFormat::from_path(Path::new(p));
        assert_eq!(f("a.png").unwrap(), OutputFormat::Png);
        assert_eq!(f("dir.x/a.PGM").unwrap(), OutputFormat::Pgm);
        assert_eq!(f("a.pnm").unwrap(), OutputFormat::Pgm);
        assert_eq!(f("a.ppm").unwrap(), OutputFormat::Ppm);
        let none = f("dir.png/out").unwrap_err().to_string();
        assert_eq!(
            none,
            "dir.png/out has no extension to choose the output format by (use .png, .pgm, .pnm or .ppm)"
        );
        let jpg = f("o.jpg").unwrap_err().to_string();
        assert_eq!(
            jpg,
            "unsupported output format '.jpg' for o.jpg (use .png, .pgm, .pnm or .ppm)"
        );
    }

    #[test]
    fn ppm_output_repeats_the_grey_in_every_channel() {
        let bytes = encode_gray(Path::new("x.ppm"), 2, 1, &[10, 200]).unwrap();
        let img = image::load_from_memory(&bytes).unwrap().into_rgb8();
        assert_eq!(img.as_raw(), &[10, 10, 10, 200, 200, 200]);
        let bytes = encode_gray(Path::new("x.pgm"), 2, 1, &[10, 200]).unwrap();
        assert!(bytes.starts_with(b"P5"));
        let err = encode_gray(Path::new("x.png"), 2, 2, &[1]).unwrap_err();
        assert!(matches!(err, FileError::BufferSize { len: 1, .. }), "{err}");
    }

    #[test]
    fn errors_name_the_path_and_keep_the_cause() {
        let missing = Path::new("/nonexistent-pifs-dir/in.png");
        let err = load_luma(missing).unwrap_err();
        assert!(matches!(err, FileError::Open { .. }));
        assert!(err
            .to_string()
            .starts_with("cannot open /nonexistent-pifs-dir/in.png: "));
        let cause = err
            .source()
            .unwrap()
            .downcast_ref::<std::io::Error>()
            .unwrap();
        assert_eq!(cause.kind(), std::io::ErrorKind::NotFound);

        let err = write_atomic(Path::new("/nonexistent-pifs-dir/out.pifs"), b"x").unwrap_err();
        let text = err.to_string();
        assert!(
            text.starts_with("cannot write /nonexistent-pifs-dir/out.pifs: ")
                && !text.contains(".pifs-tmp"),
            "{text}"
        );
        assert!(err.source().is_some());

        let mut stream = decoder_core::internal::format::MAGIC.to_vec();
        stream.extend_from_slice(&[0; 16]);
        let err = decode_luma(&stream, Path::new("s.bin")).unwrap_err();
        assert!(matches!(err, FileError::AlreadyPifs { .. }), "{err}");
        let err = decode_luma(b"hello, world", Path::new("t.txt")).unwrap_err();
        assert_eq!(err.to_string(), "t.txt: not a supported image format");
        let err = decode_luma(b"hello, world", Path::new("t.png")).unwrap_err();
        assert!(matches!(err, FileError::Decode { .. }), "{err}");
        assert!(err.source().is_some());
    }

    #[test]
    fn image_extensions_are_recognised() {
        for p in [
            "a.png", "a.JPG", "a.jpeg", "a.tif", "a.bmp", "a.pgm", "a.webp",
        ] {
            assert!(has_image_extension(Path::new(p)), "{p}");
        }
        for p in ["a.pifs", "a", "a.bin", "a.svg"] {
            assert!(!has_image_extension(Path::new(p)), "{p}");
        }
    }
}
