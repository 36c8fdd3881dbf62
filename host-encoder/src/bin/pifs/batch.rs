//! `pifs encode A.png B.png … --out-dir DIR`: many images, one stream each, spread over the
//! cores. With more images than cores, as many images are analysed at once as there are cores
//! (each analysis also uses every core, so that a short queue keeps them busy), each within its
//! share of the memory; otherwise the images go one after the other. One progress bar over the
//! batch; a failed image is reported and the others go on.

use crate::encode::{encode_one, EncodeArgs, InputLimits, Job};
use crate::error::{CliError, Result};
use crate::memory;
use crate::output::{self, Kind};
use crate::progress;
use crate::say;
use host_encoder::io;
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::HashMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

/// Encodes every image of `inputs` for `job` into `dir`.
pub fn run(args: &EncodeArgs, job: Job, inputs: &[PathBuf], dir: &Path) -> Result<()> {
    let outputs = output_names(inputs, dir)?;
    std::fs::create_dir_all(dir).map_err(|e| {
        CliError::Refused(format!("--out-dir {}: cannot make it: {e}", dir.display()))
    })?;
    for (input, out) in inputs.iter().zip(&outputs) {
        output::check(out, Some(input), Kind::Stream)?;
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let workers = if inputs.len() > cores { cores } else { 1 };
    let limits = share_of(&args.limits, workers);

    let bar = batch_bar(inputs.len());
    if let Some(bar) = &bar {
        // The batch's bar replaces each analysis's own, and status lines print above it.
        progress::hide_analysis_progress();
        say::through(bar.clone());
    }
    let next = AtomicUsize::new(0);
    let failed = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let (Some(input), Some(out)) = (inputs.get(i), outputs.get(i)) else {
                    break;
                };
                if let Err(e) = encode_one(args, &limits, job, input, out) {
                    failed.fetch_add(1, Ordering::Relaxed);
                    say::error(failure_text(input, &e));
                }
                if let Some(bar) = &bar {
                    bar.inc(1);
                }
            });
        }
    });
    if let Some(bar) = &bar {
        bar.finish_and_clear();
        say::directly();
    }
    match failed.into_inner() {
        0 => Ok(()),
        n => Err(CliError::Refused(format!(
            "{n} of {} images failed",
            inputs.len()
        ))),
    }
}

/// `DIR/<name>.pifs` for every input (its file name without its extension), refusing standard
/// input and two inputs that would write the same stream.
fn output_names(inputs: &[PathBuf], dir: &Path) -> Result<Vec<PathBuf>> {
    let mut seen: HashMap<PathBuf, &Path> = HashMap::new();
    inputs
        .iter()
        .map(|input| {
            if io::is_std_stream(input) {
                return Err(CliError::Refused(
                    "--out-dir takes image files, not standard input (\"-\")".into(),
                ));
            }
            let Some(stem) = input.file_stem() else {
                return Err(CliError::Refused(format!(
                    "{}: not a file name",
                    input.display()
                )));
            };
            let mut name = OsString::from(stem);
            name.push(".pifs");
            let out = dir.join(name);
            if let Some(first) = seen.insert(out.clone(), input) {
                return Err(CliError::Refused(format!(
                    "{} and {} would both be written to {}",
                    first.display(),
                    input.display(),
                    out.display()
                )));
            }
            Ok(out)
        })
        .collect()
}

/// The limits of one of `workers` images analysed at once: the memory budget (given, or what
/// the system has) shared between them.
fn share_of(limits: &InputLimits, workers: usize) -> InputLimits {
    let budget = limits.max_memory.or_else(memory::available);
    InputLimits {
        max_pixels: limits.max_pixels,
        max_memory: budget.map(|b| b / workers as u64),
        resize: limits.resize,
    }
}

/// The batch's progress bar (on a terminal only): images done, and the time left at the pace
/// so far.
fn batch_bar(images: usize) -> Option<ProgressBar> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = ProgressBar::new(images as u64);
    let style = ProgressStyle::with_template(
        "encoding {bar:40} {pos}/{len} images, {elapsed} so far, about {eta} left",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.enable_steady_tick(Duration::from_millis(250));
    Some(bar)
}

/// The line reporting that `input` failed with `e`, naming the image once.
fn failure_text(input: &Path, e: &CliError) -> String {
    let text = e.to_string();
    let name = input.display().to_string();
    if text.contains(&name) {
        format!("pifs: {text}")
    } else {
        format!("pifs: {name}: {text}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_named_after_their_inputs_and_never_clash() {
        let dir = Path::new("out");
        let names = output_names(
            &[PathBuf::from("a/x.png"), PathBuf::from("b/y.tar.png")],
            dir,
        )
        .expect("names");
        assert_eq!(names, [dir.join("x.pifs"), dir.join("y.tar.pifs")]);
        let clash = output_names(&[PathBuf::from("a/x.png"), PathBuf::from("b/x.jpg")], dir);
        let Err(CliError::Refused(text)) = clash else {
            panic!("two x images accepted")
        };
        assert!(
            text.contains("a/x.png") && text.contains("b/x.jpg"),
            "{text}"
        );
        assert!(output_names(&[PathBuf::from("-")], dir).is_err());
    }

    #[test]
    fn images_analysed_at_once_share_the_memory() {
        let limits = InputLimits {
            max_pixels: Some(10),
            max_memory: Some(1000),
            resize: None,
        };
        let shared = share_of(&limits, 4);
        assert_eq!(shared.max_memory, Some(250));
        assert_eq!(shared.max_pixels, Some(10));
    }
}
