//! Where results go. [`Output::create`] decides, before any work, how a path is written:
//!
//! - `-` is standard output (refused when it is a terminal and the data is binary);
//! - a character device or a FIFO (`/dev/null`, a named pipe) is opened and written through,
//!   as other codecs do: it is never replaced by a file;
//! - a block device or a socket is refused;
//! - a symbolic link is followed: the file it points to is written as below and the link
//!   stays a link; a link to nothing is refused (the message names where it points);
//! - any other path gets a new file atomically: the data goes into a temporary file in the
//!   same directory, synced, then put in place in one step, so that a reader sees the old file
//!   or the new one, never part of one, and a failed or interrupted write leaves the old file
//!   as it was. On Linux the temporary file has no name until it is complete (`O_TMPFILE`,
//!   then `linkat`), so a process killed while it works or writes, even by SIGKILL, leaves
//!   nothing behind. (A new path is linked in one step; an existing file is replaced by linking
//!   the complete file under a hidden name and renaming it over the old one in the next system
//!   call: only a kill between those two calls could leave the hidden name.) Elsewhere (or on a file system without `O_TMPFILE`) it is a hidden
//!   `.pifs-tmp-XXXXXX` file, deleted on error and by [`remove_temporary_files`], which a
//!   program calls when SIGINT or SIGTERM stops it.
//!
//! A new file's permissions follow the umask (`0666 & !umask`, as any program's files do); a
//! replaced file keeps its permission bits, and its owner and group where the process may set
//! them (as root).
//!
//! The temporary file is created by [`Output::create`], so a directory that cannot be written
//! is reported before the work whose result would go there.

use super::{output_name, FileError};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// Names of the temporary files in use (named ones only): removed by
/// [`remove_temporary_files`].
static TEMPORARY: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Whether temporary files without a name (Linux `O_TMPFILE`) are used where the system
/// allows them.
static UNNAMED: AtomicBool = AtomicBool::new(true);

/// Removes every named temporary file an [`Output`] of this process holds: for a signal
/// handler that ends the process (SIGINT, SIGTERM), where no destructor runs. Unnamed
/// temporary files need nothing: the system frees them with the process.
pub fn remove_temporary_files() {
    let names = match TEMPORARY.lock() {
        Ok(mut list) => std::mem::take(&mut *list),
        Err(poisoned) => std::mem::take(&mut *poisoned.into_inner()),
    };
    for name in names {
        let _ = std::fs::remove_file(name);
    }
}

/// Chooses whether unnamed temporary files are used where the system allows them (the
/// default) or named ones always (for tests of the named path).
pub fn use_unnamed_temporary_files(enabled: bool) {
    UNNAMED.store(enabled, Ordering::Relaxed);
}

fn unregister(path: &Path) {
    if let Ok(mut list) = TEMPORARY.lock() {
        list.retain(|p| p != path);
    }
}

/// What is written, for the refusal to write binary data to a terminal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Content {
    /// Binary data, described ("a PIFS stream", "a PNG image").
    Binary(&'static str),
    /// Text (SVG, CSV), which a terminal may show.
    Text,
}

/// An output opened by [`Output::create`]: write into it, then [`Output::commit`]. Dropped
/// without a commit, it leaves the path as it was (a device or a pipe has what was written).
pub struct Output {
    /// The path as the user gave it, for messages.
    name: PathBuf,
    dest: Dest,
}

enum Dest {
    Stdout(BufWriter<std::io::StdoutLock<'static>>),
    Through(BufWriter<File>),
    Replace {
        file: BufWriter<File>,
        /// The file to replace or create (symbolic links resolved).
        target: PathBuf,
        temp: Temp,
    },
}

enum Temp {
    /// `O_TMPFILE`: no name until it is linked.
    #[cfg(target_os = "linux")]
    Unnamed,
    /// A hidden file beside the target, deleted when dropped.
    Named(Registered),
}

/// A named temporary file, listed for [`remove_temporary_files`] while it exists; deleted
/// (and unlisted) when dropped.
struct Registered(Option<tempfile::TempPath>);

impl Registered {
    /// A new hidden temporary file in `dir` whose permissions follow the umask, listed: made
    /// while the list is held, so that a signal's handler (which takes the list) cannot find
    /// the file in the directory but not in the list.
    fn create_in(dir: &Path) -> std::io::Result<(File, Registered)> {
        let mut list = TEMPORARY
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let named = tempfile::Builder::new()
            .prefix(".pifs-tmp-")
            .permissions(mode_for_new_files())
            .tempfile_in(dir)
            .map_err(without_temporary_path)?;
        let (file, path) = named.into_parts();
        list.push(path.to_path_buf());
        Ok((file, Registered(Some(path))))
    }

