//! Output that is never half-written and never destroys an input.
//!
//! What kinpost does with an output path depends on what is there:
//!
//! - **A regular file, or nothing yet.** The output goes to a temporary file
//!   in the same directory, which is renamed over the path only when
//!   everything succeeded; on error the path is left untouched. The new file
//!   keeps the mode (and, where permitted, the owner) of the file it
//!   replaces; a new file gets the usual `0666` less the umask.
//! - **A symbolic link.** The link is followed: its target is written, the
//!   link stays. A target that does not exist yet is created, as a shell's
//!   `>` creates it; a loop of links is refused.
//! - **A file with several hard links.** The output is spooled and copied
//!   into the existing file on success, so every link sees the new content;
//!   a signal during the copy waits for it to end.
//! - **A character device or a FIFO** (`/dev/null`, `/dev/stdout`, a named
//!   pipe). The output is spooled and written to it directly on success;
//!   the device is never replaced.
//! - **A block device, a socket or a directory.** Refused.
//! - **One of the run's inputs** (same device and inode, whatever the path
//!   says). Refused before anything is written, as is a path given for two
//!   outputs of one run.
//!
//! Standard output is spooled through an anonymous temporary file (memory
//! stays flat) and copied out only on success, so a filter never hands a
//! half-converted program down the chain. An output path that is standard
//! output (`-`, `/dev/stdout`, the file a shell's `>` opened) is written
//! the same way, through the open descriptor. Standard input that is a
//! regular file counts as an input.
//!
//! Temporary files are registered while they exist; the binary calls
//! [`remove_temporaries_on_signal`] so that SIGINT, SIGTERM or SIGHUP remove
//! them before the process exits.

use crate::error::{Error, Result};
use std::fs::{File, Metadata};
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Size of the buffer between the writer and the file.
const BUFFER_BYTES: usize = 1 << 16;

/// A file's identity: device and inode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FileId {
    dev: u64,
    ino: u64,
}

impl FileId {
    #[cfg(unix)]
    fn of(m: &Metadata) -> Option<FileId> {
        use std::os::unix::fs::MetadataExt;
        Some(FileId {
            dev: m.dev(),
            ino: m.ino(),
        })
    }

    #[cfg(not(unix))]
    fn of(_: &Metadata) -> Option<FileId> {
        None
    }
}

/// The inputs opened by this process so far (identity and name as given).
/// (A handle of each input is kept open with it: while a file is open its
/// inode cannot be given to another file, so the identity stays the
/// input's even if its name is removed during the run.)
static INPUTS: Mutex<Vec<(FileId, String, Option<File>)>> = Mutex::new(Vec::new());

/// Temporary files that exist right now; removed on a signal.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Records that the file `f`, named `name` on the command line, is an input
/// of this run: no output may be written over it.
pub fn note_input(f: &File, name: &str) {
    if let Some(id) = f.metadata().ok().as_ref().and_then(FileId::of) {
        let mut inputs = INPUTS.lock().unwrap_or_else(|e| e.into_inner());
        if !inputs.iter().any(|(i, _, _)| *i == id) {
            inputs.push((id, name.to_string(), f.try_clone().ok()));
        }
    }
}

/// Opens the file at `path` for reading and records it as an input.
pub fn open_input(path: &Path) -> std::io::Result<File> {
    let f = File::open(path)?;
    note_input(&f, &path.display().to_string());
    Ok(f)
}

/// The name of the input that `m` is, if it is one.
fn input_named(m: &Metadata) -> Option<String> {
    let id = FileId::of(m)?;
    let inputs = INPUTS.lock().unwrap_or_else(|e| e.into_inner());
    inputs
        .iter()
        .find(|(i, _, _)| *i == id)
        .map(|(_, n, _)| n.clone())
}

/// The error for writing over input `input` through output `path`.
fn is_input(path: &Path, input: &str) -> Error {
    let p = path.display();
    if Path::new(input) == path {
        Error::Usage(format!(
            "{p} is an input of this run; refusing to write an output over it"
        ))
    } else {
        Error::Usage(format!(
            "{p} is the input {input} (the same file); refusing to write an output over it"
        ))
    }
}

