//! Distributing a study's recordings over processes (an MPI job, `softbody` feature `mpi`).
//!
//! An [`Ensemble`] is a group of processes (ranks) that all run the same joint fit. Each
//! recording is *owned* by one rank ([`assign`]: a static balance by estimated cost, largest
//! first onto the least loaded rank). In every evaluation each rank simulates only the
//! recordings it owns; the per-recording results (cost, per-frame totals, gradient,
//! Gauss-Newton block, or the error) are then exchanged with one all-gather, so that every rank
//! holds every recording's result and takes the sums of [`super::joint`] itself, **in the
//! recordings' order**. That is the deterministic reduction: the sums are the same floating
//! point operations in the same order as in one process, so the result is bit-identical
//! whatever the rank (or thread) count, and every rank's optimizer takes the same steps.
//!
//! A recording that fails on its rank (a CG failure, a diverged run) reaches every rank
//! through the same exchange, so all ranks stop with the same error and none waits forever.
//!
//! The results travel as plain little-endian bytes ([`Wire`]): `f64` bit patterns, so nothing
//! is rounded on the way. The evaluated model is not sent; each rank rebuilds it from the
//! recording's coordinates ([`crate::problem::Problem::model_at`]), which is what the owner
//! evaluated.

use crate::cost::FrameCost;
use crate::problem::Evaluation;
use crate::Error;
use cutfem::fem::Model;

/// A group of processes running the same joint fit.
pub trait Ensemble {
    /// This process' rank, `0..size()`.
    fn rank(&self) -> usize;
    /// The number of ranks.
    fn size(&self) -> usize;
    /// Every rank's `mine`, in rank order, on every rank (a collective: every rank calls it).
    fn all_gather(&self, mine: &[u8]) -> Vec<Vec<u8>>;
}

impl std::fmt::Debug for dyn Ensemble {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Ensemble(rank {} of {})", self.rank(), self.size())
    }
}

/// The owning rank of each recording: `costs[r]` is recording `r`'s estimated cost; the
/// largest goes first onto the least loaded rank (ties: the lower recording, the lower rank).
pub fn assign(costs: &[f64], size: usize) -> Vec<usize> {
    let size = size.max(1);
    let mut order: Vec<usize> = (0..costs.len()).collect();
    order.sort_by(|&a, &b| costs[b].total_cmp(&costs[a]).then(a.cmp(&b)));
    let mut load = vec![0.0f64; size];
    let mut owner = vec![0; costs.len()];
    for r in order {
        let rank = (0..size)
            .min_by(|&a, &b| load[a].total_cmp(&load[b]).then(a.cmp(&b)))
            .expect("at least one rank");
        owner[r] = rank;
        load[rank] += costs[r].max(0.0);
    }
    owner
}

/// A value that travels between ranks as bytes.
pub trait Wire: Sized {
    /// Appends the value's bytes.
    fn put(&self, out: &mut Vec<u8>);
    /// Reads the value back; `model` is the recording's model at the evaluated coordinates.
    fn take(input: &mut Reader<'_>, model: &Model) -> Result<Self, Error>;
}

/// Reads values written by [`Wire::put`].
#[derive(Debug)]
pub struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    /// Reads `bytes` from the start.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes }
    }
    /// True when everything was read.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
    fn take8(&mut self) -> Result<[u8; 8], Error> {
        if self.bytes.len() < 8 {
            return Err(Error::invalid(
                "a rank's results ended early (the ranks run different builds?)",
            ));
        }
        let (head, rest) = self.bytes.split_at(8);
        self.bytes = rest;
        Ok(head.try_into().expect("8 bytes"))
    }
    /// An `f64` (its bit pattern).
    pub fn f64(&mut self) -> Result<f64, Error> {
        Ok(f64::from_le_bytes(self.take8()?))
    }
    /// A `usize` (as 64 bits).
    pub fn usize(&mut self) -> Result<usize, Error> {
        usize::try_from(u64::from_le_bytes(self.take8()?))
            .map_err(|_| Error::invalid("a rank sent a count too large for this machine"))
    }
    /// One byte.
    pub fn byte(&mut self) -> Result<u8, Error> {
        let (&b, rest) = self
            .bytes
            .split_first()
            .ok_or_else(|| Error::invalid("a rank's results ended early"))?;
        self.bytes = rest;
        Ok(b)
    }
    /// A length-prefixed string.
    pub fn string(&mut self) -> Result<String, Error> {
        let n = self.usize()?;
        if self.bytes.len() < n {
            return Err(Error::invalid("a rank's message ended early"));
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(String::from_utf8_lossy(head).into_owned())
    }
}

