//! RGB images: PNG output, tiling, anti-aliased text (DejaVu Sans, [`super::font`]).

use super::font::{text_mask, text_size};
use crate::Error;
use std::path::Path;

/// An 8-bit RGB image, rows top to bottom, pixels left to right.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// width in pixels
    pub width: usize,
    /// height in pixels
    pub height: usize,
    /// `3 * width * height` bytes, pixel `(x, y)` at `3 * (x + width * y)`
    pub rgb: Vec<u8>,
}

/// Colour of the borders drawn by [`Image::tile`].
pub const BORDER_COLOR: [u8; 3] = [90, 90, 90];

impl Image {
    /// A `width` x `height` image filled with `color`.
    pub fn new(width: usize, height: usize, color: [u8; 3]) -> Self {
        let rgb = color.iter().copied().cycle().take(3 * width * height).collect();
        Image { width, height, rgb }
    }

    /// The colour of pixel `(x, y)`; panics when it is outside the image.
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the image"
        );
        let i = 3 * (x + self.width * y);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Sets pixel `(x, y)`; does nothing when it is outside the image.
    pub fn set_pixel(&mut self, x: usize, y: usize, color: [u8; 3]) {
        if x < self.width && y < self.height {
            let i = 3 * (x + self.width * y);
            self.rgb[i..i + 3].copy_from_slice(&color);
        }
    }

    /// Fills the rectangle with top-left corner `(x, y)` and size `w` x `h`, clipped to the
    /// image.
    pub fn fill_rect(&mut self, x: usize, y: usize, w: usize, h: usize, color: [u8; 3]) {
        for yy in y..(y + h).min(self.height) {
            for xx in x..(x + w).min(self.width) {
                self.set_pixel(xx, yy, color);
            }
        }
    }

    /// Copies `other` into this image with its top-left corner at `(x, y)` (clipped).
    pub fn blit(&mut self, other: &Image, x: usize, y: usize) {
        for yy in 0..other.height {
            for xx in 0..other.width {
                self.set_pixel(x + xx, y + yy, other.pixel(xx, yy));
            }
        }
    }

    /// Writes the image as an 8-bit RGB PNG file. A zero-sized image is an error.
    pub fn save_png(&self, path: &Path) -> Result<(), Error> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::Invalid(format!(
                "save_png {}: the image is empty ({}x{})",
                path.display(),
                self.width,
                self.height
            )));
        }
        let (w, h) = (u32::try_from(self.width), u32::try_from(self.height));
        let (Ok(w), Ok(h)) = (w, h) else {
            return Err(Error::Invalid(format!(
                "save_png {}: image too large",
                path.display()
            )));
        };
        let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
        let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w, h);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let to_io = |e: png::EncodingError| match e {
            png::EncodingError::IoError(e) => e,
            e => std::io::Error::other(e),
        };
        let mut writer = encoder.write_header().map_err(|e| Error::io(path, to_io(e)))?;
        writer
            .write_image_data(&self.rgb)
            .map_err(|e| Error::io(path, to_io(e)))?;
        writer.finish().map_err(|e| Error::io(path, to_io(e)))
    }

    /// Puts `images` side by side, `columns` per row (at least 1), each in a cell as large as
    /// the largest image (smaller ones centred on white; unused cells of the last row white), separated and surrounded by a
    /// 2-pixel [`BORDER_COLOR`] border. An empty list gives a 0 x 0 image.
    pub fn tile(images: &[Image], columns: usize) -> Image {
        const B: usize = 2;
        if images.is_empty() {
            return Image::new(0, 0, [0; 3]);
        }
        let columns = columns.clamp(1, images.len());
        let rows = images.len().div_ceil(columns);
        let cw = images.iter().map(|i| i.width).max().unwrap_or(0);
        let ch = images.iter().map(|i| i.height).max().unwrap_or(0);
        let mut out = Image::new(B + columns * (cw + B), B + rows * (ch + B), BORDER_COLOR);
        for n in 0..rows * columns {
            let (x0, y0) = (B + (n % columns) * (cw + B), B + (n / columns) * (ch + B));
            out.fill_rect(x0, y0, cw, ch, [255; 3]);
            if let Some(img) = images.get(n) {
                out.blit(img, x0 + (cw - img.width) / 2, y0 + (ch - img.height) / 2);
            }
        }
        out
    }

    /// Size in pixels of the box of `text` drawn by [`Image::draw_text`] at `scale`: its
    /// width and the height of its capitals (see [`super::font`]).
    pub fn text_size(text: &str, scale: usize) -> (usize, usize) {
        text_size(text, scale)
    }

    /// Draws one line of `text` in DejaVu Sans, anti-aliased, capitals `GLYPH_HEIGHT * scale`
    /// pixels high, the top-left of its box at `(x, y)` (descenders below the box), clipped to
    /// the image. No background is drawn.
    pub fn draw_text(&mut self, x: usize, y: usize, text: &str, color: [u8; 3], scale: usize) {
        let m = text_mask(text, scale);
        let top = y as i64 - m.above as i64;
        for v in 0..m.height {
            for u in 0..m.width {
                self.blend(
                    x as i64 + u as i64,
                    top + v as i64,
                    color,
                    m.alpha[u + m.width * v],
                );
            }
        }
    }

    /// Draws `text` like [`Image::draw_text`] but turned a quarter turn counter-clockwise (read
    /// bottom to top): the turned box (capital height wide, text width high) has its top-left
    /// corner at `(x, y)`.
    pub fn draw_text_up(&mut self, x: usize, y: usize, text: &str, color: [u8; 3], scale: usize) {
        let m = text_mask(text, scale);
        let left = x as i64 - m.above as i64;
        for v in 0..m.height {
            for u in 0..m.width {
                let (px, py) = (left + v as i64, y as i64 + (m.width - 1 - u) as i64);
                self.blend(px, py, color, m.alpha[u + m.width * v]);
            }
        }
    }

    /// Mixes `color` into pixel `(x, y)` with weight `alpha` (0..1); outside the image, nothing.
    pub fn blend(&mut self, x: i64, y: i64, color: [u8; 3], alpha: f32) {
        let inside = (0..self.width as i64).contains(&x) && (0..self.height as i64).contains(&y);
        if !inside || alpha <= 0.0 {
            return;
        }
        let a = alpha.min(1.0);
        let i = 3 * (x as usize + self.width * y as usize);
        for (dst, &c) in self.rgb[i..i + 3].iter_mut().zip(&color) {
            *dst = (f32::from(*dst) * (1.0 - a) + f32::from(c) * a).round() as u8;
        }
    }

    /// Stamps `text` in the top-left corner: white letters on a dark box, at scale 2 when the
    /// image is at least 256 pixels high and the text fits its width, else at scale 1.
    pub fn label(&mut self, text: &str) {
        let fits = Image::text_size(text, 2).0 + 8 <= self.width;
        let scale = if self.height >= 256 && fits { 2 } else { 1 };
        let (w, h) = Image::text_size(text, scale);
        let pad = 2 * scale;
        self.fill_rect(0, 0, w + 2 * pad, h + 2 * pad, [30, 30, 30]);
        self.draw_text(pad, pad, text, [255, 255, 255], scale);
    }
}
