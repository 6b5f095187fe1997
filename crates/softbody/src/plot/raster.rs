//! Rasterizing onto [`Image`]: the plot rectangle, anti-aliased lines, dashes and discs
//! (coverage layers clipped to the plot).

use super::Pt;
use cutfem::render::Image;

/// The plot interior `[x0, x1) x [y0, y1)` in pixels, and the text scale `s`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Plot {
    pub(super) x0: usize,
    pub(super) y0: usize,
    pub(super) x1: usize,
    pub(super) y1: usize,
    pub(super) s: usize,
}

impl Plot {
    pub(super) fn px(&self, t: f64) -> f64 {
        self.x0 as f64 + t * (self.x1 - self.x0) as f64
    }
    pub(super) fn py(&self, t: f64) -> f64 {
        self.y1 as f64 - t * (self.y1 - self.y0) as f64
    }
    pub(super) fn row(&self, t: f64) -> usize {
        (self.py(t).floor().max(0.0) as usize).clamp(self.y0, self.y1 - 1)
    }
    pub(super) fn col(&self, t: f64) -> usize {
        (self.px(t).floor().max(0.0) as usize).clamp(self.x0, self.x1 - 1)
    }
}

pub(super) fn tw(text: &str, scale: usize) -> usize {
    Image::text_size(text, scale).0
}

/// Coverage (0..1) of one colour over the plot interior, composited once so that a polyline
/// overlapping itself doesn't darken.
#[derive(Debug)]
pub struct Layer {
    p: Plot,
    cov: Vec<f32>,
    /// what was drawn, for vector output ([`super::canvas::SvgCanvas`])
    ops: Vec<Op>,
}

/// One drawing operation of a [`Layer`].
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Op {
    /// a disc: centre, radius
    Disc(Pt, f64),
    /// a polyline: points, half-width, dash `(on, off)`
    Poly(Vec<Pt>, f64, Option<(f64, f64)>),
}

impl Layer {
    pub(super) fn new(p: &Plot) -> Layer {
        Layer {
            p: *p,
            cov: vec![0.0; (p.x1 - p.x0) * (p.y1 - p.y0)],
            ops: Vec::new(),
        }
    }

    /// Stamps coverage `f(pixel centre)` over the box `[xa, xb] x [ya, yb]` (clipped).
    fn stamp(&mut self, (xa, xb, ya, yb): (f64, f64, f64, f64), f: impl Fn(f64, f64) -> f64) {
        let p = self.p;
        let span = |a: f64, b: f64, lo, hi| {
            (a.floor().max(lo as f64) as usize)..(b.ceil().max(0.0) as usize).min(hi)
        };
        for y in span(ya, yb, p.y0, p.y1) {
            for x in span(xa, xb, p.x0, p.x1) {
                let c = f(x as f64 + 0.5, y as f64 + 0.5).clamp(0.0, 1.0) as f32;
                let i = (x - p.x0) + (p.x1 - p.x0) * (y - p.y0);
                self.cov[i] = self.cov[i].max(c);
            }
        }
    }

    pub(super) fn disc(&mut self, (cx, cy): Pt, r: f64) {
        self.ops.push(Op::Disc((cx, cy), r));
        let d = r + 1.0;
        self.stamp((cx - d, cx + d, cy - d, cy + d), |x, y| {
            r + 0.5 - (x - cx).hypot(y - cy)
        });
    }

    /// Segment `ab` clipped (Liang-Barsky) to a margin `m` around the plot.
    fn clip(&self, a: Pt, b: Pt, m: f64) -> Option<(Pt, Pt)> {
        let (p, dx, dy) = (self.p, b.0 - a.0, b.1 - a.1);
        let (x0, y0, x1, y1) = (p.x0 as f64 - m, p.y0 as f64 - m, p.x1 as f64 + m, p.y1 as f64 + m);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (d, q) in [(-dx, a.0 - x0), (dx, x1 - a.0), (-dy, a.1 - y0), (dy, y1 - a.1)] {
            match () {
                _ if d == 0.0 && q < 0.0 => return None,
                _ if d < 0.0 => t0 = t0.max(q / d),
                _ if d > 0.0 => t1 = t1.min(q / d),
                _ => {}
            }
        }
        (t0 <= t1).then_some(((a.0 + t0 * dx, a.1 + t0 * dy), (a.0 + t1 * dx, a.1 + t1 * dy)))
    }

