//! Reading the files a scene names (the scene file, OBJ meshes, MTL libraries): regular files
//! only, so a device (`/dev/zero`, `/dev/urandom`) is never read without end and a FIFO never
//! blocks the loader, and no larger than `UMBRA_MAX_INPUT_BYTES` (default 4 GiB, room for a
//! 10M-triangle OBJ).

use std::fs::{self, File, Metadata, OpenOptions};
use std::io::{self, Read};
use std::path::Path;

/// The environment variable that sets the largest input file, in bytes.
pub const MAX_INPUT_BYTES_VAR: &str = "UMBRA_MAX_INPUT_BYTES";

/// The largest input file when `UMBRA_MAX_INPUT_BYTES` is not set: 4 GiB.
pub const DEFAULT_MAX_INPUT_BYTES: u64 = 4 << 30;

/// Reads the whole file at `path`, refusing anything but a regular file (checked before opening
/// it, and again on what was opened) and anything over the size limit. The errors are single
/// lines without an OS error number, for the caller to prefix with the file's name.
pub(super) fn read(path: &Path) -> io::Result<Vec<u8>> {
    let limit = max_input_bytes(std::env::var(MAX_INPUT_BYTES_VAR).ok().as_deref())?;
    // Checked on the path first so that a device or FIFO is not even opened (opening a FIFO
    // for reading waits for a writer) ...
    let metadata = fs::metadata(path)?;
    check(&metadata, limit)?;
    // ... and on the open file too, in case the path changed in between; O_NONBLOCK keeps that
    // open from waiting on a FIFO, and changes nothing for a regular file.
    let file = open_nonblocking(path)?;
    let metadata = file.metadata()?;
    check(&metadata, limit)?;
    let mut bytes = Vec::with_capacity(metadata.len() as usize);
    // A file that grows while it is read is still cut off at the limit.
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64, limit));
    }
    Ok(bytes)
}

/// The limit from the value of `UMBRA_MAX_INPUT_BYTES`, if set: a whole number of bytes.
pub(super) fn max_input_bytes(value: Option<&str>) -> io::Result<u64> {
    match value {
        None => Ok(DEFAULT_MAX_INPUT_BYTES),
        Some(text) => text.trim().parse::<u64>().map_err(|_| {
            let shown: String = text.chars().take(40).collect();
            io::Error::other(format!("{MAX_INPUT_BYTES_VAR}={shown:?} is not a whole number of bytes"))
        }),
    }
}

fn check(metadata: &Metadata, limit: u64) -> io::Result<()> {
    if !metadata.is_file() {
        return Err(io::Error::other(format!("not a regular file ({})", kind(metadata))));
    }
    if metadata.len() > limit {
        return Err(too_large(metadata.len(), limit));
    }
    Ok(())
}

fn too_large(size: u64, limit: u64) -> io::Error {
    io::Error::other(format!(
        "{} is over the input limit of {} (set {MAX_INPUT_BYTES_VAR} to change it)",
        bytes(size),
        bytes(limit)
    ))
}

/// `1234 bytes`, or `5368709120 bytes (5 GiB)` where a binary unit reads better.
fn bytes(n: u64) -> String {
    const UNITS: [(u64, &str); 3] = [(1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")];
    match UNITS.iter().find(|(unit, _)| n >= *unit) {
        Some((unit, name)) => {
            let value = n as f64 / *unit as f64;
            let value = if n % unit == 0 { format!("{value}") } else { format!("{value:.1}") };
            format!("{n} bytes ({value} {name})")
        }
        None => format!("{n} bytes"),
    }
}

fn kind(metadata: &Metadata) -> &'static str {
    let file_type = metadata.file_type();
    if file_type.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return "a FIFO";
        }
        if file_type.is_char_device() {
            return "a character device";
        }
        if file_type.is_block_device() {
            return "a block device";
        }
        if file_type.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

fn open_nonblocking(path: &Path) -> io::Result<File> {
    let mut options = OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    options.open(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_limit_is_a_whole_number_of_bytes() {
        assert_eq!(max_input_bytes(None).unwrap(), 4 << 30);
        assert_eq!(max_input_bytes(Some("100")).unwrap(), 100);
        assert_eq!(max_input_bytes(Some(" 7 ")).unwrap(), 7);
        let error = max_input_bytes(Some("4G")).unwrap_err().to_string();
        assert_eq!(error, "UMBRA_MAX_INPUT_BYTES=\"4G\" is not a whole number of bytes");
        assert!(max_input_bytes(Some("-1")).is_err());
    }

    #[test]
    fn sizes_read_as_bytes_and_binary_units() {
        assert_eq!(bytes(100), "100 bytes");
        assert_eq!(bytes(4 << 30), "4294967296 bytes (4 GiB)");
        assert_eq!(bytes(1536), "1536 bytes (1.5 KiB)");
    }

    #[test]
    fn devices_and_directories_are_refused_by_kind() {
        let dir = std::env::temp_dir();
        assert_eq!(read(&dir).unwrap_err().to_string(), "not a regular file (a directory)");
        #[cfg(unix)]
        assert_eq!(read(Path::new("/dev/zero")).unwrap_err().to_string(), "not a regular file (a character device)");
    }
}
