//! The tool's status lines: on standard output, unless standard output carries the result
//! (`-o -`), in which case they go to standard error. A closed or full terminal does not stop
//! the tool (the lines are lost, the work is not).

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};

static STDOUT_IS_DATA: AtomicBool = AtomicBool::new(false);

/// From now on, status lines go to standard error: standard output carries data.
pub fn stdout_is_data() {
    STDOUT_IS_DATA.store(true, Ordering::Relaxed);
}

/// Writes one status line.
pub fn line(text: impl std::fmt::Display) {
    if STDOUT_IS_DATA.load(Ordering::Relaxed) {
        let _ = writeln!(std::io::stderr().lock(), "{text}");
    } else {
        let _ = writeln!(std::io::stdout().lock(), "{text}");
    }
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
