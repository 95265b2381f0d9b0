//! The files the commands write: checked before a long run starts, written whole or not at all
//! (a temporary file in the same folder, renamed into place), so an interrupted or failed write
//! never leaves a half-written file under the final name.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

/// A temporary path in `path`'s folder, unique to this process: renamed over `path` when the
/// file is complete.
pub fn temporary_beside(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Checks, before a run, that `path` can be written: its folder exists and takes a new file.
///
/// # Errors
/// Naming the path and why it cannot be written.
pub fn check_writable(path: &Path) -> Result<()> {
    if path.is_dir() {
        bail!("cannot write {}: it is a folder; give a file name", path.display());
    }
    let probe = temporary_beside(path);
    std::fs::write(&probe, b"").with_context(|| format!("cannot write {}", path.display()))?;
    std::fs::remove_file(&probe).with_context(|| format!("cannot write {}", path.display()))
}

/// Moves the complete temporary file `temporary` to `path`.
///
/// # Errors
/// Naming the path; the temporary file is removed.
pub fn rename_into_place(temporary: &Path, path: &Path) -> Result<()> {
    std::fs::rename(temporary, path).map_err(|e| {
        let _ = std::fs::remove_file(temporary);
        anyhow::anyhow!("cannot write {}: {e}", path.display())
    })
}

/// Writes `bytes` to `path` whole: to a temporary file beside it first, then renamed into place.
///
/// # Errors
/// Naming the path (a full disk, a missing folder); no file is left under either name.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let temporary = temporary_beside(path);
    if let Err(e) = std::fs::write(&temporary, bytes) {
        let _ = std::fs::remove_file(&temporary);
        bail!("cannot write {}: {e}", path.display());
    }
    rename_into_place(&temporary, path)
}

/// An exclusive claim on an output name for one run, so that two runs in one folder do not
/// overwrite each other's results: `path.lock` exists while the run holds it.
pub struct OutputLock {
    path: PathBuf,
}

impl OutputLock {
    /// Claims `output`.
    ///
    /// # Errors
    /// When another run holds it, saying how to choose another name.
    pub fn claim(output: &Path) -> Result<Self> {
        let path = output.with_file_name(format!(
            "{}.lock",
            output.file_name().map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned())
        ));
        match std::fs::OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(_) => Ok(Self { path }),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => bail!(
                "another run is writing {} ({} exists): give this one another output name, or delete the lock \
                 file if no run is writing there",
                output.display(),
                path.display()
            ),
            Err(e) => bail!("cannot write {}: {e}", output.display()),
        }
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}
