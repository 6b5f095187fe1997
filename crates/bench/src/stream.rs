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

/// The three triad arrays, allocated once so the triad can be sampled repeatedly during a run
/// (on a shared host the bandwidth a machine gets varies over time).
#[derive(Debug)]
pub struct Triad {
    a: Vec<f32>,
    b: Vec<f32>,
    c: Vec<f32>,
}

impl Triad {
    /// Allocates and first-touches (in parallel, as STREAM does) three arrays of `n` f32.
    pub fn new(n: usize) -> Self {
        let mut t = Self {
            a: vec![0.0; n],
            b: vec![0.0; n],
            c: vec![0.0; n],
        };
        t.a.par_chunks_mut(CHUNK)
            .zip(t.b.par_chunks_mut(CHUNK))
            .zip(t.c.par_chunks_mut(CHUNK))
            .for_each(|((a, b), c)| {
                a.fill(0.0);
                b.fill(1.0);
                c.fill(2.0);
            });
        t
    }

    /// Array length.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// True when the arrays are empty.
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    /// The triad's bandwidth in GB/s (1e9 bytes per second) and the raw measurement.
    pub fn gbs(&mut self, policy: &Policy) -> (f64, Measurement) {
        let s = black_box(3.0f32);
        let (a, b, c) = (&mut self.a, &self.b, &self.c);
        let m = measure(policy, || {
            a.par_chunks_mut(CHUNK)
                .zip(b.par_chunks(CHUNK))
                .zip(c.par_chunks(CHUNK))
                .for_each(|((a, b), c)| {
                    for ((a, &b), &c) in a.iter_mut().zip(b).zip(c) {
                        *a = b + s * c;
                    }
                });
            black_box(&mut *a);
        });
        let n = self.a.len();
        assert!(n == 0 || self.a[n / 2] == 7.0, "triad result");
        ((12 * n) as f64 / m.seconds / 1e9, m)
    }
}

/// One STREAM triad measurement on fresh arrays of `n` f32: GB/s and the measurement.
pub fn triad_gbs(n: usize, policy: &Policy) -> (f64, Measurement) {
    Triad::new(n).gbs(policy)
}
