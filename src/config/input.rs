//! The files a config brings in, the config itself and its CSV time tables: read only when
//! they are regular files within a size limit, so that a FIFO, a device or a runaway file
//! is an error naming the file, never a hang or an out-of-memory abort.

use std::io::Read;
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// Largest config or table file [bytes]: some 100 times the largest earthquake record in
/// common use (a 2-column CSV of 200 Hz over 10 minutes is 3 MB), and a tenth of what a
/// 1000-case sweep could copy into its cases.
pub const MAX_INPUT_BYTES: u64 = 32_000_000;

/// The bytes of `path`; Err (a message without the path, which the caller names) when it
/// is not a regular file, is larger than [`MAX_INPUT_BYTES`] or cannot be read.
pub fn read_input(path: &Path) -> Result<Vec<u8>, String> {
    // Non-blocking: opening a FIFO with no writer would wait forever. Regular files read
    // as usual.
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| e.to_string())?;
    let meta = file.metadata().map_err(|e| e.to_string())?;
    if !meta.is_file() {
        return Err("is not a regular file (a directory, FIFO or device); give a file".into());
    }
    let too_large = |len: u64| format!("has {len} bytes, more than the {MAX_INPUT_BYTES} a config or table file may have");
    if meta.len() > MAX_INPUT_BYTES {
        return Err(too_large(meta.len()));
    }
    // At most one byte past the limit: the file may grow between the check and the read.
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(MAX_INPUT_BYTES + 1).read_to_end(&mut bytes).map_err(|e| e.to_string())?;
    if bytes.len() as u64 > MAX_INPUT_BYTES {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// At most `EXCERPT` characters of `text`, marked `…` where cut: what an error quotes of
/// a line it did not write.
pub fn excerpt(text: &str) -> String {
    match text.char_indices().nth(EXCERPT) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_string(),
    }
}

/// Characters of a line an error message quotes.
const EXCERPT: usize = 60;

#[cfg(test)]
mod tests {
    use super::{excerpt, read_input, MAX_INPUT_BYTES};

    #[test]
    fn reads_a_regular_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        std::fs::write(&path, "0,0\n1,1\n").unwrap();
        assert_eq!(read_input(&path).unwrap(), b"0,0\n1,1\n");
    }

    /// A FIFO without a writer (opening it blocking would hang), a directory and a
    /// device are refused at once; a file past the limit is refused without being read
    /// (sparse: its size is all there is).
    #[test]
    fn refuses_what_is_not_a_bounded_regular_file() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("fifo");
        let name = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
        for path in [fifo.as_path(), dir.path(), std::path::Path::new("/dev/zero")] {
            let err = read_input(path).unwrap_err();
            assert!(err.contains("not a regular file"), "{}: {err}", path.display());
        }
        let big = dir.path().join("big.csv");
        std::fs::File::create(&big).unwrap().set_len(MAX_INPUT_BYTES + 1).unwrap();
        let err = read_input(&big).unwrap_err();
        assert!(err.contains(&format!("has {} bytes", MAX_INPUT_BYTES + 1)), "{err}");
    }

    #[test]
    fn an_excerpt_is_short() {
        assert_eq!(excerpt("0, 1"), "0, 1");
        let long = "é".repeat(200_000);
        assert_eq!(excerpt(&long), format!("{}…", "é".repeat(60)));
    }
}
