//! Line and bar charts for report pictures, drawn onto [`Image`] with its anti-aliased text (DejaVu Sans).
//!
//! [`Chart`] draws series of `(x, y)` points (lines, markers, dashes) with 1-2-5 ticks or
//! decade ticks on log axes, dashed reference lines, a legend, a title and axis labels;
//! [`BarChart`] draws one bar per category. Non-finite values (and non-positive ones on a log
//! axis) are skipped and break lines. Output is deterministic. Images are 640 x 400 by default.
//! Every chart renders as a raster [`Image`] (`render`, saved as PNG) and as SVG
//! (`render_svg`, the same picture as vector elements, [`canvas`]).

pub mod axis;
mod canvas;
mod raster;
#[cfg(test)]
mod svg_tests;
#[cfg(test)]
mod tests;

pub use axis::Axis;
use axis::{fmt_compact, padded};
pub use canvas::{Canvas, SvgCanvas};
pub use canvas::{Picture, Svg};
use cutfem::render::{Image, GLYPH_HEIGHT};
use raster::{tw, Layer, Plot};

const WHITE: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [25, 25, 25];
const FRAME: [u8; 3] = [80, 80, 80];
const GRID: [u8; 3] = [222, 222, 222];
const GRID_MINOR: [u8; 3] = [242, 242, 242];

type Pt = (f64, f64);
/// A legend entry: label, colour, style.
type Entry<'a> = (&'a str, [u8; 3], Style);

/// How a [`Series`] is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Style {
    /// a 2-pixel anti-aliased polyline
    #[default]
    Line,
    /// a disc at every point
    Markers,
    /// a polyline with discs (thinned where the points are dense)
    LineMarkers,
    /// a dashed polyline
    Dashed,
}

/// One data series of a [`Chart`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// legend text (an empty label keeps the series out of the legend)
    pub label: String,
    /// the points, drawn in this order
    pub points: Vec<(f64, f64)>,
    /// colour, e.g. from [`palette`]
    pub color: [u8; 3],
    /// how it is drawn
    pub style: Style,
}

impl Series {
    /// A [`Style::Line`] series.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, color: [u8; 3]) -> Self {
        let label = label.into();
        Series {
            label,
            points,
            color,
            ..Series::default()
        }
    }

    /// The same series drawn in `style`.
    pub fn with_style(self, style: Style) -> Self {
        Series { style, ..self }
    }
}

/// A line chart; see [`Chart::render`].
#[derive(Clone, Debug, PartialEq)]
pub struct Chart {
    /// title above the plot (empty: none)
    pub title: String,
    /// label under the x axis (empty: none)
    pub x_label: String,
    /// label left of the y axis, written bottom to top (empty: none)
    pub y_label: String,
    /// logarithmic x axis
    pub log_x: bool,
    /// logarithmic y axis
    pub log_y: bool,
    /// the data
    pub series: Vec<Series>,
    /// dashed horizontal reference lines `(y, legend label, colour)`, e.g. truth or noise floor
    pub hlines: Vec<(f64, String, [u8; 3])>,
    /// fixed x range (default: the data's, padded)
    pub x_range: Option<(f64, f64)>,
    /// fixed y range (default: the data's and the reference lines', padded)
    pub y_range: Option<(f64, f64)>,
    /// image width in pixels
    pub width: usize,
    /// image height in pixels
    pub height: usize,
}

/// A categorical bar chart; see [`BarChart::render`].
#[derive(Clone, Debug, PartialEq)]
pub struct BarChart {
    /// title above the plot (empty: none)
    pub title: String,
    /// label left of the y axis (empty: none)
    pub y_label: String,
    /// `(category, value, colour)`, left to right; non-finite values show "n/a"
    pub bars: Vec<(String, f64, [u8; 3])>,
    /// logarithmic y axis (bars rise from the bottom; non-positive values show "n/a")
    pub log_y: bool,
    /// dashed horizontal reference lines `(y, legend label, colour)`
    pub hlines: Vec<(f64, String, [u8; 3])>,
    /// image width in pixels
    pub width: usize,
    /// image height in pixels
    pub height: usize,
}

impl Default for Chart {
    fn default() -> Self {
        Chart {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            log_x: false,
            log_y: false,
            series: Vec::new(),
            hlines: Vec::new(),
            x_range: None,
            y_range: None,
            width: 640,
            height: 400,
        }
    }
}