/// Checks, before any work, that each output path can be written and is
/// none of `inputs` nor another output of the same run.
///
/// `outputs` pairs each path with the option that named it (for the
/// message). A path that does not exist yet is compared by its resolved
/// directory and name; one that exists by device and inode, so that a
/// symbolic or hard link to an input is caught as well.
pub fn check_outputs(outputs: &[(&str, Option<&Path>)], inputs: &[Option<&Path>]) -> Result<()> {
    let mut seen: Vec<(&str, &Path, Identity)> = Vec::new();
    for (flag, path) in outputs {
        let Some(path) = path.filter(|p| p.as_os_str() != "-") else {
            continue;
        };
        let name = path.display().to_string();
        let meta = std::fs::metadata(path).ok();
        if let Some(m) = &meta {
            kind_of(path, m)?;
        }
        let cannot = |kind: std::io::ErrorKind, why: String| {
            Err(Error::io(
                &name,
                std::io::Error::new(kind, format!("cannot be written: {why}")),
            ))
        };
        if meta.is_none() && path.as_os_str().as_encoded_bytes().ends_with(b"/") {
            return cannot(
                std::io::ErrorKind::InvalidInput,
                "a path ending in `/` names a directory; expected a file to write".into(),
            );
        }
        let created = match &meta {
            Some(_) => path.to_path_buf(),
            None => new_file_at(path).map_err(|e| Error::io(&name, e))?,
        };
        match created.parent() {
            Some(d) if !d.as_os_str().is_empty() && d.exists() && !d.is_dir() => {
                return cannot(
                    std::io::ErrorKind::InvalidInput,
                    format!("{} is a file, not a directory", d.display()),
                );
            }
            Some(d) if !d.as_os_str().is_empty() && !d.is_dir() => {
                return cannot(
                    std::io::ErrorKind::NotFound,
                    "its directory does not exist".into(),
                );
            }
            _ => {}
        }
        let id = Identity::of(path);
        for input in inputs.iter().flatten() {
            if Identity::of(input).same(&id) {
                return Err(is_input(path, &input.display().to_string()));
            }
        }
        if let Some(m) = &meta
            && let Some(input) = input_named(m)
        {
            return Err(is_input(path, &input));
        }
        if let Some((other, other_path, _)) = seen.iter().find(|(_, _, i)| i.same(&id)) {
            // Two outputs on one device (`-o /dev/null --report /dev/null`) are fine.
            if !matches!(
                meta.as_ref().map(|m| kind_of(path, m)),
                Some(Ok(Kind::Stream))
            ) {
                return Err(Error::Usage(format!(
                    "{flag} {name} and {other} {} name the same file; give each output its own path",
                    other_path.display()
                )));
            }
        }
        seen.push((flag, path, id));
    }
    Ok(())
}

/// How a path is identified for comparisons.
#[derive(Debug)]
enum Identity {
    /// An existing file.
    File(FileId),
    /// A path that does not exist (yet): its resolved directory and name.
    Path(PathBuf),
    /// Nothing to compare by.
    Unknown,
}

impl Identity {
    fn of(path: &Path) -> Identity {
        if let Some(id) = std::fs::metadata(path).ok().as_ref().and_then(FileId::of) {
            return Identity::File(id);
        }
        let Ok(path) = new_file_at(path) else {
            return Identity::Unknown;
        };
        let dir = directory_of(&path);
        match (std::fs::canonicalize(dir), path.file_name()) {
            (Ok(d), Some(n)) => Identity::Path(d.join(n)),
            _ => Identity::Unknown,
        }
    }

    fn same(&self, other: &Identity) -> bool {
        match (self, other) {
            (Identity::File(a), Identity::File(b)) => a == b,
            (Identity::Path(a), Identity::Path(b)) => a == b,
            _ => false,
        }
    }
}

/// What kind of thing an existing output path is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A regular file.
    File,
    /// A character device or FIFO: written directly, never replaced.
    Stream,
}

