//! Reading inputs and writing outputs safely.
//!
//! Inputs are read whole, from regular files only (a FIFO would block, a device never ends) and
//! up to a size cap, and each read is recorded so that a robot knows every file it came from.
//! Outputs are checked before any work (folder exists, target is a regular file the user may
//! write, not a file the run read) and written through an unpredictable temporary created
//! exclusively beside the target, then renamed over it; report folders are written whole into a
//! temporary folder and moved into place.

use std::cell::RefCell;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

use crate::error::{Error, Location, Result};

/// How much a read accepts, passed to every reader (robot file, URDF, meshes, CSV) by whoever
/// holds the user's settings; the default is 256 MiB per file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InputLimits {
    /// The largest input file, bytes.
    pub max_bytes: u64,
}

impl Default for InputLimits {
    fn default() -> Self {
        InputLimits { max_bytes: 256 << 20 }
    }
}

impl InputLimits {
    /// Limits of `mib` MiB per file.
    pub fn from_mib(mib: u64) -> Self {
        InputLimits {
            max_bytes: mib.saturating_mul(1 << 20),
        }
    }
}

thread_local! {
    /// One list per open [`recording_reads`] on this thread, innermost last.
    static RECORDINGS: RefCell<Vec<Vec<PathBuf>>> = const { RefCell::new(Vec::new()) };
}

/// Pops the recording it opened even if the recorded closure panics.
struct RecordingGuard;

impl Drop for RecordingGuard {
    fn drop(&mut self) {
        RECORDINGS.with(|r| r.borrow_mut().pop());
    }
}

/// Runs `f` and returns, with its value, every file read through this module (and every file
/// reported by [`note_read`]) on this thread meanwhile. Recordings nest: an outer one sees the
/// files of the inner ones too.
pub fn recording_reads<T>(f: impl FnOnce() -> T) -> (T, Vec<PathBuf>) {
    RECORDINGS.with(|r| r.borrow_mut().push(Vec::new()));
    let guard = RecordingGuard;
    let value = f();
    let files = RECORDINGS.with(|r| r.borrow_mut().last_mut().map(std::mem::take).unwrap_or_default());
    drop(guard);
    RECORDINGS.with(|r| {
        if let Some(outer) = r.borrow_mut().last_mut() {
            outer.extend(files.iter().cloned());
        }
    });
    (value, files)
}

/// Records that the run read `path` (for readers outside this module, e.g. plugin libraries).
pub fn note_read(path: &Path) {
    RECORDINGS.with(|r| {
        if let Some(files) = r.borrow_mut().last_mut()
            && !files.iter().any(|f| f == path)
        {
            files.push(path.to_path_buf());
        }
    });
}

/// What a file system entry is, for messages (`a FIFO`, `a folder`, ...).
fn kind_of(t: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a folder"
    } else if t.is_symlink() {
        "a symbolic link"
    } else if t.is_file() {
        "a regular file"
    } else {
        "not a regular file"
    }
}

/// Checks that `path` (symbolic links followed) is an existing regular file; the message says
/// what it is instead, without the path.
pub fn check_input_file(path: &Path) -> std::result::Result<(), String> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => Ok(()),
        Ok(m) => Err(format!(
            "is {}, not a regular file; armcomp reads inputs from regular files only",
            kind_of(m.file_type())
        )),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(if path.symlink_metadata().is_ok() {
            "is a symbolic link to nothing".to_string()
        } else {
            "does not exist".to_string()
        }),
        Err(e) => Err(format!("cannot read: {e}")),
    }
}

/// Reads a whole input file: a regular file within `limits`; recorded for
/// [`recording_reads`].
pub fn read_bytes(path: &Path, limits: InputLimits) -> Result<Vec<u8>> {
    let input = |message: String| Error::InputAt {
        location: Location::file(path),
        column: None,
        message,
    };
    check_input_file(path).map_err(input)?;
    let limit = limits.max_bytes;
    let file = std::fs::File::open(path).map_err(|e| input(format!("cannot read: {e}")))?;
    let mut bytes = Vec::new();
    // One byte past the cap tells a file at the cap from a larger one without reading it all.
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| input(format!("cannot read: {e}")))?;
    if bytes.len() as u64 > limit {
        return Err(input(format!(
            "larger than the input limit of {}; raise `max_input_mb` in the user config if it is meant to be this big",
            describe_bytes(limit)
        )));
    }
    note_read(path);
    Ok(bytes)
}

