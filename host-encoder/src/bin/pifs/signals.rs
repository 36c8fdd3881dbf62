//! SIGINT, SIGTERM and SIGHUP end the tool without leaving a temporary file behind.
//!
//! On Linux an output's temporary file has no name until it is complete
//! ([`host_encoder::io::output`]), so there is nothing to remove; where it has one (another
//! system, a file system without `O_TMPFILE`), a thread waiting for these signals removes it
//! and exits with the shell's code for the signal (128 + its number). SIGKILL cannot be caught:
//! there, only an unnamed temporary file leaves nothing.
//!
//! The environment variable `PIFS_NAMED_TEMPORARY_FILES=1` makes every temporary file a named
//! one, so that the tests can check this cleanup on any system.

/// Installs the handler (once, at start).
pub fn clean_up_on_termination() {
    if std::env::var_os("PIFS_NAMED_TEMPORARY_FILES").is_some_and(|v| v == "1") {
        host_encoder::io::use_unnamed_temporary_files(false);
    }
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
            return;
        };
        let _ = std::thread::Builder::new()
            .name("signals".into())
            .spawn(move || {
                if let Some(signal) = signals.forever().next() {
                    host_encoder::io::remove_temporary_files();
                    std::process::exit(128 + signal);
                }
            });
    }
}
