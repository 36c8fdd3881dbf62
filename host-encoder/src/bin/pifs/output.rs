//! Output paths: refused before any work when they cannot be written, would replace the
//! input, or name the wrong kind of file.

use crate::error::{CliError, Result};
use host_encoder::io;
use std::path::Path;

/// What a command writes at an output path, for the checks of [`check_kind`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A PIFS stream: any name but an image format's (`.pifs` by convention).
    Stream,
    /// A decoded image: the extension chooses the format ([`io::OutputFormat`]).
    Image,
    /// A decoded image whose format an option chose: any name.
    ChosenImage,
    /// An SVG drawing: any name but an image format's.
    Svg,
    /// A CSV table: any name but an image format's.
    Csv,
    /// A JSON file: any name but an image format's.
    Json,
}

/// Refuses, before any work, an output path that cannot be written, that would replace
/// `input`, or whose name does not fit what is written there. `-` (standard output) is not a
/// path: nothing to check.
pub fn check(output: &Path, input: Option<&Path>, kind: Kind) -> Result<()> {
    if io::is_std_stream(output) {
        return Ok(());
    }
    check_writable(output)?;
    if let Some(input) = input {
        let same = match (input.canonicalize(), output.canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        };
        if same {
            return Err(CliError::Refused(format!(
                "output {} is the input file: refusing to overwrite it",
                output.display()
            )));
        }
    }
    check_kind(output, kind)
}

/// Refuses a name that promises another kind of file than the one written there.
pub fn check_kind(output: &Path, kind: Kind) -> Result<()> {
    let what = match kind {
        Kind::Image => {
            return io::OutputFormat::from_path(output)
                .map(|_| ())
                .map_err(Into::into)
        }
        Kind::ChosenImage => return Ok(()),
        Kind::Stream => ("a PIFS stream", ".pifs"),
        Kind::Svg => ("an SVG drawing", ".svg"),
        Kind::Csv => ("a CSV table", ".csv"),
        Kind::Json => ("a JSON curve file", ".json"),
    };
    if io::has_image_extension(output) {
        return Err(CliError::Refused(format!(
            "refusing to write {} into {}: use a {} name",
            what.0,
            output.display(),
            what.1
        )));
    }
    Ok(())
}

/// Refuses an output that is a directory or whose directory does not exist (a symbolic link
/// is judged by where it points; one to nothing is refused when the output is opened).
fn check_writable(output: &Path) -> Result<()> {
    if output.is_dir() {
        return Err(CliError::Refused(format!(
            "output {} is a directory",
            output.display()
        )));
    }
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        let why = if dir.exists() {
            "is not a directory"
        } else {
            "does not exist"
        };
        return Err(CliError::Refused(format!(
            "cannot write {}: {} {why}",
            output.display(),
            dir.display()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stream_is_not_written_under_an_image_name() {
        let err = check_kind(Path::new("out.png"), Kind::Stream).unwrap_err();
        assert_eq!(
            err.to_string(),
            "refusing to write a PIFS stream into out.png: use a .pifs name"
        );
        assert!(check_kind(Path::new("out.JPG"), Kind::Stream).is_err());
        assert!(check_kind(Path::new("out.pifs"), Kind::Stream).is_ok());
        assert!(check_kind(Path::new("payload.bin"), Kind::Stream).is_ok());
        assert!(check_kind(Path::new("payload"), Kind::Stream).is_ok());
        assert!(check_kind(Path::new("rd.png"), Kind::Svg).is_err());
        assert!(check_kind(Path::new("rd.svg"), Kind::Svg).is_ok());
    }

    #[test]
    fn an_image_output_needs_a_known_extension() {
        assert!(check_kind(Path::new("x.png"), Kind::Image).is_ok());
        assert!(check_kind(Path::new("x.ppm"), Kind::Image).is_ok());
        let err = check_kind(Path::new("x"), Kind::Image).unwrap_err();
        assert!(
            err.to_string().contains(".png, .pgm, .pnm or .ppm"),
            "{err}"
        );
        let err = check_kind(Path::new("x."), Kind::Image).unwrap_err();
        assert!(err.to_string().contains("has no extension"), "{err}");
    }
}
