//! One writer per folder: a lock file for dataset and run folders, and the clean-up of the
//! temporary files a killed writer left behind.
//!
//! [`FolderLock::acquire`] takes an advisory lock (`flock`) on `<folder>/.evblur.lock` and
//! writes the holder's pid into it. The OS drops the lock when the holder exits, however it
//! exits, so a killed writer never leaves a stale lock; a second writer meanwhile gets
//! [`LockError::Held`] with the holder's pid. The file is removed when the lock is dropped.
//!
//! Every writer of the project writes a file `name` under a hidden temporary sibling
//! `.name….tmp<pid>` and renames it into place. A kill between the two leaves the temporary
//! file; whoever holds the folder's lock next removes them ([`remove_stale_temps`]): while the
//! lock is held nobody else writes there, so every such file is stale.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// The lock file's name inside a locked folder.
pub const LOCK_FILE: &str = ".evblur.lock";

/// Why a folder could not be locked.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another live process holds the lock.
    #[error(
        "{}: another process (pid {pid}) is writing this folder; wait for it to finish, stop it, or choose another folder",
        dir.display()
    )]
    Held {
        /// The folder.
        dir: PathBuf,
        /// The holder's pid, as it wrote it (`unknown` when not yet written).
        pid: String,
    },
    /// The lock file could not be created, opened or locked.
    #[error("{}: cannot lock ({source}); check that the folder exists and is writable", path.display())]
    Io {
        /// The lock file.
        path: PathBuf,
        /// The OS error.
        source: io::Error,
    },
}

/// An exclusive lock on a folder, released (and its file removed) when dropped.
#[derive(Debug)]
pub struct FolderLock {
    path: PathBuf,
    // held open: closing it releases the lock (`None` where the file system has no locks)
    file: Option<File>,
}

impl FolderLock {
    /// Lock `dir` (which must exist) for writing, or fail at once with [`LockError::Held`] when
    /// another process holds it. On a file system without locks the folder is not locked
    /// (nothing worse than before locks existed) and a [`FolderLock`] is still returned.
    pub fn acquire(dir: &Path) -> Result<FolderLock, LockError> {
        let path = dir.join(LOCK_FILE);
        let io_err = |source| LockError::Io { path: path.clone(), source };
        loop {
            let mut file =
                OpenOptions::new().read(true).write(true).create(true).truncate(false).open(&path).map_err(io_err)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    let pid = std::fs::read_to_string(&path).unwrap_or_default().trim().to_string();
                    let pid = if pid.is_empty() { "unknown".to_string() } else { pid };
                    return Err(LockError::Held { dir: dir.to_path_buf(), pid });
                }
                Err(TryLockError::Error(e)) if e.kind() == io::ErrorKind::Unsupported => {
                    return Ok(FolderLock { path, file: None });
                }
                Err(TryLockError::Error(e)) => return Err(io_err(e)),
            }
            // The previous holder removes the file on release; if it did so after we opened it,
            // we hold a lock on an orphaned file that a third process would not see: start over.
            if !same_file(&path, &file) {
                continue;
            }
            file.set_len(0).and_then(|()| write!(file, "{}", std::process::id())).map_err(io_err)?;
            return Ok(FolderLock { path, file: Some(file) });
        }
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        // removed while still locked, so a waiting process that opened it starts over
        if self.file.is_some() {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

#[cfg(unix)]
fn same_file(path: &Path, file: &File) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(path), file.metadata()) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(path: &Path, _file: &File) -> bool {
    path.is_file()
}

/// Whether `name` is one of the project's temporary names: `.<name>.tmp<digits>`.
pub fn is_temp_name(name: &str) -> bool {
    let Some(rest) = name.strip_prefix('.') else { return false };
    match rest.rfind(".tmp") {
        Some(i) => {
            let digits = &rest[i + 4..];
            i > 0 && !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
        }
        None => false,
    }
}