/// The kind of the existing path `path` (metadata `m`, symlinks followed),
/// or an error for what may not be written.
fn kind_of(path: &Path, m: &Metadata) -> Result<Kind> {
    let refuse = |what: &str| {
        Err(Error::io(
            path.display().to_string(),
            std::io::Error::new(std::io::ErrorKind::InvalidInput, what.to_string()),
        ))
    };
    let t = m.file_type();
    if t.is_file() {
        return Ok(Kind::File);
    }
    if t.is_dir() {
        return refuse("is a directory; expected a file to write");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() || t.is_fifo() {
            return Ok(Kind::Stream);
        }
        if t.is_block_device() {
            return refuse("is a block device; kinpost does not write over devices");
        }
        if t.is_socket() {
            return refuse("is a socket; expected a file to write");
        }
    }
    refuse("is not a regular file; expected a file to write")
}

/// Runs `f` with a writer for `path` (or standard output when `None`), and
/// commits the output only if `f` succeeds. See the module documentation for
/// what happens with each kind of path.
pub fn write_atomically<T>(
    path: Option<&Path>,
    f: impl FnOnce(&mut dyn Write) -> Result<T>,
) -> Result<T> {
    let Some(path) = path.filter(|p| !is_standard_output(p)) else {
        return spool_then(f, "<stdout>", |spool| {
            let stdout = std::io::stdout();
            let mut lock = stdout.lock();
            // A reader that stopped early (`| head`) takes no more; the
            // run's other outputs (a report) are still written, and the
            // run ends quietly ([`standard_output_closed`]).
            let copied = std::io::copy(spool, &mut lock).and_then(|_| lock.flush());
            match copied {
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                    STDOUT_CLOSED.store(true, std::sync::atomic::Ordering::Relaxed);
                    Ok(())
                }
                other => other,
            }
        });
    };
    let display = path.display().to_string();
    let meta = std::fs::metadata(path).ok();
    let kind = match &meta {
        Some(m) => {
            if let Some(input) = input_named(m) {
                return Err(is_input(path, &input));
            }
            Some(kind_of(path, m)?)
        }
        None => None,
    };
    let shared_inode = nlink(meta.as_ref()) > 1;
    if kind == Some(Kind::Stream) || shared_inode {
        // Devices, FIFOs and files with several links are written in place.
        let target = path.to_path_buf();
        return spool_then(f, &display, move |spool| {
            if let Some(input) = std::fs::metadata(&target)
                .ok()
                .as_ref()
                .and_then(input_named)
            {
                return Err(std::io::Error::other(format!(
                    "is the input {input}; refusing to write an output over it"
                )));
            }
            // A file with several links is rewritten in place: a signal
            // waits for the copy to end (the handler takes this lock), so
            // that the file holds its old content or the whole new one. Not
            // a device or FIFO, whose reader may never come.
            let _signals_wait = (kind == Some(Kind::File))
                .then(|| TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner()));
            let mut out = std::fs::OpenOptions::new()
                .write(true)
                .truncate(kind == Some(Kind::File))
                .open(&target)?;
            std::io::copy(spool, &mut out)?;
            out.flush()?;
            if kind == Some(Kind::File) {
                out.sync_all().ok();
            }
            Ok(())
        });
    }
    // A regular file or a new one: a temporary beside the real target.
    let target = match &meta {
        Some(_) => std::fs::canonicalize(path).map_err(|e| Error::io(&display, e))?,
        None => new_file_at(path).map_err(|e| Error::io(&display, e))?,
    };
    let dir = directory_of(&target);
    let (tmp, file) = Temporary::new(&dir, meta.as_ref()).map_err(|e| Error::io(&display, e))?;
    let mut w = BufWriter::with_capacity(BUFFER_BYTES, Writeback::new(file));
    let value = f(&mut w)?;
    let file = w
        .into_inner()
        .map_err(|e| Error::io(&display, e.into_error()))?
        .file;
    file.sync_all().ok();
    drop(file);
    // An input opened after the output was started is caught here, before the rename.
    if let Some(input) = std::fs::metadata(&target)
        .ok()
        .as_ref()
        .and_then(input_named)
    {
        return Err(is_input(path, &input));
    }
    tmp.persist(&target).map_err(|e| Error::io(&display, e))?;
    Ok(value)
}