impl Default for BarChart {
    fn default() -> Self {
        BarChart {
            title: String::new(),
            y_label: String::new(),
            bars: Vec::new(),
            log_y: false,
            hlines: Vec::new(),
            width: 640,
            height: 400,
        }
    }
}

/// Ten distinguishable colours (Tableau 10), repeating.
pub fn palette(i: usize) -> [u8; 3] {
    const P: [u32; 10] = [
        0x1f77b4, 0xff7f0e, 0x2ca02c, 0xd62728, 0x9467bd, 0x8c564b, 0xe377c2, 0x7f7f7f, 0xbcbd22, 0x17becf,
    ];
    let c = P[i % P.len()];
    [(c >> 16) as u8, (c >> 8) as u8, c as u8]
}

/// `images` on a white background, `columns` per row (at least 1), in equal cells as large as
/// the largest image, images centred, 8 pixels apart. An empty list gives a 0 x 0 image.
pub fn grid_of(images: Vec<Image>, columns: usize) -> Image {
    let sizes: Vec<(usize, usize)> = images.iter().map(|i| (i.width, i.height)).collect();
    let (w, h, at) = grid_cells(&sizes, columns);
    let mut out = Image::new(w, h, WHITE);
    for (img, (x, y)) in images.iter().zip(at) {
        out.blit(img, x, y);
    }
    out
}

/// `parts` one under the other, centred, on white.
pub fn stack(parts: &[&Image]) -> Image {
    let sizes: Vec<(usize, usize)> = parts.iter().map(|i| (i.width, i.height)).collect();
    let (w, h, at) = stack_cells(&sizes);
    let mut out = Image::new(w, h, WHITE);
    for (p, (x, y)) in parts.iter().zip(at) {
        out.blit(p, x, y);
    }
    out
}

/// The size of pictures of `sizes` one under the other, centred, and each one's top-left corner.
fn stack_cells(sizes: &[(usize, usize)]) -> (usize, usize, Vec<(usize, usize)>) {
    let w = sizes.iter().map(|s| s.0).max().unwrap_or(0);
    let mut y = 0;
    let at = sizes
        .iter()
        .map(|&(pw, ph)| {
            let corner = ((w - pw) / 2, y);
            y += ph;
            corner
        })
        .collect();
    (w, y, at)
}

/// The size of a grid of pictures of `sizes`, `columns` per row (at least 1), in equal cells
/// as large as the largest, 8 pixels apart, and each picture's top-left corner (centred in
/// its cell). No pictures: 0 x 0.
fn grid_cells(sizes: &[(usize, usize)], columns: usize) -> (usize, usize, Vec<(usize, usize)>) {
    const GAP: usize = 8;
    if sizes.is_empty() {
        return (0, 0, Vec::new());
    }
    let cols = columns.clamp(1, sizes.len());
    let rows = sizes.len().div_ceil(cols);
    let cw = sizes.iter().map(|s| s.0).max().unwrap_or(0);
    let ch = sizes.iter().map(|s| s.1).max().unwrap_or(0);
    let at = sizes
        .iter()
        .enumerate()
        .map(|(n, &(w, h))| {
            let (x, y) = (GAP + (n % cols) * (cw + GAP), GAP + (n / cols) * (ch + GAP));
            (x + (cw - w) / 2, y + (ch - h) / 2)
        })
        .collect();
    (GAP + cols * (cw + GAP), GAP + rows * (ch + GAP), at)
}

/// The text scale for an image of `w` x `h` pixels: 1 per 320 x 200, from 1 to 4.
fn scale_for(w: usize, h: usize) -> usize {
    (w / 320).min(h / 200).clamp(1, 4)
}

/// Line half-width, marker radius and dash pattern (on, off) in pixels at text scale `s`.
fn pens(s: usize) -> (f64, f64, (f64, f64)) {
    let k = s.max(2) as f64 / 2.0;
    (k, 1.5 + s as f64, (9.0 * k, 6.0 * k))
}

