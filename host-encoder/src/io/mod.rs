//! Files in and out, as a command-line tool or a gateway uses them:
//!
//! - [`input`]: an image file (or standard input) read within limits, its dimensions known
//!   before its pixels are decoded, its EXIF orientation applied, converted to 8-bit luma;
//! - [`stream`]: a `.pifs` stream read header first (nothing more is read from a source that
//!   is not a stream, and at most what the header declares from one that is), and decoded into
//!   a PNG or PNM file row band by row band, so that memory follows the width, not the image;
//! - [`output`]: where results go: a new or replaced file written atomically (a temporary file
//!   without a name where the system allows it, linked into place once complete), devices and
//!   FIFOs written through, standard output for `-`;
//! - [`image_out`]: the formats decoded images are written in.
//!
//! Every function here fails with a [`FileError`], which names the user's path and keeps the
//! underlying cause as its [`source`](std::error::Error::source).

pub mod image_out;
pub mod input;
pub mod output;
pub mod stream;

pub use image_out::{encode_gray, encode_rgb, ImageWriter, OutputFormat};
pub use input::{
    decode_luma, has_image_extension, load_image, load_luma, read_input, to_luma, to_rgb,
    DecodedImage, Depth, Fit, ImageLimits, ImageProbe, Loaded, Surface, SurfaceError,
};
pub use output::{
    remove_temporary_files, use_unnamed_temporary_files, write_atomic, Content, Output,
};
pub use stream::{decode_to_image, read_stream, Decoded, StreamInput, BAND_BYTES, HOST_STRIPE};

use std::fmt;
use std::path::{Path, PathBuf};

/// The path that stands for standard input (as an input) or standard output (as an output).
pub const STD_STREAM: &str = "-";

/// Whether `path` is [`STD_STREAM`].
pub fn is_std_stream(path: &Path) -> bool {
    path.as_os_str() == STD_STREAM
}

/// How standard input is named in messages.
pub const STDIN_NAME: &str = "standard input";

/// How standard output is named in messages.
pub const STDOUT_NAME: &str = "standard output";

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
    /// The input is longer than the caller allows.
    InputTooLong {
        /// The path given.
        path: PathBuf,
        /// The most bytes accepted.
        limit: u64,
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
    /// The image is damaged or uses a feature the decoder lacks, or decoding it would need
    /// more memory than allowed ([`image::ImageError::Limits`]).
    Decode {
        /// The path given.
        path: PathBuf,
        /// The image decoder's reason.
        source: image::ImageError,
    },
    /// The PIFS stream is refused by the decoder: its header, its size against the caller's
    /// limits, or its payload.
    Stream {
        /// The path given.
        path: PathBuf,
        /// The decoder's reason.
        source: decoder_core::DecodeError,
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
    /// The output path is a file of a kind that is neither replaced nor written through (a
    /// block device, a socket).
    OutputKind {
        /// The path given.
        path: PathBuf,
        /// What it is ("a block device").
        kind: &'static str,
    },
    /// The output path is a symbolic link to a file that does not exist (links are followed,
    /// but a dangling one is not made to point at a new file).
    DanglingLink {
        /// The path given.
        path: PathBuf,
        /// Where the link points.
        target: PathBuf,
    },
    /// Binary data would be written to a terminal.
    Terminal {
        /// What would be written ("a PIFS stream").
        what: &'static str,
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
            FileError::InputTooLong { path, limit } => write!(
                f,
                "{} is longer than {limit} bytes, the most this command reads",
                path.display()
            ),
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
            FileError::Stream { path, source } => write!(f, "{}: {source}", path.display()),
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
            FileError::OutputKind { path, kind } => write!(
                f,
                "output {} is {kind}: refusing to write onto it",
                path.display()
            ),
            FileError::DanglingLink { path, target } => write!(
                f,
                "output {} is a symbolic link to {}, which does not exist: refusing to create it (name the file itself)",
                path.display(),
                target.display()
            ),
            FileError::Terminal { what } => write!(
                f,
                "refusing to write {what} to a terminal (redirect standard output, or name a file with -o)"
            ),
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
            FileError::Stream { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// How `path` is named in messages: itself, or "standard input" for `-`.
pub fn input_name(path: &Path) -> PathBuf {
    if is_std_stream(path) {
        PathBuf::from(STDIN_NAME)
    } else {
        path.to_path_buf()
    }
}

/// How `path` is named in messages: itself, or "standard output" for `-`.
pub fn output_name(path: &Path) -> PathBuf {
    if is_std_stream(path) {
        PathBuf::from(STDOUT_NAME)
    } else {
        path.to_path_buf()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::error::Error;

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

        let mut stream = decoder_core::internal::format::LEGACY_MAGIC.to_vec();
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
    fn standard_streams_are_named_in_words() {
        assert_eq!(input_name(Path::new("-")), PathBuf::from("standard input"));
        assert_eq!(
            output_name(Path::new("-")),
            PathBuf::from("standard output")
        );
        assert_eq!(input_name(Path::new("./-")), PathBuf::from("./-"));
    }
}