/// Set when the reader of standard output stopped before the output
/// ended ([`write_atomically`]).
static STDOUT_CLOSED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether the reader of standard output stopped early (`kinpost … |
/// head`): the run's other outputs are written, and it ends quietly, as
/// other filters do (no summary, exit 0).
pub fn standard_output_closed() -> bool {
    STDOUT_CLOSED.load(std::sync::atomic::Ordering::Relaxed)
}

/// Whether the output path `path` is standard output: `-`, or the file,
/// device or pipe that standard output is (`/dev/stdout`, or the file a
/// shell's `>` or `>>` opened), which is then written through the open
/// descriptor, at its offset, not replaced.
fn is_standard_output(path: &Path) -> bool {
    if path.as_os_str() == "-" {
        return true;
    }
    #[cfg(unix)]
    {
        use std::os::fd::AsFd;
        let Ok(fd) = std::io::stdout().as_fd().try_clone_to_owned() else {
            return false;
        };
        let stdout = File::from(fd).metadata().ok();
        let out = std::fs::metadata(path).ok();
        matches!(
            (stdout.as_ref().and_then(FileId::of), out.as_ref().and_then(FileId::of)),
            (Some(a), Some(b)) if a == b
        )
    }
    #[cfg(not(unix))]
    false
}

/// A file being written that hands what it holds to the disk as it grows
/// (Linux: `sync_file_range` with `SYNC_FILE_RANGE_WRITE`, which starts the
/// write-back and does not wait for it), so that the `fsync` before the
/// rename finds little left to write and the run does not end waiting for
/// the disk. Elsewhere a plain file.
struct Writeback {
    file: File,
    /// Bytes written so far.
    written: u64,
    /// Bytes handed to the disk so far.
    started: u64,
}

impl Writeback {
    /// Bytes written between two starts of the write-back.
    const STEP_BYTES: u64 = 1 << 20;

    fn new(file: File) -> Writeback {
        Writeback {
            file,
            written: 0,
            started: 0,
        }
    }
}

impl Write for Writeback {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.file.write(buf)?;
        self.written += n as u64;
        if self.written - self.started >= Self::STEP_BYTES {
            #[cfg(target_os = "linux")]
            {
                use std::os::fd::AsRawFd;
                // SAFETY: a plain system call on an open descriptor of ours;
                // it only starts write-back of bytes already written. Its
                // result does not matter: the fsync before the rename is what
                // makes the file durable.
                unsafe {
                    libc::sync_file_range(
                        self.file.as_raw_fd(),
                        self.started as libc::off64_t,
                        (self.written - self.started) as libc::off64_t,
                        libc::SYNC_FILE_RANGE_WRITE,
                    );
                }
            }
            self.started = self.written;
        }
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// Writes `bytes` to a new file at `target` (for files that belong to
/// kinpost itself, such as the fitted-model cache, not to outputs named on
/// the command line): a temporary in the same directory, registered for
/// removal on a signal and removed on failure, then renamed over `target`.
/// Whatever `target` was (a file or a symbolic link) is replaced, never
/// followed; a reader sees the old entry or the whole new one. Not synced
/// to disk: callers treat a damaged file as absent.
pub fn replace_file(target: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let (tmp, mut file) = Temporary::new(&directory_of(target), None)?;
    file.write_all(bytes)?;
    drop(file);
    tmp.persist(target)
}

/// The directory `path` is in (`.` for a bare file name): where its
/// temporary goes, so that the rename stays on one file system.
fn directory_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Most symbolic links followed to find where a new output goes (the
/// limit of Linux's own path resolution).
const MAX_LINKS: usize = 40;

/// Where an output at `path`, which does not exist as a file, is created:
/// `path` itself, or, when `path` is a symbolic link whose target does not
/// exist yet, the end of that chain of links (a relative link read from its
/// own directory), as a shell's `>` creates it. A loop is an error.
fn new_file_at(path: &Path) -> std::io::Result<PathBuf> {
    let mut at = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        match std::fs::symlink_metadata(&at) {
            Ok(m) if m.file_type().is_symlink() => {
                let to = std::fs::read_link(&at)?;
                at = directory_of(&at).join(to);
            }
            _ => return Ok(at),
        }
    }
    Err(std::io::Error::other(
        "is a loop of symbolic links (or more than 40 in a chain); expected a file to write",
    ))
}

/// Whether two metadata are of the same file (device and inode); `true`
/// where the system does not say.
pub fn same_file(a: &Metadata, b: &Metadata) -> bool {
    match (FileId::of(a), FileId::of(b)) {
        (Some(x), Some(y)) => x == y,
        _ => true,
    }
}

/// Number of hard links of an existing file (1 when unknown).
fn nlink(m: Option<&Metadata>) -> u64 {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        m.map_or(1, |m| if m.is_file() { m.nlink() } else { 1 })
    }
    #[cfg(not(unix))]
    {
        let _ = m;
        1
    }
}