/// Plot rectangle and `[y, x]` axes for an image of `w` x `h`, with `bottom` pixels under the
/// plot for tick or category labels; `labels`: which of title, x label, y label are present.
fn layout(
    w: usize,
    h: usize,
    labels: [bool; 3],
    bottom: usize,
    r: [(f64, f64, bool); 2],
) -> (Plot, [Axis; 2]) {
    let s = scale_for(w, h);
    let [title, xlab, ylab] = labels.map(usize::from);
    let (ch, pad, gap, tick) = (GLYPH_HEIGHT * s, 4 * s, 3 * s, 2 * s + 1);
    let y0 = pad + title * (ch + 3 * gap) + (1 - title) * ch / 2;
    let y1 = h
        .saturating_sub(tick + gap + bottom + xlab * (2 * gap + ch) + pad)
        .max(y0 + 1);
    let [(ylo, yhi, ylog), (xlo, xhi, xlog)] = r;
    let ya = Axis::new(ylo, yhi, ylog, ((y1 - y0) / (5 * ch / 2 + 8)).clamp(2, 10));
    let wy = ya.ticks.iter().map(|t| tw(&t.1, s)).max().unwrap_or(0);
    let x0 = pad + ylab * (ch + 2 * gap) + wy + gap + tick;
    let x1 = w.saturating_sub(pad + 6 * s).max(x0 + 1);
    let width = |a: &Axis| a.ticks.iter().map(|t| tw(&t.1, s) + 4 * ch).max().unwrap_or(0);
    let mut xa = (2..=10).rev().map(|n| Axis::new(xlo, xhi, xlog, n));
    let xa = xa.find(|a| a.ticks.len() * width(a) <= x1 - x0);
    let xa = xa.unwrap_or_else(|| Axis::new(xlo, xhi, xlog, 2));
    (Plot { x0, y0, x1, y1, s }, [ya, xa])
}

/// Grid lines, frame, ticks and tick labels.
fn draw_axes(img: &mut impl Canvas, p: &Plot, ya: &Axis, xa: Option<&Axis>) {
    let (pw, ph, tick, gap, s) = (p.x1 - p.x0, p.y1 - p.y0, 2 * p.s + 1, 3 * p.s, p.s);
    let lines = |a: &Axis| {
        let minor = a.minor.iter().map(|&v| (v, GRID_MINOR));
        let all = minor.chain(a.ticks.iter().map(|t| (t.0, GRID)));
        all.filter_map(|(v, c)| Some((a.frac(v)?, c))).collect::<Vec<_>>()
    };
    for (t, c) in lines(ya) {
        img.fill_rect(p.x0, p.row(t), pw, 1, c);
    }
    for (t, c) in xa.into_iter().flat_map(lines) {
        img.fill_rect(p.col(t), p.y0, 1, ph, c);
    }
    img.fill_rect(p.x0 - 1, p.y0 - 1, pw + 2, 1, FRAME);
    img.fill_rect(p.x0 - 1, p.y1, pw + 2, 1, FRAME);
    img.fill_rect(p.x0 - 1, p.y0 - 1, 1, ph + 2, FRAME);
    img.fill_rect(p.x1, p.y0 - 1, 1, ph + 2, FRAME);
    for (y, label) in ya
        .ticks
        .iter()
        .filter_map(|(v, l)| Some((p.row(ya.frac(*v)?), l)))
    {
        img.fill_rect(p.x0 - 1 - tick, y, tick, 1, FRAME);
        let x = (p.x0 - 1 - tick - gap).saturating_sub(tw(label, s));
        img.draw_text(x, y.saturating_sub(GLYPH_HEIGHT * s / 2), label, INK, s);
    }
    let xt = xa
        .into_iter()
        .flat_map(|a| a.ticks.iter().filter_map(|(v, l)| Some((p.col(a.frac(*v)?), l))));
    for (x, label) in xt {
        img.fill_rect(x, p.y1 + 1, 1, tick, FRAME);
        let x = x
            .saturating_sub(tw(label, s) / 2)
            .min(img.image().width.saturating_sub(tw(label, s) + 1));
        img.draw_text(x, p.y1 + 1 + tick + gap, label, INK, s);
    }
}

