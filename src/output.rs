//! Publishing results. Every file lensbake writes goes through [`write_file`] (a uniquely named
//! temporary file in the destination's directory, fsynced, renamed over the destination, the
//! directory fsynced), and every result that is a directory of files through [`publish_dir`]
//! (the files are staged in a temporary directory beside the destination, which then takes the
//! destination's place in one exchange). A reader, or a run killed at any instant, therefore sees
//! the old complete result or the new complete one, never a mixture.
//!
//! Temporary names are `.<destination name>.<process id>.<random>.tmp`, so two writers never
//! share one, and a later writer to the same destination removes the ones whose process is gone
//! (a run killed by SIGKILL cannot clean up after itself).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// How every OpenEXR file lensbake writes is laid out: run-length coded 64 x 64 tiles, as the
/// exr crate's default, but stored in increasing order. The default order leaves blocks where the
/// parallel compressor finished them, so the same image gave different bytes from run to run.
pub fn reproducible_exr_encoding() -> exr::prelude::Encoding {
    exr::prelude::Encoding {
        line_order: exr::prelude::LineOrder::Increasing,
        ..exr::prelude::Encoding::FAST_LOSSLESS
    }
}

/// Written into every published directory: its presence says lensbake may replace the directory
/// as a whole.
pub const PUBLISHED_MARKER: &str = ".lensbake-output";

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("writing {path}: {}", describe_io(.error))]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("refusing to replace {path}: {reason}")]
    Refused { path: PathBuf, reason: String },
}

impl OutputError {
    /// The cause without the path, for errors that name the path themselves.
    pub fn cause(&self) -> String {
        match self {
            OutputError::Io { error, .. } => describe_io(error),
            OutputError::Refused { reason, .. } => format!("refusing to replace it: {reason}"),
        }
    }

    fn io(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
        move |error| OutputError::Io {
            path: path.to_path_buf(),
            error,
        }
    }
}

/// An I/O error as a sentence for a user: the operating system's own words without the
/// "(os error N)" code, and without the name of a temporary file that the user never asked for
/// (`tempfile` appends "at path ...").
pub fn describe_io(error: &std::io::Error) -> String {
    let text = error.to_string();
    let cut = [" (os error", " at path "]
        .iter()
        .filter_map(|marker| text.find(marker))
        .min()
        .unwrap_or(text.len());
    let mut plain = text[..cut].to_string();
    // The OS capitalises its sentence ("No such file"); after a colon it reads lower case.
    // Acronyms ("EOF") stay as they are.
    let mut chars = plain.chars();
    if let (Some(first), Some(second)) = (chars.next(), chars.next())
        && first.is_uppercase()
        && second.is_lowercase()
    {
        plain.replace_range(..first.len_utf8(), &first.to_lowercase().to_string());
    }
    plain
}

/// Refuses to write into a folder that is not there (the OS would name only the temporary file).
fn check_folder(path: &Path, dir: &Path) -> Result<(), OutputError> {
    if dir.is_dir() {
        return Ok(());
    }
    let reason = if dir.exists() {
        format!("{} is not a folder", dir.display())
    } else {
        format!("the folder {} does not exist", dir.display())
    };
    Err(OutputError::Io {
        path: path.to_path_buf(),
        error: std::io::Error::new(std::io::ErrorKind::NotFound, reason),
    })
}

/// Refuses a destination that replacing would surprise its owner: a symbolic link (the rename
/// would replace the link, not the file it names), a file marked read-only (a rename ignores that
/// mark, and root ignores every permission), anything that is not a plain file or folder of the
/// kind asked for, and a destination among the system's device and kernel folders, where root
/// could otherwise create files (`/dev/full.png`).
fn check_destination(path: &Path, kind: Temporary) -> Result<(), OutputError> {
    let refuse = |reason: String| OutputError::Refused {
        path: path.to_path_buf(),
        reason,
    };
    if let Ok(meta) = std::fs::symlink_metadata(path) {
        let kind_matches = match kind {
            Temporary::File => meta.is_file(),
            Temporary::Directory => meta.is_dir(),
        };
        if meta.file_type().is_symlink() {
            return Err(refuse(
                "it is a symbolic link; remove it or name the file it points to".into(),
            ));
        }
        if !kind_matches {
            return Err(refuse(match kind {
                Temporary::File => "it is not a plain file".into(),
                Temporary::Directory => "it is not a directory".into(),
            }));
        }
        if meta.permissions().readonly() {
            return Err(refuse(
                "it is read-only; make it writable first if it may be replaced".into(),
            ));
        }
    }
    let folder = std::fs::canonicalize(parent_of(path)).unwrap_or_default();
    if let Some(system) = ["/dev", "/proc", "/sys"]
        .iter()
        .find(|system| folder.starts_with(system))
    {
        return Err(refuse(format!(
            "{system} holds the system's devices and kernel state, not output files"
        )));
    }
    Ok(())
}