/// Runs `f` into an anonymous spool file and, on success, hands the spool
/// (rewound) to `deliver`.
fn spool_then<T>(
    f: impl FnOnce(&mut dyn Write) -> Result<T>,
    name: &str,
    deliver: impl FnOnce(&mut File) -> std::io::Result<()>,
) -> Result<T> {
    let spool = tempfile::tempfile().map_err(|e| Error::io("<spool>", e))?;
    let mut w = BufWriter::with_capacity(BUFFER_BYTES, spool);
    let value = f(&mut w)?;
    let mut spool = w
        .into_inner()
        .map_err(|e| Error::io("<spool>", e.into_error()))?;
    spool.rewind().map_err(|e| Error::io("<spool>", e))?;
    deliver(&mut spool).map_err(|e| Error::io(name, e))?;
    Ok(value)
}

/// A named temporary file in the output's directory, registered for removal
/// on a signal and removed when dropped unless persisted.
struct Temporary {
    path: PathBuf,
}

impl Temporary {
    /// Creates the temporary in `dir`, with the permissions (and owner, where
    /// permitted) of the file it will replace, `existing`, or else `0666`
    /// less the umask. Returns the temporary and its open file.
    fn new(dir: &Path, existing: Option<&Metadata>) -> std::io::Result<(Temporary, File)> {
        let mut builder = tempfile::Builder::new();
        builder.prefix(".kinpost-").suffix(".part");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            // Opened with this mode, so the umask applies as for any new file.
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        // Register under the lock so that a signal between creation and
        // registration cannot leave the file behind.
        let mut temporaries = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
        let (file, path) = builder.tempfile_in(dir)?.keep().map_err(|e| e.error)?;
        temporaries.push(path.clone());
        drop(temporaries);
        let tmp = Temporary { path };
        if let Some(m) = existing {
            file.set_permissions(m.permissions())?;
            #[cfg(unix)]
            {
                use std::os::unix::fs::MetadataExt;
                // Only root may give a file away; elsewhere this fails harmlessly.
                let _ = std::os::unix::fs::fchown(&file, Some(m.uid()), Some(m.gid()));
            }
        }
        Ok((tmp, file))
    }

    /// Renames the temporary over `target`.
    fn persist(mut self, target: &Path) -> std::io::Result<()> {
        let mut temporaries = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
        std::fs::rename(&self.path, target)?;
        temporaries.retain(|p| *p != self.path);
        self.path = PathBuf::new();
        Ok(())
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        if self.path.as_os_str().is_empty() {
            return;
        }
        let mut temporaries = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
        let _ = std::fs::remove_file(&self.path);
        temporaries.retain(|p| *p != self.path);
    }
}

/// Installs handlers for SIGINT, SIGTERM and SIGHUP that remove every
/// temporary output file and exit with 128 + the signal number, as a shell
/// reports a process killed by that signal. Outputs already committed stay;
/// outputs under way are left as they were before the run.
pub fn remove_temporaries_on_signal() {
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
            return;
        };
        std::thread::spawn(move || {
            if let Some(sig) = signals.forever().next() {
                // Held until exit: no temporary can be created or renamed after this.
                let temporaries = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
                for p in temporaries.iter() {
                    let _ = std::fs::remove_file(p);
                }
                std::process::exit(128 + sig);
            }
        });
    }
}