    /// Renames the file to `target`.
    fn persist(mut self, target: &Path) -> std::io::Result<()> {
        let Some(path) = self.0.take() else {
            return Ok(());
        };
        let name = path.to_path_buf();
        let result = path.persist(target).map_err(|e| e.error);
        unregister(&name);
        result
    }
}

impl Drop for Registered {
    fn drop(&mut self) {
        if let Some(path) = self.0.take() {
            let name = path.to_path_buf();
            drop(path);
            unregister(&name);
        }
    }
}

impl std::fmt::Debug for Output {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let how = match &self.dest {
            Dest::Stdout(_) => "standard output",
            Dest::Through(_) => "written through",
            Dest::Replace { .. } => "replaced atomically",
        };
        f.debug_struct("Output")
            .field("name", &self.name)
            .field("how", &how)
            .finish_non_exhaustive()
    }
}

impl Output {
    /// Opens `path` for writing by the rules of this module (`-`: standard output).
    pub fn create(path: &Path, content: Content) -> Result<Output, FileError> {
        let name = output_name(path);
        let failed = |source: std::io::Error| FileError::Write {
            path: name.clone(),
            source,
        };
        if super::is_std_stream(path) {
            use std::io::IsTerminal;
            let stdout = std::io::stdout();
            if let (Content::Binary(what), true) = (content, stdout.is_terminal()) {
                return Err(FileError::Terminal { what });
            }
            return Ok(Output {
                name,
                dest: Dest::Stdout(BufWriter::new(stdout.lock())),
            });
        }
        let target = resolve_links(path)?;
        let existing = match std::fs::metadata(&target) {
            Ok(meta) => Some(meta),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(failed(e)),
        };
        if let Some(meta) = &existing {
            if meta.is_dir() {
                return Err(failed(std::io::Error::new(
                    std::io::ErrorKind::IsADirectory,
                    "it is a directory",
                )));
            }
            if let Some(kind) = special_kind(meta) {
                return match kind {
                    Special::WriteThrough => {
                        let file = std::fs::OpenOptions::new()
                            .write(true)
                            .open(&target)
                            .map_err(failed)?;
                        Ok(Output {
                            name,
                            dest: Dest::Through(BufWriter::new(file)),
                        })
                    }
                    Special::Refused(kind) => Err(FileError::OutputKind { path: name, kind }),
                };
            }
        }
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let (file, temp) = temporary_in(&dir).map_err(failed)?;
        if let Some(meta) = &existing {
            keep_attributes(&file, meta).map_err(failed)?;
        }
        Ok(Output {
            name,
            dest: Dest::Replace {
                file: BufWriter::with_capacity(1 << 16, file),
                target,
                temp,
            },
        })
    }

    /// The path as the user gave it ("standard output" for `-`).
    pub fn name(&self) -> &Path {
        &self.name
    }

    /// A write error on this output, naming it.
    pub fn error(&self, source: std::io::Error) -> FileError {
        FileError::Write {
            path: self.name.clone(),
            source,
        }
    }

    /// Completes the output: flushes it; a file is synced and put in place (replacing what was
    /// there).
    pub fn commit(self) -> Result<(), FileError> {
        let name = self.name;
        let failed = |source: std::io::Error| FileError::Write {
            path: name.clone(),
            source,
        };
        match self.dest {
            Dest::Stdout(mut out) => out.flush().map_err(failed),
            Dest::Through(out) => {
                let file = out.into_inner().map_err(|e| failed(e.into_error()))?;
                drop(file);
                Ok(())
            }
            Dest::Replace { file, target, temp } => {
                let file = file.into_inner().map_err(|e| failed(e.into_error()))?;
                file.sync_all().map_err(failed)?;
                match temp {
                    #[cfg(target_os = "linux")]
                    Temp::Unnamed => unnamed::link(&file, &target).map_err(failed)?,
                    Temp::Named(named) => named.persist(&target).map_err(failed)?,
                }
                drop(file);
                sync_directory(&target);
                Ok(())
            }
        }
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match &mut self.dest {
            Dest::Stdout(out) => out.write(buf),
            Dest::Through(out) => out.write(buf),
            Dest::Replace { file, .. } => file.write(buf),
        }
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        match &mut self.dest {
            Dest::Stdout(out) => out.write_all(buf),
            Dest::Through(out) => out.write_all(buf),
            Dest::Replace { file, .. } => file.write_all(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match &mut self.dest {
            Dest::Stdout(out) => out.flush(),
            Dest::Through(out) => out.flush(),
            // The file is synced and put in place by `commit`.
            Dest::Replace { .. } => Ok(()),
        }
    }
}

/// Writes `bytes` to `path` by the rules of this module: atomically for a file (an
/// interrupted or failed write never leaves a partial file), through for a device or a FIFO,
/// to standard output for `-`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    let mut out = Output::create(path, Content::Binary("data"))?;
    out.write_all(bytes).map_err(|e| out.error(e))?;
    out.commit()
}

/// `path` with its symbolic links followed (itself when it is not a link). A link to nothing
/// is refused.
fn resolve_links(path: &Path) -> Result<PathBuf, FileError> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_symlink() => match std::fs::canonicalize(path) {
            Ok(real) => Ok(real),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(FileError::DanglingLink {
                path: path.to_path_buf(),
                target: std::fs::read_link(path).unwrap_or_default(),
            }),
            Err(source) => Err(FileError::Write {
                path: path.to_path_buf(),
                source,
            }),
        },
        _ => Ok(path.to_path_buf()),
    }
}