/// The directory holding `path` ("." for a bare file name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    }
}

fn name_of(path: &Path) -> Result<String, OutputError> {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| OutputError::Refused {
            path: path.to_path_buf(),
            reason: "the path names no file or directory".into(),
        })
}

/// What [`temporary`] creates.
#[derive(Clone, Copy)]
enum Temporary {
    File,
    Directory,
}

/// Creates (with `create`) a temporary file or directory named for the destination `name`:
/// `.<name>.<pid>.<random>.tmp`. It is created with the modes any new file or directory gets
/// (read and write for all, less the umask): tempfile's private 0600 and 0700 would stay on the
/// published output, which the user's umask, not lensbake, should decide.
fn temporary<R>(
    name: &str,
    kind: Temporary,
    create: impl FnOnce(&tempfile::Builder) -> std::io::Result<R>,
) -> std::io::Result<R> {
    let prefix = format!(".{name}.{}.", std::process::id());
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = match kind {
            Temporary::File => 0o666,
            Temporary::Directory => 0o777,
        };
        builder.permissions(std::fs::Permissions::from_mode(mode));
    }
    #[cfg(not(unix))]
    let _ = kind;
    create(&builder)
}

/// Removes temporary files and directories left beside `name` in `dir` by writers that no longer
/// run. Only Linux can tell a live process from a dead one (`/proc`); elsewhere nothing is
/// removed, since the writer may still be at work.
fn remove_abandoned(dir: &Path, name: &str) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let prefix = format!(".{name}.");
    for entry in entries.flatten() {
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = file_name
            .strip_prefix(&prefix)
            .and_then(|r| r.strip_suffix(".tmp"))
        else {
            continue;
        };
        let Some(pid) = rest.split('.').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let path = entry.path();
            let _ = if path.is_dir() {
                std::fs::remove_dir_all(&path)
            } else {
                std::fs::remove_file(&path)
            };
        }
    }
}

/// Makes a rename inside `dir` durable. Best effort: some file systems refuse to fsync a
/// directory, and the rename itself has already happened.
fn sync_dir(dir: &Path) {
    if let Ok(handle) = File::open(dir) {
        let _ = handle.sync_all();
    }
}

/// Writes `path` atomically: `write` fills a buffered temporary file beside it, which is flushed,
/// fsynced and renamed over `path`. On any failure the temporary file is removed and `path` is
/// untouched.
pub fn write_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&File>) -> std::io::Result<()>,
) -> Result<(), OutputError> {
    let dir = parent_of(path);
    let name = name_of(path)?;
    check_folder(path, dir)?;
    check_destination(path, Temporary::File)?;
    remove_abandoned(dir, &name);
    let temp =
        temporary(&name, Temporary::File, |b| b.tempfile_in(dir)).map_err(OutputError::io(path))?;
    {
        let mut buffered = BufWriter::new(temp.as_file());
        write(&mut buffered)
            .and_then(|()| buffered.flush())
            .map_err(OutputError::io(path))?;
    }
    temp.as_file().sync_all().map_err(OutputError::io(path))?;
    temp.persist(path)
        .map_err(|error| OutputError::io(path)(error.error))?;
    sync_dir(dir);
    Ok(())
}

/// [`write_file`] of a byte string.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_file(path, |out| out.write_all(bytes))
}

/// Publishes the directory `dest` as a whole: `fill` writes the new contents into a staging
/// directory beside `dest`, which then replaces `dest` in one exchange (Linux `renameat2`
/// RENAME_EXCHANGE; elsewhere two renames, with a window where `dest` is absent). If `fill` fails,
/// or the process dies first, `dest` keeps its old contents.
///
/// An existing `dest` is replaced only when it is empty, was published by lensbake (it holds
/// [`PUBLISHED_MARKER`]), or holds nothing the new contents do not also name: a directory of the
/// user's own files is never swept away by a mistyped `--out`.
pub fn publish_dir<T, E: From<OutputError>>(
    dest: &Path,
    fill: impl FnOnce(&Path) -> Result<T, E>,
) -> Result<T, E> {
    let parent = parent_of(dest);
    let name = name_of(dest)?;
    check_destination(dest, Temporary::Directory)?;
    std::fs::create_dir_all(parent).map_err(OutputError::io(parent))?;
    remove_abandoned(parent, &name);
    let staging = temporary(&name, Temporary::Directory, |b| b.tempdir_in(parent))
        .map_err(OutputError::io(dest))?;
    let value = fill(staging.path())?;
    write_bytes(
        &staging.path().join(PUBLISHED_MARKER),
        b"Written by lensbake, which replaces this directory as a whole on its next run.\n",
    )?;
    check_replaceable(dest, staging.path())?;
    sync_dir(staging.path());
    let staged = staging.keep();
    swap_into_place(&staged, dest).inspect_err(|_| {
        let _ = std::fs::remove_dir_all(&staged);
    })?;
    sync_dir(parent);
    Ok(value)
}

