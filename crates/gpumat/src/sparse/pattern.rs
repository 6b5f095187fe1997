//! The CSR sparsity pattern, built once and shared.

use crate::error::Error;
use std::sync::{Arc, OnceLock};

/// Row pointers and sorted, unique column indices of a sparse matrix.
#[derive(Debug)]
pub struct SparsityPattern {
    rows: usize,
    cols: usize,
    row_ptr: Vec<usize>,
    col_idx: Vec<u32>,
    transpose: OnceLock<TransposeMap>,
}

/// The pattern of the transpose, with the index of each entry in the original pattern (so
/// `A^T x` can be evaluated row by row: no atomics, deterministic).
#[derive(Debug, Clone)]
pub struct TransposeMap {
    /// column pointers: the entries of column `c` are `col_ptr[c]..col_ptr[c+1]`
    pub col_ptr: Vec<usize>,
    /// the row of each entry
    pub row_idx: Vec<usize>,
    /// the index of each entry in the original (row-major) pattern
    pub entry: Vec<usize>,
}

impl PartialEq for SparsityPattern {
    fn eq(&self, o: &Self) -> bool {
        self.rows == o.rows && self.cols == o.cols && self.row_ptr == o.row_ptr && self.col_idx == o.col_idx
    }
}

impl SparsityPattern {
    /// A pattern from CSR arrays; checks that they are consistent and the columns of each row
    /// are sorted, unique and in range.
    pub fn new(
        rows: usize,
        cols: usize,
        row_ptr: Vec<usize>,
        col_idx: Vec<usize>,
    ) -> Result<Arc<Self>, Error> {
        let bad = |why: String| Err(Error::InvalidPattern(why));
        if row_ptr.len() != rows + 1 {
            return bad(format!(
                "row_ptr has {} entries, expected {}",
                row_ptr.len(),
                rows + 1
            ));
        }
        if cols > u32::MAX as usize {
            return bad(format!("{cols} columns: column indices are stored as u32"));
        }
        if row_ptr[0] != 0 || row_ptr[rows] != col_idx.len() {
            return bad("row_ptr must start at 0 and end at the number of entries".into());
        }
        // Monotonic pointers first: with row_ptr[0] = 0 and row_ptr[rows] = nnz they then
        // stay in bounds, so slicing the rows below cannot panic.
        for r in 0..rows {
            if row_ptr[r] > row_ptr[r + 1] {
                return bad(format!("row_ptr decreases at row {r}"));
            }
        }
        for r in 0..rows {
            let row = &col_idx[row_ptr[r]..row_ptr[r + 1]];
            for (k, &c) in row.iter().enumerate() {
                if c >= cols {
                    return bad(format!("column {c} out of range in row {r}"));
                }
                if k > 0 && row[k - 1] >= c {
                    return bad(format!("columns of row {r} are not sorted and unique"));
                }
            }
        }
        Ok(Arc::new(Self {
            rows,
            cols,
            row_ptr,
            // checked above: every column < cols <= u32::MAX
            col_idx: col_idx.into_iter().map(|c| c as u32).collect(),
            transpose: OnceLock::new(),
        }))
    }

    /// A pattern from `(row, col)` pairs in any order; duplicates are merged.
    #[track_caller]
    pub fn from_entries(
        rows: usize,
        cols: usize,
        entries: impl IntoIterator<Item = (usize, usize)>,
    ) -> Arc<Self> {
        let mut e: Vec<(usize, usize)> = entries.into_iter().collect();
        for &(r, c) in &e {
            assert!(
                r < rows && c < cols,
                "gpumat::SparsityPattern::from_entries: ({r}, {c}) out of range"
            );
        }
        e.sort_unstable();
        e.dedup();
        let mut row_ptr = vec![0; rows + 1];
        for &(r, _) in &e {
            row_ptr[r + 1] += 1;
        }
        for r in 0..rows {
            row_ptr[r + 1] += row_ptr[r];
        }
        let col_idx = e.into_iter().map(|(_, c)| c).collect();
        Self::new(rows, cols, row_ptr, col_idx).expect("sorted unique entries form a valid pattern")
    }

