//! The triangular solves `L y = b`, `L^T x = y` of a supernodal Cholesky factor, run over the
//! supernodal elimination tree so that independent subtrees run on different threads.
//!
//! faer's supernodal solve visits the supernodes in order and scatters each one's update
//! `L_bot x_s` into the right-hand side (`x[pattern(s)] -= L_bot(s) x_s`): one thread, and the
//! solves read the whole factor twice, so a solve is bound by one core's memory bandwidth (the
//! r = 20 cuboid's 647 MB factor: ~120 ms). Here, with `cols(s)` the supernode's columns
//! (contiguous) and `pattern(s)` its off-diagonal rows (sorted, all in ancestors of `s`):
//!
//! - forward, children before parents (multifrontal "fan-in"): a supernode receives its
//!   children's update vectors `u_c` (on `pattern(c)`, which lies in `cols(s) ∪ pattern(s)`: the
//!   supernodal elimination tree's containment property, checked when the tree is built),
//!   subtracts the part on its columns, `L_ss x_s = b_s - sum_c u_c|cols(s)`, and passes
//!   `u_s = sum_c u_c|pattern(s) + L_bot(s) x_s` to its parent;
//! - backward, parents before children: `L_ss^T x_s = y_s - L_bot(s)^T x[pattern(s)]`, reading
//!   only ancestors' finished values and writing only its own columns.
//!
//! Each supernode's arithmetic is fixed (children in ascending order), whatever runs where: the
//! result has the same bits for every thread count. Subtrees of at least [`PAR_WORK`] factor
//! entries with a sibling as large run in parallel (rayon); smaller ones run in a loop.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;

/// Factor entries below which a subtree is solved by one thread.
const PAR_WORK: usize = 1 << 20;

/// The supernodal elimination tree of a factor, with what the solves need of it.
#[derive(Debug, Clone)]
pub(crate) struct SupernodeTree {
    /// first column of each supernode, and the end (`n_supernodes + 1` entries)
    begin: Vec<usize>,
    /// each supernode's off-diagonal rows (sorted) in `rows[row_ptr[s]..row_ptr[s + 1]]`
    row_ptr: Vec<usize>,
    rows: Vec<usize>,
    /// each supernode's values (column-major, `cols + pattern` rows) in `val_ptr[s]..val_ptr[s + 1]`
    val_ptr: Vec<usize>,
    /// children of each supernode (ascending) and the roots
    children: Vec<Vec<usize>>,
    roots: Vec<usize>,
    /// factor entries in each supernode's subtree
    work: Vec<usize>,
}

impl SupernodeTree {
    /// The tree of `symbolic`, `None` when a child's pattern leaves its parent's columns and
    /// pattern (the solves then fall back to faer's).
    pub(crate) fn new(symbolic: &SymbolicSupernodalCholesky<usize>) -> Option<Self> {
        let ns = symbolic.n_supernodes();
        let mut begin = symbolic.supernode_begin().to_vec();
        begin.push(symbolic.nrows());
        let rp = symbolic.col_ptr_for_row_idx();
        let counts = symbolic.nnz_per_super();
        let mut row_ptr = vec![0usize; ns + 1];
        let mut rows = Vec::new();
        for s in 0..ns {
            let pat = &symbolic.row_idx()[rp[s]..rp[s] + counts[s]];
            if pat.windows(2).any(|w| w[0] >= w[1]) || pat.first().is_some_and(|&r| r < begin[s + 1]) {
                return None;
            }
            rows.extend_from_slice(pat);
            row_ptr[s + 1] = rows.len();
        }
        let val_ptr = symbolic.col_ptr_for_val()[..=ns].to_vec();
        let mut owner = vec![0usize; symbolic.nrows()];
        for s in 0..ns {
            owner[begin[s]..begin[s + 1]].fill(s);
        }
        let mut children = vec![Vec::new(); ns];
        let mut roots = Vec::new();
        for s in 0..ns {
            match rows[row_ptr[s]..row_ptr[s + 1]].first() {
                Some(&r) => children[owner[r]].push(s),
                None => roots.push(s),
            }
        }
        let mut work = vec![0usize; ns];
        for s in 0..ns {
            work[s] += val_ptr[s + 1] - val_ptr[s];
            let parent_rows = &rows[row_ptr[s]..row_ptr[s + 1]];
            if let Some(&r) = parent_rows.first() {
                let p = owner[r];
                // containment: pattern(s) within cols(p) ∪ pattern(p)
                let ppat = &rows[row_ptr[p]..row_ptr[p + 1]];
                let mut k = 0;
                for &r in parent_rows.iter().filter(|&&r| r >= begin[p + 1]) {
                    while k < ppat.len() && ppat[k] < r {
                        k += 1;
                    }
                    if k == ppat.len() || ppat[k] != r {
                        return None;
                    }
                }
                work[p] += work[s];
            }
        }
        Some(Self {
            begin,
            row_ptr,
            rows,
            val_ptr,
            children,
            roots,
            work,
        })
    }

