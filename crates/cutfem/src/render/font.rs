//! Text in pictures: DejaVu Sans (embedded; Bitstream Vera licence, `fonts/LICENSE` of this
//! crate) rasterized with anti-aliasing by `ab_glyph`.
//!
//! Sizes are given as an integer `scale`, as the pictures' layouts count them: at scale `s`
//! a capital letter is [`GLYPH_HEIGHT`]` * s` pixels high, so a line of text occupies the box
//! `text_size(text, s)` from the top of its capitals to its baseline; descenders (g, p, y)
//! reach about `2.3 s` pixels below that box and accents above it.

use ab_glyph::{point, Font, FontRef, GlyphId, PxScale, ScaleFont};
use std::sync::OnceLock;

/// Height in pixels of a capital letter at scale 1 (the layouts' unit of text height).
pub const GLYPH_HEIGHT: usize = 7;

static FONT_BYTES: &[u8] = include_bytes!("../../fonts/DejaVuSans.ttf");

/// The embedded font and its capital height per pixel of font size.
fn font() -> &'static (FontRef<'static>, f32) {
    static FONT: OnceLock<(FontRef<'static>, f32)> = OnceLock::new();
    FONT.get_or_init(|| {
        // The font is part of this crate's source: a parse failure is a build defect that
        // the tests below catch, never an input error.
        let font = FontRef::try_from_slice(FONT_BYTES).expect("the embedded DejaVu Sans parses");
        let h = font.glyph_id('H').with_scale(1000.0);
        let cap = font
            .outline_glyph(h)
            .map_or(0.73, |o| o.px_bounds().height() / 1000.0);
        (font, cap)
    })
}

/// One line of text as coverage values (0..1), `width` x `height`, row-major. The top of
/// the capitals is row `above` (rows before it hold accents), the baseline is row
/// `above + GLYPH_HEIGHT * scale`.
#[derive(Clone, Debug, PartialEq)]
pub struct TextMask {
    /// width in pixels: the advance of the whole line, rounded up
    pub width: usize,
    /// height in pixels: accents, capitals and descenders
    pub height: usize,
    /// rows above the top of the capitals
    pub above: usize,
    /// coverage, `width * height` values
    pub alpha: Vec<f32>,
}

/// The glyphs of `text` at font size `px`: (glyph, pen x), and the pen position at the end.
fn layout(text: &str, px: f32) -> (Vec<(GlyphId, f32)>, f32) {
    let (font, _) = font();
    let scaled = font.as_scaled(PxScale::from(px));
    let mut pen = 0.0f32;
    let mut prev: Option<GlyphId> = None;
    let mut glyphs = Vec::with_capacity(text.len());
    for c in text.chars() {
        let id = font.glyph_id(c);
        if let Some(p) = prev {
            pen += scaled.kern(p, id);
        }
        glyphs.push((id, pen));
        pen += scaled.h_advance(id);
        prev = Some(id);
    }
    (glyphs, pen)
}

/// Font size in pixels whose capitals are `GLYPH_HEIGHT * scale` pixels high.
fn font_px(scale: usize) -> f32 {
    (GLYPH_HEIGHT * scale.max(1)) as f32 / font().1
}

/// The em size in pixels of the text at `scale` (the `font-size` of CSS and SVG): `ab_glyph`
/// scales by the font's height (ascent - descent), the em is `units_per_em` of it.
pub fn font_em_px(scale: usize) -> f32 {
    let (font, _) = font();
    let em = font.units_per_em().unwrap_or(2048.0);
    font_px(scale) * em / font.height_unscaled()
}

/// Size in pixels of the box of `text` at `scale`: its advance width (rounded up) and the
/// capital height `GLYPH_HEIGHT * scale`. Empty text is 0 wide.
pub fn text_size(text: &str, scale: usize) -> (usize, usize) {
    let (_, end) = layout(text, font_px(scale));
    (end.ceil() as usize, GLYPH_HEIGHT * scale.max(1))
}

/// Rasterizes one line of `text` at `scale` (control characters are drawn as the font's
/// missing-glyph box).
pub fn text_mask(text: &str, scale: usize) -> TextMask {
    let (font, _) = font();
    let px = font_px(scale);
    let scaled = font.as_scaled(PxScale::from(px));
    let cap = (GLYPH_HEIGHT * scale.max(1)) as f32;
    let above = (scaled.ascent() - cap).ceil().max(0.0);
    let below = (-scaled.descent()).ceil().max(0.0);
    let baseline = above + cap;
    let (glyphs, end) = layout(text, px);
    let (width, height) = (end.ceil() as usize, (baseline + below) as usize);
    let mut alpha = vec![0.0f32; width * height];
    for (id, x) in glyphs {
        let glyph = id.with_scale_and_position(px, point(x, baseline));
        let Some(outline) = font.outline_glyph(glyph) else {
            continue; // a space
        };
        let b = outline.px_bounds();
        let (x0, y0) = (b.min.x as i64, b.min.y as i64);
        outline.draw(|gx, gy, c| {
            let (x, y) = (x0 + i64::from(gx), y0 + i64::from(gy));
            if (0..width as i64).contains(&x) && (0..height as i64).contains(&y) {
                let a = &mut alpha[x as usize + width * y as usize];
                *a = (*a + c).min(1.0);
            }
        });
    }
    TextMask {
        width,
        height,
        above: above as usize,
        alpha,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn capitals_are_glyph_height_tall_and_text_stays_in_its_mask() {
        for s in 1..=4 {
            let m = text_mask("HEH", s);
            let inked = |y: usize| (0..m.width).any(|x| m.alpha[x + m.width * y] > 0.5);
            let rows: Vec<usize> = (0..m.height).filter(|&y| inked(y)).collect();
            let (top, bottom) = (rows[0], *rows.last().unwrap());
            // the capitals fill the box from row `above` to the baseline, within a pixel
            assert!(
                top.abs_diff(m.above) <= 1,
                "scale {s}: top {top}, above {}",
                m.above
            );
            let base = m.above + GLYPH_HEIGHT * s;
            assert!(
                (bottom + 1).abs_diff(base) <= 1,
                "scale {s}: bottom {bottom}, baseline {base}"
            );
            assert_eq!(text_size("HEH", s), (m.width, GLYPH_HEIGHT * s));
        }
        // descenders go below the baseline, inside the mask
        let m = text_mask("gyp", 2);
        let base = m.above + GLYPH_HEIGHT * 2;
        assert!((base..m.height).any(|y| (0..m.width).any(|x| m.alpha[x + m.width * y] > 0.5)));
    }

    #[test]
    fn width_grows_with_the_text_and_the_scale() {
        assert_eq!(text_size("", 2), (0, 14));
        let (a, b) = (text_size("noise", 1).0, text_size("noise floor", 1).0);
        assert!(a > 0 && b > a);
        let (w1, w3) = (
            text_size("stiffness_field", 1).0,
            text_size("stiffness_field", 3).0,
        );
        assert!(w3.abs_diff(3 * w1) <= 3, "{w1} {w3}");
        // proportional: an "i" is narrower than an "m"
        assert!(text_size("iiii", 2).0 < text_size("mmmm", 2).0);
        // every character is drawn, none is skipped
        let m = text_mask("a\u{7}b", 2);
        assert!(m.width > text_size("ab", 2).0);
    }
}