/// Reads a whole input file as UTF-8 text (see [`read_bytes`]); a leading byte-order mark is
/// dropped.
pub fn read_text(path: &Path, limits: InputLimits) -> Result<String> {
    let bytes = read_bytes(path, limits)?;
    let mut text = String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..at].iter().filter(|b| **b == b'\n').count() + 1;
        Error::InputAt {
            location: Location::line(path, line),
            column: None,
            message: format!("not UTF-8 text (byte {at} cannot be decoded)"),
        }
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

fn describe_bytes(bytes: u64) -> String {
    if bytes >= 1 << 20 && bytes.is_multiple_of(1 << 20) {
        format!("{} MB", bytes >> 20)
    } else {
        format!("{bytes} bytes")
    }
}

/// Temporaries of writes in progress, for [`remove_pending_temporaries`].
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A temporary listed in [`PENDING`] while it lives.
struct Pending(PathBuf);

impl Pending {
    fn new(path: &Path) -> Self {
        PENDING
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(path.to_path_buf());
        Pending(path.to_path_buf())
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        PENDING
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .retain(|p| *p != self.0);
    }
}

/// Removes the temporaries of writes still in progress (a file or a staged report folder), so
/// that a process stopped by a signal leaves none behind; the targets are untouched.
pub fn remove_pending_temporaries() {
    for p in PENDING.lock().unwrap_or_else(PoisonError::into_inner).drain(..) {
        let _ = if p.is_dir() {
            std::fs::remove_dir_all(&p)
        } else {
            std::fs::remove_file(&p)
        };
    }
}

/// The folder a target lives in (`.` for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Whether two paths name the same file (same device and inode on Unix, else the same
/// canonical path); paths that cannot be inspected are not the same.
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (std::fs::metadata(a), std::fs::metadata(b)) {
            (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        }
    }
}

/// The error for an output `path` that armcomp refuses to write, of `kind`, and why.
fn refusal(path: &Path, kind: std::io::ErrorKind) -> impl Fn(String) -> Error + '_ {
    move |message| Error::Io {
        path: path.to_path_buf(),
        kind,
        os_code: None,
        message,
    }
}

/// The error for the operating system's failure `e` at `path`, said as `message`.
fn os_failure(path: &Path, e: &std::io::Error, message: String) -> Error {
    Error::Io {
        path: path.to_path_buf(),
        kind: e.kind(),
        os_code: e.raw_os_error(),
        message,
    }
}

/// Checks, before any work, that `out` may be written as an output: its folder exists and the
/// user may create files there; it is absent or a regular file (not a symbolic link, FIFO,
/// device or folder) that is not read-only, that the user owns or could give back to its owner
/// and that is none of `inputs`.
pub fn check_output(out: &Path, inputs: &[PathBuf]) -> Result<()> {
    use std::io::ErrorKind::{InvalidInput, NotADirectory, NotFound, PermissionDenied};
    let refuse = refusal(out, InvalidInput);
    if out.file_name().is_none() {
        return Err(refuse("not a file name".into()));
    }
    let dir = folder_of(out);
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => {
            return Err(refusal(out, NotADirectory)(format!(
                "`{}` is not a folder",
                dir.display()
            )));
        }
        Err(_) => {
            return Err(refusal(out, NotFound)(format!(
                "the folder `{}` does not exist",
                dir.display()
            )));
        }
    }
    let existing = existing_target(out)?;
    if let Some(i) = inputs.iter().find(|i| same_file(out, i)) {
        return Err(refuse(format!(
            "refusing to overwrite an input: this run reads `{}`; choose another output",
            i.display()
        )));
    }
    // A probe created the way the real temporary will be: the folder must take new files, and
    // a target owned by someone else must be able to keep its owner.
    let probe = temporary_in(out, existing.as_ref()).map_err(|e| os_failure(out, &e, e.to_string()))?;
    if let Some(m) = &existing {
        keep_owner(probe.as_file(), m).map_err(refusal(out, PermissionDenied))?;
    }
    Ok(())
}

/// The metadata of an existing output target, refusing anything but a writable regular file.
fn existing_target(out: &Path) -> Result<Option<std::fs::Metadata>> {
    let m = match std::fs::symlink_metadata(out) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(os_failure(out, &e, format!("cannot inspect: {e}"))),
    };
    if !m.file_type().is_file() {
        return Err(refusal(out, std::io::ErrorKind::InvalidInput)(format!(
            "is {}; armcomp replaces only regular files, so choose another output",
            kind_of(m.file_type())
        )));
    }
    if m.permissions().readonly() {
        return Err(refusal(out, std::io::ErrorKind::PermissionDenied)(
            "is read-only; armcomp does not replace it".into(),
        ));
    }
    // Opening for writing (without truncating) asks the system whether this user may write it.
    std::fs::OpenOptions::new()
        .write(true)
        .open(out)
        .map_err(|e| os_failure(out, &e, format!("is not writable: {e}")))?;
    Ok(Some(m))
}

