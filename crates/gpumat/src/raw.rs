//! A raw shared buffer: disjoint parts of one slice borrowed by parallel tasks.
//!
//! Some passes write one output buffer from many tasks whose parts are disjoint but not
//! regular chunks, and read parts other tasks have finished: the cutfem step assembly, where a
//! unit of cells writes its cells' data, its rows' blocks (a variable number per row) and the
//! blocks below the diagonal of its rows from their mirrors in earlier rows. Rust's safe
//! splitting (`chunks_mut`, `split_at_mut`) cannot express "these parts now, those parts once
//! their writers are done", so [`SharedParts`] hands out parts by range or element and leaves
//! the disjointness to the caller's schedule: its methods are `unsafe` with the contract
//! stated on each, and every access is bounds-checked. The buffer is borrowed for `'a`, so no
//! part outlives it.
//!
//! ```
//! use gpumat::raw::SharedParts;
//! let mut v = vec![0u32; 8];
//! let p = SharedParts::new(&mut v);
//! rayon::scope(|s| {
//!     for k in 0..4 {
//!         // SAFETY: the tasks borrow the disjoint parts 2k..2k+2.
//!         s.spawn(move |_| unsafe { p.part_mut(2 * k..2 * k + 2) }.fill(k as u32));
//!     }
//! });
//! assert_eq!(v, [0, 0, 1, 1, 2, 2, 3, 3]);
//! ```

use std::marker::PhantomData;
use std::ops::Range;

/// A slice whose disjoint parts tasks borrow (module docs).
pub struct SharedParts<'a, T> {
    ptr: *mut T,
    len: usize,
    _buffer: PhantomData<&'a mut [T]>,
}

impl<T> Clone for SharedParts<'_, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for SharedParts<'_, T> {}

impl<T> std::fmt::Debug for SharedParts<'_, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SharedParts").field("len", &self.len).finish()
    }
}

// SAFETY: `SharedParts` only hands out borrows of parts through its unsafe methods, whose
// callers guarantee that no two tasks borrow overlapping parts unless both borrow them shared;
// with that, sending or sharing it is sending or sharing `&mut [T]` parts.
unsafe impl<T: Send> Send for SharedParts<'_, T> {}
// SAFETY: as above (shared parts are read from several tasks: `T: Sync`).
unsafe impl<T: Send + Sync> Sync for SharedParts<'_, T> {}

impl<'a, T> SharedParts<'a, T> {
    /// The parts of `s`, borrowed for `'a`.
    pub fn new(s: &'a mut [T]) -> Self {
        Self {
            ptr: s.as_mut_ptr(),
            len: s.len(),
            _buffer: PhantomData,
        }
    }

    /// The length of the buffer.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the buffer is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    #[track_caller]
    fn check(&self, r: &Range<usize>) {
        assert!(
            r.start <= r.end && r.end <= self.len,
            "gpumat::raw: part {r:?} out of a buffer of {}",
            self.len
        );
    }

    #[inline(always)]
    #[track_caller]
    fn check_at(&self, k: usize) {
        assert!(
            k < self.len,
            "gpumat::raw: element {k} out of a buffer of {}",
            self.len
        );
    }

    /// Part `r`, borrowed exclusively.
    ///
    /// # Safety
    /// No other borrow, read or write of an element of `r` happens while the result is alive.
    #[allow(clippy::mut_from_ref)]
    #[track_caller]
    pub unsafe fn part_mut(&self, r: Range<usize>) -> &'a mut [T] {
        self.check(&r);
        // SAFETY: in bounds (checked), alive for 'a (borrowed by `new`), exclusive (the
        // caller's contract).
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(r.start), r.len()) }
    }

    /// Part `r`, borrowed shared.
    ///
    /// # Safety
    /// No task writes an element of `r`, or borrows it exclusively, while the result is alive.
    #[track_caller]
    pub unsafe fn part(&self, r: Range<usize>) -> &'a [T] {
        self.check(&r);
        // SAFETY: in bounds (checked), alive for 'a, not written (the caller's contract).
        unsafe { std::slice::from_raw_parts(self.ptr.add(r.start), r.len()) }
    }

    /// Element `k`.
    ///
    /// # Safety
    /// No task writes element `k` while this runs.
    #[inline(always)]
    #[track_caller]
    pub unsafe fn read(&self, k: usize) -> T
    where
        T: Copy,
    {
        self.check_at(k);
        // SAFETY: in bounds (checked), initialized (a slice's element), not written
        // concurrently (the caller's contract).
        unsafe { self.ptr.add(k).read() }
    }

    /// Writes `v` into element `k`.
    ///
    /// # Safety
    /// No other task reads, writes or borrows element `k` while this runs.
    #[inline(always)]
    #[track_caller]
    pub unsafe fn write(&self, k: usize, v: T)
    where
        T: Copy,
    {
        self.check_at(k);
        // SAFETY: in bounds (checked) and exclusive (the caller's contract); `T: Copy` has no
        // destructor to skip.
        unsafe { self.ptr.add(k).write(v) }
    }
}
