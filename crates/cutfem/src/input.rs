//! Bounded reading of the files a user names. A path may name an endless stream (`/dev/zero`,
//! a FIFO, a symlink to either), so nothing is read without a bound:
//!
//! - a regular file is measured first (its metadata) and refused when larger than the limit,
//!   before a byte is read;
//! - anything else is read up to the limit and refused beyond it;
//! - binary formats whose header gives the data's size (`.sdf`, `.npy`, binary STL) read the
//!   header ([`Input::head`]) and then exactly what it implies ([`Input::rest`], at most one
//!   byte more, which tells an over-long stream);
//! - text formats ([`read_text`]: scenes, observation CSVs, OBJ, camera files, logs) refuse a
//!   NUL byte as soon as it is read: no text file holds one, and `/dev/zero` is nothing else.
//!   [`read_string`] drops a leading UTF-8 byte order mark (as Windows editors write one), so
//!   every text format reads the same with or without it.
//!
//! Errors are [`std::io::Error`]s (kind `InvalidData`) whose message says what was refused, so
//! that every reader's "PATH: cause" error stays one line.

use std::fs::File;
use std::io::{Error, ErrorKind, Read};
use std::path::Path;

/// The largest data file read (meshes, observation CSVs, SDF arrays without a size header):
/// 2 GiB.
pub const MAX_DATA_BYTES: u64 = 1 << 31;

/// The largest configuration file read (scene files, camera files): 64 MiB.
pub const MAX_CONFIG_BYTES: u64 = 64 << 20;

const CHUNK: usize = 1 << 16;

/// An open input: its size when it is a regular file, and the bytes read so far.
#[derive(Debug)]
pub struct Input {
    file: File,
    size: Option<u64>,
    read: Vec<u8>,
    eof: bool,
}

fn invalid(msg: String) -> Error {
    Error::new(ErrorKind::InvalidData, msg)
}

impl Input {
    /// Opens `path` (following symlinks) and measures it when it is a regular file.
    pub fn open(path: &Path) -> Result<Self, Error> {
        let file = File::open(path)?;
        let meta = file.metadata()?;
        if meta.is_dir() {
            return Err(invalid("is a directory, not a file".into()));
        }
        Ok(Self {
            size: meta.is_file().then_some(meta.len()),
            file,
            read: Vec::new(),
            eof: false,
        })
    }

    /// The size of a regular file (`None` for a stream or a device).
    pub fn size(&self) -> Option<u64> {
        self.size
    }

    /// Reads until `n` bytes are held or the input ends; the bytes held (fewer than `n` only
    /// at the end of the input).
    pub fn head(&mut self, n: usize) -> Result<&[u8], Error> {
        self.fill(n as u64, false)?;
        Ok(&self.read[..self.read.len().min(n)])
    }

    /// The whole input (the head included), which may not exceed `max` bytes: a regular file
    /// larger than that is refused by its size before reading, a stream after `max + 1` bytes.
    pub fn rest(mut self, max: u64) -> Result<Vec<u8>, Error> {
        self.check_size(max)?;
        self.fill(max + 1, false)?;
        self.check_read(max)?;
        Ok(self.read)
    }

    /// [`Input::rest`] of a text input: a NUL byte is refused as soon as it is read.
    pub fn text(mut self, max: u64) -> Result<Vec<u8>, Error> {
        self.check_size(max)?;
        if let Some(at) = self.read.iter().position(|&b| b == 0) {
            return Err(nul(at));
        }
        self.fill(max + 1, true)?;
        self.check_read(max)?;
        Ok(self.read)
    }

    fn check_size(&self, max: u64) -> Result<(), Error> {
        match self.size {
            Some(size) if size > max => Err(invalid(format!(
                "{size} bytes, more than the {max} bytes this input may have"
            ))),
            _ => Ok(()),
        }
    }

    fn check_read(&self, max: u64) -> Result<(), Error> {
        if self.read.len() as u64 > max {
            return Err(invalid(format!(
                "more than the {max} bytes this input may have (an endless stream, not a regular file?)"
            )));
        }
        Ok(())
    }

