//! NumPy `.npy` arrays: magic `\x93NUMPY`, version byte pair (1.0, 2.0 or 3.0), header length
//! (u16 for version 1, u32 for versions 2 and 3), then an ASCII/UTF-8 Python dict literal
//! `{'descr': '<f8', 'fortran_order': False, 'shape': (nz, ny, nx), }` padded with spaces and a
//! newline, then the raw data. Only little-endian float32/float64 C-order 3-D arrays are read.

use super::SdfGrid;
use crate::Error;
use std::path::Path;

const MAGIC: &[u8] = b"\x93NUMPY";

/// The longest header read (NumPy writes ~128 bytes; its own limit is 64 KiB by default).
const MAX_HEADER: usize = 1 << 20;

/// Element type of a written `.npy` array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NpyDtype {
    /// little-endian float32 (`<f4`)
    F32,
    /// little-endian float64 (`<f8`)
    F64,
}

/// The parsed `.npy` header dict.
struct Header {
    descr: String,
    fortran_order: bool,
    shape: Vec<u64>,
}

/// A tiny parser for the header's Python dict literal.
struct Lit<'a> {
    s: &'a [u8],
    at: usize,
}

impl Lit<'_> {
    fn ws(&mut self) {
        while self.at < self.s.len() && self.s[self.at].is_ascii_whitespace() {
            self.at += 1;
        }
    }
    fn eat(&mut self, c: u8) -> bool {
        self.ws();
        if self.s.get(self.at) == Some(&c) {
            self.at += 1;
            true
        } else {
            false
        }
    }
    fn expect(&mut self, c: u8) -> Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!(
                "header: expected '{}' at character {}",
                c as char, self.at
            ))
        }
    }
    fn string(&mut self) -> Result<String, String> {
        self.ws();
        let q = match self.s.get(self.at) {
            Some(&q) if q == b'\'' || q == b'"' => q,
            _ => {
                return Err(format!(
                    "header: expected a quoted string at character {}",
                    self.at
                ))
            }
        };
        let start = self.at + 1;
        let len = self.s[start..]
            .iter()
            .position(|&c| c == q)
            .ok_or_else(|| "header: unterminated string".to_string())?;
        self.at = start + len + 1;
        Ok(String::from_utf8_lossy(&self.s[start..start + len]).into_owned())
    }
    fn word(&mut self) -> String {
        self.ws();
        let start = self.at;
        while self.at < self.s.len() && self.s[self.at].is_ascii_alphanumeric() {
            self.at += 1;
        }
        String::from_utf8_lossy(&self.s[start..self.at]).into_owned()
    }
    fn parse(mut self) -> Result<Header, String> {
        let (mut descr, mut fortran, mut shape) = (None, None, None);
        self.expect(b'{')?;
        loop {
            if self.eat(b'}') {
                break;
            }
            let key = self.string()?;
            self.expect(b':')?;
            match key.as_str() {
                "descr" => descr = Some(self.string()?),
                "fortran_order" => {
                    fortran = Some(match self.word().as_str() {
                        "True" => true,
                        "False" => false,
                        w => return Err(format!("header: fortran_order must be True/False, found '{w}'")),
                    })
                }
                "shape" => {
                    self.expect(b'(')?;
                    let mut dims = Vec::new();
                    while !self.eat(b')') {
                        let w = self.word();
                        let d = w
                            .parse::<u64>()
                            .map_err(|_| format!("header: bad shape entry '{w}'"))?;
                        dims.push(d);
                        if !self.eat(b',') {
                            self.expect(b')')?;
                            break;
                        }
                    }
                    shape = Some(dims);
                }
                other => return Err(format!("header: unknown key '{other}'")),
            }
            if !self.eat(b',') {
                self.expect(b'}')?;
                break;
            }
        }
        Ok(Header {
            descr: descr.ok_or("header: missing 'descr'")?,
            fortran_order: fortran.ok_or("header: missing 'fortran_order'")?,
            shape: shape.ok_or("header: missing 'shape'")?,
        })
    }
}

