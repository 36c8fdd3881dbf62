//! Decoded images out: 8-bit gray or RGB as PNG, PGM or PPM, written row by row
//! ([`ImageWriter`]), so that an image never has to be whole in memory to be written; the
//! values of a 16-bit stream as 16-bit gray ([`OutputFormat::encode_values`]).

use super::FileError;
use decoder_core::internal::colour::rgb_to_luma;
use std::cell::RefCell;
use std::io::Write;
use std::path::Path;
use std::rc::Rc;

/// How hard decoded images are compressed as PNG: fast (a decoded picture is smooth and
/// compresses well anyway; see docs/decisions.md).
const PNG_COMPRESSION: png::Compression = png::Compression::Fast;

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

    /// The format's name, as `--format` takes it: "png", "pgm" or "ppm".
    pub fn name(self) -> &'static str {
        match self {
            OutputFormat::Png => "png",
            OutputFormat::Pgm => "pgm",
            OutputFormat::Ppm => "ppm",
        }
    }

    /// The format named `name` (an extension without its dot, case-insensitive).
    pub fn from_name(name: &str) -> Option<OutputFormat> {
        let name = name.to_ascii_lowercase();
        Self::EXTENSIONS
            .iter()
            .find(|(ext, _)| *ext == name)
            .map(|&(_, format)| format)
    }

    /// The format `path`'s extension names (case-insensitive), or
    /// [`FileError::UnsupportedOutput`].
    pub fn from_path(path: &Path) -> Result<OutputFormat, FileError> {
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .filter(|e| !e.is_empty());
        let found = extension.as_deref().and_then(OutputFormat::from_name);
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

    /// Encodes an image of `channels` samples a pixel (1: gray, 3: RGB; `channels * width *
    /// height` samples, row-major) in this format into memory; `path` is where it is going,
    /// for the errors.
    pub fn encode(
        self,
        path: &Path,
        width: u32,
        height: u32,
        channels: u8,
        pixels: &[u8],
    ) -> Result<Vec<u8>, FileError> {
        let row = width as usize * usize::from(channels);
        if pixels.len() as u64 != u64::from(width) * u64::from(height) * u64::from(channels) {
            return Err(FileError::BufferSize {
                width,
                height,
                len: pixels.len(),
            });
        }
        let failed = |source| FileError::Write {
            path: path.to_path_buf(),
            source,
        };
        let mut writer =
            ImageWriter::new(self, Vec::new(), width, height, channels).map_err(failed)?;
        for row in pixels.chunks_exact(row.max(1)) {
            writer.write_row(row).map_err(failed)?;
        }
        writer.finish().map_err(failed)
    }
}

impl OutputFormat {
    /// Encodes 16-bit gray values (`width * height`, row-major) in this format into memory:
    /// PNG of bit depth 16, PGM and PPM of largest value 65535 (big-endian samples, the grey
    /// in every channel of a PPM).
    pub fn encode_values(
        self,
        path: &Path,
        width: u32,
        height: u32,
        values: &[u16],
    ) -> Result<Vec<u8>, FileError> {
        if values.len() as u64 != u64::from(width) * u64::from(height) {
            return Err(FileError::BufferSize {
                width,
                height,
                len: values.len(),
            });
        }
        let failed = |source| FileError::Write {
            path: path.to_path_buf(),
            source,
        };
        let mut out = Vec::new();
        match self {
            OutputFormat::Png => {
                let mut encoder = png::Encoder::new(&mut out, width, height);
                encoder.set_color(png::ColorType::Grayscale);
                encoder.set_depth(png::BitDepth::Sixteen);
                encoder.set_compression(PNG_COMPRESSION);
                let be: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
                encoder
                    .write_header()
                    .and_then(|mut w| w.write_image_data(&be))
                    .map_err(|e| failed(png_error(e)))?;
            }
            OutputFormat::Pgm | OutputFormat::Ppm => {
                let (magic, repeat) = match self {
                    OutputFormat::Pgm => ("P5", 1),
                    _ => ("P6", 3),
                };
                out.extend_from_slice(format!("{magic}\n{width} {height}\n65535\n").as_bytes());
                for v in values {
                    for _ in 0..repeat {
                        out.extend_from_slice(&v.to_be_bytes());
                    }
                }
            }
        }
        Ok(out)
    }
}

/// Encodes a grayscale image in the format `path`'s extension names ([`OutputFormat`]) into
/// memory.
pub fn encode_gray(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[u8],
) -> Result<Vec<u8>, FileError> {
    OutputFormat::from_path(path)?.encode(path, width, height, 1, pixels)
}

/// Encodes an RGB image (`3 * width * height` bytes) in the format `path`'s extension names
/// into memory: PNG and PPM in colour, PGM (gray only) as its luma.
pub fn encode_rgb(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[u8],
) -> Result<Vec<u8>, FileError> {
    OutputFormat::from_path(path)?.encode(path, width, height, 3, pixels)
}

/// Writes a gray or RGB image row by row, top to bottom, in an [`OutputFormat`]: PNG through the
/// `png` crate's streaming writer (its compressor's window and one row of filter state), PGM
/// and PPM as they come. Memory does not grow with the image.
pub struct ImageWriter<W: Write + 'static> {
    out: Rc<RefCell<W>>,
    inner: Inner<W>,
    /// Samples in a row: the width times the channels.
    row_len: usize,
    channels: u8,
    rows_left: u32,
}

