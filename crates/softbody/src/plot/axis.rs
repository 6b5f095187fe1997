//! Axis ranges, tick choice (1-2-5 steps, decades on log axes) and compact tick labels.

/// Mapped positions are clamped to this many axis lengths (keeps far-off points finite).
const FAR: f64 = 1e4;

/// One axis: the range `lo..hi` (log or linear), labelled `ticks` `(value, label)` and
/// unlabelled `minor` ticks.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    pub lo: f64,
    pub hi: f64,
    pub log: bool,
    pub ticks: Vec<(f64, String)>,
    pub minor: Vec<f64>,
}

/// The 1-2-5 step (times a power of ten) giving at most about `max_ticks` intervals over
/// `span`; NaN when `span` is not positive and finite.
pub fn nice_step(span: f64, max_ticks: usize) -> f64 {
    let raw = span / max_ticks.max(1) as f64;
    if !(raw.is_finite() && raw > 0.0) {
        return f64::NAN;
    }
    let mag = 10f64.powf(raw.log10().floor());
    let steps = [1.0, 2.0, 5.0, 10.0].map(|m| m * mag);
    steps
        .into_iter()
        .find(|&s| s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * mag)
}

/// The multiples of [`nice_step`] in `[lo, hi]` (empty for a degenerate range).
pub fn linear_ticks(lo: f64, hi: f64, max_ticks: usize) -> Vec<f64> {
    let step = nice_step(hi - lo, max_ticks);
    let (a, b) = ((lo / step - 1e-9).ceil(), (hi / step + 1e-9).floor());
    if !(a.is_finite() && b.is_finite()) || b - a > 1000.0 {
        return Vec::new();
    }
    let snap = |v: f64| if v.abs() < 1e-9 * step { 0.0 } else { v };
    (a as i64..=b as i64).map(|i| snap(i as f64 * step)).collect()
}

/// Ticks of a log axis over `[lo, hi]` (`0 < lo < hi`): `(labelled, minor)`. Spanning two or
/// more decades, the labelled ticks are powers of ten (every k-th decade when there would be
/// more than `max_ticks`); within a narrower range 1-2-5 or 1..9 multiples are labelled.
pub fn log_ticks(lo: f64, hi: f64, max_ticks: usize) -> (Vec<f64>, Vec<f64>) {
    let (a, b, max) = (lo.log10(), hi.log10(), max_ticks.max(2));
    if !(a.is_finite() && b.is_finite() && a < b) {
        return (Vec::new(), Vec::new());
    }
    let inside = |v: &f64| v.log10() >= a - 1e-9 && v.log10() <= b + 1e-9;
    let multiples = |ms: &[f64]| -> Vec<f64> {
        let e = a.floor() as i32..=b.ceil() as i32;
        e.flat_map(|e| ms.iter().map(move |m| m * 10f64.powi(e)))
            .filter(inside)
            .collect()
    };
    let decades = multiples(&[1.0]);
    let all = multiples(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    let (labelled, minor) = if decades.len() >= 2 {
        let every = [1, 2, 3, 5, 10, 20, 50, 100]
            .into_iter()
            .find(|k| decades.len().div_ceil(*k) <= max);
        let every = every.unwrap_or(200) as i64;
        let lab = |v: &f64| (v.log10().round() as i64).rem_euclid(every) == 0;
        let minor = if every == 1 && decades.len() <= 8 {
            all
        } else {
            decades.clone()
        };
        (decades.into_iter().filter(lab).collect(), minor)
    } else {
        let choices = [multiples(&[1.0, 2.0, 5.0]), all.clone()];
        let labelled = choices.into_iter().find(|t| t.len() >= 2 && t.len() <= max + 1);
        (labelled.unwrap_or_else(|| linear_ticks(lo, hi, max_ticks)), all)
    };
    let minor = minor.into_iter().filter(|v| !labelled.contains(v)).collect();
    (labelled, minor)
}

/// A compact label with about 3 significant digits: `0`, `0.5`, `2000`, `12345`, `1e-3`,
/// `1.5e5`, `-0.25`.
pub fn fmt_compact(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() {
        format!("{}", if v == 0.0 { 0.0 } else { v })
    } else if !(1e-2..1e5).contains(&a) {
        fmt_sci(v, 2)
    } else {
        trim(format!(
            "{v:.*}",
            (2 - a.log10().floor() as i32).clamp(0, 4) as usize
        ))
    }
}

/// Drops trailing zeros (and a trailing point) of a decimal number.
fn trim(s: String) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').into()
    } else {
        s
    }
}