/// Remove the temporary files (see [`is_temp_name`]) in `dir` and its subfolders down to
/// `depth` levels (0: `dir` only), as left by a killed writer; returns what was removed. Call it
/// only while holding `dir`'s lock: a live writer's temporary files look the same. The depth
/// keeps it to the folders our writers write (an `--out` given as a big folder is not searched
/// through). A missing `dir` has nothing to remove.
pub fn remove_stale_temps(dir: &Path, depth: usize) -> io::Result<Vec<PathBuf>> {
    let mut removed = Vec::new();
    let mut stack = vec![(dir.to_path_buf(), 0)];
    while let Some((d, level)) = stack.pop() {
        let entries = match std::fs::read_dir(&d) {
            Ok(e) => e,
            Err(e) if e.kind() == io::ErrorKind::NotFound => continue,
            Err(e) => return Err(io::Error::new(e.kind(), format!("{}: cannot list ({e})", d.display()))),
        };
        for entry in entries {
            let entry = entry?;
            let kind = entry.file_type()?;
            if kind.is_dir() {
                if level < depth {
                    stack.push((entry.path(), level + 1));
                }
            } else if kind.is_file() && is_temp_name(&entry.file_name().to_string_lossy()) {
                std::fs::remove_file(entry.path()).map_err(|e| {
                    io::Error::new(
                        e.kind(),
                        format!("{}: cannot remove this stale temporary file ({e})", entry.path().display()),
                    )
                })?;
                removed.push(entry.path());
            }
        }
    }
    removed.sort();
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events::sinks::test_util::temp_dir;

    #[test]
    fn a_second_writer_is_refused_with_the_holders_pid_until_the_first_lets_go() {
        let dir = temp_dir("held");
        let first = FolderLock::acquire(&dir).unwrap();
        assert_eq!(std::fs::read_to_string(dir.join(LOCK_FILE)).unwrap(), std::process::id().to_string());
        // flock locks belong to the open file, so a second open in this process conflicts as
        // another process's would
        let err = FolderLock::acquire(&dir).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, LockError::Held { .. }), "{msg}");
        assert!(msg.contains(&format!("pid {}", std::process::id())) && msg.contains(&*dir.to_string_lossy()), "{msg}");
        drop(first);
        assert!(!dir.join(LOCK_FILE).exists(), "the lock file is removed on release");
        let again = FolderLock::acquire(&dir).unwrap();
        drop(again);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_lock_file_left_by_a_dead_process_does_not_block() {
        let dir = temp_dir("dead");
        std::fs::write(dir.join(LOCK_FILE), "999999").unwrap(); // no process holds it
        let lock = FolderLock::acquire(&dir).unwrap();
        assert_eq!(std::fs::read_to_string(dir.join(LOCK_FILE)).unwrap(), std::process::id().to_string());
        drop(lock);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_folder_is_an_error_naming_the_lock_file() {
        let dir = std::env::temp_dir().join(format!("evblur-lock-missing-{}", std::process::id()));
        let err = FolderLock::acquire(&dir).unwrap_err();
        assert!(matches!(err, LockError::Io { .. }) && err.to_string().contains(LOCK_FILE), "{err}");
    }

    #[test]
    fn temporary_names_are_recognised_and_only_those_removed() {
        for name in [".events.h5.tmp123", ".checkpoint.bin.tmp9", ".x.npz.t.tmp42", ".metrics.json.tmp1"] {
            assert!(is_temp_name(name), "{name}");
        }
        for name in ["events.h5", ".tmp12", ".a.tmp", ".a.tmpx1", "a.tmp12", ".evblur.lock", "00.png"] {
            assert!(!is_temp_name(name), "{name}");
        }
        let dir = temp_dir("temps");
        std::fs::create_dir_all(dir.join("images_1/deeper")).unwrap();
        let files =
            [".events.h5.tmp77", "images_1/.00.png.tmp77", "images_1/deeper/.x.tmp77", "events.h5", "images_1/00.png"];
        for f in files {
            std::fs::write(dir.join(f), "x").unwrap();
        }
        let removed = remove_stale_temps(&dir, 1).unwrap();
        assert_eq!(removed, vec![dir.join(".events.h5.tmp77"), dir.join("images_1/.00.png.tmp77")]);
        assert!(dir.join("events.h5").is_file() && dir.join("images_1/00.png").is_file());
        assert!(dir.join("images_1/deeper/.x.tmp77").is_file(), "below the depth: left alone");
        assert_eq!(remove_stale_temps(&dir, 2).unwrap(), vec![dir.join("images_1/deeper/.x.tmp77")]);
        assert!(remove_stale_temps(&dir.join("absent"), 3).unwrap().is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