/// Title centred on the image, x label under the plot, y label (rotated) left of it.
fn draw_titles(img: &mut impl Canvas, p: &Plot, title: &str, x_label: &str, y_label: &str) {
    let (s, pad) = (p.s, 4 * p.s);
    let ts = if s >= 2 && tw(title, s + 1) + 2 * pad <= img.image().width {
        s + 1
    } else {
        s
    };
    img.draw_text(
        img.image().width.saturating_sub(tw(title, ts)) / 2,
        pad,
        title,
        INK,
        ts,
    );
    let (xc, yc) = ((p.x0 + p.x1) / 2, (p.y0 + p.y1) / 2);
    let bottom = img.image().height.saturating_sub(pad + GLYPH_HEIGHT * s);
    img.draw_text(xc.saturating_sub(tw(x_label, s) / 2), bottom, x_label, INK, s);
    img.draw_text_up(pad, yc.saturating_sub(tw(y_label, s) / 2), y_label, INK, s);
}

/// Dashed horizontal reference lines; returns their legend entries.
fn hlines<'a>(
    img: &mut impl Canvas,
    p: &Plot,
    ya: &Axis,
    lines: &'a [(f64, String, [u8; 3])],
) -> Vec<Entry<'a>> {
    for (y, color) in lines.iter().filter_map(|l| Some((p.py(ya.frac(l.0)?), l.2))) {
        let mut layer = Layer::new(p);
        let (hw, _, dash) = pens(p.s);
        layer.polyline(&[(p.x0 as f64, y), (p.x1 as f64, y)], 0.75 * hw, Some(dash));
        img.composite(&layer, color);
    }
    lines.iter().map(|h| (h.1.as_str(), h.2, Style::Dashed)).collect()
}

/// Draws mapped points (`None` breaks the line).
fn draw_series(img: &mut impl Canvas, p: &Plot, pts: &[Option<Pt>], color: [u8; 3], style: Style) {
    let (hw, r, dash) = pens(p.s);
    let mut layer = Layer::new(p);
    for run in pts.split(|q| q.is_none()) {
        let run: Vec<Pt> = run.iter().flatten().copied().collect();
        match (style, run.len()) {
            (Style::Markers, _) | (_, 0) => {}
            (_, 1) => layer.disc(run[0], r),
            _ => layer.polyline(&run, hw, (style == Style::Dashed).then_some(dash)),
        }
        let mut last = (f64::INFINITY, f64::INFINITY);
        for &q in run
            .iter()
            .filter(|_| matches!(style, Style::Markers | Style::LineMarkers))
        {
            if style == Style::Markers || (q.0 - last.0).hypot(q.1 - last.1) >= 3.0 * r {
                layer.disc(q, r);
                last = q;
            }
        }
    }
    img.composite(&layer, color);
}

/// A legend box (entries with empty labels left out) in the plot corner covering the fewest
/// pixels drawn so far (other than background and grid).
fn draw_legend(img: &mut impl Canvas, p: &Plot, entries: &[Entry]) {
    let entries: Vec<&Entry> = entries.iter().filter(|e| !e.0.is_empty()).collect();
    if entries.is_empty() {
        return;
    }
    let (s, m, ch) = (p.s, 4 * p.s, GLYPH_HEIGHT * p.s);
    let (pad, sw, row) = (3 * s + 1, 16 * s, ch + 3 * s);
    let bw = 3 * pad + sw + entries.iter().map(|e| tw(e.0, s)).max().unwrap_or(0);
    let bh = (2 * pad + row * entries.len()).saturating_sub(3 * s);
    let (xr, yb) = (
        p.x1.saturating_sub(m + bw).max(p.x0),
        p.y1.saturating_sub(m + bh).max(p.y0),
    );
    let corners = [(xr, p.y0 + m), (p.x0 + m, p.y0 + m), (xr, yb), (p.x0 + m, yb)];
    let count = |&(x, y): &(usize, usize)| {
        let (xs, ys) = (
            x.saturating_sub(2)..(x + bw + 2).min(img.image().width),
            y.saturating_sub(2)..(y + bh + 2).min(img.image().height),
        );
        let all = ys.flat_map(|y| xs.clone().map(move |x| (x, y)));
        all.filter(|&(x, y)| ![WHITE, GRID, GRID_MINOR].contains(&img.image().pixel(x, y)))
            .count()
    };
    let (bx, by) = corners.iter().copied().min_by_key(count).unwrap_or(corners[0]);
    let (w, h) = (bw.min(p.x1.saturating_sub(bx)), bh.min(p.y1.saturating_sub(by)));
    img.fill_rect(bx, by, w, h, [170, 170, 170]);
    img.fill_rect(bx + 1, by + 1, w.saturating_sub(2), h.saturating_sub(2), WHITE);
    for (i, &&(label, color, style)) in entries.iter().enumerate() {
        let (x, y) = (bx + pad, by + pad + i * row);
        let yc = (y + ch / 2) as f64 + 0.5;
        let (a, b, mid) = (
            Some((x as f64, yc)),
            Some(((x + sw) as f64, yc)),
            Some(((x + sw / 2) as f64, yc)),
        );
        let line = if style == Style::Dashed {
            style
        } else {
            Style::Line
        };
        if style != Style::Markers {
            draw_series(img, p, &[a, b], color, line);
        }
        if matches!(style, Style::Markers | Style::LineMarkers) {
            draw_series(img, p, &[mid], color, Style::Markers);
        }
        img.draw_text(x + sw + pad, y, label, INK, s);
    }
}