enum Inner<W: Write + 'static> {
    Png(Box<png::StreamWriter<'static, Shared<W>>>),
    /// PGM or PPM: `rgb` for PPM; `converted` holds a row in the file's samples when they
    /// are not the image's (gray expanded to RGB, RGB reduced to luma).
    Pnm {
        rgb: bool,
        converted: Vec<u8>,
    },
}

/// The output, shared between the writer and the `png` crate's stream writer (which owns what
/// it writes into), so that [`ImageWriter::finish`] can hand it back.
struct Shared<W>(Rc<RefCell<W>>);

impl<W: Write> Write for Shared<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.0.borrow_mut().write_all(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.0.borrow_mut().flush()
    }
}

impl<W: Write + 'static> std::fmt::Debug for ImageWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImageWriter")
            .field("row_len", &self.row_len)
            .field("channels", &self.channels)
            .field("rows_left", &self.rows_left)
            .finish_non_exhaustive()
    }
}

/// A `png` crate error as an I/O error (its I/O errors as they were).
fn png_error(e: png::EncodingError) -> std::io::Error {
    match e {
        png::EncodingError::IoError(e) => e,
        other => std::io::Error::other(other.to_string()),
    }
}

impl<W: Write + 'static> ImageWriter<W> {
    /// Starts an image of `width x height` (at least 1 x 1) and `channels` samples a pixel (1:
    /// gray, 3: RGB) in `format` on `out`: writes its header. PGM holds gray only: an RGB image
    /// is written as its luma (BT.601).
    pub fn new(
        format: OutputFormat,
        out: W,
        width: u32,
        height: u32,
        channels: u8,
    ) -> std::io::Result<Self> {
        if channels != 1 && channels != 3 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "an image of 1 or 3 channels",
            ));
        }
        let out = Rc::new(RefCell::new(out));
        let inner = match format {
            OutputFormat::Png => {
                let mut encoder = png::Encoder::new(Shared(out.clone()), width, height);
                encoder.set_color(if channels == 3 {
                    png::ColorType::Rgb
                } else {
                    png::ColorType::Grayscale
                });
                encoder.set_depth(png::BitDepth::Eight);
                encoder.set_compression(PNG_COMPRESSION);
                let stream = encoder
                    .write_header()
                    .and_then(png::Writer::into_stream_writer)
                    .map_err(png_error)?;
                Inner::Png(Box::new(stream))
            }
            OutputFormat::Pgm | OutputFormat::Ppm => {
                let rgb = format == OutputFormat::Ppm;
                let magic = if rgb { "P6" } else { "P5" };
                write!(out.borrow_mut(), "{magic}\n{width} {height}\n255\n")?;
                Inner::Pnm {
                    rgb,
                    converted: Vec::new(),
                }
            }
        };
        Ok(ImageWriter {
            out,
            inner,
            row_len: width as usize * usize::from(channels),
            channels,
            rows_left: height,
        })
    }

    /// Writes the next row (`width * channels` samples).
    pub fn write_row(&mut self, row: &[u8]) -> std::io::Result<()> {
        if row.len() != self.row_len || self.rows_left == 0 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "a row of the wrong length, or past the image's last",
            ));
        }
        self.rows_left -= 1;
        match &mut self.inner {
            Inner::Png(stream) => stream.write_all(row),
            Inner::Pnm { rgb, converted } => {
                let file_channels = if *rgb { 3 } else { 1 };
                if file_channels == self.channels {
                    return self.out.borrow_mut().write_all(row);
                }
                converted.clear();
                if *rgb {
                    converted.extend(row.iter().flat_map(|&v| [v, v, v]));
                } else {
                    converted.extend(row.chunks_exact(3).map(|p| rgb_to_luma(p[0], p[1], p[2])));
                }
                self.out.borrow_mut().write_all(converted)
            }
        }
    }

    /// Ends the image (every row must have been written), flushes it and hands the output
    /// back.
    pub fn finish(self) -> std::io::Result<W> {
        if self.rows_left != 0 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "the image ended before its last row",
            ));
        }
        if let Inner::Png(stream) = self.inner {
            stream.finish().map_err(png_error)?;
        }
        let out = Rc::try_unwrap(self.out)
            .map_err(|_| std::io::Error::other("the PNG writer kept its output"))?;
        let mut out = out.into_inner();
        out.flush()?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert_eq!(OutputFormat::from_name("PPM"), Some(OutputFormat::Ppm));
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
    fn every_format_reads_back_as_written() {
        let (w, h) = (37u32, 23u32);
        let pixels: Vec<u8> = (0..w * h).map(|i| (i * 7 % 251) as u8).collect();
        for (_, format) in OutputFormat::EXTENSIONS {
            let bytes = format.encode(Path::new("x"), w, h, 1, &pixels).unwrap();
            let img = image::load_from_memory(&bytes).unwrap().into_luma8();
            assert_eq!(img.dimensions(), (w, h), "{format:?}");
            assert_eq!(img.as_raw(), &pixels, "{format:?}");
        }
    }

    #[test]
    fn a_short_image_is_an_error() {
        let mut writer = ImageWriter::new(OutputFormat::Png, Vec::new(), 2, 2, 1).unwrap();
        writer.write_row(&[1, 2]).unwrap();
        assert!(writer.write_row(&[1, 2, 3]).is_err());
        assert!(writer.finish().is_err());
    }
}