/// A new, unpredictable, exclusively created file beside `out`, with the target's permissions
/// (or the default ones for new files).
fn temporary_in(out: &Path, existing: Option<&std::fs::Metadata>) -> std::io::Result<tempfile::NamedTempFile> {
    let name = out.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
    remove_orphaned_temporaries(out, &name);
    // The process's id in the name tells a later write whether its writer still runs.
    let prefix = format!(".{name}.{}.", std::process::id());
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // The creation mode goes through the umask, as for any new file.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let tmp = builder.tempfile_in(folder_of(out))?;
    if let Some(m) = existing {
        tmp.as_file().set_permissions(m.permissions())?;
    }
    Ok(tmp)
}

/// Removes the temporaries of earlier writes of `out` whose process no longer runs: a process
/// killed outright (SIGKILL, a power cut) between writing and renaming leaves its temporary,
/// which no signal handler could remove. Only regular files of this user named as
/// [`temporary_in`] names them (`.<name>.<pid>.<random>.tmp`) are touched; where `/proc` does
/// not tell whether a process runs, none is.
fn remove_orphaned_temporaries(out: &Path, name: &str) {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::MetadataExt;
        let Ok(entries) = std::fs::read_dir(folder_of(out)) else {
            return;
        };
        let me = std::fs::metadata("/proc/self").map(|m| m.uid()).ok();
        let prefix = format!(".{name}.");
        for entry in entries.flatten() {
            let file = entry.file_name().to_string_lossy().into_owned();
            let Some(rest) = file.strip_prefix(&prefix).and_then(|r| r.strip_suffix(".tmp")) else {
                continue;
            };
            let Some((pid, random)) = rest.split_once('.') else {
                continue;
            };
            let ours = pid.parse::<u32>().is_ok_and(|p| p != std::process::id())
                && !random.is_empty()
                && random.chars().all(|c| c.is_ascii_alphanumeric());
            let gone = ours && !Path::new(&format!("/proc/{pid}")).exists();
            let regular = entry
                .metadata()
                .is_ok_and(|m| m.file_type().is_file() && Some(m.uid()) == me);
            if gone && regular {
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (out, name);
}

/// Gives `file` the owner of `target`, or says why the owner would change.
fn keep_owner(file: &std::fs::File, target: &std::fs::Metadata) -> std::result::Result<(), String> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let mine = file.metadata().map_err(|e| e.to_string())?;
        if (mine.uid(), mine.gid()) != (target.uid(), target.gid()) {
            std::os::unix::fs::fchown(file, Some(target.uid()), Some(target.gid())).map_err(|_| {
                let whose = if mine.uid() != target.uid() {
                    format!("is owned by another user (uid {})", target.uid())
                } else {
                    format!(
                        "belongs to a group this user cannot give files to (gid {})",
                        target.gid()
                    )
                };
                format!("{whose}; replacing it would change that, so choose another output")
            })?;
        }
    }
    #[cfg(not(unix))]
    let _ = (file, target);
    Ok(())
}

/// Writes `bytes` to `path` atomically: an unpredictable temporary created exclusively in the
/// same folder, synced, then renamed over the target, so a reader never sees half a file and a
/// failed write leaves any old file intact. The target must be absent or a writable regular
/// file; a replaced file keeps its permissions and owner.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let io = |e: std::io::Error| os_failure(path, &e, e.to_string());
    if path.file_name().is_none() {
        return Err(refusal(path, std::io::ErrorKind::InvalidInput)(
            "not a file name".into(),
        ));
    }
    let existing = existing_target(path)?;
    let mut tmp = temporary_in(path, existing.as_ref()).map_err(io)?;
    let _pending = Pending::new(tmp.path());
    if let Some(m) = &existing {
        keep_owner(tmp.as_file(), m).map_err(refusal(path, std::io::ErrorKind::PermissionDenied))?;
    }
    tmp.write_all(bytes).map_err(io)?;
    tmp.as_file().sync_all().map_err(io)?;
    // Dropping the temporary on any failure above removes it.
    tmp.persist(path).map_err(|e| io(e.error))?;
    Ok(())
}

