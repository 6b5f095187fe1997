//! 3x3 block-sparse matrices on a device: the pattern once, the values every step (architecture
//! principle "pattern once / values every step"); SpMV, the Newmark-1 matrix and block-Jacobi.
//!
//! - SpMV `y_b = A_b x_b` (kernel `gpumat_bsr3_spmv`): one thread per block row and batch, the
//!   row's blocks in pattern order, as the CPU's row loop.
//! - Newmark-1 (theta scheme, thesis eq. 4.3): `A = cm M + ck K` entry by entry on a shared
//!   pattern, `cm = 1/(theta dt) + a1`, `ck = a2 + theta dt` (kernel `gpumat_newmark_a_bsr3`).
//! - Block-Jacobi `z = D^-1 r` with `D` the 3x3 diagonal blocks, inverted once per matrix by the
//!   adjugate (`gpumat_inverse3`); a singular or non-finite block is
//!   [`Error::SingularDiagonal`], as on the CPU.

use super::{Device, DeviceBuffer, DeviceReal};
use crate::cuda::launch;
use crate::error::Error;
use crate::scalar::Scalar;
use crate::sparse::{SparseMatrix, SparsityPattern};
use crate::{Mat3, Vec3};
use std::sync::Arc;

/// A block pattern on a device: CSR arrays and the position of each row's diagonal block.
#[derive(Debug)]
pub struct DevicePattern {
    host: Arc<SparsityPattern>,
    row_ptr: DeviceBuffer<u64>,
    col_idx: DeviceBuffer<u32>,
    diag: Option<DeviceBuffer<u64>>,
}

impl DevicePattern {
    /// Uploads `pattern` (the diagonal positions too when every row has its diagonal).
    pub fn new(device: &Arc<dyn Device>, pattern: &Arc<SparsityPattern>) -> Result<Self, Error> {
        let row_ptr: Vec<u64> = pattern.row_ptr().iter().map(|&v| v as u64).collect();
        let diag: Option<Vec<u64>> = pattern
            .diagonal_entries()
            .iter()
            .map(|d| d.map(|d| d as u64))
            .collect();
        Ok(Self {
            host: pattern.clone(),
            row_ptr: DeviceBuffer::from_slice(device, &row_ptr)?,
            col_idx: DeviceBuffer::from_slice(device, pattern.col_idx())?,
            diag: match diag.filter(|d| d.len() == pattern.rows()) {
                Some(d) => Some(DeviceBuffer::from_slice(device, &d)?),
                None => None,
            },
        })
    }
    /// True when this is the upload of `pattern`.
    pub fn is(&self, pattern: &Arc<SparsityPattern>) -> bool {
        self.host.same_as(pattern)
    }
    /// The host pattern.
    pub fn host(&self) -> &Arc<SparsityPattern> {
        &self.host
    }
}

/// A batched 3x3 block-sparse matrix on a device (values batch after batch, in pattern order).
#[derive(Debug)]
pub struct DeviceBsr3<R: DeviceReal> {
    pattern: Arc<DevicePattern>,
    values: DeviceBuffer<Mat3<R>>,
    batches: usize,
}