fn put_f64(out: &mut Vec<u8>, v: f64) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_usize(out: &mut Vec<u8>, v: usize) {
    out.extend_from_slice(&(v as u64).to_le_bytes());
}

/// Appends a length-prefixed string.
pub fn put_string(out: &mut Vec<u8>, s: &str) {
    put_usize(out, s.len());
    out.extend_from_slice(s.as_bytes());
}

impl Wire for Vec<f64> {
    fn put(&self, out: &mut Vec<u8>) {
        put_usize(out, self.len());
        for &v in self {
            put_f64(out, v);
        }
    }
    fn take(input: &mut Reader<'_>, _: &Model) -> Result<Self, Error> {
        let n = input.usize()?;
        if n > input.bytes.len() / 8 {
            return Err(Error::invalid("a rank sent a vector longer than its message"));
        }
        (0..n).map(|_| input.f64()).collect()
    }
}

impl Wire for FrameCost {
    fn put(&self, out: &mut Vec<u8>) {
        put_usize(out, self.frame);
        put_f64(out, self.cost);
        put_f64(out, self.sum_squared);
        put_usize(out, self.count);
        put_usize(out, self.outside);
        put_f64(out, self.weighted_squared);
        put_usize(out, self.informative);
    }
    fn take(input: &mut Reader<'_>, _: &Model) -> Result<Self, Error> {
        Ok(FrameCost {
            frame: input.usize()?,
            cost: input.f64()?,
            sum_squared: input.f64()?,
            count: input.usize()?,
            outside: input.usize()?,
            weighted_squared: input.f64()?,
            informative: input.usize()?,
        })
    }
}

impl Wire for Evaluation {
    fn put(&self, out: &mut Vec<u8>) {
        put_f64(out, self.cost);
        put_usize(out, self.frames.len());
        for f in &self.frames {
            f.put(out);
        }
        for s in [self.forward_s, self.cost_s, self.backward_s] {
            put_f64(out, s);
        }
        for n in [self.forward_iterations, self.backward_iterations, self.fallbacks] {
            put_usize(out, n);
        }
        match &self.gauss_newton {
            Some(h) => {
                put_usize(out, 1);
                h.put(out);
            }
            None => put_usize(out, 0),
        }
    }
    fn take(input: &mut Reader<'_>, model: &Model) -> Result<Self, Error> {
        let cost = input.f64()?;
        let n = input.usize()?;
        let frames = (0..n.min(input.bytes.len()))
            .map(|_| FrameCost::take(input, model))
            .collect::<Result<Vec<_>, _>>()?;
        if frames.len() != n {
            return Err(Error::invalid("a rank sent fewer frames than it announced"));
        }
        Ok(Evaluation {
            cost,
            frames,
            model: model.clone(),
            forward_s: input.f64()?,
            cost_s: input.f64()?,
            backward_s: input.f64()?,
            forward_iterations: input.usize()?,
            backward_iterations: input.usize()?,
            fallbacks: input.usize()?,
            gauss_newton: match input.usize()? {
                0 => None,
                _ => Some(Vec::<f64>::take(input, model)?),
            },
        })
    }
}