/// Checks, before any work, that `dir` may receive a report: its parent folder exists; it is
/// absent, or a folder (not a link) holding only files a report writes (`is_report_file`), and
/// none of `inputs` lies in it.
pub fn check_report_folder(dir: &Path, is_report_file: &dyn Fn(&str) -> bool, inputs: &[PathBuf]) -> Result<()> {
    let refuse = refusal(dir, std::io::ErrorKind::InvalidInput);
    let os = |e: std::io::Error| os_failure(dir, &e, e.to_string());
    if dir.file_name().is_none() {
        return Err(refuse("not a folder name; name the report's own folder".into()));
    }
    let parent = folder_of(dir);
    if !parent.is_dir() {
        return Err(refusal(dir, std::io::ErrorKind::NotFound)(format!(
            "the folder `{}` does not exist",
            parent.display()
        )));
    }
    let m = match std::fs::symlink_metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(os_failure(dir, &e, format!("cannot inspect: {e}"))),
    };
    if !m.is_dir() {
        return Err(refuse(format!(
            "is {}; a report is written as a folder of its own",
            kind_of(m.file_type())
        )));
    }
    let canonical = std::fs::canonicalize(dir).map_err(os)?;
    if let Some(i) = inputs
        .iter()
        .find(|i| std::fs::canonicalize(i).is_ok_and(|c| c.starts_with(&canonical)))
    {
        return Err(refuse(format!(
            "holds `{}`, a file this run reads; the report replaces the folder, so choose another",
            i.display()
        )));
    }
    for entry in std::fs::read_dir(dir).map_err(os)? {
        let entry = entry.map_err(os)?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let regular = entry.file_type().is_ok_and(|t| t.is_file());
        if !regular || !is_report_file(&name) {
            return Err(refuse(format!(
                "holds `{name}`, which is not part of a report; the report replaces the folder, so give a new or empty one"
            )));
        }
    }
    Ok(())
}

