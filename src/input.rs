//! Opening inputs: a path or standard input (`-`), with progress reporting
//! for LinuxCNC's `[FILTER]` protocol.

use crate::error::{Error, Result};
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// An opened input.
pub struct Input {
    /// Buffered reader.
    pub reader: Box<dyn BufRead>,
    /// Name used in messages.
    pub name: String,
    /// Size in bytes, when known (files).
    pub size: Option<u64>,
}

/// Opens `path`, or standard input for `None` or `-`.
pub fn open(path: Option<&Path>) -> Result<Input> {
    match path {
        None => Ok(stdin()),
        Some(p) if p.as_os_str() == "-" => Ok(stdin()),
        Some(p) => {
            let name = p.display().to_string();
            crate::text::check_not_dir(p)?;
            let f = crate::output::open_input(p).map_err(|e| Error::io(&name, e))?;
            let size = f.metadata().ok().map(|m| m.len());
            Ok(Input {
                reader: Box::new(BufReader::with_capacity(1 << 16, f)),
                name,
                size,
            })
        }
    }
}

fn stdin() -> Input {
    note_stdin();
    Input {
        reader: Box::new(BufReader::with_capacity(1 << 16, std::io::stdin())),
        name: "<stdin>".into(),
        size: None,
    }
}

/// Records standard input, where it is a regular file (`< p.nc`), as an
/// input of the run: no output may be written over it.
fn note_stdin() {
    #[cfg(unix)]
    {
        use std::os::fd::AsFd;
        if let Ok(fd) = std::io::stdin().as_fd().try_clone_to_owned() {
            let file = std::fs::File::from(fd);
            if file.metadata().is_ok_and(|m| m.is_file()) {
                crate::output::note_input(&file, "<stdin>");
            }
        }
    }
}

/// Reads the first bytes (up to 4 KiB) of a buffered input without
/// consuming them.
pub fn peek(reader: &mut dyn BufRead) -> Result<Vec<u8>> {
    let buf = reader.fill_buf().map_err(|e| Error::io("<input>", e))?;
    Ok(buf[..buf.len().min(4096)].to_vec())
}

/// Reads as much of the start of a buffered input as its buffer holds (64
/// KiB for a file [`open`] opened) without consuming it: enough for a CAM
/// program's header of comments and tool list before its TCP code.
pub fn peek_far(reader: &mut dyn BufRead) -> Result<Vec<u8>> {
    let buf = reader.fill_buf().map_err(|e| Error::io("<input>", e))?;
    Ok(buf.to_vec())
}

/// Progress on standard error in LinuxCNC's filter protocol
/// (`FILTER_PROGRESS=n`, n in percent), enabled when the environment variable
/// `AXIS_PROGRESS_BAR` is set and the input size is known.
pub struct FilterProgress {
    size: Option<u64>,
    last: u64,
}

impl FilterProgress {
    /// Progress for an input of `size` bytes; silent unless `AXIS_PROGRESS_BAR` is set.
    pub fn new(size: Option<u64>) -> Self {
        let enabled = std::env::var_os("AXIS_PROGRESS_BAR").is_some();
        FilterProgress {
            size: if enabled {
                size.filter(|s| *s > 0)
            } else {
                None
            },
            last: u64::MAX,
        }
    }

    /// Reports that `done` bytes have been read.
    pub fn update(&mut self, done: u64) {
        if let Some(size) = self.size {
            let pct = (done.min(size) * 100) / size;
            if pct != self.last {
                self.last = pct;
                eprintln!("FILTER_PROGRESS={pct}");
            }
        }
    }
}

/// Reads a whole (small) text input such as a machine file.
pub fn read_to_string(path: &Path) -> Result<String> {
    let name = path.display().to_string();
    let mut s = String::new();
    crate::output::open_input(path)
        .and_then(|mut f| f.read_to_string(&mut s))
        .map_err(|e| Error::io(&name, e))?;
    Ok(s)
}
