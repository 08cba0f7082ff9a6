//! Atomic output: every file and folder the tools write appears complete or not at all.
//! Files are written to a temporary sibling and renamed; folders are assembled in a staging
//! sibling and renamed into place when complete. An interrupted run leaves only a hidden
//! `.NAME.tmp-PID` sibling, which the staging guard removes when it is dropped.

use crate::CoreError;
use std::path::{Path, PathBuf};

fn sibling(path: &Path, tag: &str) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.{tag}-{}", std::process::id()))
}

/// Write `bytes` to `path` atomically (temporary sibling, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CoreError> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| CoreError::io(parent, e))?;
    }
    let tmp = sibling(path, "tmp");
    if let Err(e) = std::fs::write(&tmp, bytes) {
        // a disk that fills up part way leaves no half-written temporary behind
        let _ = std::fs::remove_file(&tmp);
        return Err(CoreError::io(&tmp, e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        CoreError::io(path, e)
    })
}

/// Encode an image as PNG and write it atomically.
pub fn save_png(path: &Path, img: &image::DynamicImage) -> Result<(), CoreError> {
    let mut buf = std::io::Cursor::new(Vec::new());
    img.write_to(&mut buf, image::ImageFormat::Png)
        .map_err(|e| CoreError::Image { path: path.to_path_buf(), source: e })?;
    write_atomic(path, buf.get_ref())
}

/// A folder being assembled next to its final place; renamed into place by [`StagingDir::commit`],
/// removed if dropped before that (error, panic or Ctrl-C).
#[derive(Debug)]
pub struct StagingDir {
    staging: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl StagingDir {
    /// Start assembling `target`. Fails if `target` exists and `overwrite` is false, so that a
    /// mistyped path never destroys earlier results.
    pub fn new(target: &Path, overwrite: bool) -> Result<Self, CoreError> {
        if target.exists() && !overwrite {
            return Err(CoreError::io(
                target,
                std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    "output folder already exists (pass --force to replace it)",
                ),
            ));
        }
        if let Some(parent) = target.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| CoreError::io(parent, e))?;
        }
        let staging = sibling(target, "tmp");
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| CoreError::io(&staging, e))?;
        }
        std::fs::create_dir_all(&staging).map_err(|e| CoreError::io(&staging, e))?;
        Ok(StagingDir { staging, target: target.to_path_buf(), committed: false })
    }

    /// Where to write the folder's contents for now.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The final location.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Move the finished folder into place (replacing an older one, if allowed at creation).
    pub fn commit(mut self) -> Result<PathBuf, CoreError> {
        let old = sibling(&self.target, "old");
        let had_old = self.target.exists();
        if had_old {
            std::fs::rename(&self.target, &old).map_err(|e| CoreError::io(&self.target, e))?;
        }
        if let Err(e) = std::fs::rename(&self.staging, &self.target) {
            if had_old {
                let _ = std::fs::rename(&old, &self.target);
            }
            return Err(CoreError::io(&self.target, e));
        }
        self.committed = true;
        if had_old {
            let _ = std::fs::remove_dir_all(&old);
        }
        Ok(self.target.clone())
    }
}

impl Drop for StagingDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("assetfield-core-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn staging_commits_or_vanishes() {
        let root = scratch("staging");
        let target = root.join("out");
        {
            let s = StagingDir::new(&target, false).unwrap();
            std::fs::write(s.path().join("a.txt"), "half").unwrap();
            // dropped without commit: nothing appears
        }
        assert!(!target.exists());
        assert_eq!(std::fs::read_dir(&root).unwrap().count(), 0, "staging folder left behind");
        let s = StagingDir::new(&target, false).unwrap();
        std::fs::write(s.path().join("a.txt"), "full").unwrap();
        s.commit().unwrap();
        assert_eq!(std::fs::read_to_string(target.join("a.txt")).unwrap(), "full");
        assert!(
            StagingDir::new(&target, false).is_err(),
            "existing output must not be replaced silently"
        );
        let s = StagingDir::new(&target, true).unwrap();
        std::fs::write(s.path().join("b.txt"), "new").unwrap();
        s.commit().unwrap();
        assert!(!target.join("a.txt").exists() && target.join("b.txt").exists());
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn atomic_write_replaces_whole_file() {
        let root = scratch("atomic");
        let p = root.join("sub/x.json");
        write_atomic(&p, b"{}").unwrap();
        write_atomic(&p, b"{\"a\":1}").unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "{\"a\":1}");
        assert_eq!(std::fs::read_dir(root.join("sub")).unwrap().count(), 1);
        std::fs::remove_dir_all(&root).unwrap();
    }
}