    /// Rows.
    pub fn rows(&self) -> usize {
        self.rows
    }
    /// Columns.
    pub fn cols(&self) -> usize {
        self.cols
    }
    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.col_idx.len()
    }
    /// Row pointers.
    pub fn row_ptr(&self) -> &[usize] {
        &self.row_ptr
    }
    /// Column indices.
    /// (Stored as `u32`: half the index traffic of `usize` in every SpMV.)
    pub fn col_idx(&self) -> &[u32] {
        &self.col_idx
    }
    /// The entry range of row `r`.
    pub fn row_range(&self, r: usize) -> std::ops::Range<usize> {
        self.row_ptr[r]..self.row_ptr[r + 1]
    }
    /// The entry index of `(r, c)`, if stored.
    pub fn find(&self, r: usize, c: usize) -> Option<usize> {
        let range = self.row_range(r);
        let c = u32::try_from(c).ok()?;
        self.col_idx[range.clone()]
            .binary_search(&c)
            .ok()
            .map(|k| range.start + k)
    }
    /// The entry index of each diagonal element, if stored.
    pub fn diagonal_entries(&self) -> Vec<Option<usize>> {
        (0..self.rows.min(self.cols)).map(|r| self.find(r, r)).collect()
    }
    /// The row of every entry.
    pub fn entry_rows(&self) -> Vec<usize> {
        let mut rows = Vec::with_capacity(self.nnz());
        for r in 0..self.rows {
            rows.extend(std::iter::repeat(r).take(self.row_range(r).len()));
        }
        rows
    }
    /// The transpose map, computed on first use and cached.
    pub fn transpose_map(&self) -> &TransposeMap {
        self.transpose.get_or_init(|| {
            let mut col_ptr = vec![0usize; self.cols + 1];
            for &c in &self.col_idx {
                col_ptr[c as usize + 1] += 1;
            }
            for c in 0..self.cols {
                col_ptr[c + 1] += col_ptr[c];
            }
            let mut next = col_ptr.clone();
            let mut row_idx = vec![0; self.nnz()];
            let mut entry = vec![0; self.nnz()];
            for r in 0..self.rows {
                for k in self.row_range(r) {
                    let c = self.col_idx[k] as usize;
                    row_idx[next[c]] = r;
                    entry[next[c]] = k;
                    next[c] += 1;
                }
            }
            TransposeMap {
                col_ptr,
                row_idx,
                entry,
            }
        })
    }
    /// Splits `values` (one batch of values on this pattern) into consecutive blocks of
    /// `rows_per_chunk` rows: `(first row, the entries of those rows)`. Parallel row passes
    /// hand each block to one task, which then owns its rows' entries (no atomics, and the
    /// values do not depend on the number of threads).
    ///
    /// ```
    /// use gpumat::SparsityPattern;
    /// let p = SparsityPattern::from_entries(3, 3, [(0, 0), (0, 2), (1, 1), (2, 0), (2, 2)]);
    /// let mut v = [1, 2, 3, 4, 5];
    /// let blocks = p.split_rows_mut(&mut v, 2);
    /// assert_eq!(blocks.len(), 2);
    /// assert_eq!((blocks[0].0, &*blocks[0].1), (0, &[1, 2, 3][..]));
    /// assert_eq!((blocks[1].0, &*blocks[1].1), (2, &[4, 5][..]));
    /// ```
    #[track_caller]
    pub fn split_rows_mut<'a, T>(
        &self,
        values: &'a mut [T],
        rows_per_chunk: usize,
    ) -> Vec<(usize, &'a mut [T])> {
        assert!(
            values.len() == self.nnz() && rows_per_chunk > 0,
            "gpumat::SparsityPattern::split_rows_mut: {} values for {} entries, {rows_per_chunk} rows per chunk",
            values.len(),
            self.nnz()
        );
        let mut out = Vec::with_capacity(self.rows.div_ceil(rows_per_chunk));
        let mut rest = values;
        for r0 in (0..self.rows).step_by(rows_per_chunk) {
            let r1 = (r0 + rows_per_chunk).min(self.rows);
            let (head, tail) = rest.split_at_mut(self.row_ptr[r1] - self.row_ptr[r0]);
            out.push((r0, head));
            rest = tail;
        }
        out
    }
    /// True when both are the same pattern (pointer or structure).
    pub fn same_as(self: &Arc<Self>, other: &Arc<Self>) -> bool {
        Arc::ptr_eq(self, other) || **self == **other
    }
}