/// Installs a panic hook that removes every temporary output file before
/// the panic's message is printed. The release build aborts on a panic
/// (`panic = "abort"`, Cargo.toml): nothing unwinds, so the temporaries'
/// own clean-up never runs. A panic is a bug (docs/robustness.md); this
/// keeps it from leaving half-written files behind. For the binary only:
/// in a test process the hook would take other tests' temporaries.
pub fn remove_temporaries_on_panic() {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        // Not blocking: the panicking thread may hold the list itself.
        if let Ok(temporaries) = TEMPORARIES.try_lock() {
            for p in temporaries.iter() {
                let _ = std::fs::remove_file(p);
            }
        }
        previous(info);
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An input whose name is removed during the run keeps its identity: a
    /// new file may not get its inode and be taken for it. (Inputs were
    /// recorded by device and inode alone; a file created after an input
    /// was removed could get the same inode and was refused as an input.)
    #[cfg(unix)]
    #[test]
    fn a_removed_input_lends_its_identity_to_no_new_file() {
        let dir = tempfile::tempdir().unwrap();
        for k in 0..20 {
            let input = dir.path().join(format!("gone-{k}.nc"));
            std::fs::write(&input, b"program").unwrap();
            drop(open_input(&input).unwrap());
            std::fs::remove_file(&input).unwrap();
            let out = dir.path().join(format!("new-{k}.nc"));
            std::fs::write(&out, b"old").unwrap();
            write_atomically(Some(&out), |w| {
                w.write_all(b"new").map_err(|e| Error::io("new.nc", e))
            })
            .unwrap_or_else(|e| panic!("round {k}: {e}"));
            assert_eq!(std::fs::read(&out).unwrap(), b"new");
        }
    }

    /// An output of several write-back steps, in writes of every size
    /// (small ones through the buffer, large ones past it), arrives whole
    /// and in order, and replaces the file it names.
    #[test]
    fn large_output_arrives_whole() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.nc");
        std::fs::write(&p, b"old").unwrap();
        let mut expected = Vec::new();
        let mut k = 0u64;
        while expected.len() < 3 * Writeback::STEP_BYTES as usize + 12_345 {
            let len = [1usize, 17, 4096, 70_000, 300_000][(k % 5) as usize];
            let piece: Vec<u8> = (0..len).map(|i| ((i as u64 + k) % 251) as u8).collect();
            expected.extend_from_slice(&piece);
            k += 1;
        }
        write_atomically(Some(&p), |w| {
            let mut at = 0;
            let mut k = 0u64;
            while at < expected.len() {
                let len = [1usize, 17, 4096, 70_000, 300_000][(k % 5) as usize];
                w.write_all(&expected[at..at + len])
                    .map_err(|e| Error::io("big.nc", e))?;
                at += len;
                k += 1;
            }
            Ok(())
        })
        .unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), expected);
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "no temporary is left");
    }

    #[test]
    fn error_leaves_path_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.nc");
        std::fs::write(&p, b"old").unwrap();
        let r: Result<()> = write_atomically(Some(&p), |w| {
            w.write_all(b"half").unwrap();
            Err(Error::Usage("boom".into()))
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temporary left behind"
        );
        write_atomically(Some(&p), |w| {
            w.write_all(b"new").unwrap();
            Ok(())
        })
        .unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
        let registered = TEMPORARIES.lock().unwrap();
        assert!(
            !registered.iter().any(|t| t.starts_with(dir.path())),
            "{registered:?}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn keeps_mode_links_and_refuses_inputs() {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let dir = tempfile::tempdir().unwrap();
        let write = |p: &Path, s: &'static [u8]| {
            write_atomically(Some(p), |w| {
                w.write_all(s).unwrap();
                Ok(())
            })
        };
        // The mode of an existing file is kept.
        let p = dir.path().join("run.sh");
        std::fs::write(&p, b"old").unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
        write(&p, b"new").unwrap();
        assert_eq!(std::fs::metadata(&p).unwrap().mode() & 0o777, 0o755);
        // A symbolic link is followed: the target changes, the link stays.
        let link = dir.path().join("link.nc");
        std::os::unix::fs::symlink(&p, &link).unwrap();
        write(&link, b"through").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&p).unwrap(), b"through");
        // A hard link keeps sharing the content.
        let hard = dir.path().join("hard.nc");
        std::fs::hard_link(&p, &hard).unwrap();
        write(&hard, b"shared").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"shared");
        assert_eq!(std::fs::metadata(&p).unwrap().nlink(), 2);
        // An input is refused, also through another name.
        let input = dir.path().join("in.nc");
        std::fs::write(&input, b"program").unwrap();
        let f = open_input(&input).unwrap();
        drop(f);
        let alias = dir.path().join("alias.nc");
        std::os::unix::fs::symlink(&input, &alias).unwrap();
        for out in [&input, &alias] {
            let e = write(out, b"clobber").unwrap_err();
            assert_eq!(e.exit_code(), crate::error::exit::USAGE, "{e}");
            assert!(e.to_string().contains("refusing"), "{e}");
        }
        assert_eq!(std::fs::read(&input).unwrap(), b"program");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert!(!names.iter().any(|n| n.ends_with(".part")), "{names:?}");
    }

    /// A symbolic link whose target does not exist yet is written through,
    /// as a shell's `>` does: the target is created and the link stays.
    /// (The link was replaced by a plain file and no target was created.)
    #[cfg(unix)]
    #[test]
    fn a_dangling_link_is_written_through() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        let target = sub.join("made.nc");
        let link = dir.path().join("link.nc");
        // A relative link, resolved from the link's own directory.
        std::os::unix::fs::symlink("sub/made.nc", &link).unwrap();
        // and a chain of two links.
        let outer = dir.path().join("outer.nc");
        std::os::unix::fs::symlink(&link, &outer).unwrap();
        check_outputs(&[("-o", Some(&outer))], &[]).unwrap();
        write_atomically(Some(&outer), |w| {
            w.write_all(b"through").unwrap();
            Ok(())
        })
        .unwrap();
        for l in [&link, &outer] {
            assert!(
                std::fs::symlink_metadata(l)
                    .unwrap()
                    .file_type()
                    .is_symlink()
            );
        }
        assert_eq!(std::fs::read(&target).unwrap(), b"through");
        // The link and its target named for two outputs are one file.
        std::fs::remove_file(&target).unwrap();
        let e =
            check_outputs(&[("-o", Some(&link)), ("--report", Some(&target))], &[]).unwrap_err();
        assert!(e.to_string().contains("name the same file"), "{e}");
        // A link into a directory that does not exist, and a loop, are refused.
        let nowhere = dir.path().join("nowhere.nc");
        std::os::unix::fs::symlink("missing/x.nc", &nowhere).unwrap();
        assert!(check_outputs(&[("-o", Some(&nowhere))], &[]).is_err());
        let looped = dir.path().join("loop.nc");
        std::os::unix::fs::symlink("loop.nc", &looped).unwrap();
        assert!(check_outputs(&[("-o", Some(&looped))], &[]).is_err());
        let e = write_atomically(Some(&looped), |w| {
            w.write_all(b"x").unwrap();
            Ok(())
        })
        .unwrap_err();
        assert!(e.to_string().contains("symbolic links"), "{e}");
        assert!(
            std::fs::symlink_metadata(&looped)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert!(!names.iter().any(|n| n.ends_with(".part")), "{names:?}");
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_written_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        write_atomically(Some(Path::new("/dev/null")), |w| {
            w.write_all(b"gone").unwrap();
            Ok(())
        })
        .unwrap();
        assert!(
            std::fs::metadata("/dev/null")
                .unwrap()
                .file_type()
                .is_char_device()
        );
    }

    #[test]
    fn two_outputs_on_one_path_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.nc");
        let e = check_outputs(&[("-o", Some(&p)), ("--report", Some(&p))], &[]).unwrap_err();
        assert!(e.to_string().contains("name the same file"), "{e}");
        let input = dir.path().join("p.nc");
        std::fs::write(&input, b"G0 X0\n").unwrap();
        let e = check_outputs(&[("--report", Some(&input))], &[Some(&input)]).unwrap_err();
        assert!(e.to_string().contains("input"), "{e}");
        check_outputs(&[("-o", Some(&p)), ("--report", None)], &[Some(&input)]).unwrap();
        let null = Path::new("/dev/null");
        check_outputs(&[("-o", Some(null)), ("--report", Some(null))], &[]).unwrap();
    }
}
