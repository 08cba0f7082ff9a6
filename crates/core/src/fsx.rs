//! Atomic output: every file and folder the tools write appears complete or not at all.
//! Files are written to a temporary sibling and renamed; folders are assembled in a staging
//! sibling and renamed into place when complete. An interrupted run leaves only a hidden
//! `.NAME.tmp-PID` sibling, which the staging guard removes when it is dropped; a run killed
//! outright (kill -9, power loss) cannot clean up, so the next write of the same NAME removes
//! the siblings whose process is gone ([`clean_stale`]).

use crate::CoreError;
use std::path::{Path, PathBuf};

fn sibling(path: &Path, tag: &str) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.{tag}-{}", std::process::id()))
}

/// The process id in a sibling's name `.NAME.TAG-PID`, for `NAME` and one of our tags.
fn sibling_pid(file_name: &str, name: &str) -> Option<u32> {
    let rest = file_name.strip_prefix('.')?.strip_prefix(name)?;
    let pid = rest.strip_prefix(".tmp-").or_else(|| rest.strip_prefix(".old-"))?;
    if pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// Whether process `pid` may still be running. Linux answers through `/proc`; elsewhere
/// nothing is known, so every process counts as running and nothing is removed.
fn process_may_run(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    if cfg!(target_os = "linux") && Path::new("/proc/self").exists() {
        Path::new("/proc").join(pid.to_string()).exists()
    } else {
        true
    }
}

/// Remove what killed runs left beside `path`: the hidden `.NAME.tmp-PID` (a file or folder
/// being written) and `.NAME.old-PID` (the previous output during a replacement) of every
/// process that is gone. When `path` itself is missing and a stale `.NAME.old-PID` exists, the
/// run was killed between the two renames of a replacement: that previous output is put back
/// first, so a kill never loses what was there before. Siblings of running processes (another
/// run writing the same output now) are left alone.
pub fn clean_stale(path: &Path) -> Result<(), CoreError> {
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return Ok(());
    };
    let parent = match path.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(p) => p.to_path_buf(),
        None => PathBuf::from("."),
    };
    let Ok(entries) = std::fs::read_dir(&parent) else { return Ok(()) };
    let mut stale: Vec<(PathBuf, bool)> = Vec::new();
    for entry in entries.flatten() {
        let file_name = entry.file_name().to_string_lossy().into_owned();
        if let Some(pid) = sibling_pid(&file_name, &name)
            && !process_may_run(pid)
        {
            let is_old = file_name.ends_with(&format!(".old-{pid}"));
            stale.push((entry.path(), is_old));
        }
    }
    let mut restored = path.symlink_metadata().is_ok();
    for (p, is_old) in &stale {
        if *is_old && !restored {
            std::fs::rename(p, path).map_err(|e| CoreError::io(path, e))?;
            tracing::info!(
                "{}: put back the output that a killed run was replacing",
                path.display()
            );
            restored = true;
            continue;
        }
        let removed = if p.is_dir() && !p.is_symlink() {
            std::fs::remove_dir_all(p)
        } else {
            std::fs::remove_file(p)
        };
        match removed {
            Ok(()) => tracing::info!("removed {}, left by a killed run", p.display()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(CoreError::io(p, e)),
        }
    }
    Ok(())
}

/// Bytes of memory the machine has available now (Linux: `MemAvailable` of `/proc/meminfo`),
/// or `None` where that is not known.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Read a whole input file that must be a regular file (a FIFO could block, a device such as
/// `/dev/zero` never end) and must fit the memory available; the read stops at the size seen
/// first, so a file that grows meanwhile stays bounded.
pub fn read_regular_file(path: &Path) -> Result<Vec<u8>, CoreError> {
    use std::io::{Error, ErrorKind, Read};
    let meta = std::fs::metadata(path).map_err(|e| CoreError::io(path, e))?;
    if !meta.is_file() {
        let what =
            if meta.is_dir() { "a folder" } else { "not a regular file (a FIFO or a device)" };
        return Err(CoreError::io(path, Error::new(ErrorKind::InvalidInput, what)));
    }
    let len = meta.len();
    if let Some(free) = available_memory()
        && len > free
    {
        let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
        let msg = format!(
            "the file holds {:.1} GiB, more than the {:.1} GiB of memory available",
            gib(len),
            gib(free)
        );
        return Err(CoreError::io(path, Error::new(ErrorKind::OutOfMemory, msg)));
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(len).read_to_end(&mut bytes))
        .map_err(|e| CoreError::io(path, e))?;
    Ok(bytes)
}

