//! The files the apps write (CSV, PNG, SVG, reports, scenes, screenshots): checked before a long
//! run starts, written whole or not at all (a temporary file in the same folder, renamed into
//! place), so an interrupted or failed write never leaves a half-written file under the final
//! name, and claimed by one run at a time where two runs could pick the same name.
//!
//! Every error names the path: `cannot write PATH: why`.

use std::io;
use std::path::{Path, PathBuf};

/// `cannot write PATH: why`, keeping the kind of `error`.
pub fn cannot_write(path: &Path, error: impl std::fmt::Display, kind: io::ErrorKind) -> io::Error {
    io::Error::new(kind, format!("cannot write {}: {error}", path.display()))
}

/// A temporary path in `path`'s folder, unique to this process: renamed over `path` when the
/// file is complete.
pub fn temporary_beside(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Checks, before a run, that `path` can be written: it is not a folder, and its folder exists
/// and takes a new file.
///
/// # Errors
/// Naming the path and why it cannot be written.
pub fn check_writable(path: &Path) -> io::Result<()> {
    if path.is_dir() {
        return Err(cannot_write(path, "it is a folder; give a file name", io::ErrorKind::IsADirectory));
    }
    let probe = temporary_beside(path);
    std::fs::write(&probe, b"")
        .and_then(|()| std::fs::remove_file(&probe))
        .map_err(|e| cannot_write(path, &e, e.kind()))
}

/// Moves the complete temporary file `temporary` to `path`.
///
/// # Errors
/// Naming the path; the temporary file is removed.
pub fn rename_into_place(temporary: &Path, path: &Path) -> io::Result<()> {
    std::fs::rename(temporary, path).map_err(|e| {
        let _ = std::fs::remove_file(temporary);
        cannot_write(path, &e, e.kind())
    })
}

/// Writes `bytes` to `path` whole: to a temporary file beside it first, then renamed into place.
///
/// # Errors
/// Naming the path (a full disk, a missing folder); no file is left under either name.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let temporary = temporary_beside(path);
    if let Err(e) = std::fs::write(&temporary, bytes) {
        let _ = std::fs::remove_file(&temporary);
        return Err(cannot_write(path, &e, e.kind()));
    }
    rename_into_place(&temporary, path)
}

/// An exclusive claim on an output name for one run, so that two runs in one folder do not
/// overwrite each other's results: `path.lock` exists while the run holds it.
#[derive(Debug)]
pub struct OutputLock {
    path: PathBuf,
}

impl OutputLock {
    /// Claims `output`.
    ///
    /// # Errors
    /// When another run holds it, saying how to choose another name.
    pub fn claim(output: &Path) -> io::Result<Self> {
        let path = output.with_file_name(format!(
            "{}.lock",
            output.file_name().map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned())
        ));
        match std::fs::OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(_) => Ok(Self { path }),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => Err(io::Error::new(
                e.kind(),
                format!(
                    "another run is writing {} ({} exists): give this one another output name, or delete the lock \
                     file if no run is writing there",
                    output.display(),
                    path.display()
                ),
            )),
            Err(e) => Err(cannot_write(output, &e, e.kind())),
        }
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_is_written_whole_and_a_second_claim_is_refused() {
        let dir = std::env::temp_dir().join(format!("cloth-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("result.csv");
        check_writable(&path).unwrap();
        write_atomically(&path, b"a,b\n").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"a,b\n");
        let claim = OutputLock::claim(&path).unwrap();
        let second = OutputLock::claim(&path).unwrap_err().to_string();
        assert!(second.starts_with("another run is writing"), "{second}");
        drop(claim);
        OutputLock::claim(&path).unwrap();
        // Nothing but the file is left in the folder: no temporary, no lock.
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["result.csv"]);
        let missing = dir.join("no/such/folder.csv");
        let e = write_atomically(&missing, b"x").unwrap_err().to_string();
        assert!(e.starts_with(&format!("cannot write {}: ", missing.display())), "{e}");
        assert!(check_writable(&dir).unwrap_err().to_string().contains("it is a folder"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
