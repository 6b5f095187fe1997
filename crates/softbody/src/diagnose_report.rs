//! The pictures of a diagnosis report (`softbody diagnose`): where and how the fitted model
//! misses the measurements, which effect could fix it, and the rms over the user's successive
//! models.
//!
//! * `rms_over_time.png`: rms per frame of the model as given, with the noise floor;
//! * `surface_residual.png`: the reference surface coloured by the mean signed residual of the
//!   points whose reference point lies nearest each vertex (blue: observed inside the model,
//!   red: outside), from three sides, with the region centres and a colour bar;
//! * `worst_frame.png`: the simulated surface at the worst frame with that frame's points
//!   coloured by their signed residual;
//! * `residual_direction.png`: the per-frame mean residual vector (and its component along
//!   gravity) with the direction analysis in words;
//! * `history.png` (when there is a history): rms per run over the user's models;
//! * `candidates.png`: predicted and refitted rms per candidate effect.

mod charts;
mod raster;
#[cfg(test)]
mod tests;

use crate::plot::axis::fmt_compact;
use crate::plot::{grid_of, stack, Canvas, Figure, Picture, SvgCanvas};
use adjoint::diagnosis::history::Entry;
use adjoint::diagnosis::Diagnosis;
use charts::{candidates, history, residual_direction, rms_over_time};
use cutfem::render::{Camera, Image, GLYPH_HEIGHT};
use cutfem::TriMesh;
use raster::View;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// What the pictures need besides the diagnosis.
pub struct PictureInputs<'a> {
    /// reference surface (marching cubes)
    pub reference: &'a TriMesh,
    /// simulated surface of the fitted model at `d.worst_frame`
    pub worst: &'a TriMesh,
    /// gravity of the scene if on, for the direction plot
    pub gravity: Option<[f64; 3]>,
    /// earlier runs of this scene, oldest first (may be empty)
    pub history: &'a [Entry],
}

const WHITE: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [25, 25, 25];
const REF_GREY: [u8; 3] = [120, 120, 120];
/// Vertices without observed points.
const NO_DATA: [f64; 3] = [0.55, 0.55, 0.55];
/// Title of `surface_residual.png`.
const SURFACE_TITLE: &str =
    "mean signed residual on the reference surface (red: observed outside the model, blue: inside)";
/// Side of one rendered view in pixels.
const VIEW: usize = 380;

/// The report's pictures, in its order.
const PICTURES: [&str; 6] = [
    "rms_over_time.png",
    "surface_residual.png",
    "worst_frame.png",
    "residual_direction.png",
    "history.png",
    "candidates.png",
];

