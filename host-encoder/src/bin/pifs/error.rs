//! The tool's one error type: every failure is one line naming the user's path and the cause.

use host_encoder::io::FileError;
use host_encoder::EncodeError;
use std::fmt;
use std::path::PathBuf;

/// Why a command failed.
#[derive(Debug)]
pub enum CliError {
    /// Reading or writing a file.
    File(FileError),
    /// The encoder refused the image or the target.
    Encode(EncodeError),
    /// The stream at `path` is refused by the decoder.
    Stream {
        /// The stream's path.
        path: PathBuf,
        /// The decoder's reason.
        source: decoder_core::DecodeError,
        /// Where to look next, if anywhere (an option's name).
        hint: Option<&'static str>,
    },
    /// A drawing backend failed (the text is its message).
    Plot {
        /// The output's path.
        path: PathBuf,
        /// What the backend said.
        cause: String,
    },
    /// An argument or file the command refuses before doing any work; the text says why.
    Refused(String),
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::File(e) => e.fmt(f),
            CliError::Encode(e) => e.fmt(f),
            CliError::Stream { path, source, hint } => {
                write!(f, "{}: {source}", path.display())?;
                match hint {
                    Some(h) => write!(f, " (see {h})"),
                    None => Ok(()),
                }
            }
            CliError::Plot { path, cause } => {
                write!(f, "cannot draw {}: {cause}", path.display())
            }
            CliError::Refused(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for CliError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            CliError::File(e) => Some(e),
            CliError::Encode(e) => Some(e),
            CliError::Stream { source, .. } => Some(source),
            CliError::Plot { .. } | CliError::Refused(_) => None,
        }
    }
}

impl From<FileError> for CliError {
    fn from(e: FileError) -> Self {
        CliError::File(e)
    }
}

impl From<EncodeError> for CliError {
    fn from(e: EncodeError) -> Self {
        CliError::Encode(e)
    }
}

/// The result of a command.
pub type Result<T> = std::result::Result<T, CliError>;