/// A chart: drawn once on any [`Canvas`], rendered as a raster image, as SVG, or as both.
pub trait Figure {
    /// Width and height in pixels.
    fn size(&self) -> (usize, usize);
    /// Draws the figure on `c` (of the figure's size, white).
    fn draw_on<C: Canvas>(&self, c: &mut C);

    /// The raster picture.
    fn render(&self) -> Image {
        let (w, h) = self.size();
        let mut img = Image::new(w, h, WHITE);
        self.draw_on(&mut img);
        img
    }

    /// The picture in both forms (PNG and SVG), drawn in one pass.
    fn picture(&self) -> Picture {
        let (w, h) = self.size();
        let mut c = SvgCanvas::new(w, h, WHITE);
        self.draw_on(&mut c);
        c.into_picture()
    }

    /// The picture as SVG.
    fn render_svg(&self) -> Svg {
        self.picture().svg
    }
}

impl Figure for Chart {
    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
    fn draw_on<C: Canvas>(&self, c: &mut C) {
        self.draw(c)
    }
}

impl Figure for BarChart {
    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
    fn draw_on<C: Canvas>(&self, c: &mut C) {
        self.draw(c)
    }
}

impl Chart {
    /// The plot interior `[x0, y0, x1, y1]` (pixels, end exclusive) and the `[y, x]` axes.
    pub fn plot_area(&self) -> ([usize; 4], [Axis; 2]) {
        let (p, axes) = self.frame();
        ([p.x0, p.y0, p.x1, p.y1], axes)
    }

    fn frame(&self) -> (Plot, [Axis; 2]) {
        let okx = |v: f64| v.is_finite() && (!self.log_x || v > 0.0);
        let oky = |v: f64| v.is_finite() && (!self.log_y || v > 0.0);
        let all = self.series.iter().flat_map(|s| s.points.iter());
        let (xs, ys): (Vec<f64>, Vec<f64>) = all.filter(|q| okx(q.0) && oky(q.1)).copied().unzip();
        let xr = self.x_range.filter(|r| okx(r.0) && okx(r.1) && r.0 < r.1);
        let yr = self.y_range.filter(|r| oky(r.0) && oky(r.1) && r.0 < r.1);
        let xr = xr.unwrap_or_else(|| padded(xs.into_iter(), self.log_x, 0.03));
        let ys = ys.into_iter().chain(self.hlines.iter().map(|l| l.0));
        let yr = yr.unwrap_or_else(|| padded(ys, self.log_y, 0.05));
        let labels = [&self.title, &self.x_label, &self.y_label].map(|l| !l.is_empty());
        let (w, h) = (self.width, self.height);
        let ranges = [(yr.0, yr.1, self.log_y), (xr.0, xr.1, self.log_x)];
        layout(w, h, labels, GLYPH_HEIGHT * scale_for(w, h), ranges)
    }

    /// Draws the chart on `img` (of the chart's size): white background, grid, frame, tick
    /// labels, reference lines, series, legend (in the corner with the least data), title and
    /// axis labels.
    pub fn draw(&self, img: &mut impl Canvas) {
        if self.width == 0 || self.height == 0 {
            return;
        }
        let (p, [ya, xa]) = self.frame();
        draw_axes(img, &p, &ya, Some(&xa));
        let refs = hlines(img, &p, &ya, &self.hlines);
        for se in &self.series {
            let map = |&(x, y): &Pt| Some((p.px(xa.frac(x)?), p.py(ya.frac(y)?)));
            let pts: Vec<_> = se.points.iter().map(map).collect();
            draw_series(img, &p, &pts, se.color, se.style);
        }
        let lines = self.series.iter().map(|e| (e.label.as_str(), e.color, e.style));
        draw_legend(img, &p, &lines.chain(refs).collect::<Vec<_>>());
        draw_titles(img, &p, &self.title, &self.x_label, &self.y_label);
    }
}

