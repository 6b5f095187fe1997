//! The STREAM triad `a[i] = b[i] + s c[i]` on f32 arrays much larger than the last-level
//! cache, run on all of rayon's threads: the sustainable memory bandwidth every table row is
//! compared with. Bytes counted as in STREAM: two arrays read, one written (`12 n`), write-
//! allocate traffic not counted (the same convention as the `bytes` of the table rows).

use crate::timing::{measure, Measurement, Policy};
use rayon::prelude::*;
use std::hint::black_box;

/// Default array length: 2^25 f32 (128 MiB per array).
pub const DEFAULT_LEN: usize = 1 << 25;
/// Elements per rayon work item.
const CHUNK: usize = 1 << 16;

/// The triad's bandwidth in GB/s (1e9 bytes per second) and the raw measurement.
pub fn triad_gbs(n: usize, policy: &Policy) -> (f64, Measurement) {
    let mut a = vec![0.0f32; n];
    let mut b = vec![0.0f32; n];
    let mut c = vec![0.0f32; n];
    // First touch in parallel, as STREAM's initialisation does.
    a.par_chunks_mut(CHUNK)
        .zip(b.par_chunks_mut(CHUNK))
        .zip(c.par_chunks_mut(CHUNK))
        .for_each(|((a, b), c)| {
            a.fill(0.0);
            b.fill(1.0);
            c.fill(2.0);
        });
    let s = black_box(3.0f32);
    let m = measure(policy, || {
        a.par_chunks_mut(CHUNK)
            .zip(b.par_chunks(CHUNK))
            .zip(c.par_chunks(CHUNK))
            .for_each(|((a, b), c)| {
                for ((a, &b), &c) in a.iter_mut().zip(b).zip(c) {
                    *a = b + s * c;
                }
            });
        black_box(&mut a);
    });
    assert_eq!(a[n / 2], 7.0, "triad result");
    ((12 * n) as f64 / m.seconds / 1e9, m)
}
