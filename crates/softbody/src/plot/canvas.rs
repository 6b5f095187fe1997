//! The drawing targets of the charts: the raster [`Image`] (saved as PNG) and [`SvgCanvas`],
//! which draws the same picture into an image (so that layout decisions that look at pixels,
//! such as the legend's corner, are the same) and records it as SVG elements: rectangles,
//! text in DejaVu Sans at the raster's sizes, polylines and discs clipped to the plot.

use super::raster::{Layer, Op};
use super::Pt;
use cutfem::render::{font_em_px, Image, GLYPH_HEIGHT};
use std::fmt::Write;

/// A surface the charts draw on (module docs).
pub trait Canvas {
    /// The raster picture drawn so far.
    fn image(&self) -> &Image;
    /// A filled rectangle.
    fn fill_rect(&mut self, x: usize, y: usize, w: usize, h: usize, color: [u8; 3]);
    /// One line of text, the top-left of its capitals' box at `(x, y)` ([`Image::draw_text`]).
    fn draw_text(&mut self, x: usize, y: usize, text: &str, color: [u8; 3], scale: usize);
    /// Text read bottom to top ([`Image::draw_text_up`]).
    fn draw_text_up(&mut self, x: usize, y: usize, text: &str, color: [u8; 3], scale: usize);
    /// The lines and discs of `layer` in `color`.
    fn composite(&mut self, layer: &Layer, color: [u8; 3]);
}

impl Canvas for Image {
    fn image(&self) -> &Image {
        self
    }
    fn fill_rect(&mut self, x: usize, y: usize, w: usize, h: usize, color: [u8; 3]) {
        Image::fill_rect(self, x, y, w, h, color)
    }
    fn draw_text(&mut self, x: usize, y: usize, text: &str, color: [u8; 3], scale: usize) {
        Image::draw_text(self, x, y, text, color, scale)
    }
    fn draw_text_up(&mut self, x: usize, y: usize, text: &str, color: [u8; 3], scale: usize) {
        Image::draw_text_up(self, x, y, text, color, scale)
    }
    fn composite(&mut self, layer: &Layer, color: [u8; 3]) {
        layer.composite(self, color)
    }
}

/// A picture as SVG: its size and its elements.
#[derive(Clone, Debug, PartialEq)]
pub struct Svg {
    /// width in pixels (user units)
    pub width: usize,
    /// height in pixels (user units)
    pub height: usize,
    body: String,
}

impl Svg {
    /// The standalone SVG document.
    pub fn document(&self) -> String {
        let (w, h) = (self.width, self.height);
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" \
             font-family=\"DejaVu Sans, Verdana, sans-serif\">\n{}</svg>\n",
            self.body
        )
    }

    /// Writes [`Svg::document`] to `path`.
    pub fn save(&self, path: &std::path::Path) -> Result<(), String> {
        std::fs::write(path, self.document()).map_err(|e| format!("{}: {e}", path.display()))
    }
}

/// `items` placed like [`super::grid_of`] places images.
pub fn svg_grid(items: Vec<Svg>, columns: usize) -> Svg {
    let sizes: Vec<(usize, usize)> = items.iter().map(|s| (s.width, s.height)).collect();
    let (width, height, at) = super::grid_cells(&sizes, columns);
    placed(width, height, &items, &at)
}

/// A white picture of `width` x `height` with `items` at `at` (top-left corners).
fn placed(width: usize, height: usize, items: &[Svg], at: &[(usize, usize)]) -> Svg {
    let mut body = format!("<rect width=\"{width}\" height=\"{height}\" fill=\"#ffffff\"/>\n");
    for (s, (x, y)) in items.iter().zip(at) {
        let _ = writeln!(
            body,
            "<svg x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\">\n{}</svg>",
            s.body,
            w = s.width,
            h = s.height
        );
    }
    Svg { width, height, body }
}

/// A picture drawn once into both forms: the raster image and its SVG twin.
#[derive(Clone, Debug)]
pub struct Picture {
    /// the raster image (PNG)
    pub png: Image,
    /// the same picture as SVG
    pub svg: Svg,
}

