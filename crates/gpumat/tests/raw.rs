//! `gpumat::raw::SharedParts`: parallel tasks writing disjoint irregular parts, and a second
//! phase reading parts the first phase finished, give what a sequential pass gives.

use gpumat::raw::SharedParts;
use proptest::prelude::*;
use rayon::prelude::*;

/// Cuts `0..n` at the sorted cut points `cuts` (duplicates give empty parts).
fn ranges(n: usize, cuts: &[usize]) -> Vec<std::ops::Range<usize>> {
    let mut c: Vec<usize> = cuts.iter().map(|&c| c % (n + 1)).collect();
    c.sort_unstable();
    let mut out = Vec::new();
    let mut start = 0;
    for &e in c.iter().chain(std::iter::once(&n)) {
        out.push(start..e);
        start = e;
    }
    out
}

proptest! {
    /// Phase 1: each task fills its part with a function of the index. Phase 2 (after the
    /// first has joined): each task writes, into a second buffer, its part's elements plus the
    /// element mirrored at `n - 1 - i` (in another task's part). Both equal the sequential
    /// results, whatever the partition and thread count.
    #[test]
    fn disjoint_parts_match_a_sequential_pass(
        n in 0usize..2000,
        cuts in proptest::collection::vec(0usize..2001, 0..40),
        threads in 1usize..5,
    ) {
        let parts = ranges(n, &cuts);
        let f = |i: usize| (i as u64).wrapping_mul(2654435761) % 1000;
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let (mut a, mut b) = (vec![0u64; n], vec![0u64; n]);
        pool.install(|| {
            let pa = SharedParts::new(&mut a);
            parts.par_iter().for_each(|r| {
                // SAFETY: the parts of a partition are disjoint.
                let s = unsafe { pa.part_mut(r.clone()) };
                for (k, v) in r.clone().zip(s) {
                    *v = f(k);
                }
            });
            let pb = SharedParts::new(&mut b);
            parts.par_iter().for_each(|r| {
                for k in r.clone() {
                    // SAFETY: `a` is only read in this phase; `b`'s parts are disjoint.
                    unsafe { pb.write(k, pa.read(k) + pa.read(n - 1 - k)) };
                }
            });
        });
        let want_a: Vec<u64> = (0..n).map(f).collect();
        let want_b: Vec<u64> = (0..n).map(|k| f(k) + f(n - 1 - k)).collect();
        prop_assert_eq!(a, want_a);
        prop_assert_eq!(b, want_b);
    }
}

#[test]
fn shared_parts_read_what_was_written() {
    let mut v: Vec<i32> = (0..10).collect();
    let p = SharedParts::new(&mut v);
    assert_eq!((p.len(), p.is_empty()), (10, false));
    // SAFETY: one thread, no other borrow alive while each call runs.
    unsafe {
        assert_eq!(p.part(2..5), &[2, 3, 4]);
        assert!(p.part(10..10).is_empty());
        p.write(9, -1);
        assert_eq!(p.read(9), -1);
    }
    assert_eq!(v[9], -1);
}

#[test]
#[should_panic(expected = "gpumat::raw: part 8..11 out of a buffer of 10")]
fn a_part_out_of_the_buffer_panics() {
    let mut v = vec![0u8; 10];
    let p = SharedParts::new(&mut v);
    // SAFETY: the only borrow (and it panics before it exists).
    let _ = unsafe { p.part_mut(8..11) };
}

#[test]
#[should_panic(expected = "gpumat::raw: element 10 out of a buffer of 10")]
fn an_element_out_of_the_buffer_panics() {
    let mut v = vec![0u8; 10];
    let p = SharedParts::new(&mut v);
    // SAFETY: no other access (and it panics before writing).
    unsafe { p.write(10, 1) };
}
