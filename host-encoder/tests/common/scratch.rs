//! Scratch directories for the tests that run `pifs` on files.

use std::path::{Path, PathBuf};

/// An empty directory under the system's temporary directory for one test, named after the
/// process so that concurrent runs do not meet. It is removed when the test is done with it,
/// and kept when the test fails, for a look at what it left.
pub struct Scratch(PathBuf);

impl Scratch {
    /// The directory `pifs-<process id>-<name>`, emptied if it was there.
    pub fn new(name: &str) -> Scratch {
        let dir = std::env::temp_dir().join(format!("pifs-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}
