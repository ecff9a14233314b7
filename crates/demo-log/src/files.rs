//! The one way this crate reads an input file: regular files only.
//!
//! Opening a named pipe (FIFO) blocks until some other process opens it for writing, and reading a
//! character device (`/dev/zero`) never ends, so every reader ([`crate::HandLog::from_path`],
//! [`crate::read_demo`], [`crate::verify`], [`crate::salvage`], [`crate::salvage_to`]) goes
//! through [`read_regular`]: the path is looked at (`stat`, which never blocks) before it is
//! opened, and anything that is not a regular file is refused by name. The opened file is checked
//! again, so that a file swapped for something else between the two steps is refused too.

use std::io::Read;
use std::path::Path;

/// Why a file was not read.
#[derive(Debug)]
pub(crate) enum ReadFail {
    /// The path names something other than a regular file (the reason says what).
    NotRegular(String),
    /// The OS refused.
    Io(std::io::Error),
}

impl ReadFail {
    /// As a [`crate::DemoError`] naming `path`: `Format` for not-a-file, `Io` otherwise.
    pub(crate) fn into_demo(self, path: &Path) -> crate::DemoError {
        match self {
            ReadFail::NotRegular(reason) => crate::DemoError::Format { path: path.to_path_buf(), reason },
            ReadFail::Io(source) => crate::DemoError::Io { path: path.to_path_buf(), source },
        }
    }
}

/// What a file type is, in words (`"a named pipe"`, `"a directory"`, ...).
fn kind_of(t: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a named pipe";
        }
        if t.is_socket() {
            return "a socket";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
    }
    if t.is_dir() { "a directory" } else { "not a regular file" }
}

fn not_regular(t: std::fs::FileType) -> ReadFail {
    let kind = kind_of(t);
    if kind.starts_with("not ") {
        ReadFail::NotRegular(kind.to_string())
    } else {
        ReadFail::NotRegular(format!("not a regular file ({kind})"))
    }
}

/// The whole content of the regular file at `path` (a symbolic link is followed).
///
/// # Errors
/// [`ReadFail::NotRegular`] for a named pipe, socket, device or directory, or a dangling symbolic
/// link (with its target); [`ReadFail::Io`] when the OS refuses.
pub(crate) fn read_regular(path: &Path) -> Result<Vec<u8>, ReadFail> {
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if let Ok(l) = std::fs::symlink_metadata(path)
                && l.file_type().is_symlink()
            {
                let target = std::fs::read_link(path).map(|t| t.display().to_string()).unwrap_or_default();
                return Err(ReadFail::NotRegular(format!(
                    "dangling symbolic link (its target {target:?} does not exist)"
                )));
            }
            return Err(ReadFail::Io(e));
        }
        Err(e) => return Err(ReadFail::Io(e)),
    };
    if !meta.is_file() {
        return Err(not_regular(meta.file_type()));
    }
    let mut f = std::fs::File::open(path).map_err(ReadFail::Io)?;
    let meta = f.metadata().map_err(ReadFail::Io)?;
    if !meta.is_file() {
        return Err(not_regular(meta.file_type()));
    }
    let mut buf = Vec::with_capacity(usize::try_from(meta.len()).unwrap_or(0).saturating_add(1));
    f.read_to_end(&mut buf).map_err(ReadFail::Io)?;
    Ok(buf)
}

/// The whole content of the regular file at `path` (a symbolic link is followed), checked before
/// and after it is opened as the module docs say; the failure as a [`crate::DemoError`] naming
/// `path`.
///
/// # Errors
/// [`crate::DemoError::Format`] for something that is not a regular file (a named pipe, socket,
/// device or directory, a dangling symbolic link), [`crate::DemoError::Io`] when the OS refuses.
pub fn read_input(path: impl AsRef<Path>) -> Result<Vec<u8>, crate::DemoError> {
    let path = path.as_ref();
    read_regular(path).map_err(|e| e.into_demo(path))
}