enum Special {
    WriteThrough,
    Refused(&'static str),
}

/// What to do with a file that is not regular: `None` for a regular file.
#[cfg(unix)]
fn special_kind(meta: &std::fs::Metadata) -> Option<Special> {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_char_device() || t.is_fifo() {
        Some(Special::WriteThrough)
    } else if t.is_block_device() {
        Some(Special::Refused("a block device"))
    } else if t.is_socket() {
        Some(Special::Refused("a socket"))
    } else {
        None
    }
}

#[cfg(not(unix))]
fn special_kind(meta: &std::fs::Metadata) -> Option<Special> {
    (!meta.is_file()).then_some(Special::Refused("not a regular file"))
}

/// A temporary file in `dir`: unnamed where the system allows it, else a hidden named one
/// (registered for [`remove_temporary_files`]) whose permissions follow the umask.
fn temporary_in(dir: &Path) -> std::io::Result<(File, Temp)> {
    #[cfg(target_os = "linux")]
    if UNNAMED.load(Ordering::Relaxed) {
        match unnamed::create(dir) {
            Ok(file) => return Ok((file, Temp::Unnamed)),
            Err(e) if unnamed::unsupported(&e) => {}
            Err(e) => return Err(e),
        }
    }
    let (file, named) = Registered::create_in(dir)?;
    Ok((file, Temp::Named(named)))
}

/// `0666`, which the system narrows by the umask, as for any new file.
#[cfg(unix)]
fn mode_for_new_files() -> std::fs::Permissions {
    use std::os::unix::fs::PermissionsExt;
    std::fs::Permissions::from_mode(0o666)
}

#[cfg(not(unix))]
fn mode_for_new_files() -> std::fs::Permissions {
    std::env::temp_dir()
        .metadata()
        .map(|m| m.permissions())
        .unwrap_or_else(|_| unreachable!("the temporary directory has permissions"))
}

/// Gives the temporary `file` the permission bits of the file it replaces, and its owner and
/// group where the process may (ownership is left as it is where it may not).
#[cfg(unix)]
fn keep_attributes(file: &File, old: &std::fs::Metadata) -> std::io::Result<()> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let new = file.metadata()?;
    if new.uid() != old.uid() || new.gid() != old.gid() {
        let _ = std::os::unix::fs::fchown(file, Some(old.uid()), Some(old.gid()));
    }
    file.set_permissions(std::fs::Permissions::from_mode(old.mode() & 0o7777))
}

#[cfg(not(unix))]
fn keep_attributes(file: &File, old: &std::fs::Metadata) -> std::io::Result<()> {
    file.set_permissions(old.permissions())
}

/// Syncs the directory holding `path`, so that the new name survives a crash (best effort).
fn sync_directory(path: &Path) {
    #[cfg(unix)]
    if let Some(dir) = path.parent() {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
    }
    #[cfg(not(unix))]
    let _ = path;
}

