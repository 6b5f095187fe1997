//! The thesis `.sdf` binary format (little-endian):
//!
//! | bytes | type | meaning |
//! |---|---|---|
//! | 0..4 | int32 | `resolution`: voxels per world unit |
//! | 4..16 | int32\[3\] | `offset`: lattice index of node (0, 0, 0) |
//! | 16..28 | int32\[3\] | `size`: node counts in x, y, z |
//! | 28.. | float32\[size product\] | values in voxel units, x fastest, negative inside |
//!
//! Node `(i, j, k)` is at world position `(offset + (i, j, k)) / resolution`; world values are
//! the stored ones divided by `resolution`.

use super::SdfGrid;
use crate::Error;
use std::path::Path;

const HEADER: usize = 28;

fn i32_at(bytes: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

impl SdfGrid {
    /// Reads a thesis `.sdf` file (format in the [module docs](crate::sdf)).
    ///
    /// Every problem is an error naming the file, never a panic: a truncated or over-long file
    /// (bytes expected vs found), a non-positive resolution or size, a node count over 2^31
    /// (refused before allocating), and NaN or infinite values (the node is named). The header
    /// alone decides how much is read ([`crate::input`]): a regular file's size is compared
    /// with it before reading, a stream (a symlink to `/dev/zero`) is read to one byte past it.
    pub fn read_sdf(path: impl AsRef<Path>) -> Result<SdfGrid, Error> {
        let path = path.as_ref();
        let bad = |msg: String| Error::format(path, msg);
        // the header alone decides how much is read: an endless stream is never read whole
        let mut input = crate::input::Input::open(path).map_err(|e| Error::io(path, e))?;
        let head = input.head(HEADER).map_err(|e| Error::io(path, e))?;
        if head.len() < HEADER {
            return Err(bad(format!(
                "truncated .sdf header: expected at least {HEADER} bytes, found {}",
                head.len()
            )));
        }
        let resolution = i32_at(head, 0);
        let offset = [i32_at(head, 4), i32_at(head, 8), i32_at(head, 12)];
        let size = [i32_at(head, 16), i32_at(head, 20), i32_at(head, 24)];
        if resolution <= 0 {
            return Err(bad(format!("resolution must be positive, found {resolution}")));
        }
        if size.iter().any(|&s| s <= 0) {
            return Err(bad(format!(
                "size must be positive in x, y and z, found {size:?}"
            )));
        }
        // in u128: three positive i32 cannot overflow it (a u64 product wraps at 2^64)
        let count: u128 = size.iter().map(|&s| s as u128).product();
        if count > 1u128 << 31 {
            return Err(bad(format!(
                "absurd size {size:?}: {count} nodes (more than 2^31); not an .sdf file?"
            )));
        }
        let count = count as u64;
        let expected = HEADER as u64 + 4 * count;
        let mismatch = |found: u64| {
            let what = if found < expected {
                "truncated .sdf file"
            } else {
                "trailing data in .sdf file"
            };
            bad(format!(
                "{what}: size {size:?} needs {expected} bytes, found {found}"
            ))
        };
        // a regular file is measured before reading; a stream is read up to one byte past
        if let Some(found) = input.size().filter(|&n| n != expected) {
            return Err(mismatch(found));
        }
        let stream = input.size().is_none();
        let bytes = input.rest(expected).map_err(|e| match e.kind() {
            std::io::ErrorKind::InvalidData if stream => bad(format!(
                "trailing data in .sdf file: size {size:?} needs {expected} bytes, found more (not a regular file?)"
            )),
            _ => Error::io(path, e),
        })?;
        if bytes.len() as u64 != expected {
            return Err(mismatch(bytes.len() as u64));
        }
        let dims = size.map(|s| s as usize);
        let scale = 1.0 / resolution as f64;
        let mut values = Vec::with_capacity(count as usize);
        for (n, chunk) in bytes[HEADER..].chunks_exact(4).enumerate() {
            let v = f32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
            if !v.is_finite() {
                let (i, j, k) = (n % dims[0], (n / dims[0]) % dims[1], n / (dims[0] * dims[1]));
                return Err(bad(format!("value at node ({i}, {j}, {k}) is {v}")));
            }
            values.push(v as f64 / resolution as f64);
        }
        Ok(SdfGrid {
            exact: None,
            origin: offset.map(|o| o as f64 / resolution as f64),
            spacing: scale,
            dims,
            values,
        })
    }

    /// Writes the grid as a thesis `.sdf` file (values converted to voxel units, float32).
    ///
    /// The format can only hold grids whose spacing is `1 / resolution` for an integer
    /// resolution and whose origin lies on that lattice (both within round-off); otherwise, or
    /// for non-finite values or sizes over `i32`, this returns an error naming the file.
    pub fn write_sdf(&self, path: impl AsRef<Path>) -> Result<(), Error> {
        let path = path.as_ref();
        let refuse = |msg: String| Error::Invalid(format!("{}: cannot write .sdf: {msg}", path.display()));
        let inv = 1.0 / self.spacing;
        let resolution = inv.round();
        if !(self.spacing > 0.0 && inv.is_finite())
            || resolution < 1.0
            || resolution > i32::MAX as f64
            || (inv - resolution).abs() > 1e-9 * resolution
        {
            return Err(refuse(format!(
                "spacing {} is not 1/resolution for an integer resolution",
                self.spacing
            )));
        }
        let mut offset = [0i32; 3];
        for a in 0..3 {
            let o = self.origin[a] * resolution;
            let r = o.round();
            if !(o.is_finite() && (o - r).abs() <= 1e-6 * r.abs().max(1.0)) || r.abs() > i32::MAX as f64 {
                return Err(refuse(format!(
                    "origin {:?} is not on the lattice of spacing 1/{resolution}",
                    self.origin
                )));
            }
            offset[a] = r as i32;
        }
        if self.dims.iter().any(|&n| n == 0 || n > i32::MAX as usize) {
            return Err(refuse(format!("size {:?} does not fit the format", self.dims)));
        }
        if self.values.len() != self.node_count() {
            return Err(refuse(format!(
                "{} values for {:?} nodes",
                self.values.len(),
                self.dims
            )));
        }
        if let Some(n) = self.values.iter().position(|v| !v.is_finite()) {
            return Err(refuse(format!(
                "value {} at flat index {n} is not finite",
                self.values[n]
            )));
        }
        let mut out = Vec::with_capacity(HEADER + 4 * self.values.len());
        out.extend_from_slice(&(resolution as i32).to_le_bytes());
        for o in offset {
            out.extend_from_slice(&o.to_le_bytes());
        }
        for n in self.dims {
            out.extend_from_slice(&(n as i32).to_le_bytes());
        }
        for &v in &self.values {
            out.extend_from_slice(&((v * resolution) as f32).to_le_bytes());
        }
        std::fs::write(path, out).map_err(|e| Error::io(path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A header whose node count overflows 64 bits (2^30 per axis is 2^90 nodes) is refused as
    /// absurd, not wrapped to a small count and misread as a file with trailing data.
    #[test]
    fn node_counts_beyond_64_bits_are_absurd() {
        let dir = std::env::temp_dir().join(format!("cutfem-thesis-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (size, name) in [([1 << 30; 3], "a.sdf"), ([i32::MAX, i32::MAX, 2], "b.sdf")] {
            let mut bytes: Vec<u8> = [5i32, 0, 0, 0]
                .iter()
                .chain(&size)
                .flat_map(|v| v.to_le_bytes())
                .collect();
            bytes.extend([0u8; 64]);
            let path = dir.join(name);
            std::fs::write(&path, bytes).unwrap();
            let e = SdfGrid::read_sdf(&path).unwrap_err().to_string();
            assert!(e.contains("absurd size") && e.contains(name), "{e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
