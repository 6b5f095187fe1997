//! The timing policy shared by every system (gpumat in-process, the Eigen programs and the
//! numpy script receive the same numbers on their command line).
//!
//! One warm-up call first; its duration calibrates an inner loop so that one repetition lasts
//! at least [`Policy::min_sample`] (short kernels are timed in batches, so the clock's own cost
//! does not count). Then repetitions run until at least [`Policy::min_samples`] are done and
//! the [`Policy::budget`] is spent, or [`Policy::max_samples`] are done. The reported time is
//! the minimum over repetitions of (repetition time / inner count).
//!
//! Systems compared with each other are measured side by side: [`Policy::rounds`] rounds, each
//! timing every system in turn (A, B, A, B, ...), every system keeping its best round. Load
//! from other processes that comes and goes then hits all systems alike.

use std::time::{Duration, Instant};

/// How long and how often to repeat a measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Policy {
    /// at least this many timed repetitions
    pub min_samples: usize,
    /// at most this many timed repetitions
    pub max_samples: usize,
    /// keep repeating (up to `max_samples`) while the case has run less than this
    pub budget: Duration,
    /// an inner loop makes one repetition last at least this long
    pub min_sample: Duration,
    /// rounds of side-by-side measurement ([`measure_interleaved`], the peers' runs)
    pub rounds: usize,
}

impl Policy {
    /// The `--quick` policy.
    pub fn quick() -> Self {
        Self {
            min_samples: 3,
            max_samples: 20,
            budget: Duration::from_millis(200),
            min_sample: Duration::from_millis(2),
            rounds: 2,
        }
    }
    /// The full policy.
    pub fn full() -> Self {
        Self {
            min_samples: 5,
            max_samples: 50,
            budget: Duration::from_millis(500),
            min_sample: Duration::from_millis(5),
            rounds: 3,
        }
    }
    /// Human-readable description, for the `machine.timing` field.
    pub fn describe(&self) -> String {
        format!(
            "minimum over N repetitions (N >= {} and <= {} per round, repeating while a round has run \
             < {} s); one warm-up call per round; a repetition loops the kernel until it lasts >= {} ms \
             and is divided by the loop count; {} rounds side by side (gpumat fused, gpumat unfused, \
             Eigen, numpy in turn, each keeping its best round), in the same run; every system uses \
             this policy",
            self.min_samples,
            self.max_samples,
            self.budget.as_secs_f64(),
            self.min_sample.as_secs_f64() * 1e3,
            self.rounds
        )
    }
    /// The policy as command-line arguments for the peer programs:
    /// `BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S`.
    pub fn peer_args(&self) -> Vec<String> {
        vec![
            format!("{}", self.budget.as_secs_f64()),
            self.min_samples.to_string(),
            self.max_samples.to_string(),
            format!("{}", self.min_sample.as_secs_f64()),
        ]
    }
}

/// The result of [`measure`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    /// seconds per call: the minimum over repetitions
    pub seconds: f64,
    /// timed repetitions
    pub samples: usize,
    /// calls per repetition
    pub inner: usize,
}

/// Times `f` under `policy` (see the module docs). `f` should `black_box` its results.
pub fn measure(policy: &Policy, mut f: impl FnMut()) -> Measurement {
    let t0 = Instant::now();
    f();
    let first = t0.elapsed().as_secs_f64();
    let want = policy.min_sample.as_secs_f64();
    let inner = if first >= want {
        1
    } else {
        ((want / first.max(1e-9)).ceil() as usize).clamp(1, 10_000_000)
    };
    let start = Instant::now();
    let mut best = f64::INFINITY;
    let mut samples = 0;
    while samples < policy.max_samples && (samples < policy.min_samples || start.elapsed() < policy.budget) {
        let t = Instant::now();
        for _ in 0..inner {
            f();
        }
        best = best.min(t.elapsed().as_secs_f64() / inner as f64);
        samples += 1;
    }
    Measurement {
        seconds: best,
        samples,
        inner,
    }
}

/// The better (faster) of two measurements of the same kernel, samples added up.
pub fn best_of(a: Option<Measurement>, b: Measurement) -> Measurement {
    match a {
        Some(a) if a.seconds <= b.seconds => Measurement {
            samples: a.samples + b.samples,
            ..a
        },
        Some(a) => Measurement {
            samples: a.samples + b.samples,
            ..b
        },
        None => b,
    }
}

/// Measures every kernel of `fs` in turn, [`Policy::rounds`] times (A, B, A, B, ...); each
/// kernel keeps its best round (`samples` adds up the rounds).
pub fn measure_interleaved(policy: &Policy, fs: &mut [&mut dyn FnMut()]) -> Vec<Measurement> {
    let mut best: Vec<Option<Measurement>> = vec![None; fs.len()];
    for _ in 0..policy.rounds.max(1) {
        for (f, b) in fs.iter_mut().zip(best.iter_mut()) {
            *b = Some(best_of(*b, measure(policy, &mut **f)));
        }
    }
    best.into_iter().map(|m| m.expect("at least one round")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measure_reports_a_positive_minimum() {
        let p = Policy {
            min_samples: 2,
            max_samples: 3,
            budget: Duration::from_millis(1),
            min_sample: Duration::from_micros(100),
            rounds: 2,
        };
        let mut calls = 0usize;
        let m = measure(&p, || {
            calls += 1;
            std::hint::black_box(calls);
        });
        assert!(m.seconds > 0.0 && m.samples >= 2 && m.samples <= 3);
        assert_eq!(calls, 1 + m.samples * m.inner);
        let (mut a, mut b) = (0usize, 0usize);
        let ms = measure_interleaved(&p, &mut [&mut || a += 1, &mut || b += 1]);
        assert_eq!(ms.len(), 2);
        assert!(ms.iter().all(|m| m.samples >= 4));
        assert!(a > 0 && b > 0);
    }
}