    fn cols(&self, s: usize) -> std::ops::Range<usize> {
        self.begin[s]..self.begin[s + 1]
    }

    fn pattern(&self, s: usize) -> &[usize] {
        &self.rows[self.row_ptr[s]..self.row_ptr[s + 1]]
    }

    /// `(L_ss, L_bot)` of supernode `s`.
    fn blocks<'a>(&self, values: &'a [f64], s: usize) -> (MatRef<'a, f64>, MatRef<'a, f64>) {
        let m = self.begin[s + 1] - self.begin[s];
        let all = MatRef::from_column_major_slice(
            &values[self.val_ptr[s]..self.val_ptr[s + 1]],
            m + self.pattern(s).len(),
            m,
        );
        all.split_at_row(m)
    }

    /// Solves `L L^T x = b` in place (`x` in the factor's own, permuted, ordering).
    pub(crate) fn solve(&self, values: &[f64], x: &mut [f64]) {
        let shared = Shared(x.as_mut_ptr(), x.len());
        let shared = &shared;
        let go = |roots: &[usize], f: &(dyn Fn(usize) + Sync)| {
            if self.parallel(roots) {
                roots.par_iter().for_each(|&r| f(r));
            } else {
                roots.iter().for_each(|&r| f(r));
            }
        };
        go(&self.roots, &|r| {
            // a root's update vector is empty (its pattern is)
            self.forward(values, shared, r);
        });
        go(&self.roots, &|r| self.backward(values, shared, r));
    }

    /// Whether some supernode's children (or the roots) are solved in parallel.
    #[cfg(test)]
    pub(crate) fn splits(&self) -> bool {
        self.parallel(&self.roots) || self.children.iter().any(|k| self.parallel(k))
    }

    /// Whether `nodes` are run in parallel: two of them at least [`PAR_WORK`] each.
    fn parallel(&self, nodes: &[usize]) -> bool {
        nodes.iter().filter(|&&c| self.work[c] >= PAR_WORK).count() >= 2
    }

    /// The forward solve of the subtree of `s`; returns `u_s` (module docs). One loop over the
    /// subtree's supernodes in ascending order (children before parents); the subtrees below a
    /// supernode whose children run in parallel are solved by calls of their own, so the
    /// recursion is only as deep as the parallel splits on a path (each takes >= [`PAR_WORK`]
    /// entries), never as deep as the tree (a long chain of supernodes).
    fn forward(&self, values: &[f64], x: &Shared, s: usize) -> Vec<f64> {
        let mut pending: std::collections::HashMap<usize, Vec<f64>> = Default::default();
        for t in self.local(s) {
            let kids = &self.children[t];
            if self.parallel(kids) {
                let updates: Vec<Vec<f64>> = kids.par_iter().map(|&c| self.forward(values, x, c)).collect();
                pending.extend(kids.iter().copied().zip(updates));
            }
            let mine = kids.iter().map(|&c| {
                (
                    c,
                    pending.remove(&c).expect("a child is solved before its parent"),
                )
            });
            let u = self.forward_node(values, x, t, mine);
            pending.insert(t, u);
        }
        pending.remove(&s).expect("the subtree's root is solved last")
    }

    /// The supernodes of the subtree of `s` down to (not below) the supernodes whose children
    /// run in parallel, ascending.
    fn local(&self, s: usize) -> Vec<usize> {
        let mut out = vec![s];
        let mut k = 0;
        while k < out.len() {
            let kids = &self.children[out[k]];
            if !self.parallel(kids) {
                out.extend_from_slice(kids);
            }
            k += 1;
        }
        out.sort_unstable();
        out
    }

    /// One supernode's forward step (module docs), given its children's update vectors in
    /// ascending order of the child.
    fn forward_node(
        &self,
        values: &[f64],
        x: &Shared,
        s: usize,
        updates: impl Iterator<Item = (usize, Vec<f64>)>,
    ) -> Vec<f64> {
        let cols = self.cols(s);
        let pat = self.pattern(s);
        // SAFETY: supernode `s` is the only one that reads or writes its own columns during the
        // forward pass (each runs once; every other supernode writes only its own columns).
        let xs = unsafe { x.range(cols.clone()) };
        let mut acc = vec![0.0f64; pat.len()];
        for (c, u) in updates {
            let mut k = 0;
            for (&r, &v) in self.pattern(c).iter().zip(&u) {
                if r < cols.end {
                    xs[r - cols.start] -= v;
                } else {
                    while pat[k] < r {
                        k += 1;
                    }
                    acc[k] += v;
                }
            }
        }
        let (top, bot) = self.blocks(values, s);
        let m = cols.len();
        solve_lower_triangular_in_place(top, MatMut::from_column_major_slice_mut(xs, m, 1), Par::Seq);
        matmul(
            MatMut::from_column_major_slice_mut(&mut acc, pat.len(), 1),
            Accum::Add,
            bot,
            MatRef::from_column_major_slice(xs, m, 1),
            1.0,
            Par::Seq,
        );
        acc
    }

    /// The backward solve of the subtree of `s`: [`SupernodeTree::local`] in descending order
    /// (parents before children), the children of a parallel split in calls of their own.
    fn backward(&self, values: &[f64], x: &Shared, s: usize) {
        for t in self.local(s).into_iter().rev() {
            self.backward_node(values, x, t);
            let kids = &self.children[t];
            if self.parallel(kids) {
                kids.par_iter().for_each(|&c| self.backward(values, x, c));
            }
        }
    }

    /// One supernode's backward step (module docs).
    fn backward_node(&self, values: &[f64], x: &Shared, s: usize) {
        let cols = self.cols(s);
        let pat = self.pattern(s);
        // SAFETY: the rows of `pattern(s)` belong to ancestors of `s`, finished before `s` starts
        // and not written again; no other supernode reads or writes `cols(s)` meanwhile.
        let tmp: Vec<f64> = pat.iter().map(|&r| unsafe { x.get(r) }).collect();
        // SAFETY: as above, `cols(s)` is this supernode's alone during its step.
        let xs = unsafe { x.range(cols.clone()) };
        let (top, bot) = self.blocks(values, s);
        let m = cols.len();
        matmul(
            MatMut::from_column_major_slice_mut(xs, m, 1),
            Accum::Add,
            bot.transpose(),
            MatRef::from_column_major_slice(&tmp, pat.len(), 1),
            -1.0,
            Par::Seq,
        );
        solve_upper_triangular_in_place(
            top.transpose(),
            MatMut::from_column_major_slice_mut(xs, m, 1),
            Par::Seq,
        );
    }
}

/// The right-hand side shared by the tree's tasks, each of which touches only the entries the
/// module docs give it.
struct Shared(*mut f64, usize);

// SAFETY: the tasks access disjoint entries, or entries no task writes at the time (the callers'
// SAFETY notes); the pointer outlives them (`SupernodeTree::solve` borrows the slice mutably for
// the whole solve).
unsafe impl Sync for Shared {}

impl Shared {
    /// # Safety
    /// No other task accesses `range` while the returned slice lives.
    #[allow(clippy::mut_from_ref)]
    unsafe fn range(&self, range: std::ops::Range<usize>) -> &mut [f64] {
        assert!(range.start <= range.end && range.end <= self.1);
        // SAFETY: in bounds (asserted); exclusive by the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.0.add(range.start), range.len()) }
    }

    /// # Safety
    /// No task writes entry `i` at the time.
    unsafe fn get(&self, i: usize) -> f64 {
        assert!(i < self.1);
        // SAFETY: in bounds (asserted); not written concurrently by the caller's contract.
        unsafe { *self.0.add(i) }
    }
}