/// Writes the PNGs into `dir`, returns their paths (in this order): `rms_over_time.png`,
/// `surface_residual.png`, `worst_frame.png`, `residual_direction.png`, `history.png` (only
/// with a history), `candidates.png`.
pub fn write_pictures(dir: &Path, d: &Diagnosis, inputs: &PictureInputs) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    // the charts in both forms (PNG and SVG), the surface renderings as PNG
    let mut charts = vec![
        ("rms_over_time.png", rms_over_time(d).picture()),
        ("residual_direction.png", residual_direction(d, inputs.gravity)),
    ];
    if !inputs.history.is_empty() {
        charts.push(("history.png", history(inputs.history)));
    }
    charts.push(("candidates.png", candidates(d)));
    let surfaces = [
        ("surface_residual.png", surface_residual(d, inputs.reference)),
        ("worst_frame.png", worst_frame(d, inputs.worst)),
    ];
    for (name, img) in &surfaces {
        let path = dir.join(name);
        img.save_png(&path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    for (name, picture) in &charts {
        picture.save(&dir.join(name))?;
    }
    // in the report's order
    let written: Vec<&str> = charts
        .iter()
        .map(|c| c.0)
        .chain(surfaces.iter().map(|s| s.0))
        .collect();
    let out = PICTURES
        .iter()
        .filter(|n| written.contains(n))
        .map(|n| dir.join(n))
        .collect();
    Ok(out)
}

/// Writes the history picture alone (rms per run over the user's models) to `path`.
pub fn write_history_picture(path: &Path, history_entries: &[Entry]) -> Result<(), String> {
    history(history_entries).save(path)
}

/// `text` split into lines of at most `chars` characters at spaces.
fn wrap(text: &str, chars: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for para in text.split('\n') {
        let mut line = String::new();
        for word in para.split_whitespace() {
            if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > chars {
                lines.push(std::mem::take(&mut line));
            }
            if !line.is_empty() {
                line.push(' ');
            }
            line.push_str(word);
        }
        lines.push(line);
    }
    lines
}

/// `text` wrapped to `width` pixels at `scale`, on white, centred or left-aligned.
fn text_block(width: usize, text: &str, scale: usize, center: bool) -> Picture {
    let (pad, row) = (6, (GLYPH_HEIGHT + 4) * scale);
    let chars = (width.saturating_sub(2 * pad) / (6 * scale)).max(8);
    let lines = wrap(text, chars);
    let mut c = SvgCanvas::new(width, 2 * pad + lines.len() * row, WHITE);
    for (i, line) in lines.iter().enumerate() {
        let w = Image::text_size(line, scale).0;
        let x = if center { width.saturating_sub(w) / 2 } else { pad };
        c.draw_text(x, pad + i * row, line, INK, scale);
    }
    c.into_picture()
}

/// A row of legend entries `(label, colour, dashed)`: a filled swatch, or a dashed line.
fn key_row(width: usize, entries: &[(&str, [u8; 3], bool)]) -> Picture {
    let (s, gap, sw) = (2, 24, 24);
    let total: usize = entries
        .iter()
        .map(|(l, _, _)| sw + 6 + Image::text_size(l, s).0 + gap)
        .sum::<usize>()
        .saturating_sub(gap);
    let ch = GLYPH_HEIGHT * s;
    let width = width.max(total + 12);
    let mut img = SvgCanvas::new(width, ch + 12, WHITE);
    let mut x = width.saturating_sub(total) / 2;
    for &(label, color, dashed) in entries {
        if dashed {
            for k in 0..3 {
                img.fill_rect(x + 9 * k, 6 + ch / 2 - 1, 6, 3, color);
            }
        } else {
            img.fill_rect(x, 6, sw, ch, color);
        }
        img.draw_text(x + sw + 6, 6, label, INK, s);
        x += sw + 6 + Image::text_size(label, s).0 + gap;
    }
    img.into_picture()
}

/// Diverging colour map: `t` in `[-1, 1]` (clamped) from blue through white to red.
fn diverging(t: f64) -> [f64; 3] {
    const MAP: [[f64; 3]; 5] = [
        [33.0, 102.0, 172.0],
        [146.0, 197.0, 222.0],
        [247.0, 247.0, 247.0],
        [244.0, 165.0, 130.0],
        [178.0, 24.0, 43.0],
    ];
    if t.is_nan() {
        return NO_DATA;
    }
    let s = (t.clamp(-1.0, 1.0) + 1.0) * 2.0;
    let i = (s.floor() as usize).min(3);
    let f = s - i as f64;
    [0, 1, 2].map(|d| (MAP[i][d] + f * (MAP[i + 1][d] - MAP[i][d])) / 255.0)
}

fn to_rgb(c: [f64; 3]) -> [u8; 3] {
    c.map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8)
}

/// The `q` quantile (`0..=1`) of the finite `|values|`; `None` when there are none.
fn abs_quantile(values: impl Iterator<Item = f64>, q: f64) -> Option<f64> {
    let mut a: Vec<f64> = values.filter(|v| v.is_finite()).map(f64::abs).collect();
    if a.is_empty() {
        return None;
    }
    a.sort_by(f64::total_cmp);
    let i = ((q * a.len() as f64).ceil() as usize).clamp(1, a.len()) - 1;
    Some(a[i])
}