impl SdfGrid {
    /// Reads a `.npy` array of shape `(nz, ny, nx)` (indexed `[z][y][x]`, C order, so x is
    /// fastest as in [`SdfGrid::values`]) of little-endian float32 or float64 values in world
    /// units, placing node `(0, 0, 0)` at `origin` with the given `spacing`.
    ///
    /// Errors naming the file for a bad magic/version/header, `fortran_order: True`, a dtype
    /// other than `<f4`/`<f8`, a shape that is not 3-D, a wrong data length, non-finite values,
    /// and an invalid spacing or origin.
    pub fn read_npy(path: impl AsRef<Path>, origin: [f64; 3], spacing: f64) -> Result<SdfGrid, Error> {
        let path = path.as_ref();
        let bad = |msg: String| Error::format(path, msg);
        if !(spacing.is_finite() && spacing > 0.0) || origin.iter().any(|x| !x.is_finite()) {
            return Err(Error::Invalid(format!(
                "{}: spacing must be positive and origin finite, found spacing {spacing}, origin {origin:?}",
                path.display()
            )));
        }
        // the header decides how much is read: an endless stream is never read whole
        let mut input = crate::input::Input::open(path).map_err(|e| Error::io(path, e))?;
        let magic = input.head(12).map_err(|e| Error::io(path, e))?.to_vec();
        if magic.len() < 10 || &magic[..6] != MAGIC {
            return Err(bad("not a .npy file (missing the \\x93NUMPY magic)".into()));
        }
        let (header_len, start): (usize, usize) = match magic[6] {
            1 => (u16::from_le_bytes([magic[8], magic[9]]) as usize, 10),
            2 | 3 if magic.len() >= 12 => (
                u32::from_le_bytes([magic[8], magic[9], magic[10], magic[11]]) as usize,
                12,
            ),
            v => return Err(bad(format!("unsupported .npy version {v}.{}", magic[7]))),
        };
        if header_len > MAX_HEADER {
            return Err(bad(format!(
                "absurd .npy header length {header_len} (more than {MAX_HEADER} bytes)"
            )));
        }
        let data_start = start + header_len;
        let head = input.head(data_start).map_err(|e| Error::io(path, e))?;
        if head.len() < data_start {
            return Err(bad(format!(
                "truncated .npy header: expected {data_start} bytes, found {}",
                head.len()
            )));
        }
        let header = Lit {
            s: &head[start..data_start],
            at: 0,
        }
        .parse()
        .map_err(bad)?;
        if header.fortran_order {
            return Err(bad(
                "fortran_order True is not supported (save a C-order array)".into()
            ));
        }
        let width = match header.descr.as_str() {
            "<f4" => 4,
            "<f8" => 8,
            d => {
                return Err(bad(format!(
                    "dtype '{d}' is not supported (expected little-endian float32 '<f4' or float64 '<f8')"
                )))
            }
        };
        let [nz, ny, nx] = match header.shape[..] {
            [a, b, c] => [a, b, c],
            ref s => {
                return Err(bad(format!(
                    "expected a 3-D array (nz, ny, nx), found shape {s:?}"
                )))
            }
        };
        let count = nx
            .checked_mul(ny)
            .and_then(|n| n.checked_mul(nz))
            .filter(|&n| n <= 1 << 31);
        let count = count.ok_or_else(|| bad(format!("absurd shape ({nz}, {ny}, {nx})")))?;
        let expected = data_start as u64 + count * width as u64;
        let mismatch = |found: String| {
            bad(format!(
                "shape ({nz}, {ny}, {nx}) of {} needs {expected} bytes, found {found}",
                header.descr
            ))
        };
        // a regular file is measured before reading; a stream is read up to one byte past
        if let Some(found) = input.size().filter(|&n| n != expected) {
            return Err(mismatch(found.to_string()));
        }
        let stream = input.size().is_none();
        let bytes = input.rest(expected).map_err(|e| match e.kind() {
            std::io::ErrorKind::InvalidData if stream => mismatch("more (not a regular file?)".into()),
            _ => Error::io(path, e),
        })?;
        if bytes.len() as u64 != expected {
            return Err(mismatch(bytes.len().to_string()));
        }
        let data = &bytes[data_start..];
        let values: Vec<f64> = if width == 4 {
            data.chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64)
                .collect()
        } else {
            data.chunks_exact(8)
                .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
                .collect()
        };
        let dims = [nx as usize, ny as usize, nz as usize];
        if let Some(n) = values.iter().position(|v| !v.is_finite()) {
            let (i, j, k) = (n % dims[0], (n / dims[0]) % dims[1], n / (dims[0] * dims[1]));
            return Err(bad(format!(
                "value at node (x {i}, y {j}, z {k}) is {}",
                values[n]
            )));
        }
        Ok(SdfGrid {
            exact: None,
            origin,
            spacing,
            dims,
            values,
        })
    }

    /// Writes the values as a version-1.0 `.npy` array of shape `(nz, ny, nx)` in C order
    /// (world units; the origin and spacing are not stored).
    pub fn write_npy(&self, path: impl AsRef<Path>, dtype: NpyDtype) -> Result<(), Error> {
        let path = path.as_ref();
        if self.values.len() != self.node_count() {
            return Err(Error::Invalid(format!(
                "{}: cannot write .npy: {} values for {:?} nodes",
                path.display(),
                self.values.len(),
                self.dims
            )));
        }
        let descr = match dtype {
            NpyDtype::F32 => "<f4",
            NpyDtype::F64 => "<f8",
        };
        let [nx, ny, nz] = self.dims;
        let mut dict =
            format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({nz}, {ny}, {nx}), }}");
        // pad so that magic (6) + version (2) + length (2) + header is a multiple of 64
        let total = 10 + dict.len() + 1;
        dict.push_str(&" ".repeat((64 - total % 64) % 64));
        dict.push('\n');
        let width = if dtype == NpyDtype::F32 { 4 } else { 8 };
        let mut out = Vec::with_capacity(10 + dict.len() + width * self.values.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
        out.extend_from_slice(dict.as_bytes());
        for &v in &self.values {
            match dtype {
                NpyDtype::F32 => out.extend_from_slice(&(v as f32).to_le_bytes()),
                NpyDtype::F64 => out.extend_from_slice(&v.to_le_bytes()),
            }
        }
        std::fs::write(path, out).map_err(|e| Error::io(path, e))
    }
}
