//! Output that is never half-written.
//!
//! With a path, the output goes to a temporary file in the same directory
//! that is renamed over the path only when everything succeeded; on error the
//! path is left untouched. Standard output is spooled through an anonymous
//! temporary file (memory stays flat) and copied out only on success, so a
//! filter never hands a half-converted program down the chain.

use crate::error::{Error, Result};
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

/// Runs `f` with a writer for `path` (or standard output when `None`), and
/// commits the output only if `f` succeeds.
pub fn write_atomically<T>(
    path: Option<&Path>,
    f: impl FnOnce(&mut dyn Write) -> Result<T>,
) -> Result<T> {
    match path {
        Some(path) => {
            let display = path.display().to_string();
            let dir = match path.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            let tmp = tempfile::Builder::new()
                .prefix(".kinpost-")
                .suffix(".part")
                .tempfile_in(dir)
                .map_err(|e| Error::io(&display, e))?;
            let mut w = BufWriter::with_capacity(1 << 16, tmp);
            let value = f(&mut w)?;
            let tmp = w
                .into_inner()
                .map_err(|e| Error::io(&display, e.into_error()))?;
            tmp.as_file().sync_all().ok();
            tmp.persist(path)
                .map_err(|e| Error::io(&display, e.error))?;
            Ok(value)
        }
        None => {
            let spool = tempfile::tempfile().map_err(|e| Error::io("<spool>", e))?;
            let mut w = BufWriter::with_capacity(1 << 16, spool);
            let value = f(&mut w)?;
            let mut spool = w
                .into_inner()
                .map_err(|e| Error::io("<spool>", e.into_error()))?;
            spool.rewind().map_err(|e| Error::io("<spool>", e))?;
            let stdout = std::io::stdout();
            let mut lock = stdout.lock();
            std::io::copy(&mut spool, &mut lock).map_err(|e| Error::io("<stdout>", e))?;
            lock.flush().map_err(|e| Error::io("<stdout>", e))?;
            Ok(value)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