impl BarChart {
    /// Draws the bars on `img` (of the chart's size; value labels on top, category labels
    /// below: smaller or rotated when they don't fit), reference lines with a legend, title and
    /// y label.
    pub fn draw(&self, img: &mut impl Canvas) {
        let (w, h, s) = (self.width, self.height, scale_for(self.width, self.height));
        if w == 0 || h == 0 {
            return;
        }
        let ok = |v: f64| v.is_finite() && (!self.log_y || v > 0.0);
        let vals = self
            .bars
            .iter()
            .map(|b| b.1)
            .chain(self.hlines.iter().map(|l| l.0));
        let yr = padded(vals.chain((!self.log_y).then_some(0.0)), self.log_y, 0.1);
        let ranges = [(yr.0, yr.1, self.log_y), (0.0, 1.0, false)];
        let labels = [!self.title.is_empty(), false, !self.y_label.is_empty()];
        let slot = |p: &Plot| (p.x1 - p.x0) as f64 / self.bars.len().max(1) as f64;
        let (p, _) = layout(w, h, labels, GLYPH_HEIGHT * s, ranges);
        let fit = |texts: &[String], sc| texts.iter().all(|t| (tw(t, sc) + 2 * sc) as f64 <= slot(&p));
        let value = |v: f64| if ok(v) { fmt_compact(v) } else { "n/a".to_string() };
        let values: Vec<String> = self.bars.iter().map(|b| value(b.1)).collect();
        let names: Vec<String> = self.bars.iter().map(|b| b.0.clone()).collect();
        let (vs, ls, up) = (
            if fit(&values, s) { s } else { 1 },
            if fit(&names, s) { s } else { 1 },
            !fit(&names, 1),
        );
        // turned labels are written in full; at most half the picture is kept for them
        let up_h = names.iter().map(|l| tw(l, 1)).max().unwrap_or(0).min(h / 2);
        let (p, [ya, _]) = layout(w, h, labels, if up { up_h } else { GLYPH_HEIGHT * ls }, ranges);
        draw_axes(img, &p, &ya, None);
        let base = if self.log_y {
            p.y1
        } else {
            ya.frac(0.0).map_or(p.y1, |t| p.row(t) + 1)
        };
        img.fill_rect(p.x0, base, (p.x1 - p.x0) * usize::from(base < p.y1), 1, FRAME);
        for (i, (label, v, color)) in self.bars.iter().enumerate() {
            let (v, color) = (*v, *color);
            let xa = (p.px(0.0) + slot(&p) * (i as f64 + 0.15)).round() as usize;
            let xb = ((p.px(0.0) + slot(&p) * (i as f64 + 0.85)).round() as usize).max(xa + 1);
            let xc = (xa + xb) / 2;
            let top = ya.frac(v).filter(|_| ok(v)).map(|t| p.py(t).round() as usize);
            let top = top.map_or(base, |t| t.clamp(p.y0, p.y1));
            let (y_hi, y_lo) = (top.min(base), top.max(base));
            img.fill_rect(xa, y_hi, xb - xa, y_lo - y_hi, color);
            let th = GLYPH_HEIGHT * vs + 2 * s;
            let ty = if top > base {
                (top + 2 * s).min(p.y1.saturating_sub(th))
            } else {
                top.saturating_sub(th)
            };
            img.draw_text(
                xc.saturating_sub(tw(&values[i], vs) / 2),
                ty.max(p.y0),
                &values[i],
                INK,
                vs,
            );
            let ly = p.y1 + 5 * s + 1;
            if up {
                img.draw_text_up(xc.saturating_sub(GLYPH_HEIGHT / 2), ly, label, INK, 1);
            } else {
                img.draw_text(xc.saturating_sub(tw(label, ls) / 2), ly, label, INK, ls);
            }
        }
        let refs = hlines(img, &p, &ya, &self.hlines);
        draw_legend(img, &p, &refs);
        draw_titles(img, &p, &self.title, "", &self.y_label);
    }
}