/// An exclusive advisory lock on the folder `dir` (created if missing), held until the returned
/// handle drops; other lensbake writers that lock it wait. Where folders cannot be opened as
/// files (not Unix), nothing is locked.
pub fn lock_folder(dir: &Path) -> Result<Option<File>, OutputError> {
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    std::fs::create_dir_all(dir).map_err(OutputError::io(dir))?;
    let Ok(handle) = File::open(dir) else {
        return Ok(None);
    };
    handle.lock().map_err(OutputError::io(dir))?;
    Ok(Some(handle))
}

/// Creates the directory `dest`, which does not exist yet, with the files `files` (name, bytes)
/// in one rename: no reader ever sees it part-written. Ok(false), with nothing changed, when
/// another writer created `dest` first (two runs racing to make the same new directory).
pub fn create_dir_whole(dest: &Path, files: &[(&str, &[u8])]) -> Result<bool, OutputError> {
    let parent = parent_of(dest);
    let name = name_of(dest)?;
    std::fs::create_dir_all(parent).map_err(OutputError::io(parent))?;
    remove_abandoned(parent, &name);
    let staging = temporary(&name, Temporary::Directory, |b| b.tempdir_in(parent))
        .map_err(OutputError::io(dest))?;
    for (file, bytes) in files {
        write_bytes(&staging.path().join(file), bytes)?;
    }
    sync_dir(staging.path());
    if dest.exists() {
        return Ok(false);
    }
    let staged = staging.keep();
    // rename(2) replaces an empty directory but not one with files: a writer that lost the race
    // to a finished one fails here and leaves the winner's files alone.
    match std::fs::rename(&staged, dest) {
        Ok(()) => {
            sync_dir(parent);
            Ok(true)
        }
        Err(error) => {
            let _ = std::fs::remove_dir_all(&staged);
            if dest.is_dir() {
                Ok(false)
            } else {
                Err(OutputError::io(dest)(error))
            }
        }
    }
}

fn check_replaceable(dest: &Path, staged: &Path) -> Result<(), OutputError> {
    let Ok(entries) = std::fs::read_dir(dest) else {
        return Ok(());
    };
    if dest.join(PUBLISHED_MARKER).exists() {
        return Ok(());
    }
    for entry in entries {
        let entry = entry.map_err(OutputError::io(dest))?;
        if !staged.join(entry.file_name()).exists() {
            return Err(OutputError::Refused {
                path: dest.to_path_buf(),
                reason: format!(
                    "it holds {}, which this run does not write and lensbake did not publish; \
                     move it away or choose another output directory",
                    entry.file_name().to_string_lossy()
                ),
            });
        }
    }
    Ok(())
}