impl Picture {
    /// Writes the PNG to `path` and the SVG beside it (`path` with the extension `svg`).
    pub fn save(&self, path: &std::path::Path) -> Result<(), String> {
        self.png
            .save_png(path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        self.svg.save(&path.with_extension("svg"))
    }

    /// `parts`, `columns` per row, placed as [`super::grid_of`] places images.
    pub fn grid(parts: Vec<Picture>, columns: usize) -> Picture {
        let (pngs, svgs): (Vec<Image>, Vec<Svg>) = parts.into_iter().map(|p| (p.png, p.svg)).unzip();
        Picture {
            png: super::grid_of(pngs, columns),
            svg: svg_grid(svgs, columns),
        }
    }

    /// `parts` one under the other, centred, on white ([`super::stack`]).
    pub fn stack(parts: &[Picture]) -> Picture {
        let images: Vec<&Image> = parts.iter().map(|p| &p.png).collect();
        let sizes: Vec<(usize, usize)> = images.iter().map(|i| (i.width, i.height)).collect();
        let (w, h, at) = super::stack_cells(&sizes);
        let svgs: Vec<Svg> = parts.iter().map(|p| p.svg.clone()).collect();
        Picture {
            png: super::stack(&images),
            svg: placed(w, h, &svgs, &at),
        }
    }
}

/// Draws into an image and records SVG elements (module docs).
#[derive(Debug)]
pub struct SvgCanvas {
    img: Image,
    body: String,
}

fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            c if c.is_control() => out.push('\u{fffd}'),
            c => out.push(c),
        }
    }
    out
}

/// `x,y x,y ...` with two decimals.
fn points(pts: &[Pt]) -> String {
    let v: Vec<String> = pts.iter().map(|p| format!("{:.2},{:.2}", p.0, p.1)).collect();
    v.join(" ")
}

impl SvgCanvas {
    /// A canvas of `width` x `height` filled with `background`.
    pub fn new(width: usize, height: usize, background: [u8; 3]) -> Self {
        let body = format!(
            "<rect width=\"{width}\" height=\"{height}\" fill=\"{}\"/>\n",
            hex(background)
        );
        SvgCanvas {
            img: Image::new(width, height, background),
            body,
        }
    }

    /// The picture in both forms.
    pub fn into_picture(self) -> Picture {
        let svg = Svg {
            width: self.img.width,
            height: self.img.height,
            body: self.body,
        };
        Picture { png: self.img, svg }
    }

    fn text_element(&mut self, transform: String, text: &str, color: [u8; 3], scale: usize) {
        if text.is_empty() {
            return;
        }
        let _ = writeln!(
            self.body,
            "<text transform=\"{transform}\" font-size=\"{:.2}\" fill=\"{}\">{}</text>",
            font_em_px(scale),
            hex(color),
            escape(text)
        );
    }
}

impl Canvas for SvgCanvas {
    fn image(&self) -> &Image {
        &self.img
    }
    fn fill_rect(&mut self, x: usize, y: usize, w: usize, h: usize, color: [u8; 3]) {
        self.img.fill_rect(x, y, w, h, color);
        // clipped to the image, as the raster is
        let (w, h) = (
            w.min(self.img.width.saturating_sub(x)),
            h.min(self.img.height.saturating_sub(y)),
        );
        if w > 0 && h > 0 {
            let _ = writeln!(
                self.body,
                "<rect x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" fill=\"{}\"/>",
                hex(color)
            );
        }
    }
    fn draw_text(&mut self, x: usize, y: usize, text: &str, color: [u8; 3], scale: usize) {
        self.img.draw_text(x, y, text, color, scale);
        let baseline = y + GLYPH_HEIGHT * scale.max(1);
        self.text_element(format!("translate({x} {baseline})"), text, color, scale);
    }
    fn draw_text_up(&mut self, x: usize, y: usize, text: &str, color: [u8; 3], scale: usize) {
        self.img.draw_text_up(x, y, text, color, scale);
        // the baseline is the column `x + capital height`; the text starts at the bottom
        let (w, cap) = Image::text_size(text, scale);
        let t = format!("translate({} {}) rotate(-90)", x + cap, y + w);
        self.text_element(t, text, color, scale);
    }
    fn composite(&mut self, layer: &Layer, color: [u8; 3]) {
        layer.composite(&mut self.img, color);
        let c = hex(color);
        for op in layer.ops() {
            match op {
                Op::Disc(q, r) => {
                    if layer.contains(*q) {
                        let _ = writeln!(
                            self.body,
                            "<circle cx=\"{:.2}\" cy=\"{:.2}\" r=\"{:.2}\" fill=\"{c}\"/>",
                            q.0,
                            q.1,
                            r + 0.5
                        );
                    }
                }
                Op::Poly(pts, hw, dash) => {
                    let dash = dash.map_or(String::new(), |(on, off)| {
                        format!(" stroke-dasharray=\"{on:.2} {off:.2}\"")
                    });
                    for run in layer.clipped_runs(pts) {
                        let _ = writeln!(
                            self.body,
                            "<polyline points=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"{:.2}\" \
                             stroke-linecap=\"round\" stroke-linejoin=\"round\"{dash}/>",
                            points(&run),
                            2.0 * hw
                        );
                    }
                }
            }
        }
    }
}