/// Writes `files` (name, content) as the folder `dir`: into a temporary folder beside it, then
/// moved into place, replacing an earlier report folder, so `dir` never mixes two reports.
pub fn write_folder_atomic(dir: &Path, files: &[(String, Vec<u8>)]) -> Result<()> {
    let io = |e: std::io::Error| os_failure(dir, &e, e.to_string());
    let parent = folder_of(dir);
    let name = dir.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
    let hidden = |what: &str| {
        tempfile::Builder::new()
            .prefix(&format!(".{name}.{what}"))
            .tempdir_in(parent)
            .map_err(io)
    };
    let staged = hidden("new.")?;
    let _pending = Pending::new(staged.path());
    for (file, bytes) in files {
        let mut f = std::fs::File::create_new(staged.path().join(file)).map_err(io)?;
        f.write_all(bytes).map_err(io)?;
        f.sync_all().map_err(io)?;
    }
    if std::fs::symlink_metadata(dir).is_err() {
        std::fs::rename(staged.path(), dir).map_err(io)?;
        let _ = staged.keep();
        return Ok(());
    }
    // The old report moves onto an empty placeholder (rename replaces an empty folder), the new
    // one takes its place, and the old one is removed with the placeholder.
    let old = hidden("old.")?;
    std::fs::rename(dir, old.path()).map_err(io)?;
    if let Err(e) = std::fs::rename(staged.path(), dir) {
        let _ = std::fs::rename(old.path(), dir);
        let _ = old.keep();
        return Err(io(e));
    }
    let _ = staged.keep();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> tempfile::TempDir {
        tempfile::Builder::new().prefix(tag).tempdir().unwrap()
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_write_removes_the_temporary_a_killed_writer_left_and_nothing_else() {
        let dir = scratch("armcomp-io");
        let put = |name: &str| std::fs::write(dir.path().join(name), b"left").unwrap();
        // Above Linux's largest process id, so never running; pid 1 always runs.
        let orphan = ".out.csv.999999999.Ab3xYz.tmp";
        let running = ".out.csv.1.Ab3xYz.tmp";
        let other_output = ".other.csv.999999999.Ab3xYz.tmp";
        let not_ours = ".out.csv.999999999.tmp";
        for name in [orphan, running, other_output, not_ours] {
            put(name);
        }
        write_atomic(&dir.path().join("out.csv"), b"new").unwrap();
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        let mut kept = [not_ours, running, other_output, "out.csv"].map(String::from).to_vec();
        kept.sort();
        assert_eq!(left, kept);
    }

    #[test]
    fn atomic_write_replaces_content_keeps_mode_and_leaves_no_temp() {
        let dir = scratch("armcomp-io");
        let p = dir.path().join("out.txt");
        write_atomic(&p, b"one").unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o640)).unwrap();
        }
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o640);
        }
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert!(check_output(&p, std::slice::from_ref(&p)).is_err());
        assert!(check_output(&p, &[]).is_ok());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "the probe is gone");
    }

    #[cfg(unix)]
    #[test]
    fn links_fifos_and_read_only_files_are_never_replaced() {
        let dir = scratch("armcomp-io-links");
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, "keep").unwrap();
        let link = dir.path().join("link.txt");
        std::os::unix::fs::symlink(&victim, &link).unwrap();
        let e = write_atomic(&link, b"x").unwrap_err().to_string();
        assert!(e.contains("a symbolic link"), "{e}");
        assert!(check_output(&link, &[]).is_err());
        let ro = dir.path().join("ro.txt");
        std::fs::write(&ro, "keep").unwrap();
        let mut perms = std::fs::metadata(&ro).unwrap().permissions();
        perms.set_readonly(true);
        std::fs::set_permissions(&ro, perms).unwrap();
        assert!(write_atomic(&ro, b"x").unwrap_err().to_string().contains("read-only"));
        assert!(
            check_output(Path::new("/dev/null"), &[])
                .unwrap_err()
                .to_string()
                .contains("character device")
        );
        assert!(
            check_output(&dir.path().join("no/such/out.txt"), &[])
                .unwrap_err()
                .to_string()
                .contains("does not exist")
        );
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
        assert_eq!(std::fs::read_to_string(&ro).unwrap(), "keep");
    }

    #[cfg(unix)]
    #[test]
    fn a_replaced_file_keeps_its_owner() {
        use std::os::unix::fs::MetadataExt;
        let dir = scratch("armcomp-io-owner");
        let p = dir.path().join("theirs.txt");
        std::fs::write(&p, "old").unwrap();
        // Only a privileged user can hand a file to someone else; others cannot set this up.
        if std::os::unix::fs::chown(&p, Some(4242), Some(4242)).is_ok() {
            check_output(&p, &[]).unwrap();
            write_atomic(&p, b"new").unwrap();
            let m = std::fs::metadata(&p).unwrap();
            assert_eq!((m.uid(), m.gid()), (4242, 4242));
            assert_eq!(std::fs::read(&p).unwrap(), b"new");
        }
    }

    #[test]
    fn reads_are_capped_recorded_and_regular_only() {
        let dir = scratch("armcomp-io-read");
        let p = dir.path().join("in.txt");
        std::fs::write(&p, "\u{feff}abc").unwrap();
        let any = InputLimits::default();
        let (text, read) = recording_reads(|| read_text(&p, any).unwrap());
        assert_eq!(text, "abc", "the byte-order mark is dropped");
        assert_eq!(read, vec![p.clone()]);
        // The file is 6 bytes: a limit of 6 takes it, one of 5 names the limit it broke.
        assert!(read_text(&p, InputLimits { max_bytes: 6 }).is_ok());
        let e = read_text(&p, InputLimits { max_bytes: 5 }).unwrap_err().to_string();
        assert!(e.contains("larger than the input limit of 5 bytes"), "{e}");
        assert!(read_text(dir.path(), any).unwrap_err().to_string().contains("a folder"));
        #[cfg(unix)]
        assert!(
            read_text(Path::new("/dev/zero"), any)
                .unwrap_err()
                .to_string()
                .contains("character device")
        );
    }

    #[test]
    fn report_folders_are_replaced_whole_and_other_files_protected() {
        let dir = scratch("armcomp-io-report");
        let report = dir.path().join("report");
        let svg = |n: &str| n.ends_with(".svg") || n == "index.html";
        check_report_folder(&report, &svg, &[]).unwrap();
        write_folder_atomic(
            &report,
            &[("a.svg".into(), b"1".to_vec()), ("index.html".into(), b"1".to_vec())],
        )
        .unwrap();
        check_report_folder(&report, &svg, &[]).unwrap();
        write_folder_atomic(&report, &[("index.html".into(), b"2".to_vec())]).unwrap();
        let names: Vec<_> = std::fs::read_dir(&report)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["index.html"], "the old report's plots are gone with it");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temporary folder left"
        );
        std::fs::write(report.join("notes.txt"), "mine").unwrap();
        let e = check_report_folder(&report, &svg, &[]).unwrap_err().to_string();
        assert!(e.contains("notes.txt"), "{e}");
        let input = report.join("index.html");
        let e = check_report_folder(&report, &|_| true, &[input])
            .unwrap_err()
            .to_string();
        assert!(e.contains("a file this run reads"), "{e}");
    }
}