/// A colour-map limit from the values: their 95th percentile of `|v|`, else their largest,
/// else 1.
fn limit_of(values: &[f64]) -> f64 {
    let ok = |v: &f64| v.is_finite() && *v > 0.0;
    abs_quantile(values.iter().copied(), 0.95)
        .filter(ok)
        .or_else(|| abs_quantile(values.iter().copied(), 1.0).filter(ok))
        .unwrap_or(1.0)
}

/// A horizontal colour bar from `-limit` to `limit` with labelled ticks and a caption.
fn colorbar(width: usize, limit: f64, caption: &str, no_data: bool) -> Image {
    let s = 2;
    let ch = GLYPH_HEIGHT * s;
    let bar_w = 360.min(width.saturating_sub(300)).max(100);
    let mut img = Image::new(width.max(bar_w + 300), 3 * ch + 44, WHITE);
    let x0 = (img.width - bar_w) / 2;
    let top = 6;
    let cap_w = Image::text_size(caption, s).0;
    img.draw_text(img.width.saturating_sub(cap_w) / 2, top, caption, INK, s);
    let by = top + ch + 8;
    for i in 0..bar_w {
        let t = 2.0 * (i as f64 + 0.5) / bar_w as f64 - 1.0;
        img.fill_rect(x0 + i, by, 1, 18, to_rgb(diverging(t)));
    }
    for k in 0..3 {
        let t = k as f64 / 2.0;
        let x = x0 + ((bar_w - 1) as f64 * t).round() as usize;
        img.fill_rect(x, by + 18, 1, 5, INK);
        let label = fmt_compact((2.0 * t - 1.0) * limit);
        let lw = Image::text_size(&label, s).0;
        img.draw_text(x.saturating_sub(lw / 2), by + 26, &label, INK, s);
    }
    if no_data {
        let x = x0 + bar_w + 40;
        img.fill_rect(x, by, 18, 18, to_rgb(NO_DATA));
        img.draw_text(x + 24, by + 2, "no data", INK, s);
    }
    img
}

/// The bounding box of `points`.
fn bbox(points: impl Iterator<Item = [f64; 3]>) -> Option<([f64; 3], [f64; 3])> {
    points.fold(None, |acc, p| {
        let (lo, hi) = acc.unwrap_or((p, p));
        Some((
            [0, 1, 2].map(|d| lo[d].min(p[d])),
            [0, 1, 2].map(|d| hi[d].max(p[d])),
        ))
    })
}

fn diagonal((lo, hi): ([f64; 3], [f64; 3])) -> f64 {
    (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt()
}

/// Nearest-vertex queries through a uniform spatial hash of the vertices.
struct VertexHash<'a> {
    points: &'a [[f64; 3]],
    lo: [f64; 3],
    cell: f64,
    /// largest cell index per axis
    top: [i64; 3],
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl<'a> VertexHash<'a> {
    fn new(points: &'a [[f64; 3]]) -> Option<Self> {
        let b = bbox(points.iter().copied())?;
        let diag = diagonal(b);
        let cell = if diag > 0.0 {
            2.0 * diag / (points.len() as f64).sqrt()
        } else {
            1.0
        };
        let mut me = VertexHash {
            points,
            lo: b.0,
            cell,
            top: [0; 3],
            cells: HashMap::new(),
        };
        for (i, p) in points.iter().enumerate() {
            let k = me.key(*p);
            for d in 0..3 {
                me.top[d] = me.top[d].max(k[d]);
            }
            me.cells.entry(k).or_default().push(i as u32);
        }
        Some(me)
    }

    fn key(&self, p: [f64; 3]) -> [i64; 3] {
        [0, 1, 2].map(|d| ((p[d] - self.lo[d]) / self.cell).floor().clamp(-1e9, 1e9) as i64)
    }

    /// The index of the vertex nearest `p` (lowest index on ties within a cell order).
    fn nearest(&self, p: [f64; 3]) -> usize {
        let c = self.key(p);
        // beyond this shell there are no cells
        let last = (0..3)
            .map(|d| c[d].abs().max((c[d] - self.top[d]).abs()))
            .max()
            .unwrap_or(0);
        let d2 = |q: &[f64; 3]| (0..3).map(|d| (q[d] - p[d]).powi(2)).sum::<f64>();
        let mut best = (f64::INFINITY, 0usize);
        for r in 0..=last {
            for dx in -r..=r {
                for dy in -r..=r {
                    for dz in -r..=r {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                            continue;
                        }
                        let Some(list) = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                            continue;
                        };
                        for &i in list {
                            let e = d2(&self.points[i as usize]);
                            if e < best.0 {
                                best = (e, i as usize);
                            }
                        }
                    }
                }
            }
            // every vertex of a farther shell is at least r cells away
            if best.0 <= (r as f64 * self.cell).powi(2) {
                break;
            }
        }
        best.1
    }
}