/// Puts the directory `staged` at `dest`; the old `dest`, if any, is removed afterwards.
fn swap_into_place(staged: &Path, dest: &Path) -> Result<(), OutputError> {
    if !dest.exists() {
        return std::fs::rename(staged, dest).map_err(OutputError::io(dest));
    }
    #[cfg(target_os = "linux")]
    {
        use rustix::fs::{CWD, RenameFlags, renameat_with};
        if renameat_with(CWD, staged, CWD, dest, RenameFlags::EXCHANGE).is_ok() {
            // `staged` now names the old contents.
            let _ = std::fs::remove_dir_all(staged);
            return Ok(());
        }
    }
    let parent = parent_of(dest);
    let old = temporary(&name_of(dest)?, Temporary::Directory, |b| {
        b.tempdir_in(parent)
    })
    .map_err(OutputError::io(dest))?
    .keep();
    std::fs::remove_dir(&old).map_err(OutputError::io(dest))?;
    std::fs::rename(dest, &old).map_err(OutputError::io(dest))?;
    if let Err(error) = std::fs::rename(staged, dest) {
        let _ = std::fs::rename(&old, dest);
        return Err(OutputError::io(dest)(error));
    }
    let _ = std::fs::remove_dir_all(&old);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("lensbake-output-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = scratch("failed-write");
        let path = dir.join("a.txt");
        write_bytes(&path, b"old").unwrap();
        let result = write_file(&path, |out| {
            out.write_all(b"half")?;
            Err(std::io::Error::other("encoder failed"))
        });
        assert!(result.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(names(&dir), ["a.txt"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Published files and directories take the modes the umask leaves (0644 and 0755 under
    /// the usual 022), not tempfile's private 0600 and 0700. The umask is read from /proc.
    #[cfg(target_os = "linux")]
    #[test]
    fn outputs_take_the_modes_the_umask_leaves() {
        use std::os::unix::fs::PermissionsExt;
        let status = std::fs::read_to_string("/proc/self/status").unwrap();
        let umask = status
            .lines()
            .find_map(|l| l.strip_prefix("Umask:"))
            .map(|m| u32::from_str_radix(m.trim(), 8).unwrap())
            .unwrap();
        let dir = scratch("modes");
        let file = dir.join("a.txt");
        write_bytes(&file, b"text").unwrap();
        let published = dir.join("folder");
        assert!(create_dir_whole(&published, &[("b.txt", b"text")]).unwrap());
        let mode = |path: &Path| std::fs::metadata(path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&file), 0o666 & !umask);
        assert_eq!(mode(&published), 0o777 & !umask);
        assert_eq!(mode(&published.join("b.txt")), 0o666 & !umask);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn temporaries_of_dead_writers_are_removed_and_live_ones_kept() {
        let dir = scratch("abandoned");
        // Process id 0 is never a user process, so its temporary file is abandoned.
        std::fs::write(dir.join(".a.txt.0.x1.tmp"), b"stray").unwrap();
        let live = format!(".a.txt.{}.x2.tmp", std::process::id());
        std::fs::write(dir.join(&live), b"in progress").unwrap();
        write_bytes(&dir.join("a.txt"), b"new").unwrap();
        assert_eq!(names(&dir), [live, "a.txt".to_string()]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_published_directory_is_replaced_whole_and_a_failed_one_not_at_all() {
        let dir = scratch("publish");
        let dest = dir.join("out");
        let publish = |files: &[&str]| {
            publish_dir(&dest, |stage| -> Result<(), OutputError> {
                for file in files {
                    write_bytes(&stage.join(file), file.as_bytes())?;
                }
                Ok(())
            })
        };
        publish(&["a", "b"]).unwrap();
        publish(&["c"]).unwrap();
        assert_eq!(names(&dest), [PUBLISHED_MARKER, "c"]);
        let failed = publish_dir(&dest, |stage| -> Result<(), OutputError> {
            write_bytes(&stage.join("d"), b"d")?;
            Err(OutputError::Refused {
                path: stage.to_path_buf(),
                reason: "a bad argument found late".into(),
            })
        });
        assert!(failed.is_err());
        assert_eq!(names(&dest), [PUBLISHED_MARKER, "c"]);
        assert_eq!(names(&dir), ["out"], "no staging directory is left");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_directory_of_foreign_files_is_not_replaced() {
        let dir = scratch("foreign");
        std::fs::write(dir.join("thesis.tex"), b"mine").unwrap();
        let result = publish_dir(&dir, |stage| write_bytes(&stage.join("x.png"), b"png"));
        assert!(
            matches!(result, Err(OutputError::Refused { .. })),
            "{result:?}"
        );
        assert_eq!(names(&dir), ["thesis.tex"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn a_link_or_a_read_only_file_is_not_replaced() {
        use std::os::unix::fs::PermissionsExt;
        let dir = scratch("guarded");
        let target = dir.join("target.txt");
        std::fs::write(&target, b"the user's file").unwrap();
        let link = dir.join("link.png");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let error = write_bytes(&link, b"new").unwrap_err();
        assert!(error.to_string().contains("symbolic link"), "{error}");
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        let linked_dir = dir.join("linked-dir");
        std::os::unix::fs::symlink(&dir, &linked_dir).unwrap();
        let published = publish_dir(&linked_dir, |_| Ok::<(), OutputError>(()));
        assert!(published.unwrap_err().to_string().contains("symbolic link"));

        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o444)).unwrap();
        let error = write_bytes(&target, b"new").unwrap_err();
        assert!(error.to_string().contains("read-only"), "{error}");
        assert_eq!(std::fs::read(&target).unwrap(), b"the user's file");
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o644)).unwrap();
        write_bytes(&target, b"new").unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn nothing_is_written_among_the_system_devices() {
        if !Path::new("/dev").is_dir() {
            return;
        }
        let error = write_bytes(Path::new("/dev/lensbake-test-output.png"), b"x").unwrap_err();
        assert!(error.to_string().contains("devices"), "{error}");
        assert!(!Path::new("/dev/lensbake-test-output.png").exists());
    }
}