impl<A: Wire, B: Wire> Wire for (A, B) {
    fn put(&self, out: &mut Vec<u8>) {
        self.0.put(out);
        self.1.put(out);
    }
    fn take(input: &mut Reader<'_>, model: &Model) -> Result<Self, Error> {
        Ok((A::take(input, model)?, B::take(input, model)?))
    }
}

impl<A: Wire, B: Wire, C: Wire> Wire for (A, B, C) {
    fn put(&self, out: &mut Vec<u8>) {
        self.0.put(out);
        self.1.put(out);
        self.2.put(out);
    }
    fn take(input: &mut Reader<'_>, model: &Model) -> Result<Self, Error> {
        Ok((
            A::take(input, model)?,
            B::take(input, model)?,
            C::take(input, model)?,
        ))
    }
}

/// Every rank's outcome of a step all ranks take (reading files, creating the report folder):
/// `Ok` when every rank succeeded, else the first failure in rank order (`rank k: message`), on
/// every rank. A collective: every rank calls it, so a failure on one rank stops them all.
pub fn agree(ensemble: &dyn Ensemble, mine: Result<(), String>) -> Result<(), String> {
    let mut bytes = Vec::new();
    match &mine {
        Ok(()) => put_usize(&mut bytes, 0),
        Err(e) => {
            put_usize(&mut bytes, 1);
            put_string(&mut bytes, e);
        }
    }
    for (rank, b) in ensemble.all_gather(&bytes).iter().enumerate() {
        let mut r = Reader::new(b);
        if r.usize().map_err(|e| e.to_string())? != 0 {
            let msg = r.string().map_err(|e| e.to_string())?;
            return Err(if ensemble.size() > 1 {
                format!("rank {rank}: {msg}")
            } else {
                msg
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assign_balances_largest_first() {
        // 5, 4, 3, 3, 1 on two ranks: 5 -> 0, 4 -> 1, 3 -> 1 (7), 3 -> 0 (8), 1 -> 1 (8)
        assert_eq!(assign(&[3.0, 5.0, 1.0, 4.0, 3.0], 2), vec![1, 0, 1, 1, 0]);
        assert_eq!(assign(&[1.0, 1.0, 1.0], 1), vec![0, 0, 0]);
        // more ranks than recordings: one each, the rest idle
        assert_eq!(assign(&[2.0, 1.0], 4), vec![0, 1]);
    }

    #[test]
    fn values_round_trip_bit_for_bit() {
        let model = Model::default();
        let v = vec![0.1, -0.0, f64::MIN_POSITIVE, 1e300, std::f64::consts::PI];
        let ev = Evaluation {
            cost: 1.0 / 3.0,
            frames: vec![FrameCost {
                frame: 3,
                cost: 0.7,
                sum_squared: 2.0f64.sqrt(),
                count: 11,
                outside: 2,
                weighted_squared: 1e-17,
                informative: 9,
            }],
            model: model.clone(),
            forward_s: 1.5,
            cost_s: 0.25,
            backward_s: 2.0,
            forward_iterations: 7,
            backward_iterations: 8,
            fallbacks: 1,
            gauss_newton: Some(vec![1.0, 0.5, 0.5, 2.0]),
        };
        let mut out = Vec::new();
        (ev.clone(), v.clone()).put(&mut out);
        let mut r = Reader::new(&out);
        let (ev2, v2) = <(Evaluation, Vec<f64>)>::take(&mut r, &model).unwrap();
        assert!(r.is_empty());
        assert_eq!(
            v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            v2.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(ev2.frames, ev.frames);
        assert_eq!(ev2.cost.to_bits(), ev.cost.to_bits());
        assert_eq!(ev2.gauss_newton, ev.gauss_newton);
        assert_eq!((ev2.forward_iterations, ev2.fallbacks), (7, 1));
        // a truncated message is an error, not a panic
        for cut in [0, 5, out.len() / 2, out.len() - 1] {
            let mut r = Reader::new(&out[..cut]);
            assert!(<(Evaluation, Vec<f64>)>::take(&mut r, &model).is_err());
        }
    }
}