    /// Reads until `n` bytes are held or the input ends; with `text`, errors at a NUL byte.
    fn fill(&mut self, n: u64, text: bool) -> Result<(), Error> {
        let mut buf = vec![0u8; CHUNK];
        while !self.eof && (self.read.len() as u64) < n {
            let want = (n - self.read.len() as u64).min(CHUNK as u64) as usize;
            let got = match self.file.read(&mut buf[..want]) {
                Ok(0) => {
                    self.eof = true;
                    break;
                }
                Ok(k) => k,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if text {
                if let Some(at) = buf[..got].iter().position(|&b| b == 0) {
                    return Err(nul(self.read.len() + at));
                }
            }
            self.read.extend_from_slice(&buf[..got]);
        }
        Ok(())
    }
}

fn nul(at: usize) -> Error {
    invalid(format!("binary data (a NUL byte at byte {at}), not a text file"))
}

/// The bytes of the file at `path`, at most `max` (module docs).
pub fn read(path: &Path, max: u64) -> Result<Vec<u8>, Error> {
    Input::open(path)?.rest(max)
}

/// The bytes of the text file at `path`, at most `max`, without a NUL byte (module docs).
pub fn read_text(path: &Path, max: u64) -> Result<Vec<u8>, Error> {
    Input::open(path)?.text(max)
}

/// [`read_text`] as a `String` without a leading byte order mark (invalid UTF-8 is an error
/// naming the line).
pub fn read_string(path: &Path, max: u64) -> Result<String, Error> {
    let mut text = String::from_utf8(read_text(path, max)?).map_err(|e| {
        let ok = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = ok.iter().filter(|&&b| b == b'\n').count() + 1;
        invalid(format!("line {line}: not UTF-8 text"))
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// A stable 64-bit digest of `bytes` (FNV-1a): the same on every machine and Rust version, so
/// it may be written to a file and compared by a later run (a fit log's fingerprint of its
/// problem, a study's repeated recordings). Not cryptographic.
pub fn digest(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// [`digest`] of a file's bytes (`None` when it cannot be read).
pub fn file_digest(path: &Path) -> Option<u64> {
    read(path, MAX_DATA_BYTES).ok().map(|b| digest(&b))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("cutfem-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn regular_files_are_measured_before_reading() {
        let p = tmp("ten", b"0123456789");
        assert_eq!(read(&p, 10).unwrap(), b"0123456789");
        let e = read(&p, 9).unwrap_err().to_string();
        assert!(e.contains("10 bytes, more than the 9"), "{e}");
        let mut input = Input::open(&p).unwrap();
        assert_eq!(input.size(), Some(10));
        assert_eq!(input.head(4).unwrap(), b"0123");
        assert_eq!(input.head(40).unwrap().len(), 10);
        assert_eq!(input.rest(10).unwrap(), b"0123456789");
        let e = read_text(&tmp("nul", b"ab\0cd"), 100).unwrap_err().to_string();
        assert!(e.contains("NUL byte at byte 2"), "{e}");
        let e = read_string(&tmp("latin", b"a\nb\xff\n"), 100)
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2: not UTF-8"), "{e}");
        let bom = read_string(&tmp("bom", "\u{feff}{\"a\": 1}\n".as_bytes()), 100).unwrap();
        assert_eq!(bom, "{\"a\": 1}\n");
        let e = read(p.parent().unwrap(), 100).unwrap_err().to_string();
        assert!(e.contains("directory"), "{e}");
    }

    #[test]
    fn endless_streams_are_cut_at_the_bound() {
        let zero = Path::new("/dev/zero");
        if !zero.exists() {
            return;
        }
        let e = read(zero, 1000).unwrap_err().to_string();
        assert!(e.contains("more than the 1000 bytes"), "{e}");
        let e = read_text(zero, MAX_DATA_BYTES).unwrap_err().to_string();
        assert!(e.contains("NUL byte at byte 0"), "{e}");
        let mut input = Input::open(zero).unwrap();
        assert_eq!(input.size(), None);
        assert_eq!(input.head(28).unwrap(), &[0u8; 28]);
    }
}