/// Mean signed residual per vertex of `mesh` over the points (not outside) whose reference
/// point lies nearest it; `NaN` where there are none.
fn vertex_means(mesh: &TriMesh, d: &Diagnosis) -> Vec<f64> {
    let Some(hash) = VertexHash::new(&mesh.vertices) else {
        return Vec::new();
    };
    let mut acc = vec![(0.0, 0usize); mesh.vertices.len()];
    for r in d.records.iter().filter(|r| !r.outside && r.residual.is_finite()) {
        let a = &mut acc[hash.nearest(r.reference)];
        a.0 += r.residual;
        a.1 += 1;
    }
    acc.into_iter()
        .map(|(s, n)| if n > 0 { s / n as f64 } else { f64::NAN })
        .collect()
}

/// Views of `mesh` (vertex colours `colors`) from the azimuths `thetas` (radians), framing
/// the box `frame`, each with a caption; `decorate` draws on each view.
fn views(
    mesh: &TriMesh,
    colors: &[[f64; 3]],
    frame: ([f64; 3], [f64; 3]),
    thetas: &[f64],
    mut decorate: impl FnMut(&mut View),
) -> Vec<Image> {
    thetas
        .iter()
        .map(|&theta| {
            let camera = Camera::framing(frame.0, frame.1, theta, 0.35);
            let mut v = raster::shaded(mesh, colors, &camera, VIEW, VIEW);
            decorate(&mut v);
            let label = format!("view from azimuth {:.0} deg", theta.to_degrees());
            v.img
                .draw_text(6, VIEW - 6 - GLYPH_HEIGHT * 2, &label, REF_GREY, 2);
            v.img
        })
        .collect()
}

/// A picture that says there is nothing to draw.
fn empty_picture(title: &str, why: &str) -> Image {
    stack(&[
        &text_block(3 * VIEW, title, 2, true).png,
        &text_block(3 * VIEW, why, 2, true).png,
        &Image::new(3 * VIEW, 120, WHITE),
    ])
}