/// `v` as `1.5e-3` with at most `digits` decimals (trailing zeros dropped).
fn fmt_sci(v: f64, digits: usize) -> String {
    let s = format!("{v:.digits$e}");
    let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
    format!("{}e{e}", trim(m.into()))
}

impl Axis {
    /// An axis over `lo..hi` (`lo < hi`, positive for log) with about `max_ticks` labels.
    pub fn new(lo: f64, hi: f64, log: bool, max_ticks: usize) -> Axis {
        if log {
            let (t, minor) = log_ticks(lo, hi, max_ticks);
            let ticks = t.into_iter().map(|v| (v, fmt_compact(v))).collect();
            return Axis {
                lo,
                hi,
                log,
                ticks,
                minor,
            };
        }
        let e_step = nice_step(hi - lo, max_ticks).log10().floor();
        let sci = !(1e-2..1e5).contains(&lo.abs().max(hi.abs()));
        let label = |v: f64| match () {
            _ if v == 0.0 => "0".to_string(),
            _ if sci => fmt_sci(v, (v.abs().log10().floor() - e_step).clamp(0.0, 6.0) as usize),
            _ => format!("{v:.*}", (-e_step).clamp(0.0, 10.0) as usize),
        };
        let ticks = linear_ticks(lo, hi, max_ticks)
            .into_iter()
            .map(|v| (v, label(v)))
            .collect();
        Axis {
            lo,
            hi,
            log,
            ticks,
            minor: Vec::new(),
        }
    }

    /// Position of `v` along the axis (0 at `lo`, 1 at `hi`); `None` where it can't be drawn.
    pub fn frac(&self, v: f64) -> Option<f64> {
        let f = |x: f64| if self.log { x.log10() } else { x };
        let t = (f(v) - f(self.lo)) / (f(self.hi) - f(self.lo));
        (v.is_finite() && (!self.log || v > 0.0) && t.is_finite()).then(|| t.clamp(-FAR, FAR))
    }
}

/// The range of the finite `values` padded by `frac` of its span on both sides (in log space
/// when `log`; not below 0 when it starts at 0 and `frac` is large, as for bars); a single
/// value gets a range around it, none `[0, 1]` (`[1, 10]` for log).
pub(super) fn padded(values: impl Iterator<Item = f64>, log: bool, frac: f64) -> (f64, f64) {
    let f = |v: f64| if log { v.log10() } else { v };
    let ok = values.filter(|&v| v.is_finite() && (!log || v > 0.0)).map(f);
    let (lo, hi) = ok.fold((f64::INFINITY, f64::NEG_INFINITY), |r, v| {
        (r.0.min(v), r.1.max(v))
    });
    let d = if lo == hi {
        lo.abs().max(1e-300) * 0.1
    } else {
        frac * (hi - lo)
    };
    let (lo, hi) = match () {
        _ if lo > hi => (0.0, 1.0),
        _ if lo == hi && log => (lo - 0.5, hi + 0.5),
        _ if lo == 0.0 && frac > 0.05 => (0.0, hi + d),
        _ if d.is_finite() => (lo - d, hi + d),
        _ => (lo / 2.0, hi / 2.0),
    };
    let g = |v: f64| {
        if log {
            10f64.powf(v.clamp(-300.0, 300.0))
        } else {
            v
        }
    };
    (g(lo), g(hi))
}
