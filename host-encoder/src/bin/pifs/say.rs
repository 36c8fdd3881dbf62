//! The tool's status lines: on standard output, unless standard output carries the result
//! (`-o -`), in which case they go to standard error. A closed or full terminal does not stop
//! the tool (the lines are lost, the work is not).

use indicatif::ProgressBar;
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

static STDOUT_IS_DATA: AtomicBool = AtomicBool::new(false);

/// A progress bar on the terminal that status lines are printed above.
static BAR: Mutex<Option<ProgressBar>> = Mutex::new(None);

/// From now on, status lines are printed above `bar` (which is hidden while they are written).
pub fn through(bar: ProgressBar) {
    *BAR.lock().unwrap_or_else(|p| p.into_inner()) = Some(bar);
}

/// From now on, status lines are printed directly again.
pub fn directly() {
    *BAR.lock().unwrap_or_else(|p| p.into_inner()) = None;
}

/// Runs `write` with the progress bar, if any, out of the way.
fn above_bar(write: impl FnOnce()) {
    let bar = BAR.lock().unwrap_or_else(|p| p.into_inner()).clone();
    match bar {
        Some(bar) => bar.suspend(write),
        None => write(),
    }
}

/// Writes one line to standard error (an error that does not end the command).
pub fn error(text: impl std::fmt::Display) {
    above_bar(|| {
        let _ = writeln!(std::io::stderr().lock(), "{text}");
    });
}

/// From now on, status lines go to standard error: standard output carries data.
pub fn stdout_is_data() {
    STDOUT_IS_DATA.store(true, Ordering::Relaxed);
}

/// Writes one status line.
pub fn line(text: impl std::fmt::Display) {
    above_bar(|| {
        if STDOUT_IS_DATA.load(Ordering::Relaxed) {
            let _ = writeln!(std::io::stderr().lock(), "{text}");
        } else {
            let _ = writeln!(std::io::stdout().lock(), "{text}");
        }
    });
}

/// Writes text as it is (several lines, a table).
pub fn text(text: impl std::fmt::Display) {
    if STDOUT_IS_DATA.load(Ordering::Relaxed) {
        let _ = write!(std::io::stderr().lock(), "{text}");
    } else {
        let _ = write!(std::io::stdout().lock(), "{text}");
    }
}

/// A status line, formatted: `say!("{}: done", path.display())`.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::say::line(format_args!($($arg)*))
    };
}