    /// A segment `hw` pixels either side of its axis.
    pub(super) fn segment(&mut self, a: Pt, b: Pt, hw: f64) {
        let m = hw + 2.0;
        let Some((a, b)) = self.clip(a, b, m) else { return };
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let l2 = (dx * dx + dy * dy).max(1e-300);
        let (xa, xb, ya, yb) = (a.0.min(b.0), a.0.max(b.0), a.1.min(b.1), a.1.max(b.1));
        self.stamp((xa - m, xb + m, ya - m, yb + m), |x, y| {
            let t = (((x - a.0) * dx + (y - a.1) * dy) / l2).clamp(0.0, 1.0);
            hw + 0.5 - (x - a.0 - t * dx).hypot(y - a.1 - t * dy)
        });
    }

    /// A polyline, dashed `(on, off)` pixels when `dash` is given.
    pub(super) fn polyline(&mut self, pts: &[Pt], hw: f64, dash: Option<(f64, f64)>) {
        self.ops.push(Op::Poly(pts.to_vec(), hw, dash));
        let mut pos = 0.0;
        for w in pts.windows(2) {
            let (Some((on, off)), Some((a, b))) = (dash, self.clip(w[0], w[1], hw + 2.0)) else {
                self.segment(w[0], w[1], hw);
                continue;
            };
            let len = (b.0 - a.0).hypot(b.1 - a.1);
            let at = |t: f64| (a.0 + (b.0 - a.0) * t / len, a.1 + (b.1 - a.1) * t / len);
            let mut t = 0.0;
            while t < len {
                let ph = pos % (on + off);
                let t2 = (t + if ph < on { on - ph } else { on + off - ph }).min(len);
                if ph < on {
                    self.segment(at(t), at(t2), hw);
                }
                (pos, t) = (pos + t2 - t, t2);
            }
        }
    }

    /// The operations drawn so far, in order.
    pub(super) fn ops(&self) -> &[Op] {
        &self.ops
    }

    /// Whether `q` lies in the plot.
    pub(super) fn contains(&self, q: Pt) -> bool {
        let p = self.p;
        (p.x0 as f64..=p.x1 as f64).contains(&q.0) && (p.y0 as f64..=p.y1 as f64).contains(&q.1)
    }

    /// The parts of the polyline `pts` inside the plot, as polylines.
    pub(super) fn clipped_runs(&self, pts: &[Pt]) -> Vec<Vec<Pt>> {
        let mut runs: Vec<Vec<Pt>> = Vec::new();
        let mut open = false;
        for w in pts.windows(2) {
            let Some((a, b)) = self.clip(w[0], w[1], 0.0) else {
                open = false;
                continue;
            };
            match runs.last_mut() {
                Some(run) if open && run.last() == Some(&a) => run.push(b),
                _ => runs.push(vec![a, b]),
            }
            // the run goes on when the segment left the plot at its own end point
            open = b == w[1];
        }
        runs
    }

    pub(super) fn composite(&self, img: &mut Image, color: [u8; 3]) {
        let pw = self.p.x1 - self.p.x0;
        for (i, &c) in self.cov.iter().enumerate() {
            let (x, y) = (self.p.x0 + i % pw, self.p.y0 + i / pw);
            if c > 0.0 && x < img.width && y < img.height {
                let old = img.pixel(x, y);
                let mix = |k: usize| (old[k] as f32 + c * (color[k] as f32 - old[k] as f32)).round() as u8;
                img.set_pixel(x, y, [mix(0), mix(1), mix(2)]);
            }
        }
    }
}