impl<R: DeviceReal> DeviceBsr3<R>
where
    Mat3<R>: Scalar + bytemuck::Pod,
    Vec3<R>: Scalar + bytemuck::Pod,
{
    /// Zero values on `pattern`, `batches` value sets.
    pub fn zeros(pattern: &Arc<DevicePattern>, batches: usize) -> Result<Self, Error> {
        Ok(Self {
            pattern: pattern.clone(),
            values: DeviceBuffer::zeros(pattern.row_ptr.device(), pattern.host.nnz() * batches)?,
            batches,
        })
    }
    /// An upload of `a` onto `pattern` (which must be the upload of `a`'s pattern).
    pub fn from_host(pattern: &Arc<DevicePattern>, a: &SparseMatrix<Mat3<R>>) -> Result<Self, Error> {
        let mut m = Self::zeros(pattern, a.batches())?;
        m.upload_values(a)?;
        Ok(m)
    }
    /// Overwrites the values with `a`'s (same pattern, same batches): the per-step upload.
    pub fn upload_values(&mut self, a: &SparseMatrix<Mat3<R>>) -> Result<(), Error> {
        assert!(
            self.pattern.is(a.pattern()) && a.batches() == self.batches,
            "DeviceBsr3::upload_values: another pattern or batch count"
        );
        self.values.upload(a.values())
    }
    /// The values back on the host.
    pub fn to_host(&self) -> Result<SparseMatrix<Mat3<R>>, Error> {
        Ok(SparseMatrix::from_values(
            self.pattern.host.clone(),
            self.batches,
            self.values.to_vec()?,
        ))
    }
    /// Block rows.
    pub fn rows(&self) -> usize {
        self.pattern.host.rows()
    }
    /// Block columns.
    pub fn cols(&self) -> usize {
        self.pattern.host.cols()
    }
    /// Value sets.
    pub fn batches(&self) -> usize {
        self.batches
    }
    /// The pattern.
    pub fn pattern(&self) -> &Arc<DevicePattern> {
        &self.pattern
    }
    fn device(&self) -> &Arc<dyn Device> {
        self.values.device()
    }

    /// `y = A x` for every batch: `x` holds `cols x batches`, `y` `rows x batches` vectors.
    pub fn spmv(&self, x: &DeviceBuffer<Vec3<R>>, y: &mut DeviceBuffer<Vec3<R>>) -> Result<(), Error> {
        let (rows, cols, nb) = (self.rows(), self.cols(), self.batches);
        assert!(
            x.len() == cols * nb && y.len() == rows * nb,
            "DeviceBsr3::spmv: x has {} and y {} vectors for a {rows} x {cols} x {nb} matrix",
            x.len(),
            y.len()
        );
        let p = &self.pattern;
        let args = [
            p.row_ptr.arg(),
            p.col_idx.arg(),
            self.values.arg(),
            super::Arg::Index(p.host.nnz() as u64),
            x.arg(),
            y.arg(),
            super::Arg::Index(rows as u64),
            super::Arg::Index(cols as u64),
            super::Arg::Index(nb as u64),
        ];
        // SAFETY: the arguments follow gpumat_bsr3_spmv's parameters (build.rs `spmv`); the
        // pattern arrays, nnz x batches values, and x / y sizes are the ones checked above.
        unsafe {
            self.device().launch(
                &format!("gpumat_bsr3_spmv_{}", R::SUFFIX),
                launch::elementwise(rows * nb),
                &args,
            )
        }
    }

    /// `self = cm M + ck K` entry by entry (the Newmark-1 matrix; all three on one pattern with
    /// the same batches).
    pub fn assign_newmark(
        &mut self,
        m: &DeviceBsr3<R>,
        k: &DeviceBsr3<R>,
        cm: R,
        ck: R,
    ) -> Result<(), Error> {
        assert!(
            Arc::ptr_eq(&m.pattern, &self.pattern)
                && Arc::ptr_eq(&k.pattern, &self.pattern)
                && m.batches == self.batches
                && k.batches == self.batches,
            "DeviceBsr3::assign_newmark: M, K and A must share the pattern and batches"
        );
        let len = self.values.len();
        let args = [
            m.values.arg(),
            k.values.arg(),
            self.values.arg(),
            cm.arg(),
            ck.arg(),
            super::Arg::Index(len as u64),
        ];
        // SAFETY: gpumat_newmark_a_bsr3's parameters (build.rs `spmv`); the three value arrays
        // have `len` blocks each (same pattern and batches, asserted).
        unsafe {
            self.device().launch(
                &format!("gpumat_newmark_a_bsr3_{}", R::SUFFIX),
                launch::elementwise(len),
                &args,
            )
        }
    }
}

/// Block-Jacobi on a device: the inverse diagonal blocks of a [`DeviceBsr3`].
#[derive(Debug)]
pub struct DeviceBlockJacobi<R: DeviceReal> {
    inv: DeviceBuffer<Mat3<R>>,
}

impl<R: DeviceReal> DeviceBlockJacobi<R>
where
    Mat3<R>: Scalar + bytemuck::Pod,
    Vec3<R>: Scalar + bytemuck::Pod,
{
    /// Inverts `a`'s diagonal blocks (one read-back of the singularity flags).
    pub fn new(a: &DeviceBsr3<R>) -> Result<Self, Error> {
        let (rows, nb) = (a.rows(), a.batches());
        let device = a.device();
        let diag = match &a.pattern.diag {
            Some(d) => d,
            None => {
                let row = a.pattern.host.diagonal_entries().iter().position(Option::is_none);
                return Err(Error::MissingDiagonal {
                    row: row.unwrap_or(a.pattern.host.rows().min(a.pattern.host.cols())),
                });
            }
        };
        let inv = DeviceBuffer::<Mat3<R>>::zeros(device, rows * nb)?;
        let bad = DeviceBuffer::<u32>::zeros(device, rows * nb)?;
        let args = [
            a.values.arg(),
            inv.arg(),
            diag.arg(),
            super::Arg::Index(a.pattern.host.nnz() as u64),
            bad.arg(),
            super::Arg::Index(rows as u64),
            super::Arg::Index(nb as u64),
        ];
        // SAFETY: gpumat_block_jacobi_setup's parameters (build.rs `precond`): rows x batches
        // inverses and flags, one diagonal position per row, nnz x batches values.
        unsafe {
            device.launch(
                &format!("gpumat_block_jacobi_setup_{}", R::SUFFIX),
                launch::elementwise(rows * nb),
                &args,
            )?;
        }
        if let Some(i) = bad.to_vec()?.iter().position(|&f| f != 0) {
            return Err(Error::SingularDiagonal {
                row: i % rows.max(1),
                batch: i / rows.max(1),
            });
        }
        Ok(Self { inv })
    }
    /// `z = D^-1 r`.
    pub fn apply(&self, r: &DeviceBuffer<Vec3<R>>, z: &mut DeviceBuffer<Vec3<R>>) -> Result<(), Error> {
        let len = self.inv.len();
        assert!(
            r.len() == len && z.len() == len,
            "DeviceBlockJacobi::apply: {len} blocks, r has {}, z {}",
            r.len(),
            z.len()
        );
        let args = [self.inv.arg(), r.arg(), z.arg(), super::Arg::Index(len as u64)];
        // SAFETY: gpumat_block_jacobi_apply's parameters; inv, r and z have `len` elements.
        unsafe {
            self.inv.device().launch(
                &format!("gpumat_block_jacobi_apply_{}", R::SUFFIX),
                launch::elementwise(len),
                &args,
            )
        }
    }
}