/// The system error under `tempfile`'s wrapper, whose message names the temporary file's random
/// path: the user named another path, and the message is about that one.
fn without_temporary_path(e: std::io::Error) -> std::io::Error {
    let inner = e
        .get_ref()
        .and_then(|wrapper| std::error::Error::source(wrapper))
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

/// Linux's unnamed temporary files.
#[cfg(target_os = "linux")]
mod unnamed {
    use rustix::fs::{linkat, openat, AtFlags, Mode, OFlags, CWD};
    use std::fs::File;
    use std::os::fd::AsRawFd;
    use std::path::{Path, PathBuf};

    /// An unnamed file in `dir`'s file system, mode `0666 & !umask`.
    pub fn create(dir: &Path) -> std::io::Result<File> {
        // Linking it later goes through /proc; without /proc, a named file is used instead.
        if !Path::new("/proc/self/fd").is_dir() {
            return Err(std::io::Error::from_raw_os_error(
                rustix::io::Errno::OPNOTSUPP.raw_os_error(),
            ));
        }
        let fd = openat(
            CWD,
            dir,
            OFlags::WRONLY | OFlags::TMPFILE | OFlags::CLOEXEC,
            Mode::from_raw_mode(0o666),
        )?;
        Ok(File::from(fd))
    }

    /// Whether `e` says the file system (or the kernel) has no unnamed files.
    pub fn unsupported(e: &std::io::Error) -> bool {
        use rustix::io::Errno;
        let code = e.raw_os_error();
        [Errno::OPNOTSUPP, Errno::ISDIR, Errno::INVAL, Errno::NOSYS]
            .iter()
            .any(|errno| code == Some(errno.raw_os_error()))
    }

    /// Gives `file` the name `target`: directly when nothing is there, else under a hidden
    /// name that is at once renamed over `target` (so a reader never sees a missing file).
    pub fn link(file: &File, target: &Path) -> std::io::Result<()> {
        let proc_path = PathBuf::from(format!("/proc/self/fd/{}", file.as_raw_fd()));
        let link_as = |name: &Path| linkat(CWD, &proc_path, CWD, name, AtFlags::SYMLINK_FOLLOW);
        if !target.exists() {
            match link_as(target) {
                Ok(()) => return Ok(()),
                Err(rustix::io::Errno::EXIST) => {}
                Err(e) => return Err(e.into()),
            }
        }
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        for attempt in 0u32.. {
            let hidden = dir.join(format!(".pifs-tmp-{}-{attempt}", std::process::id()));
            match link_as(&hidden) {
                Ok(()) => {
                    return std::fs::rename(&hidden, target).inspect_err(|_| {
                        let _ = std::fs::remove_file(&hidden);
                    });
                }
                Err(rustix::io::Errno::EXIST) if attempt < 100 => continue,
                Err(e) => return Err(e.into()),
            }
        }
        unreachable!("the loop returns")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    fn mode(path: &Path) -> u32 {
        use std::os::unix::fs::PermissionsExt;
        std::fs::metadata(path).unwrap().permissions().mode() & 0o7777
    }

    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .filter_map(Result::ok)
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".pifs-tmp"))
            .collect()
    }

    #[test]
    fn a_file_is_replaced_whole_and_keeps_its_mode() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.pifs");
        write_atomic(&path, b"first").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"first");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
        }
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        #[cfg(unix)]
        assert_eq!(mode(&path), 0o640);
        assert!(leftovers(dir.path()).is_empty());
    }

    #[test]
    fn an_output_dropped_without_commit_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.pifs");
        std::fs::write(&path, b"old").unwrap();
        let mut out = Output::create(&path, Content::Text).unwrap();
        out.write_all(b"new, unfinished").unwrap();
        drop(out);
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert!(leftovers(dir.path()).is_empty());
    }

    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_is_followed_and_stays_a_link() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.pifs");
        let link = dir.path().join("link.pifs");
        std::fs::write(&real, b"old").unwrap();
        std::os::unix::fs::symlink(&real, &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(&real).unwrap(), b"new");
        let dangling = dir.path().join("dangling.pifs");
        std::os::unix::fs::symlink(dir.path().join("nowhere.pifs"), &dangling).unwrap();
        let err = write_atomic(&dangling, b"x").unwrap_err();
        assert!(matches!(err, FileError::DanglingLink { .. }), "{err}");
        assert!(!dir.path().join("nowhere.pifs").exists());
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_written_through() {
        write_atomic(Path::new("/dev/null"), b"into nothing").unwrap();
        let meta = std::fs::metadata("/dev/null").unwrap();
        use std::os::unix::fs::FileTypeExt;
        assert!(meta.file_type().is_char_device());
        if Path::new("/dev/full").exists() {
            let err = write_atomic(Path::new("/dev/full"), b"x").unwrap_err();
            let text = err.to_string();
            assert!(
                text.starts_with("cannot write /dev/full: No space left on device"),
                "{text}"
            );
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_socket_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("socket.pifs");
        let _listener = std::os::unix::net::UnixListener::bind(&path).unwrap();
        let err = write_atomic(&path, b"x").unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "output {} is a socket: refusing to write onto it",
                path.display()
            )
        );
    }

    #[test]
    fn named_temporary_files_are_listed_until_done() {
        let dir = tempfile::tempdir().unwrap();
        let (file, kept) = Registered::create_in(dir.path()).unwrap();
        assert_eq!(leftovers(dir.path()).len(), 1);
        remove_temporary_files();
        assert!(leftovers(dir.path()).is_empty());
        drop((file, kept));
        let (_file, kept) = Registered::create_in(dir.path()).unwrap();
        kept.persist(&dir.path().join("done")).unwrap();
        assert!(leftovers(dir.path()).is_empty());
        assert!(dir.path().join("done").exists());
        assert!(TEMPORARY.lock().unwrap().is_empty());
    }
}