/// Picture 2: the reference surface coloured by the mean signed residual per vertex.
fn surface_residual(d: &Diagnosis, reference: &TriMesh) -> Image {
    let title = SURFACE_TITLE;
    let Some(frame) = bbox(reference.vertices.iter().copied()) else {
        return empty_picture(title, "the reference surface is empty");
    };
    let means = vertex_means(reference, d);
    let limit = limit_of(&means);
    let colors: Vec<[f64; 3]> = means.iter().map(|&m| diverging(m / limit)).collect();
    let hash = VertexHash::new(&reference.vertices);
    // region centres, put on their nearest vertex
    let marks: Vec<(usize, [f64; 3])> = d
        .regions
        .iter()
        .map(|r| {
            let at = hash
                .as_ref()
                .map_or(r.center, |h| reference.vertices[h.nearest(r.center)]);
            (r.id, at)
        })
        .collect();
    let tol = 0.02 * diagonal(frame);
    let thetas = [30.0f64, 150.0, 270.0].map(f64::to_radians);
    let imgs = views(reference, &colors, frame, &thetas, |v| {
        for (id, p) in &marks {
            if let Some((x, y, _)) = v.visible(*p, tol) {
                v.disc((x, y), 5.0, WHITE);
                v.disc((x, y), 3.5, INK);
                let text = id.to_string();
                let (tw, th) = Image::text_size(&text, 2);
                let (tx, ty) = ((x + 8.0) as usize, (y as usize).saturating_sub(th / 2));
                v.img
                    .fill_rect(tx.saturating_sub(2), ty.saturating_sub(2), tw + 4, th + 4, WHITE);
                v.img.draw_text(tx, ty, &text, INK, 2);
            }
        }
    });
    let tiles = grid_of(imgs, 3);
    let w = tiles.width;
    let no_data = means.iter().any(|m| m.is_nan());
    stack(&[
        &text_block(w, title, 2, true).png,
        &tiles,
        &colorbar(w, limit, "mean signed residual per vertex", no_data),
        &text_block(w, "dots with numbers: centres of the surface regions", 2, true).png,
    ])
}

/// Picture 3: the simulated surface at the worst frame with that frame's points.
fn worst_frame(d: &Diagnosis, worst: &TriMesh) -> Image {
    let f = d.worst_frame;
    let (rms, n) = d
        .per_frame
        .iter()
        .find(|p| p.0 == f)
        .map_or((f64::NAN, 0), |p| (p.1, p.2));
    let title = format!("worst frame {f}: rms {} over {n} points", fmt_compact(rms));
    let points: Vec<_> = d.records.iter().filter(|r| r.frame == f).collect();
    let all = worst
        .vertices
        .iter()
        .copied()
        .chain(points.iter().map(|r| r.position));
    let Some(frame) = bbox(all) else {
        return empty_picture(&title, "no simulated surface and no observed point");
    };
    let values: Vec<f64> = points.iter().filter(|r| !r.outside).map(|r| r.residual).collect();
    let limit = limit_of(&values);
    let diag = diagonal(frame);
    let radius = if points.len() > 3000 { 1.6 } else { 2.5 };
    let grey = vec![[0.8; 3]; worst.vertices.len()];
    let imgs = views(
        worst,
        &grey,
        frame,
        &[30.0f64.to_radians(), 210.0f64.to_radians()],
        |v| {
            let mut seen: Vec<(f64, f64, f64, [u8; 3])> = points
                .iter()
                .filter_map(|r| {
                    let tol = 0.02 * diag + if r.outside { 0.0 } else { r.residual.abs() };
                    let (x, y, z) = v.visible(r.position, tol)?;
                    let c = if r.outside {
                        INK
                    } else {
                        to_rgb(diverging(r.residual / limit))
                    };
                    Some((x, y, z, c))
                })
                .collect();
            // far to near, so that near points stay on top
            seen.sort_by(|a, b| b.2.total_cmp(&a.2));
            for (x, y, _, c) in seen {
                v.disc((x, y), radius, c);
            }
        },
    );
    let tiles = grid_of(imgs, 2);
    let w = tiles.width;
    let outside = points.iter().filter(|r| r.outside).count();
    let mut parts = vec![
        text_block(w, &title, 2, true).png,
        tiles,
        colorbar(w, limit, "signed residual of each observed point", false),
    ];
    if outside > 0 {
        let s = if outside == 1 { "" } else { "s" };
        let note = format!("black: {outside} point{s} far from every triangle of the model");
        parts.push(text_block(w, &note, 2, true).png);
    }
    stack(&parts.iter().collect::<Vec<_>>())
}