/// Whether `path` lies inside a staging folder (an ancestor named `.NAME.tmp-PID`): that
/// folder is new, so nothing stale can stand beside its files.
fn inside_staging(path: &Path) -> bool {
    path.ancestors().skip(1).filter_map(Path::file_name).any(|n| {
        let n = n.to_string_lossy();
        n.starts_with('.')
            && n.rsplit_once(".tmp-")
                .is_some_and(|(_, pid)| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
    })
}

/// Write `bytes` to `path` atomically (temporary sibling, then rename). Temporaries that a
/// killed run left for the same path are removed first ([`clean_stale`]), except inside a
/// staging folder, which holds none (so a dataset's thousand views read no folder listing).
/// The temporary is created afresh, never opened through a link someone left in its place.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CoreError> {
    write_atomic_with(path, bytes, false)
}

/// [`write_atomic`], and on the disk before it returns: the temporary's data is synced
/// before the rename and the folder after it, so a power cut leaves the old file or the new
/// one, never an empty one. For what a person saves (an edited layout); a dataset's views
/// do without (a sync per file would slow them tenfold, and a lost view is written again).
pub fn write_durable(path: &Path, bytes: &[u8]) -> Result<(), CoreError> {
    write_atomic_with(path, bytes, true)
}

fn write_atomic_with(path: &Path, bytes: &[u8], sync: bool) -> Result<(), CoreError> {
    use std::io::Write;
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
    if let Some(parent) = parent {
        std::fs::create_dir_all(parent).map_err(|e| CoreError::io(parent, e))?;
    }
    if !inside_staging(path) {
        clean_stale(path)?;
    }
    let tmp = sibling(path, "tmp");
    let written = create_fresh(&tmp).and_then(|mut f| {
        f.write_all(bytes)?;
        if sync { f.sync_all() } else { Ok(()) }
    });
    if let Err(e) = written {
        // a disk that fills up part way leaves no half-written temporary behind
        let _ = std::fs::remove_file(&tmp);
        return Err(CoreError::io(&tmp, e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        CoreError::io(path, e)
    })?;
    if sync {
        // the rename itself is durable once the folder is; a folder that cannot be opened
        // for syncing (some platforms) keeps the rename the file system gives
        let dir = parent.unwrap_or(Path::new("."));
        if let Ok(d) = std::fs::File::open(dir) {
            d.sync_all().map_err(|e| CoreError::io(dir, e))?;
        }
    }
    Ok(())
}

/// Create `path` as a new file for writing: `create_new` (O_CREAT | O_EXCL) refuses an
/// existing name, symbolic links included, so nothing is written through a link left at the
/// temporary's name. What is there (our own process's leftover, or such a link) is removed
/// (the link, not what it points to) and the file created once more; if something takes
/// the name again in between, the error says so.
fn create_fresh(path: &Path) -> std::io::Result<std::fs::File> {
    let mut o = std::fs::OpenOptions::new();
    o.write(true).create_new(true);
    match o.open(path) {
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            std::fs::remove_file(path)?;
            o.open(path)
        }
        r => r,
    }
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
    /// mistyped path never destroys earlier results. What a killed run left for `target` is
    /// cleaned up first ([`clean_stale`]).
    pub fn new(target: &Path, overwrite: bool) -> Result<Self, CoreError> {
        clean_stale(target)?;
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

    /// A file name beside `path` as a run of process `pid` names its temporaries.
    fn left_by(path: &Path, tag: &str, pid: u32) -> PathBuf {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        path.with_file_name(format!(".{name}.{tag}-{pid}"))
    }

    /// A process id that no running process has (the highest id Linux hands out, plus one).
    const GONE: u32 = 4_194_305;

    #[test]
    fn what_a_killed_run_left_is_removed_by_the_next_write() {
        let root = scratch("stale");
        let field = root.join("field.safetensors");
        let dead_tmp = left_by(&field, "tmp", GONE);
        std::fs::write(&dead_tmp, b"half a tensor").unwrap();
        // a temporary of a running process (this one's parent, say) is someone's write now
        let live = left_by(&field, "tmp", std::os::unix::process::parent_id());
        std::fs::write(&live, b"being written").unwrap();
        // look-alikes that are not ours stay
        let other = root.join(".field.safetensors.tmp-12x");
        std::fs::write(&other, b"not ours").unwrap();
        write_atomic(&field, b"whole").unwrap();
        assert!(!dead_tmp.exists(), "the killed run's temporary must go");
        assert!(live.exists() && other.exists());
        // a staging folder of a killed run goes when the folder is next made
        let out = root.join("render");
        let dead_dir = left_by(&out, "tmp", GONE);
        std::fs::create_dir_all(dead_dir.join("views")).unwrap();
        std::fs::write(dead_dir.join("views/0.png"), b"png").unwrap();
        let s = StagingDir::new(&out, false).unwrap();
        assert!(!dead_dir.exists());
        s.commit().unwrap();
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_replacement_killed_between_its_renames_gets_the_old_output_back() {
        let root = scratch("killed-commit");
        let out = root.join("lib");
        // killed after `lib` became `.lib.old-PID` and before the staged folder took its place
        let old = left_by(&out, "old", GONE);
        std::fs::create_dir_all(&old).unwrap();
        std::fs::write(old.join("index.ron"), "earlier").unwrap();
        let staged = left_by(&out, "tmp", GONE);
        std::fs::create_dir_all(&staged).unwrap();
        clean_stale(&out).unwrap();
        assert_eq!(std::fs::read_to_string(out.join("index.ron")).unwrap(), "earlier");
        assert!(!old.exists() && !staged.exists());
        // and the usual rule holds again: it exists, so it is not replaced without --force
        assert!(StagingDir::new(&out, false).is_err());
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn files_inside_a_staging_folder_skip_the_stale_scan() {
        assert!(inside_staging(Path::new("runs/.d.tmp-123/train/r_0.png")));
        assert!(inside_staging(Path::new(".lib.tmp-9/index.ron")));
        assert!(!inside_staging(Path::new("runs/d/train/r_0.png")));
        assert!(!inside_staging(Path::new("runs/.d.tmp-12x/a.png")));
        // the file's own name does not count: a temporary is not written atomically
        assert!(!inside_staging(Path::new("runs/.f.tmp-5")));
    }

    #[test]
    fn inputs_must_be_regular_files() {
        let root = scratch("regular");
        let f = root.join("x.safetensors");
        std::fs::write(&f, b"abc").unwrap();
        assert_eq!(read_regular_file(&f).unwrap(), b"abc");
        // /dev/zero would be read for ever, a folder is no file
        for p in [Path::new("/dev/zero"), root.as_path()] {
            if p.exists() {
                let e = read_regular_file(p).unwrap_err().to_string();
                assert!(e.contains("not a regular file") || e.contains("a folder"), "{e}");
            }
        }
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

    #[cfg(unix)]
    #[test]
    fn the_temporary_is_never_written_through_a_link() {
        let dir = std::env::temp_dir().join(format!("af-fsx-link-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let victim = dir.join("victim.txt");
        std::fs::write(&victim, "keep me").unwrap();
        let target = dir.join("saved.ron");
        // a link planted at the name this process's temporary takes
        std::os::unix::fs::symlink(&victim, sibling(&target, "tmp")).unwrap();
        write_durable(&target, b"new text").unwrap();
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep me");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new text");
        assert!(!std::fs::symlink_metadata(&target).unwrap().file_type().is_symlink());
        assert!(!sibling(&target, "tmp").exists(), "no temporary left");
        write_atomic(&target, b"again").unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "again");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
